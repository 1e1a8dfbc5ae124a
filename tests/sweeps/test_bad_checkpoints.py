"""Damaged or missing checkpoints and partner files: one clear error line, exit 2, nothing on disk changed."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from rllib_conv import partners
from rllib_conv.cli import main
from rllib_conv.common.run_folders import RL_MODULE_DIR, checkpoints
from rllib_conv.common.sealed import MANIFEST, seal, verify
from rllib_conv.training.checkpoints import last_checkpoint
from tests.helpers import digest


def _sealed(tmp_path: Path) -> Path:
    folder = tmp_path / "ckpt"
    (folder / "sub").mkdir(parents=True)
    (folder / "a.bin").write_bytes(b"\x00\x01" * 100)
    (folder / "sub" / "b.json").write_text('{"x": 1}')
    seal(folder)
    return folder


def test_a_sealed_checkpoint_verifies(tmp_path) -> None:
    folder = _sealed(tmp_path)
    verify(folder)
    assert set(json.loads((folder / MANIFEST).read_text())) == {"a.bin", "sub/b.json"}
    assert not list(folder.glob("*.tmp"))


@pytest.mark.parametrize(
    ("damage", "match"),
    [
        (lambda f: (f / "a.bin").write_bytes(b"\x00\x01" * 50), "corrupt: a.bin differs"),  # truncated
        (lambda f: (f / "a.bin").write_bytes(b"\x00\x02" * 100), "corrupt: a.bin differs"),  # same size, other bytes
        (lambda f: (f / "sub" / "b.json").unlink(), "incomplete: sub/b.json is missing"),
        (lambda f: (f / MANIFEST).unlink(), "incomplete: no manifest.json"),
        (lambda f: (f / MANIFEST).write_text("{"), "unreadable manifest.json"),
        (lambda f: shutil.rmtree(f), "does not exist"),
    ],
)
def test_damage_is_named(tmp_path, damage, match) -> None:
    folder = _sealed(tmp_path)
    damage(folder)
    with pytest.raises(ValueError, match=match):
        verify(folder)


def _copy_trial(bandit_egos, tmp_path: Path) -> Path:
    return Path(shutil.copytree(bandit_egos["bandit-s2-hand"].path, tmp_path / "trial"))


def _adapt(trial: Path, tmp_path: Path) -> int:
    return main(["adapt", str(trial), "--storage", str(tmp_path / "runs"), "--out", str(tmp_path / "curves")])


@pytest.mark.slow
def test_adapt_refuses_a_corrupt_checkpoint(bandit_egos, tmp_path, capsys) -> None:
    trial = _copy_trial(bandit_egos, tmp_path)
    state = last_checkpoint(trial) / RL_MODULE_DIR / "task" / "module_state.pkl"
    state.write_bytes(state.read_bytes()[:-10])
    before = digest(trial)
    assert _adapt(trial, tmp_path) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is corrupt" in err[0] and "module_state.pkl" in err[0], err
    assert digest(trial) == before and not (tmp_path / "runs").exists() and not (tmp_path / "curves").exists()


@pytest.mark.slow
def test_adapt_refuses_a_trial_without_checkpoints(bandit_egos, tmp_path, capsys) -> None:
    trial = _copy_trial(bandit_egos, tmp_path)
    for folder in checkpoints(trial):
        shutil.rmtree(folder)
    assert _adapt(trial, tmp_path) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "has no checkpoint" in err[0], err
    assert not (tmp_path / "runs").exists()


@pytest.mark.slow
def test_population_partner_files_gone_or_damaged(bandit_egos, tmp_path, capsys) -> None:
    """A population of trained partners (here: the task module of a trained ego, sealed like `partners train` does)."""
    folder = tmp_path / "pop"
    module = Path(
        shutil.copytree(last_checkpoint(bandit_egos["bandit-s2-hand"].path) / RL_MODULE_DIR / "task", folder / "partners" / "p0")
    )
    seal(module)
    pop = partners.get("bandit-s2-hand").model_copy(update={"name": "trained"})
    pop.partners = [
        e.model_copy(update={"kind": "trained_policy", "params": {"checkpoint": f"partners/p{i}"}})
        for i, e in enumerate(pop.partners[:2])
    ]
    shutil.copytree(module, folder / "partners" / "p1")
    pop.save(folder / "population.json")
    assert len(partners.get(str(folder)).build()) == 2  # intact, it loads

    exp = tmp_path / "exp.yaml"
    exp.write_text(json.dumps({"name": "x", "population": str(folder)}))
    storage = tmp_path / "runs"

    state = folder / "partners" / "p1" / "module_state.pkl"
    state.write_bytes(b"garbage")
    before = digest(folder)
    assert main(["train", str(exp), "--storage", str(storage)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is corrupt: module_state.pkl differs" in err[0], err
    assert digest(folder) == before and not storage.exists()

    shutil.rmtree(folder / "partners" / "p1")
    before = digest(folder)
    assert main(["train", str(exp), "--storage", str(storage)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "partner 'hand-train-1'" in err[0] and "does not exist" in err[0], err
    assert digest(folder) == before and not storage.exists()
