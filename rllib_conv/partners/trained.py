"""Partners that are trained networks: any logits function, or a policy module loaded from disk."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch

from rllib_conv.partners.base import Partner
from rllib_conv.partners.kinds import register_kind

LogitsFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


class PolicyPartner(Partner):
    """Acts with `logits_fn(obs [B, d], mask [B, A]) -> masked logits [B, A]`, greedily or by sampling.

    Sampling uses the partner's own seeded RNG, so play is reproducible.
    """

    kind = "policy"

    def __init__(self, name: str, logits_fn: LogitsFn | None = None, greedy: bool = False, seed: int = 0) -> None:
        super().__init__(name)
        self.logits_fn = logits_fn
        self.greedy = bool(greedy)
        self._seed = seed
        self._rng = np.random.default_rng(seed)

    def seed(self, seed: int | None) -> None:
        self._rng = np.random.default_rng(self._seed if seed is None else seed)

    @torch.no_grad()
    def probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        """Return the action probabilities [B, A]."""
        obs = torch.as_tensor(np.asarray(observations), dtype=torch.float32)
        mask = torch.as_tensor(np.asarray(action_masks), dtype=torch.float32)
        return torch.softmax(self.logits_fn(obs, mask), dim=-1).numpy()

    def act_batch(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        p = self.probs(observations, action_masks)
        if self.greedy:
            return p.argmax(axis=1)
        # Inverse-CDF sampling, one uniform per row: vectorised and seeded.
        cdf = np.cumsum(p, axis=1)
        u = self._rng.random((len(p), 1)) * cdf[:, -1:]
        return np.minimum((cdf < u).sum(axis=1), p.shape[1] - 1)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        return int(self.act_batch(np.asarray(observation)[None], np.asarray(action_mask)[None])[0])

    def params(self) -> dict[str, Any]:
        return {"greedy": self.greedy, "seed": self._seed}


@register_kind
class TrainedPolicyPartner(PolicyPartner):
    """A trained policy module (`TaskModule`) loaded from its RLlib module checkpoint folder."""

    kind = "trained_policy"

    def __init__(self, name: str, checkpoint: str, greedy: bool = True, seed: int = 0) -> None:
        from rllib_conv.modules.task_module import TaskModule
        from rllib_conv.pipelines.checkpoints import MANIFEST, verify

        path = Path(checkpoint)
        if not (path / "class_and_ctor_args.pkl").is_file() or not any(path.glob("module_state*")):
            raise ValueError(f"partner {name!r}: checkpoint {str(path)!r} does not exist or holds no module state")
        if (path / MANIFEST).is_file():  # populations written by `partners train` are sealed
            verify(path)
        self.checkpoint = str(path)
        try:
            self.module = TaskModule.from_checkpoint(path)
        except Exception as exc:  # a damaged pickle raises anything from EOFError to UnpicklingError
            raise ValueError(f"partner {name!r}: checkpoint {str(path)!r} cannot be loaded ({type(exc).__name__}: {exc})") from None
        self.module.eval()
        super().__init__(name, lambda obs, mask: self.module.policy(obs, mask).logits, greedy, seed)

    def params(self) -> dict[str, Any]:
        return {"checkpoint": self.checkpoint, **super().params()}
