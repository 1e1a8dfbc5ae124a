"""Evaluation sets (`partners.evaluation_sets`): the shipped manifests, their disjointness, population members, bad manifests."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from rllib_conv import envs, partners
from rllib_conv.cli import main
from rllib_conv.common.resources import evaluation_set_file, evaluation_sets
from rllib_conv.envs.overcooked.human_data import CACHE_ENV
from rllib_conv.partners.evaluation_sets import ROLES, disjoint, find_set, load_set, overlap, set_named, shipped_set
from rllib_conv.pipelines import human_proxies
from rllib_conv.pipelines.plans import plan_for
from rllib_conv.training.behaviour_cloning import BCSettings

GAMES = ("bandit", "blocks")
# The bounds each shipped manifest's description states, in its partners' order.
BOUNDS = {
    ("bandit", "heldout"): [1.0, 1.0, 0.85, 0.825, 0.75],
    ("bandit", "validation"): [1.0, 1.0, 0.8, 0.9125, 0.75],
    ("blocks", "heldout"): [20.0] * 5 + [18.5],
    ("blocks", "validation"): [20.0] * 5 + [19.25],
}


def test_every_game_with_an_exact_bound_lbf_overcooked_and_hanabi_ship_both_sets_and_nothing_else_is_shipped() -> None:
    # Level-Based Foraging and Overcooked have no exact bound: their sets declare trained ones
    # (tests/pipelines/test_evaluate_k_seats.py; Overcooked's need the human proxies, tests below); Hanabi's declare
    # the game's maximum and need a self-play population (tests below).
    shipped = (*GAMES, "lbf", "overcooked", "hanabi")
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
    with pytest.raises(ValueError, match="no shipped heldout set for game 'chess'"):
        find_set("heldout", "chess")
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


def test_a_set_becomes_a_population_to_train_with_every_member_in_train(tmp_path, capsys) -> None:
    ref = {"population": "blocks-perm", "split": "test", "members": ["perm-1032"]}
    data = {**BASE, "partners": [{"name": "id", "kind": "blocks_permutation", "params": {"perm": [0, 1, 2, 3]}}]}
    path = write(tmp_path, {**data, "populations": [ref]})
    pop = set_named(str(path)).training_population()
    assert (pop.name, [e.name for e in pop.partners]) == ("s-partners", ["id", "blocks-perm.perm-1032"])
    assert {e.split for e in pop.partners} == {"train"} and pop.env == "blocks"
    # The CLI writes it where a config's `population` finds it, and refuses to replace it unless asked.
    out = tmp_path / "pops"
    assert main(["partners", "from-set", str(path), "--out", str(out), "--name", "br"]) == 0
    assert [e.name for e in partners.get(str(out / "br")).entries("train")] == ["id", "blocks-perm.perm-1032"]
    assert main(["partners", "from-set", str(path), "--out", str(out), "--name", "br"]) == 2
    assert "already exists" in capsys.readouterr().err
    assert main(["partners", "from-set", "chess_heldout", "--out", str(tmp_path / "none")]) == 2
    assert "nor a shipped set (bandit_heldout" in capsys.readouterr().err and not (tmp_path / "none").exists()


def test_overcookeds_sets_say_what_to_run_without_the_human_proxies(tmp_path, monkeypatch) -> None:
    monkeypatch.setenv(CACHE_ENV, str(tmp_path))
    for role in ROLES:
        with pytest.raises(ValueError, match="run `rllib-conv human-proxies overcooked --layouts cramped_room` first"):
            shipped_set("overcooked", role).resolve()
    assert shipped_set("overcooked", "heldout").waiting_for() == ["overcooked-cramped_room-hproxy"]
    assert shipped_set("overcooked", "validation").waiting_for() == ["overcooked-cramped_room-bc"]
    assert shipped_set("bandit", "heldout").waiting_for() == []
    # A plan that evaluates on them still loads: the stage checks the fit when it runs, after the proxies are trained.
    assert plan_for("overcooked").evaluate == {"overcooked-cramped_room-cooks": ["heldout", "validation"]}


@pytest.mark.slow
def test_overcookeds_sets_hold_new_conventions_and_human_proxies_apart_and_declare_a_bound_for_each(
    ray_session, tmp_path, monkeypatch, short_human_cache
) -> None:
    # The built-in proxy populations read $RLLIB_CONV_CACHE/overcooked: point it at proxies trained on the short data.
    (tmp_path / "cache").mkdir()
    (tmp_path / "cache" / "overcooked").symlink_to(short_human_cache)
    monkeypatch.setenv(CACHE_ENV, str(tmp_path / "cache"))
    human_proxies.run(["cramped_room"], [0, 1, 2], short_human_cache, BCSettings(epochs=1), episodes=2)
    assert [shipped_set("overcooked", role).waiting_for() for role in ROLES] == [[], []]
    heldout, validation = (shipped_set("overcooked", role).resolve() for role in ROLES)
    assert disjoint(heldout, validation)
    # No ego of the plan trains with a held-out partner: not a cook of the training split, not a BC proxy.
    cooks, bc = partners.get("overcooked-cramped_room-cooks"), partners.get("overcooked-cramped_room-bc")
    trained_with = cooks.model_copy(update={"partners": [*cooks.entries("train"), *bc.partners]})
    assert disjoint(heldout, trained_with)
    names = [e.name for e in heldout.partners]
    assert sum(n.startswith("overcooked-cramped_room-hproxy/") for n in names) == 3 and len(names) == 6
    for role, pop in (("heldout", heldout), ("validation", validation)):
        assert set(shipped_set("overcooked", role).bounds) == {e.name for e in pop.partners}, role


def _hanabi_stand_in(folder: Path) -> None:
    """A population where Hanabi's sets look for their self-play one: its members' names and splits, random players."""
    members = [(f"sp{k:02d}", "train" if k < 4 else "test") for k in range(8)]
    manifest = {
        "name": "hanabi-eval-selfplay",
        "env": "hanabi",
        "partner_agent": "player_1",
        "partners": [
            {"name": n, "kind": "random_legal", "params": {"seed": 50 + i}, "split": split}
            for i, (n, split) in enumerate(members)
        ],
    }
    pop = partners.Population.model_validate(manifest)
    pop.save(folder / "populations" / "hanabi-eval-selfplay" / "population.json")


def test_hanabis_sets_say_what_to_train_then_hold_disjoint_halves_each_member_bounded(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    made_by = "rllib-conv partners train tune_configs/selfplay_hanabi.yaml --set name=hanabi-eval-selfplay --set seed=1000"
    for role in ROLES:
        with pytest.raises(ValueError, match=f"does not exist yet: run `{made_by}` first"):
            shipped_set("hanabi", role).resolve()
    _hanabi_stand_in(tmp_path)
    heldout, validation = (shipped_set("hanabi", role) for role in ("heldout", "validation"))
    held, valid = heldout.resolve(), validation.resolve()
    assert [e.name for e in held.partners] == ["random-1"] + [f"hanabi-eval-selfplay/sp0{k}" for k in range(4, 8)]
    assert [e.name for e in valid.partners] == ["rule"] + [f"hanabi-eval-selfplay/sp0{k}" for k in range(4)]
    assert disjoint(held, valid) and disjoint(valid, held)
    for eval_set, pop in ((heldout, held), (validation, valid)):
        assert eval_set.bounds == {e.name: envs.game("hanabi").max_score for e in pop.partners}
