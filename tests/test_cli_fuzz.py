"""Property-based fuzzing of the CLI's validation path (issue 47): `--set` values and config files, no Ray.

Whatever is given, `rllib-conv train` either accepts it (and reaches the pipeline, stubbed
here so nothing trains) or refuses it: exit 2, one `rllib-conv: error:` line naming the
culprit (the `--set` or the file), never a traceback. Bounded: a fixed number of examples,
each with a deadline, no shrinking database on disk.
"""

from __future__ import annotations

import sys
import tempfile
import types
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rllib_conv.cli import main

BOUNDED = settings(
    max_examples=80,
    deadline=2000,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
GOOD = {"name": "fuzz", "population": "bandit-s1-hand", "run": {"timesteps": 64}}
KEYS = [
    "lam",
    "seed",
    "name",
    "method",
    "env",
    "population",
    "ppo.lr",
    "ppo.entropy_coeff",
    "ppo.num_epochs",
    "run.timesteps",
    "run.resources.gpu",
    "model.hidden",
    "mapping.kind",
    "mapping.weights",
    "freeze",
    "lam.x",
    "ppo",
    "nothing.at.all",
]
NASTY = [
    "",
    "~",
    "[1",
    "{a: 1}",
    "-1",
    "1e400",
    "nan",
    ".inf",
    "!!binary AAAA",
    "!!python/object:os.system",
    "*a",
    "&a 1",
    "{grid_search: []}",
    "{grid_search: [0.1, x]}",
    "9" * 5000,
    "[" * 1000,
    "'",
    '"',
    "\x00",
    "\udcff".encode("utf-8", "surrogateescape").decode("utf-8", "replace"),
    "[[0, 0.1], [5, -1]]",
    "{lr: -1}",
    "²",
]


class Reached(Exception):
    """Raised by the stubbed pipeline: the arguments passed every check."""


@pytest.fixture(autouse=True)
def stub_pipeline(monkeypatch):
    """`pipelines.train` replaced by a stub that stops at its door: nothing trains, Ray never loads."""
    stub = types.ModuleType("rllib_conv.pipelines.train")

    def run(*args, **kwargs):
        raise Reached

    stub.run = run
    monkeypatch.setitem(sys.modules, "rllib_conv.pipelines.train", stub)


def _outcome(argv: list[str], capsys) -> tuple[int | None, list[str]]:
    try:
        status = main(argv)
    except Reached:
        status = None
    except SystemExit as exc:
        status = exc.code
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return status, err.strip().splitlines()


@BOUNDED
@given(
    key=st.one_of(st.sampled_from(KEYS), st.text(max_size=12)),
    value=st.one_of(st.sampled_from(NASTY), st.text(max_size=30), st.integers().map(str), st.floats().map(str)),
)
def test_any_set_is_accepted_or_one_line_naming_the_set(key, value, capsys) -> None:
    with tempfile.TemporaryDirectory() as folder:
        config = Path(folder) / "exp.yaml"
        config.write_text(yaml.safe_dump(GOOD))
        text = f"{key}={value}"
        status, lines = _outcome(["train", str(config), "--storage", str(Path(folder) / "runs"), "--set", text], capsys)
        if status is None:
            return
        assert status == 2 and len(lines) == 1 and lines[0].startswith("rllib-conv: error: "), lines
        assert "--set" in lines[0], lines[0]
        assert not (Path(folder) / "runs").exists()


@BOUNDED
@given(
    content=st.one_of(
        st.binary(max_size=200),
        st.text(max_size=200).map(str.encode),
        st.dictionaries(
            st.sampled_from(KEYS + ["population"]), st.sampled_from(NASTY + ["bandit-s1-hand", "0.5", "3"]), max_size=5
        ).map(lambda d: yaml.safe_dump(d).encode()),
    )
)
def test_any_config_file_is_accepted_or_one_line_naming_the_file(content, capsys) -> None:
    with tempfile.TemporaryDirectory() as folder:
        config = Path(folder) / "exp.yaml"
        config.write_bytes(content)
        status, lines = _outcome(["train", str(config), "--storage", str(Path(folder) / "runs")], capsys)
        if status is None:
            return
        assert status == 2 and len(lines) == 1 and lines[0].startswith("rllib-conv: error: "), lines
        assert "exp.yaml" in lines[0], lines[0]
        assert not (Path(folder) / "runs").exists()
