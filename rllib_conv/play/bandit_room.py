"""`BanditRoom`: the paper's user study as a room.

Train task then Test task (`envs.make("bandit", task="user_study"[, new_task=True])`),
contexts A, B, C in turn, 5 tries each. In a try both players pick an arm without seeing
the other's pick; when both have picked, both picks are revealed, the try is recorded (one
user-study CSV row) and the next try starts. The agent picks its arm at the start of a try,
before the person, from its policy alone, and learns from the person's arm after the reveal.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rllib_conv import envs
from rllib_conv.common.user_study_table import USER_STUDY_ARMS
from rllib_conv.play.agent import (
    AdaptiveAgent,
    Prior,
    bandit_observation,
    bandit_targets,
)
from rllib_conv.play.recording import SessionRecorder
from rllib_conv.play.room import (
    CONTEXT_NAMES,
    SEATS,
    STUDY_TASKS,
    TASK_LABELS,
    TRIES,
    PlayError,
    Room,
    parse_int,
)


class BanditRoom(Room):
    """The user-study bandit: Train then Test task, contexts A-C, `tries` tries each (module docstring)."""

    game = "bandit"

    def __init__(
        self,
        code: str,
        pair: int,
        mode: str,
        recorder: SessionRecorder,
        agent: AdaptiveAgent | None = None,
        agent_seat: int | None = None,
        priors: dict[str, Prior] | None = None,
        tries: int = TRIES,
    ) -> None:
        super().__init__(code, pair, mode, recorder)
        if not 1 <= tries <= TRIES:
            raise ValueError(f"tries must be in 1..{TRIES} (the user-study format), got {tries}")
        self.prizes = {task: envs.make("bandit", task="user_study", new_task=task == "test").prizes for task in STUDY_TASKS}
        self.schedule = [(task, c, t) for task in STUDY_TASKS for c in range(len(CONTEXT_NAMES)) for t in range(1, tries + 1)]
        self.tries = tries
        self.step = 0
        self.picks: dict[int, int | None] = {1: None, 2: None}  # 0-based arms of the current try
        self.history: list[dict[str, Any]] = []
        self.score = 0.0
        self.agent = agent
        self.agent_seat = agent_seat
        self.priors = priors or {}
        if agent is not None:
            if agent_seat not in SEATS:
                raise ValueError(f"agent_seat must be 1 or 2, got {agent_seat!r}")
            self.kinds[agent_seat] = "agent"
            self._agent_pick()

    @property
    def finished(self) -> bool:
        """Whether every try of both tasks has been played."""
        return self.step >= len(self.schedule)

    def _agent_pick(self) -> None:
        # The agent commits to its arm before the person picks: it never sees the person's choice.
        task, context, _ = self.schedule[self.step]
        self.agent.prior = self.priors[task]
        obs = bandit_observation(context, len(CONTEXT_NAMES))
        self.picks[self.agent_seat] = self.agent.act(obs, np.ones(USER_STUDY_ARMS, dtype=np.int8))

    def move(self, token: Any, payload: dict[str, Any]) -> dict[str, Any]:
        seat = self.seat_of(token)
        with self.lock:
            if self.finished:
                raise PlayError(409, f"the session is over: all {len(self.schedule)} tries have been played")
            if not self.full():
                raise PlayError(409, f"your partner has not joined yet: give them the room code {self.code}")
            arm = parse_int(payload.get("arm"), "arm", 1, USER_STUDY_ARMS) - 1
            if self.picks[seat] is not None:
                raise PlayError(409, f"you already picked arm {self.picks[seat] + 1} for this try; wait for your partner's pick")
            self.picks[seat] = arm
            if all(p is not None for p in self.picks.values()):
                try:
                    self._resolve()
                except (OSError, ValueError) as exc:
                    self.picks[seat] = None  # not recorded, so not played: the person picks again
                    raise PlayError(500, f"could not record this try ({exc}); your pick was not counted, please pick again") from None
            self._bump()
            return self.view(token)

    def _resolve(self) -> None:
        task, context, attempt = self.schedule[self.step]
        a1, a2 = self.picks[1], self.picks[2]
        prize = float(self.prizes[task][context, a1]) if a1 == a2 else 0.0
        row = {"pair": self.pair, "task": task, "context": CONTEXT_NAMES[context], "try": attempt, "action_1": a1 + 1, "action_2": a2 + 1}
        self.log.append([row])  # first: if recording fails, nothing below happens
        self.history.append({"task": task, "context": CONTEXT_NAMES[context], "try": attempt, "arms": {1: a1 + 1, 2: a2 + 1}, "prize": prize})
        self.score += prize
        if self.agent is not None:
            person = 3 - self.agent_seat
            self.agent.learn(bandit_targets(context, len(CONTEXT_NAMES), USER_STUDY_ARMS, self.picks[person]))
        self.step += 1
        self.picks = {1: None, 2: None}
        if self.agent is not None and not self.finished:
            self._agent_pick()

    def _status(self, seat: int) -> tuple[str, str]:
        """(phase, sentence) for `seat`: whose turn it is."""
        partner = "the agent" if self.partner_kind(seat) == "agent" else "your partner"
        if self.finished:
            return "finished", f"Session finished: {self.score:g} prize{'' if self.score == 1 else 's'} in {len(self.schedule)} tries. Thank you!"
        if not self.full():
            return "waiting_for_partner", f"Waiting for your partner to join: give them the room code {self.code}."
        if self.picks[seat] is None:
            task, context, attempt = self.schedule[self.step]
            if task == "test" and context == 0 and attempt == 1:
                # The prizes change under the players' feet: say so, as the study's interface moved to a new task.
                return "choose", "The Test task starts: the green arms have changed. Your turn: pick an arm."
            return "choose", "Your turn: pick an arm."
        return "waiting", f"You picked arm {self.picks[seat] + 1}. Waiting for {partner} to pick."

    def view(self, token: Any) -> dict[str, Any]:
        seat = self.seat_of(token)
        with self.lock:
            phase, status = self._status(seat)
            out = self._common_view(seat) | {
                "phase": phase,
                "status": status,
                "score": self.score,
                "played": self.step,
                "total": len(self.schedule),
                "tries": self.tries,
                "your_choice": None if self.picks[seat] is None else self.picks[seat] + 1,
                # Whether (never which arm) the partner has picked: the reveal waits for both.
                "partner_chose": self.picks[3 - seat] is not None and self.full(),
                "history": [self._mine(h, seat) for h in self.history],
            }
            out["last"] = out["history"][-1] if self.history else None
            if self.finished:
                out.update({"task": None, "task_label": None, "context": None, "try": None, "arms": []})
            else:
                task, context, attempt = self.schedule[self.step]
                prizes = self.prizes[task][context]
                out.update(
                    {
                        "task": task,
                        "task_label": TASK_LABELS[task],
                        "context": CONTEXT_NAMES[context],
                        "try": attempt,
                        "arms": [{"arm": a + 1, "prize": float(prizes[a])} for a in range(len(prizes))],
                    }
                )
            return out

    @staticmethod
    def _mine(h: dict[str, Any], seat: int) -> dict[str, Any]:
        return {"task": h["task"], "context": h["context"], "try": h["try"], "you": h["arms"][seat], "partner": h["arms"][3 - seat], "prize": h["prize"]}
