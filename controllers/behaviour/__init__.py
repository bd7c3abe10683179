"""Behaviour layer: other vehicles and lane context in, obstacles, pass side, lateral
reference and speed target out (used by the SUMO loop and the plant-only simulator)."""
