"""The plan's `no_worse_margin`: declared in the plan file, checked, and written into plan.json for the report."""

from __future__ import annotations

import json

import pytest
import yaml

from analysis.loaders import read_plan
from analysis.report.verdicts import no_worse_margin
from rllib_conv.pipelines.plans import narrow, plan_for, read_plan_file, shipped_plan
from rllib_conv.pipelines.reproduce import Reproduction


def test_the_blocks_plan_declares_its_margin_and_the_others_take_the_default() -> None:
    assert plan_for("blocks").no_worse_margin == 0.2
    assert plan_for("bandit").no_worse_margin is None  # the report's default: 1% of the maximum score


def test_a_negative_margin_is_refused_naming_the_file_and_the_key(tmp_path) -> None:
    plan = yaml.safe_load(shipped_plan("blocks").read_text())
    plan["no_worse_margin"] = -0.5
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(plan))
    with pytest.raises(ValueError, match=r"plan\.yaml.*no_worse_margin"):
        read_plan_file(path)


@pytest.mark.parametrize(("game", "population", "margin"), [("blocks", "blocks-perm", 0.2), ("bandit", "bandit-s2-hand", 0.01)])
def test_the_report_reads_the_margin_the_run_declared(tmp_path, monkeypatch, game, population, margin) -> None:
    # No stage runs: the plan.json a run writes before its stages is what the report reads.
    monkeypatch.setattr(Reproduction, "stages", lambda self: [])
    Reproduction(narrow(plan_for(game), [population], ["agg"]), tmp_path, log=lambda _: None).run()
    written = json.loads((tmp_path / "plan.json").read_text())
    assert ("no_worse_margin" in written) == (game == "blocks")
    assert no_worse_margin(read_plan(tmp_path)) == pytest.approx(margin)
