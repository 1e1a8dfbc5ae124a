"""A report's inputs archived beside it (`analysis.archive`), and every committed report rebuilt from its archive.

Known answer: a report built from its own `data/` folder is the same report, byte for byte,
apart from the line that says when and from where it was built.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from analysis.archive import DATA_DIR, report_inputs
from analysis.report import build_report

FIXTURE = Path(__file__).parent / "fixtures" / "repro"
RESULTS = Path(__file__).parents[2] / "benchmarks" / "results"


def _body(report: Path) -> list[str]:
    """The report's lines without the one naming when and from which folder it was built."""
    return [line for line in report.read_text().splitlines() if not line.startswith("Built by `python -m analysis")]


def test_the_archive_holds_every_table_and_trial_file_and_no_checkpoint(tmp_path: Path) -> None:
    report = build_report(FIXTURE, tmp_path / "out")
    data = report.parent / DATA_DIR
    copied = sorted(p.relative_to(data) for p in data.rglob("*") if p.is_file())
    assert copied == sorted(relative for _, relative in report_inputs(FIXTURE))
    names = {p.name for p in copied}
    assert {"plan.json", "config.yaml", "eval.json", "progress.csv"} <= names
    assert any(p.parts[1] == "adaptation" for p in copied) and not any("checkpoint" in str(p) for p in copied)
    assert sum((data / p).stat().st_size for p in copied) < 5_000_000


def test_a_report_rebuilt_from_its_archive_is_the_same_report(tmp_path: Path) -> None:
    first = build_report(FIXTURE, tmp_path / "first")
    again = build_report(first.parent / DATA_DIR, tmp_path / "again")
    assert _body(again) == _body(first)
    # Rebuilding in place leaves the archive as it was: it is the report's input, never overwritten by itself.
    before = sorted((p, p.read_bytes()) for p in (first.parent / DATA_DIR).rglob("*") if p.is_file())
    build_report(first.parent / DATA_DIR, first.parent)
    assert sorted((p, p.read_bytes()) for p in (first.parent / DATA_DIR).rglob("*") if p.is_file()) == before


def _committed() -> list[Path]:
    return sorted(p.parent for p in RESULTS.glob("*/report.md"))


def test_every_committed_report_has_its_data_command_and_commit() -> None:
    # Reports once committed without their data (issue 45) were re-run or moved out of benchmarks/results/ (2026-12-07).
    assert [p.name for p in _committed() if not (p / DATA_DIR).is_dir()] == []
    for folder in _committed():
        command = (folder / "COMMAND").read_text()
        assert "rllib-conv reproduce" in command and "code " in command, folder


@pytest.mark.parametrize("folder", _committed(), ids=lambda p: p.name)
def test_a_committed_report_rebuilds_from_its_committed_data(folder: Path, tmp_path: Path) -> None:
    again = build_report(folder / DATA_DIR, tmp_path / "again")
    assert _body(again) == _body(folder / "report.md")
