"""Tune callbacks of every pipeline: a progress line per result, a live table of trials, result files kept free of repeats."""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any

from ray.tune import Callback

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
        parts = [f"[{trial.trial_id}] iter {result.get('training_iteration', 0):4d}", f"steps {steps:8d}"]
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


class ProgressTable(Callback):
    """Print a table of every trial (its swept values, status, iteration, steps, return) as the sweep runs.

    Reprinted at most every `every` seconds while results arrive, whenever a trial
    finishes or fails, and once at the end.
    """

    METRICS = (("env_steps", "steps"), ("return_mean", "return"), (MARGINAL_REG_KEY, "reg"))

    def __init__(self, every: float = 30.0) -> None:
        self.every = every
        self._last_print = 0.0

    def table(self, trials: list) -> str:
        """The current table as text: one row per trial."""
        rows = []
        for trial in trials:
            cfg, result = trial.config or {}, trial.last_result or {}
            row = {"trial": trial.trial_id, "status": trial.status}
            # The swept values (grid keys, nested ones as "model/z_dim"), else the usual identifiers.
            swept = getattr(trial, "evaluated_params", None) or {k: cfg.get(k) for k in ("population", "method", "lam", "seed") if k in cfg}
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

    def _print(self, trials: list) -> None:
        self._last_print = time.monotonic()
        print(self.table(trials), flush=True)

    def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict[str, Any], **info: Any) -> None:
        if time.monotonic() - self._last_print >= self.every:
            self._print(trials)

    def on_trial_complete(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        self._print(trials)

    def on_trial_error(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        self._print(trials)

    def on_experiment_end(self, trials: list, **info: Any) -> None:
        self._print(trials)


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
    def _logged(path: Path) -> list[int]:
        if path.suffix == ".csv":
            rows = path.read_text().splitlines()
            if len(rows) < 2:
                return []
            column = rows[0].split(",").index("training_iteration")
            return [int(float(r.split(",")[column])) for r in rows[1:] if r]
        return [json.loads(line)["training_iteration"] for line in path.read_text().splitlines() if line.strip()]

    def _trim(self, path: Path, before: int) -> None:
        lines = path.read_text().splitlines(keepends=True)
        if path.suffix == ".csv":
            keep = lines[:1] + [line for line, it in zip(lines[1:], self._logged(path)) if it < before]
        else:
            keep = [line for line in lines if line.strip() and json.loads(line)["training_iteration"] < before]
        tmp = path.with_suffix(path.suffix + ".tmp")
        tmp.write_text("".join(keep))
        tmp.replace(path)

    def on_trial_result(self, iteration: int, trials: list, trial: Any, result: dict[str, Any], **info: Any) -> None:
        current = int(result.get("training_iteration", 0))
        if trial.trial_id not in self._last:  # first result since this driver started: ask the disk
            self._last[trial.trial_id] = max((max(self._logged(f), default=0) for f in self._files(trial)), default=0)
        if current <= self._last[trial.trial_id]:
            for path in self._files(trial):
                self._trim(path, before=current)
        self._last[trial.trial_id] = current
