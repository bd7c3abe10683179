"""The paper's two-loop controller (docs/method.md §1), composed from its stages (controller.py)."""
