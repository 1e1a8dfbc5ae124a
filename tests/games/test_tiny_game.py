"""A game defined only in the tests trains, adapts, reports and plays through the CLI, with no edit anywhere else.

`tests/games/tiny.py` is one module: a PettingZoo env, its `GameRecord` and a scripted
partner kind, named by import path. Everything the stages need of it they ask its record.
"""

from __future__ import annotations

import json

import pandas as pd
import pytest
import yaml

from rllib_conv import envs
from rllib_conv.cli import main
from rllib_conv.common.run_folders import POPULATION_FILE, trial_folders
from tests.games.tiny import GAME, TinyEnv, population


def test_the_record_is_found_by_its_import_path() -> None:
    record = envs.game(GAME)
    assert record.env is TinyEnv and record.name == GAME and GAME in envs.names()
    assert record.training_defaults().timesteps == 256 and record.adapt_defaults(32).every == 16
    assert record.zeroshot_defaults(32, 256).task_steps == 256  # derived: the game declares no zero-shot budgets


@pytest.mark.slow
def test_a_game_from_the_tests_trains_adapts_reports_and_pairs(ray_session, tmp_path, capsys) -> None:
    pop_dir = tmp_path / "tiny-pop"
    population().save(pop_dir / POPULATION_FILE)
    scale = {"populations": {str(pop_dir): ["modular-lam0.5"]}, "adapt_partners": 1}
    plan = {
        "game": GAME,
        "paper_method": "modular-lam0.5",
        "methods": {"modular-lam0.5": {"method": "modular", "lam": 0.5}},
        "full": scale,
        "quick": scale,
    }
    (tmp_path / "plan.yaml").write_text(yaml.safe_dump(plan))
    out = tmp_path / "reproduce"

    assert main(["reproduce", GAME, "--quick", "--plan", str(tmp_path / "plan.yaml"), "--out", str(out)]) == 0

    game_dir = out / GAME
    written = json.loads((game_dir / "plan.json").read_text())
    assert written["stages"] == ["selfplay", "train", "adapt", "marginals"]  # an oracle, no new task: no zero-shot
    assert written["report"] == {"title": "Tiny test game", "max_score": 1.0}
    curve = pd.read_csv(game_dir / "adaptation" / "tiny-pop__modular-lam0.5.csv")
    assert set(curve["partner"]) == {"left-test"} and curve["steps"].max() == 48 and curve["mean_return"].between(0, 1).all()
    marginals = pd.read_csv(game_dir / "marginals.csv")
    assert len(marginals) == 1 and marginals["distance"].notna().all()
    report = (out / "report" / "report.md").read_text().splitlines()
    # The training table's max comes from plan.json (the record's max_score): the analysis knows no game by name.
    assert any(line.startswith(f"| {GAME} | tiny-pop |") and line.endswith("| 1 |") for line in report)

    (trial,) = trial_folders(game_dir / "runs" / "tiny-pop__modular-lam0.5")
    capsys.readouterr()
    assert (
        main(
            [
                "pair",
                f"{trial}:ego@left",
                f"{pop_dir}:left",
                "--episodes",
                "40",
                "--out",
                str(tmp_path / "pair"),
                "--name",
                "tiny",
            ]
        )
        == 0
    )
    played = pd.read_csv(tmp_path / "pair" / "tiny.csv").iloc[0]
    assert (played["env"], played["episodes"]) == (GAME, 40) and 0.0 <= played["mean_return"] <= 1.0
