"""Output names after their inputs: what `adapt`, `zeroshot`, `marginals` and `pair` call their CSVs and Tune runs.

A name says what was run: the runs (an experiment's name, then the Tune trial id and
sub-folders below it), then the options that differ from the defaults. Names are folder
and file names: characters outside `[A-Za-z0-9._=+@,-]` become `_`, and a name longer
than `MAX_NAME` is cut and keeps a digest of the whole, so two names stay apart.
Light on purpose (no torch, no Ray): the command line names its outputs before it loads
a pipeline.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path
from typing import Sequence

from rllib_conv.common.run_folders import SPEC_FILE

MAX_NAME = 120  # longer derived output names are cut and keep a digest, so they stay unique and fit a file system


def digest(texts: Sequence[str]) -> str:
    """Six hex digits that only the same texts get again."""
    return hashlib.sha1("\n".join(texts).encode()).hexdigest()[:6]


def slug(text: str) -> str:
    """`text` as a folder and file name: runs of characters outside [A-Za-z0-9._=+@,-] become one `_`; long names keep a digest."""
    name = re.sub(r"[^\w.=+@,-]+", "_", text).strip("_")
    return name if len(name) <= MAX_NAME else f"{name[: MAX_NAME - 7]}-{digest([text])}"


def trial_id(trial: Path) -> str:
    """Tune's short id of a trial folder `<Trainable>_<id>_<index>_...` (`6b1e2_00000`); the folder name otherwise."""
    parts = trial.name.split("_")
    return "_".join(parts[1:3]) if len(parts) >= 3 else trial.name


def run_label(run: str | Path) -> str:
    """A short name of a RUNS argument: its experiment's name, then the Tune trial id and sub-folders below it.

    `runs/tiny` -> `tiny`; `runs/tiny/EgoTrainable_6b1e2_00000_0_...` -> `tiny-6b1e2_00000`; a
    folder inside a trial (one trained ego of several) adds its own name. A folder outside any
    experiment (no experiment.yaml above it) is named by its parent and itself.
    """
    path = Path(run).resolve()
    experiment = next((p for p in (path, *path.parents) if (p / SPEC_FILE).is_file()), path.parent)
    below = path.relative_to(experiment).parts if path != experiment else ()
    return "-".join([experiment.name, *(trial_id(Path(part)) for part in below)])


def name_from(runs: Sequence[str], extras: Sequence[str]) -> str:
    """An output name after the inputs: the runs (the first, a count and a digest when several), then the options that differ."""
    labels = [run_label(r) for r in runs]
    head = (
        labels[0]
        if len(labels) == 1
        else f"{labels[0]}+{len(labels) - 1}-more-{digest(sorted(str(Path(r).resolve()) for r in runs))}"
    )
    return slug("-".join([head, *extras]))


def adapt_name(
    runs: Sequence[str],
    *,
    method: str | None = None,
    head_init: str = "fresh",
    pick_steps: int | None = None,
    frozen_task: bool = False,
    guard: bool = False,
    split: str = "test",
    population: str | None = None,
    partners: Sequence[str] = (),
    sets: Sequence[str] = (),
) -> str:
    """The name of an adaptation after its runs and the options that differ from the paper's (fresh head, test split, ...)."""
    changed = [
        method,
        None if head_init == "fresh" else head_init,
        pick_steps and f"pick-steps={pick_steps}",
        "frozen-task" if frozen_task else None,
        "guarded" if guard else None,
        None if split == "test" else f"{split}-split",
        population and Path(population).stem,
    ]
    return name_from(runs, [v for v in changed if v] + list(partners) + list(sets))


def zeroshot_name(runs: Sequence[str], *, new_population: str | None = None, sets: Sequence[str] = ()) -> str:
    """The name of a zero-shot evaluation after its runs, its new population (when given) and its `--set`s."""
    return name_from(runs, ([Path(new_population).stem] if new_population else []) + list(sets))


def marginals_name(runs: Sequence[str], *, episodes: int, seed: int, defaults: tuple[int, int] = (200, 0)) -> str:
    """The name of a marginals table after its runs and the episodes and seed that differ from `defaults`."""
    return name_from(
        runs, [f"{k}={v}" for k, v, default in (("episodes", episodes, defaults[0]), ("seed", seed, defaults[1])) if v != default]
    )


def evaluate_name(runs: Sequence[str], *, eval_set: str, module: str | None = None, episodes: int = 64, seed: int = 0) -> str:
    """The name of an evaluation after its runs, its set (always: held-out and validation must not meet) and the options that differ."""
    changed = [module and f"module={module}", episodes != 64 and f"episodes={episodes}", seed and f"seed={seed}"]
    return name_from(runs, [Path(eval_set).stem, *(v for v in changed if v)])


def seat_label(source: str, what: str, is_run: bool) -> str:
    """A seat's part of a pairing's name: the run's label (or the population's or kind's name), then what it plays."""
    return f"{run_label(source) if is_run else Path(source).stem}-{what}"
