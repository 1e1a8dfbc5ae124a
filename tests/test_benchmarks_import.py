"""Every benchmark script imports: a renamed function they use fails here, not on the next measurement day."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

from benchmarks._common import machine, vector_isa

SCRIPTS = sorted(p.stem for p in (Path(__file__).parents[1] / "benchmarks").glob("*.py") if p.stem != "__init__")


@pytest.mark.parametrize("name", SCRIPTS)
def test_a_benchmark_script_imports(name: str) -> None:
    module = importlib.import_module(f"benchmarks.{name}")
    assert module.__doc__, f"benchmarks/{name}.py has no docstring"


def test_the_vector_isa_is_read_from_the_cpu_flags() -> None:
    epyc = "processor\t: 0\nmodel name\t: AMD EPYC\nflags\t\t: fpu sse4_2 avx avx2 fma\n\nprocessor\t: 1\nflags\t\t: fpu\n"
    xeon = "flags\t\t: fpu avx512f fma avx2 amx_tile avx sse4_2 avx512_vnni\n"
    assert vector_isa(epyc) == ["sse4_2", "avx", "avx2", "fma"]
    assert vector_isa(xeon) == ["sse4_2", "avx", "avx2", "fma", "avx512f", "avx512_vnni", "amx_tile"]
    assert vector_isa("") == []
    assert set(machine()) >= {"cpu", "vector_isa", "torch_cpu_capability", "cores"}
