"""Behaviour cloning (`training.behaviour_cloning`): it learns an obvious policy, deterministically, from our env's encoding.

Synthetic rows only: nothing here reads the human data (the pipeline's tests do, from a
temporary cache).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import torch

from rllib_conv.envs.overcooked import STAY, OvercookedEnv
from rllib_conv.envs.overcooked.encoding import CHANNEL
from rllib_conv.partners.trained import TrainedPolicyPartner
from rllib_conv.training import behaviour_cloning as bc

A_ACTION, B_ACTION = 2, 5


def two_kinds(rows: int = 600, dim: int = 12, seed: int = 0) -> bc.Steps:
    """Rows of two state kinds (feature 0 on: kind A, feature 1 on: kind B) plus noise; A -> action 2, B -> action 5."""
    rng = np.random.default_rng(seed)
    kind_b = rng.random(rows) < 0.5
    obs = rng.random((rows, dim)).astype(np.float32) * 0.5
    obs[:, 0] = ~kind_b
    obs[:, 1] = kind_b
    actions = np.where(kind_b, B_ACTION, A_ACTION).astype(np.int64)
    trial = np.arange(rows) // 100  # 6 trials of 100 steps, one seat
    return bc.Steps(obs, actions, trial, np.zeros(rows, dtype=np.int64), np.arange(rows) % 100)


def test_an_action_per_state_kind_is_learned_to_over_95_percent_on_fresh_rows() -> None:
    result = bc.train(two_kinds(), bc.BCSettings(epochs=20, stay="keep"), seed=0)
    fresh = two_kinds(seed=1)
    assert bc.accuracy(result.module, fresh)["accuracy"] > 0.95
    assert set(bc.predict(result.module, fresh.obs)) == {A_ACTION, B_ACTION}


def test_the_same_seed_gives_the_same_weights_and_another_seed_other_weights() -> None:
    settings = bc.BCSettings(epochs=3, stay="keep")
    first, again, other = (bc.train(two_kinds(), settings, seed=s).module.state_dict() for s in (7, 7, 8))
    assert all(torch.equal(first[k], again[k]) for k in first)
    assert not all(torch.equal(first[k], other[k]) for k in first)


def test_the_stay_rules_keep_every_row_the_first_stay_of_each_run_or_no_stay() -> None:
    # One seat's actions: a run of three stays, a move, a run of two stays; then the other seat starts with a stay.
    actions = np.array([STAY, STAY, STAY, 1, STAY, STAY, STAY])
    seat = np.array([0, 0, 0, 0, 0, 0, 1])
    t = np.array([0, 1, 2, 3, 4, 5, 0])
    steps = bc.Steps(np.zeros((7, 1), np.float32), actions, np.zeros(7, np.int64), seat, t)
    assert bc.stay_rows(steps, "keep").tolist() == [True] * 7
    assert np.flatnonzero(bc.stay_rows(steps, "collapse")).tolist() == [0, 3, 4, 6]
    assert np.flatnonzero(bc.stay_rows(steps, "drop")).tolist() == [3]
    with pytest.raises(ValueError, match="stay must be one of keep, collapse, drop"):
        bc.stay_rows(steps, "sometimes")


def test_dropping_stay_rows_means_the_clone_never_predicts_stay() -> None:
    steps = two_kinds()
    steps.actions[::2] = STAY  # half the rows are waits
    result = bc.train(steps, bc.BCSettings(epochs=5, stay="drop"), seed=0)
    assert bc.accuracy(result.module, steps)["predicted_stay"] == 0.0
    assert result.train_rows < len(steps) / 2 + 1


def test_held_out_trials_are_whole_trials_and_never_all_of_them() -> None:
    held = bc.holdout_trials(np.repeat(np.arange(8), 10), 0.15, seed=3)
    assert len(held) == 2 and set(held) <= set(range(8))
    assert bc.holdout_trials(np.zeros(10, np.int64), 0.15, seed=3) == []  # one trial: nothing to hold out
    assert bc.holdout_trials(np.repeat(np.arange(2), 5), 0.9, seed=0) in ([0], [1])


def test_logged_states_are_encoded_as_the_env_encodes_them_from_each_seat() -> None:
    env = OvercookedEnv("cramped_room")
    env.reset()
    state = env.state
    text = json.dumps(state.to_dict())
    # One trial of 42 logged steps per seat: the encoding's urgency flag marks the last 39 (fewer than 40 left).
    t = np.tile(np.arange(42), 2)
    frame = pd.DataFrame({"trial": 0, "seat": np.repeat([0, 1], 42), "t": t, "state": text, "action": 4})
    steps = bc.encode_trajectories(frame, "cramped_room")
    mine, theirs = env.encoder.encode(state)
    grids = env.encoder.unflatten(steps.obs).copy()
    urgency = grids[:, CHANNEL["urgency"]].max(axis=(1, 2))
    assert np.array_equal(urgency, (t >= 3).astype(np.float32))
    grids[:, CHANNEL["urgency"]] = 0.0
    assert all(np.array_equal(g.reshape(-1), mine) for g in grids[:42])
    assert all(np.array_equal(g.reshape(-1), theirs) for g in grids[42:])
    assert not np.array_equal(mine, theirs)  # each seat sees itself first
    with pytest.raises(ValueError, match=r"lack the columns \['action'\]"):
        bc.encode_trajectories(frame.drop(columns=["action"]), "cramped_room")


def test_a_saved_clone_loads_as_a_trained_partner_and_acts_as_the_module(tmp_path) -> None:
    result = bc.train(two_kinds(dim=8), bc.BCSettings(epochs=5, stay="keep"), seed=0)
    folder = bc.save(result, tmp_path / "clone")
    assert json.loads((folder / "bc.json").read_text())["seed"] == 0
    partner = TrainedPolicyPartner("clone", str(folder), greedy=True)
    fresh = two_kinds(dim=8, seed=2)
    mask = np.ones((len(fresh), 6), dtype=np.int8)
    assert np.array_equal(partner.act_batch(fresh.obs, mask), bc.predict(result.module, fresh.obs))


@pytest.mark.parametrize(
    "field, value, message",
    [("stay", "never", "stay must be one of"), ("epochs", 0, "epochs must be a positive integer"), ("lr", 0.0, "lr must be > 0")],
)
def test_bad_settings_are_one_clear_error(field: str, value, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        bc.BCSettings(**{field: value})


def test_no_rows_is_one_clear_error() -> None:
    empty = two_kinds().take(np.zeros(600, dtype=bool))
    with pytest.raises(ValueError, match="at least one row"):
        bc.train(empty)
