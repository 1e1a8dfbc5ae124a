"""The command line under hostile and careless use (issue 47): each refused command is one line naming its culprit, exit 2, nothing written.

Every case here failed before its fix: a count too large for Python's iterators, a binary
config, a bad PPO override found only after Ray started, a scripted seat that did not say
which seat, `--env-config` values blamed on nobody, an option blamed that was never given,
pydantic's type names in place of words, a run path holding ':', an unwritable output found
only after training, and a damaged trial config read as another experiment.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from rllib_conv.cli import main
from rllib_conv.common.sealed import seal_file
from rllib_conv.pipelines.pair_config import split_seat
from rllib_conv.training.experiment import ExperimentConfig, check_trial
from tests.helpers import digest

TRIAL_CONFIG = yaml.safe_dump(
    ExperimentConfig(population="bandit-s1-hand", lam=0.5).resolve("bandit").model_dump(), sort_keys=False
)


def _trial(folder: Path, sealed: bool = True) -> Path:
    """A trained-ego trial folder as the CLI checks it: a config (sealed, as training writes it) and a checkpoint folder."""
    (folder / "checkpoint_000000").mkdir(parents=True)
    (folder / "config.yaml").write_text(TRIAL_CONFIG)
    if sealed:
        seal_file(folder / "config.yaml")
    return folder


@pytest.fixture
def inputs(tmp_path: Path, monkeypatch) -> Path:
    """Good and damaged inputs in the working directory (so default output folders count as writes)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "exp.yaml").write_text(yaml.safe_dump({"name": "x", "population": "bandit-s1-hand", "run": {"timesteps": 64}}))
    (tmp_path / "binary.yaml").write_bytes(b"\x00\x01\xff\xfe\x89PNG\r\n")
    (tmp_path / "latin1.yaml").write_bytes("name: caf\xe9\npopulation: bandit-s1-hand\n".encode("latin-1"))
    (tmp_path / "a_file").write_text("not a folder\n")
    _trial(tmp_path / "trial")
    _trial(tmp_path / "runs:colon" / "trial")
    (tmp_path / "runs:colon" / "nockpt").mkdir()
    (tmp_path / "runs:colon" / "nockpt" / "config.yaml").write_text(TRIAL_CONFIG)
    damaged = _trial(tmp_path / "damaged")
    (damaged / "config.yaml").write_text(TRIAL_CONFIG[:100])  # the cut of issue 47: lam 0.5 read as lam 0
    binary_trial = tmp_path / "binary_trial"
    (binary_trial / "checkpoint_000000").mkdir(parents=True)
    (binary_trial / "config.yaml").write_bytes(b"lam: \xff\xfe\n")
    return tmp_path


PAIR = ["bandit-s1-hand:hand-train-1", "bandit-s1-hand:hand-train-0"]
CASES = [
    (["pair", *PAIR, "--episodes", "99999999999999999999"], ["--episodes", "from 1 to"], ["islice"]),
    (["marginals", "trial", "--episodes", "9" * 5000], ["--episodes", "5000 characters"], []),
    (["train", "binary.yaml"], ["'binary.yaml'", "not UTF-8"], ["codec"]),
    (["train", "latin1.yaml"], ["'latin1.yaml'", "not UTF-8"], ["codec"]),
    (["adapt", "binary_trial"], ["binary_trial/config.yaml'", "not UTF-8"], ["codec"]),
    (["adapt", "trial", "--set", "ppo.lr=-1"], ["--set ppo.lr=-1", "lr: Input should be greater than 0"], []),
    (["adapt", "trial", "--set", "ppo.learning_rate=1"], ["--set ppo.learning_rate=1", "learning_rate"], []),
    (
        ["pair", "bandit_convention:{arms: [-1, 0, 1, 2]}", "bandit-s1-hand:hand-train-0"],
        ["seat 'bandit_convention:{arms: [-1, 0, 1, 2]}'", "arms"],
        [],
    ),
    (["pair", *PAIR, "--env-config", "{symmetric: abc}"], ["--env-config", "symmetric"], []),
    (["adapt", "trial", "--guard", "--head-init", "pick"], ["--guard", "--head-init"], ["--name"]),
    (
        ["zeroshot", "trial", "--set", "task_entropy=-1"],
        ["--set task_entropy=-1", "a number >= 0, or a schedule"],
        ["constrained-float", "list[tuple"],
    ),
    (["zeroshot", "trial", "--set", "task_entropy=[[0, 0.1], [5, -1]]"], ["--set task_entropy", ">= 0"], ["constrained-float"]),
    (
        ["train", "exp.yaml", "--set", "lam={grid_search: []}"],
        ["--set lam={grid_search: []}", "grid_search needs a non-empty list"],
        [],
    ),
    (["train", "exp.yaml", "--set", "lam=" + "9" * 5000], ["--set lam=9999", "characters"], []),
    (["train", "exp.yaml", "--set", "lam=" + "[" * 1000], ["--set lam=[[[["], []),
    (
        ["pair", "runs:colon/nockpt:ego", "bandit-s1-hand:hand-train-0"],
        ["'runs:colon/nockpt'", "has no checkpoint"],
        ["neither a partner kind"],
    ),
    (["adapt", "trial", "--out", "a_file"], ["--out 'a_file' is a file"], []),
    (["adapt", "trial", "--out", "a_file/below"], ["--out 'a_file/below'", "is a file"], []),
    (["zeroshot", "trial", "--storage", "a_file/runs"], ["--storage"], []),
    (["marginals", "trial", "--out", "a_file"], ["--out 'a_file' is a file"], []),
    (["pair", *PAIR, "--out", "a_file"], ["--out 'a_file' is a file"], []),
    (["marginals", "damaged"], ["trial config", "damaged/config.yaml'", "corrupt"], []),
    (["adapt", "damaged"], ["damaged/config.yaml'", "corrupt"], []),
    (["pair", "damaged:ego@hand-train-0", "bandit-s1-hand:hand-train-0"], ["damaged/config.yaml'", "corrupt"], []),
]


@pytest.mark.parametrize(("argv", "named", "absent"), CASES, ids=[" ".join(a)[:60] for a, _, _ in CASES])
def test_a_refused_command_is_one_line_naming_its_culprit_and_changes_nothing(inputs, capsys, argv, named, absent) -> None:
    before = digest(inputs)
    names = sorted(p.name for p in inputs.iterdir())
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's own errors
        status = exc.code
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert status == 2, (out, err)
    assert len(lines) == 1 and lines[0].startswith("rllib-conv: error: "), err
    assert "Traceback" not in out + err
    for word in named:
        assert word in lines[0], (word, lines[0])
    for word in absent:
        assert word not in lines[0], (word, lines[0])
    assert len(lines[0]) < 600, "an error line repeats a long argument whole"
    assert digest(inputs) == before and sorted(p.name for p in inputs.iterdir()) == names


def test_a_run_path_holding_a_colon_splits_at_its_last_colon_on_disk(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a:b" / "trial").mkdir(parents=True)
    assert split_seat("a:b/trial:ego@hand-train-0") == ("a:b/trial", "ego@hand-train-0")
    assert split_seat(f"{tmp_path}/a:b/trial:task") == (f"{tmp_path}/a:b/trial", "task")
    # Nothing on disk: the first colon, so a kind's parameters may hold colons.
    assert split_seat("bandit_convention:{arms: [0, 1]}") == ("bandit_convention", "{arms: [0, 1]}")


def test_an_unsealed_trial_config_written_before_sealing_is_still_read(inputs, capsys) -> None:
    """Runs trained before configs were sealed carry no digest: they are read as they are (a sealed one is checked)."""
    legacy = _trial(inputs / "legacy", sealed=False)
    assert check_trial(legacy).lam == 0.5
    assert check_trial(inputs / "trial").lam == 0.5
    with pytest.raises(ValueError, match="corrupt"):
        check_trial(inputs / "damaged")


FAST_CASES = [
    ["adapt", "trial", "--set", "ppo.lr=-1"],
    ["adapt", "trial", "--out", "a_file"],
    ["adapt", "trial", "--guard", "--head-init", "pick"],
    ["zeroshot", "trial", "--set", "task_entropy=-1"],
    ["marginals", "damaged"],
    ["train", "binary.yaml"],
    ["pair", "runs:colon/nockpt:ego", "bandit-s1-hand:hand-train-0"],
]


def test_these_refusals_come_before_torch_or_ray_load(inputs) -> None:
    """`adapt --set ppo.lr=-1` and an unwritable `--out` were found only after Ray started (3 s, or a whole adaptation)."""
    script = (
        "import sys, time\n"
        "from rllib_conv.cli import main\n"
        f"for argv in {FAST_CASES!r}:\n"
        "    begin = time.perf_counter()\n"
        "    assert main(argv) == 2, argv\n"
        "    heavy = [m for m in ('torch', 'ray') if m in sys.modules]\n"
        "    assert not heavy, (argv, heavy)\n"
        "    assert time.perf_counter() - begin < 2.0, argv  # about 0.1 s each; generous on a shared machine\n"
        "print('light')\n"
    )
    done = subprocess.run([sys.executable, "-c", script], cwd=inputs, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "light"
    assert done.stderr.count("rllib-conv: error: ") == len(FAST_CASES)


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere: file permissions cannot refuse it")
def test_an_output_folder_without_write_permission_is_refused_before_any_work(inputs, capsys) -> None:
    locked = inputs / "locked"
    locked.mkdir(mode=0o500)
    try:
        before = digest(inputs)
        assert main(["adapt", "trial", "--out", str(locked / "adaptation")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--out" in err[0] and "no permission to write" in err[0], err
        assert digest(inputs) == before
    finally:
        locked.chmod(0o700)
