"""A report's inputs, archived: every file the report reads from a reproduction folder, and nothing else.

`build_report` copies them into `<out>/data/` beside `report.md`, in the reproduction's own
layout (`<game>/plan.json`, `<game>/adaptation/*.csv`, `<game>/runs/<experiment>/<trial>/
config.yaml`, ...), so that `python -m analysis <out>/data --out DIR` builds the same report
again without the run folder, its checkpoints or Ray. What is copied, per game folder:

- the plan and the stage markers (`plan.json`, `*.done`);
- the per-curve and per-seed tables: adaptation and zero-shot CSVs, `marginals.csv`,
  `heldout.csv`, cross-play matrices, self-play reports, the evaluation sets' scores and summaries;
- per trained ego: its resolved config (with its seal), its final evaluation (`eval.json`)
  and its training curve (`progress.csv`), never its checkpoints.

A few hundred kB per game: small enough to commit beside a report.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from analysis.loaders import game_dirs, trial_dirs
from rllib_conv.common.run_folders import (
    ADAPTATION_DIR,
    CONFIG_FILE,
    CROSSPLAY_DIR,
    EVAL_FILE,
    EVALUATION_DIR,
    HELDOUT_FILE,
    MARGINALS_FILE,
    MARKER_SUFFIX,
    PLAN_FILE,
    POPULATIONS_DIR,
    SELFPLAY_REPORT_FILE,
    ZEROSHOT_DIR,
)
from rllib_conv.common.sealed import digest_path

DATA_DIR = "data"
# What the report reads in a game folder, as glob patterns relative to it.
GAME_FILES: tuple[str, ...] = (
    PLAN_FILE,
    f"*{MARKER_SUFFIX}",
    MARGINALS_FILE,
    HELDOUT_FILE,
    f"{ADAPTATION_DIR}/*.csv",
    f"{ZEROSHOT_DIR}/*.csv",
    f"{CROSSPLAY_DIR}/*.csv",
    f"{POPULATIONS_DIR}/*/{SELFPLAY_REPORT_FILE}",
    f"{EVALUATION_DIR}/*/summary.json",
    f"{EVALUATION_DIR}/*/scores.csv",
)
TRIAL_FILES: tuple[str, ...] = (CONFIG_FILE, digest_path(CONFIG_FILE).name, EVAL_FILE, "progress.csv")


def report_inputs(root: str | Path) -> list[tuple[Path, Path]]:
    """(file, its path relative to the archive) for every file the report of `root` reads."""
    root = Path(root)
    found = []
    for game_dir in game_dirs(root):
        # A root that is itself a game folder is archived as one game folder of its name.
        base = root if game_dir != root else root.parent
        for pattern in GAME_FILES:
            found += [(p, p.relative_to(base)) for p in sorted(game_dir.glob(pattern)) if p.is_file()]
        for trial in trial_dirs(game_dir):
            found += [(trial / f, (trial / f).relative_to(base)) for f in TRIAL_FILES if (trial / f).is_file()]
    return found


def archive(root: str | Path, dest: str | Path) -> list[Path]:
    """Copy the report inputs of `root` into `dest` (emptied first; `report_inputs`); return the copies."""
    dest = Path(dest)
    if dest.exists():
        shutil.rmtree(dest)
    copies = []
    for source, relative in report_inputs(root):
        target = dest / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        copies.append(Path(shutil.copy2(source, target)))
    return copies
