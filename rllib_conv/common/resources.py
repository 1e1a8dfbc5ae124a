"""The data files the package ships, found through `importlib.resources` wherever it is installed.

The repository keeps them in top-level folders (`tune_configs/`, `analysis/data/`);
`pyproject.toml` maps those folders to the packages `rllib_conv.tune_configs` and
`rllib_conv.data`, so an editable install reads the repository's files and a wheel
carries copies. Nothing here climbs the file tree from `__file__`.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

CONFIGS_PACKAGE = "rllib_conv.tune_configs"
EVAL_SETS_DIR = "eval_sets"  # inside the configs: each game's evaluation sets, `<game>_<role>.yaml`
DATA_PACKAGE = "rllib_conv.data"
USER_STUDY_CSV = "user_study.csv"


def _file(package: str, name: str) -> Path:
    # Installed packages are plain folders (pip unpacks wheels), so the resource is a real path.
    path = Path(str(resources.files(package).joinpath(name)))
    if not path.is_file():
        raise ValueError(f"{name!r} is not among the files of {package} (have: {', '.join(sorted(available(package)))})")
    return path


def available(package: str = CONFIGS_PACKAGE) -> list[str]:
    """The names of the data files of `package` (default: the shipped configs and plans)."""
    return sorted(p.name for p in resources.files(package).iterdir() if p.is_file() and not p.name.startswith("__"))


def config_file(name: str) -> Path:
    """A shipped experiment config or plan, e.g. `config_file("bandit_modular.yaml")`."""
    return _file(CONFIGS_PACKAGE, name)


def evaluation_sets() -> list[str]:
    """The names of the shipped evaluation-set manifests (`tune_configs/eval_sets/<game>_<role>.yaml`)."""
    folder = resources.files(CONFIGS_PACKAGE).joinpath(EVAL_SETS_DIR)
    return sorted(p.name for p in folder.iterdir() if p.is_file() and p.name.endswith(".yaml")) if folder.is_dir() else []


def evaluation_set_file(name: str) -> Path:
    """A shipped evaluation-set manifest by file name, e.g. `evaluation_set_file("bandit_heldout.yaml")`."""
    path = Path(str(resources.files(CONFIGS_PACKAGE).joinpath(EVAL_SETS_DIR, name)))
    if not path.is_file():
        raise ValueError(f"{name!r} is not among the shipped evaluation sets (have: {', '.join(evaluation_sets())})")
    return path


def user_study_csv() -> Path:
    """The paper's user-study table, transcribed (`analysis/data/user_study.csv` in the repository)."""
    return _file(DATA_PACKAGE, USER_STUDY_CSV)
