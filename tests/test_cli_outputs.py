"""Where results go: outputs named after their inputs, a reused run said so, one last `wrote`/`results in` line, quiet by default.

One tiny ego (64 env steps on the bandit with 1 symmetric context) is trained once through
`rllib-conv train`; the other commands read it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from rllib_conv import envs, partners
from rllib_conv.cli import main
from rllib_conv.common.run_folders import trial_folders
from rllib_conv.pipelines.pair import pair
from rllib_conv.pipelines.pair_config import PairConfig
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.evaluate import ego_head_partner, load_module, task_probs

pytestmark = pytest.mark.slow  # every test here trains (RLlib, Tune or `rllib-conv` subprocesses)

TINY = {
    "name": "tiny",
    "population": "bandit-s1-hand",
    "model": {"hidden": 8},
    "ppo": {"rollout_per_partner": 16, "num_epochs": 1},
    "run": {"timesteps": 64},
}


@pytest.fixture(scope="module")
def tiny(ray_session, tmp_path_factory) -> dict[str, Path]:
    """The experiment file, the storage folder and the one trial folder of a tiny trained ego."""
    root = tmp_path_factory.mktemp("cli_outputs")
    config = root / "tiny.yaml"
    config.write_text(yaml.safe_dump(TINY))
    assert main(["train", str(config), "--storage", str(root / "runs")]) == 0
    (tune_trial,) = (root / "runs" / "tiny").glob("EgoTrainable_*")
    (trial,) = trial_folders(root / "runs" / "tiny")  # the trained ego: the Tune trial, or its one replica folder
    return {"root": root, "config": config, "storage": root / "runs", "tune_trial": tune_trial, "trial": trial}


def last_line(out: str) -> str:
    return out.strip().splitlines()[-1]


def test_train_again_says_the_run_is_reused_and_trains_nothing(tiny, capsys) -> None:
    progress = (tiny["tune_trial"] / "progress.csv").read_text()
    capsys.readouterr()
    assert main(["train", str(tiny["config"]), "--storage", str(tiny["storage"])]) == 0
    out = capsys.readouterr().out
    assert f"note: {tiny['storage'] / 'tiny'} already holds this experiment (1 of 1 trained egos finished)" in out
    assert (tiny["tune_trial"] / "progress.csv").read_text() == progress
    assert last_line(out) == f"results in {tiny['storage'] / 'tiny'}"
    assert f"figure: {tiny['storage'] / 'tiny' / 'learning_curves.png'}" in out


def test_plot_redraws_the_figures_of_a_training_folder(tiny, capsys) -> None:
    figure = tiny["storage"] / "tiny" / "learning_curves.png"
    figure.unlink()
    assert main(["plot", str(tiny["storage"] / "tiny")]) == 0
    assert last_line(capsys.readouterr().out) == f"wrote {figure}"
    assert figure.read_bytes().startswith(b"\x89PNG")


def test_adapt_names_its_outputs_after_the_inputs_so_a_second_adaptation_does_not_clash(tiny, tmp_path, capsys) -> None:
    common = [
        "--set",
        "steps=16",
        "--set",
        "every=16",
        "--set",
        "episodes=4",
        "--storage",
        str(tmp_path / "runs"),
        "--out",
        str(tmp_path / "curves"),
    ]
    assert main(["adapt", str(tiny["trial"]), "--partner", "hand-test-0", *common]) == 0
    first = capsys.readouterr().out
    assert main(["adapt", str(tiny["trial"]), "--partner", "hand-test-1", *common]) == 0  # another experiment, another name
    second = capsys.readouterr().out
    csvs = sorted((tmp_path / "curves").glob("*.csv"))
    run = "-".join(
        ["tiny", "_".join(tiny["tune_trial"].name.split("_")[1:3]), *tiny["trial"].relative_to(tiny["tune_trial"]).parts]
    )
    assert len(csvs) == 2 and all(c.name.startswith(f"{run}-hand-test-") for c in csvs), csvs
    assert {last_line(first), last_line(second)} == {f"wrote {c}" for c in csvs}
    assert {pd.read_csv(c)["partner"].iloc[0] for c in csvs} == {"hand-test-0", "hand-test-1"}
    assert f"figure: {csvs[0].with_suffix('.png')}" in first + second
    table = [line for line in first.split("by env steps:\n", 1)[1].splitlines() if not line.startswith(("figure: ", "wrote "))]
    assert table[0].split() == ["steps", "modular", "lam", "0.0", "return", "modular", "lam", "0.0", "exact"]
    assert max(map(len, table)) < 100  # it was ~250 characters wide


def test_marginals_writes_a_csv_named_after_the_run_into_the_out_folder(tiny, tmp_path, capsys) -> None:
    assert main(["marginals", str(tiny["storage"] / "tiny"), "--out", str(tmp_path / "m")]) == 0
    path = tmp_path / "m" / "tiny.csv"
    assert last_line(capsys.readouterr().out) == f"wrote {path}"
    assert pd.read_csv(path)["population"].tolist() == ["bandit-s1-hand"]


def test_pair_an_ego_head_with_a_population_member_matches_the_exact_evaluation(tiny, tmp_path, capsys) -> None:
    trial = tiny["trial"]
    seats = [f"{trial}:ego@hand-train-1", "bandit-s1-hand:hand-train-1"]
    assert main(["pair", *seats, "--episodes", "50", "--out", str(tmp_path / "pairs")]) == 0
    (path,) = (tmp_path / "pairs").glob("*.csv")
    assert last_line(capsys.readouterr().out) == f"wrote {path}"
    assert path.name.endswith("-ego@hand-train-1__bandit-s1-hand-hand-train-1.csv")
    row = pd.read_csv(path).iloc[0]
    module = load_module(last_checkpoint(trial))
    env = envs.make("bandit", symmetric=1)
    partner = partners.get("bandit-s1-hand").entries("train")[1].build()
    # By hand: the ego's probability of the partner's one arm in each context, times its prize, over the contexts.
    contexts, mask = np.eye(env.num_contexts, dtype=np.float32), np.ones((env.num_contexts, env.num_arms), dtype=np.int8)
    probs, arms = ego_head_partner(module, "ego@hand-train-1").action_probs(contexts, mask), partner.act_batch(contexts, mask)
    rows = np.arange(env.num_contexts)
    assert row["exact_return"] == pytest.approx(float(np.mean(probs[rows, arms] * env.prizes[rows, arms])), abs=1e-6)
    assert (row["seat_0"], row["seat_1"], row["episodes"]) == (seats[0], seats[1], 50)


def test_runs_given_as_relative_paths_load(tiny, tmp_path, monkeypatch, capsys) -> None:
    """The README writes `runs/...`: RLlib's loader reads a relative path as a URI without a scheme unless it is resolved first."""
    monkeypatch.chdir(tiny["root"])
    trial = tiny["trial"].relative_to(tiny["root"])
    assert (
        main(
            ["pair", f"{trial}:ego@hand-train-1", "bandit-s1-hand:hand-train-1", "--episodes", "5", "--out", str(tmp_path / "p")]
        )
        == 0
    )
    assert main(["marginals", "runs/tiny", "--out", str(tmp_path / "m")]) == 0
    assert last_line(capsys.readouterr().out) == f"wrote {tmp_path / 'm' / 'tiny.csv'}"
    assert len(list((tmp_path / "p").glob("*.csv"))) == 1


def test_pair_the_task_module_alone_in_the_second_seat(tiny) -> None:
    arms = [4, 1, 2, 3]
    table = pair(PairConfig(seats=[f"bandit_convention:{{arms: {arms}}}", f"{tiny['trial']}:task"], episodes=20))
    module = load_module(last_checkpoint(tiny["trial"]))
    probs = task_probs(module, np.eye(4, dtype=np.float32), np.ones((4, 8), dtype=np.float32))
    prizes = envs.make("bandit", symmetric=1).prizes
    expected = np.mean([probs[c, a] * prizes[c, a] for c, a in enumerate(arms)])
    assert table["exact_return"].iloc[0] == pytest.approx(expected, abs=1e-6)
    assert table["env_config"].iloc[0] == str({"symmetric": 1, "new_task": False})


def test_commands_are_quiet_unless_verbose(tiny) -> None:
    """Loading a checkpoint makes RLlib warn about deprecations; only -v shows that."""
    run = [
        sys.executable,
        "-m",
        "rllib_conv.cli",
        "pair",
        f"{tiny['trial']}:task",
        "bandit-s1-hand:hand-train-0",
        "--episodes",
        "2",
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    quiet = subprocess.run([*run, "--out", str(tiny["root"] / "q")], capture_output=True, text=True, env=env, timeout=120)
    loud = subprocess.run([*run, "--out", str(tiny["root"] / "v"), "-v"], capture_output=True, text=True, env=env, timeout=120)
    assert quiet.returncode == 0 and loud.returncode == 0, quiet.stderr + loud.stderr
    assert quiet.stderr == ""
    assert "Deprecat" in loud.stderr
    assert last_line(quiet.stdout).startswith(f"wrote {tiny['root'] / 'q'}")


def test_a_trained_egos_config_is_sealed_and_a_damaged_copy_is_refused(tiny, tmp_path, capsys) -> None:
    """Issue 47: `config.yaml` cut to 100 bytes (lam 0.5 read as lam 0) made `marginals` write a CSV labelled with the wrong lam."""
    trial = tiny["trial"]
    assert (trial / "config.yaml.sha256").is_file()  # written with the config, so damage is caught
    copy = tmp_path / "copy" / trial.name
    shutil.copytree(trial, copy)
    (copy / "config.yaml").write_text((trial / "config.yaml").read_text()[:100])
    capsys.readouterr()
    assert main(["marginals", str(copy), "--out", str(tmp_path / "m")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{copy / 'config.yaml'}" in err[0] and "corrupt" in err[0], err
    assert not (tmp_path / "m").exists()
