"""`reproduce` stopped by Ctrl-C in its train stage, killed with SIGKILL in the middle of that stage and again in its
adapt stage, then run again: it finishes without re-running a finished trial or pack, and its results and report equal
an uninterrupted run's."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pytest
import yaml

from rllib_conv.common.resources import config_file
from tests.sweeps.killing import kill_ray_instance, private_ray_tmp

pytestmark = pytest.mark.slow  # every test here trains (RLlib, Tune or `rllib-conv` subprocesses)


def _plan(tmp_path: Path) -> Path:
    """The quick bandit plan, adapting to two test partners for the full 240 steps, so each stage lasts long enough to be killed in."""
    plan = yaml.safe_load(config_file("plan_bandit.yaml").read_text())
    plan["quick"].update({"adapt_partners": 2, "adapt_overrides": {"steps": 240, "episodes": 50}, "zeroshot_populations": []})
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(plan, sort_keys=False))
    return path


def _start(plan: Path, out: Path, ray_tmp: str) -> subprocess.Popen:
    env = {**os.environ, "RAY_TMPDIR": ray_tmp, "OMP_NUM_THREADS": "1", "RAY_ADDRESS": ""}
    cmd = [sys.executable, "-m", "rllib_conv.cli", "reproduce", "bandit", "--quick", "--plan", str(plan), "--out", str(out)]
    # SIGINT at its default in the child: a background job (nohup, a scheduler, `make test &`) starts with SIGINT
    # ignored and a child inherits that, so the Ctrl-C test's SIGINT would otherwise never reach Python.
    return subprocess.Popen(
        cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=_default_sigint
    )


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _finish(proc: subprocess.Popen, ray_tmp: str) -> str:
    out, _ = proc.communicate(timeout=900)
    kill_ray_instance(ray_tmp)
    assert proc.returncode == 0, out.decode()[-4000:]
    return out.decode()


def _kill_when(proc: subprocess.Popen, ray_tmp: str, ready: Callable[[], bool], what: str) -> None:
    deadline = time.time() + 600
    while time.time() < deadline and proc.poll() is None and not ready():
        time.sleep(0.05)
    assert proc.poll() is None and ready(), f"the run should still be {what} when killed"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    kill_ray_instance(ray_tmp)


def _finished_units(game: Path) -> dict[Path, float]:
    """Every finished trained ego (eval.json) and adaptation pack (curves.csv), with the time it was written."""
    files = [*game.glob("runs/*__*/*/seed=*/eval.json"), *game.glob("runs/adapt-stage-*/*/curves.csv")]
    return {f: f.stat().st_mtime_ns for f in files}


def _results(root: Path) -> dict[str, pd.DataFrame]:
    game = root / "bandit"
    files = [*sorted((game / "adaptation").glob("*.csv")), game / "marginals.csv"]
    return {f.name: pd.read_csv(f).assign(run=lambda t: t["run"].str.replace(str(root), "ROOT")) for f in files}


def _report(root: Path) -> str:
    text = (root / "report" / "report.md").read_text().replace(str(root), "ROOT")
    text = re.sub(r"^Built by .*$", "", text, flags=re.M)
    return re.sub(r"\(\d+ s\)", "(_ s)", text)  # stage wall times


def _interrupt_in_train(plan: Path, out: Path) -> None:
    """Ctrl-C (SIGINT to the driver) once a trial reports: Tune stops the trials and returns; the stage must not count
    as finished, and the driver says how to go on."""
    game, ray_tmp = out / "bandit", private_ray_tmp()
    proc = _start(plan, out, ray_tmp)
    deadline = time.time() + 600
    while time.time() < deadline and proc.poll() is None and not any(game.glob("runs/train-stage-*/*/progress.csv")):
        time.sleep(0.05)
    assert proc.poll() is None and not (game / "train.done").exists(), "the run should still be training when interrupted"
    os.kill(proc.pid, signal.SIGINT)
    log, _ = proc.communicate(timeout=600)
    kill_ray_instance(ray_tmp)
    log = log.decode()
    assert proc.returncode == 130, log[-4000:]
    assert re.search(r"rllib-conv: interrupted: \d+ of \d+ trials of .*train-stage-.* run the same command again", log), log[
        -4000:
    ]
    assert "[bandit] train: finished" not in log and not (game / "train.done").exists()


def test_reproduce_interrupted_then_killed_in_train_and_in_adapt_finishes_as_an_uninterrupted_run(tmp_path) -> None:
    """Ctrl-C in train, then SIGKILL in train and again in adapt, then run to the end: no finished trial or pack runs
    again, and the results and report equal an uninterrupted run's."""
    plan = _plan(tmp_path)
    reference, ray_a = tmp_path / "reference", private_ray_tmp()
    _finish(_start(plan, reference, ray_a), ray_a)

    killed = tmp_path / "killed"
    game = killed / "bandit"
    _interrupt_in_train(plan, killed)
    ray_b = private_ray_tmp()
    proc = _start(plan, killed, ray_b)
    # Train again: some egos finished, the stage not.
    _kill_when(
        proc, ray_b, lambda: any(game.glob("runs/*__*/*/seed=*/eval.json")) and not (game / "train.done").exists(), "training"
    )
    after_train_kill = _finished_units(game)

    ray_c = private_ray_tmp()
    proc = _start(plan, killed, ray_c)
    # Adapt: training done, some packs finished, the stage not.
    _kill_when(
        proc, ray_c, lambda: any(game.glob("runs/adapt-stage-*/*/curves.csv")) and not (game / "adapt.done").exists(), "adapting"
    )
    after_adapt_kill = _finished_units(game)
    assert set(after_train_kill) < set(after_adapt_kill)

    ray_d = private_ray_tmp()
    log = _finish(_start(plan, killed, ray_d), ray_d)
    assert "[bandit] train: done before, skipped" in log
    final = _finished_units(game)
    # Nothing finished before a kill ran again: its files were not rewritten.
    rewritten = [str(f.relative_to(game)) for f, t in after_adapt_kill.items() if final[f] != t]
    assert not rewritten

    ours, theirs = _results(killed), _results(reference)
    assert ours.keys() == theirs.keys() and len(ours) >= 4
    for name, table in theirs.items():
        pd.testing.assert_frame_equal(ours[name], table, rtol=1e-6, atol=1e-7, obj=name)
    assert _report(killed) == _report(reference)
