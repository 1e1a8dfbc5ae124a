"""The 2019 human data stays on users' machines: neither the repository nor the wheel holds it or anything made from it.

Upstream's data README: "Do not distribute in any manner without the express consent of
CHAI". `rllib_conv.envs.overcooked.human_data` fetches it into a user cache; these tests fail
when a pickle, the sdist, a converted trajectory file or any big binary file sits among the
files git would commit, or in a wheel built from this checkout, under any name (the pickles'
and the sdist's SHA-256 and the pickle and parquet magic bytes are checked, not only names).
"""

from __future__ import annotations

import fnmatch
import hashlib
import os
import subprocess
import sys
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# The digests human_data.py records, written out again so this test needs no `overcooked` extra.
DATA_SHA256 = {
    "478bf319274bdb6c5bede8048ee901d088912353111ab85e9fb2bf389c6ccddf": "overcooked_ai-1.1.0.tar.gz",
    "28659cfd09ee033d82b56bed905b239f078877e1b09d1f1b916e4bc0480ca4fa": "clean_train_trials.pickle",
    "59979552a053f1efe762de976f37dd83e269d70d19b67613c61e856c86705666": "clean_test_trials.pickle",
}
DATA_NAMES = ("*.pickle", "*.pkl", "*.parquet", "overcooked_ai-*", "*trials*.csv", "*.tar.gz", "*.zip")
# Pickles (protocol 2+), parquet files, gzip and zip archives begin with these bytes.
DATA_MAGIC = (b"\x80\x02", b"\x80\x03", b"\x80\x04", b"\x80\x05", b"PAR1", b"\x1f\x8b", b"PK\x03\x04")
BIG = 1_000_000  # bytes; the largest file in the repository today is a 340 kB figure
# Folders that are never shipped or committed (build outputs, environments, caches).
SKIP_DIRS = {".git", ".venv", "build", "dist", "__pycache__", ".pytest_cache", ".ruff_cache", ".hypothesis"}


def repository_files() -> list[Path]:
    """What git would commit: tracked files and untracked ones it does not ignore (a walk of the tree without git)."""
    if (ROOT / ".git").exists():
        listed = subprocess.run(
            ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT, capture_output=True, check=True
        ).stdout
        return [ROOT / name for name in listed.decode().split("\0") if name and (ROOT / name).is_file()]
    out = []
    for folder, dirs, files in os.walk(ROOT):
        dirs[:] = [d for d in dirs if d not in SKIP_DIRS and not d.endswith(".egg-info")]
        out += [Path(folder) / f for f in files]
    return out


def problems(name: str, data: bytes) -> list[str]:
    """Why a file of this name and content looks like the human data (empty when it does not)."""
    found = []
    base = name.rsplit("/", 1)[-1]
    if any(fnmatch.fnmatch(base, pattern) for pattern in DATA_NAMES):
        found.append("a data file's name")
    if data.startswith(DATA_MAGIC):
        found.append("a pickle, parquet or archive by its first bytes")
    digest = hashlib.sha256(data).hexdigest()
    if digest in DATA_SHA256:
        found.append(f"the bytes of {DATA_SHA256[digest]}")
    if len(data) > BIG:
        found.append(f"{len(data)} bytes (over {BIG})")
    return found


def test_the_checks_catch_the_data_under_any_name() -> None:
    assert problems("x/clean_train_trials.pickle", b"") == ["a data file's name"]
    assert problems("notes.txt", b"\x80\x04\x95 a pickle") == ["a pickle, parquet or archive by its first bytes"]
    assert problems("renamed.txt", b"PAR1....") and problems("a.py", b"x" * (BIG + 1))
    assert problems("rllib_conv/envs/overcooked/human_data.py", b'"""the code that fetches it"""') == []


def test_the_repository_holds_no_human_data() -> None:
    files = repository_files()
    assert len(files) > 100  # the listing worked: the repository holds some 400 files
    found = {str(p.relative_to(ROOT)): why for p in files if (why := problems(str(p.relative_to(ROOT)), p.read_bytes()))}
    assert not found, found


def test_the_wheel_holds_no_human_data(tmp_path: Path) -> None:
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp_path), str(ROOT)],
        check=True,
        capture_output=True,
    )
    wheel = next(tmp_path.glob("rllib_conv-*.whl"))
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        # The listing is the package: the code that fetches the data ships, the data does not.
        assert "rllib_conv/cli/__init__.py" in names and "rllib_conv/envs/overcooked/human_data.py" in names
        found = {n: why for n in names if (why := problems(n, archive.read(n)))}
    assert not found, found
    assert not [n for n in names if "human_data/" in n or "trajectories/" in n]
