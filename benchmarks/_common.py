"""Shared by the benchmark scripts: machine description and result files."""

from __future__ import annotations

import datetime as dt
import functools
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")

BENCHMARKS = Path(__file__).resolve().parent
RESULTS = BENCHMARKS / "results"


# The vector instruction sets that bound how fast torch's kernels can run, in the order of their generations: the
# same work ran ~1.8x faster on an Intel Xeon with AVX-512 than on an AMD EPYC, so every result says which it had.
VECTOR_ISA = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512_vnni", "avx512_bf16", "amx_tile")


def vector_isa(cpuinfo: str) -> list[str]:
    """The `VECTOR_ISA` flags that the first `flags` line of a /proc/cpuinfo text lists, in `VECTOR_ISA`'s order."""
    line = next((x for x in cpuinfo.splitlines() if x.startswith("flags")), "")
    present = set(line.partition(":")[2].split())
    return [flag for flag in VECTOR_ISA if flag in present]


def machine() -> dict[str, Any]:
    """Describe the machine a benchmark ran on (CPU model, its vector ISA, cores, Python, key packages)."""
    cpu, cpuinfo = platform.processor() or "", ""
    try:
        cpuinfo = Path("/proc/cpuinfo").read_text()
        cpu = next(line.split(":", 1)[1].strip() for line in cpuinfo.splitlines() if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    versions = {}
    for pkg in ("ray", "torch", "pettingzoo", "gymnasium", "numpy"):
        try:
            versions[pkg] = __import__(pkg).__version__
        except Exception:  # a missing package just goes unreported
            versions[pkg] = None
    try:  # what torch's kernels were built to use here (e.g. AVX512, AVX2)
        capability = __import__("torch").backends.cpu.get_cpu_capability()
    except Exception:  # no torch, or one without the query: reported as unknown
        capability = None
    return {
        "cpu": cpu,
        "vector_isa": vector_isa(cpuinfo),
        "torch_cpu_capability": capability,
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "platform": platform.platform(),
        "omp_num_threads": os.environ.get("OMP_NUM_THREADS"),
        "packages": versions,
    }


def write_result(name: str, data: dict[str, Any]) -> Path:
    """Write `data` with the machine and the producing command line to `results/<name>.json`."""
    command = "OMP_NUM_THREADS=1 python " + " ".join(sys.argv)
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / f"{name}.json"
    record = {
        "benchmark": name,
        "date": dt.datetime.now().isoformat(timespec="seconds"),
        "command": command,
        "machine": machine(),
        **data,
    }
    path.write_text(json.dumps(record, indent=2) + "\n")
    return path


def alternating(ways: Sequence[T], rounds: int) -> Iterator[T]:
    """`ways` in turn for `rounds` rounds, the order reversed every other round (A B, B A, A B, ...), so a drift in the machine's speed falls on each alike."""
    for i in range(rounds):
        yield from (ways if i % 2 == 0 else ways[::-1])


def median_seconds(ways: dict[str, Callable[[], Any]], rounds: int) -> dict[str, float]:
    """The median wall seconds of one call of each of `ways`, timed `rounds` times each in `alternating` order."""
    times: dict[str, list[float]] = {name: [] for name in ways}
    for name in alternating(list(ways), rounds):
        start = time.perf_counter()
        ways[name]()
        times[name].append(time.perf_counter() - start)
    return {name: statistics.median(t) for name, t in times.items()}


@functools.cache
def benchmarks_only_folder() -> Path:
    """A temporary folder that holds nothing but a link to this checkout's `benchmarks` package.

    A child run as `python -m benchmarks.<name>` from it imports these scripts (`-m` puts the
    working folder first on the path) and everything else, `rllib_conv` included, from
    PYTHONPATH: how one script measures an older commit's code (a git worktree) beside today's.
    """
    folder = Path(tempfile.mkdtemp(prefix="benchmarks-only-"))
    (folder / "benchmarks").symlink_to(BENCHMARKS, target_is_directory=True)
    return folder


def run_with_code(code: Path, script: str, args: Sequence[str], marker: str) -> str:
    """Run `python -m benchmarks.<script> *args` in a fresh process whose rllib_conv is `code`'s; return its `marker` line's rest.

    The benchmark scripts are this checkout's (`benchmarks_only_folder`), everything else
    comes from `code` (a git worktree of an older commit, or this checkout): how one script
    measures two versions of the code side by side.
    """
    env = {**os.environ, "PYTHONPATH": str(code), "OMP_NUM_THREADS": "1", "RAY_ADDRESS": ""}
    command = [sys.executable, "-m", f"benchmarks.{script}", *args]
    proc = subprocess.run(command, cwd=benchmarks_only_folder(), env=env, capture_output=True, text=True)
    line = next((ln for ln in proc.stdout.splitlines() if ln.startswith(f"{marker} ")), None)
    if proc.returncode != 0 or line is None:
        raise RuntimeError(f"{script} {' '.join(args)} with {code} failed:\n{(proc.stdout + proc.stderr)[-4000:]}")
    return line[len(marker) + 1 :]
