"""Comparison baselines for the two-loop controller (docs/method.md §8).

``ipopt_nmpc``: the two-loop controller with the Ipopt outer loop (the planner itself
is :mod:`controllers.two_loop.outer.ipopt_planner`; CasADi is imported lazily, so importing
this package stays light without it). ``lane_keep``: pure pursuit, no avoidance.
``sumo``: SUMO's own driver model (not a controller). ``recorded``: the ego's own
recorded trajectory, the human's drive (not a controller either). ``r157_reference``:
UN R157's careful and competent human driver (docs/baselines.md).
"""
