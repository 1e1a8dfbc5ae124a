"""Population manifests: built-ins, save/load round trip, and clear errors for bad manifests."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rllib_conv import partners
from rllib_conv.envs.blocks import RED, encode_observation
from rllib_conv.partners.population import Population, population_ref, with_absolute_paths


def test_builtin_populations_build_and_have_the_papers_sizes() -> None:
    sizes = {
        "bandit-s2-hand": (4, 4),
        "bandit-s3-hand-newtask": (4, 4),
        "bandit-s2-random": (10, 10),
        "bandit-user-study": (24, 22),
        "blocks-perm": (3, 6),
        "blocks-perm-newtask": (3, 6),
    }
    for name, (n_train, n_test) in sizes.items():
        pop = partners.get(name)
        pop.validate_partners()
        assert (len(pop.entries("train")), len(pop.entries("test"))) == (n_train, n_test), name
    assert set(sizes) <= set(partners.names())


def test_new_task_population_keeps_conventions() -> None:
    old, new = partners.get("bandit-s2-hand"), partners.get("bandit-s2-hand-newtask")
    assert new.env_config == {"symmetric": 2, "new_task": True}
    for a, b in zip(old.partners, new.partners):
        assert a.params["arms"][:2] == b.params["arms"][:2]  # symmetric contexts unchanged
        assert [x + 4 for x in a.params["arms"][2:]] == b.params["arms"][2:]  # rule arms moved


def test_manifest_round_trip(tmp_path) -> None:
    pop = partners.get("blocks-perm")
    pop.partners[0].seed, pop.partners[0].score, pop.partners[0].checkpoint = 7, 19.5, str(tmp_path / "ckpt" / "p0")
    path = pop.save(tmp_path / "pop.json")
    loaded = partners.get(str(path))
    assert loaded == pop
    mask = np.ones(6, dtype=np.int8)
    for red_cell in range(4):
        # P2's view after P1 put red on `red_cell`: every partner answers with its permutation.
        grid = np.zeros(4, dtype=np.int64)
        grid[red_cell] = RED
        obs = encode_observation(np.zeros(4), grid, move=1, sees_goal=False)
        actions = [p.act(obs, mask) for p in loaded.build()]
        assert actions == [p.act(obs, mask) for p in pop.build()]
        assert actions == [e.params["perm"][red_cell] for e in pop.partners]


def _write(tmp_path, data) -> str:
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    return str(path)


@pytest.mark.parametrize(
    ("mutate", "match"),
    [
        (lambda d: d.update(colour="red"), "colour: Extra inputs are not permitted"),
        (lambda d: d["partners"][0].update(split="validation"), r"partners\.0\.split"),
        (lambda d: d["partners"][1].update(kind="telepath"), "unknown partner kind 'telepath'"),
        (lambda d: d.update(env="chess"), "unknown env 'chess'"),
        (lambda d: d.pop("partners"), "partners: Field required"),
        (lambda d: d["partners"][1].update(name=d["partners"][0]["name"]), "duplicate partner name"),
    ],
)
def test_bad_manifests_name_the_problem(tmp_path, mutate, match) -> None:
    data = partners.get("bandit-s2-hand").model_dump()
    mutate(data)
    with pytest.raises(ValueError, match=match):
        partners.get(_write(tmp_path, data))


def test_unknown_population_and_missing_manifest(tmp_path) -> None:
    with pytest.raises(ValueError, match="unknown population 'nope'.*bandit-s2-hand"):
        partners.get("nope")
    with pytest.raises(ValueError, match="does not exist"):
        Population.load(tmp_path / "missing.json")
    (tmp_path / "broken.json").write_text("{not json")
    with pytest.raises(ValueError, match="not valid JSON/YAML"):
        partners.get(str(tmp_path / "broken.json"))


@pytest.mark.parametrize("name", ["9" * 4000, "9" * 4000 + ".json"])
def test_a_name_too_long_for_the_file_system_is_an_unknown_population(name: str) -> None:
    # Path.exists raises OSError (ENAMETOOLONG) for such a name; a config's population is user input.
    with pytest.raises(ValueError, match="unknown population|does not exist"):
        partners.get(name)
    assert population_ref(name) == name


def test_relative_checkpoints_resolve_against_the_manifest_folder(tmp_path) -> None:
    pop = partners.get("blocks-perm")
    pop.partners[0].checkpoint = "partners/p0"
    pop.save(tmp_path / "pop" / "population.json")
    loaded = partners.get(str(tmp_path / "pop"))  # a folder works as well as the manifest path
    assert loaded.partners[0].checkpoint == str((tmp_path / "pop" / "partners" / "p0").resolve())


def test_save_is_atomic_and_leaves_no_temp_files(tmp_path) -> None:
    pop = partners.get("bandit-s1-hand")
    pop.save(tmp_path / "p.json")
    pop.save(tmp_path / "p.json")
    assert [p.name for p in tmp_path.iterdir()] == ["p.json"]


def test_a_population_reference_keeps_names_and_makes_paths_absolute(tmp_path, monkeypatch) -> None:
    partners.get("bandit-s1-hand").save(tmp_path / "pop" / "population.json")
    monkeypatch.chdir(tmp_path)
    assert population_ref("bandit-s1-hand") == "bandit-s1-hand"
    assert population_ref("pop") == str((tmp_path / "pop").resolve())
    assert population_ref("pop/population.json") == str((tmp_path / "pop" / "population.json").resolve())
    assert population_ref("missing") == "missing"  # left for `partners.get` to name the problem
    pop = str((tmp_path / "pop").resolve())
    assert with_absolute_paths({"population": {"grid_search": ["pop", "blocks-perm"]}}, "population") == {
        "population": {"grid_search": [pop, "blocks-perm"]}
    }
    assert with_absolute_paths({"new_population": "pop", "seed": 1}, "new_population") == {"new_population": pop, "seed": 1}
    assert with_absolute_paths({"seed": 1}, "population") == {"seed": 1}


def test_an_empty_population_name_is_refused_not_read_as_the_working_folder(tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    for name in ("", "  "):
        with pytest.raises(ValueError, match="population must name a built-in"):
            partners.get(name)


def test_a_manifest_names_event_weights_only_for_partners_that_have_them(tmp_path) -> None:
    pop = partners.get("blocks-perm")
    pop.partners[0].hidden_utility = {"onion_pickup": 1.0}
    saved = json.loads(pop.save(tmp_path / "population.json").read_text())["partners"]
    assert saved[0]["hidden_utility"] == {"onion_pickup": 1.0}
    assert all("hidden_utility" not in entry for entry in saved[1:])
    assert Population.load(tmp_path).partners[1].hidden_utility is None
