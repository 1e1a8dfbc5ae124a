"""`build_report`: the report's entry point; it loads the data once and writes the sections in order."""

from __future__ import annotations

import datetime as _dt
from pathlib import Path
from typing import Iterable

from analysis.archive import DATA_DIR, archive
from analysis.report.context import Context
from analysis.report.sections.adaptation import adaptation_section
from analysis.report.sections.beyond import beyond_section
from analysis.report.sections.differences import differences_section
from analysis.report.sections.evaluation import evaluation_section
from analysis.report.sections.heldout import heldout_section
from analysis.report.sections.marginals import marginals_section
from analysis.report.sections.selfplay import selfplay_section
from analysis.report.sections.status import status_section
from analysis.report.sections.training import training_section
from analysis.report.sections.user_study import user_study_section
from analysis.report.sections.zeroshot import zeroshot_section

# Said only where a result pools several independently trained populations (earlier reports read as they were).
POOLED_STATISTICS = (
    " Where one result pools several independently trained self-play populations (listed under What was found), the "
    "population is the unit above the seed: each seed is averaged over its test partners, the seeds within each "
    "population, and the interval is over the population means (n = populations); paired differences pair within "
    "(population, seed, test partner) and are averaged up the same way."
)


def build_report(root: str | Path, out: str | Path | None = None, user_study: Iterable[str | Path] | None = None) -> Path:
    """Build `report.md` and its figures for the reproduction under `root`; return the report's path.

    `root` is a `reproduce --out` folder (one sub-folder per game) or one game folder;
    `out` defaults to `<root>/report`. `user_study` names recorded session CSVs (files
    or folders) to analyse beside the paper's table; by default `<root>/user_study/` if
    it exists. Only files are read; nothing is trained or evaluated. Every file read from
    `root` is copied into `<out>/data/` (`analysis.archive`): the report builds again from it.
    """
    root, out = Path(root), Path(out) if out is not None else Path(root) / "report"
    if not root.is_dir():
        raise ValueError(
            f"root {str(root)!r} is not a folder (expected a `rllib-conv reproduce --out` folder or one game folder)"
        )
    out.mkdir(parents=True, exist_ok=True)
    ctx = Context(root, out, user_study)
    # Sections that compare numbers run first, so the summary at the top can list their differences.
    body = [
        status_section(ctx),
        adaptation_section(ctx),
        beyond_section(ctx),
        zeroshot_section(ctx),
        heldout_section(ctx),
        evaluation_section(ctx),
        marginals_section(ctx),
        user_study_section(ctx),
        training_section(ctx),
        selfplay_section(ctx),
    ]
    head = [
        "# Reproduction report: paper vs ours",
        "",
        f"Built by `python -m analysis {root}` on {_dt.datetime.now().strftime('%Y-%m-%d %H:%M')} from the files under `{root.resolve()}`. "
        "Paper: Shih et al., ICLR 2021 (numbers read from its LaTeX source; see `analysis/paper.py` for each source). "
        "Statistics: the replicated unit is the training seed (curves of one seed share a trained ego, so they are not "
        "independent). Every number measured with test partners (adaptation, zero-shot) is averaged per seed over its test "
        "partners first; intervals are two-sided 95% Student-t intervals over the seed means (n = seeds; with one seed, no "
        "interval), the interval of the grand mean of a balanced nested (seed, partner) design. A hierarchical bootstrap is "
        "not used: with the 3 to 5 seeds of blocks and Hanabi it resamples among only 10 to 126 distinct seed sets and its "
        "intervals come out too narrow; one rule serves every game. "
        'A paper number counts as matching when it lies inside our interval, widened by its rounding. A claim "A beats B" '
        "is judged on the paired difference A − B over the (seed, test partner) units both methods share, averaged per seed, "
        "with its 95% t-interval over seeds: supported when the whole interval is above 0, contradicted when it is below 0, "
        "not shown otherwise; these are the only verdicts, and the tallies count them. The paper's claims are checked on its "
        "own method (ours λ=0.5) alone; other variants of ours are judged in tables of their own and never change a verdict."
        + (POOLED_STATISTICS if ctx.kinds else ""),
        "",
    ]
    text = "\n".join(
        head + [body[0], "", differences_section(ctx), ""] + [b + "\n" for b in body[1:] if b]
    )  # a section with nothing to say leaves no line
    path = out / "report.md"
    path.write_text(text)
    if (out / DATA_DIR).resolve() != root.resolve():  # not a rebuild from the report's own data
        archive(root, out / DATA_DIR)
    return path
