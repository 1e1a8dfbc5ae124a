"""The study's conditions and settings: who a participant plays with, built from the command line.

A condition is a name and a partner: `human` (two participants paired with each other) or
an adapting agent, each with a trained ego as its task module (`--agent NAME=RUN`; the
positional RUN is the agent named `agent`). `--conditions agent,human` (or e.g.
`ours,baseline`) lists the conditions participants are assigned to, balanced. Conditions
are named by the researcher and shown only on the admin page, with their description
(method, run, adaptation settings): participants see "the agent" or "another participant".

`build_settings` turns the arguments into `StudySettings` (loading the trained egos),
raising ValueError naming the argument for anything wrong.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

from rllib_conv.common.adapters import FRESH, POSTERIOR, choose, names
from rllib_conv.envs.bandit import user_study_prizes
from rllib_conv.play.agent import bandit_oracle_prior, uniform_prior
from rllib_conv.play.room import DEFAULT_GAMES, GAMES, SEATS, TRIES, AgentSettings

HUMAN = "human"
DEFAULT_AGENT = "agent"
ORACLE = "oracle"  # --agent NAME=oracle: the bandit's true marginals as task module (piloting without training)
TEST_PRIORS: tuple[str, ...] = ("oracle", "uniform")
# How agents adapt (`rllib_conv.common.adapters`): `fresh`, the paper's partner module learnt from the person (a table of
# logits, `agent.py`; `table` is its old spelling), or `posterior`, the convention posterior around it (`convention_agent.py`).
ADAPTERS: tuple[str, ...] = tuple(names(role="start", surface="play"))
NAME = re.compile(r"^[a-z][a-z0-9_-]{0,31}$")
CODE = re.compile(r"^[A-Za-z0-9_-]{1,64}$")
DEFAULT_CONSENT = (
    "This is a study of how people and AI agents coordinate in a simple game. You will play about "
    "30 short rounds with a partner (an AI agent or another participant); it takes about 10 minutes. "
    "We record only your choices in the game and the participant id you arrived with, and use them "
    "for research only. You may stop at any time by closing this page."
)


@dataclass(frozen=True)
class Condition:
    """One condition: its name, its agent (None: two participants) and a description for the admin page."""

    name: str
    agent: AgentSettings | None
    description: str

    @property
    def kind(self) -> str:
        """ "agent" (a person with an adapting agent) or "human" (two people)."""
        return "agent" if self.agent is not None else "human"


@dataclass
class StudySettings:
    """Everything a study server needs besides its database.

    `person_seat`: the seat of the person in agent conditions (None: opposite each trained
    ego); `pair_timeout`: seconds a participant of the human condition waits for a partner
    before the session ends; `idle_timeout`: seconds without a move before a room ends;
    `completion_code`: the code shown at the end (None: a random code per participant);
    `consent`: the consent text on the first page.
    """

    game: str
    conditions: list[Condition]
    new_task: bool = False
    tries: int = TRIES
    games: int = DEFAULT_GAMES
    seed: int = 0
    person_seat: int | None = None
    agent_delay: float = 0.6
    pair_timeout: float = 300.0
    idle_timeout: float = 600.0
    completion_code: str | None = None
    consent: str = DEFAULT_CONSENT

    def __post_init__(self) -> None:
        if self.game not in GAMES:
            raise ValueError(f"--game must be one of {list(GAMES)}, got {self.game!r}")
        if not self.conditions:
            raise ValueError("--conditions must name at least one condition")
        names = [c.name for c in self.conditions]
        if len(set(names)) != len(names):
            raise ValueError(f"--conditions lists a condition twice: {names}")
        if not 1 <= self.tries <= TRIES:
            raise ValueError(f"tries must be in 1..{TRIES}, got {self.tries}")
        if self.games < 1:
            raise ValueError(f"--games must be at least 1, got {self.games}")
        if self.person_seat is not None and self.person_seat not in SEATS:
            raise ValueError(f"--seat must be 1 or 2, got {self.person_seat}")
        for option, value in (("--pair-timeout", self.pair_timeout), ("--idle-timeout", self.idle_timeout)):
            if not value > 0:
                raise ValueError(f"{option} must be a positive number of seconds, got {value}")
        if self.completion_code is not None and not CODE.match(self.completion_code):
            raise ValueError(f"--completion-code must be 1-64 letters, digits, '-' or '_', got {self.completion_code!r}")
        if not self.consent.strip():
            raise ValueError("--consent: the consent text is empty")

    def condition(self, name: str) -> Condition:
        """The condition called `name` (KeyError if the study has none)."""
        return next(c for c in self.conditions if c.name == name)

    def replay_settings(self) -> dict[str, Any]:
        """What restored sessions replay with: a restart on the same database must keep these."""
        return {
            "game": self.game,
            "new_task": self.new_task,
            "tries": self.tries,
            "games": self.games,
            "seed": self.seed,
            "person_seat": self.person_seat,
        }


def parse_named(values: Sequence[str], option: str, default_name: str | None = None) -> dict[str, str]:
    """`NAME=VALUE` arguments as a dict; a bare VALUE takes `default_name` (ValueError if there is none, or a name repeats)."""
    out: dict[str, str] = {}
    for value in values:
        name, sep, rest = value.partition("=")
        if default_name is not None and (not sep or not NAME.match(name)):
            name, rest = default_name, value  # a bare VALUE (a path may hold '=' itself: .../seed=0)
        elif not sep:
            raise ValueError(f"{option} expects NAME=VALUE, got {value!r}")
        if not NAME.match(name):
            raise ValueError(
                f"{option}: condition name {name!r} must be 1-32 lower-case letters, digits, '-' or '_', starting with a letter"
            )
        if name in out:
            raise ValueError(f"{option} names {name!r} twice")
        if not rest:
            raise ValueError(f"{option} {value!r}: nothing after '='")
        out[name] = rest
    return out


def _test_prior(test_run: str | None, test_prior: str, name: str) -> tuple[Any, str]:
    """The agent's Test-task prior and its description: a trained ego's task module or a fixed rule."""
    if test_run is not None:
        from rllib_conv.play.ego_run import load_run, require_user_study  # torch and Ray load only with a run

        ego = load_run(test_run, f"--test-run {name}")
        require_user_study(ego, new_task=True, what=f"--test-run {name}")
        return ego.prior, f"Test task: {ego.describe()}"
    if test_prior == "oracle":
        return bandit_oracle_prior(user_study_prizes(new_task=True)), "Test task: the true marginals"
    return uniform_prior, "Test task: uniform over the arms"


def build_agent(
    name: str,
    run: str,
    game: str | None,
    test_run: str | None,
    test_prior: str,
    step_size: float,
    greedy: bool,
    seed: int,
    adapter: str = FRESH,
) -> tuple[str, AgentSettings, bool]:
    """(game, settings, new_task) of the agent `name` with its task module from `run` (or the oracle)."""
    adapt = f"adapts with step size {step_size:g}{', greedy' if greedy else ''}"
    if adapter == POSTERIOR:
        adapt += ", and by a posterior over its training partners' conventions (not in the paper)"
    if run == ORACLE:
        if adapter == POSTERIOR:
            raise ValueError(
                f"--adapter posterior: --agent {name}=oracle has no training partners' heads; give a trained modular run"
            )
        if game not in (None, "bandit"):
            raise ValueError(f"--agent {name}=oracle: the oracle agent is the bandit's true marginals; --game is {game!r}")
        test, test_words = _test_prior(test_run, test_prior, name)
        priors = {"train": bandit_oracle_prior(user_study_prizes(new_task=False)), "test": test}
        description = f"oracle task module (the true marginals), {adapt}; {test_words}"
        return (
            "bandit",
            AgentSettings(priors=priors, ego_seat=1, step_size=step_size, greedy=greedy, seed=seed, description=description),
            False,
        )

    from rllib_conv.play.ego_run import convention_source, load_run, require_user_study  # torch and Ray load only with a run

    what = "RUN" if name == DEFAULT_AGENT else f"--agent {name}"
    ego = load_run(run, what)
    game = game or ego.game
    if ego.game != game:
        raise ValueError(f"{what} {str(ego.trial)!r} was trained on {ego.game!r}, but --game is {game!r}")
    if game not in GAMES:
        raise ValueError(f"{what} {str(ego.trial)!r} was trained on {game!r}; play supports {list(GAMES)}")
    new_task = False
    conventions = convention_source(ego, what) if adapter == POSTERIOR else None
    if game == "bandit":
        require_user_study(ego, new_task=False, what=what)
        test, test_words = _test_prior(test_run, test_prior, name)
        priors = {"train": ego.prior, "test": test}
        description = f"{ego.describe()}; {adapt}; {test_words}"
    else:
        if test_run is not None:
            raise ValueError(f"--test-run {name}: the Test task is the bandit's; a blocks session plays the run's own task")
        new_task = bool(ego.env_config.get("new_task", False))
        priors = {"task": ego.prior}
        description = f"{ego.describe()}; {adapt}"
    settings = AgentSettings(
        priors=priors,
        ego_seat=ego.ego_seat,
        step_size=step_size,
        greedy=greedy,
        seed=seed,
        description=description,
        conventions=conventions,
    )
    return game, settings, new_task


def build_settings(
    run: str | Path | None = None,
    *,
    agents: Sequence[str] = (),
    conditions: str | None = None,
    game: str | None = None,
    test_runs: Sequence[str] = (),
    test_prior: str = "oracle",
    step_size: float = 3.0,
    greedy: bool = False,
    seed: int = 0,
    adapter: str = FRESH,
    **options: Any,
) -> StudySettings:
    """The study's settings from the `play` arguments (see its --help); ValueError naming the bad argument.

    Agents: the positional `run` (named "agent") and each `--agent NAME=RUN`. Bandit: each
    RUN must be an ego trained on the user-study Train task; on the Test task the prior is
    the task module of its `--test-run NAME=RUN2` or, without one, `test_prior` ("oracle":
    the true marginals; "uniform"). Blocks: RUN's task is the session's. `conditions`
    (comma-separated) defaults to every agent, or `human` without any. `adapter` "posterior"
    has every agent in the trained ego's seat adapt by the convention posterior too. `options` go to
    `StudySettings` as they are (tries, games, person_seat, timeouts, completion code, consent).
    """
    adapter = choose(adapter, "play", "start", "--adapter")
    if test_prior not in TEST_PRIORS:
        raise ValueError(f"--test-prior must be one of {list(TEST_PRIORS)}, got {test_prior!r}")
    if not (isinstance(step_size, (int, float)) and step_size > 0):
        raise ValueError(f"--step-size must be a positive number, got {step_size!r}")
    if game is not None and game not in GAMES:
        raise ValueError(f"--game must be one of {list(GAMES)}, got {game!r}")
    runs = parse_named(agents, "--agent")
    if run is not None:
        if DEFAULT_AGENT in runs:
            raise ValueError(f"RUN and --agent {DEFAULT_AGENT}=... both name the agent {DEFAULT_AGENT!r}; give one")
        runs = {DEFAULT_AGENT: str(run), **runs}
    if HUMAN in runs:
        raise ValueError(f"--agent: {HUMAN!r} is the two-person condition; give the agent another name")
    tests = parse_named(test_runs, "--test-run", DEFAULT_AGENT)
    for name in tests:
        if name not in runs:
            raise ValueError(
                f"--test-run {name}: no agent {name!r} (agents: {sorted(runs) or 'none; give RUN or --agent NAME=RUN'})"
            )
    names = [n.strip() for n in conditions.split(",")] if conditions is not None else (list(runs) or [HUMAN])
    for name in names:
        if name != HUMAN and name not in runs:
            raise ValueError(
                f"--conditions: {name!r} is neither {HUMAN!r} nor an agent given as RUN or --agent NAME=RUN (agents: {sorted(runs) or 'none'})"
            )
    unused = sorted(set(runs) - set(names))
    if unused:
        raise ValueError(f"--conditions {','.join(names)} leaves out the agent(s) {unused}; list them or drop them")

    built: dict[str, Condition] = {}
    new_tasks: dict[str, bool] = {}
    for name in names:
        if name == HUMAN:
            built[name] = Condition(HUMAN, None, "two participants paired with each other")
            continue
        agent_game, agent, new_task = build_agent(
            name, runs[name], game, tests.get(name), test_prior, step_size, greedy, seed, adapter
        )
        game = game or agent_game
        if agent_game != game:
            raise ValueError(f"--agent {name}: trained on {agent_game!r}, but the study plays {game!r}")
        new_tasks[name] = new_task
        built[name] = Condition(name, agent, agent.description)
    if len(set(new_tasks.values())) > 1:
        raise ValueError(f"the agents were trained on different blocks tasks ({new_tasks}); one study plays one task")
    settings = StudySettings(
        game=game or "bandit", conditions=[built[n] for n in names], new_task=any(new_tasks.values()), seed=seed, **options
    )
    for c in settings.conditions:
        if c.agent is not None and settings.person_seat == c.agent.ego_seat == 2 and settings.game == "blocks":
            raise ValueError(f"--seat 2: agent {c.name!r} was trained as P2 and there is no P1 agent; use --seat 1")
    return settings
