"""`Context`: everything a report is built from (the loaded frames) and what its sections accumulate; the method groups the paper's claims are about."""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np
import pandas as pd

from analysis import figures, loaders
from analysis.populations import member_kinds, pool
from analysis.report.formatting import digits
from analysis.report.verdicts import ClaimCheck, Comparison
from analysis.summaries import seed_summary
from rllib_conv.common import methods

# The paper's own method (`methods.PAPER_METHOD`): its claims are checked on this label alone, never
# on the best of several variants (which would be a multiple-comparison advantage for ours). The
# variants the paper does not have (`methods.EXTENSIONS`) are shown in the tables, left out of its claims.

PAPER_SEEDS = 3  # this project's default seed count for a full reproduction
CONVERGED = 0.9  # share of the game's maximum score below which a trained ego counts as under-trained


class Context:
    """Everything loaded from ROOT plus what the report accumulates while its sections are written."""

    def __init__(self, root: Path, out: Path, user_study: Iterable[str | Path] | None) -> None:
        self.root, self.out, self.figdir = root, out, out / "figures"
        self.games = loaders.game_dirs(root)
        self.plans = {loaders.game_of(g): loaders.read_plan(g) for g in self.games}
        self.stages = loaders.load_stage_times(root)
        # Independently trained populations of one kind are reported as one, the population above the seed
        # (`analysis.populations`); the self-play reports, cross-play and held-out tables stay per population.
        self.kinds = member_kinds(self.plans.values())
        self.training = pool(loaders.load_training(root), self.kinds)
        self.evals = pool(loaders.load_evals(root), self.kinds)
        self.adaptation = pool(loaders.load_adaptation(root), self.kinds)
        self.zeroshot = pool(loaders.load_zeroshot(root), self.kinds)
        self.marginals = pool(loaders.load_marginals(root), self.kinds)
        self.selfplay = loaders.load_selfplay_reports(root)
        self.crossplay = loaders.load_crossplay(root)
        self.heldout = loaders.load_heldout(root)
        self.evaluations = loaders.load_evaluations(root)
        live = list(user_study) if user_study is not None else ([root / "user_study"] if (root / "user_study").is_dir() else [])
        self.live_study_paths = live
        self.comparisons: list[Comparison] = []
        self.claims: list[ClaimCheck] = []
        self.notes: list[str] = []  # absent data, said in the summary
        self.train_summary = self._train_summary()

    # -- helpers --
    def game_of_population(self, population: str) -> str | None:
        """The game a population was run on, from whichever table mentions it (None if none does)."""
        for frame in (self.training, self.adaptation, self.zeroshot, self.marginals, self.selfplay):
            if not frame.empty and population in set(frame["population"]):
                return str(frame.loc[frame["population"] == population, "game"].iloc[0])
        return None

    def pooled(self, population: str) -> list[str]:
        """The independently trained populations a result of `population` pools (none: a population of its own)."""
        return sorted(m for m, kind in self.kinds.items() if kind == population)

    def quick(self, game: str | None) -> bool:
        """Whether `game` was run with the quick (tiny) plan."""
        return bool(self.plans.get(game or "", {}).get("quick", False))

    def save(self, fig: object, name: str, caption: str = "") -> str:
        """Save `fig` as figures/<name>.png and .pdf; return the markdown that shows it, with its `caption` in italics below."""
        figures.save(fig, self.figdir / name)
        image = f"![{name}](figures/{name}.png) ([PDF](figures/{name}.pdf))"
        return f"{image}\n\n*{caption}*" if caption else image

    def _train_summary(self) -> pd.DataFrame:
        """Per (game, population, label): final return with the training partners, each seed averaged over them, then over seeds (eval.json; exact where known)."""
        if self.evals.empty:
            return pd.DataFrame(columns=["game", "population", "label", "method", "mean", "lo", "hi", "n"])
        ev = self.evals.copy()
        ev["value"] = ev["exact_return"].where(ev["exact_return"].notna(), ev["mean_return"]).astype(float)
        return seed_summary(ev, ["game", "population", "label", "method"], "value")

    def reasons(self, game: str | None, population: str, label: str, n: int) -> list[str]:
        """Data-derived reasons why a number of (population, label) may differ from the paper's."""
        out = []
        if self.quick(game):
            out.append("quick plan: shortened training and adaptation, one seed, one test partner; not meant to match the paper")
        seeds = self.plans.get(game or "", {}).get("seeds", [])
        if seeds and len(seeds) < PAPER_SEEDS and not self.quick(game):
            out.append(f"only {len(seeds)} seed(s)")
        declared = self.plans.get(game or "", {}).get("declared_seeds")
        if declared is not None and len(seeds) < declared and not self.quick(game):
            out.append(f"{len(seeds)} of the {declared} seeds the plan declared its claims need")
        row = self.train_summary[(self.train_summary["population"] == population) & (self.train_summary["label"] == label)]
        top = loaders.max_score(self.plans.get(game or "", {"game": game}))
        # A single network (BaselineAgg, MAML) cannot follow conflicting conventions: a low training return is expected there.
        single = not row.empty and methods.method(row["method"].iloc[0]).single_head
        if not single and not row.empty and np.isfinite(top) and row["mean"].iloc[0] < CONVERGED * top:
            out.append(
                f"the trained ego is under-trained: {row['mean'].iloc[0]:.{digits(game)}f} of a possible {top:g} with its training partners"
            )
        if n == 1:
            out.append("a single seed: no interval to judge the difference by")
        return out
