"""two_loop."""
