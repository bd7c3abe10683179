"""The reference path and its Frenet frame (docs/method.md §2)."""
