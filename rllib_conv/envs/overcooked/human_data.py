"""The 2019 human-human Overcooked trials (Carroll et al., NeurIPS 2019): fetched, converted into trajectories, loaded.

The data ships only inside the registry's `overcooked-ai==1.1.0` sdist
(`overcooked_ai_py/data/human_data/clean_{train,test}_trials.pickle`), and upstream's data
README says "Do not distribute in any manner without the express consent of CHAI". So this
module never puts it in the repository or the wheel: `fetch` downloads the sdist with the
user's own pip into a cache folder and extracts the two pickles there, `convert` writes the
trajectories beside them, and `trajectories` reads them back. Everything lives under
`cache_folder()`: the `cache` argument, else `$RLLIB_CONV_CACHE/overcooked`, else
`~/.cache/rllib-conv/overcooked`.

Upstream's train/test split is kept as it is: train (39 trials) is what BC learns from,
test (37 trials, other pairs of people) is what the human proxy learns from. A trial is one
pair of people (`workerid_num`) playing one layout for about 1 200 logged steps. The data
names two layouts by their 2019 names; `LAYOUTS` maps them to the current ones.

On-disk format (`<cache>/trajectories/<layout>/<split>.parquet`, one file per layout and
split, written by pandas with pyarrow, so `ray.data.read_parquet` and RLlib's offline API
read it as it is). One row per trial, seat and step, sorted by (trial, seat, t):

| column | type | what it holds |
|---|---|---|
| `trial` | int | the trial's number within its layout and split (0, 1, ...; order of `worker`) |
| `worker` | int | upstream's `workerid_num`: the pair of people who played it |
| `seat` | int | 0 or 1: which player of the logged state this row follows |
| `t` | int | the step within the trial, from 0 |
| `state` | str | the state before the step, JSON: `{"players": [{"position": [x, y], "orientation": [dx, dy], "held_object": null or {"name", "position", "state"?}}, ...], "objects": [{"name", "position", "state"?}, ...]}`; soups keep the 2019 form `"state": [ingredient, count, cooking time]`. `OvercookedState.from_dict(json.loads(state))` reads it (timestep 0) |
| `next_state` | str | the logged state after the step, in the same form |
| `action` | int | this seat's action: an index into `env.ACTIONS` (0 north, 1 south, 2 east, 3 west, 4 stay, 5 interact: `overcooked`'s `Action.ALL_ACTIONS` order) |
| `partner_action` | int | the other seat's action at the same step, same indices |
| `reward` | float | the step's sparse reward for both seats, as our env gives it: 20 per soup delivered (the 2019 logs count 5) |
| `score` | float | the logged score after the step (5 per soup), as upstream wrote it |
| `done` | bool | True on the trial's last logged step |

Reading a state back: build the layout's MDP first (`env.build_mdp(layout)` or an
`OvercookedEnv`), then `OvercookedState.from_dict(json.loads(row.state))`; the package
configures its recipes globally when an MDP is built, and a cooked soup cannot be read before.
Every logged trial replays exactly through `OvercookedEnv` from its first state (players,
objects and sparse rewards at every step; tests/envs/test_overcooked_human_data.py).

Nothing here decides what to do with "stay" (about 70-75% of logged actions: the game was
logged faster than people act); `summary` counts it per layout, split and seat.
"""

from __future__ import annotations

import ast
import hashlib
import json
import os
import pickle
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import pandas as pd
from overcooked.mdp.actions import Action

from rllib_conv.envs.overcooked.env import STAY, action_index

__all__ = [
    "LAYOUTS",
    "SPLITS",
    "HumanDataUnpickler",
    "cache_folder",
    "convert",
    "fetch",
    "load_trials",
    "summary",
    "trajectories",
    "trajectory_path",
]

SDIST = "overcooked-ai==1.1.0"
SDIST_FILE = "overcooked_ai-1.1.0.tar.gz"
# Digests observed on the first successful download (2026-12-05, from the registry): a changed
# file means a changed upload or a corrupt cache, and is refused rather than converted.
SDIST_SHA256 = "478bf319274bdb6c5bede8048ee901d088912353111ab85e9fb2bf389c6ccddf"
PICKLES = {
    "train": (
        "overcooked_ai-1.1.0/src/overcooked_ai_py/data/human_data/clean_train_trials.pickle",
        "28659cfd09ee033d82b56bed905b239f078877e1b09d1f1b916e4bc0480ca4fa",
    ),
    "test": (
        "overcooked_ai-1.1.0/src/overcooked_ai_py/data/human_data/clean_test_trials.pickle",
        "59979552a053f1efe762de976f37dd83e269d70d19b67613c61e856c86705666",
    ),
}
SPLITS = ("train", "test")
# The data's layout names -> the names `OvercookedGridworld.from_layout_name` knows today.
DATA_LAYOUTS = {
    "cramped_room": "cramped_room",
    "asymmetric_advantages": "asymmetric_advantages",
    "coordination_ring": "coordination_ring",
    "random0": "forced_coordination",
    "random3": "counter_circuit_o_1order",
}
LAYOUTS = tuple(DATA_LAYOUTS.values())
CACHE_ENV = "RLLIB_CONV_CACHE"
COLUMNS = ("trial", "worker", "seat", "t", "state", "next_state", "action", "partner_action", "reward", "score", "done")
# The logged score counts 5 per soup; the game (and our env) gives 20.
LOGGED_POINTS_PER_SOUP = 5.0
SOUP_REWARD = 20.0


def cache_folder(cache: str | os.PathLike[str] | None = None) -> Path:
    """The folder holding the Overcooked human data: `cache`, else `$RLLIB_CONV_CACHE/overcooked`, else `~/.cache/rllib-conv/overcooked`."""
    if cache is not None:
        return Path(cache).expanduser()
    root = os.environ.get(CACHE_ENV)
    return (Path(root).expanduser() if root else Path.home() / ".cache" / "rllib-conv") / "overcooked"


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _pickle_path(folder: Path, split: str) -> Path:
    return folder / "human_data" / Path(PICKLES[split][0]).name


def _download_sdist(into: Path) -> Path:
    """Download the sdist with this interpreter's pip (its index and cache settings apply) into `into`."""
    base = [sys.executable, "-m", "pip", "download", SDIST, "--no-deps", "--no-binary", ":all:", "-d", str(into)]
    base += ["--disable-pip-version-check", "--quiet"]
    # pip reads the sdist's metadata, which builds it; without isolation that needs only the
    # setuptools already here (no second download), with isolation it works where there is none.
    for extra in (["--no-build-isolation"], []):
        done = subprocess.run([*base, *extra], capture_output=True, text=True)
        if done.returncode == 0 and (into / SDIST_FILE).is_file():
            return into / SDIST_FILE
    lines = (done.stderr or done.stdout).strip().splitlines()
    tail = " ".join([line for line in lines if line.startswith("ERROR")] or lines[-3:])
    raise RuntimeError(
        f"could not download {SDIST} from the package registry (pip exited {done.returncode}): {tail}. "
        "The 2019 human data ships only in that sdist: check the network or pip's index settings "
        f"(PIP_INDEX_URL), or put {SDIST_FILE} in the cache folder {into.parent} by hand"
    )


def fetch(cache: str | os.PathLike[str] | None = None) -> dict[str, Path]:
    """Make sure the two pickles are in the cache folder, with the recorded SHA-256; return {split: path}.

    The first call downloads the `overcooked-ai==1.1.0` sdist (2.3 MB) through pip (or takes
    it from `<cache>/overcooked_ai-1.1.0.tar.gz` when a user put it there), checks its digest
    and extracts only the two pickles into `<cache>/human_data/`; the sdist is not kept. Later
    calls only check the pickles' digests. A digest that differs is a ValueError naming the
    file (delete it to fetch again); a registry that cannot be reached is a RuntimeError.
    """
    folder = cache_folder(cache)
    paths = {split: _pickle_path(folder, split) for split in SPLITS}
    if not all(p.is_file() for p in paths.values()):
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "human_data").mkdir(exist_ok=True)
        with tempfile.TemporaryDirectory(dir=folder, prefix=".download-") as tmp:
            given = folder / SDIST_FILE
            sdist = given if given.is_file() else _download_sdist(Path(tmp))
            if _sha256(sdist) != SDIST_SHA256:
                raise ValueError(f"{sdist}: SHA-256 is not the recorded {SDIST_SHA256} of {SDIST}; delete it and fetch again")
            with tarfile.open(sdist, "r:gz") as archive:
                for split, path in paths.items():
                    member = archive.extractfile(PICKLES[split][0])
                    if member is None:
                        raise ValueError(f"{sdist}: holds no {PICKLES[split][0]}")
                    # Written under a temporary name and renamed: an interrupted fetch leaves no half pickle.
                    part = path.with_suffix(".part")
                    part.write_bytes(member.read())
                    part.replace(path)
    for split, path in paths.items():
        if _sha256(path) != PICKLES[split][1]:
            raise ValueError(f"{path}: SHA-256 is not the recorded {PICKLES[split][1]}; delete it and run the fetch again")
    return paths


class HumanDataUnpickler(pickle.Unpickler):
    """Reads upstream's 2019 pickles under pandas 2-3 and numpy 2.

    The pickles were written by pandas 0.x / numpy 1.x and name two things that have since
    moved: pandas' `Int64Index` family (removed in pandas 2; a plain `pandas.Index` with an
    integer dtype holds the same data) and the `numpy.core` package (renamed `numpy._core`
    in numpy 2; the old name still imports but warns). Everything else unpickles as written.
    """

    _PANDAS_NUMERIC = "pandas.core.indexes.numeric"
    _INDEXES = {"Int64Index", "UInt64Index", "Float64Index", "NumericIndex"}

    def find_class(self, module: str, name: str) -> Any:
        """Map the moved names to their current homes, then find the class as pickle would."""
        if module == self._PANDAS_NUMERIC and name in self._INDEXES:
            return pd.Index
        if (module == "numpy.core" or module.startswith("numpy.core.")) and int(np.__version__.split(".")[0]) >= 2:
            module = "numpy._core" + module[len("numpy.core") :]
        return super().find_class(module, name)


def load_trials(split: str, cache: str | os.PathLike[str] | None = None) -> pd.DataFrame:
    """Upstream's DataFrame of one split as it was pickled (fetched first if needed): one row per logged step.

    Unpickling runs code named in the file, so only a file whose SHA-256 `fetch` has just
    checked against the recorded digest is opened.
    """
    if split not in SPLITS:
        raise ValueError(f"split must be one of {', '.join(SPLITS)}, not {split!r}")
    with open(fetch(cache)[split], "rb") as f:
        frame = HumanDataUnpickler(f).load()
    if not isinstance(frame, pd.DataFrame):
        raise ValueError(f"{_pickle_path(cache_folder(cache), split)}: holds a {type(frame).__name__}, not a DataFrame")
    return frame


def _held(obj: dict[str, Any] | None) -> dict[str, Any] | None:
    if obj is None:
        return None
    out = {"name": obj["name"], "position": list(obj["position"])}
    if "state" in obj:
        out["state"] = list(obj["state"])
    return out


def normalise_state(logged: str | dict[str, Any]) -> dict[str, Any]:
    """A logged state (the data's Python-literal string or dict) as the JSON-able dict of the format above.

    The logs write objects as a dict keyed "x,y" (or a list) and carry fields the current MDP
    does not use (`order_list`, `pot_explosion`); these are dropped, the rest kept as logged.
    """
    raw = ast.literal_eval(logged) if isinstance(logged, str) else logged
    objects = raw["objects"].values() if isinstance(raw["objects"], dict) else raw["objects"]
    players = [
        {"position": list(p["position"]), "orientation": list(p["orientation"]), "held_object": _held(p.get("held_object"))}
        for p in raw["players"]
    ]
    return {"players": players, "objects": sorted((_held(o) for o in objects), key=lambda o: tuple(o["position"]))}


def action_indices(joint_action: str | Iterable[Any]) -> tuple[int, int]:
    """A logged joint action (e.g. "[[0, -1], 'INTERACT']") as two indices into `env.ACTIONS`."""
    raw = ast.literal_eval(joint_action) if isinstance(joint_action, str) else joint_action
    out = []
    for a in raw:
        # The logs spell interact in capitals and directions as lists; the package uses "interact" and tuples.
        try:
            out.append(action_index(Action.INTERACT if isinstance(a, str) and a.upper() == "INTERACT" else a))
        except ValueError:
            raise ValueError(f"joint_action {joint_action!r}: unknown action {a!r}") from None
    if len(out) != 2:
        raise ValueError(f"joint_action {joint_action!r}: expected 2 actions, got {len(out)}")
    return out[0], out[1]


def _convert_trial(steps: pd.DataFrame, trial: int, worker: int) -> pd.DataFrame:
    """One trial's logged steps (sorted by `cur_gameloop`) as rows of both seats."""
    # Most steps repeat the state before them (people stand still): each distinct string is parsed once.
    memo: dict[str, str] = {}
    as_json = lambda s: memo[s] if s in memo else memo.setdefault(s, json.dumps(normalise_state(s)))  # noqa: E731
    states = [as_json(s) for s in steps["state"]]
    nexts = [as_json(s) for s in steps["next_state"]]
    joint = np.array([action_indices(a) for a in steps["joint_action"]], dtype=np.int64)
    score = steps["score"].to_numpy(dtype=float)
    # The step's reward from the score it adds (5 per soup in the logs), in the game's 20 per soup.
    gained = np.diff(np.concatenate([[0.0], score]))
    reward = gained / LOGGED_POINTS_PER_SOUP * SOUP_REWARD
    n = len(steps)
    done = np.zeros(n, dtype=bool)
    done[-1] = True
    seats = []
    for seat in (0, 1):
        seats.append(
            pd.DataFrame(
                {
                    "trial": trial,
                    "worker": worker,
                    "seat": seat,
                    "t": np.arange(n),
                    "state": states,
                    "next_state": nexts,
                    "action": joint[:, seat],
                    "partner_action": joint[:, 1 - seat],
                    "reward": reward,
                    "score": score,
                    "done": done,
                }
            )
        )
    return pd.concat(seats, ignore_index=True)


def trajectory_path(layout: str, split: str, cache: str | os.PathLike[str] | None = None) -> Path:
    """Where `convert` writes one layout's split: `<cache>/trajectories/<layout>/<split>.parquet`."""
    _check(layout, split)
    return cache_folder(cache) / "trajectories" / layout / f"{split}.parquet"


def _check(layout: str, split: str) -> None:
    if layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {', '.join(LAYOUTS)}, not {layout!r}")
    if split not in SPLITS:
        raise ValueError(f"split must be one of {', '.join(SPLITS)}, not {split!r}")


def convert(
    cache: str | os.PathLike[str] | None = None, layouts: Iterable[str] | None = None, overwrite: bool = False
) -> dict[tuple[str, str], Path]:
    """Fetch if needed, then write each layout's train and test trajectories; return {(layout, split): path}.

    A file already there is kept unless `overwrite` (the conversion is deterministic). Checks
    that each trial's logged steps are contiguous (`next_state` of one is `state` of the next).
    """
    chosen = list(LAYOUTS if layouts is None else layouts)
    for layout in chosen:
        _check(layout, "train")
    written = {}
    for split in SPLITS:
        wanted = {layout: trajectory_path(layout, split, cache) for layout in chosen}
        todo = {layout: path for layout, path in wanted.items() if overwrite or not path.is_file()}
        written.update({(layout, split): path for layout, path in wanted.items()})
        if not todo:
            continue
        frame = load_trials(split, cache)
        for data_name, layout in DATA_LAYOUTS.items():
            if layout not in todo:
                continue
            rows = frame[frame["layout_name"] == data_name]
            parts = []
            for trial, (worker, steps) in enumerate(sorted(rows.groupby("workerid_num"), key=lambda kv: kv[0])):
                steps = steps.sort_values("cur_gameloop")
                if not (steps["state"].iloc[1:].to_numpy() == steps["next_state"].iloc[:-1].to_numpy()).all():
                    raise ValueError(f"{split} trials, {data_name} worker {worker}: logged steps are not contiguous")
                parts.append(_convert_trial(steps, trial, int(worker)))
            out = pd.concat(parts, ignore_index=True).sort_values(["trial", "seat", "t"], ignore_index=True)
            path = todo[layout]
            path.parent.mkdir(parents=True, exist_ok=True)
            part = path.with_suffix(".part")
            out.to_parquet(part, index=False)
            part.replace(path)
    return written


def trajectories(layout: str, split: str, cache: str | os.PathLike[str] | None = None) -> pd.DataFrame:
    """One layout's split as a DataFrame of the format above (fetched and converted first if needed)."""
    path = trajectory_path(layout, split, cache)
    if not path.is_file():
        convert(cache, [layout])
    frame = pd.read_parquet(path)
    missing = set(COLUMNS) - set(frame.columns)
    if missing:
        raise ValueError(f"{path}: lacks the columns {sorted(missing)}; delete it to convert again")
    return frame


def summary(cache: str | os.PathLike[str] | None = None, layouts: Iterable[str] | None = None) -> pd.DataFrame:
    """Trials, steps and the fraction of "stay" actions per layout, split and seat (converting first if needed)."""
    rows = []
    for layout in LAYOUTS if layouts is None else layouts:
        for split in SPLITS:
            frame = trajectories(layout, split, cache)
            for seat, part in frame.groupby("seat"):
                rows.append(
                    {
                        "layout": layout,
                        "split": split,
                        "seat": int(seat),
                        "trials": part["trial"].nunique(),
                        "steps": len(part),
                        "stay": round(float((part["action"] == STAY).mean()), 3),
                        "soups": int(part.loc[part["done"], "score"].sum() / LOGGED_POINTS_PER_SOUP),
                    }
                )
    return pd.DataFrame(rows)
