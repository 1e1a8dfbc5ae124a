"""The live sweep table: one row per trial with its swept values, status and latest metrics."""

from __future__ import annotations

from types import SimpleNamespace

from rllib_conv.training import callbacks
from rllib_conv.training.callbacks import STEPS_DONE, STEPS_TOTAL, ProgressTable


def _trial(trial_id, status, params, result):
    return SimpleNamespace(trial_id=trial_id, status=status, config={}, evaluated_params=params, last_result=result)


def test_table_rows_hold_swept_values_and_latest_metrics() -> None:
    trials = [
        _trial("x_0", "RUNNING", {"lam": 0.5, "model/z_dim": 5}, {"training_iteration": 3, "env_steps": 768, "return_mean": 0.91234}),
        _trial("x_1", "TERMINATED", {"lam": 0.0, "model/z_dim": 30}, {"training_iteration": 40, "env_steps": 10240, "return_mean": 1.0}),
        _trial("x_2", "PENDING", {"lam": 0.3, "model/z_dim": 30}, {}),
    ]
    lines = ProgressTable().table(trials).splitlines()
    assert lines[0] == "--- 1/3 trials finished ---"
    assert lines[1].split() == ["trial", "status", "lam", "model/z_dim", "iter", "steps", "return", "reg"]
    assert lines[2].split() == ["x_0", "RUNNING", "0.5", "5", "3", "768", "0.912"]
    assert lines[3].split() == ["x_1", "TERMINATED", "0.0", "30", "40", "10240", "1.000"]
    assert lines[4].split() == ["x_2", "PENDING", "0.3", "30", "0"]
    assert len({len(line) for line in lines[1:]}) == 1  # columns aligned


def test_stage_line_counts_this_runs_steps_for_its_eta(monkeypatch) -> None:
    # A resumed stage: pack "a" had played 500 of its 1000 steps before the kill and starts again from
    # zero; "b" is new. In this run's first 10 s they play 100 + 200 steps: 30 steps/s, 1700 left, 57 s.
    now = [0.0]
    monkeypatch.setattr(callbacks.time, "monotonic", lambda: now[0])
    progress = callbacks.StageProgress("[bandit] adapt", every=1e9, log=lambda line: None)
    trials = [_trial("a", "RUNNING", {}, {STEPS_DONE: 500, STEPS_TOTAL: 1000}), _trial("b", "RUNNING", {}, {})]
    now[0] = 10.0
    progress.on_trial_result(1, trials, trials[0], {STEPS_DONE: 100, STEPS_TOTAL: 1000})
    progress.on_trial_result(1, trials, trials[1], {STEPS_DONE: 200, STEPS_TOTAL: 1000})
    assert progress.line(trials) == "[bandit] adapt: 0/2 trials done, 0.3k/2.0k env steps, 0m10s elapsed, ETA 0m57s"
    # Later results add what was played since the trial's previous one: 600 steps in 20 s, 1400 left.
    now[0] = 20.0
    progress.on_trial_result(2, trials, trials[0], {STEPS_DONE: 400, STEPS_TOTAL: 1000})
    assert progress.line(trials) == "[bandit] adapt: 0/2 trials done, 0.6k/2.0k env steps, 0m20s elapsed, ETA 0m47s"
