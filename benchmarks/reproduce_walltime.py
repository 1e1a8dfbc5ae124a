"""Wall time of fixed `reproduce` slices, by the code before the speed work (a git worktree of its commit) and now.

    OMP_NUM_THREADS=1 python -m benchmarks.reproduce_walltime [--old-commit 63f6b75] [--slices bandit blocks] [--work DIR] [--name NAME]
    python -m benchmarks.reproduce_walltime --measured reproduce/bandit --old-summary benchmarks/results/reproduce_bandit_round2_old.json [--name NAME]

Each slice runs from an empty folder, old code then new, one after the other on the same
machine (it is shared and noisy: compare the ratio, not the seconds). Printed and written
to `benchmarks/results/<NAME>.json` (default `reproduce_walltime`; slices not run this time are kept from the
file, each row with the date it was measured; another `--old-commit` deserves another name): per slice the wall time of each, the
ratio, the stage times, and for the new code where each stage's core-seconds went (trial
set-up, RLlib iterations, evaluations, and what is left of cores x wall: Tune's overhead
and idle cores), read from the `time/*` results every trial reports.

`--measured` runs nothing: it reads a full plan already run by the new code (its stage
markers and trials) beside the stage times an old `reproduce_summary` file recorded, or the
game folder of the old code's own run of the plan on the same machine, and
writes `reproduce_walltime_<game>_full.json` (or `<NAME>.json`); the totals and the ratio
cover the stages both runs finished.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
from datetime import datetime
from pathlib import Path
from typing import Any

from analysis import loaders
from benchmarks._common import RESULTS, machine, write_result

REPO = Path(__file__).resolve().parents[1]
SLICE_SCRIPT = REPO / "benchmarks" / "_reproduce_slice.py"
OLD_COMMIT = "63f6b75"  # main before issue 22: the house issue, the old training loop
SLICES = {
    "bandit": {
        "what": "bandit Arms 2 hand-designed partners, every method (8 + scratch), 3 seeds: train, adapt, zero-shot, marginals",
        "args": ["bandit", "--populations", "bandit-s2-hand"],
    },
    "blocks": {
        "what": "blocks hand-designed partners, ours lam 0.5 and BaselineAgg (+ scratch, picked head), 50k-step egos, 3 seeds: train, adapt",
        "args": [
            "blocks",
            "--populations",
            "blocks-perm",
            "--methods",
            "modular-lam0.5",
            "agg",
            "--train-steps",
            "50000",
            "--no-zeroshot",
        ],
    },
}
STAGE_RUNS = {"train": "train-stage-", "adapt": "adapt-stage-", "zeroshot": "zeroshot-stage-"}


# pyproject.toml's package-dir: the editable install maps these packages to this checkout's
# folders, so an old worktree on PYTHONPATH would read today's plans and data without links of its own.
DATA_PACKAGES = {"rllib_conv/tune_configs": "tune_configs", "rllib_conv/data": "analysis/data"}


def worktree(commit: str, work: Path) -> Path:
    """A checkout of `commit` (a git worktree, made once) whose rllib_conv reads its own shipped configs and data."""
    path = work / f"old-{commit}"
    if not (path / "rllib_conv").is_dir():
        subprocess.run(
            ["git", "-C", str(REPO), "worktree", "add", "--detach", str(path), commit], check=True, capture_output=True
        )
    for package, folder in DATA_PACKAGES.items():
        link = path / package
        if (path / folder).is_dir() and not link.exists():
            link.symlink_to(path / folder, target_is_directory=True)
    return path


def kept_slices(rows: list[dict[str, Any]], name: str) -> list[dict[str, Any]]:
    """The slices of the committed results file `name` that this run did not re-run (each keeps the date it was measured)."""
    path = RESULTS / f"{name}.json"
    if not path.is_file():
        return []
    earlier = json.loads(path.read_text())
    ran = {r["slice"] for r in rows}
    return [{"date": earlier.get("date"), **r} for r in earlier.get("slices", []) if r["slice"] not in ran]


def run_slice(code: Path, args: list[str], out: Path) -> dict[str, Any]:
    """Run a slice with the rllib_conv of `code`; return its wall seconds and stage seconds."""
    env = {**os.environ, "PYTHONPATH": str(code), "OMP_NUM_THREADS": "1", "RAY_ADDRESS": ""}
    # Run by its file, not with -m: it must start in `code`'s folder (an old commit may read its
    # plans by relative path), where `benchmarks` would be that commit's; it imports only rllib_conv.
    proc = subprocess.run(
        [sys.executable, str(SLICE_SCRIPT), args[0], str(out), *args[1:]], cwd=code, env=env, capture_output=True, text=True
    )
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith("SLICE ")), None)
    if proc.returncode != 0 or line is None:
        raise RuntimeError(f"slice {args} with {code} failed:\n{(proc.stdout + proc.stderr)[-4000:]}")
    return json.loads(line[len("SLICE ") :])


def _last_result(trial: Path) -> dict[str, Any]:
    lines = (
        [ln for ln in (trial / "result.json").read_text().splitlines() if ln.strip()] if (trial / "result.json").is_file() else []
    )
    return json.loads(lines[-1]) if lines else {}


def breakdown(game_dir: Path, stages: dict[str, float], cores: int) -> dict[str, dict[str, float]]:
    """Per stage of the new code: core-seconds in trial set-up, RLlib iterations and evaluations; the rest of cores x wall."""
    out = {}
    for stage, prefix in STAGE_RUNS.items():
        results = [_last_result(t) for run in (game_dir / "runs").glob(f"{prefix}*") for t in run.iterdir() if t.is_dir()]
        results = [r for r in results if r]
        if not results or stage not in stages:
            continue
        parts = {kind: sum(r.get(f"time/{kind}", 0.0) for r in results) for kind in ("setup", "iterate", "evaluate")}
        busy = parts["setup"] + sum(r.get("time_total_s", 0.0) for r in results)
        out[stage] = {
            "trials": len(results),
            **{f"{k}_core_s": v for k, v in parts.items()},
            "tune_and_idle_core_s": cores * stages[stage] - busy,
        }
    return out


def _print_rows(rows: list[dict[str, Any]]) -> None:
    print(
        f"{'slice':8} {'stage':9} {'old s':>8} {'new s':>8} {'ratio':>6}   new core-seconds: setup / iterate / evaluate / Tune+idle"
    )
    for row in rows:
        for stage, old_s in row["old_stages_s"].items():
            new_s = row["new_stages_s"].get(stage, float("nan"))
            b = row["new_breakdown"].get(stage)
            split = (
                f"{b['setup_core_s']:.0f} / {b['iterate_core_s']:.0f} / {b['evaluate_core_s']:.0f} / {b['tune_and_idle_core_s']:.0f}"
                if b
                else ""
            )
            print(
                f"{row['slice']:8} {stage:9} {old_s:8.0f} {new_s:8.0f} {old_s / new_s if new_s else float('nan'):6.1f}   {split}"
            )
        print(f"{row['slice']:8} {'total':9} {row['old_wall_s']:8.0f} {row['new_wall_s']:8.0f} {row['speedup']:6.1f}")


def _stage_seconds(game_dir: Path) -> dict[str, float]:
    """The seconds of each finished stage of a reproduce game folder (its stage markers)."""
    return {s["stage"]: s["seconds"] for s in loaders.load_stage_times(game_dir).to_dict(orient="records") if s.get("done")}


def measured(game_dir: Path, old_summary: Path, cores: int, name: str | None = None) -> None:
    """The full plan of `game_dir` (already run) against the stage times of `old_summary`; print and write them (to `name`, default `reproduce_walltime_<game>_full`)."""
    # A stage's seconds count where recorded: a folder grown later (more seeds) marks its earlier stages not done.
    if old_summary.is_dir():  # the old code's own full run, side by side with this one
        old = _stage_seconds(old_summary)
    else:
        old = {
            s["stage"]: s["seconds"]
            for s in json.loads(old_summary.read_text())["stages"]
            if math.isfinite(s.get("seconds") or math.nan)
        }
    new = _stage_seconds(game_dir)
    # Only the stages both runs finished are compared (an old run may be stopped once the stages a change touches are done).
    both = [stage for stage in new if stage in old]
    row = {
        "slice": game_dir.name,
        "what": f"the full {game_dir.name} plan: {loaders.read_plan(game_dir)}",
        "stages_compared": both,
        "old_wall_s": sum(old[s] for s in both),
        "new_wall_s": sum(new[s] for s in both),
        "speedup": sum(old[s] for s in both) / sum(new[s] for s in both),
        "old_stages_s": old,
        "new_stages_s": new,
        "new_breakdown": breakdown(game_dir, new, cores),
        **({"old_breakdown": breakdown(old_summary, old, cores)} if old_summary.is_dir() else {}),
    }
    _print_rows([row])
    print(
        f"wrote {write_result(name or f'reproduce_walltime_{game_dir.name}_full', {'old_summary': str(old_summary), 'cores': cores, 'slices': [row]})}"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--old-commit", default=OLD_COMMIT)
    p.add_argument("--slices", nargs="+", default=list(SLICES), choices=list(SLICES))
    p.add_argument(
        "--work", type=Path, default=None, help="where the old worktree and the slices' folders go (default: a temp dir)"
    )
    p.add_argument("--measured", type=Path, help="run nothing: a reproduce game folder the new code already ran in full")
    p.add_argument(
        "--old-summary",
        type=Path,
        help="with --measured: the old code's reproduce_summary JSON (its stage times), or the game folder of its own full run",
    )
    p.add_argument(
        "--name",
        default=None,
        help="the results file, benchmarks/results/<NAME>.json (default: reproduce_walltime, or with --measured reproduce_walltime_<game>_full)",
    )
    args = p.parse_args()
    cores = os.cpu_count() or 1
    if args.measured or args.old_summary:
        if not (args.measured and args.measured.is_dir() and args.old_summary and args.old_summary.exists()):
            p.error("--measured needs a game folder and --old-summary a reproduce_summary JSON or the old code's game folder")
        measured(args.measured, args.old_summary, cores, args.name)
        return
    work = args.work or Path(tempfile.mkdtemp(prefix="walltime-"))
    old = worktree(args.old_commit, work)
    rows = []
    for name in args.slices:
        spec = SLICES[name]
        before = run_slice(old, spec["args"], work / f"{name}-old")
        after = run_slice(REPO, spec["args"], work / f"{name}-new")
        game_dir = work / f"{name}-new" / spec["args"][0]
        rows.append(
            {
                "slice": name,
                "date": datetime.now().isoformat(timespec="seconds"),
                "what": spec["what"],
                "old_wall_s": before["wall_s"],
                "new_wall_s": after["wall_s"],
                "speedup": before["wall_s"] / after["wall_s"],
                "old_stages_s": before["stages"],
                "new_stages_s": after["stages"],
                "new_breakdown": breakdown(game_dir, after["stages"], cores),
            }
        )
        print(
            f"{name}: old {before['wall_s']:.0f} s, new {after['wall_s']:.0f} s, {before['wall_s'] / after['wall_s']:.1f}x faster",
            flush=True,
        )
    print()
    _print_rows(rows)
    name = args.name or "reproduce_walltime"
    path = write_result(name, {"old_commit": args.old_commit, "cores": cores, "slices": kept_slices(rows, name) + rows})
    print(f"wrote {path}")
    print(f"machine: {machine()['cpu']}, {cores} cores")


if __name__ == "__main__":
    main()
