"""The live sweep table: one row per trial with its swept values, status and latest metrics."""

from __future__ import annotations

import pickle
from functools import partial
from types import SimpleNamespace

from rllib_conv.training import callbacks
from rllib_conv.training.callbacks import STEPS_DONE, STEPS_TOTAL, ProgressTable
from rllib_conv.training.tuning import JOB_KEY, job_param_space, job_units


def _trial(trial_id, status, params, result):
    return SimpleNamespace(trial_id=trial_id, status=status, config={}, evaluated_params=params, last_result=result)


def test_table_rows_hold_swept_values_and_latest_metrics() -> None:
    trials = [
        _trial(
            "x_0", "RUNNING", {"lam": 0.5, "model/z_dim": 5}, {"training_iteration": 3, "env_steps": 768, "return_mean": 0.91234}
        ),
        _trial(
            "x_1",
            "TERMINATED",
            {"lam": 0.0, "model/z_dim": 30},
            {"training_iteration": 40, "env_steps": 10240, "return_mean": 1.0},
        ),
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
    # zero; "b" is new. In this run's first 10 s, both running, they play 100 + 200 steps: 300 steps in
    # 20 trial-seconds, 15 steps/s a trial; a has 900 left, b 800, one core each: 60 s.
    now = [0.0]
    monkeypatch.setattr(callbacks.time, "monotonic", lambda: now[0])
    progress = callbacks.StageProgress("[bandit] adapt", every=1e9, log=lambda line: None)
    trials = [_trial("a", "RUNNING", {}, {STEPS_DONE: 500, STEPS_TOTAL: 1000}), _trial("b", "RUNNING", {}, {})]
    now[0] = 10.0
    progress.on_trial_result(1, trials, trials[0], {STEPS_DONE: 100, STEPS_TOTAL: 1000})
    progress.on_trial_result(1, trials, trials[1], {STEPS_DONE: 200, STEPS_TOTAL: 1000})
    assert progress.line(trials) == "[bandit] adapt: 0/2 trials done, 0.3k/2.0k env steps, 0m10s elapsed, ETA 1m00s"
    # Later results add what was played since the trial's previous one: 600 steps in 40 trial-seconds;
    # b's 800 left decide: 53 s.
    now[0] = 20.0
    progress.on_trial_result(2, trials, trials[0], {STEPS_DONE: 400, STEPS_TOTAL: 1000})
    assert progress.line(trials) == "[bandit] adapt: 0/2 trials done, 0.6k/2.0k env steps, 0m20s elapsed, ETA 0m53s"


def test_a_stage_whose_trials_may_stop_early_prints_bounds_and_why(monkeypatch) -> None:
    # Two self-play pairs of at most 1000 steps each, 200 and 100 played in 10 s by two trials: 15 steps a
    # trial-second; pair b has 900 left: at most 60 s. Once both have stopped nothing is left, and the line says so plainly.
    now = [0.0]
    monkeypatch.setattr(callbacks.time, "monotonic", lambda: now[0])
    progress = callbacks.StageProgress(
        "[hanabi] self-play", every=1e9, log=lambda line: None, stops_early="a pair stops when it passes the gate"
    )
    trials = [_trial("a", "RUNNING", {}, {}), _trial("b", "RUNNING", {}, {})]
    now[0] = 10.0
    progress.on_trial_result(1, trials, trials[0], {STEPS_DONE: 200, STEPS_TOTAL: 1000})
    progress.on_trial_result(1, trials, trials[1], {STEPS_DONE: 100, STEPS_TOTAL: 1000})
    assert progress.line(trials) == (
        "[hanabi] self-play: 0/2 trials done, 0.3k/at most 2.0k env steps, 0m10s elapsed, ETA at most 1m00s (a pair stops when it passes the gate)"
    )
    for trial in trials:
        trial.status = "TERMINATED"
    assert progress.line(trials) == "[hanabi] self-play: 2/2 trials done, 0.3k/0.3k env steps, 0m10s elapsed, ETA 0m00s"


def test_stage_eta_counts_a_last_trial_alone_on_one_core(monkeypatch) -> None:
    # Five trials of 1000 steps on 2 cores. After 100 s two are done and two are half way (3000
    # steps in 200 trial-seconds: 15 a trial-second). Left: 500 + 500 on the two cores, then the
    # fifth's 1000 on the first free one: 1500 steps on one core, 100 s (the stage's rate would say 67).
    now = [0.0]
    monkeypatch.setattr(callbacks.time, "monotonic", lambda: now[0])
    progress = callbacks.StageProgress("[blocks] train", every=1e9, log=lambda line: None)
    trials = [_trial(t, "RUNNING", {}, {}) for t in "abcde"]
    for t in trials[2:]:
        t.status = "PENDING"
    now[0] = 50.0
    for t in trials[:2]:
        progress.on_trial_result(1, trials, t, {STEPS_DONE: 1000, STEPS_TOTAL: 1000})
        t.status = "TERMINATED"
    for t in trials[2:4]:
        t.status = "RUNNING"
    now[0] = 100.0
    for t in trials[2:4]:
        progress.on_trial_result(1, trials, t, {STEPS_DONE: 500, STEPS_TOTAL: 1000})
    assert progress.line(trials) == "[blocks] train: 2/5 trials done, 3.0k/5.0k env steps, 1m40s elapsed, ETA 1m40s"
    for t in trials:
        t.status = "TERMINATED"
    assert progress.eta_seconds(trials) == 0.0


def test_stage_total_counts_waiting_trials_by_their_units(monkeypatch) -> None:
    # 15 seeds of 1000 steps cut into trials of 5, 5, 3 and 2 seeds, the first two running: 2 000 played.
    # Known: 10 000 steps for 10 seeds, 1 000 a seed; the waiting trials hold 3 and 2 seeds: 15 000 in
    # all (counting them at the mean trial's 5 000 would say 20 000).
    now = [0.0]
    monkeypatch.setattr(callbacks.time, "monotonic", lambda: now[0])
    sizes = {"a": 5, "b": 5, "c": 3, "d": 2}
    progress = callbacks.StageProgress("[blocks] train", every=1e9, log=lambda line: None, units=lambda config: config["seeds"])
    trials = [_trial(t, "RUNNING" if t in "ab" else "PENDING", {}, {}) for t in sizes]
    for t in trials:
        t.config = {"seeds": sizes[t.trial_id]}
    now[0] = 10.0
    for t in trials[:2]:
        progress.on_trial_result(1, trials, t, {STEPS_DONE: 1000, STEPS_TOTAL: 5000})
    assert progress.line(trials).startswith("[blocks] train: 0/4 trials done, 2.0k/15.0k env steps")
    for t in trials[:2]:
        t.last_result = {STEPS_DONE: 1000, STEPS_TOTAL: 5000}
    assert (
        callbacks.StageProgress("[blocks] train").line(trials).startswith("[blocks] train: 0/4 trials done, 2.0k/20.0k env steps")
    )


def test_a_stage_counts_units_in_its_trials_jobs_and_its_progress_pickles_with_tunes_state() -> None:
    space = job_param_space([{"index": 0, "curves": [1, 2, 3]}, {"index": 1, "curves": [4]}])
    assert [job_units({JOB_KEY: job}, "curves") for job in space[JOB_KEY]["grid_search"]] == [3, 1]
    progress = pickle.loads(pickle.dumps(callbacks.StageProgress("[bandit] adapt", units=partial(job_units, key="curves"))))
    assert progress.units({JOB_KEY: {"curves": [1, 2]}}) == 2
