"""Shared test set-up: one torch thread, quiet warnings from PettingZoo's Dict-observation checks."""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("RAY_DEDUP_LOGS", "0")
