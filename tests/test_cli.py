"""The `rllib-conv` command: listing and showing, bad input (exit 2, one line, nothing written), a tiny train.

Every other bad input: tests/test_cli_errors.py; help: tests/test_cli_help.py; where results go: tests/test_cli_outputs.py.
"""

from __future__ import annotations

import pytest
import yaml

from rllib_conv.cli import main
from rllib_conv.common.run_folders import trial_folders


def test_envs_and_partners_list(capsys) -> None:
    assert main(["envs"]) == 0
    assert {"bandit", "blocks", "hanabi"} <= set(capsys.readouterr().out.split())
    assert main(["partners", "list"]) == 0
    out = capsys.readouterr().out
    assert "bandit-s2-hand" in out and "blocks-perm" in out and "bandit-user-study" in out
    assert "rllib-conv partners show NAME" in out


def test_partners_show_lists_members_with_split_kind_and_params(capsys) -> None:
    assert main(["partners", "show", "bandit-s2-hand"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("bandit-s2-hand: bandit {'symmetric': 2")
    members = [line for line in lines if line.strip().startswith(("hand-train-", "hand-test-"))]
    assert len(members) == 8
    assert members[0].split()[:3] == ["hand-train-0", "train", "bandit_convention"]
    assert members[0].rstrip().endswith('{"arms": [0, 1, 2, 3]}')
    assert {m.split()[1] for m in members} == {"train", "test"}


def test_bad_config_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys) -> None:
    path = tmp_path / "exp.yaml"
    path.write_text(yaml.safe_dump({"population": "bandit-s2-hand", "lamda": 0.5}))
    storage = tmp_path / "runs"
    assert main(["train", str(path), "--storage", str(storage)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "lamda: Extra inputs are not permitted" in err[0]
    assert main(["train", str(tmp_path / "missing.yaml"), "--storage", str(storage)]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["train", str(path), "--set", "lamda", "--storage", str(storage)]) == 2
    assert not storage.exists()


def test_adapt_rejects_a_zero_pick_budget_before_anything_runs(tmp_path, capsys) -> None:
    out, storage = tmp_path / "curves", tmp_path / "runs"
    try:
        status = main(
            ["adapt", str(tmp_path), "--head-init", "pick", "--pick-steps", "0", "--out", str(out), "--storage", str(storage)]
        )
    except SystemExit as exc:  # argparse refuses it
        status = exc.code
    assert status == 2
    assert "argument --pick-steps: expected a whole number >= 1, got '0'" in capsys.readouterr().err  # not silently the default
    assert not out.exists() and not storage.exists()


def test_unknown_population_is_reported_before_training(tmp_path, capsys) -> None:
    path = tmp_path / "exp.yaml"
    path.write_text(yaml.safe_dump({"name": "x", "population": {"grid_search": ["bandit-s2-hand", "no-such-population"]}}))
    assert main(["train", str(path), "--storage", str(tmp_path / "runs")]) == 2
    assert "unknown population 'no-such-population'" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()


@pytest.mark.slow
def test_train_prints_a_summary_per_trial(ray_session, tmp_path, capsys) -> None:
    path = tmp_path / "exp.yaml"
    exp = {
        "name": "tiny",
        "population": {"grid_search": ["bandit-s1-hand", "bandit-s2-hand"]},
        "model": {"hidden": 8},
        "ppo": {"rollout_per_partner": 16, "num_epochs": 1},
        "run": {"timesteps": 64},
    }
    path.write_text(yaml.safe_dump(exp))
    assert main(["train", str(path), "--storage", str(tmp_path / "runs")]) == 0
    out = capsys.readouterr().out
    rows = [line for line in out.splitlines() if "bandit-s" in line]
    assert len(rows) == 2 and "bandit-s1-hand" in rows[0] + rows[1] and "bandit-s2-hand" in rows[0] + rows[1]
    assert all(" modular " in row for row in rows)  # read from each trial's config.yaml, not None
    assert len(trial_folders(tmp_path / "runs" / "tiny")) == 2  # one trained ego per population
    assert out.splitlines()[-1] == f"results in {tmp_path / 'runs' / 'tiny'}"
    assert f"tensorboard --logdir {tmp_path / 'runs' / 'tiny'}" in out
