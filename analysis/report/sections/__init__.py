"""The report's sections, one per module: each takes the `Context` and returns its markdown."""
