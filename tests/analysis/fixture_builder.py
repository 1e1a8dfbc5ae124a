"""Build the analysis tests' fixture from a reproduction: what `analysis` reads, in the layout `rllib-conv reproduce` writes.

    .venv/bin/python -m tests.analysis.fixture_builder REPRO/bandit tests/analysis/fixtures/repro/bandit

`slim` copies from one game folder of a reproduction (the layout of
`rllib_conv.common.run_folders`) the files the loaders and the report read:

- plan.json, the stage markers (`<stage>.done`), `marginals.csv`;
- the CSVs of `adaptation/`, `zeroshot/`, `crossplay/`, `user_study/` and each population's
  `selfplay_report.csv`;
- per experiment `runs/<population>__<label>/`: its `experiment.yaml`, and per trained ego
  `<point>/seed=<s>/` its `config.yaml` (and the digest sealing it), `progress.csv`, `eval.json`;
- per Tune run of a stage (`runs/train-stage-<hash>/`, `runs/adapt-<name>/`, ...): its
  `experiment.yaml` alone, so that the fixture shows the loaders skipping those folders.

Left out: checkpoints, Tune's own trial files and event files (the loaders never read them).
The `run` column of the CSVs holds absolute paths on the machine that ran; they become paths
relative to the game folder, so the fixture reads the same anywhere. A trained ego that is not
a `seed=<s>` replica folder (the older trial-as-ego layout) is refused: the fixture is of the
current layout.
"""

from __future__ import annotations

import argparse
import csv
import io
import shutil
from pathlib import Path

from rllib_conv.common.run_folders import (
    ADAPTATION_DIR,
    CONFIG_FILE,
    CROSSPLAY_DIR,
    EVAL_FILE,
    MARGINALS_FILE,
    MARKER_SUFFIX,
    PLAN_FILE,
    POPULATIONS_DIR,
    PROGRESS_FILES,
    REPLICA_PREFIX,
    RUNS_DIR,
    SELFPLAY_REPORT_FILE,
    SPEC_FILE,
    STAGE_PREFIXES,
    USER_STUDY_DIR,
    ZEROSHOT_DIR,
    trial_folders,
)
from rllib_conv.common.sealed import digest_path

RUN_COLUMN = "run"  # the CSV column naming a trained ego's folder
EGO_FILES = (CONFIG_FILE, digest_path(CONFIG_FILE).name, PROGRESS_FILES[0], EVAL_FILE)
TABLE_FOLDERS = (ADAPTATION_DIR, ZEROSHOT_DIR, CROSSPLAY_DIR, USER_STUDY_DIR)


def slim(game: Path, out: Path) -> list[Path]:
    """Write the fixture of reproduction game folder `game` into the new folder `out`; return the files written, sorted.

    ValueError when `out` exists, `game` is no game folder (no plan.json), a trained ego is
    not a replica folder, or a `run` path lies outside `game`.
    """
    game, out = Path(game).resolve(), Path(out)
    if out.exists():
        raise ValueError(f"out {str(out)!r} exists; the fixture is written into a new folder")
    if not (game / PLAN_FILE).is_file():
        raise ValueError(f"{str(game)!r} is not a reproduction's game folder ({PLAN_FILE} missing)")
    files = [
        game / PLAN_FILE,
        *sorted(game.glob(f"*{MARKER_SUFFIX}")),
        *sorted(game.glob(f"{POPULATIONS_DIR}/*/{SELFPLAY_REPORT_FILE}")),
    ]
    tables = [
        *([game / MARGINALS_FILE] if (game / MARGINALS_FILE).is_file() else []),
        *(p for folder in TABLE_FOLDERS for p in sorted(game.glob(f"{folder}/*.csv"))),
    ]
    for folder in sorted(p for p in (game / RUNS_DIR).glob("*") if p.is_dir()):
        if (folder / SPEC_FILE).is_file():
            files.append(folder / SPEC_FILE)
        if folder.name.startswith(STAGE_PREFIXES):
            continue  # a stage's Tune run: its trials' files are Tune's, not trained egos
        for ego in trial_folders(folder, missing_ok=True):
            if not ego.name.startswith(REPLICA_PREFIX):
                raise ValueError(
                    f"trained ego {str(ego)!r} is not a {REPLICA_PREFIX}<s> replica folder (the older trial-as-ego layout)"
                )
            files += [ego / name for name in EGO_FILES if (ego / name).is_file()]
    texts = {src: _relative_runs(src, game) for src in tables}  # every check before anything is written
    written = [_copy(src, out / src.relative_to(game)) for src in files]
    written += [_write(out / src.relative_to(game), text) for src, text in texts.items()]
    return sorted(written)


def _copy(src: Path, dst: Path) -> Path:
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dst)
    return dst


def _write(dst: Path, text: str) -> Path:
    dst.parent.mkdir(parents=True, exist_ok=True)
    dst.write_text(text)
    return dst


def _relative_runs(table: Path, game: Path) -> str:
    """`table`'s text with its `run` column relative to `game` (a table without one, unchanged)."""
    rows = list(csv.reader(io.StringIO(table.read_text())))
    if not rows or RUN_COLUMN not in rows[0]:
        return table.read_text()
    column = rows[0].index(RUN_COLUMN)
    for row in rows[1:]:
        run = Path(row[column])
        if run.is_absolute():
            try:
                row[column] = run.relative_to(game).as_posix()
            except ValueError:
                raise ValueError(f"{table.name}: run {str(run)!r} lies outside the game folder {str(game)!r}") from None
    text = io.StringIO()
    csv.writer(text, lineterminator="\n").writerows(rows)
    return text.getvalue()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("game", type=Path, help="a reproduction's game folder, e.g. REPRO/bandit")
    parser.add_argument("out", type=Path, help="the new fixture folder, e.g. tests/analysis/fixtures/repro/bandit")
    args = parser.parse_args(argv)
    try:
        written = slim(args.game, args.out)
    except ValueError as error:
        parser.exit(2, f"error: {error}\n")
    print(f"{len(written)} files written under {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
