"""floe package."""
