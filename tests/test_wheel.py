"""A wheel carries what the package reads: configs, plans and the user-study table, found from any folder.

Builds a wheel of this checkout, installs it (without dependencies) into a fresh virtual
environment outside the repository whose other packages come from the test environment,
and runs the installed package from an unrelated folder: `rllib-conv partners list`, the
demo's config load, a plan load, the user-study table load and a shipped evaluation set. Nothing may come from the
checkout itself.
"""

from __future__ import annotations

import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

CHECKS = """
import rllib_conv, sys
from rllib_conv.common.resources import config_file, evaluation_sets, user_study_csv
from rllib_conv.common.user_study_table import load_user_study
from rllib_conv.pipelines.demo import DEMO_CONFIG
from rllib_conv.pipelines.plans import plan_for
from rllib_conv.training import experiment
assert rllib_conv.__file__.startswith(sys.prefix), rllib_conv.__file__
config = experiment.load(config_file(DEMO_CONFIG))
print("demo population", config.raw["population"])
print("bandit plan populations", len(plan_for("bandit").populations))
table = load_user_study()
print("user study rows", len(table), "from", user_study_csv())
from rllib_conv.partners.evaluation_sets import shipped_set
print("evaluation sets", len(evaluation_sets()), "blocks held-out", len(shipped_set("blocks", "heldout").resolve().partners))
"""


@pytest.fixture(scope="module")
def installed(tmp_path_factory) -> Path:
    """The `bin/` folder of a fresh venv holding only this checkout's wheel (dependencies shared)."""
    tmp = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(tmp / "dist"), str(ROOT)],
        check=True,
        capture_output=True,
    )
    wheel = next((tmp / "dist").glob("rllib_conv-*.whl"))
    env = tmp / "venv"
    venv.create(env, with_pip=False)
    site = Path(sysconfig.get_paths(vars={"base": str(env), "platbase": str(env)})["purelib"])
    # The dependencies (torch, Ray, ...) are the test environment's; the .pth adds its
    # site-packages without running its .pth files, so its editable rllib_conv stays out.
    (site / "shared_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    pip = [str(env / "bin" / "python"), "-m", "pip"]
    subprocess.run([*pip, "install", "--no-deps", "--no-index", "-q", str(wheel)], check=True, capture_output=True)
    return env / "bin"


def test_the_installed_cli_lists_the_populations_from_another_folder(installed: Path, tmp_path: Path) -> None:
    out = subprocess.run([str(installed / "rllib-conv"), "partners", "list"], cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "bandit-user-study" in out.stdout and "blocks-perm" in out.stdout


def test_configs_plans_and_the_user_study_table_load_from_the_wheel(installed: Path, tmp_path: Path) -> None:
    out = subprocess.run([str(installed / "python"), "-c", CHECKS], cwd=tmp_path, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "demo population bandit-s2-hand" in out.stdout
    assert "bandit plan populations 4" in out.stdout
    # 23 pairs x 2 tasks x 3 contexts x 2 tries (1 and 5) in the paper's table.
    assert "user study rows 276" in out.stdout and str(ROOT) not in out.stdout
    assert "evaluation sets 10 blocks held-out 6" in out.stdout  # bandit, blocks, hanabi, lbf, overcooked: heldout and validation
