"""Learner connector piece: drop PPO's artificial bootstrap rows once advantages are computed.

RLlib's PPO appends one extra timestep to every episode chunk (to bootstrap values)
and masks it out of the loss. For one-step games that doubles every batch, so a
minibatch of 16 holds only ~8 real samples. Run after GAE, this piece keeps only the
rows with `loss_mask` true: minibatch sizes then mean real samples (as in the paper's
code), the learner does half the work on the bandit, and every loss term, the marginal
regulariser included, sees real states only.
"""

from __future__ import annotations

from typing import Any

import tree
from ray.rllib.connectors.connector_v2 import ConnectorV2
from ray.rllib.core.columns import Columns


class DropBootstrapRows(ConnectorV2):
    """Keep the rows whose `loss_mask` is true in every module's batch; remove the mask."""

    def __call__(self, *, rl_module: Any, batch: dict[str, Any], episodes: Any, **kwargs: Any) -> Any:
        for module_id, module_batch in batch.items():
            mask = module_batch.pop(Columns.LOSS_MASK, None)
            if mask is None:
                continue
            batch[module_id] = tree.map_structure(
                lambda x, m=mask: x[m] if hasattr(x, "shape") and len(x) == len(m) else x, module_batch
            )
        return batch
