"""`BanditRoom`: the paper's user study as a room.

Train task then Test task (`envs.make("bandit", task="user_study"[, new_task=True])`),
contexts A, B, C in turn, 5 tries each. In a try both players pick an arm without seeing
the other's pick; when both have picked, the try is written to the database (one
user-study row), both picks are revealed and the next try starts. A person's pick made
before the partner's is written too, so it survives a restart. The agent picks its arm at
the start of a try, before the person, from its policy alone, and learns from the
person's arm after the reveal; its hidden pick is not stored (after a restart it picks
the try in progress again, which the person has not seen).
"""

from __future__ import annotations

import sqlite3
import time
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
from rllib_conv.play.room import (
    CONTEXT_NAMES,
    STUDY_TASKS,
    TASK_LABELS,
    TRIES,
    CallLater,
    PlayError,
    Room,
    parse_int,
    thread_call_later,
)
from rllib_conv.play.store import Store


class BanditRoom(Room):
    """The user-study bandit: Train then Test task, contexts A-C, `tries` tries each (module docstring)."""

    game = "bandit"

    def __init__(
        self,
        pair: int,
        store: Store,
        agent: AdaptiveAgent | None = None,
        agent_seat: int | None = None,
        priors: dict[str, Prior] | None = None,
        tries: int = TRIES,
        call_later: CallLater = thread_call_later,
    ) -> None:
        super().__init__(pair, store, agent, agent_seat, call_later)
        if not 1 <= tries <= TRIES:
            raise ValueError(f"tries must be in 1..{TRIES} (the user-study format), got {tries}")
        if agent is not None and set(priors or {}) != set(STUDY_TASKS):
            raise ValueError(f"an agent room needs a prior per task {list(STUDY_TASKS)}, got {sorted(priors or {})}")
        self.prizes = {task: envs.make("bandit", task="user_study", new_task=task == "test").prizes for task in STUDY_TASKS}
        self.schedule = [(task, c, t) for task in STUDY_TASKS for c in range(len(CONTEXT_NAMES)) for t in range(1, tries + 1)]
        self.tries = tries
        self.step = 0
        self.picks: dict[int, int | None] = {1: None, 2: None}  # 0-based arms of the current try
        self.history: list[dict[str, Any]] = []
        self.score = 0.0
        self.priors = priors or {}

    @property
    def finished(self) -> bool:
        return self.step >= len(self.schedule)

    def start(self) -> None:
        with self.lock:
            if self.agent is not None and not self.finished and self.picks[self.agent_seat] is None:
                self._agent_pick()

    def _agent_pick(self) -> None:
        # The agent commits to its arm before the person picks: it never sees the person's choice.
        task, context, _ = self.schedule[self.step]
        self.agent.prior = self.priors[task]
        obs = bandit_observation(context, len(CONTEXT_NAMES))
        self.picks[self.agent_seat] = self.agent.act(obs, np.ones(USER_STUDY_ARMS, dtype=np.int8))

    def move(self, seat: int, payload: dict[str, Any]) -> dict[str, Any]:
        with self.lock:
            if self.finished:
                raise PlayError(409, f"the session is over: all {len(self.schedule)} tries have been played")
            arm = parse_int(payload.get("arm"), "arm", 1, USER_STUDY_ARMS) - 1
            self._check_step(payload, self.step, "try")
            if self.picks[seat] is not None:
                raise PlayError(409, f"you already picked arm {self.picks[seat] + 1} for this try; wait for your partner's pick")
            picks = dict(self.picks)
            picks[seat] = arm
            try:
                if picks[3 - seat] is None:
                    self.store.add_pick(self.pair, self.step, seat, arm, time.time())
                else:
                    self.store.add_try(self.pair, self.step, self._row(picks), self._prize(picks), time.time())
            except sqlite3.Error as exc:
                raise PlayError(503, f"could not record your pick ({exc}); it was not counted, please pick again") from None
            self.picks = picks
            if picks[3 - seat] is not None:
                self._resolve()
            self._bump()
            return self.view(seat)

    def _row(self, picks: dict[int, int | None]) -> dict[str, Any]:
        task, context, attempt = self.schedule[self.step]
        return {
            "task": task,
            "context": CONTEXT_NAMES[context],
            "try": attempt,
            "action_1": picks[1] + 1,
            "action_2": picks[2] + 1,
        }

    def _prize(self, picks: dict[int, int | None]) -> float:
        task, context, _ = self.schedule[self.step]
        return float(self.prizes[task][context, picks[1]]) if picks[1] == picks[2] else 0.0

    def _resolve(self, next_pick: bool = True) -> None:
        """Reveal the try both have picked in (already written), learn, start the next one (the agent picks if `next_pick`)."""
        task, context, attempt = self.schedule[self.step]
        prize = self._prize(self.picks)
        self.history.append(
            {
                "task": task,
                "context": CONTEXT_NAMES[context],
                "try": attempt,
                "arms": {1: self.picks[1] + 1, 2: self.picks[2] + 1},
                "prize": prize,
            }
        )
        self.score += prize
        if self.agent is not None:
            self.agent.prior = self.priors[task]
            person = 3 - self.agent_seat
            picked = bandit_targets(context, len(CONTEXT_NAMES), USER_STUDY_ARMS, self.picks[person])
            self.agent.learn(picked)
            self.agent.watch(picked)  # on the bandit the hindsight target is the person's own move
        self.step += 1
        self.picks = {1: None, 2: None}
        if next_pick and self.agent is not None and not self.finished:
            self._agent_pick()

    def restore(self) -> None:
        with self.lock:
            for row in self.store.tries(self.pair):
                if row["step"] != self.step:
                    raise ValueError(f"room {self.pair}: the database skips from try {self.step} to {row['step']}")
                self.picks = {1: row["action_1"] - 1, 2: row["action_2"] - 1}
                self._resolve(next_pick=False)  # `start` draws the agent's pick for the try in progress
            for row in self.store.picks(self.pair):
                if row["step"] == self.step:
                    self.picks[row["seat"]] = row["action"]

    def _status(self, seat: int) -> tuple[str, str]:
        """(phase, sentence) for `seat`: whose turn it is."""
        if self.finished:
            return (
                "finished",
                f"Session finished: {self.score:g} prize{'' if self.score == 1 else 's'} in {len(self.schedule)} tries. Thank you!",
            )
        if self.picks[seat] is None:
            task, context, attempt = self.schedule[self.step]
            if task == "test" and context == 0 and attempt == 1:
                # The prizes change under the players' feet: say so, as the study's interface moved to a new task.
                return "choose", "Part 2 starts: the green arms have changed. Your turn: pick an arm."
            return "choose", "Your turn: pick an arm."
        return "waiting", f"You picked arm {self.picks[seat] + 1}. Waiting for {self._partner_words(seat)} to pick."

    def view(self, seat: int) -> dict[str, Any]:
        with self.lock:
            phase, status = self._status(seat)
            out = self._common_view(seat) | {
                "phase": phase,
                "status": status,
                "score": self.score,
                "step": self.step,
                "played": self.step,
                "total": len(self.schedule),
                "tries": self.tries,
                "your_choice": None if self.picks[seat] is None else self.picks[seat] + 1,
                # Whether (never which arm) the partner has picked: the reveal waits for both.
                "partner_chose": self.picks[3 - seat] is not None,
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
        return {
            "task": h["task"],
            "context": h["context"],
            "try": h["try"],
            "you": h["arms"][seat],
            "partner": h["arms"][3 - seat],
            "prize": h["prize"],
        }
