"""`ConventionMultiRLModule`: one trained ego as plain modules: a task module, one ego head per partner, fixed partners.

Module IDs: `task` (the shared task module, mapped to no agent), `ego@<partner>` (the
ego's head for that partner; `ego` alone for BaselineAgg's single head; `ego@<a>+<b>` for
the partners `a` and `b` in a game of three seats, `partners.population.team_name`) and
`partner@<partner>` (the fixed partner). Heads only hold a reference to the task module,
re-wired whenever modules are built or added, so its weights exist once.

This is the layout of a trained ego on disk (every trial folder's checkpoint) and of what
evaluation, adaptation, zero-shot and the web app read back. Training runs on the packed
form, `StackedEgoMultiRLModule`, whose replicas' IDs carry a suffix `#<r>` (`replica_id`).
"""

from __future__ import annotations

from rllib_conv.modules.partner_head import PartnerHeadModule
from rllib_conv.modules.shared_wiring import SharedWiringMultiRLModule
from rllib_conv.modules.task_module import TaskModule

TASK_ID = "task"
AGG_HEAD_ID = "ego"
EGO_PREFIX = "ego@"
PARTNER_PREFIX = "partner@"
REPLICA_SEPARATOR = "#"


def ego_id(partner_name: str) -> str:
    """Module ID of the ego head that plays with `partner_name`."""
    return EGO_PREFIX + partner_name


def partner_id(partner_name: str) -> str:
    """Module ID of the fixed partner `partner_name`."""
    return PARTNER_PREFIX + partner_name


def replica_id(module_id: str, replica: int | None) -> str:
    """`module_id` of replica `replica` (`ego@p` -> `ego@p#2`); None leaves it as it is."""
    return module_id if replica is None else f"{module_id}{REPLICA_SEPARATOR}{replica}"


class ConventionMultiRLModule(SharedWiringMultiRLModule):
    """MultiRLModule that wires every `PartnerHeadModule` to the shared `TaskModule`."""

    SHARED_ID = TASK_ID
    DEPENDENT = PartnerHeadModule

    @property
    def task(self) -> TaskModule:
        """The shared task module."""
        return self._rl_modules[TASK_ID]
