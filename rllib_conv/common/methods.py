"""The method registry: one record per ego-training method (`method:` in configs), stating what it has and supports.

Every question of the kind "can this method do X" is answered here, never by a tuple of
names written where the question is asked: the configs (which settings a method takes),
the RLlib builder (one head or one per partner, task logits learned, replaced or unused),
adaptation, zero-shot composition, the marginals figure and the web app's agent.

A new method is one more `Method` record in `METHODS` plus whatever it does differently in
`rllib_conv.training` (see ARCHITECTURE.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from rllib_conv.common import adapters

TaskLogits = Literal["learned", "oracle", "unused"]
Output = Literal["task", "network"]


@dataclass(frozen=True, kw_only=True)
class Method:
    """What one ego-training method is made of and which pipelines and settings it supports."""

    name: str  # the `method:` value
    title: str  # the paper's name for it
    # The task module's logits in the policy: learned (added to the head's), the true
    # marginals (`oracle`), or not used at all (the policy is the head's alone).
    task_logits: TaskLogits
    # One ego head shared by every partner (a single network) instead of one head per partner.
    single_head: bool
    # Whether the marginal regulariser's weight `lam` may be above 0.
    regularised: bool
    # Whether the head penalty `head_l2` (not in the paper) may be above 0.
    head_penalty: bool
    # Trained by first-order MAML across the partners instead of plain PPO.
    meta_learned: bool
    # Zero-shot coordination can compose its task module with other partners' heads.
    composable: bool
    # Which learned output estimates the marginal best response (the marginals figure):
    # the task module, the whole single network, or none.
    marginals: Output | None
    # What the web app's agent uses as its prior over actions (the task module, the whole
    # network), or None when the method has no estimate of the marginals to play.
    prior: Output | None


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method(
            name="modular",
            title="ours (task module + one head per partner)",
            task_logits="learned",
            single_head=False,
            regularised=True,
            head_penalty=True,
            meta_learned=False,
            composable=True,
            marginals="task",
            prior="task",
        ),
        Method(
            name="agg",
            title="BaselineAgg",
            task_logits="learned",
            single_head=True,
            regularised=True,
            head_penalty=False,
            meta_learned=False,
            composable=False,
            marginals="network",
            prior="network",
        ),
        Method(
            name="no_task_logits",
            title="BaselineModular",
            task_logits="unused",
            single_head=False,
            regularised=False,
            head_penalty=False,
            meta_learned=False,
            composable=True,
            marginals=None,
            prior=None,
        ),
        Method(
            name="oracle",
            title="oracle marginals",
            task_logits="oracle",
            single_head=False,
            regularised=False,
            head_penalty=False,
            meta_learned=False,
            composable=True,
            marginals=None,
            prior="task",
        ),
        Method(
            name="maml",
            title="First-Order MAML",
            task_logits="learned",
            single_head=True,
            regularised=False,
            head_penalty=False,
            meta_learned=True,
            composable=False,
            marginals="network",
            prior="network",
        ),
    )
}
# The names as a type, for configs: pydantic checks a `method:` value against them.
MethodName = Literal[tuple(METHODS)]  # type: ignore[valid-type]


def method(name: str) -> Method:
    """The registry record of `name`; ValueError naming the known methods if there is none."""
    try:
        return METHODS[name]
    except KeyError:
        raise ValueError(f"unknown method {name!r}; known methods: {', '.join(METHODS)}") from None


def names(**having: object) -> list[str]:
    """The method names, in registry order; keyword filters keep those whose fields equal them (`names(composable=True)`)."""
    return [m.name for m in METHODS.values() if all(getattr(m, key) == value for key, value in having.items())]


# --- labels ---------------------------------------------------------------------------------------
# A label names one trained or adapted variant in a reproduce plan (`tune_configs/plan_<game>.yaml`),
# in the stage tables' file names (`<population>__<label>.csv`), the figures and the report. The
# variants the shipped plans define are named here, once; a user's plan may add labels of its own
# (the report then shows them under their label).


def lam_label(lam: float, base: str = "modular") -> str:
    """`modular-lam0.5`: ours trained with regulariser weight `lam` (`base` `lowz`: its low-dim z variant)."""
    return f"{base}-lam{float(lam):g}"


def row_label(method_name: str, lam: float) -> str:
    """A table row's label when its file names none: `lam_label` for a regularised method with lam > 0, else the method."""
    regularised = method_name in METHODS and METHODS[method_name].regularised
    return lam_label(lam, method_name) if regularised and float(lam) > 0 else str(method_name)


PAPER_LAM = 0.5  # the regulariser weight of the paper's method
PAPER_METHOD = lam_label(PAPER_LAM)  # ours, λ=0.5: the paper's method, the reference of every claim
LAM0 = lam_label(0.0)  # ours without the regulariser (fig:marginals)
LAM03 = lam_label(0.3)
LOW_Z = lam_label(PAPER_LAM, "lowz")  # ours with a low-dimensional z
HEAD_PENALTY = f"{PAPER_METHOD}-hl0.01"  # ours with the head penalty head_l2 0.01 (not in the paper)
SEAT_HEADS = f"{PAPER_METHOD}-seat"  # ours with a head per partner seat and partner, `model.heads: seat` (k seats)
SEAT_KNOWN = f"{SEAT_HEADS}-known"  # its egos adapting with the seat heads of a team's known members kept (k seats)
PICKED = f"{PAPER_METHOD}-pick"  # ours, adapting from a picked head (not in the paper)
HEAD_PENALTY_PICKED = f"{HEAD_PENALTY}-pick"
BC_TRAINED = f"{PAPER_METHOD}-bc"  # ours trained with Overcooked's BC proxies, as PPO_BC is (not in the paper)
GUARDED = f"{PAPER_METHOD}-guarded"  # ours, its fine-tuning guarded (not in the paper; Hanabi's plan)
BEYOND_POSTERIOR = "beyond-posterior"  # ours' egos adapting by the convention posterior (not in the paper)
BEYOND_GUARDED = "beyond-guarded"  # the same, its fine-tuning guarded (not in the paper)
BEYOND_PLASTIC = "beyond-plastic"  # ours' egos adapting by PLASTIC-Policy, the ad hoc teamwork reference (k seats)
# The posterior's information-parity controls (not in the paper; `common.adapters.CONTROLS`).
CONTROL_LOOKUP = "control-lookup"  # bandit: the partner's arm per seen context, else the task marginal
CONTROL_COUNTS = "control-counts-planner"  # blocks: the planner against a model of the partner's own moves
CONTROL_PRIOR = "control-prior-planner"  # blocks: the planner against the posterior's prior, frozen
CONTROL_LABELS: tuple[str, ...] = (CONTROL_LOOKUP, CONTROL_COUNTS, CONTROL_PRIOR)
# The adapters (`common.adapters`) behind each shipped label that adapts by more than the paper's fresh head (the
# report's "information used"; every other label adapts by the fresh head): the shipped plans' settings, checked by a test.
ADAPTED_BY: dict[str, tuple[str, ...]] = {
    GUARDED: (adapters.FRESH, adapters.GUARD),
    PICKED: (adapters.PICK,),
    HEAD_PENALTY_PICKED: (adapters.PICK,),
    BEYOND_POSTERIOR: (adapters.POSTERIOR,),
    BEYOND_GUARDED: (adapters.POSTERIOR, adapters.GUARD),
    BEYOND_PLASTIC: (adapters.PLASTIC,),
    SEAT_KNOWN: (adapters.KNOWN_SEATS,),
    CONTROL_LOOKUP: (adapters.LOOKUP,),
    CONTROL_COUNTS: (adapters.COUNTS_PLANNER,),
    CONTROL_PRIOR: (adapters.PRIOR_PLANNER,),
}
SCRATCH = "scratch"  # adapting a fresh network (seeded as ours)
PPO_BC = "ppo_bc"  # BaselineAgg trained with Overcooked's BC proxies: Carroll et al.'s PPO_BC, their human-aware agent
BASELINES: tuple[str, ...] = ("agg", "no_task_logits", "maml")  # the paper's baselines, by method name
# Variants beyond the paper's: the reports list them apart from the paper's claims.
EXTENSIONS: tuple[str, ...] = (
    HEAD_PENALTY,
    SEAT_HEADS,
    SEAT_KNOWN,
    PICKED,
    HEAD_PENALTY_PICKED,
    GUARDED,
    BC_TRAINED,
    BEYOND_POSTERIOR,
    BEYOND_GUARDED,
    BEYOND_PLASTIC,
    *CONTROL_LABELS,
)
# Every label of the shipped plans, in the order figures and tables show them.
LABELS: tuple[str, ...] = (LAM0, LAM03, PAPER_METHOD, *EXTENSIONS, LOW_Z, *BASELINES, PPO_BC, "oracle", SCRATCH)
