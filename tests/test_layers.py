"""The house's import contract: layers point down only, the analysis reads files, the wheel lists every package.

Layers, lowest first (ARCHITECTURE.md):

    common < envs < partners < modules < learners < training < adaptation < pipelines < play < cli

A module may import its own layer and the layers below it, never one above: every import
counts, those inside functions included. `analysis` stands beside the layers and may
import only `rllib_conv.common` (the file formats it reads); nothing in `rllib_conv` but
the CLI imports `analysis`. `rllib_conv.common` and `analysis` import neither torch nor Ray.
"""

from __future__ import annotations

import ast
import os
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("common", "envs", "partners", "modules", "learners", "training", "adaptation", "pipelines", "play", "cli")
HEAVY = ("torch", "ray")
# The house holds ~140 modules and ~1 700 imports: floors well below both, so that a glob that finds
# nothing (or one folder) fails instead of passing on an empty contract.
MIN_MODULES = 100
MIN_IMPORTS = 1000


def module_name(path: Path) -> str:
    """`rllib_conv/envs/bandit.py` -> `rllib_conv.envs.bandit` (a package's `__init__` is the package)."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(module: str, source: str, is_package: bool = False) -> list[tuple[int, str]]:
    """(line, imported name) for every import in `source`, at any depth; `from a import b` yields `a.b`."""
    out = []
    package = module if is_package else module.rpartition(".")[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: resolve against the importing module's package
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*anchor, *([base] if base else [])])
            out += [(node.lineno, f"{base}.{alias.name}") for alias in node.names]
    return out


def layer_of(module: str) -> int | None:
    """The layer index of an `rllib_conv` module (None for the package root and the data packages)."""
    parts = module.split(".")
    if parts[0] != "rllib_conv" or len(parts) < 2:
        return None
    name = parts[1]
    return LAYERS.index(name) if name in LAYERS else None


def violations(sources: dict[str, tuple[str, bool]]) -> list[str]:
    """Every import in `sources` (module -> (source, is package)) that breaks the contract, as readable lines."""
    found = []
    for module, (source, is_package) in sorted(sources.items()):
        own = layer_of(module)
        for line, target in imports(module, source, is_package):
            top = target.split(".")[0]
            where = f"{module}:{line} imports {target}"
            if module.startswith("analysis"):
                if top == "rllib_conv" and not (target == "rllib_conv" or target.startswith("rllib_conv.common")):
                    found.append(f"{where}: the analysis may import only rllib_conv.common (it reads files)")
            elif top == "analysis" and own != LAYERS.index("cli"):
                found.append(f"{where}: only the CLI may import the analysis")
            if (module.startswith("analysis") or own == LAYERS.index("common")) and top in HEAVY:
                found.append(f"{where}: {module.split('.')[0] if own is None else 'rllib_conv.common'} must not import {top}")
            theirs = layer_of(target)
            if own is not None and theirs is not None and theirs > own:
                found.append(f"{where}: {LAYERS[own]} may not import the higher layer {LAYERS[theirs]}")
    return found


def house_sources() -> dict[str, tuple[str, bool]]:
    """The source of every module of `rllib_conv` and `analysis`."""
    files = [*(ROOT / "rllib_conv").rglob("*.py"), *(ROOT / "analysis").rglob("*.py")]
    return {module_name(p): (p.read_text(), p.name == "__init__.py") for p in files}


def test_every_import_points_down_and_the_analysis_reads_only_files() -> None:
    sources = house_sources()
    # Listed independently of `house_sources` (os.walk, not rglob): every .py of both trees was read and parsed.
    on_disk = {
        module_name(Path(folder, f))
        for top in ("rllib_conv", "analysis")
        for folder, _, files in os.walk(ROOT / top)
        for f in files
        if f.endswith(".py")
    }
    assert set(sources) == on_disk
    assert len(sources) >= MIN_MODULES, f"read only {len(sources)} modules"
    assert {LAYERS[i] for m in sources if (i := layer_of(m)) is not None} == set(LAYERS), "a layer has no module"
    assert any(m.startswith("analysis.") for m in sources)
    assert sum(len(imports(m, source, is_package)) for m, (source, is_package) in sources.items()) >= MIN_IMPORTS
    assert violations(sources) == []


@pytest.mark.parametrize(
    ("module", "source", "complaint"),
    [
        (
            "rllib_conv.envs.new_game",
            "def f():\n    from rllib_conv.training import tuning\n",
            "envs may not import the higher layer training",
        ),
        ("rllib_conv.partners.x", "import rllib_conv.pipelines.adapt\n", "partners may not import the higher layer pipelines"),
        ("rllib_conv.modules.x", "from ..play import agent\n", "modules may not import the higher layer play"),
        ("rllib_conv.pipelines.x", "from analysis.report import build_report\n", "only the CLI may import the analysis"),
        ("analysis.x", "from rllib_conv.partners import user_study\n", "the analysis may import only rllib_conv.common"),
        ("analysis.x", "import torch\n", "must not import torch"),
        ("rllib_conv.common.x", "def f():\n    import ray\n", "rllib_conv.common must not import ray"),
    ],
)
def test_the_contract_catches_a_new_upward_import(module, source, complaint) -> None:
    found = violations({module: (source, False)})
    assert len(found) == 1 and complaint in found[0], found


def test_downward_and_same_layer_imports_pass() -> None:
    sources = {
        "rllib_conv.cli": ("from analysis.report import build_report\nfrom rllib_conv.play import server\n", False),
        "rllib_conv.training.x": ("from rllib_conv import envs, partners\nfrom rllib_conv.training.tuning import fit\n", False),
        "analysis.x": ("from rllib_conv.common.run_folders import CONFIG_FILE\n", False),
    }
    assert violations(sources) == []


def test_the_wheel_lists_every_package_and_maps_the_data_folders() -> None:
    setuptools = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    folders = {module_name(p) for top in ("rllib_conv", "analysis") for p in (ROOT / top).rglob("__init__.py")}
    mapped = {package: folder for package, folder in setuptools["package-dir"].items()}
    assert mapped == {"rllib_conv.tune_configs": "tune_configs", "rllib_conv.data": "analysis/data"}
    expected = (folders - {"analysis.data"}) | set(mapped)
    assert sorted(setuptools["packages"]) == sorted(expected)
