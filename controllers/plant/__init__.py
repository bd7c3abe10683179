"""The single-track vehicle model: the plant and the preview's model (docs/method.md §6)."""
