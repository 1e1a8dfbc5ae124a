"""The 2019 human-human Overcooked data: fetched from the registry, loaded through the shim, converted, replayed exactly.

The data tests download the `overcooked-ai==1.1.0` sdist (2.3 MB) into a temporary cache
once per session: where the registry cannot be reached they fail (the fixture raises), they
do not skip. The known-answer test replays every logged trial through `OvercookedEnv`:
from the first logged state, each logged joint action gives the logged next state (players
and objects) and the sparse reward the logged score implies (20 per soup, logged as 5).
"""

from __future__ import annotations

import json
import pickle
import subprocess
from pathlib import Path

import pandas as pd
import pytest
from overcooked.mdp.overcooked_mdp import OvercookedState

from rllib_conv.cli import main
from rllib_conv.envs.overcooked import human_data as hd
from rllib_conv.envs.overcooked.env import ACTIONS, CLASSIC_LAYOUTS, INTERACT, NORTH, STAY, WEST, OvercookedEnv, build_mdp

# Upstream's 2019 split, counted here from the pickles (rows = logged steps = trials x ~1 200).
TRIALS = {
    "train": {"cramped_room": 8, "asymmetric_advantages": 9, "coordination_ring": 8, "random0": 6, "random3": 8},
    "test": {"cramped_room": 8, "asymmetric_advantages": 8, "coordination_ring": 8, "random0": 6, "random3": 7},
}
ROWS = {"train": 46_729, "test": 44_373}


@pytest.fixture(scope="session")
def cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A cache folder holding the fetched pickles and cramped_room's converted trajectories."""
    folder = tmp_path_factory.mktemp("overcooked-cache")
    hd.fetch(folder)  # needs the registry: a RuntimeError here fails every data test
    hd.convert(folder, ["cramped_room"])
    return folder


# --- without the data -------------------------------------------------------------------------------


def test_the_cache_folder_is_the_argument_then_the_environment_variable_then_the_home_cache(monkeypatch, tmp_path) -> None:
    monkeypatch.delenv(hd.CACHE_ENV, raising=False)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert hd.cache_folder() == tmp_path / "home" / ".cache" / "rllib-conv" / "overcooked"
    monkeypatch.setenv(hd.CACHE_ENV, str(tmp_path / "root"))
    assert hd.cache_folder() == tmp_path / "root" / "overcooked"
    assert hd.cache_folder(tmp_path / "mine") == tmp_path / "mine"


def test_the_unpickler_maps_the_removed_pandas_index_and_numpy_core() -> None:
    # Protocol-0 GLOBAL opcodes: exactly what the 2019 pickles name.
    old_index = b"cpandas.core.indexes.numeric\nInt64Index\n."
    old_numpy = b"cnumpy.core.multiarray\n_reconstruct\n."
    with pytest.raises((ModuleNotFoundError, AttributeError)):
        pickle.loads(old_index)  # pandas 2+ has no Int64Index: why the shim exists
    import io

    import numpy as np

    assert hd.HumanDataUnpickler(io.BytesIO(old_index)).load() is pd.Index
    assert hd.HumanDataUnpickler(io.BytesIO(old_numpy)).load() is np._core.multiarray._reconstruct


def test_a_logged_state_becomes_the_json_that_the_mdp_reads() -> None:
    logged = (
        "{'players': [{'position': [1, 2], 'orientation': [0, -1]}, {'position': [3, 1], 'orientation': [1, 0], "
        "'held_object': {'name': 'soup', 'position': [3, 1], 'state': ['onion', 3, 20]}}], "
        "'objects': {'2,0': {'name': 'soup', 'position': [2, 0], 'state': ['onion', 2, 0]}, "
        "'0,1': {'name': 'onion', 'position': [0, 1]}}, 'order_list': ['onion'], 'pot_explosion': False}"
    )
    state = hd.normalise_state(logged)
    assert state == {
        "players": [
            {"position": [1, 2], "orientation": [0, -1], "held_object": None},
            {
                "position": [3, 1],
                "orientation": [1, 0],
                "held_object": {"name": "soup", "position": [3, 1], "state": ["onion", 3, 20]},
            },
        ],
        "objects": [{"name": "onion", "position": [0, 1]}, {"name": "soup", "position": [2, 0], "state": ["onion", 2, 0]}],
    }
    build_mdp("cramped_room")  # the package configures recipes when an MDP is built; a cooked soup needs them
    mdp_state = OvercookedState.from_dict(json.loads(json.dumps(state)))
    assert mdp_state.players[1].held_object.is_ready and len(mdp_state.objects[(2, 0)].ingredients) == 2
    assert mdp_state.players[0].orientation == (0, -1) and mdp_state.timestep == 0


def test_logged_joint_actions_become_indices_into_the_envs_actions() -> None:
    assert hd.action_indices("[[0, -1], 'INTERACT']") == (NORTH, INTERACT)
    assert hd.action_indices("[[0, 0], [-1, 0]]") == (STAY, WEST)
    assert ACTIONS[STAY] == (0, 0)
    with pytest.raises(ValueError, match="unknown action"):
        hd.action_indices("[[2, 0], [0, 0]]")
    with pytest.raises(ValueError, match="expected 2 actions"):
        hd.action_indices("[[0, 0]]")


def test_the_data_layouts_are_carrolls_five() -> None:
    assert sorted(hd.LAYOUTS) == sorted(CLASSIC_LAYOUTS)
    with pytest.raises(ValueError, match="layout must be one of"):
        hd.trajectory_path("random0", "train")  # the data's old name is not a layout of ours
    with pytest.raises(ValueError, match="split must be one of"):
        hd.trajectory_path("cramped_room", "valid")


def test_an_unreachable_registry_is_one_clear_error(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("PIP_INDEX_URL", "http://127.0.0.1:9/simple")
    monkeypatch.setenv("PIP_EXTRA_INDEX_URL", "")
    monkeypatch.setenv("PIP_FIND_LINKS", "")
    monkeypatch.setenv("PIP_RETRIES", "0")
    monkeypatch.setenv("PIP_TIMEOUT", "2")
    with pytest.raises(RuntimeError, match=r"could not download overcooked-ai==1\.1\.0 from the package registry"):
        hd.fetch(tmp_path)
    assert not list((tmp_path / "human_data").glob("*.pickle"))


# --- with the data ----------------------------------------------------------------------------------


def test_a_second_fetch_downloads_nothing_and_checks_the_digests(cache: Path, monkeypatch) -> None:
    def no_download(*args, **kwargs):
        raise AssertionError("fetch ran a subprocess although the pickles are cached")

    monkeypatch.setattr(subprocess, "run", no_download)
    paths = hd.fetch(cache)
    assert paths == {split: cache / "human_data" / f"clean_{split}_trials.pickle" for split in hd.SPLITS}


def test_a_changed_pickle_is_refused_by_its_digest(cache: Path, tmp_path: Path) -> None:
    copy = tmp_path / "human_data"
    copy.mkdir()
    for split in hd.SPLITS:
        (copy / f"clean_{split}_trials.pickle").write_bytes((cache / "human_data" / f"clean_{split}_trials.pickle").read_bytes())
    with open(copy / "clean_test_trials.pickle", "ab") as f:
        f.write(b"\0")
    with pytest.raises(ValueError, match=r"clean_test_trials\.pickle: SHA-256 is not the recorded"):
        hd.fetch(tmp_path)


def test_the_pickles_hold_upstreams_split(cache: Path) -> None:
    for split in hd.SPLITS:
        frame = hd.load_trials(split, cache)
        assert len(frame) == ROWS[split]
        assert frame.groupby("layout_name")["workerid_num"].nunique().to_dict() == TRIALS[split]
    # No pair of people plays a layout in both splits (the human proxy meets people BC never saw).
    train, test = (hd.load_trials(s, cache).groupby("layout_name")["workerid_num"].unique() for s in hd.SPLITS)
    assert all(not set(train[layout]) & set(test[layout]) for layout in train.index)


def test_cramped_room_trajectories_have_the_documented_columns_and_both_seats(cache: Path) -> None:
    frame = hd.trajectories("cramped_room", "train", cache)
    assert list(frame.columns) == list(hd.COLUMNS)
    assert frame["trial"].nunique() == 8 and len(frame) == 2 * 9_564
    seats = [part.reset_index(drop=True) for _, part in frame.groupby("seat")]
    # The two seats are one game seen from each side.
    assert (seats[0]["action"] == seats[1]["partner_action"]).all() and (seats[0]["state"] == seats[1]["state"]).all()
    for _, trial in seats[0].groupby("trial"):
        assert list(trial["t"]) == list(range(len(trial))) and trial["done"].sum() == 1 and trial["done"].iloc[-1]
        # The logged states chain: the next row starts where this one ended.
        assert (trial["state"].iloc[1:].to_numpy() == trial["next_state"].iloc[:-1].to_numpy()).all()
        # Rewards are 20 per soup and add up to the final logged score (5 per soup).
        assert set(trial["reward"]) <= {0.0, 20.0} and trial["reward"].sum() == trial["score"].iloc[-1] * 4
    assert set(frame["action"]) <= set(range(len(ACTIONS)))


def test_stay_is_most_of_the_logged_cramped_room_actions(cache: Path) -> None:
    table = hd.summary(cache, ["cramped_room"]).set_index(["split", "seat"])
    assert table.loc[("train", 0), "stay"] == pytest.approx(0.697, abs=0.001)
    assert table.loc[("train", 1), "stay"] == pytest.approx(0.750, abs=0.001)
    assert table.loc[("train", 0), "trials"] == 8 and table.loc[("test", 1), "steps"] == 9_626


def test_the_cli_fetches_converts_and_prints_the_summary(cache: Path, capsys) -> None:
    assert main(["human-data", "overcooked", "--cache", str(cache), "--layouts", "cramped_room"]) == 0
    out = capsys.readouterr().out
    assert "cramped_room" in out and "0.697" in out and "0.750" in out
    assert str(cache / "trajectories") in out


def test_the_cli_refuses_an_unknown_layout_with_exit_2(cache: Path, capsys) -> None:
    assert main(["human-data", "overcooked", "--cache", str(cache), "--layouts", "random0"]) == 2
    assert "--layouts: unknown layout 'random0'" in capsys.readouterr().err


def _object_key(state: OvercookedState) -> list[tuple]:
    # SoupState.__eq__ zips the ingredient lists, so a 2-onion pot would equal a 3-onion one: compare whole.
    return sorted(
        (o.name, o.position, tuple(sorted(getattr(o, "ingredients", []))), getattr(o, "_cooking_tick", None))
        for o in state.objects.values()
    )


def replay(layout: str, split: str, cache: Path) -> int:
    """Replay every trial of one layout's split through OvercookedEnv; assert each step; return the steps replayed."""
    frame = hd.trajectories(layout, split, cache)
    steps = 0
    for trial, rows in frame[frame["seat"] == 0].groupby("trial"):
        env = OvercookedEnv(layout=layout, horizon=len(rows) + 1)  # the 2019 rounds outlast our 400-step episodes
        env.reset(options={"state": OvercookedState.from_dict(json.loads(rows["state"].iloc[0]))})
        for t, (after, action, partner, reward) in enumerate(
            zip(rows["next_state"], rows["action"], rows["partner_action"], rows["reward"])
        ):
            _, _, _, truncated, infos = env.step({"player_0": int(action), "player_1": int(partner)})
            logged, replayed = OvercookedState.from_dict(json.loads(after)), env.state
            where = f"{layout} {split} trial {trial} step {t}"
            assert replayed.players == logged.players, where
            assert _object_key(replayed) == _object_key(logged), where
            assert infos["player_0"]["sparse_reward"] == infos["player_1"]["sparse_reward"] == reward, where
            assert not truncated["player_0"], where
        steps += len(rows)
    return steps


def test_every_cramped_room_train_trial_replays_exactly_through_the_env(cache: Path) -> None:
    assert replay("cramped_room", "train", cache) == 9_564


@pytest.mark.slow  # about a minute on 2 cores: converts and replays 76 trials
def test_every_trial_of_every_layout_and_split_replays_exactly(cache: Path) -> None:
    hd.convert(cache)
    steps = {split: sum(replay(layout, split, cache) for layout in hd.LAYOUTS) for split in hd.SPLITS}
    assert steps == ROWS
