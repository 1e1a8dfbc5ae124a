"""Which rows of each module's batch every minibatch update uses: RLlib's cyclic minibatch plan, as row indices.

RLlib's `MiniBatchCyclicIterator` walks each module's batch in `minibatch_size` steps,
wrapping around at its end; each wrap completes an epoch of that module and, with
shuffling, reorders its batch (`SampleBatch.shuffle`, one `permutation(len)` per wrap).
It stops once every module has covered `num_epochs` epochs. `CyclicMinibatchPlan` yields
the same sequence as index tensors instead of copied sub-batches, so the learner can
slice its tensors once per minibatch.

Permutations come from `permute(module_id, n)`: RLlib's global NumPy RNG by default, or
one generator per module (`ModulePermuters`, seeded by `rllib_conv.common.seeds.shuffle_seed`), so that modules of independent runs
packed into one learner shuffle as each would alone.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np
import torch

Permute = Callable[[str, int], np.ndarray]


def global_permute(module_id: str, n: int) -> np.ndarray:
    """A permutation from NumPy's global RNG, as `SampleBatch.shuffle` draws it."""
    return np.random.permutation(n)


class ModulePermuters:
    """One NumPy generator per module, seeded from (seed, module ID); its states travel with checkpoints."""

    def __init__(self, seeds: dict[str, int]) -> None:
        self._rngs = {mid: np.random.default_rng(seed) for mid, seed in seeds.items()}

    def __call__(self, module_id: str, n: int) -> np.ndarray:
        return self._rngs[module_id].permutation(n)

    def get_state(self) -> dict[str, dict]:
        """The generators' states (for exact resumes)."""
        return {mid: rng.bit_generator.state for mid, rng in self._rngs.items()}

    def set_state(self, state: dict[str, dict]) -> None:
        """Restore states from `get_state` (modules not in `state` keep theirs)."""
        for mid, s in state.items():
            if mid in self._rngs:
                self._rngs[mid].bit_generator.state = s


class CyclicMinibatchPlan:
    """Row indices per module for every minibatch update of one learner update (see the module docstring)."""

    def __init__(
        self, sizes: dict[str, int], minibatch_size: int, num_epochs: int, shuffle: bool, permute: Permute = global_permute
    ) -> None:
        empty = [mid for mid, n in sizes.items() if n == 0]
        if empty:
            raise ValueError(f"the batch of module(s) {empty} is empty; every module being trained needs rows")
        self.sizes, self.minibatch_size, self.num_epochs = dict(sizes), int(minibatch_size), int(num_epochs)
        self.shuffle, self.permute = shuffle, permute

    def __iter__(self) -> Iterator[dict[str, torch.Tensor]]:
        order = {mid: np.arange(n) for mid, n in self.sizes.items()}
        start = dict.fromkeys(self.sizes, 0)
        covered = dict.fromkeys(self.sizes, 0)
        while min(covered.values()) < self.num_epochs:
            out = {}
            for mid, n in self.sizes.items():
                s, need, parts = start[mid], self.minibatch_size, []
                while s + need >= n:  # `>=` as RLlib: a minibatch ending exactly at the end wraps too
                    parts.append(order[mid][s:])
                    need -= n - s
                    s = 0
                    covered[mid] += 1
                    if self.shuffle:
                        order[mid] = order[mid][self.permute(mid, n)]
                if need > 0:
                    parts.append(order[mid][s : s + need])
                start[mid] = s + need
                out[mid] = torch.from_numpy(np.concatenate(parts) if len(parts) > 1 else parts[0].copy())
            yield out
