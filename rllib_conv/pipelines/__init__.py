"""Runnable pipelines: each is a config plus one entry point the CLI calls."""
