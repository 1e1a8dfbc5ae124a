"""The live sweep table: one row per trial with its swept values, status and latest metrics."""

from __future__ import annotations

from types import SimpleNamespace

from rllib_conv.training.callbacks import ProgressTable


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
