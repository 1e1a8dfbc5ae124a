"""Build `report.md`: every figure the data allow, and the paper's numbers beside ours with 95% intervals.

`build_report(ROOT)` reads a reproduction (`rllib-conv reproduce GAME --out ROOT`, one
folder per game, or a single game folder) through `analysis.loaders`, draws the
figures of `analysis.figures` into `<out>/figures/` (PNG and PDF) and writes
`<out>/report.md`. Every comparison and every "where they differ" statement is
computed from the data: a paper number is flagged when it falls outside our seed-level
95% interval (widened by half a unit of the paper's last printed digit, for its rounding),
a paper claim is supported, contradicted or not shown by the paired difference of its
methods over seeds (`verdicts`), and the listed reasons are the ones the data show (a quick plan, too few seeds, an
under-trained ego, a known behaviour of the released code). Anything absent (a game,
a stage, a population) is skipped and named in the report.

Modules: `build` (the entry point), `context` (the loaded data and the method groups the
claims are about), `verdicts` (comparisons and claim checks, and the rules that judge
them), `formatting`, and one module per section under `sections/`.
"""

from analysis.report.build import build_report

__all__ = ["build_report"]
