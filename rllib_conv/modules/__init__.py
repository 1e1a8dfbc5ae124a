"""RLlib modules: the shared task module, per-partner ego heads, fixed partners, and their wiring.

The paper's model is `task_module` (g^t) and `partner_head` (g^p_i: logits and values add
to the task module's); `multi` holds one ego as plain modules. `packed/` holds the packed
replicas that train (K egos' weights stacked and run batched), equal to K plain egos.
"""

from rllib_conv.modules.fixed_partner import FixedPartnerModule
from rllib_conv.modules.mapping import PartnerMapping
from rllib_conv.modules.multi import (
    AGG_HEAD_ID,
    TASK_ID,
    ConventionMultiRLModule,
    ego_id,
    partner_id,
)
from rllib_conv.modules.partner_head import PartnerHeadModule
from rllib_conv.modules.task_module import TaskModule

__all__ = [
    "AGG_HEAD_ID",
    "TASK_ID",
    "ConventionMultiRLModule",
    "FixedPartnerModule",
    "PartnerHeadModule",
    "PartnerMapping",
    "TaskModule",
    "ego_id",
    "partner_id",
]
