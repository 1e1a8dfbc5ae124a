"""Self-play partner populations: train pairs through Tune, keep the partner seat of each pair that passes.

Each pair is one Tune trial (`SelfPlayTrainable`, seed `seed + pair`). Each seat has its
own policy module (`seat@player_0`, `seat@player_1`), or one module plays both seats
(`seat@all`, Hanabi; the env draws who moves first). Every `gate.check_every`
iterations the pair plays `gate.check_episodes` episodes as fixed partners would
(greedy by default); when that clears `gate.score` a `gate.episodes` evaluation decides.
A pair stops when it passes or when its step budget runs out; one that never passes is
reported and left out of the population.

The population folder is self-contained: `population.json`, `partners/<name>/` (the kept
seat's module), `counterparts/<name>/` (its self-play counterpart, for cross-play) and
`selfplay_report.csv` (every pair: seed, split, passed, score, steps to gate, wall time).

With `fcp` (Fictitious Co-Play, Strouse et al., NeurIPS 2021) a pair also snapshots its
partner seat before training and at every gate check (`fcp/` in its trial folder, with the
check's score); a passing pair adds the snapshot before training (`<name>-init`) and the one
whose score is nearest half its final score (`<name>-mid`, FCP's "past checkpoint") to the
population, in the pair's split, beside the final seat (`<name>`).

With `population_entropy` (Maximum-Entropy Population, Zhao et al., AAAI 2023) the pairs of
each split are one trial: one algorithm on a `ReplicatedGame` (a copy of the game per pair),
pair k of the split with its own seat modules (`seat@player_0#k`) and everything random
seeded from its own seed (initial weights, exploration, games, minibatch shuffles), so with
alpha 0 each pair trains exactly as it would in a population of one. The learner adds
`-alpha * PE` per seat, PE the entropy of the pairs' mean policy for that seat
(`learners.population_entropy`). The trial stops when one gate check sees every pair
clear the gate and the full evaluation confirms it, or when the budget is spent; the pairs
then export one by one, as separate pairs do.

With `trajectory_diversity` (TrajeDi, Lupu et al., ICML 2021) the pairs train together the
same way, and the learner adds `-beta * JSD` per seat, JSD the Jensen-Shannon divergence of
the pairs' trajectory distributions (`learners.trajectory_diversity`, with
`trajectory_discount`); it may be combined with `population_entropy`.

With `hidden_utility` (hidden-utility self-play, HSP; Yu et al., ICLR 2023) each pair trains
alone in the env config `SelfPlayConfig.pair_env_config` gives it: its partner seat rewarded
by a weighted count of its own events (`envs/overcooked/hidden_utility.py`), the weights
drawn from the pair's seed; the counterpart plays for the game's reward and the gate scores
the game. Each partner's manifest entry and report row keep its weights.
"""

from __future__ import annotations

import json
import math
import shutil
import time
from collections.abc import Sequence
from functools import partial
from pathlib import Path
from typing import Any

import pandas as pd
from ray import tune
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec

from rllib_conv import envs
from rllib_conv.common.atomic_files import folder_replaced_atomically
from rllib_conv.common.config_files import Checked
from rllib_conv.common.run_folders import (
    POPULATION_FILE,
    RL_MODULE_DIR,
    SELFPLAY,
    SELFPLAY_REPORT_FILE,
    SELFPLAY_TRIAL_FILE,
)
from rllib_conv.common.sealed import seal, verify
from rllib_conv.common.seeds import module_sampling_seed, pair_seed, shuffle_seed, stream_seed
from rllib_conv.envs.replicated_game import ReplicatedGame, replicated_env_config
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv, RLlibGame, game_env_config
from rllib_conv.learners.marginal_learner import MarginalPPOLearner
from rllib_conv.modules.multi import REPLICA_SEPARATOR, replica_id
from rllib_conv.modules.task_module import TaskModule
from rllib_conv.partners.episodes import score_episodes
from rllib_conv.partners.population import PartnerEntry, Population, refuse_existing
from rllib_conv.partners.trained import PolicyPartner
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from rllib_conv.training.algorithm import BASE_SEED, base_ppo_config
from rllib_conv.training.callbacks import STEPS_DONE, STEPS_TOTAL
from rllib_conv.training.stage import Stage, configs_spec, fit_stage
from rllib_conv.training.trainable import AlgorithmTrainable
from rllib_conv.training.tuning import job_param_space, trial_job
from rllib_conv.training.weights import learner_module

SEAT_PREFIX = "seat@"
SHARED_SEAT = "seat@all"


def seat_module_id(cfg: SelfPlayConfig, agent: str, member: int | None = None) -> str:
    """Module ID of the policy playing `agent`'s seat (of pair `member` of a split trained together, `seat@player_0#1`)."""
    return replica_id(SHARED_SEAT if cfg.shared_seats else SEAT_PREFIX + agent, member)


class SeatMapping:
    """Policy mapping for self-play: each seat to its own module, or every seat to one; `player_0#k` to pair k's."""

    def __init__(self, shared: bool) -> None:
        self.shared = shared

    def __call__(self, agent_id: str, episode: Any, **kwargs: Any) -> str:
        agent, sep, tag = agent_id.rpartition(REPLICA_SEPARATOR)
        member = int(tag) if sep and tag.isdigit() else None
        return replica_id(SHARED_SEAT if self.shared else SEAT_PREFIX + (agent if member is not None else agent_id), member)


def split_pairs(cfg: SelfPlayConfig, pair: int) -> list[int]:
    """The pairs the trial of `pair` trains: that pair alone, or with `population_entropy` every pair of its split."""
    if not cfg.joint:
        return [pair]
    if pair < cfg.train_pairs:
        return list(range(cfg.train_pairs))
    return list(range(cfg.train_pairs, cfg.train_pairs + cfg.test_pairs))


def trial_pairs(cfg: SelfPlayConfig) -> list[int]:
    """The `pair` of every trial: each pair, or with `population_entropy` the first pair of each split."""
    if not cfg.joint:
        return list(range(cfg.train_pairs + cfg.test_pairs))
    return [0] + ([cfg.train_pairs] if cfg.test_pairs else [])


def members(cfg: SelfPlayConfig) -> list[tuple[int | None, int]]:
    """(member, pair) of every pair the trial of `cfg.pair` trains; member None for a pair trained alone."""
    if not cfg.joint:
        return [(None, cfg.pair)]
    return list(enumerate(split_pairs(cfg, cfg.pair)))


def game_agents(cfg: SelfPlayConfig) -> list[str]:
    """The game's agents; ValueError unless `partner_agent` names every seat but one (the ego's)."""
    agents = list(envs.make(cfg.env, **cfg.env_config).possible_agents)
    seats = cfg.partner_agents
    if len(seats) != len(agents) - 1 or not set(seats) <= set(agents):
        want = "one of the game's two agents" if len(agents) == 2 else f"a list of {len(agents) - 1} of the game's agents"
        raise ValueError(f"partner_agent {cfg.partner_agent!r} must be {want} {agents} (every seat but the ego's)")
    return agents


def ego_seat(cfg: SelfPlayConfig) -> str:
    """The seat that is not a partner's: a member's counterpart plays it."""
    return next(a for a in game_agents(cfg) if a not in cfg.partner_agents)


def build_selfplay_config(cfg: SelfPlayConfig) -> PPOConfig:
    """Return the PPOConfig training pair `cfg.pair` by self-play."""
    env = PettingZooMultiAgentEnv(envs.make(cfg.env, **cfg.env_config))
    sizes = {"hidden": cfg.model.hidden, "z_dim": cfg.model.z_dim}
    specs = {
        seat_module_id(cfg, a): RLModuleSpec(
            module_class=TaskModule,
            observation_space=env.observation_spaces[a],
            action_space=env.action_spaces[a],
            model_config=sizes,
        )
        for a in game_agents(cfg)
    }
    shuffle_seeds = {mid: stream_seed(pair_seed(cfg.seed, cfg.pair), mid) for mid in specs}
    return (
        base_ppo_config(
            RLlibGame,
            game_env_config(cfg.env, cfg.pair_env_config(pair_seed(cfg.seed, cfg.pair))),
            cfg.ppo,
            cfg.run,
            pair_seed(cfg.seed, cfg.pair),
            cfg.ppo.rollout_per_partner,
        )
        # A list, not a set: see build_ppo_config.
        .multi_agent(policies=list(specs), policy_mapping_fn=SeatMapping(cfg.shared_seats), policies_to_train=list(specs))
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs=specs))
        # Each seat shuffles its minibatches with its own generator: RLlib's global one would
        # serve the seats in the order of a set of agent IDs, which follows the string hash seed.
        .learners(
            learner_class=MarginalPPOLearner,
            learner_config_dict=cfg.ppo.learner_settings(shuffle_seeds=shuffle_seeds).config_dict(),
        )
    )


def build_joint_config(cfg: SelfPlayConfig) -> PPOConfig:
    """Return the PPOConfig training the pairs of `cfg.pair`'s split together (MEP's `population_entropy`, TrajeDi's `trajectory_diversity`).

    Pair k of the split plays copy k of a `ReplicatedGame` with modules `seat@<agent>#k`,
    seeded from its own seed alone (see the module docstring); the learner's populations are
    the pairs' modules of each seat.
    """
    env = PettingZooMultiAgentEnv(envs.make(cfg.env, **cfg.env_config))
    sizes = {"hidden": cfg.model.hidden, "z_dim": cfg.model.z_dim}
    specs: dict[str, RLModuleSpec] = {}
    shuffle_seeds: dict[str, int] = {}
    populations: dict[str, list[str]] = {}
    pairs, agents = split_pairs(cfg, cfg.pair), game_agents(cfg)
    for member, pair in enumerate(pairs):
        seed = pair_seed(cfg.seed, pair)
        for agent in agents:
            base, mid = seat_module_id(cfg, agent), seat_module_id(cfg, agent, member)
            if mid in specs:  # shared seats: one module for both
                continue
            specs[mid] = RLModuleSpec(
                module_class=TaskModule,
                observation_space=env.observation_spaces[agent],
                action_space=env.action_spaces[agent],
                model_config={**sizes, "init_seed": stream_seed(seed, base), "sample_seed": module_sampling_seed(seed, base)},
            )
            shuffle_seeds[mid] = shuffle_seed(seed, base)
            populations.setdefault(base, []).append(mid)
    settings = cfg.ppo.learner_settings(
        shuffle_seeds=shuffle_seeds,
        population_entropy=float(cfg.population_entropy or 0.0),
        populations=populations,
        trajectory_diversity=float(cfg.trajectory_diversity or 0.0),
        trajectory_discount=cfg.discount,
    )
    env_config = replicated_env_config(cfg.env, cfg.env_config, [pair_seed(cfg.seed, p) for p in pairs], BASE_SEED)
    return (
        base_ppo_config(ReplicatedGame, env_config, cfg.ppo, cfg.run, BASE_SEED, cfg.ppo.rollout_per_partner)
        .multi_agent(policies=list(specs), policy_mapping_fn=SeatMapping(cfg.shared_seats), policies_to_train=list(specs))
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs=specs))
        .learners(learner_class=MarginalPPOLearner, learner_config_dict=settings.config_dict())
    )


def joint_description(cfg: SelfPlayConfig) -> str:
    """How a split's pairs trained together, for the population's description (MEP, TrajeDi or both)."""
    bonuses = []
    if cfg.population_entropy is not None:
        bonuses.append(f"population entropy {cfg.population_entropy} (MEP)")
    if cfg.trajectory_diversity is not None:
        bonuses.append(f"trajectory diversity {cfg.trajectory_diversity}, discount {cfg.discount} (TrajeDi)")
    return ", each split's pairs trained together with " + " and ".join(bonuses)


def seat_partner(module: Any, module_id: str, greedy: bool, seed: int = 0) -> PolicyPartner:
    """The seat policy `module_id` of a (multi-)module as a `Partner`."""
    policy = module[module_id]
    return PolicyPartner(module_id, lambda obs, mask: policy.policy(obs, mask).logits, greedy, seed)


def selfplay_score(module: Any, cfg: SelfPlayConfig, episodes: int, seed: int, member: int | None = None) -> float:
    """Mean self-play score of the pair's (pair `member`'s) seat policies, acting as fixed partners would (`envs.make_scored`)."""
    make_env = partial(envs.make_scored, cfg.env, **cfg.env_config)
    seats = {
        a: seat_partner(module, seat_module_id(cfg, a, member), cfg.greedy_partners, seed + i)
        for i, a in enumerate(make_env().possible_agents)
    }
    return float(score_episodes(make_env, seats, episodes, seed).mean())


FCP_DIR = "fcp"  # a trial's partner-seat snapshots (`fcp: true`)
FCP_INDEX = "snapshots.jsonl"  # one line per snapshot: folder, iteration, env steps, score


def fcp_snapshots(trial: Path) -> list[dict[str, Any]]:
    """The partner-seat snapshots a pair kept (`fcp: true`), in the order taken; [] if none."""
    index = trial / FCP_DIR / FCP_INDEX
    if not index.is_file():
        return []
    # A pair run again after a kill retakes the snapshots after its last checkpoint: the last line of a folder is its own.
    snapshots = {}
    for line in index.read_text().splitlines():
        if line:
            snapshot = json.loads(line)
            snapshots[snapshot["folder"]] = snapshot
    return list(snapshots.values())


def fcp_members(snapshots: list[dict[str, Any]], final_score: float) -> dict[str, dict[str, Any]]:
    """FCP's partners besides the final seat: the snapshot before training ("init") and the one between it and the
    last (the final seat itself) whose score is nearest half of `final_score` ("mid"; the earliest on a tie; none if
    the pair passed at its first check)."""
    if not snapshots:
        return {}
    chosen = {"init": snapshots[0]}
    later = snapshots[1:-1]
    if later:
        chosen["mid"] = min(later, key=lambda s: abs(s["score"] - final_score / 2))
    return chosen


class SelfPlayTrainable(AlgorithmTrainable):
    """One self-play pair, or a split's pairs trained together (MEP): trains until they pass the score gate or the step budget runs out."""

    def build(self, config: dict[str, Any]) -> None:
        self.cfg = SelfPlayConfig.model_validate(config).resolve()
        self.members = members(self.cfg)
        self.algo = (build_joint_config if self.cfg.joint else build_selfplay_config)(self.cfg).build_algo()
        self.passed = {pair: False for _, pair in self.members}
        self.score = {pair: math.nan for _, pair in self.members}
        self.steps_to_gate: int | None = None
        self._start = time.perf_counter()
        if self.cfg.fcp and not fcp_snapshots(self.trial_folder):  # a restored pair keeps the snapshots it took
            score = selfplay_score(self.algo.env_runner.module, self.cfg, self.cfg.gate.check_episodes, seed=100_000)
            self._snapshot(0, 0, score)

    def _snapshot(self, iteration: int, steps: int, score: float) -> None:
        """Save the partner seat's module as it is now, with the score of the check that saw it (`fcp: true`)."""
        folder = self.trial_folder / FCP_DIR
        name = f"it{iteration:06d}"
        learner_module(self.algo)[seat_module_id(self.cfg, self.cfg.partner_agents[0])].save_to_path(folder / name)
        with (folder / FCP_INDEX).open("a") as index:  # after the module: an indexed snapshot is always whole
            index.write(json.dumps({"folder": name, "iteration": iteration, "env_steps": steps, "score": score}) + "\n")

    def advance(self) -> dict[str, Any]:
        cfg, gate = self.cfg, self.cfg.gate
        with self.timings.measure("iterate"):
            result = self.algo.train()
        runners = result.get("env_runners", {})
        steps = int(runners.get("num_env_steps_sampled_lifetime", 0))
        first = cfg.partner_agents[0]  # shared rewards: any seat's return is the team's
        out = {
            "env_steps": steps,
            "train_return": float(runners.get("agent_episode_returns_mean", {}).get(first, math.nan)),
            STEPS_DONE: min(steps, cfg.run.timesteps),
            STEPS_TOTAL: cfg.run.timesteps,
        }
        budget_spent = steps >= cfg.run.timesteps
        module = self.algo.env_runner.module
        iteration = self.iteration + 1
        if iteration % gate.check_every == 0 or budget_spent:
            # Every pair must clear the check at once: the scores kept are those of the weights exported.
            out["gate_check"] = min(
                selfplay_score(module, cfg, gate.check_episodes, seed=100_000 + iteration, member=m) for m, _ in self.members
            )
            if cfg.fcp:
                self._snapshot(iteration, steps, out["gate_check"])
            if (out["gate_check"] >= gate.score and gate.stop) or budget_spent:
                for m, pair in self.members:
                    self.score[pair] = selfplay_score(module, cfg, gate.episodes, seed=pair_seed(cfg.seed, pair), member=m)
                    self.passed[pair] = self.score[pair] >= gate.score
                if all(self.passed.values()):
                    self.steps_to_gate = steps
        passed = all(self.passed.values())
        out.update({"gate_score": min(self.score.values()), "passed": passed, "done": passed or budget_spent})
        if out["done"]:
            wall_s = time.perf_counter() - self._start
            reports = [
                {
                    "pair": pair,
                    **({} if m is None else {"member": m}),
                    "seed": pair_seed(cfg.seed, pair),
                    "passed": self.passed[pair],
                    "score": self.score[pair],
                    # A pair trained with others reaches the gate when all of them do.
                    "steps_to_gate": self.steps_to_gate if self.passed[pair] else None,
                    "env_steps": steps,
                    "wall_s": wall_s,
                }
                for m, pair in self.members
            ]
            # One pair: its report; pairs trained together: the list of theirs.
            written = reports if cfg.joint else reports[0]
            (self.trial_folder / SELFPLAY_TRIAL_FILE).write_text(json.dumps(written, indent=2) + "\n")
            out.update({k: v for k, v in reports[0].items() if k not in out})
        return out


def _pair_reports(cfg: SelfPlayConfig, results: tune.ResultGrid) -> list[tuple[Any, dict[str, Any]]]:
    """(trial result, pair report) of every pair of `cfg` (a stage may train several configs' pairs), in pair order; a
    trial that wrote no report fails each of its pairs."""
    out = []
    for r in results:
        job = trial_job(r.config)
        if job.get("name", cfg.name) != cfg.name:
            continue
        report_path = Path(r.path) / SELFPLAY_TRIAL_FILE
        if report_path.is_file():
            written = json.loads(report_path.read_text())
            reports = written if isinstance(written, list) else [written]
        else:
            pairs = split_pairs(cfg, job["pair"])
            reports = [{"pair": p, "passed": False, "error": str(r.error)} for p in pairs]
        out.extend((r, report) for report in reports)
    return sorted(out, key=lambda item: item[1]["pair"])


def write_population(cfg: SelfPlayConfig, results: tune.ResultGrid, folder: Path) -> tuple[Population, pd.DataFrame]:
    """Copy each passing pair's seat modules into `folder` and write the manifest and report."""
    counterpart_agent = ego_seat(cfg)
    rows, entries = [], []
    for r, report in _pair_reports(cfg, results):
        pair = report["pair"]
        name = f"sp{pair:02d}"
        split = "train" if pair < cfg.train_pairs else "test"
        hidden = cfg.hidden_utility.draw(pair_seed(cfg.seed, pair)) if cfg.hidden_utility else None
        rows.append({"partner": name, "split": split, **report, **({"hidden_utility": json.dumps(hidden)} if hidden else {})})
        if not report.get("passed") or r.checkpoint is None:
            continue
        verify(r.checkpoint.path)
        modules = Path(r.checkpoint.path) / RL_MODULE_DIR
        for sub, agent in (("partners", cfg.partner_agents[0]), ("counterparts", counterpart_agent)):
            seal(shutil.copytree(modules / seat_module_id(cfg, agent, report.get("member")), folder / sub / name))
        params = {"greedy": cfg.greedy_partners, "seed": report["seed"]}
        trial = Path(r.path)
        for tag, snap in fcp_members(fcp_snapshots(trial), report["score"]).items():
            member = f"{name}-{tag}"
            seal(shutil.copytree(trial / FCP_DIR / snap["folder"], folder / "partners" / member))
            entries.append(
                PartnerEntry(
                    name=member,
                    kind="trained_policy",
                    params={"checkpoint": f"partners/{member}", **params},
                    split=split,
                    checkpoint=f"partners/{member}",
                    seed=report["seed"],
                    score=snap["score"],
                    hidden_utility=hidden,
                )
            )
        entries.append(
            PartnerEntry(
                name=name,
                kind="trained_policy",
                params={"checkpoint": f"partners/{name}", **params},
                split=split,
                checkpoint=f"partners/{name}",
                seed=report["seed"],
                score=report["score"],
                counterpart={
                    "name": f"{name}-counterpart",
                    "kind": "trained_policy",
                    "params": {"checkpoint": f"counterparts/{name}", **params},
                },
                hidden_utility=hidden,
            )
        )
    population = Population(
        name=cfg.name,
        env=cfg.env,
        env_config=cfg.env_config,
        partner_agent=cfg.partner_agent,
        description=f"self-play partners (seat {' or '.join(cfg.partner_agents)}), gate {cfg.gate.score} over {cfg.gate.episodes} episodes"
        + (", with each pair's start and midpoint (Fictitious Co-Play)" if cfg.fcp else "")
        + (joint_description(cfg) if cfg.joint else "")
        + (
            f", each pair's partner seat rewarded by its own weighted {', '.join(cfg.hidden_utility.events)} "
            "(hidden-utility self-play, HSP; weights per partner)"
            if cfg.hidden_utility
            else ""
        ),
        partners=entries,
    )
    population.save(folder / POPULATION_FILE)
    report = pd.DataFrame(rows)
    report.to_csv(folder / SELFPLAY_REPORT_FILE, index=False)
    return population, report


def train_population(
    config: Checked[SelfPlayConfig],
    out: str | Path = "populations",
    storage: str | Path = "runs",
    address: str | None = None,
    overwrite: bool = False,
    label: str | None = None,
    loggers: Sequence[str] = (),
) -> tuple[Population, pd.DataFrame]:
    """Train every pair of the self-play config `config` (checked: `config_files.load_checked`) and write the population to `out/<name>/`.

    `label` prints one progress line for all pairs (`StageProgress`) instead of one per
    result; `loggers` adds experiment tracking (`tuning.logger_callbacks`).

    The population is assembled in a temporary folder and moved into place only when
    complete, so a crash never leaves a half-written population (or replaces an old one).
    """
    return train_populations([config], out, storage, address, overwrite, label, loggers)[0]


def train_populations(
    configs: list[Checked[SelfPlayConfig]],
    out: str | Path = "populations",
    storage: str | Path = "runs",
    address: str | None = None,
    overwrite: bool = False,
    label: str | None = None,
    loggers: Sequence[str] = (),
) -> list[tuple[Population, pd.DataFrame]]:
    """`train_population` for several configs (names differ) as ONE Tune run: every pair of every config is a trial, so
    no core idles at one population's tail while the next waits; each population is written when all are trained."""
    cfgs = [config.first for config in configs]
    names = [cfg.name for cfg in cfgs]
    if len(set(names)) < len(names):
        raise ValueError(f"self-play configs must have different names; got {names}")
    targets = []
    for cfg in cfgs:
        game_agents(cfg)
        target = Path(out).resolve() / cfg.name
        refuse_existing(target, overwrite)
        targets.append(target)
    first = cfgs[0]
    checkpoint = tune.CheckpointConfig(num_to_keep=1, checkpoint_frequency=first.run.checkpoint_every, checkpoint_at_end=True)
    stage = Stage(SELFPLAY, SelfPlayTrainable, checkpoint, stops_early="a pair stops when it passes the gate")
    # One pair (or, MEP, one split's pairs) a trial: the units need no packing, and the trials' configs are the configs
    # with their pairs. One config keeps its own grid (and its run's name and spec); several are jobs.
    if len(configs) == 1:
        spec: Any = configs[0].raw
        space = {**configs[0].raw, "pair": tune.grid_search(trial_pairs(first))}
    else:
        spec = configs_spec([c.raw for c in configs], names)
        space = job_param_space([{**c.raw, "pair": pair} for c, cfg in zip(configs, cfgs) for pair in trial_pairs(cfg)])
    results = fit_stage(stage, spec, space, names, storage, address, label, loggers)
    written = []
    for cfg, target in zip(cfgs, targets):
        with folder_replaced_atomically(target) as staging:
            _, report = write_population(cfg, results, staging)
        written.append((Population.load(target / POPULATION_FILE), report))
    return written
