"""`SharedWiringMultiRLModule`: a MultiRLModule whose dependent modules use one shared module they do not own.

Both multi modules of an ego are built this way: in `ConventionMultiRLModule` every
`PartnerHeadModule` computes on the shared `TaskModule`; in `StackedEgoMultiRLModule` every
`HeadView` reads its weights from the shared `EgoStack`. A dependent module holds an
*unregistered* reference to the shared one (`set_shared`), so the shared weights live in
one place, get one optimizer and are saved once; the reference is re-pointed whenever
modules are built or added.
"""

from __future__ import annotations

from typing import ClassVar

from ray.rllib.core.rl_module.multi_rl_module import MultiRLModule
from ray.rllib.core.rl_module.rl_module import RLModule


class SharedWiringMultiRLModule(MultiRLModule):
    """Points every module of type `DEPENDENT` at the module `SHARED_ID` (subclasses set both)."""

    SHARED_ID: ClassVar[str]
    DEPENDENT: ClassVar[type[RLModule]]

    def setup(self) -> None:
        super().setup()
        self._wire()

    def add_module(self, module_id: str, module: RLModule, *, override: bool = False) -> None:
        super().add_module(module_id, module, override=override)
        self._wire()

    def _wire(self) -> None:
        shared = self._rl_modules.get(self.SHARED_ID)
        for module in self._rl_modules.values():
            if isinstance(module, self.DEPENDENT):
                module.set_shared(shared)

    def head_ids(self) -> list[str]:
        """IDs of the dependent modules (the ego's heads or head views), in insertion order."""
        return [mid for mid, m in self._rl_modules.items() if isinstance(m, self.DEPENDENT)]
