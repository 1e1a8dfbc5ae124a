"""Evaluation sets (`partners.evaluation_sets`): the shipped manifests, their disjointness, population members, bad manifests."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from rllib_conv import envs, partners
from rllib_conv.common.resources import evaluation_set_file, evaluation_sets
from rllib_conv.partners.evaluation_sets import ROLES, disjoint, find_set, load_set, overlap, shipped_set

GAMES = ("bandit", "blocks")
# The bounds each shipped manifest's description states, in its partners' order.
BOUNDS = {
    ("bandit", "heldout"): [1.0, 1.0, 0.85, 0.825, 0.75],
    ("bandit", "validation"): [1.0, 1.0, 0.8, 0.9125, 0.75],
    ("blocks", "heldout"): [20.0] * 5 + [18.5],
    ("blocks", "validation"): [20.0] * 5 + [19.25],
}


def test_every_game_with_an_exact_bound_and_lbf_ship_both_sets_and_nothing_else_is_shipped() -> None:
    # Level-Based Foraging has no exact bound: its sets declare trained ones (tests/pipelines/test_evaluate_k_seats.py).
    shipped = (*GAMES, "lbf")
    assert evaluation_sets() == sorted(f"{g}_{r}.yaml" for g in shipped for r in ROLES)
    for game in shipped:
        for role in ROLES:
            found = shipped_set(game, role)
            assert (found.env, found.role, found.built_by) == (game, role, found.built_by.strip()) and found.built_by
            assert find_set(role, game) == found


@pytest.mark.parametrize("game", GAMES)
def test_the_validation_and_held_out_sets_share_no_partner(game) -> None:
    heldout, validation = (shipped_set(game, role).resolve() for role in ("heldout", "validation"))
    assert disjoint(heldout, validation) and disjoint(validation, heldout)
    assert overlap(heldout, heldout) == [e.name for e in heldout.partners]  # the check does see shared partners


@pytest.mark.parametrize(("game", "role"), list(BOUNDS))
def test_the_shipped_sets_have_the_bounds_their_descriptions_state(game, role) -> None:
    pop = shipped_set(game, role).resolve()
    ego = next(a for a in ("player_0", "player_1") if a != pop.partner_agent)
    assert [envs.best_response_return(game, pop.env_config, ego, e.build()) for e in pop.partners] == pytest.approx(
        BOUNDS[game, role]
    )


def test_the_held_out_blocks_set_holds_no_training_partner_of_blocks_perm() -> None:
    train = partners.get("blocks-perm")
    train.partners = train.entries("train")
    for role in ROLES:
        assert disjoint(shipped_set("blocks", role).resolve(), train)


def write(folder: Path, data: dict, name: str = "set.yaml") -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump(data))
    return path


BASE = {"name": "s", "role": "heldout", "env": "blocks", "env_config": {"new_task": False}, "built_by": "a test"}


def test_a_set_takes_members_of_a_population_by_name_and_a_population_folder_beside_it(tmp_path) -> None:
    ref = {"population": "blocks-perm", "split": "test", "members": ["perm-1032", "perm-2301"]}
    pop = load_set(write(tmp_path, {**BASE, "populations": [ref]})).resolve()
    assert [e.name for e in pop.partners] == ["blocks-perm/perm-1032", "blocks-perm/perm-2301"]
    assert {e.split for e in pop.partners} == {"test"}
    partners.get("blocks-perm").save(tmp_path / "pops" / "mine" / "population.json")
    (tmp_path / "sets").mkdir()
    pop = load_set(write(tmp_path / "sets", {**BASE, "populations": [{"population": "../pops/mine", "split": "train"}]}))
    assert len(pop.resolve().partners) == 3


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({**BASE, "role": "test"}, "role: Input should be 'heldout' or 'validation'"),
        ({k: v for k, v in BASE.items() if k != "built_by"}, "built_by: Field required"),
        (BASE, "the set has no partners"),
        ({**BASE, "partners": [{"name": "x", "kind": "nope"}]}, "unknown partner kind 'nope'"),
        ({**BASE, "partners": [{"name": "x", "kind": "blocks_permutation", "params": {"perm": [0, 0, 1, 2]}}]}, "perm must be"),
        ({**BASE, "populations": [{"population": "bandit-s2-hand"}]}, "is for bandit seat player_1, the set for blocks"),
        ({**BASE, "populations": [{"population": "blocks-perm", "members": ["x"]}]}, r"has no member\(s\) \['x'\]"),
        ({**BASE, "populations": [{"population": "nowhere"}]}, "population 'nowhere': unknown population"),
    ],
)
def test_a_bad_set_names_its_file_and_the_problem(tmp_path, data, message) -> None:
    path = write(tmp_path, data)
    with pytest.raises(ValueError, match=message) as err:
        load_set(path).resolve()
    assert str(path) in str(err.value)


def test_unknown_sets_and_unreadable_files_are_refused(tmp_path) -> None:
    with pytest.raises(ValueError, match="no shipped heldout set for game 'hanabi'"):
        find_set("heldout", "hanabi")
    with pytest.raises(ValueError, match="'nope' is neither heldout nor validation nor an evaluation-set manifest"):
        find_set("nope", "bandit")
    (tmp_path / "bad.yaml").write_text("name: [1\n")
    with pytest.raises(ValueError, match="is not valid YAML"):
        load_set(tmp_path / "bad.yaml")
    (tmp_path / "list.yaml").write_text("- 1\n")
    with pytest.raises(ValueError, match="expected a mapping"):
        load_set(tmp_path / "list.yaml")
    with pytest.raises(ValueError, match="is not among the shipped evaluation sets"):
        evaluation_set_file("chess_heldout.yaml")
