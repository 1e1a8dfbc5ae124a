"""Random-number state that RLlib checkpoints leave out, so a resumed trial continues exactly.

An RLlib checkpoint holds weights, optimizer and metrics, but not the games' RNGs, the
global torch/numpy/random generators, the replicas' own exploration generators (in the
env runners' `EgoStack`, or MEP's seats), the learner's per-module shuffling generators nor the partner
round robin. Saved beside each checkpoint and restored after it, they make a
trial killed and resumed from its checkpoint produce the same results as one never
interrupted, whenever no episode spans the checkpoint (as on the one-step bandit);
otherwise the episodes in flight restart and the run continues with fresh ones.
"""

from __future__ import annotations

import pickle
import random
from pathlib import Path
from typing import Any

import numpy as np
import torch

from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.modules.task_module import TaskModule

RNG_FILE = "rng_state.pkl"


def _process_state() -> dict[str, Any]:
    return {"torch": torch.get_rng_state(), "numpy": np.random.get_state(), "random": random.getstate()}


def _set_process_state(state: dict[str, Any]) -> None:
    torch.set_rng_state(state["torch"])
    np.random.set_state(state["numpy"])
    random.setstate(state["random"])


def _samplers(runner: Any) -> list[torch.Generator]:
    """The exploration generators of the runner's stacked ego, or of its modules that have one (MEP's seats)."""
    module = runner.module
    if module is None:
        return []
    if STACK_ID in module:
        return list(module[STACK_ID].samplers)
    return [m.sampler for mid in sorted(module.keys()) if isinstance(m := module[mid], TaskModule) and m.sampler is not None]


def _runner_state(runner: Any) -> dict[str, Any]:
    mapping = runner.config.policy_mapping_fn
    envs = runner.env.envs if runner.env is not None else []  # a driver-side runner may have no env
    return {
        "process": _process_state(),
        "envs": [env.unwrapped.get_rng_state() for env in envs],
        "mapping": mapping.get_state() if hasattr(mapping, "get_state") else None,
        "samplers": [g.get_state() for g in _samplers(runner)],
    }


def _set_runner_state(runner: Any, state: dict[str, Any]) -> None:
    _set_process_state(state["process"])
    for env, env_state in zip(runner.env.envs if runner.env is not None else [], state["envs"]):
        env.unwrapped.set_rng_state(env_state)
    mapping = runner.config.policy_mapping_fn
    if state["mapping"] is not None and hasattr(mapping, "set_state"):
        mapping.set_state(state["mapping"])
    for generator, saved in zip(_samplers(runner), state.get("samplers", [])):
        generator.set_state(saved)


def capture(algo: Any) -> dict[str, Any]:
    """The RNG state of this process and of every env runner of `algo`, by runner index (0 = local)."""
    group = algo.env_runner_group
    runners = {0: _runner_state(group.local_env_runner)} if group.local_env_runner is not None else {}
    if group.num_remote_env_runners():
        for result in group.foreach_env_runner(_runner_state, local_env_runner=False, return_actor_ids=True):
            runners[result.actor_id] = result.get()
    permuters = [r.get() for r in algo.learner_group.foreach_learner(_permuter_state)] if algo.learner_group.is_local else []
    return {"trainer": _process_state(), "runners": runners, "learners": permuters}


def restore(algo: Any, state: dict[str, Any]) -> None:
    """Put back a state from `capture` (after `algo.restore_from_path`)."""
    group = algo.env_runner_group
    for index, runner_state in state["runners"].items():
        if index == 0:
            if group.local_env_runner is not None:
                _set_runner_state(group.local_env_runner, runner_state)
        else:
            group.foreach_env_runner(
                lambda r, s=runner_state: _set_runner_state(r, s), remote_worker_ids=[index], local_env_runner=False
            )
    for saved in state.get("learners", [])[:1]:
        algo.learner_group.foreach_learner(lambda learner, s=saved: _set_permuter_state(learner, s))
    _set_process_state(state["trainer"])


def _permuter_state(learner: Any) -> dict | None:
    permuters = getattr(learner, "permuters", None)
    return permuters.get_state() if permuters is not None else None


def _set_permuter_state(learner: Any, state: dict | None) -> None:
    if state is not None and getattr(learner, "permuters", None) is not None:
        learner.permuters.set_state(state)


def save(algo: Any, folder: str | Path) -> None:
    """Write `capture(algo)` into a checkpoint folder."""
    Path(folder, RNG_FILE).write_bytes(pickle.dumps(capture(algo)))


def load(algo: Any, folder: str | Path) -> None:
    """Restore the state saved by `save`, if the checkpoint has one."""
    path = Path(folder, RNG_FILE)
    if path.is_file():
        restore(algo, pickle.loads(path.read_bytes()))
