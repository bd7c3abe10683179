"""Catalog options -> nested parameter dataclasses (dotted keys)."""
