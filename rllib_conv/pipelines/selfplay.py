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
"""

from __future__ import annotations

import json
import math
import shutil
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pandas as pd
from ray import tune
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec

from rllib_conv import envs
from rllib_conv.common.config_files import Checked
from rllib_conv.common.run_folders import (
    POPULATION_FILE,
    RL_MODULE_DIR,
    SELFPLAY,
    SELFPLAY_REPORT_FILE,
    SELFPLAY_TRIAL_FILE,
)
from rllib_conv.common.sealed import seal, verify
from rllib_conv.common.seeds import pair_seed, stream_seed
from rllib_conv.envs.rllib_adapter import PettingZooMultiAgentEnv, RLlibGame, game_env_config
from rllib_conv.learners.marginal_learner import MarginalPPOLearner
from rllib_conv.learners.settings import LearnerSettings
from rllib_conv.modules.task_module import TaskModule
from rllib_conv.partners.episodes import play_episodes
from rllib_conv.partners.population import PartnerEntry, Population
from rllib_conv.partners.trained import PolicyPartner
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from rllib_conv.training.algorithm import base_ppo_config
from rllib_conv.training.callbacks import STEPS_DONE, STEPS_TOTAL
from rllib_conv.training.stage import Stage, fit_stage
from rllib_conv.training.trainable import AlgorithmTrainable
from rllib_conv.training.weights import learner_module

SEAT_PREFIX = "seat@"
SHARED_SEAT = "seat@all"


def seat_module_id(cfg: SelfPlayConfig, agent: str) -> str:
    """Module ID of the policy playing `agent`'s seat."""
    return SHARED_SEAT if cfg.shared_seats else SEAT_PREFIX + agent


class SeatMapping:
    """Policy mapping for self-play: each seat to its own module, or every seat to one."""

    def __init__(self, shared: bool) -> None:
        self.shared = shared

    def __call__(self, agent_id: str, episode: Any, **kwargs: Any) -> str:
        return SHARED_SEAT if self.shared else SEAT_PREFIX + agent_id


def game_agents(cfg: SelfPlayConfig) -> list[str]:
    """The game's two agents; ValueError unless `partner_agent` is one of them."""
    agents = list(envs.make(cfg.env, **cfg.env_config).possible_agents)
    if len(agents) != 2 or cfg.partner_agent not in agents:
        raise ValueError(f"partner_agent {cfg.partner_agent!r} must be one of the game's two agents {agents}")
    return agents


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
            game_env_config(cfg.env, cfg.env_config),
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
            learner_config_dict=LearnerSettings(adam_eps=cfg.ppo.adam_eps, shuffle_seeds=shuffle_seeds).config_dict(),
        )
    )


def seat_partner(module: Any, module_id: str, greedy: bool, seed: int = 0) -> PolicyPartner:
    """The seat policy `module_id` of a (multi-)module as a `Partner`."""
    policy = module[module_id]
    return PolicyPartner(module_id, lambda obs, mask: policy.policy(obs, mask).logits, greedy, seed)


def selfplay_score(module: Any, cfg: SelfPlayConfig, episodes: int, seed: int) -> float:
    """Mean self-play score of the pair's seat policies, acting as fixed partners would (`envs.make_scored`)."""
    env = envs.make_scored(cfg.env, **cfg.env_config)
    seats = {
        a: seat_partner(module, seat_module_id(cfg, a), cfg.greedy_partners, seed + i) for i, a in enumerate(env.possible_agents)
    }
    return float(play_episodes(env, seats, episodes, seed).mean())


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
    """One self-play pair: trains until it passes the score gate or its step budget runs out."""

    def build(self, config: dict[str, Any]) -> None:
        self.cfg = SelfPlayConfig.model_validate(config).resolve()
        self.algo = build_selfplay_config(self.cfg).build_algo()
        self.passed, self.score, self.steps_to_gate = False, math.nan, None
        self._start = time.perf_counter()
        if self.cfg.fcp and not fcp_snapshots(self.trial_folder):  # a restored pair keeps the snapshots it took
            score = selfplay_score(self.algo.env_runner.module, self.cfg, self.cfg.gate.check_episodes, seed=100_000)
            self._snapshot(0, 0, score)

    def _snapshot(self, iteration: int, steps: int, score: float) -> None:
        """Save the partner seat's module as it is now, with the score of the check that saw it (`fcp: true`)."""
        folder = self.trial_folder / FCP_DIR
        name = f"it{iteration:06d}"
        learner_module(self.algo)[seat_module_id(self.cfg, self.cfg.partner_agent)].save_to_path(folder / name)
        with (folder / FCP_INDEX).open("a") as index:  # after the module: an indexed snapshot is always whole
            index.write(json.dumps({"folder": name, "iteration": iteration, "env_steps": steps, "score": score}) + "\n")

    def advance(self) -> dict[str, Any]:
        cfg, gate = self.cfg, self.cfg.gate
        with self.timings.measure("iterate"):
            result = self.algo.train()
        runners = result.get("env_runners", {})
        steps = int(runners.get("num_env_steps_sampled_lifetime", 0))
        first = cfg.partner_agent  # shared rewards: any seat's return is the team's
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
            out["gate_check"] = selfplay_score(module, cfg, gate.check_episodes, seed=100_000 + iteration)
            if cfg.fcp:
                self._snapshot(iteration, steps, out["gate_check"])
            if out["gate_check"] >= gate.score or budget_spent:
                self.score = selfplay_score(module, cfg, gate.episodes, seed=pair_seed(cfg.seed, cfg.pair))
                self.passed = self.score >= gate.score
                if self.passed:
                    self.steps_to_gate = steps
        out.update({"gate_score": self.score, "passed": self.passed, "done": self.passed or budget_spent})
        if out["done"]:
            report = {
                "pair": cfg.pair,
                "seed": pair_seed(cfg.seed, cfg.pair),
                "passed": self.passed,
                "score": self.score,
                "steps_to_gate": self.steps_to_gate,
                "env_steps": steps,
                "wall_s": time.perf_counter() - self._start,
            }
            (self.trial_folder / SELFPLAY_TRIAL_FILE).write_text(json.dumps(report, indent=2) + "\n")
            out.update({k: v for k, v in report.items() if k not in out})
        return out


def write_population(cfg: SelfPlayConfig, results: tune.ResultGrid, folder: Path) -> tuple[Population, pd.DataFrame]:
    """Copy each passing pair's seat modules into `folder` and write the manifest and report."""
    agents = game_agents(cfg)
    counterpart_agent = next(a for a in agents if a != cfg.partner_agent)
    rows, entries = [], []
    for r in sorted(results, key=lambda r: r.config["pair"]):
        pair = r.config["pair"]
        name = f"sp{pair:02d}"
        split = "train" if pair < cfg.train_pairs else "test"
        report_path = Path(r.path) / SELFPLAY_TRIAL_FILE
        report = (
            json.loads(report_path.read_text())
            if report_path.is_file()
            else {"pair": pair, "passed": False, "error": str(r.error)}
        )
        rows.append({"partner": name, "split": split, **report})
        if not report.get("passed") or r.checkpoint is None:
            continue
        verify(r.checkpoint.path)
        modules = Path(r.checkpoint.path) / RL_MODULE_DIR
        for sub, agent in (("partners", cfg.partner_agent), ("counterparts", counterpart_agent)):
            seal(shutil.copytree(modules / seat_module_id(cfg, agent), folder / sub / name))
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
            )
        )
    population = Population(
        name=cfg.name,
        env=cfg.env,
        env_config=cfg.env_config,
        partner_agent=cfg.partner_agent,
        description=f"self-play partners (seat {cfg.partner_agent}), gate {cfg.gate.score} over {cfg.gate.episodes} episodes"
        + (", with each pair's start and midpoint (Fictitious Co-Play)" if cfg.fcp else ""),
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
    cfg, raw = config.first, config.raw
    game_agents(cfg)
    target = Path(out).resolve() / cfg.name
    if target.exists() and not overwrite:
        raise ValueError(f"population folder {str(target)!r} already exists; choose another name or pass --overwrite")
    pairs = cfg.train_pairs + cfg.test_pairs
    checkpoint = tune.CheckpointConfig(num_to_keep=1, checkpoint_frequency=cfg.run.checkpoint_every, checkpoint_at_end=True)
    stage = Stage(SELFPLAY, SelfPlayTrainable, checkpoint, stops_early="a pair stops when it passes the gate")
    # One pair a trial: the units need no packing, and the trials' configs are the config with its pair.
    space = {**raw, "pair": tune.grid_search(list(range(pairs)))}
    results = fit_stage(stage, raw, space, [cfg.name], storage, address, label, loggers)
    target.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{cfg.name}.", dir=target.parent))
    try:
        population, report = write_population(cfg, results, staging)
        if target.exists():
            shutil.rmtree(target)
        staging.rename(target)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return Population.load(target / POPULATION_FILE), report
