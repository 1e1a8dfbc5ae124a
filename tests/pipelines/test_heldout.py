"""The held-out evaluation (`pipelines/heldout.py`), its plan keys (`plans.HeldoutSpec`, `adapt_to`) and its report section.

Known answers on the bandit: a hand-designed convention coordinates perfectly with itself
(return 1 in every episode) and, with 4 good arms per context on `bandit-s0-hand`, never with
a member whose arm differs in every context.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from analysis.report.context import Context
from analysis.report.sections.heldout import heldout_section
from rllib_conv import partners
from rllib_conv.common.resources import config_file
from rllib_conv.partners.population import Population
from rllib_conv.pipelines.heldout import HELDOUT_COLUMNS, HeldoutAgent, members_agent, play_heldout
from rllib_conv.pipelines.plans import plan_for

POP = "bandit-s2-hand"


def test_members_score_one_with_themselves_and_each_pairing_is_one_row() -> None:
    pop = partners.get(POP)
    table = play_heldout([members_agent("hand", pop)], pop, episodes=50)
    assert list(table.columns) == HELDOUT_COLUMNS
    n = len(pop.partners)
    assert len(table) == n * n and sorted(table["seed"].unique()) == list(range(n))  # scripted: the member's place
    same = table[table["player"] == table["partner"]]
    assert len(same) == n and np.allclose(same["mean_return"], 1.0) and np.allclose(same["stderr"], 0.0)
    # Members whose conventions differ do worse: a convention is not a best response to another.
    assert table.loc[table["player"] != table["partner"], "mean_return"].mean() < 1.0


def test_with_three_seats_each_player_meets_every_team_of_the_held_out_members() -> None:
    types, heldout = partners.get("lbf-heuristics"), partners.get("lbf-heldout-types")  # H1-H4; H3 and H4
    table = play_heldout([members_agent("types", types)], heldout, episodes=3)
    teams = ["H3+H3", "H3+H4", "H4+H3", "H4+H4"]
    assert table["partner"].tolist() == teams * 4 and table["player"].tolist() == [
        p for p in ("H1", "H2", "H3", "H4") for _ in teams
    ]
    assert table["mean_return"].between(0.0, 1.0).all() and table["mean_return"].max() > 0.0  # shares of the food


def test_an_agent_trained_for_the_other_seat_and_a_zero_episode_count_are_refused() -> None:
    pop = partners.get(POP)
    other_seat = next(a for a in ("player_0", "player_1") if a != pop.partner_agent)
    agent = HeldoutAgent("x", members_agent("x", pop).players, other_seat)
    with pytest.raises(ValueError, match=r"agent 'x' was trained with its partner in seat"):
        play_heldout([agent], pop, episodes=2)
    with pytest.raises(ValueError, match="episodes must be at least 1"):
        play_heldout([], pop, episodes=0)


def _plan_file(tmp_path: Path, edit) -> Path:
    raw = yaml.safe_load(config_file("plan_overcooked.yaml").read_text())
    edit(raw)
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(raw))
    return path


def test_the_shipped_overcooked_plan_declares_the_anchor_and_adapts_to_the_human_proxies() -> None:
    plan = plan_for("overcooked")
    assert plan.heldout is not None and plan.heldout.partners == "overcooked-cramped_room-hproxy"
    assert set(plan.heldout.agents) == {"PPO_SP", "PPO_BC", "BC"} and plan.heldout.claims == [("PPO_BC", "PPO_SP")]
    assert plan.adapt_to["overcooked-cramped_room-cooks"] == ["overcooked-cramped_room-hproxy"]


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda r: r["full"]["heldout"].update(claims=[["PPO_BC", "PPO_XX"]]), r"claims: \['PPO_XX'\] are not agents"),
        (lambda r: r["full"]["heldout"]["agents"].update(X={"members": "a", "selfplay": "b"}), "exactly one of selfplay"),
        (lambda r: r["full"]["heldout"]["agents"].update(X={"trained": "agg"}), "`trained` and `population` go together"),
        (lambda r: r["full"]["heldout"]["agents"].update(X={"selfplay": "nope"}), "'nope' is not a self-play population"),
        (
            lambda r: r["full"]["heldout"]["agents"].update(X={"trained": "maml", "population": "overcooked-cramped_room-bc"}),
            "the plan trains no 'maml' on 'overcooked-cramped_room-bc'",
        ),
        (lambda r: r["full"]["adapt_to"].update(nowhere=["x"]), r"full.adapt_to: \['nowhere'\] not defined"),
        (
            lambda r: r["full"]["populations"]["overcooked-cramped_room-bc"].append("agg"),
            "'agg' egos of 'overcooked-cramped_room-(bc|cooks)' and '.*' would both adapt to 'overcooked-cramped_room-hproxy'",
        ),
    ],
)
def test_a_bad_heldout_or_adapt_to_key_is_one_error_naming_it(tmp_path: Path, edit, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        plan_for("overcooked", path=_plan_file(tmp_path, edit))


def _context(tmp_path: Path, rows: list[list], claims: list[list[str]]) -> Context:
    game = tmp_path / "root" / "overcooked"
    game.mkdir(parents=True)
    (game / "plan.json").write_text(pd.Series({"game": "overcooked", "heldout": {"partners": "hp", "claims": claims}}).to_json())
    pd.DataFrame(rows, columns=HELDOUT_COLUMNS).to_csv(game / "heldout.csv", index=False)
    return Context(tmp_path / "root", tmp_path / "out", None)


def test_the_section_averages_partners_per_seed_and_judges_the_declared_claim_by_welch(tmp_path: Path) -> None:
    # A: seeds 0-2 score 100, 110, 120 (each the mean of two partners); B: 40, 50, 60.
    rows = []
    for agent, base in (("A", 100.0), ("B", 40.0)):
        for seed in range(3):
            for partner, shift in (("p0", -5.0), ("p1", 5.0)):
                rows.append([agent, seed, f"{agent}{seed}", partner, 20, base + 10 * seed + shift, 1.0])
    text = heldout_section(_context(tmp_path, rows, [["A", "B"]]))
    assert "| A | 110.0 [85.2, 134.8] (n=3) |" in text  # mean 110, sd 10, t(0.975, 2) = 4.303: 10 * 4.303 / sqrt(3) = 24.8
    assert "| A beats B | supported | A − B +60.0 [" in text
    reverse = heldout_section(_context(tmp_path / "r", rows, [["B", "A"]]))
    assert "| B beats A | contradicted |" in reverse


def test_no_heldout_file_says_so(tmp_path: Path) -> None:
    (tmp_path / "root" / "bandit").mkdir(parents=True)
    assert "No held-out evaluation" in heldout_section(Context(tmp_path / "root", tmp_path / "out", None))


def test_a_population_folder_works_as_the_held_out_set(tmp_path: Path) -> None:
    pop = partners.get(POP)
    pop.save(tmp_path / "pop" / "population.json")
    again = Population.load(tmp_path / "pop" / "population.json")
    table = play_heldout([members_agent("hand", pop)], again, episodes=5)
    assert len(table) == len(pop.partners) ** 2
