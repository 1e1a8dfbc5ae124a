"""Bad input to every command: exit status 2, one `rllib-conv: error:` line naming the argument or file, no traceback, nothing written.

Each case runs in a folder holding the files it reads (configs, trial folders, a folder
that is not a reproduction); the folder's every byte is compared before and after, with
the working directory there, so a default output folder (runs/, adaptation/, ...) counts.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from rllib_conv.cli import main
from rllib_conv.common.resources import evaluation_set_file
from rllib_conv.training.experiment import ExperimentConfig
from tests.helpers import digest


@pytest.fixture
def inputs(tmp_path: Path, monkeypatch) -> Path:
    """Configs, trial folders and CSVs, good and malformed, in the working directory."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "exp.yaml").write_text(yaml.safe_dump({"name": "x", "population": "bandit-s1-hand", "run": {"timesteps": 64}}))
    (tmp_path / "bad.yaml").write_text("name: [1\n")
    (tmp_path / "list.yaml").write_text("- 1\n- 2\n")
    (tmp_path / "a_folder").mkdir()
    trial = tmp_path / "trial"
    (trial / "checkpoint_000000").mkdir(parents=True)
    (trial / "config.yaml").write_text(
        yaml.safe_dump(ExperimentConfig(population="bandit-s1-hand").resolve("bandit").model_dump())
    )
    (tmp_path / "trial_badyaml").mkdir()
    (tmp_path / "trial_badyaml" / "config.yaml").write_text("lam: [0.5\n")
    (tmp_path / "trial_badschema").mkdir()
    (tmp_path / "trial_badschema" / "config.yaml").write_text("population: bandit-s1-hand\nlamda: 0.5\n")
    (tmp_path / "trial_nockpt").mkdir()
    (tmp_path / "trial_nockpt" / "config.yaml").write_text((trial / "config.yaml").read_text())
    (tmp_path / "notrepro").mkdir()
    (tmp_path / "notrepro" / "notes.txt").write_text("not a reproduction\n")
    return tmp_path


BLOCKS_SET = str(evaluation_set_file("blocks_heldout.yaml"))
CASES = [
    # command line itself
    (["nocommand"], "invalid choice"),
    (["train"], "required: config"),
    # experiment files and --set
    (["train", "exp.yaml", "--set", "lam=[1"], "--set lam=[1: not valid YAML"),
    (["train", "exp.yaml", "--set", "lamda=0.3"], "--set lamda=0.3: lamda: Extra inputs are not permitted"),
    (["train", "exp.yaml", "--set", "lam.x=1"], "--set lam.x=1: lam"),
    (["train", "exp.yaml", "--set", "lamda"], "--set expects key=value"),
    (["train", "exp.yaml", "--set", "run.timesteps=0"], "--set run.timesteps=0: run.timesteps: Input should be greater than 0"),
    (["train", "bad.yaml"], "'bad.yaml' is not valid YAML"),
    (["train", "list.yaml"], "list.yaml: expected a mapping of settings, got list"),
    (["train", "a_folder"], "'a_folder' is a folder"),
    (["train", "missing.yaml"], "'missing.yaml' does not exist"),
    (["sweep", "exp.yaml", "--resume"], "--resume"),
    (["demo", "--set", "ppo.lr=[1"], "--set ppo.lr=[1: not valid YAML"),
    (["partners", "train", "bad.yaml"], "'bad.yaml' is not valid YAML"),
    (["partners", "train", "exp.yaml"], "exp.yaml: env: Field required"),
    (["partners", "show", "no-such-population"], "unknown population 'no-such-population'"),
    # trained-ego folders
    (["adapt", "missing"], "'missing' is neither a trained-ego trial folder"),
    (["adapt", "trial_badyaml"], "config.yaml' is not valid YAML"),
    (["adapt", "trial_badschema"], "lamda: Extra inputs are not permitted"),
    (["adapt", "trial_nockpt"], "has no checkpoint"),
    (["adapt", "trial", "--pick-steps", "0"], "argument --pick-steps: expected a whole number >= 1, got '0'"),
    (["adapt", "trial", "--set", "steps=0"], "--set steps=0: steps: Input should be greater than 0"),
    (["adapt", "trial", "--set", "every=[1"], "--set every=[1: not valid YAML"),
    (["adapt", "trial", "--pick-steps", "5"], "--pick-steps: pick_steps is set but head_init is 'fresh'"),
    (
        ["adapt", "trial", "--head-init", "pick", "--guard"],
        "arguments with --head-init, --guard: guard: true compares the adapting ego",
    ),
    (["adapt", "trial", "--guard", "--set", "guard_z=0"], "--set guard_z=0: guard_z: Input should be greater than 0"),
    (["adapt", "trial", "--name", "a/b"], "--name: must be a non-empty folder name"),
    (["adapt", "trial", "--split", "dev"], "argument --split: invalid choice"),
    (["zeroshot", "trial_badyaml"], "config.yaml' is not valid YAML"),
    (["zeroshot", "trial", "--set", "head_steps=x"], "--set head_steps=x: head_steps: Input should be a valid integer"),
    (["marginals", "missing"], "'missing' is neither a trained-ego trial folder"),
    (["marginals", "trial", "--episodes", "0"], "argument --episodes"),
    # populations and pairs
    (["crossplay", "bandit-s1-hand", "bandit-s1-hand", "--episodes", "-1"], "argument --episodes"),
    (["pair", "bandit-s1-hand:hand-train-0"], "SEATS: List should have at least 2 items"),
    (["pair", "bandit-s1-hand", "bandit-s1-hand:hand-train-0"], "seat 'bandit-s1-hand': expected SOURCE:WHAT"),
    (["pair", "bandit-s1-hand:hand-train-0", "bandit-s1-hand:hand-train-1", "--env", "chess"], "--env: unknown env 'chess'"),
    (
        ["pair", "bandit-s1-hand:hand-train-0", "bandit-s1-hand:hand-train-1", "--env-config", "{a"],
        "--env-config: not valid YAML",
    ),
    (
        ["pair", "bandit-s1-hand:hand-train-0", "bandit-s1-hand:hand-train-1", "--env-config", "[1]"],
        "--env-config: Input should be a valid dictionary",
    ),
    (["pair", "trial_badyaml:task", "bandit-s1-hand:hand-train-0"], "config.yaml' is not valid YAML"),
    (["pair", "nothing:x", "bandit-s1-hand:hand-train-0"], "seat 'nothing:x': 'nothing' is neither a partner kind"),
    (["pair", "bandit-s1-hand:nobody", "bandit-s1-hand:hand-train-0"], "population 'bandit-s1-hand' has no member 'nobody'"),
    (["pair", "bandit_convention:{arms: [0", "bandit-s1-hand:hand-train-0"], "the parameters are not valid YAML"),
    (["pair", "bandit_convention:{colour: 1}", "bandit-s1-hand:hand-train-0"], "unexpected keyword argument 'colour'"),
    (["pair", "bandit-s1-hand:hand-train-0", "bandit-s2-hand:hand-train-0"], "different bandit settings"),
    (["pair", "bandit_convention:{arms: [0]}", "bandit_convention:{arms: [0]}"], "no seat names a game"),
    # evaluation sets (the trial's ego plays the bandit with 1 symmetric context)
    (["evaluate", "missing"], "RUNS 'missing' does not exist"),
    (["evaluate", "trial_badyaml"], "config.yaml' is not valid YAML"),
    (["evaluate", "trial_nockpt"], "has no checkpoint"),
    (["evaluate", "trial", "--eval-set", "test"], "--eval-set 'test': 'test' is neither heldout nor validation"),
    (["evaluate", "trial", "--eval-set", "bad.yaml"], "--eval-set 'bad.yaml': evaluation set 'bad.yaml' is not valid YAML"),
    (["evaluate", "trial", "--eval-set", "exp.yaml"], "evaluation set 'exp.yaml': role: Field required"),
    (["evaluate", "trial"], "--eval-set 'heldout': the set is for bandit {'symmetric': 2}, the egos were trained on bandit"),
    (
        ["evaluate", "trial", "--eval-set", BLOCKS_SET],
        "the set is for blocks {'new_task': False}, the egos were trained on bandit",
    ),
    (["evaluate", "trial", "--confidence", "1.5"], "--confidence: Input should be less than 1"),
    (["evaluate", "trial", "--episodes", "0"], "argument --episodes"),
    # reproductions and reports
    (["reproduce", "bandit", "--seeds", "0"], "argument --seeds"),
    (["reproduce", "bandit", "--train-steps", "-5"], "argument --train-steps"),
    (["reproduce", "bandit", "--plan", "missing.yaml"], "--plan file 'missing.yaml' does not exist"),
    (["reproduce", "bandit", "--plan", "bad.yaml"], "--plan file 'bad.yaml' is not valid YAML"),
    (["report", "notrepro"], "ROOT 'notrepro' is not a reproduce folder"),
    (["report", "missing"], "ROOT 'missing' is not a reproduce folder"),
    (["plot", "missing"], "FOLDER 'missing' does not exist"),
    (["plot", "notrepro"], "holds nothing to plot"),
    # the web app
    (["play", "--port", "70000"], "--port: expected a port 0-65535"),
    (["play", "--port", "-1"], "--port: expected a port 0-65535"),
    (["play", "--port", "eighty"], "argument --port: invalid int value"),
    (["play", "trial_badyaml"], "config.yaml' is not valid YAML"),
]


@pytest.mark.parametrize(("argv", "message"), CASES, ids=[" ".join(argv) for argv, _ in CASES])
def test_bad_input_is_one_line_exit_2_and_nothing_written(inputs, capsys, argv, message) -> None:
    before = digest(inputs)
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's own errors
        status = exc.code
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert status == 2, (out, err)
    assert len(lines) == 1 and lines[0].startswith("rllib-conv: error: "), err
    assert message in lines[0]
    assert "Traceback" not in err + out
    assert digest(inputs) == before
    assert sorted(p.name for p in inputs.iterdir()) == sorted(
        ["exp.yaml", "bad.yaml", "list.yaml", "a_folder", "trial", "trial_badyaml", "trial_badschema", "trial_nockpt", "notrepro"]
    )


def test_a_report_on_a_reproduce_folder_passes_the_check_a_plain_folder_fails(inputs, capsys) -> None:
    (inputs / "game").mkdir()
    (inputs / "game" / "plan.json").write_text(json.dumps({"game": "bandit"}))
    from rllib_conv.cli import _check_report_inputs

    _check_report_inputs(inputs / "game", None)  # a game folder
    _check_report_inputs(inputs, None)  # a folder of game folders
    with pytest.raises(ValueError, match="--user-study 'nowhere' does not exist"):
        _check_report_inputs(inputs, ["nowhere"])


LIGHT_CASES = [
    ["train", "missing.yaml"],
    ["train", "exp.yaml", "--set", "lam=[1"],
    ["adapt", "trial_badyaml"],
    ["adapt", "trial", "--set", "steps=0"],
    ["zeroshot", "trial_nockpt"],
    ["marginals", "missing"],
    ["evaluate", "trial"],
    ["evaluate", "trial", "--eval-set", "test"],
    ["pair", "bandit-s1-hand", "x:y"],
    ["play", "--port", "70000"],
    ["report", "notrepro"],
    ["reproduce", "bandit", "--plan", "missing.yaml"],
]


def test_bad_input_is_answered_without_loading_torch_or_ray(inputs) -> None:
    """What made every command take seconds: torch and Ray loaded before the arguments were checked."""
    script = (
        "import sys\n"
        "from rllib_conv.cli import main\n"
        f"for argv in {LIGHT_CASES!r}:\n"
        "    assert main(argv) == 2, argv\n"
        "    heavy = [m for m in ('torch', 'ray') if m in sys.modules]\n"
        "    assert not heavy, (argv, heavy)\n"
        "print('light')\n"
    )
    done = subprocess.run([sys.executable, "-c", script], cwd=inputs, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "light"
    assert done.stderr.count("rllib-conv: error: ") == len(LIGHT_CASES)
