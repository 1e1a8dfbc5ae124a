"""`rllib-conv reproduce GAME`: every stage the paper's results for a game need, resumable.

What runs is the game's plan (`tune_configs/plan_<game>.yaml`, read by `plans`; `--plan FILE`
for an edited copy). Stages run in order, each through the ordinary pipelines (and so through Tune); everything
lands under `<out>/<game>/`:

| stage | what | output |
|---|---|---|
| `selfplay` | self-play partner populations (an entry with `populations: N`: `<name>-p0` ... `<name>-p<N-1>`) | `populations/<name>/` |
| `train` | egos: every method x lam x population x seed | `runs/<experiment>/` |
| `adapt` | adaptation curves to test partners (also another population's: `adapt_to`), the adapt-only variants (`scratch`, ...) included | `adaptation/<experiment>.csv` |
| `zeroshot` | the three zero-shot steps (bandit, blocks) | `zeroshot/<experiment>.csv` |
| `marginals` | task-module distance to the true marginals, every finished ego in `runs/` | `marginals.csv` |
| `heldout` | named agents with every member of a held-out population (Carroll et al.'s PPO_SP and PPO_BC with H_proxy) | `heldout.csv` |
| `evaluate` | every method trained on a population against the game's evaluation sets the plan names (`rllib-conv evaluate`) | `evaluation/<population>__<set>/` |

A finished stage leaves `<stage>.done`: its wall time, then the experiments it covered.
Running the command again skips a stage whose marker covers everything the plan asks of it;
a wider plan (more populations or methods than a narrowed earlier run) runs the stage again,
and inside it every finished experiment is skipped and an interrupted one continues (every
Tune experiment resumes). `quick` shrinks everything (1 seed, few partners, short runs) for
the demo and the tests.

Egos train for the paper's budget (blocks: 1M env steps). `train_steps` (`--train-steps`)
sets another; the train marker names each experiment's budget, so a folder trained with a
different one is not taken as done, and `fit` then refuses to mix the two.

`redo` (`--redo adapt|zeroshot|marginals|heldout|evaluate`) runs a finished stage again for the plan's
experiments, after a default or the code changed: their outputs (CSV and Tune folder) move
to `superseded/<time>/` under the game folder, never deleted, and the marker stops
covering them. Without it an unchanged config would find its finished Tune experiment and
return the old results.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from rllib_conv import envs, partners
from rllib_conv.common import config_files
from rllib_conv.common.atomic_files import replaced_atomically
from rllib_conv.common.resources import config_file
from rllib_conv.common.run_folders import (
    ADAPT,
    ADAPTATION_DIR,
    EVAL_FILE,
    EVALUATE,
    EVALUATION_DIR,
    HELDOUT,
    HELDOUT_FILE,
    MARGINALS,
    MARGINALS_FILE,
    MARKER_SUFFIX,
    PLAN_FILE,
    POPULATION_FILE,
    POPULATIONS_DIR,
    RUNS_DIR,
    SELFPLAY,
    SPEC_FILE,
    SUPERSEDED_DIR,
    TRAIN,
    ZEROSHOT,
    ZEROSHOT_DIR,
    config_run_name,
    experiment_name,
    experiment_of,
    marker_path,
    read_marker,
    read_trial_config,
    split_experiment,
    stage_run_prefix,
    trial_folders,
    write_marker,
)
from rllib_conv.envs.oracles import has_oracle
from rllib_conv.pipelines.adapt import run_adaptations
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.pipelines.evaluate import write_evaluation
from rllib_conv.pipelines.evaluate_config import EvaluateConfig
from rllib_conv.pipelines.evaluate_config import check as check_evaluation
from rllib_conv.pipelines.heldout import HeldoutAgent, members_agent, play_heldout, selfplay_agent, trained_agent
from rllib_conv.pipelines.marginal_report import marginal_report
from rllib_conv.pipelines.plans import GAMES, AdaptVariant, HeldoutAgentSpec, Plan, TrainedVariant, narrow, plan_for
from rllib_conv.pipelines.selfplay import train_populations
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from rllib_conv.pipelines.train import train_stage
from rllib_conv.pipelines.zeroshot import run_zeroshots
from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig
from rllib_conv.training.experiment import ExperimentConfig

# Stages `redo` can run again: the folder of each experiment's CSV (its Tune folder beside it), or the stage's one file. Training and
# self-play feed every later stage, so redoing those means a fresh output folder.
REDO_OUTPUTS = {
    ADAPT: ADAPTATION_DIR,
    ZEROSHOT: ZEROSHOT_DIR,
    MARGINALS: MARGINALS_FILE,
    HELDOUT: HELDOUT_FILE,
    EVALUATE: EVALUATION_DIR,
}
# What a problem in a stage's config is blamed on: the plan builds them, no file or `--set` holds them.
ARGUMENTS = "arguments"


def _merge(base: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in extra.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


class Reproduction:
    """Runs a `Plan`'s stages under `root`, skipping finished ones.

    Each stage builds its configs from the plan as raw dicts and checks them once
    (`config_files.checked`) before handing them to its pipeline.
    """

    def __init__(
        self, plan: Plan, root: Path, address: str | None = None, log: Callable[[str], None] = print, loggers: Sequence[str] = ()
    ) -> None:
        self.plan, self.root, self.address, self.log, self.loggers = plan, root, address, log, tuple(loggers)
        self.runs = root / RUNS_DIR

    def populations(self) -> dict[str, list[TrainedVariant]]:
        """Built-in populations plus this plan's self-play ones, each with its methods."""
        selfplay = {str(self.root / POPULATIONS_DIR / sp["name"]): self.plan.selfplay_methods for sp in self.plan.selfplay}
        return {**self.plan.populations, **selfplay}

    def experiment(self, population: str, method: TrainedVariant) -> dict[str, Any]:
        """The training experiment of one population and method, over the plan's seeds."""
        raw = {
            "name": experiment_name(population, method.label),
            "population": population,
            "seed": {"grid_search": self.plan.seeds},
            **method.settings,
        }
        raw = _merge(_merge(raw, self.plan.train_overrides), self.plan.population_overrides.get(population, {}))
        return raw if self.plan.train_steps is None else _merge(raw, {"run": {"timesteps": self.plan.train_steps}})

    def train_steps(self, experiment: dict[str, Any]) -> int:
        """The env steps each ego of `experiment` (an `experiment(...)` dict) trains for."""
        return experiment.get("run", {}).get("timesteps") or envs.game(self.plan.game).training_defaults().timesteps

    def stage_selfplay(self) -> None:
        """Train the plan's self-play populations not written yet, every pair of them in one Tune run."""
        todo = [o for o in self.plan.selfplay if not (self.root / POPULATIONS_DIR / o["name"] / POPULATION_FILE).is_file()]
        if not todo:
            return
        base = config_files.load(config_file(f"selfplay_{self.plan.game}.yaml"), schema=SelfPlayConfig)
        configs = [config_files.checked(_merge(base, overrides), SelfPlayConfig, ARGUMENTS) for overrides in todo]
        written = train_populations(
            configs,
            out=self.root / POPULATIONS_DIR,
            storage=self.runs,
            address=self.address,
            label=f"[{self.plan.game}] self-play",
            loggers=self.loggers,
        )
        for overrides, (_, report) in zip(todo, written):
            self.log(f"self-play {overrides['name']}: {int(report['passed'].sum())}/{len(report)} pairs passed the gate")

    def trained(self) -> list[tuple[str, TrainedVariant]]:
        """Every (population, method) whose egos this plan trains."""
        return [(p, m) for p, ms in self.populations().items() for m in ms]

    def variants(self, methods: list[TrainedVariant]) -> list[AdaptVariant]:
        """The plan's adapt-only variants whose base egos are among `methods`."""
        labels = {m.label for m in methods}
        return [v for v in self.plan.adapt_variants if v.base.label in labels]

    def training(self) -> list[dict[str, Any]]:
        """Every experiment this plan trains: its methods on its populations, then the zero-shot ones not among them."""
        experiments = [self.experiment(p, m) for p, m in self.trained()]
        experiments += [self.experiment(p, m) for p in self.plan.zeroshot_populations for m in self.plan.zeroshot_methods]
        return list({e["name"]: e for e in experiments}.values())

    def stage_train(self) -> None:
        configs = [config_files.checked(e, ExperimentConfig, ARGUMENTS) for e in self.training()]
        train_stage(configs, storage=self.runs, address=self.address, label=f"[{self.plan.game}] train", loggers=self.loggers)

    def adapt_jobs(self) -> list[tuple[str, str, dict[str, Any], str]]:
        """Every adaptation of this plan: (partners' population, experiment name, settings, experiment of the egos).

        The egos trained on a population adapt to its test partners (none: nothing) and to
        those of each population `adapt_to` names for it, with the adapt-only variants too.
        """
        trained, variants = [], []  # every trained method's adaptations first, then the adapt-only variants'
        for population, methods in self.populations().items():
            for target in [population, *self.plan.adapt_to.get(Path(population).name, [])]:
                if not self.has_test_partners(target):
                    continue
                for m in methods:
                    trained.append((target, experiment_name(target, m.label), {}, self.experiment(population, m)["name"]))
                for v in self.variants(methods):
                    base = self.experiment(population, v.base)["name"]
                    variants.append((target, experiment_name(target, v.label), v.settings, base))
        return trained + variants

    def has_test_partners(self, population: str) -> bool:
        """Whether `population` has test members (a self-play one of this plan not trained yet is taken to)."""
        if population.startswith(str(self.root / POPULATIONS_DIR)) and not (Path(population) / POPULATION_FILE).is_file():
            return True
        return bool(partners.get(population).entries("test"))

    def adapt_partners(self, population: str) -> list[str]:
        """The new partners the egos of `population` adapt to: its held-out partners, or with several partner seats every
        team of them (`H3+H4`), as `rllib-conv adapt` does, or the plan's `adapt_teams`; the plan's `adapt_partners` first ones."""
        names = self.plan.adapt_teams.get(population) or [name for name, _ in partners.get(population).teams("test")]
        return names[: self.plan.adapt_partners]

    def stage_adapt(self) -> None:
        configs = []
        for target, name, settings, egos_of in self.adapt_jobs():
            runs = self.egos(egos_of)
            if covers(self.root / ADAPTATION_DIR / f"{name}.csv", runs):
                continue
            names = self.adapt_partners(target)
            if not names:  # a self-play population whose test pairs all failed their gate
                continue
            raw = _merge({"name": name, "population": target, "partners": names}, {**self.plan.adapt_overrides, **settings})
            configs.append(config_files.checked({**raw, "runs": runs}, AdaptConfig, ARGUMENTS))
        if configs:
            label = f"[{self.plan.game}] adapt"
            run_adaptations(
                configs,
                out=self.root / ADAPTATION_DIR,
                storage=self.runs,
                address=self.address,
                label=label,
                loggers=self.loggers,
            )

    def egos(self, experiment: str) -> list[str]:
        """The trained egos of `experiment` with this plan's seeds (a folder may hold more, from a wider earlier plan)."""
        seeds = set(self.plan.seeds)
        return [str(t.resolve()) for t in trial_folders(self.runs / experiment) if read_trial_config(t).get("seed") in seeds]

    def stage_zeroshot(self) -> None:
        configs = []
        for population in self.plan.zeroshot_populations:
            for method in self.plan.zeroshot_methods:
                name = self.experiment(population, method)["name"]
                runs = self.egos(name)
                if not covers(self.root / ZEROSHOT_DIR / f"{name}.csv", runs):
                    raw = _merge({"name": name, "runs": runs}, self.plan.zeroshot_overrides)
                    configs.append(config_files.checked(raw, ZeroShotConfig, ARGUMENTS))
        if configs:
            label = f"[{self.plan.game}] zeroshot"
            run_zeroshots(
                configs, out=self.root / ZEROSHOT_DIR, storage=self.runs, address=self.address, label=label, loggers=self.loggers
            )

    def has_marginals(self, experiment: str) -> bool:
        """Whether the marginals stage measures experiment `<population>__<label>` (see `Plan.no_marginals`)."""
        return split_experiment(experiment)[0] not in self.plan.no_marginals

    def stage_marginals(self) -> None:
        experiments = [e for e in sorted(self.runs.glob("*__*")) if self.has_marginals(e.name)]
        # Finished egos only (their eval.json is written when training ends): another
        # process may be training an experiment in the same folder, or a killed wider
        # run may have left one whose training never began.
        trials = [t for exp in experiments for t in trial_folders(exp, missing_ok=True) if (t / EVAL_FILE).is_file()]
        table = marginal_report(trials)
        table["experiment"] = [experiment_of(r).name for r in table["run"]]
        table.to_csv(self.root / MARGINALS_FILE, index=False)

    def heldout_agent(self, label: str, spec: HeldoutAgentSpec) -> HeldoutAgent:
        """The held-out evaluation's agent `label` from what this plan trained (`pipelines/heldout.py`)."""
        if spec.selfplay is not None:
            return selfplay_agent(label, partners.get(str(self.root / POPULATIONS_DIR / spec.selfplay)))
        if spec.members is not None:
            return members_agent(label, partners.get(spec.members))
        method = next(m for m in self.populations()[spec.population] if m.label == spec.trained)
        return trained_agent(label, self.runs / self.experiment(spec.population, method)["name"], self.plan.seeds)

    def stage_heldout(self) -> None:
        spec = self.plan.heldout
        agents = [self.heldout_agent(label, a) for label, a in spec.agents.items()]
        self.log(f"[{self.plan.game}] heldout: {len(agents)} agents with every member of {spec.partners}")
        table = play_heldout(agents, partners.get(spec.partners), spec.episodes)
        with replaced_atomically(self.root / HELDOUT_FILE) as tmp:
            table.to_csv(tmp, index=False)

    def stage_evaluate(self) -> None:
        seeds = set(self.plan.seeds)
        for name in self.stage_experiments(EVALUATE):
            population, role = split_experiment(name)
            runs = [str(self.runs / self.experiment(population, m)["name"]) for m in self.plan.populations[population]]
            raw = {**self.plan.evaluate_overrides, "runs": runs, "eval_set": role}
            cfg = config_files.checked(raw, EvaluateConfig, ARGUMENTS).first
            found = check_evaluation(cfg)
            found = dataclasses.replace(found, egos=[e for e in found.egos if e.seed in seeds])  # this plan's seeds only
            self.log(f"[{self.plan.game}] evaluate: {len(found.egos)} egos of {population} against {found.eval_set.name}")
            command = ["rllib-conv", "evaluate", *runs, "--eval-set", role]
            command += [f"--{k}={v}" for k, v in self.plan.evaluate_overrides.items()]
            write_evaluation(cfg, found, self.root / EVALUATION_DIR / name, command)

    def stages(self) -> list[tuple[str, Callable[[], None]]]:
        """The plan's stages, in order."""
        stages = [(SELFPLAY, self.stage_selfplay), (TRAIN, self.stage_train), (ADAPT, self.stage_adapt)]
        if self.plan.zeroshot_populations:
            stages.append((ZEROSHOT, self.stage_zeroshot))
        if has_oracle(self.plan.game):
            stages.append((MARGINALS, self.stage_marginals))
        if self.plan.heldout is not None:
            stages.append((HELDOUT, self.stage_heldout))
        if self.plan.evaluate:
            stages.append((EVALUATE, self.stage_evaluate))
        return stages

    def run(self) -> dict[str, float]:
        """Run every unfinished stage; return the wall time of each stage run now."""
        self.root.mkdir(parents=True, exist_ok=True)
        stages = self.stages()
        # The items let a report tell a stage this plan finished from one an earlier, smaller plan finished.
        items = {n: self.stage_items(n) for n, _ in stages}
        plan = {
            "game": self.plan.game,
            "seeds": self.plan.seeds,
            "quick": self.plan.quick,
            "train_steps": self.plan.train_steps,
            "stages": list(items),
            "items": items,
        }
        plan["report"] = envs.game(self.plan.game).report_facts()  # what the report needs of the game (analysis reads files only)
        if self.plan.heldout is not None:  # what the report judges, declared before the run
            plan["heldout"] = {"partners": self.plan.heldout.partners, "claims": self.plan.heldout.claims}
        if self.plan.no_worse_margin is not None:
            plan["no_worse_margin"] = self.plan.no_worse_margin  # the "no worse" claims' margin, declared in the plan
        if self.plan.declared_seeds is not None:
            plan["declared_seeds"] = self.plan.declared_seeds  # the seeds the claims need, declared in the plan
        if self.plan.population_groups:
            # Independently trained self-play populations of one entry: the report pools them, population above seed.
            plan["population_groups"] = self.plan.population_groups
        (self.root / PLAN_FILE).write_text(json.dumps(plan, indent=2))
        times = {}
        for name, stage in stages:
            marker = marker_path(self.root, name)
            earlier, covered = read_marker(marker)
            missing = [i for i in items[name] if i not in covered]
            if marker.is_file() and not missing:
                self.log(f"[{self.plan.game}] {name}: done before, skipped")
                continue
            more = f" (not covered before: {', '.join(missing)})" if marker.is_file() else ""
            self.log(f"[{self.plan.game}] {name}: running{more}")
            start = time.perf_counter()
            stage()
            times[name] = time.perf_counter() - start
            write_marker(marker, earlier + times[name], [*covered, *missing])
            self.log(f"[{self.plan.game}] {name}: finished in {times[name]:.0f} s")
        return times

    def redo(self, stage: str) -> list[Path]:
        """Move this plan's outputs of `stage` to `superseded/<time>/` and uncover them in its marker; return where they went."""
        if stage not in REDO_OUTPUTS:
            raise ValueError(f"--redo: expected one of {sorted(REDO_OUTPUTS)}, got {stage!r}")
        items = self.stage_items(stage)
        if stage in (MARGINALS, HELDOUT):  # one file, no Tune run
            outputs = [self.root / REDO_OUTPUTS[stage]]
        elif stage == EVALUATE:  # a folder per (population, set), no Tune run
            outputs = [self.root / EVALUATION_DIR / n for n in self.stage_experiments(stage)]
        else:
            folder = REDO_OUTPUTS[stage]
            names = self.stage_experiments(stage)
            outputs = [p for n in names for p in (self.root / folder / f"{n}.csv", self.runs / config_run_name(stage, n))]
            outputs += stage_runs(self.runs, stage_run_prefix(stage), names)
        dest = self.root / SUPERSEDED_DIR / time.strftime("%Y%m%d-%H%M%S")
        moved = []
        for path in outputs:
            if path.exists():
                target = dest / path.relative_to(self.root)
                target.parent.mkdir(parents=True, exist_ok=True)
                moved.append(Path(shutil.move(path, target)))
        marker = marker_path(self.root, stage)
        if marker.is_file():
            seconds, covered = read_marker(marker)
            write_marker(marker, seconds, [c for c in covered if c not in items])
        self.log(f"[{self.plan.game}] {stage}: {len(moved)} output(s) moved to {dest}, to be redone")
        return moved

    def stage_experiments(self, stage: str) -> list[str]:
        """The experiments stage `stage` of this plan produces, by name."""
        trained = [self.experiment(p, m)["name"] for p, m in self.trained()]
        zeroshot = [self.experiment(p, m)["name"] for p in self.plan.zeroshot_populations for m in self.plan.zeroshot_methods]
        return {
            SELFPLAY: [sp["name"] for sp in self.plan.selfplay],
            TRAIN: [e["name"] for e in self.training()],
            ADAPT: [name for _, name, _, _ in self.adapt_jobs()],
            ZEROSHOT: zeroshot,
            MARGINALS: sorted(n for n in {*trained, *zeroshot} if self.has_marginals(n)),
            HELDOUT: sorted(self.plan.heldout.agents) if self.plan.heldout else [],
            EVALUATE: [experiment_name(p, role) for p, roles in self.plan.evaluate.items() for role in roles],
        }[stage]

    def stage_items(self, stage: str) -> list[str]:
        """What stage `stage` of this plan produces, one line per experiment (with the seeds), for its marker.

        Training items also name the egos' env steps: with another budget the stage runs
        again, and `fit` refuses to continue a folder trained for a different one.
        """
        seeds = f" seeds={','.join(map(str, self.plan.seeds))}"
        if stage == TRAIN:
            return [f"{e['name']}{seeds} steps={self.train_steps(e)}" for e in self.training()]
        return [name + seeds for name in self.stage_experiments(stage)]


def covers(csv: Path, runs: list[str]) -> bool:
    """Whether a stage's CSV holds rows of every one of `runs` (then that experiment is done for this plan)."""
    if not csv.is_file():
        return False
    try:
        return set(runs) <= set(pd.read_csv(csv, usecols=["run"])["run"])
    except (pd.errors.EmptyDataError, ValueError):
        return False


def stage_runs(runs: Path, prefix: str, experiments: list[str]) -> list[Path]:
    """The stage Tune runs `runs/<prefix><hash>/` that ran any of `experiments` (their spec lists them)."""
    found = []
    for folder in sorted(runs.glob(f"{prefix}*")):
        spec = config_files.read_yaml(folder / SPEC_FILE) if (folder / SPEC_FILE).is_file() else {}
        if set(spec.get("experiments", [])) & set(experiments):
            found.append(folder)
    return found


def reproduce(
    game: str,
    out: str | Path = "reproduce",
    seeds: int | None = None,
    quick: bool = False,
    address: str | None = None,
    populations: list[str] | None = None,
    methods: list[str] | None = None,
    redo: str | None = None,
    train_steps: int | None = None,
    plan_file: str | Path | None = None,
    loggers: Sequence[str] = (),
) -> dict[str, dict[str, float]]:
    """Run `game` (or `all`) under `<out>/<game>/`, each plan optionally `narrow`ed; return the stage wall times per game.

    `seeds` defaults to the seeds each plan declares (`plan_for`). `redo` names a finished
    stage to run again for the plan's experiments (see `Reproduction.redo`);
    `train_steps` replaces every ego's training budget (see `plan_for`); `plan_file` is a plan
    YAML to run instead of the shipped one (one game only). The report over `out` is built
    by `analysis.report.build_report`, which reads these folders (`rllib-conv reproduce` does both).
    `loggers` adds experiment tracking to every stage's Tune run (`tuning.logger_callbacks`).
    """
    games = GAMES if game == "all" else (game,)
    if plan_file is not None and len(games) > 1:
        raise ValueError("--plan: a plan file is for one game; name the game instead of 'all'")
    plans = [
        narrow(plan_for(g, seeds, quick, train_steps, plan_file), populations, methods) for g in games
    ]  # validate every game before running any
    times = {}
    for plan in plans:
        repro = Reproduction(plan, Path(out) / plan.game, address, loggers=loggers)
        if redo is not None:
            repro.redo(redo)
        times[plan.game] = repro.run()
    return times


def stage_table(root: str | Path) -> pd.DataFrame:
    """Which stages of the games under `root` are finished, and how long they took."""
    rows = []
    for marker in sorted(Path(root).glob(f"*/*{MARKER_SUFFIX}")):
        rows.append({"game": marker.parent.name, "stage": marker.stem, "wall": f"{read_marker(marker)[0]:.1f} s"})
    return pd.DataFrame(rows)
