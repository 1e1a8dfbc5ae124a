"""Adapting an ego of a game of three seats (Level-Based Foraging) to held-out teams: fresh head and PLASTIC."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from rllib_conv import partners
from rllib_conv.adaptation.registry import check_seats
from rllib_conv.cli import main
from rllib_conv.common.config_files import checked
from rllib_conv.partners.population import parse_team
from rllib_conv.pipelines.adapt import CURVE_COLUMNS, adaptation_curves, run_adaptations
from rllib_conv.pipelines.adapt_config import AdaptConfig

pytest.importorskip("lbforaging")


def test_a_new_partner_is_a_team_one_name_per_seat_or_one_for_every_seat() -> None:
    pop = partners.get("lbf-heuristics")
    assert parse_team(pop, "H3+H4") == ("H3", "H4") and parse_team(pop, "H3") == ("H3", "H3")
    with pytest.raises(ValueError, match=r"partners: 'H3\+H4\+H1' names 3 partners, but population 'lbf-heuristics' has 2"):
        parse_team(pop, "H3+H4+H1")
    with pytest.raises(ValueError, match=r"partners: population 'lbf-heuristics' has no partner\(s\) \['H9'\]"):
        parse_team(pop, "H3+H9")


@pytest.mark.parametrize("start", ["pick", "posterior", "lookup", "counts-planner", "prior-planner"])
def test_what_adapts_one_partners_heads_is_refused_with_three_seats_and_allowed_with_two(start: str) -> None:
    check_seats(start, "blocks", 2)
    with pytest.raises(ValueError, match=f"head_init '{start}' adapts to one partner in a game of two seats; 'lbf' has 3"):
        check_seats(start, "lbf", 3)
    for allowed in ("fresh", "plastic", "guard"):
        check_seats(allowed, "lbf", 3)


@pytest.mark.slow
def test_a_three_seat_ego_adapts_to_held_out_teams_fresh_guarded_from_scratch_and_by_plastic(lbf_ego: Path, tmp_path) -> None:
    run = str(lbf_ego)
    base = {"runs": [run], "every": 50, "steps": 100, "episodes": 4, "ppo": {"num_epochs": 1, "minibatch_size": 25}}
    fresh = checked({**base, "name": "fresh", "partners": ["H3+H4"], "guard": True}, AdaptConfig)
    scratch = checked({**base, "name": "scratch", "partners": ["H4"], "method": "scratch"}, AdaptConfig)
    plastic = checked({**base, "name": "plastic", "partners": ["H4", "H3+H4"], "head_init": "plastic"}, AdaptConfig)
    # By default every team of the held-out split.
    assert [p["partner"] for p in adaptation_curves(fresh.first.model_copy(update={"partners": None}))] == [
        "H3+H3",
        "H3+H4",
        "H4+H3",
        "H4+H4",
    ]
    tables = run_adaptations([fresh, scratch, plastic], out=tmp_path / "out", storage=tmp_path / "runs")
    for name, partners_ in (("fresh", ["H3+H4"]), ("scratch", ["H4+H4"]), ("plastic", ["H3+H4", "H4+H4"])):
        curves = pd.read_csv(tmp_path / "out" / f"{name}.csv")
        assert len(curves) == len(tables[name]) and set(CURVE_COLUMNS) <= set(curves.columns)
        assert sorted(curves["partner"].unique()) == partners_
        assert (curves["method"] == ("scratch" if name == "scratch" else "modular")).all()
        for _, curve in curves.groupby("partner"):
            steps = curve["steps"].tolist()  # evaluated before every update (of at least 50 env steps), to the end
            assert len(steps) == 3 and steps[0] == 0 and steps[1] >= 50 and steps[2] >= 100
            assert curve["mean_return"].between(0.0, 1.0).all() and curve["stderr"].notna().all()
    # The packs' own tables say what each point played: the guard whether it kept the ego before any update (it
    # does at the start), PLASTIC which trained head, for a team of training partners: the first team's before any
    # evidence, then the belief's.
    packs = pd.concat([pd.read_csv(f) for f in (tmp_path / "runs").glob("adapt-stage-*/AdaptTrainable_*/curves.csv")])
    guarded = packs.dropna(subset=["prior_kept"]).sort_values("steps")
    assert guarded["partner"].tolist() == ["H3+H4"] * 3 and bool(guarded["prior_kept"].iloc[0])
    picked = packs.dropna(subset=["picked"])
    assert len(picked) == 2 * 3 and sorted(picked["partner"].unique()) == ["H3+H4", "H4+H4"]
    assert set(picked["picked"]) <= {"ego@H1+H1", "ego@H1+H2", "ego@H2+H1", "ego@H2+H2"}
    assert (picked.query("steps == 0")["picked"] == "ego@H1+H1").all()


@pytest.mark.slow
@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--head-init", "pick"], "head_init 'pick' adapts to one partner in a game of two seats; 'lbf' has 3"),
        (["--head-init", "posterior"], "head_init 'posterior' adapts to one partner in a game of two seats; 'lbf' has 3"),
        (["--partner", "H3+H4+H3"], "names 3 partners, but population 'lbf-heuristics' has 2 partner seats"),
    ],
)
def test_what_three_seats_cannot_do_is_refused_naming_it_and_writes_nothing(lbf_ego: Path, tmp_path, capsys, args, message):
    out, storage = tmp_path / "out", tmp_path / "runs"
    assert main(["adapt", str(lbf_ego), "--out", str(out), "--storage", str(storage), *args]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists() and not storage.exists()
