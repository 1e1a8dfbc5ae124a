"""Adapt trained egos to new partners: keep the task module, add a fresh head, train with lam 0.

One adaptation curve is one (trained ego, new partner) pair: the ego is rebuilt from the
run's resolved config with the new partner as its only partner, the task module's weights
(and, for single-network methods, the head's) load from the run's checkpoint, and the ego
is evaluated before every update. All methods go through this one pipeline; `scratch`
starts from a fresh single network instead. With `head_init: pick` the first `pick_steps`
env steps try the fresh head and each training partner's head on the new partner instead
of training, and the best one's weights start the new head (`head_pick`). With
`head_init: posterior` the fresh head adapts as the paper's does, while the new partner's
moves in those env steps feed a posterior over which training partner's convention it
follows; the ego is evaluated playing by it (`convention_posterior.PosteriorPlayer`: on
blocks, the best response to its prediction of the partner), and once one known
convention is near certain the ego starts again from the trained ego with that partner's
head, which PPO fine-tunes from there. The posterior's information-parity controls
(`head_init` lookup, counts-planner, prior-planner; `common.adapters.CONTROLS`) learn of the
new partner only from its moves in those env steps as the ego's seat sees them
(`envs.seen_moves`: the ego's own observation and move, then the partner's action) and are
evaluated playing by them, the trained ego's task module alone where they have no move;
PPO still trains the fresh head beside them, so every curve spends the same env steps, but
they never play it. `head_init: plastic` (`adaptation.plastic`) does the same with PLASTIC's
belief over which training partner sits in each partner seat, from each seat's moves in its
situation as the ego's own observation shows it (`envs.seat_views`), and is evaluated playing
the trained ego's head for the most probable team. With `guard: true` (fresh or posterior) the ego
is evaluated as it was before any update until the adapting one is measured better on its
own training rollouts (`fine_tune_guard`); the rows then say whether the prior was kept.

In a game of more than two seats a new partner is a team, one partner per partner seat
(`H3+H4`; a single name sits in every seat): the curve's partner is the team's name, its
fresh head `ego@<team>`, every episode seats that team, and it is evaluated with the team in
its seats. By default a curve adapts to every team of the split. The adapters that choose among
one partner's heads or situations (pick, posterior, the controls) are refused there. An ego
with one head per partner seat and partner (`model.heads: seat`) adapts one fresh seat head
per seat; with `head_init: known-seats` a member it trained with in that seat keeps its
trained seat head instead (`known_seat_heads`), and PPO adapts them all.

Curves train in packs: one Tune trial (`AdaptTrainable`) holds up to `max_pack` curves of
egos that differ only in seed and partner, as replicas of one algorithm (each with its own
modules, seeds and game copy, so it trains as it would alone). Several adapt configs (a
whole `reproduce` stage) run as one Tune run (`run_adaptations`), so no core idles. A pack
writes its curves (`curves.csv` in its trial folder) when it finishes; a run that is
killed and started again keeps finished packs and runs the others again from their start.

Output: one tidy CSV per adapt config, one row per evaluation point: run, method, lam,
z_dim, seed, partner, steps, mean_return, stderr, exact_return (one-step games only), and
where an adapter chooses a trained head (pick, posterior, plastic), `picked`.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
from ray import tune

from rllib_conv import envs, partners
from rllib_conv.adaptation.context_lookup import ContextLookup
from rllib_conv.adaptation.convention_posterior import (
    ConventionPosterior,
    KnownConventions,
    PosteriorPlayer,
    known_conventions,
    require_action_probs,
)
from rllib_conv.adaptation.counts_planner import CountsPlanner
from rllib_conv.adaptation.fine_tune_guard import FineTuneGuard
from rllib_conv.adaptation.head_pick import HeadPick, pick_head
from rllib_conv.adaptation.plastic import Plastic
from rllib_conv.adaptation.prior_planner import PriorPlanner
from rllib_conv.adaptation.registry import (
    CONTROLS,
    FRESH,
    GUARD,
    KNOWN_SEATS,
    LOOKUP,
    PICK,
    PLASTIC,
    POSTERIOR,
    PRIOR_PLANNER,
    adapter,
    check_game,
    check_information,
    check_seats,
    check_trained_ego,
)
from rllib_conv.common.atomic_files import replaced_atomically
from rllib_conv.common.config_files import Checked
from rllib_conv.common.methods import method
from rllib_conv.common.run_folders import ADAPT, RL_MODULE_DIR, SEAT_HEADS_DIR, trial_folders
from rllib_conv.common.seeds import pick_seed
from rllib_conv.envs.seat_views import seat_view
from rllib_conv.modules import partner_id
from rllib_conv.modules.multi import AGG_HEAD_ID, TASK_ID, replica_id
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.partners.base import Partner
from rllib_conv.partners.population import PartnerEntry, Population, parse_team, team_name
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.training.algorithm import Replica, build_algorithm, packing_key
from rllib_conv.training.callbacks import STEPS_DONE, STEPS_TOTAL
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.ego_setup import EgoSetup, setup_for
from rllib_conv.training.evaluate import check_episodes, ego_head_partner, ego_task_partner, load_module, seated_return
from rllib_conv.training.experiment import ExperimentConfig, trial_config
from rllib_conv.training.replica_export import copy_replica, replica_module
from rllib_conv.training.replica_steps import replica_env_steps
from rllib_conv.training.settings import MappingSettings
from rllib_conv.training.stage import Stage, Table, run_packed, validated
from rllib_conv.training.trainable import AlgorithmTrainable
from rllib_conv.training.weights import learner_module, push_learner_weights

CURVES_FILE = "curves.csv"  # a finished pack's curves, in its trial folder
CURVE_COLUMNS = ["run", "method", "lam", "z_dim", "seed", "partner", "steps", "mean_return", "stderr", "exact_return"]
CURVES_TABLE = Table(CURVES_FILE, CURVE_COLUMNS, order=["run", "partner", "steps"], what="adaptation")


@dataclass
class Curve:
    """One adaptation curve to run: the ego setup adapting `run` to `partner`, the weights it starts from, its labels."""

    run: str
    partner: str
    setup: EgoSetup
    load: dict[str, str]
    trained: ExperimentConfig
    label: dict[str, Any]

    @property
    def team(self) -> tuple[str, ...]:
        """The new partner, one name per partner seat (one seat: the partner alone)."""
        return self.setup.teams[0]

    @property
    def head(self) -> str:
        """The new head: the one the ego adapts (`ego@<partner>`, `ego@<team>`; the one head of a single-network method)."""
        return self.setup.head_for(self.team)

    def seats(self, ego: Partner) -> dict[str, Partner]:
        """Every seat's player for one evaluation: `ego` in the ego's seat, a fresh copy of the new partner in each other."""
        entries = {e.name: e for e in self.setup.train}
        return {self.setup.ego_agent: ego} | {a: entries[n].build() for a, n in zip(self.setup.partner_agents, self.team)}


def _new_partner(pop: Population, partner: str) -> tuple[list[PartnerEntry], tuple[str, ...] | None]:
    """The entries a curve adapting to `partner` seats (each once, in seat order) and its team (None with one partner seat)."""
    if len(pop.partner_agents) == 1:
        entry = next((e for e in pop.partners if e.name == partner), None)
        if entry is None:
            raise ValueError(f"population {pop.name!r} has no partner {partner!r}; it has {[e.name for e in pop.partners]}")
        return [entry], None
    team = parse_team(pop, partner)
    entries = {e.name: e for e in pop.partners}
    return [entries[name] for name in dict.fromkeys(team)], team


def adapt_curve(cfg: AdaptConfig, run: str, partner: str) -> Curve:
    """The curve adapting the trained ego in folder `run` to `partner` (a team, in a game of several partner seats) under `cfg`;
    ValueError if it cannot."""
    trial = Path(run)
    trained = trial_config(trial)
    pop = partners.get(cfg.population or trained.population)
    game = trained.env
    if pop.env != game:
        raise ValueError(f"population {pop.name!r} is for {pop.env!r}, but the ego in {str(trial)!r} was trained on {game!r}")
    entries, team = _new_partner(pop, partner)
    seats = len(pop.partner_agents) + 1
    check_seats(cfg.head_init, game, seats)
    if cfg.guard:
        check_seats(GUARD, game, seats)
    check_trained_ego(cfg.head_init, method(trained.method), repr(str(trial)))
    check_information(cfg.head_init, game)
    if cfg.head_init == PLASTIC and partners.get(trained.population).partner_agents != pop.partner_agents:
        raise ValueError(
            f"head_init 'plastic' plays the heads the ego in {str(trial)!r} trained for teams in seats "
            f"{partners.get(trained.population).partner_agents}; population {pop.name!r} seats its partners in {pop.partner_agents}"
        )
    if adapter(cfg.head_init).uses["adapt"].training_policies:
        require_action_probs(partners.get(trained.population), f"head_init {cfg.head_init!r}")
    every, _, episodes = protocol(cfg, trained)
    check_episodes(episodes, game, trained.env_config)
    defaults = envs.game(game).adapt_defaults(trained.ppo.rollout_per_partner)
    batches = {k: getattr(defaults, k) for k in ("minibatch_size", "num_epochs") if getattr(defaults, k) is not None}
    ppo = trained.ppo.model_dump()
    ppo.update({"rollout_per_partner": every, **batches, **cfg.ppo})
    scratch = cfg.method == "scratch"
    exp = trained.model_copy(
        update={
            "lam": 0.0,
            "head_l2": 0.0,
            "method": "agg" if scratch else trained.method,
            "freeze": [] if cfg.train_task else ["task"],
            "ppo": type(trained.ppo).model_validate(ppo),
            "env_config": {**pop.env_config},
            "mapping": MappingSettings(),  # one partner: the training run's mapping does not apply
        }
    )
    newest = last_checkpoint(trial)  # verified once, for every module read from it
    checkpoint = newest / RL_MODULE_DIR
    load = {} if scratch else {TASK_ID: str(checkpoint / TASK_ID)}
    if method(exp.method).single_head and not scratch:
        load[AGG_HEAD_ID] = str(checkpoint / AGG_HEAD_ID)
    label = {
        "run": run,
        "method": cfg.method or trained.method,
        "lam": trained.lam,
        "z_dim": trained.model.z_dim or trained.model.hidden,
        "seed": trained.seed,
        "partner": partner if team is None else team_name(team),
    }
    setup = setup_for(exp, pop, entries, team)
    check_game(cfg.head_init, game, setup.env_config, setup.ego_agent)
    if cfg.head_init == KNOWN_SEATS:
        load |= known_seat_heads(newest, trained, setup)
    return Curve(run, partner, setup, load, trained, label)


def known_seat_heads(checkpoint: Path, trained: ExperimentConfig, setup: EgoSetup) -> dict[str, str]:
    """The seat heads of `setup`'s new team that the ego of `checkpoint` (its verified last one) trained (the member, in
    the same seat): module ID -> saved head (`head_init: known-seats`); ValueError if it has none or knows no member there."""
    saved, trial = checkpoint / SEAT_HEADS_DIR, str(checkpoint.parent)
    why = None
    if trained.model.heads != "seat":
        why = "has team heads"
    elif not setup.seat_heads:
        why = "plays a game of one partner seat (its heads are per partner)"
    elif not saved.is_dir():
        why = "keeps no seat heads (trained before they were saved apart: train it again)"
    if why is not None:
        raise ValueError(
            f"head_init 'known-seats' starts from the seat heads of an ego trained with model.heads: seat in a game of "
            f"more than two seats; the ego in {trial!r} {why}"
        )
    known = {mid: str(saved / mid) for mid in setup.weight_heads if (saved / mid).is_dir()}
    if not known:
        raise ValueError(
            f"head_init 'known-seats': no member of team {team_name(setup.teams[0])!r} trained with the ego in {trial!r} "
            f"in its seat (its seat heads: {sorted(p.name for p in saved.iterdir())}); use head_init fresh"
        )
    return known


def protocol(cfg: AdaptConfig, trained: ExperimentConfig) -> tuple[int, int, int]:
    """(every, steps, episodes): env steps between evaluations (one update each), the curve's length and the
    episodes per evaluation, defaults per game."""
    defaults = envs.game(trained.env).adapt_defaults(trained.ppo.rollout_per_partner)
    episodes = defaults.episodes if cfg.episodes is None else cfg.episodes
    return cfg.every or defaults.every, cfg.steps or defaults.steps, episodes


class AdaptTrainable(AlgorithmTrainable):
    """A pack of adaptation curves as replicas of one algorithm: evaluate all, update all, ... until `steps` env steps.

    Its config is a job (`job_param_space`): `config`, the adapt config, and `curves`, the
    (run, partner) pairs of the pack. The curves are checked to be packable (`packing_key`).
    """

    def outputs_complete(self, config: dict[str, Any]) -> bool:
        return (self.trial_folder / CURVES_FILE).is_file()

    def build(self, config: dict[str, Any]) -> None:
        job = config
        self.cfg = AdaptConfig.model_validate(job["config"])
        self.curves = [adapt_curve(self.cfg, c["run"], c["partner"]) for c in job["curves"]]
        self.replicas = [Replica(c.setup, c.load) for c in self.curves]
        self.algo = build_algorithm(self.replicas)
        _, self.total, self.episodes = protocol(self.cfg, self.curves[0].trained)
        module = learner_module(self.algo)
        self.plain = [replica_module(module, r, rep) for r, rep in enumerate(self.replicas)]  # evaluation copies
        k = len(self.curves)
        self.steps, self.offset = [0] * k, [0] * k  # offset: env steps spent picking the head, before the first update
        self.picked: list[str | None] = [None] * k
        self.finished = [False] * k
        self.rows: list[dict[str, Any]] = []
        self._trained: dict[str, Any] = {}  # run -> its trained ego, loaded once for all its curves
        if self.cfg.head_init == POSTERIOR:
            self._start_posteriors()
        if self.cfg.head_init in CONTROLS:
            self._start_controls()
        if self.cfg.head_init == PLASTIC:
            self._start_plastic()
        if self.cfg.guard:
            self._start_guards()

    def _start_guards(self) -> None:
        """Per curve: the ego before any update (kept for evaluation) and a guard; the runners keep every module's episode returns."""
        module = learner_module(self.algo)
        self.prior = [replica_module(module, r, rep) for r, rep in enumerate(self.replicas)]
        self.guards = [FineTuneGuard(self.cfg.guard_z) for _ in self.curves]
        self.ego_modules = [replica_id(c.head, r) for r, c in enumerate(self.curves)]
        self.algo.env_runner_group.foreach_env_runner(lambda runner: runner.record_module_returns(), local_env_runner=True)

    def _update_guards(self) -> None:
        """Give each curve's guard its adapting ego's returns in the episodes of the last sample."""
        returns: dict[str, list[float]] = {}
        for taken in self.algo.env_runner_group.foreach_env_runner(
            lambda runner: runner.take_module_returns(), local_env_runner=True
        ):
            for mid, values in taken.items():
                returns.setdefault(mid, []).extend(values)
        for guard, mid in zip(self.guards, self.ego_modules):
            guard.observe(returns.get(mid, []))

    def _trained_ego(self, run: str) -> Any:
        """The trained ego of `run` (its last checkpoint), loaded once per trial."""
        if run not in self._trained:
            self._trained[run] = load_module(last_checkpoint(run))
        return self._trained[run]

    def _start_posteriors(self) -> None:
        """Per curve: what its trained ego knows (shared by the curves of one run), an empty posterior; the new partner's moves recorded."""
        by_run: dict[str, KnownConventions] = {}
        for curve in self.curves:
            if curve.run not in by_run:
                by_run[curve.run] = known_conventions(
                    partners.get(curve.trained.population), self._trained_ego(curve.run), "head_init 'posterior'"
                )
        self.known = [by_run[c.run] for c in self.curves]
        self.handed: list[int | None] = [None] * len(self.curves)
        s = self.cfg.posterior
        self.posteriors = [
            ConventionPosterior(known.models, envs.convention_key(c.setup.population.env), s.recombined, s.novel, s.epsilon)
            for known, c in zip(self.known, self.curves)
        ]
        self.planners = [envs.best_response(c.setup.population.env, c.setup.env_config, c.setup.ego_agent) for c in self.curves]
        self.partner_modules = [replica_id(partner_id(c.setup.train[0].name), r) for r, c in enumerate(self.curves)]
        mids = self.partner_modules
        self.algo.env_runner_group.foreach_env_runner(
            lambda runner: [runner.module[m].record_moves() for m in mids], local_env_runner=True
        )

    def _update_posteriors(self) -> None:
        """Add the new partners' moves of the last update to their posteriors; hand a near-certain known convention's head over."""
        mids = self.partner_modules
        for moves in self.algo.env_runner_group.foreach_env_runner(
            lambda runner: {m: runner.module[m].take_moves() for m in mids}, local_env_runner=True
        ):
            for r, mid in enumerate(mids):
                if moves[mid] is not None:
                    self.posteriors[r].observe(*moves[mid])
        heads, tasks = {}, {}
        for r, posterior in enumerate(self.posteriors):
            post = posterior.hypotheses()[:-1]
            if self.handed[r] is None and post.max() >= self.cfg.posterior.handover:
                self.handed[r] = int(post.argmax())
                self.picked[r] = self.known[r].head_ids[self.handed[r]]
                # The trained ego with that head, as it was: the head fits the task module it was trained beside.
                trained = self._trained_ego(self.curves[r].run)
                heads[r], tasks[r] = trained[self.picked[r]].state_dict(), trained[TASK_ID].state_dict()
        self._load_new_heads(heads, tasks)

    def _start_controls(self) -> None:
        """Per curve: its control, knowing nothing of the new partner yet; the ego's seat records the partner's moves from now on."""
        s, self.controls = self.cfg.posterior, []
        for c in self.curves:
            game, env_config, ego = c.setup.population.env, c.setup.env_config, c.setup.ego_agent
            if self.cfg.head_init == LOOKUP:
                self.controls.append(ContextLookup(envs.convention_key(game)))
                continue
            planner = envs.best_response(game, env_config, ego)
            if self.cfg.head_init == PRIOR_PLANNER:
                models = [e.build() for e in partners.get(c.trained.population).entries("train")]
                self.controls.append(PriorPlanner(planner, models, s.recombined, s.novel, s.epsilon))
            else:
                self.controls.append(CountsPlanner(planner))
        egos = [c.setup.ego_agent for c in self.curves]
        self.algo.env_runner_group.foreach_env_runner(
            lambda runner: [env.unwrapped.record_seen_moves(egos) for env in runner.env.envs], local_env_runner=True
        )

    def _update_controls(self) -> None:
        """Give each curve's control the new partner's moves of the last update, as the ego's seat saw them."""
        for per_env in self.algo.env_runner_group.foreach_env_runner(
            lambda runner: [env.unwrapped.take_seen_moves() for env in runner.env.envs], local_env_runner=True
        ):
            for per_copy in per_env:
                for control, seen in zip(self.controls, per_copy):
                    if seen is not None:
                        control.observe(*seen)

    def _start_plastic(self) -> None:
        """Per curve: PLASTIC over its run's training partners, no evidence yet; the ego's seat records every partner seat's moves."""
        self.plastic = []
        for c in self.curves:
            game, env_config, ego = c.setup.population.env, c.setup.env_config, c.setup.ego_agent
            types = [e.build() for e in partners.get(c.trained.population).entries("train")]
            views = {agent: seat_view(game, env_config, ego, agent) for agent in c.setup.partner_agents}
            self.plastic.append(Plastic(types, views, self.cfg.posterior.epsilon))
        egos = [c.setup.ego_agent for c in self.curves]
        self.algo.env_runner_group.foreach_env_runner(
            lambda runner: [env.unwrapped.record_seen_moves(egos) for env in runner.env.envs], local_env_runner=True
        )

    def _update_plastic(self) -> None:
        """Give each curve's PLASTIC its partner seats' moves of the last update, as the ego's seat saw them."""
        for per_env in self.algo.env_runner_group.foreach_env_runner(
            lambda runner: [env.unwrapped.take_seen_moves(seated=True) for env in runner.env.envs], local_env_runner=True
        ):
            for per_copy in per_env:
                for belief, seen in zip(self.plastic, per_copy):
                    if seen is not None:
                        belief.observe(*seen)

    def _load_new_heads(self, states: dict[int, dict[str, Any]], tasks: dict[int, dict[str, Any]] | None = None) -> None:
        """Start replica r's new head from `states[r]` (a plain head's state dict) and its task module from `tasks[r]`, everywhere."""
        if not states:
            return

        def load(learner: Any) -> None:
            for r, state in states.items():
                learner.module[STACK_ID].load_head(r, 0, state)
            for r, state in (tasks or {}).items():
                learner.module[STACK_ID].load_task(r, state)

        self.algo.learner_group.foreach_learner(load)
        push_learner_weights(self.algo)

    def _player(self, r: int, plain: Any, head_id: str) -> Any:
        """The ego of curve r as it is evaluated: its new head (or, guarded and not yet trusted, the ego before any update), or the posterior player around it."""
        if self.cfg.guard and not self.guards[r].trusted:
            plain = self.prior[r]  # not yet measured better than the ego before any update
        if self.cfg.head_init in CONTROLS:  # the trained ego's task module alone where the control has no move
            return self.controls[r].player(head_id, ego_task_partner(self._trained_ego(self.curves[r].run)))
        if self.cfg.head_init == PLASTIC:
            self.picked[r] = self.plastic[r].head_id()
            return self.plastic[r].player(self._trained_ego(self.curves[r].run))
        adapting = ego_head_partner(plain, head_id)  # `player_return` seeds every player it plays
        if self.cfg.head_init != POSTERIOR:
            return adapting
        return PosteriorPlayer(
            head_id, self.posteriors[r], self.known[r].heads, adapting, self.handed[r], planner=self.planners[r]
        )

    def _pick_heads(self) -> list[HeadPick]:
        """Per curve: try the fresh head and every trained head on the new partner; copy the winner into the new head."""
        module, picks, chosen = learner_module(self.algo), [], {}
        for r, (curve, rep) in enumerate(zip(self.curves, self.replicas)):
            plain = copy_replica(module, r, rep, self.plain[r])
            entry, new_head = curve.setup.train[0], curve.setup.head_for(curve.setup.train[0].name)
            trained = self._trained_ego(curve.run)
            seed = pick_seed(self.cfg.seed)  # head-picking episodes, apart from the evaluation episodes
            players = {FRESH: ego_head_partner(plain, new_head, seed)}
            players |= {mid: ego_head_partner(trained, mid, seed) for mid in trained.head_ids()}
            game, env_config = curve.setup.population.env, curve.setup.env_config
            budget = self.cfg.pick_steps or curve.setup.exp.ppo.rollout_per_partner
            pick = pick_head(
                lambda: envs.make_scored(game, **env_config),  # heads are picked by the score, as they are judged
                players,
                entry.build,
                curve.setup.ego_agent,
                curve.setup.partner_agent,
                budget,
                seed,
            )
            if pick.chosen != FRESH:
                chosen[r] = trained[pick.chosen].state_dict()
            self.offset[r] = max(pick.steps, budget)
            picks.append(pick)
        self._load_new_heads(chosen)
        return picks

    def _evaluate(self) -> list[float]:
        """Evaluate every unfinished curve at its current steps (a row each); mark those at their end finished."""
        module, returns = learner_module(self.algo), []
        for r, (curve, rep) in enumerate(zip(self.curves, self.replicas)):
            if self.finished[r]:
                continue
            plain = copy_replica(module, r, rep, self.plain[r])
            score = seated_return(
                curve.seats(self._player(r, plain, curve.head)),
                curve.setup.population.env,
                curve.setup.env_config,
                self.episodes,
                seed=self.cfg.seed + self.iteration,
            )
            row = {
                **curve.label,
                "steps": self.steps[r],
                "mean_return": score["mean"],
                "stderr": score["stderr"],
                "exact_return": score.get("exact", math.nan),
            }
            if self.cfg.guard:
                row["prior_kept"] = not self.guards[r].trusted
            self.rows.append({**row, **({"picked": self.picked[r]} if self.picked[r] else {})})
            returns.append(score["mean"] if self.episodes else score["exact"])
            self.finished[r] = self.steps[r] >= self.total
        return returns

    def advance(self) -> dict[str, Any]:
        with self.timings.measure("evaluate"):
            returns = self._evaluate()
        done = all(self.finished)
        if done:
            self._write_curves()
        elif self.cfg.head_init == PICK and self.picked[0] is None:
            with self.timings.measure("evaluate"):
                self.picked = [p.chosen for p in self._pick_heads()]
            self.steps = list(self.offset)
        else:
            with self.timings.measure("iterate"):
                result = self.algo.train()
            with self.timings.measure("evaluate"):
                if self.cfg.head_init == POSTERIOR:
                    self._update_posteriors()
                if self.cfg.head_init in CONTROLS:
                    self._update_controls()
                if self.cfg.head_init == PLASTIC:
                    self._update_plastic()
                if self.cfg.guard:
                    self._update_guards()
            self.steps = [self.offset[r] + replica_env_steps(result, r) for r in range(len(self.curves))]
        return {
            "steps": min(self.steps),
            "mean_return": sum(returns) / len(returns),
            "curves": len(self.curves),
            STEPS_DONE: sum(min(s, self.total) for s in self.steps),
            STEPS_TOTAL: self.total * len(self.curves),
            "done": done,
        }

    def _write_curves(self) -> None:
        # Whole or absent: a pack counts as finished only with its curves.
        with replaced_atomically(self.trial_folder / CURVES_FILE) as tmp:
            pd.DataFrame(self.rows).to_csv(tmp, index=False)


def adaptation_curves(cfg: AdaptConfig) -> list[dict[str, str]]:
    """Every (run, partner) pair to adapt, validated before anything runs."""
    pairs = []
    for run in cfg.runs:
        for trial in trial_folders(run):
            last_checkpoint(trial)
            trained = trial_config(trial)
            pop = partners.get(cfg.population or trained.population)
            split = [e.name for e in pop.entries(cfg.split)]
            if len(pop.partner_agents) > 1:  # every team of the split, or the teams given (each by its canonical name)
                if cfg.partners:
                    names = [team_name(parse_team(pop, name)) for name in cfg.partners]
                else:
                    names = [name for name, _ in pop.teams(cfg.split)]
            else:
                names = cfg.partners or split
                unknown = set(names) - {e.name for e in pop.partners}
                if unknown:
                    raise ValueError(f"population {pop.name!r} has no partner(s) {sorted(unknown)}")
            pairs += [{"run": str(trial.resolve()), "partner": name} for name in names]
    if not pairs:
        raise ValueError(f"no partners to adapt to (split {cfg.split!r} is empty)")
    return pairs


def curve_packing_key(cfg: AdaptConfig, pair: dict[str, str]) -> Hashable:
    """What curves must share to pack into one trial (`algorithm.packing_key`): the curve of `pair` under `cfg`'s."""
    return packing_key(adapt_curve(cfg, pair["run"], pair["partner"]).setup)


def run_adaptations(
    configs: list[Checked[AdaptConfig]],
    out: str | Path = "adaptation",
    storage: str | Path = "runs",
    address: str | None = None,
    label: str | None = None,
    loggers: Sequence[str] = (),
) -> dict[str, pd.DataFrame]:
    """Adapt every run of every adapt config in `configs` (checked) in one Tune run; write and return each config's curves CSV by name.

    One config runs as the Tune experiment `adapt-<name>`; several as `adapt-stage-<hash>`
    (their specs' hash: the same configs continue the same run). `label` names the stage in
    its progress line (a `StageProgress`); without it every result prints a line.
    """
    cfgs = validated(configs, lambda config: config.first, "adapt")
    curves = [adaptation_curves(cfg) for cfg in cfgs]
    for cfg, pairs in zip(cfgs, curves):
        for pair in pairs:
            adapt_curve(cfg, pair["run"], pair["partner"])  # wrong game, missing weights: fail early
    stage = Stage(
        ADAPT,
        AdaptTrainable,
        tune.CheckpointConfig(checkpoint_at_end=False),
        units="curves",
        table=CURVES_TABLE,
        manifest_key="population",
    )
    raws = [config.raw for config in configs]
    return run_packed(
        stage, raws, cfgs, curves, lambda i, pair: curve_packing_key(cfgs[i], pair), out, storage, address, label, loggers
    )


def run_adaptation(
    config: Checked[AdaptConfig],
    out: str | Path = "adaptation",
    storage: str | Path = "runs",
    address: str | None = None,
    loggers: Sequence[str] = (),
) -> pd.DataFrame:
    """Adapt every run of the adapt config `config` (checked) to every chosen partner; write and return the tidy curves CSV."""
    return next(iter(run_adaptations([config], out, storage, address, loggers=loggers).values()))
