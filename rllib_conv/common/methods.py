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

TaskLogits = Literal["learned", "oracle", "unused"]
Output = Literal["task", "network"]


@dataclass(frozen=True)
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
        Method("modular", "ours (task module + one head per partner)", "learned", False, True, True, False, True, "task", "task"),
        Method("agg", "BaselineAgg", "learned", True, True, False, False, False, "network", "network"),
        Method("no_task_logits", "BaselineModular", "unused", False, False, False, False, True, None, None),
        Method("oracle", "oracle marginals", "oracle", False, False, False, False, True, None, "task"),
        Method("maml", "First-Order MAML", "learned", True, False, False, True, False, "network", "network"),
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
