"""Write one replica of a packed algorithm as an ordinary trained ego: its own folder, unsuffixed modules, sealed.

Everything that reads a trained ego back (adaptation, zero-shot, marginals, the web app,
`rllib-conv pair`) reads a trial folder holding `config.yaml`, `eval.json`, `progress.csv`
and `checkpoint_000000/learner_group/learner/rl_module/{task, ego@..., partner@...}`; an ego with one head
per partner seat and partner also keeps those seat heads, `checkpoint_000000/seat_heads/ego@<seat>=<partner>`
(adapting to a team with a known member starts from them: `head_init: known-seats`).
A replica's weights are slices of the algorithm's `EgoStack`; its export holds them in plain
modules under their plain IDs, a `ConventionMultiRLModule` checkpoint of their own, written
to a temporary folder and moved into place only when complete.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pandas as pd
import torch
import yaml
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec

from rllib_conv.common.atomic_files import folder_replaced_atomically
from rllib_conv.common.run_folders import (
    CHECKPOINT_PREFIX,
    CONFIG_FILE,
    EVAL_FILE,
    PROGRESS_FILES,
    RL_MODULE_DIR,
    SEAT_HEADS_DIR,
)
from rllib_conv.common.sealed import seal, seal_file
from rllib_conv.modules.multi import TASK_ID, ConventionMultiRLModule
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.training.algorithm import Replica, module_specs, seat_head_specs

EXPORT_CHECKPOINT = f"{CHECKPOINT_PREFIX}000000"


def replica_module(module: Any, index: int, replica: Replica) -> ConventionMultiRLModule:
    """A `ConventionMultiRLModule` under plain IDs holding the current weights of replica `index` of `module` (a stacked ego)."""
    plain = MultiRLModuleSpec(
        multi_rl_module_class=ConventionMultiRLModule, rl_module_specs=module_specs(replica.setup, seed=replica.own_seed)
    ).build()
    return copy_replica(module, index, replica, plain)


def copy_replica(module: Any, index: int, replica: Replica, plain: ConventionMultiRLModule) -> ConventionMultiRLModule:
    """Write replica `index`'s current weights from `module` (a stacked ego) into `plain` (built by `replica_module`); return it."""
    stack = module[STACK_ID]
    with torch.no_grad():
        plain[TASK_ID].load_state_dict(stack.task_state(index))
        for h, mid in enumerate(replica.setup.head_ids):
            plain[mid].load_state_dict(stack.head_state(index, h))
    return plain


def seat_head_modules(module: Any, index: int, replica: Replica) -> dict[str, Any]:
    """Replica `index`'s seat heads (`EgoSetup.weight_heads`) from `module` (a stacked ego), each a plain head module; none in team mode."""
    if not replica.setup.seat_heads:
        return {}
    stack, out = module[STACK_ID], {}
    for w, (mid, spec) in enumerate(seat_head_specs(replica.setup).items()):
        out[mid] = spec.build()
        out[mid].load_state_dict(stack.weight_head_state(index, w))
    return out


def export_replica(
    plain: ConventionMultiRLModule,
    replica: Replica,
    folder: Path,
    evaluation: dict[str, Any],
    progress: list[dict[str, Any]],
    seat_heads: dict[str, Any] | None = None,
) -> Path:
    """Write a replica (`plain`: its modules from `replica_module`) as a trained-ego trial folder at `folder`; return it.

    An existing complete export (a resumed trial re-running its last iteration) is left as
    it is: a deterministic resume would write the same files.
    """
    if (folder / EVAL_FILE).is_file():
        return folder
    with folder_replaced_atomically(folder) as staging:
        (staging / CONFIG_FILE).write_text(yaml.safe_dump(replica.setup.exp.model_dump(), sort_keys=False))
        seal_file(staging / CONFIG_FILE)  # read back only if unchanged (`trial_config`): a damaged config is another experiment
        pd.DataFrame(progress).to_csv(staging / PROGRESS_FILES[0], index=False)
        checkpoint = staging / EXPORT_CHECKPOINT
        plain.save_to_path(checkpoint / RL_MODULE_DIR)
        for mid, head in (seat_heads or {}).items():  # `seat_head_modules`
            head.save_to_path(checkpoint / SEAT_HEADS_DIR / mid)
        seal(checkpoint)
        # Last: a folder with eval.json is a finished ego (readers skip unfinished ones).
        (staging / EVAL_FILE).write_text(json.dumps(evaluation, indent=2) + "\n")
    return folder
