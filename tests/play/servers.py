"""Helpers of the play tests: studies that need no training, the real `rllib-conv play` in a subprocess."""

from __future__ import annotations

from rllib_conv.play.conditions import StudySettings, build_settings
from rllib_conv.play.simulated import ServerProcess

ADMIN_TOKEN = "test-admin-token"


def oracle_study(conditions: str = "agent,human", **options) -> StudySettings:
    """A bandit study whose agent condition plays the oracle agent (no training needed)."""
    agents = ["agent=oracle"] if "agent" in conditions.split(",") else []
    return build_settings(agents=agents, conditions=conditions, **options)


class StudyProcess(ServerProcess):
    """`rllib-conv play ARGS` with the tests' admin token."""

    def __init__(self, args: list[str]) -> None:
        super().__init__([*args, "--admin-token", ADMIN_TOKEN])
