"""Files read once per version (`common.file_versions`) and sealed folders hashed once per version (`common.sealed`)."""

from __future__ import annotations

import os
import time

import pytest
import yaml

from rllib_conv import partners
from rllib_conv.common import run_folders, sealed
from rllib_conv.common.file_versions import SETTLED_NS, read_once
from rllib_conv.common.run_folders import CONFIG_FILE, read_trial_config
from rllib_conv.partners.population import Population
from rllib_conv.training.experiment import trial_config


def age(path, seconds: float = 60.0) -> None:
    """Stamp `path` as written `seconds` ago (and so settled)."""
    then = time.time_ns() - int(seconds * 1e9)
    os.utime(path, ns=(then, then))


def test_a_settled_file_is_read_once_per_version_and_again_after_a_write(tmp_path) -> None:
    path, reads, cache = tmp_path / "f.txt", [], {}

    def read(p):
        reads.append(p)
        return p.read_text()

    path.write_text("one")
    age(path)
    assert [read_once(path, read, cache) for _ in range(3)] == ["one"] * 3 and len(reads) == 1
    path.write_text("two")  # the same size, a new stamp
    age(path, 30)
    assert read_once(path, read, cache) == "two" and len(reads) == 2


def test_a_file_written_just_now_is_read_every_time(tmp_path) -> None:
    # A write within the clock's resolution could keep the stamp: nothing this young is cached.
    path, cache = tmp_path / "f.txt", {}
    path.write_text("one")
    assert read_once(path, lambda p: p.read_text(), cache) == "one" and cache == {}
    assert SETTLED_NS >= 1_000_000_000


def test_a_missing_file_gets_the_readers_own_error(tmp_path) -> None:
    def read(p):
        raise ValueError(f"config {p.name!r} does not exist")

    with pytest.raises(ValueError, match="config 'nope.yaml' does not exist"):
        read_once(tmp_path / "nope.yaml", read, {})


def test_a_sealed_folder_is_hashed_once_until_a_file_of_it_changes(tmp_path, monkeypatch) -> None:
    folder = tmp_path / "ckpt"
    folder.mkdir()
    (folder / "weights.bin").write_bytes(b"abcd")
    sealed.seal(folder)
    for p in folder.iterdir():
        age(p)
    hashed = []
    digest = sealed._digest
    monkeypatch.setattr(sealed, "_digest", lambda p: hashed.append(p.name) or digest(p))
    for _ in range(3):
        sealed.verify(folder)
    assert hashed == ["weights.bin"]
    (folder / "weights.bin").write_bytes(b"abce")  # damaged, same size: its new stamp forces a new hash
    with pytest.raises(ValueError, match="weights.bin differs from what was saved"):
        sealed.verify(folder)


def test_a_population_read_twice_is_two_independent_copies(tmp_path) -> None:
    partners.get("blocks-perm").save(tmp_path / "population.json")
    age(tmp_path / "population.json")
    first = Population.load(tmp_path)
    name = first.partners[0].name
    first.partners[0].name = "changed"  # a caller's edit must not reach the next reader
    assert Population.load(tmp_path).partners[0].name == name != "changed"


def test_a_trial_config_is_parsed_once_per_version_and_handed_out_as_copies(tmp_path, monkeypatch) -> None:
    (tmp_path / CONFIG_FILE).write_text(yaml.safe_dump({"population": "bandit-s2-hand", "lam": 0.5, "seed": 3}))
    age(tmp_path / CONFIG_FILE)
    parsed = []
    read_yaml = run_folders.read_yaml
    monkeypatch.setattr(run_folders, "read_yaml", lambda *a: parsed.append(a) or read_yaml(*a))
    first = read_trial_config(tmp_path)
    first["lam"] = 9.0  # a caller's edit must not reach the next reader
    assert trial_config(tmp_path).lam == 0.5 and read_trial_config(tmp_path)["seed"] == 3
    assert len(parsed) == 1  # the raw dict and the checked config share one parse
