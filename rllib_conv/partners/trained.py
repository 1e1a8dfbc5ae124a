"""Partners that are trained networks: any logits function, or an RLlib policy module loaded from disk."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

import numpy as np
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.rl_module import RLModule

from rllib_conv.common.sealed import is_sealed, verify
from rllib_conv.envs.rllib_adapter import RLLIB_MASK_KEY, RLLIB_OBS_KEY
from rllib_conv.partners.base import Partner
from rllib_conv.partners.kinds import register_kind

LogitsFn = Callable[[torch.Tensor, torch.Tensor], torch.Tensor]


class PolicyPartner(Partner):
    """Acts with `logits_fn(obs [B, d], mask [B, A]) -> masked logits [B, A]`, greedily or by sampling.

    Sampling uses the partner's own seeded RNG, so play is reproducible. `memo`: remember the
    probabilities of every (observation, mask) it acted on, for a network that does not change
    while it plays (an evaluation): games revisit few states, and one forward pass per move is
    what playing costs; the actions drawn are the same as without it.
    """

    kind = "policy"
    batchable = True  # a function of each row and the RNG: one forward pass can choose for many games

    def __init__(
        self, name: str, logits_fn: LogitsFn | None = None, greedy: bool = False, seed: int = 0, memo: bool = False
    ) -> None:
        super().__init__(name)
        self.logits_fn = logits_fn
        self.greedy = bool(greedy)
        self._seed = seed
        self._rng = np.random.default_rng(seed)
        self._memo: dict[tuple[bytes, bytes], np.ndarray] | None = {} if memo else None

    def seed(self, seed: int | None) -> None:
        self._rng = np.random.default_rng(self._seed if seed is None else seed)

    @torch.no_grad()
    def probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        """Return the action probabilities [B, A]."""
        obs = torch.as_tensor(np.asarray(observations), dtype=torch.float32)
        mask = torch.as_tensor(np.asarray(action_masks), dtype=torch.float32)
        return torch.softmax(self.logits_fn(obs, mask), dim=-1).numpy()

    def act_batch(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        return self._choose(self.probs(observations, action_masks))

    def action_probs(self, observations: np.ndarray, action_masks: np.ndarray) -> np.ndarray:
        """What `act` draws from: `probs`, or its one-hot argmax when greedy."""
        p = self.probs(observations, action_masks)
        if not self.greedy:
            return p.astype(np.float64)
        out = np.zeros(p.shape, dtype=np.float64)
        out[np.arange(len(p)), p.argmax(axis=1)] = 1.0
        return out

    def _choose(self, p: np.ndarray) -> np.ndarray:
        """An action per row of probabilities [B, A]."""
        if self.greedy:
            return p.argmax(axis=1)
        # Inverse-CDF sampling, one uniform per row: vectorised and seeded.
        cdf = np.cumsum(p, axis=1)
        u = self._rng.random((len(p), 1)) * cdf[:, -1:]
        return np.minimum((cdf < u).sum(axis=1), p.shape[1] - 1)

    def act(self, observation: np.ndarray, action_mask: np.ndarray) -> int:
        obs, mask = np.asarray(observation)[None], np.asarray(action_mask)[None]
        if self._memo is None:
            return int(self.act_batch(obs, mask)[0])
        key = (obs.tobytes(), mask.tobytes())
        if (p := self._memo.get(key)) is None:
            p = self._memo[key] = self.probs(obs, mask)
        return int(self._choose(p)[0])

    def params(self) -> dict[str, Any]:
        return {"greedy": self.greedy, "seed": self._seed}


def module_logits(module: RLModule) -> LogitsFn:
    """The masked action logits of any RLlib policy module, through its own inference forward pass.

    The module sees the observations as the RLlib adapter gives them (`{"observations",
    "action_mask"}`), so any module trained on our games (the self-play `TaskModule`, a
    user's own) can be a partner.
    """

    def logits(obs: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        batch = {Columns.OBS: {RLLIB_OBS_KEY: obs, RLLIB_MASK_KEY: mask}}
        return module.forward_inference(batch)[Columns.ACTION_DIST_INPUTS]

    return logits


def load_rl_module(checkpoint: str | Path) -> RLModule:
    """An RLlib module (single or multi-agent) from its checkpoint folder; the class the checkpoint names is rebuilt.

    The path is made absolute first: RLlib reads a relative one as a URI without a scheme.
    """
    return RLModule.from_checkpoint(Path(checkpoint).resolve())


@register_kind
class TrainedPolicyPartner(PolicyPartner):
    """A trained policy module loaded from its RLlib module checkpoint folder (`RLModule.from_checkpoint`)."""

    kind = "trained_policy"

    def __init__(self, name: str, checkpoint: str, greedy: bool = True, seed: int = 0) -> None:
        path = Path(checkpoint)
        if not (path / "class_and_ctor_args.pkl").is_file() or not any(path.glob("module_state*")):
            raise ValueError(f"partner {name!r}: checkpoint {str(path)!r} does not exist or holds no module state")
        if is_sealed(path):  # populations written by `partners train` are sealed
            verify(path)
        self.checkpoint = str(path)
        try:
            # The checkpoint names its module class (ours: `TaskModule`); RLlib rebuilds that class.
            self.module = load_rl_module(path)
        except Exception as exc:  # a damaged pickle raises anything from EOFError to UnpicklingError
            raise ValueError(
                f"partner {name!r}: checkpoint {str(path)!r} cannot be loaded ({type(exc).__name__}: {exc})"
            ) from None
        self.module.eval()
        super().__init__(name, module_logits(self.module), greedy, seed)

    def params(self) -> dict[str, Any]:
        return {"checkpoint": self.checkpoint, **super().params()}
