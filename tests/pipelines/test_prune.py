"""HSP's pool pruning (`rllib-conv partners prune`): event profiles, farthest-point choice, the pruned population."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from rllib_conv import partners
from rllib_conv.cli import main
from rllib_conv.partners.event_profiles import event_profile, most_diverse
from rllib_conv.partners.population import PartnerEntry, Population
from rllib_conv.pipelines.prune import PRUNE_REPORT_FILE


def test_farthest_point_choice_on_known_profiles() -> None:
    profiles = np.array([[0, 0], [10, 0], [0, 10], [1, 1]])
    # Summed L1 distances 22, 40, 40, 22: the first of the two farthest; then the one furthest from it; then the
    # one furthest from both (rows 0 and 3 tie at 10; the earlier wins).
    assert most_diverse(profiles, 3) == [1, 2, 0]
    assert most_diverse(profiles, 1) == [1]
    assert sorted(most_diverse(profiles, 4)) == [0, 1, 2, 3]
    with pytest.raises(ValueError, match="keep must be between 1 and the 4 members"):
        most_diverse(profiles, 5)


def cook(name: str, role: str, counterpart: str | None, split: str = "train") -> PartnerEntry:
    params = {"layout": "cramped_room", "role": role, "pot": -1, "onions": -1, "seed": 0}
    other = {"layout": "cramped_room", "role": counterpart, "pot": -1, "onions": -1, "seed": 1}
    return PartnerEntry(
        name=name,
        kind="overcooked_cook",
        params=params,
        split=split,
        counterpart=None if counterpart is None else {"name": f"{name}-counterpart", "kind": "overcooked_cook", "params": other},
    )


def cooks(tmp_path) -> str:
    """Scripted cooks as a self-play population would list them: each with the counterpart it plays beside."""
    pop = Population(
        name="cooks-sp",
        env="overcooked",
        env_config={"layout": "cramped_room"},
        partner_agent="player_1",
        partners=[
            cook("onions", "onions", "dishes"),
            cook("dishes", "dishes", "onions"),
            cook("both", "both", "both"),
            cook("onions-again", "onions", "dishes"),
            cook("held-out", "both", "both", split="test"),
        ],
    )
    return str(pop.save(tmp_path / "cooks-sp" / "population.json").parent)


def test_a_cook_carrying_onions_and_one_carrying_dishes_have_the_profiles_their_roles_say(tmp_path) -> None:
    pop = partners.get(cooks(tmp_path))
    onions, dishes = (event_profile(pop, pop.partners[i], episodes=1) for i in (0, 1))
    assert onions["onion_pickup"] > 0 == onions["dish_pickup"]
    assert dishes["dish_pickup"] > 0 == dishes["onion_pickup"]


def test_prune_keeps_the_most_different_pairs_and_every_test_member(tmp_path, capsys) -> None:
    source = cooks(tmp_path)
    assert main(["partners", "prune", source, "--keep", "2", "--episodes", "1", "--out", str(tmp_path / "out")]) == 0
    folder = tmp_path / "out" / "cooks-sp-pruned2"
    report = pd.read_csv(folder / PRUNE_REPORT_FILE)
    assert list(report["partner"]) == ["onions", "dishes", "both", "onions-again"] and report["kept"].sum() == 2
    pruned = partners.get(str(folder))
    kept = [e.name for e in pruned.entries("train")]
    assert len(kept) == 2 and len(set(kept) & {"onions", "onions-again"}) <= 1  # two equal cooks are no diversity
    assert [e.name for e in pruned.entries("test")] == ["held-out"]
    assert "kept" in capsys.readouterr().out
    # A second run to the same folder is refused and writes nothing.
    before = (folder / "population.json").read_text()
    assert (
        main(
            [
                "partners",
                "prune",
                source,
                "--keep",
                "1",
                "--episodes",
                "1",
                "--out",
                str(tmp_path / "out"),
                "--name",
                "cooks-sp-pruned2",
            ]
        )
        == 2
    )
    assert (folder / "population.json").read_text() == before


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["bandit-s2-hand", "--keep", "1"], "has no events to profile partners by"),
        (["COOKS", "--keep", "4"], "--keep must be between 1 and 3"),
    ],
)
def test_prune_refuses_what_it_cannot_do_with_one_clear_error(tmp_path, capsys, args, message) -> None:
    args = [cooks(tmp_path) if a == "COOKS" else a for a in args]
    assert main(["partners", "prune", *args, "--out", str(tmp_path / "out")]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
