"""Tune callbacks of every pipeline: a progress line per result, a live table of trials, result files kept free of repeats and whole across a kill."""

from __future__ import annotations

import csv
import json
import math
import shutil
import time
from pathlib import Path
from typing import Any, Callable

from ray.tune import Callback

from rllib_conv.common.atomic_files import replaced_atomically, write_text_atomically
from rllib_conv.common.run_folders import PROGRESS_FILES
from rllib_conv.learners.marginal_learner import HEAD_L2_KEY, MARGINAL_REG_KEY


class ProgressLine(Callback):
    """Print one line per trial iteration: steps, returns (mean and worst partner), regulariser, head size, gate."""

    FIELDS = (
        ("return_mean", "return"),
        ("train_return", "return"),
        ("mean_return", "eval"),
        (MARGINAL_REG_KEY, "reg"),
        (HEAD_L2_KEY, "heads"),
        ("gate_check", "gate check"),
        ("gate_score", "gate"),
    )

    def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict[str, Any], **info: Any) -> None:
        steps = result.get("env_steps", result.get("steps", 0))
        parts = [f"[{trial.trial_id}] iter {result.get('training_iteration', 0):4d}"]
        if "phase" in result:  # zero-shot: its steps count from 0 again in each phase
            parts.append(f"phase {result['phase']}")
        parts.append(f"steps {steps:8d}")
        for key, label in self.FIELDS:
            value = result.get(key)
            if isinstance(value, (int, float)) and not math.isnan(value):
                parts.append(f"{label} {value:.3f}")
            if key == "return_mean":
                returns = [v for k, v in result.items() if k.startswith("return/")]
                if returns:
                    parts.append(f"min {min(returns):.3f}")
        parts.append(f"{result.get('time_total_s', 0.0):7.1f}s")
        print("  ".join(parts), flush=True)


class _ThrottledPrint(Callback):
    """Prints `text(trials)` at most every `every` seconds while results arrive, and whenever a trial finishes or fails."""

    every: float
    log: Any  # where the text goes (None: print)
    _last_print: float

    def text(self, trials: list) -> str:
        raise NotImplementedError

    def _print(self, trials: list) -> None:
        self._last_print = time.monotonic()
        text = self.text(trials)
        # `print` is looked up when used, not stored: Tune pickles its callbacks, and a stored
        # builtin fails to pickle once something (a progress bar) has replaced builtins.print.
        if self.log is None:
            print(text, flush=True)
        else:
            self.log(text)

    def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict[str, Any], **info: Any) -> None:
        if time.monotonic() - self._last_print >= self.every:
            self._print(trials)

    def on_trial_complete(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        self._print(trials)

    def on_trial_error(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        self._print(trials)


class ProgressTable(_ThrottledPrint):
    """Print a table of every trial (its swept values, status, iteration, steps, return) as the sweep runs.

    Reprinted at most every `every` seconds while results arrive, whenever a trial
    finishes or fails, and once at the end.
    """

    METRICS = (("env_steps", "steps"), ("return_mean", "return"), (MARGINAL_REG_KEY, "reg"))

    def __init__(self, every: float = 30.0) -> None:
        self.every = every
        self.log = None
        self._last_print = 0.0

    def table(self, trials: list) -> str:
        """The current table as text: one row per trial."""
        rows = []
        for trial in trials:
            cfg, result = trial.config or {}, trial.last_result or {}
            row = {"trial": trial.trial_id, "status": trial.status}
            # The swept values (grid keys, nested ones as "model/z_dim"), else the usual identifiers.
            swept = getattr(trial, "evaluated_params", None) or {
                k: cfg.get(k) for k in ("population", "method", "lam", "seed") if k in cfg
            }
            row.update(swept)
            row["iter"] = result.get("training_iteration", 0)
            for key, label in self.METRICS:
                value = result.get(key)
                row[label] = f"{value:.3f}" if isinstance(value, float) else ("" if value is None else value)
            rows.append(row)
        columns = list(dict.fromkeys(k for row in rows for k in row))
        cells = [[str(row.get(c, "")) for c in columns] for row in rows]
        widths = [max(len(c), *(len(r[i]) for r in cells)) for i, c in enumerate(columns)]
        lines = ["  ".join(c.rjust(w) for c, w in zip(columns, widths))]
        lines += ["  ".join(v.rjust(w) for v, w in zip(r, widths)) for r in cells]
        done = sum(t.status == "TERMINATED" for t in trials)
        return "\n".join([f"--- {done}/{len(trials)} trials finished ---", *lines])

    text = table

    def on_experiment_end(self, trials: list, **info: Any) -> None:
        self._print(trials)


# What every trial of a stage reports, for `StageProgress`: env steps played so far and to play in all
# (summed over the trial's replicas or curves).
STEPS_DONE = "stage_steps"
STEPS_TOTAL = "stage_steps_total"


def _count(n: float) -> str:
    return f"{n / 1e6:.2f}M" if n >= 1e6 else f"{n / 1e3:.1f}k"


def _duration(seconds: float) -> str:
    seconds = int(round(seconds))
    return f"{seconds // 3600}h{seconds % 3600 // 60:02d}m" if seconds >= 3600 else f"{seconds // 60}m{seconds % 60:02d}s"


class StageProgress(_ThrottledPrint):
    """One line for a whole stage, at most every `every` seconds and when a trial ends:
    trials done / total, env steps played / to play, elapsed time and an ETA.

    `log` prints the line (default `print`). Steps come from each trial's latest result
    (`STEPS_DONE`, `STEPS_TOTAL`; a resumed run knows its trials' last results); a trial
    not yet started counts as the mean known total. The ETA schedules what is left on the
    cores the stage has shown it uses (the most trials seen running at once): each running
    trial finishes its own steps, then the waiting ones take the first free core, at the
    step rate one running trial has had in this run. So a last trial left alone on one core
    counts at one core's speed, not the whole stage's. Steps played before a resume do not
    count towards the rate, and a resumed trial that starts again from zero (an adaptation
    pack) counts from zero.

    `units` (optional) says how many units (seeds, curves, runs) a trial's config runs
    together: a trial not yet started then counts as the known steps per unit times its own
    units, so a stage cut into trials of different sizes shows its true total.

    `stops_early` (optional) says why trials may end before their steps are played (a
    self-play pair stops at its gate): the total and the ETA are then printed as bounds,
    followed by that reason.
    """

    def __init__(
        self,
        label: str,
        every: float = 30.0,
        log: Any = None,
        units: Callable[[dict[str, Any]], int] | None = None,
        stops_early: str | None = None,
    ) -> None:
        self.label, self.every, self.log, self.units, self.stops_early = label, every, log, units, stops_early
        self._start = time.monotonic()
        self._last_print = self._start
        self._latest: dict[str, dict[str, Any]] = {}
        self._played = 0.0  # env steps played in this run
        self._busy = 0.0  # trial-seconds spent running in this run
        self._clock = self._start  # when `_busy` was last brought up to date
        self._cores = 1  # the most trials seen running at once

    def _result(self, trial: Any) -> dict[str, Any]:
        return self._latest.get(trial.trial_id) or getattr(trial, "last_result", None) or {}

    def _size(self, trial: Any) -> int:
        """The units `trial` runs (1 without `units`)."""
        return self.units(trial.config) if self.units else 1

    def _work(self, trials: list) -> tuple[list[float], list[float], float]:
        """Env steps left for the running trials and for the waiting ones (unstarted at the known steps per unit), and the steps played."""
        known = [(t, r) for t in trials if STEPS_DONE in (r := self._result(t))]
        units = sum(self._size(t) for t, _ in known)
        per_unit = sum(float(r.get(STEPS_TOTAL, r[STEPS_DONE])) for _, r in known) / units if known else 0.0
        running, waiting, done = [], [], 0.0
        for trial in trials:
            result = self._result(trial)
            played = float(result.get(STEPS_DONE, 0.0))
            done += played
            if trial.status == "TERMINATED":
                continue
            left = max(0.0, float(result.get(STEPS_TOTAL, per_unit * self._size(trial))) - played)
            (running if trial.status == "RUNNING" else waiting).append(left)
        return running, waiting, done

    def _tick(self, trials: list) -> None:
        """Add the trial-seconds since the last call (at the number of trials running now)."""
        now = time.monotonic()
        running = sum(t.status == "RUNNING" for t in trials)
        self._busy += (now - self._clock) * running
        self._clock = now
        self._cores = max(self._cores, running)

    def eta_seconds(self, trials: list) -> float | None:
        """Seconds until every trial is done, None before any rate is known."""
        running, waiting, _ = self._work(trials)
        return self._eta(running, waiting)

    def _eta(self, running: list[float], waiting: list[float]) -> float | None:
        if not running and not waiting:
            return 0.0
        if self._played <= 0 or self._busy <= 0:
            return None
        cores = sorted(running) + [0.0] * max(0, self._cores - len(running))
        for left in waiting:  # Tune starts a waiting trial on the first core that frees up
            cores[cores.index(min(cores))] += left
        return max(cores) / (self._played / self._busy)  # at the env steps per running trial-second

    def line(self, trials: list) -> str:
        """The progress line for `trials` now."""
        self._tick(trials)
        finished = sum(t.status == "TERMINATED" for t in trials)
        running, waiting, done = self._work(trials)
        eta = self._eta(running, waiting)
        elapsed = time.monotonic() - self._start
        bound, why = ("at most ", f" ({self.stops_early})") if self.stops_early and (running or waiting) else ("", "")
        return (
            f"{self.label}: {finished}/{len(trials)} trials done, {_count(done)}/{bound}{_count(done + sum(running) + sum(waiting))} env steps, "
            f"{_duration(elapsed)} elapsed, ETA {'?' if eta is None else bound + _duration(eta)}{why}"
        )

    text = line

    def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict[str, Any], **info: Any) -> None:
        self._tick(trials)
        # Before: the trial's previous result in this run, or what an earlier run left (a restored trial's last result).
        before = self._result(trial)
        now, then = float(result.get(STEPS_DONE, 0.0)), float(before.get(STEPS_DONE, 0.0))
        self._played += now - then if now >= then else now  # fewer steps than before: it started again
        self._latest[trial.trial_id] = result
        super().on_trial_result(iteration, trials, trial, result, **info)


PROGRESS = {"lines": ProgressLine, "table": ProgressTable}


class TrimRerunResults(Callback):
    """Keep each trial's result files free of repeated iterations after a resume.

    A trial resumed from its checkpoint at iteration k re-runs k+1, k+2, ...; Tune would
    append those rows again. When a result arrives whose iteration is not past the last
    one on disk, the rows from that iteration on are dropped first (this callback runs
    before Tune's loggers write the new row). Works on local (or mounted) storage.
    """

    def __init__(self) -> None:
        self._last: dict[str, int] = {}

    @staticmethod
    def _files(trial: Any) -> list[Path]:
        folders = {Path(p) for p in (getattr(trial, "local_path", None), getattr(trial, "path", None)) if p}
        return [folder / name for folder in folders for name in PROGRESS_FILES if (folder / name).is_file()]

    @staticmethod
    def _row_iterations(path: Path, lines: list[str]) -> list[int | None]:
        """The training iteration of each row of `lines`, the text of `path` (after a CSV's header), None for a row cut short by a kill."""
        if path.suffix == ".csv":
            if len(lines) < 2:
                return []
            column = next(csv.reader(lines[:1])).index("training_iteration")
            return [_parsed(lambda: int(float(row[column]))) for row in csv.reader(lines[1:])]
        return [_parsed(lambda: int(json.loads(line)["training_iteration"])) for line in lines]

    def _logged(self, path: Path) -> list[int]:
        return [it for it in self._row_iterations(path, path.read_text().splitlines()) if it is not None]

    def _trim(self, path: Path, before: int) -> None:
        lines = path.read_text().splitlines(keepends=True)
        header = lines[:1] if path.suffix == ".csv" else []
        rows = lines[len(header) :]
        keep = header + [line for line, it in zip(rows, self._row_iterations(path, lines)) if it is not None and it < before]
        write_text_atomically(path, "".join(keep))

    def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict[str, Any], **info: Any) -> None:
        current = int(result.get("training_iteration", 0))
        if trial.trial_id not in self._last:  # first result since this driver started: ask the disk
            self._last[trial.trial_id] = max((max(self._logged(f), default=0) for f in self._files(trial)), default=0)
        if current <= self._last[trial.trial_id]:
            for path in self._files(trial):
                self._trim(path, before=current)
        self._last[trial.trial_id] = current


def _parsed(read: Callable[[], int]) -> int | None:
    try:
        return read()
    except (ValueError, IndexError, KeyError, TypeError):
        return None


CHECKPOINTED = ".checkpointed"  # suffix of a trial's result files as they were at its last checkpoint


class KeepLogsAtCheckpoints(Callback):
    """Copy each trial's result files into its storage folder, atomically, whenever it saves a checkpoint.

    Tune writes a trial's progress.csv and result.json in a staging folder on the driver and copies
    that folder to storage in the background every so often, file over file. A run killed during
    that copy leaves torn files in storage, and the trial resumed from its checkpoint lost the rows
    before it (seen once in the SIGKILL sweep test, under load). `restore_checkpointed_logs` puts
    these copies back before a resume; `TrimRerunResults` drops the rows re-run after the checkpoint.
    Works on local (or mounted) storage.
    """

    def on_checkpoint(self, iteration: int, trials: list, trial: Any, checkpoint: Any, **info: Any) -> None:
        staging, storage = Path(trial.local_path), Path(trial.path)
        if staging == storage or not storage.is_dir():
            return
        for name in PROGRESS_FILES:
            if (staging / name).is_file():
                _copy_atomically(staging / name, storage / f"{name}{CHECKPOINTED}")


def restore_checkpointed_logs(experiment: Path) -> None:
    """Before the Tune experiment at `experiment` resumes: each trial's result files become those of its last checkpoint (`KeepLogsAtCheckpoints`)."""
    for copy in experiment.glob(f"*/*{CHECKPOINTED}"):
        _copy_atomically(copy, copy.with_name(copy.name.removesuffix(CHECKPOINTED)))


def _copy_atomically(source: Path, target: Path) -> None:
    with replaced_atomically(target) as tmp:
        shutil.copyfile(source, tmp)
