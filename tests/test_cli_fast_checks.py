"""Misspelt population names and seats are refused before torch or Ray load (a second, not 2-6 s)."""

from __future__ import annotations

import subprocess
import sys

import pytest

_PROBE = """
import sys
from rllib_conv.cli import main
rc = main(sys.argv[1:])
heavy = sorted(m for m in ("torch", "ray.rllib", "ray.tune") if m in sys.modules)
print("RC", rc, "HEAVY", ",".join(heavy) or "none")
"""


@pytest.mark.parametrize(
    "argv",
    [
        ["train", "tune_configs/bandit_modular.yaml", "--set", "population=nosuch"],
        ["sweep", "tune_configs/bandit_modular.yaml", "--set", "population={grid_search: [bandit-s1-hand, nosuch]}"],
        ["pair", "bandit-s1-hand:hand-train-0", "bandit-s1-hand:nosuch"],
        ["pair", "nosuch:0", "bandit-s1-hand:hand-train-0"],
    ],
)
def test_a_misspelt_population_is_refused_before_torch_loads(argv: list[str], tmp_path) -> None:
    out = subprocess.run(
        [sys.executable, "-c", _PROBE, *argv, *(["--storage", str(tmp_path)] if argv[0] != "pair" else ["--out", str(tmp_path)])],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert "RC 2 HEAVY none" in out.stdout, out.stdout + out.stderr
    assert "nosuch" in out.stderr and not any(tmp_path.iterdir())
