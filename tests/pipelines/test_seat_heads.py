"""The modular ego with one head per (partner seat, partner) (`model.heads: seat`) in a game of three seats: its layout,
a tiny training run whose saved team heads are sums of its saved seat heads, its adaptation to a held-out team, and to
teams with members it trained with (`head_init: known-seats`)."""

from __future__ import annotations

import shutil

import pandas as pd
import pytest
import torch
import yaml

from rllib_conv.cli import main
from rllib_conv.common.config_files import checked
from rllib_conv.common.run_folders import SEAT_HEADS_DIR, trial_folders
from rllib_conv.common.sealed import seal
from rllib_conv.modules.packed.ego_stack import summed_head_state
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.partners.trained import load_rl_module
from rllib_conv.pipelines.adapt import adapt_curve, known_seat_heads, run_adaptations
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.training.algorithm import Replica, build_algorithm
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.ego_setup import resolve, setup_for
from rllib_conv.training.evaluate import load_module
from rllib_conv.training.experiment import ExperimentConfig, trial_config
from rllib_conv.training.settings import ModelSettings
from rllib_conv.training.weights import learner_module

pytest.importorskip("lbforaging")

SEATS = {"model": {"heads": "seat"}}


def test_seat_heads_hold_the_weights_and_each_team_head_adds_one_per_seat() -> None:
    setup = resolve(ExperimentConfig(population="lbf-heuristics", **SEATS))
    assert setup.seat_heads and setup.head_ids == ["ego@H1+H1", "ego@H1+H2", "ego@H2+H1", "ego@H2+H2"]
    assert setup.weight_heads == ["ego@player_1=H1", "ego@player_1=H2", "ego@player_2=H1", "ego@player_2=H2"]
    assert setup.head_members == [[0, 2], [0, 3], [1, 2], [1, 3]]
    # A new team (adaptation): one fresh head per seat, even where one partner sits in both.
    new = setup_for(setup.exp, setup.population, setup.population.entries("test"), team=("H3", "H3"))
    assert new.weight_heads == ["ego@player_1=H3", "ego@player_2=H3"] and new.head_members == [[0, 1]]
    # Team heads (the default), a single head, and a game of two seats: each head holds its own weights.
    team = resolve(ExperimentConfig(population="lbf-heuristics"))
    assert not team.seat_heads and team.weight_heads == team.head_ids and team.head_members == [[0], [1], [2], [3]]
    assert resolve(ExperimentConfig(population="lbf-heuristics", method="agg", **SEATS)).weight_heads == ["ego"]
    two = resolve(ExperimentConfig(population="blocks-perm", **SEATS))
    assert not two.seat_heads and two.weight_heads == two.head_ids


@pytest.mark.slow
def test_an_ego_with_seat_heads_trains_saves_them_and_their_sums_and_adapts_to_new_and_to_known_members(
    ray_session, tmp_path
) -> None:
    config = tmp_path / "seats.yaml"
    tiny = {"name": "seats", "population": "lbf-heuristics", "model": {"hidden": 8, "heads": "seat"}}
    config.write_text(yaml.safe_dump({**tiny, "ppo": {"rollout_per_partner": 50, "num_epochs": 1}, "run": {"timesteps": 400}}))
    assert main(["train", str(config), "--storage", str(tmp_path / "runs")]) == 0
    (trial,) = trial_folders(tmp_path / "runs" / "seats")
    module = load_module(last_checkpoint(trial))
    heads = {mid: module[mid] for mid in module.head_ids()}
    assert sorted(heads) == ["ego@H1+H1", "ego@H1+H2", "ego@H2+H1", "ego@H2+H2"]
    assert all(h.pi[0].weight.shape == (16, 8) for h in heads.values())  # saved as one head, two seat heads wide
    # Sums of seat heads: (1=H1 + 2=H1) + (1=H2 + 2=H2) = (1=H1 + 2=H2) + (1=H2 + 2=H1), for policy and value alike;
    # heads trained apart (`model.heads: team`) would not satisfy it.
    z = torch.randn(32, 8, generator=torch.Generator().manual_seed(0))
    for part in ("pi", "vf"):
        out = {mid: getattr(h, part)(z).detach() for mid, h in heads.items()}
        torch.testing.assert_close(out["ego@H1+H1"] + out["ego@H2+H2"], out["ego@H1+H2"] + out["ego@H2+H1"])
        assert not torch.allclose(out["ego@H1+H1"], out["ego@H1+H2"])
    # The seat heads are saved too, and each team head is exactly the sum of its seats' saved heads.
    seat_heads = {p.name: load_rl_module(p).state_dict() for p in (last_checkpoint(trial) / SEAT_HEADS_DIR).iterdir()}
    assert sorted(seat_heads) == ["ego@player_1=H1", "ego@player_1=H2", "ego@player_2=H1", "ego@player_2=H2"]
    summed = summed_head_state([seat_heads["ego@player_1=H2"], seat_heads["ego@player_2=H1"]])
    for name, tensor in heads["ego@H2+H1"].state_dict().items():
        assert torch.equal(summed[name], tensor), name

    base = {"runs": [str(trial)], "every": 50, "steps": 100, "episodes": 4, "ppo": {"num_epochs": 1, "minibatch_size": 25}}
    fresh = checked({**base, "name": "fresh", "partners": ["H3+H4"]}, AdaptConfig)
    plastic = checked({**base, "name": "plastic", "partners": ["H4"], "head_init": "plastic"}, AdaptConfig)
    known = checked({**base, "name": "known", "partners": ["H2+H3"], "head_init": "known-seats"}, AdaptConfig)
    run_adaptations([fresh, plastic, known], out=tmp_path / "out", storage=tmp_path / "adapt-runs")
    for name, team in (("fresh", "H3+H4"), ("plastic", "H4+H4"), ("known", "H2+H3")):
        curves = pd.read_csv(tmp_path / "out" / f"{name}.csv")
        assert curves["partner"].unique().tolist() == [team] and curves["steps"].tolist()[0] == 0
        assert curves["steps"].max() >= 100 and curves["mean_return"].between(0.0, 1.0).all()

    cfg = AdaptConfig(runs=[str(trial)], head_init="known-seats")

    # Both members known (a training team): the adapting team head starts as the trained team head, weight for weight.
    both = adapt_curve(cfg, str(trial), "H2+H1")
    assert sorted(both.load) == ["ego@player_1=H2", "ego@player_2=H1", "task"]
    # One known: its seat head kept, the new member's fresh (seeded as `fresh` seeds it).
    one = adapt_curve(cfg, str(trial), "H3+H1")
    assert sorted(one.load) == ["ego@player_2=H1", "task"]
    fresh = adapt_curve(AdaptConfig(runs=[str(trial)]), str(trial), "H3+H1")
    algo = build_algorithm([Replica(both.setup, both.load), Replica(one.setup, one.load), Replica(fresh.setup, fresh.load)])
    try:
        stack = learner_module(algo)[STACK_ID]
        for name, tensor in module["ego@H2+H1"].state_dict().items():
            assert torch.equal(stack.head_state(0, 0)[name], tensor), name
        saved = load_rl_module(one.load["ego@player_2=H1"]).state_dict()
        for name, tensor in saved.items():
            assert torch.equal(stack.weight_head_state(1, 1)[name], tensor), name
            assert torch.equal(stack.weight_head_state(1, 0)[name], stack.weight_head_state(2, 0)[name]), name
            assert not torch.equal(stack.weight_head_state(2, 1)[name], tensor), name
    finally:
        algo.stop()

    # A team it knows no member of (in those seats), and an ego with team heads, are refused by name.
    with pytest.raises(ValueError, match=r"no member of team 'H3\+H4' trained with the ego in .* use head_init fresh"):
        adapt_curve(cfg, str(trial), "H3+H4")
    as_team = trial_config(trial).model_copy(update={"model": ModelSettings(hidden=8)})
    with pytest.raises(
        ValueError,
        match="known-seats' starts from the seat heads of an ego trained with model.heads: seat in a game of more than two seats.*team heads",
    ):
        known_seat_heads(last_checkpoint(trial), as_team, one.setup)
    two_seats = resolve(ExperimentConfig(population="blocks-perm", **SEATS))
    with pytest.raises(ValueError, match="plays a game of one partner seat"):
        known_seat_heads(last_checkpoint(trial), trial_config(trial), two_seats)
    older = tmp_path / "older"
    shutil.copytree(trial, older)
    checkpoint = older / last_checkpoint(trial).name
    shutil.rmtree(checkpoint / SEAT_HEADS_DIR)
    seal(checkpoint)  # as an ego exported before seat heads were saved apart
    with pytest.raises(ValueError, match=r"keeps no seat heads \(trained before they were saved apart: train it again\)"):
        known_seat_heads(checkpoint, trial_config(older), one.setup)
