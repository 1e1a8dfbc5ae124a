"""`rllib-conv reproduce GAME`: every stage the paper's results for a game need, resumable.

Stages run in order, each through the ordinary pipelines (and so through Tune); everything
lands under `<out>/<game>/`:

| stage | what | output |
|---|---|---|
| `selfplay` | self-play partner populations | `populations/<name>/` |
| `train` | egos: every method x lam x population x seed | `runs/<experiment>/` |
| `adapt` | adaptation curves to test partners, the adapt-only variants (`scratch`, ...) included | `adaptation/<experiment>.csv` |
| `zeroshot` | the three zero-shot steps (bandit, blocks) | `zeroshot/<experiment>.csv` |
| `marginals` | task-module distance to the true marginals, every finished ego in `runs/` | `marginals.csv` |

A finished stage leaves `<stage>.done`: its wall time, then the experiments it covered.
Running the command again skips a stage whose marker covers everything the plan asks of it;
a wider plan (more populations or methods than a narrowed earlier run) runs the stage again,
and inside it every finished experiment is skipped and an interrupted one continues (every
Tune experiment resumes). `quick` shrinks everything (1 seed, few partners, short runs) for
the demo and the tests.

Egos train for the paper's budget (blocks: 1M env steps). `train_steps` (`--train-steps`)
sets another; the train marker names each experiment's budget, so a folder trained with a
different one is not taken as done, and `fit` then refuses to mix the two.

`redo` (`--redo adapt|zeroshot|marginals`) runs a finished stage again for the plan's
experiments, after a default or the code changed: their outputs (CSV and Tune folder) move
to `superseded/<time>/` under the game folder, never deleted, and the marker stops
covering them. Without it an unchanged config would find its finished Tune experiment and
return the old results.
"""

from __future__ import annotations

import json
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import pandas as pd

from analysis.loaders import split_experiment
from rllib_conv import config, partners
from rllib_conv.config import GAME_DEFAULTS, SelfPlayConfig
from rllib_conv.pipelines.adapt import TUNE_PREFIX as ADAPT_PREFIX
from rllib_conv.pipelines.adapt import run_adaptation
from rllib_conv.pipelines.marginals import marginal_report
from rllib_conv.pipelines.selfplay import train_population
from rllib_conv.pipelines.train import EVAL_FILE, run
from rllib_conv.pipelines.zeroshot import TUNE_PREFIX as ZEROSHOT_PREFIX
from rllib_conv.pipelines.zeroshot import run_zeroshot

GAMES = ("bandit", "blocks", "hanabi")
CONFIGS = Path(__file__).resolve().parents[2] / "tune_configs"


@dataclass
class Method:
    """One trained-ego variant: a label for tables and the config keys it sets."""

    label: str
    settings: dict[str, Any]


MODULAR_05 = Method("modular-lam0.5", {"method": "modular", "lam": 0.5})
BANDIT_METHODS = [
    Method("modular-lam0", {"method": "modular", "lam": 0.0}),
    Method("modular-lam0.3", {"method": "modular", "lam": 0.3}),
    MODULAR_05,
    Method("lowz-lam0.5", {"method": "modular", "lam": 0.5, "model": {"z_dim": 5}}),
    Method("agg", {"method": "agg"}),
    Method("no_task_logits", {"method": "no_task_logits"}),
    Method("maml", {"method": "maml"}),
    Method("oracle", {"method": "oracle"}),
]
# Not in the paper: ours with the head penalty (`head_l2`), so heads hold conventions only.
HEAD_PENALTY_05 = Method("modular-lam0.5-hl0.01", {"method": "modular", "lam": 0.5, "head_l2": 0.01})
BLOCKS_METHODS = [
    Method("modular-lam0", {"method": "modular", "lam": 0.0}),
    MODULAR_05,
    HEAD_PENALTY_05,
    Method("lowz-lam0.5", {"method": "modular", "lam": 0.5, "model": {"z_dim": 20}}),
    Method("agg", {"method": "agg"}),
    Method("no_task_logits", {"method": "no_task_logits"}),
    Method("maml", {"method": "maml"}),
    Method("oracle", {"method": "oracle"}),
]
# Partners other than hand-designed ones: the comparison the paper draws (ours vs baselines).
CORE_METHODS = [MODULAR_05, Method("agg", {"method": "agg"}), Method("no_task_logits", {"method": "no_task_logits"}), Method("maml", {"method": "maml"})]
HANABI_METHODS = [MODULAR_05, Method("agg", {"method": "agg"})]
ZEROSHOT_METHODS = [MODULAR_05, Method("no_task_logits", {"method": "no_task_logits"})]


@dataclass
class AdaptVariant:
    """Adaptation only: adaptation `settings` applied to the trained egos of `base` (nothing more is trained)."""

    label: str
    base: Method
    settings: dict[str, Any]


# `scratch` only borrows the modular egos' seeds: it adapts a fresh network.
SCRATCH = AdaptVariant("scratch", MODULAR_05, {"method": "scratch"})
# Not in the paper: adapt from the best of the fresh head and the training partners' heads.
HEAD_PICK_05 = AdaptVariant("modular-lam0.5-pick", MODULAR_05, {"head_init": "pick"})
HEAD_PENALTY_PICK_05 = AdaptVariant("modular-lam0.5-hl0.01-pick", HEAD_PENALTY_05, {"head_init": "pick"})


@dataclass
class Plan:
    """What to run for one game at one scale."""

    game: str
    seeds: list[int]
    populations: dict[str, list[Method]]  # built-in population -> methods trained and adapted on it
    selfplay: list[dict[str, Any]]  # self-play configs (overrides of tune_configs/selfplay_<game>.yaml)
    selfplay_methods: list[Method] = field(default_factory=lambda: list(CORE_METHODS))
    population_overrides: dict[str, dict[str, Any]] = field(default_factory=dict)  # training settings per population
    zeroshot_populations: list[str] = field(default_factory=list)
    zeroshot_methods: list[Method] = field(default_factory=lambda: list(ZEROSHOT_METHODS))
    # Run for every population whose methods include their base (`modular-lam0.5` always does).
    adapt_variants: list[AdaptVariant] = field(default_factory=lambda: [SCRATCH])
    # Populations left out of the marginals: their partners' conventions are not uniform over
    # optimal actions (the user-study participants prefer some arms), so the distance to that
    # uniform distribution measures nothing the regulariser aims at.
    no_marginals: list[str] = field(default_factory=list)
    adapt_partners: int | None = None  # test partners per population (None: all)
    train_overrides: dict[str, Any] = field(default_factory=dict)
    train_steps: int | None = None  # every ego's training env steps, over any default or override (None: keep them)
    adapt_overrides: dict[str, Any] = field(default_factory=dict)
    zeroshot_overrides: dict[str, Any] = field(default_factory=dict)


def plan_for(game: str, seeds: int = 3, quick: bool = False, train_steps: int | None = None) -> Plan:
    """The paper's experiments for `game` (or a small version with `quick`).

    Egos train for the paper's budget (`GAME_DEFAULTS`) unless `train_steps` sets another.
    """
    if game not in GAMES:
        raise ValueError(f"game must be one of {', '.join(GAMES)} (or all), got {game!r}")
    if seeds < 1:
        raise ValueError(f"--seeds: expected at least 1 seed per method, got {seeds}")
    if train_steps is not None and train_steps < 1:
        raise ValueError(f"--train-steps: expected a positive number of env steps, got {train_steps}")
    plan = _plan(game, seeds, quick)
    plan.train_steps = train_steps
    return plan


def _plan(game: str, seeds: int, quick: bool) -> Plan:
    if quick:
        quick_train = {"run": {"timesteps": 2048}} if game == "bandit" else {"run": {"timesteps": 4000}, "ppo": {"rollout_per_partner": 400, "minibatch_size": 100}}
        quick_methods = [MODULAR_05, Method("agg", {"method": "agg"})]
        return Plan(
            game=game,
            seeds=[0],
            populations={"bandit": {"bandit-s2-hand": quick_methods}, "blocks": {"blocks-perm": quick_methods}, "hanabi": {}}[game],
            selfplay_methods=quick_methods,
            selfplay=[{"name": f"{game}-quick-selfplay", "train_pairs": 1, "test_pairs": 1, "run": {"timesteps": 2000 if game == "bandit" else 4000}, "gate": {"score": 0.0, "episodes": 50, "check_every": 1, "check_episodes": 20}}]
            if game == "hanabi"
            else [],
            zeroshot_populations=["bandit-s1-hand"] if game == "bandit" else [],
            adapt_partners=1,
            train_overrides=quick_train,
            adapt_overrides={"steps": 64} if game == "bandit" else {"steps": 1280, "episodes": 50},
            zeroshot_overrides={"head_steps": 512, "task_steps": 1024},
        )
    seed_list = list(range(seeds))
    if game == "bandit":
        return Plan(
            game=game,
            seeds=seed_list,
            populations={**{f"bandit-s{m}-hand": BANDIT_METHODS for m in (2, 3, 4)}, "bandit-user-study": CORE_METHODS},
            selfplay=[{"name": f"bandit-s{m}-selfplay", "env_config": {"symmetric": m}} for m in (2, 3, 4)],
            zeroshot_populations=[f"bandit-s{m}-hand" for m in (1, 2, 3)],
            no_marginals=["bandit-user-study"],
            adapt_partners=4,
            # 24 training partners: the paper's 64 steps per partner would leave 7 updates in 10 000 steps.
            population_overrides={"bandit-user-study": {"ppo": {"rollout_per_partner": 16}, "run": {"timesteps": 40_000}}},
        )
    if game == "blocks":
        return Plan(
            game=game,
            seeds=seed_list,
            populations={"blocks-perm": BLOCKS_METHODS},
            selfplay=[{"name": "blocks-selfplay"}],
            selfplay_methods=[*CORE_METHODS, HEAD_PENALTY_05],
            zeroshot_populations=["blocks-perm"],
            zeroshot_methods=[*ZEROSHOT_METHODS, HEAD_PENALTY_05],
            adapt_variants=[SCRATCH, HEAD_PICK_05, HEAD_PENALTY_PICK_05],
            adapt_partners=6,
        )
    return Plan(game=game, seeds=seed_list, populations={}, selfplay=[{"name": "hanabi-selfplay"}], selfplay_methods=HANABI_METHODS, adapt_partners=4)


def narrow(plan: Plan, populations: list[str] | None = None, methods: list[str] | None = None) -> Plan:
    """Keep only the named populations (built-in, self-play or zero-shot ones) and method labels of `plan`.

    `modular-lam0.5` is always kept: learning from scratch and zero-shot start from its runs.
    ValueError naming the unknown ones and the choices.
    """
    if populations:
        known = [*plan.populations, *(sp["name"] for sp in plan.selfplay), *plan.zeroshot_populations]
        unknown = sorted(set(populations) - set(known))
        if unknown:
            raise ValueError(f"--populations: {unknown} not in the {plan.game} plan; choose from {sorted(set(known))}")
        plan.populations = {k: v for k, v in plan.populations.items() if k in populations}
        plan.selfplay = [sp for sp in plan.selfplay if sp["name"] in populations]
        plan.zeroshot_populations = [p for p in plan.zeroshot_populations if p in populations]
    if methods:
        known = {m.label for ms in [*plan.populations.values(), plan.selfplay_methods] for m in ms}
        unknown = sorted(set(methods) - known)
        if unknown:
            raise ValueError(f"--methods: {unknown} not in the {plan.game} plan; choose from {sorted(known)}")
        keep = set(methods) | {MODULAR_05.label}
        plan.populations = {k: [m for m in v if m.label in keep] for k, v in plan.populations.items()}
        plan.selfplay_methods = [m for m in plan.selfplay_methods if m.label in keep]
    return plan


# Stages `redo` can run again: where each experiment's CSV and Tune folder live. Training and
# self-play feed every later stage, so redoing those means a fresh output folder.
REDO_OUTPUTS = {"adapt": ("adaptation", ADAPT_PREFIX), "zeroshot": ("zeroshot", ZEROSHOT_PREFIX), "marginals": None}


def _merge(base: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for k, v in extra.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


class Reproduction:
    """Runs a `Plan`'s stages under `root`, skipping finished ones."""

    def __init__(self, plan: Plan, root: Path, address: str | None = None, log: Callable[[str], None] = print) -> None:
        self.plan, self.root, self.address, self.log = plan, root, address, log
        self.runs = root / "runs"

    def populations(self) -> dict[str, list[Method]]:
        """Built-in populations plus this plan's self-play ones, each with its methods."""
        selfplay = {str(self.root / "populations" / sp["name"]): self.plan.selfplay_methods for sp in self.plan.selfplay}
        return {**self.plan.populations, **selfplay}

    def experiment(self, population: str, method: Method) -> dict[str, Any]:
        """The training experiment of one population and method, over the plan's seeds."""
        short = Path(population).name
        raw = {
            "name": f"{short}__{method.label}",
            "population": population,
            "seed": {"grid_search": self.plan.seeds},
            **method.settings,
        }
        raw = _merge(_merge(raw, self.plan.train_overrides), self.plan.population_overrides.get(population, {}))
        return raw if self.plan.train_steps is None else _merge(raw, {"run": {"timesteps": self.plan.train_steps}})

    def train_steps(self, experiment: dict[str, Any]) -> int:
        """The env steps each ego of `experiment` (an `experiment(...)` dict) trains for."""
        return experiment.get("run", {}).get("timesteps") or GAME_DEFAULTS[self.plan.game]["timesteps"]

    def stage_selfplay(self) -> None:
        for overrides in self.plan.selfplay:
            target = self.root / "populations" / overrides["name"]
            if (target / "population.json").is_file():
                continue
            raw = config.from_dict(_merge(config.load(CONFIGS / f"selfplay_{self.plan.game}.yaml", schema=SelfPlayConfig), overrides), schema=SelfPlayConfig)
            _, report = train_population(raw, out=self.root / "populations", storage=self.runs, address=self.address)
            self.log(f"self-play {overrides['name']}: {int(report['passed'].sum())}/{len(report)} pairs passed the gate")

    def trained(self) -> list[tuple[str, Method]]:
        """Every (population, method) whose egos this plan trains."""
        return [(p, m) for p, ms in self.populations().items() for m in ms]

    def variants(self, methods: list[Method]) -> list[AdaptVariant]:
        """The plan's adapt-only variants whose base egos are among `methods`."""
        labels = {m.label for m in methods}
        return [v for v in self.plan.adapt_variants if v.base.label in labels]

    def stage_train(self) -> None:
        for population, method in self.trained():
            results = run(config.from_dict(self.experiment(population, method)), storage=self.runs, address=self.address)
            if results.errors:
                raise RuntimeError(f"training {Path(population).name} / {method.label}: {len(results.errors)} trial(s) failed")

    def stage_adapt(self) -> None:
        for population, methods in self.populations().items():
            pop = partners.get(population)
            names = [e.name for e in pop.entries("test")][: self.plan.adapt_partners]
            jobs = [(self.experiment(population, m)["name"], {}) for m in methods]
            for v in self.variants(methods):
                jobs.append((f"{Path(population).name}__{v.label}", {**v.settings, "runs": [str(self.runs / self.experiment(population, v.base)["name"])]}))
            for name, extra in jobs:
                if (self.root / "adaptation" / f"{name}.csv").is_file():
                    continue
                raw = _merge({"name": name, "runs": [str(self.runs / name)], "population": population, "partners": names}, {**self.plan.adapt_overrides, **extra})
                run_adaptation(config.from_dict(raw, schema=config.AdaptConfig), out=self.root / "adaptation", storage=self.runs, address=self.address)

    def stage_zeroshot(self) -> None:
        for population in self.plan.zeroshot_populations:
            for method in self.plan.zeroshot_methods:
                exp = self.experiment(population, method)
                name = exp["name"]
                if (self.root / "zeroshot" / f"{name}.csv").is_file():
                    continue
                run(config.from_dict(exp), storage=self.runs, address=self.address)  # continues or skips if trained
                raw = _merge({"name": name, "runs": [str(self.runs / name)]}, self.plan.zeroshot_overrides)
                run_zeroshot(config.from_dict(raw, schema=config.ZeroShotConfig), out=self.root / "zeroshot", storage=self.runs, address=self.address)

    def has_marginals(self, experiment: str) -> bool:
        """Whether the marginals stage measures experiment `<population>__<label>` (see `Plan.no_marginals`)."""
        return split_experiment(experiment)[0] not in self.plan.no_marginals

    def stage_marginals(self) -> None:
        experiments = [e for e in sorted(self.runs.glob("*__*")) if self.has_marginals(e.name)]
        # Finished trials only (their eval.json is written when training ends): another
        # process may be training an experiment in the same folder.
        trials = [t.parent for exp in experiments for t in sorted(exp.glob(f"*/{EVAL_FILE}"))]
        table = marginal_report(trials)
        table["experiment"] = [Path(r).parent.name for r in table["run"]]
        table.to_csv(self.root / "marginals.csv", index=False)

    def stages(self) -> list[tuple[str, Callable[[], None]]]:
        """The plan's stages, in order."""
        stages = [("selfplay", self.stage_selfplay), ("train", self.stage_train), ("adapt", self.stage_adapt)]
        if self.plan.zeroshot_populations:
            stages.append(("zeroshot", self.stage_zeroshot))
        if self.plan.game in ("bandit", "blocks"):
            stages.append(("marginals", self.stage_marginals))
        return stages

    def run(self) -> dict[str, float]:
        """Run every unfinished stage; return the wall time of each stage run now."""
        self.root.mkdir(parents=True, exist_ok=True)
        plan = {"game": self.plan.game, "seeds": self.plan.seeds, "quick": self.plan.adapt_partners == 1, "train_steps": self.plan.train_steps}
        (self.root / "plan.json").write_text(json.dumps(plan, indent=2))
        times = {}
        for name, stage in self.stages():
            marker = self.root / f"{name}.done"
            items = self.stage_items(name)
            earlier, covered = read_marker(marker)
            missing = [i for i in items if i not in covered]
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
        if stage == "marginals":
            outputs = [self.root / "marginals.csv"]
        else:
            folder, prefix = REDO_OUTPUTS[stage]
            outputs = [p for n in self.stage_experiments(stage) for p in (self.root / folder / f"{n}.csv", self.runs / f"{prefix}{n}")]
        dest = self.root / "superseded" / time.strftime("%Y%m%d-%H%M%S")
        moved = []
        for path in outputs:
            if path.exists():
                target = dest / path.relative_to(self.root)
                target.parent.mkdir(parents=True, exist_ok=True)
                moved.append(Path(shutil.move(path, target)))
        marker = self.root / f"{stage}.done"
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
            "selfplay": [sp["name"] for sp in self.plan.selfplay],
            "train": trained,
            "adapt": [*trained, *(f"{Path(p).name}__{v.label}" for p, ms in self.populations().items() for v in self.variants(ms))],
            "zeroshot": zeroshot,
            "marginals": sorted(n for n in {*trained, *zeroshot} if self.has_marginals(n)),
        }[stage]

    def stage_items(self, stage: str) -> list[str]:
        """What stage `stage` of this plan produces, one line per experiment (with the seeds), for its marker.

        Training items also name the egos' env steps: with another budget the stage runs
        again, and `fit` refuses to continue a folder trained for a different one.
        """
        seeds = f" seeds={','.join(map(str, self.plan.seeds))}"
        if stage == "train":
            experiments = [self.experiment(p, m) for p, m in self.trained()]
            return [f"{e['name']}{seeds} steps={self.train_steps(e)}" for e in experiments]
        return [name + seeds for name in self.stage_experiments(stage)]


def read_marker(marker: Path) -> tuple[float, list[str]]:
    """A stage marker's wall seconds and covered items; (0, []) when there is none.

    Markers from before items were recorded hold only the time, so they cover nothing.
    """
    if not marker.is_file():
        return 0.0, []
    first, *items = marker.read_text().splitlines()
    return float(first.split()[0]), [i for i in items if i]


def write_marker(marker: Path, seconds: float, items: list[str]) -> None:
    """Write a stage marker: `<seconds> s` on the first line (what `analysis` reads), then one covered item per line."""
    marker.write_text("\n".join([f"{seconds:.1f} s", *items]) + "\n")


def reproduce(
    game: str,
    out: str | Path = "reproduce",
    seeds: int = 3,
    quick: bool = False,
    address: str | None = None,
    populations: list[str] | None = None,
    methods: list[str] | None = None,
    redo: str | None = None,
    train_steps: int | None = None,
) -> dict[str, dict[str, float]]:
    """Run `game` (or `all`), optionally `narrow`ed, then build `<out>/report/report.md` over every game under `out`.

    `redo` names a finished stage to run again for the plan's experiments (see `Reproduction.redo`);
    `train_steps` replaces every ego's training budget (see `plan_for`).
    Returns the stage wall times per game.
    """
    from analysis.report import build_report

    games = GAMES if game == "all" else (game,)
    plans = [narrow(plan_for(g, seeds, quick, train_steps), populations, methods) for g in games]  # validate every game before running any
    times = {}
    for plan in plans:
        repro = Reproduction(plan, Path(out) / plan.game, address)
        if redo is not None:
            repro.redo(redo)
        times[plan.game] = repro.run()
    print(f"report: {build_report(out)}")
    return times


def stage_table(root: str | Path) -> pd.DataFrame:
    """Which stages of the games under `root` are finished, and how long they took."""
    rows = []
    for marker in sorted(Path(root).glob("*/*.done")):
        rows.append({"game": marker.parent.name, "stage": marker.stem, "wall": f"{read_marker(marker)[0]:.1f} s"})
    return pd.DataFrame(rows)
