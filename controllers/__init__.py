"""Numerical core of hwyeval: vehicle models, Frenet path, C/GMRES, controllers.

Everything here takes and returns numpy arrays; nothing imports SUMO, touches files
or logs to Rerun.
"""
