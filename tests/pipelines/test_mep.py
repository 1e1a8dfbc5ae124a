"""MEP (`population_entropy`): pairs trained together equal pairs trained alone at alpha 0, differ by the bonus, and export as a population."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from rllib_conv import partners
from rllib_conv.cli import main
from rllib_conv.common import config_files
from rllib_conv.envs.bandit import good_arms, paper_prizes
from rllib_conv.envs.bandit.oracle import bandit_states
from rllib_conv.pipelines.selfplay import (
    SeatMapping,
    build_joint_config,
    selfplay_score,
    split_pairs,
    train_population,
    trial_pairs,
)
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig

MEP_YAML = "tune_configs/selfplay_bandit_mep.yaml"
TRAJEDI_YAML = "tune_configs/selfplay_bandit_trajedi.yaml"
OBS, MASK = bandit_states({"symmetric": 4})


def joint_config(yaml: str, **overrides) -> SelfPlayConfig:
    """The self-play config `yaml` (a joint generator's example) with `overrides`, resolved."""
    raw = config_files.load(yaml, [], schema=SelfPlayConfig)
    raw.update(overrides)
    return SelfPlayConfig.model_validate(raw).resolve()


def mep_config(**overrides) -> SelfPlayConfig:
    return joint_config(MEP_YAML, **overrides)


def trained_weights(cfg: SelfPlayConfig, iterations: int) -> tuple[dict, dict]:
    """Every module's weights before and after `iterations` training iterations of `cfg`'s joint algorithm."""
    algo = build_joint_config(cfg).build_algo()
    module = algo.learner_group._learner.module

    def weights() -> dict:
        return {mid: {k: v.detach().clone() for k, v in module[mid].state_dict().items()} for mid in module.keys()}

    try:
        before = weights()
        for _ in range(iterations):
            algo.train()
        return before, weights()
    finally:
        algo.stop()


def greedy_arms(module, member: int) -> list[list[int]]:
    """Pair `member`'s greedy arm per context, for each seat."""
    obs, mask = torch.as_tensor(OBS), torch.as_tensor(MASK, dtype=torch.float32)
    return [module[f"seat@player_{s}#{member}"].policy(obs, mask).logits.argmax(-1).tolist() for s in (0, 1)]


def test_each_split_is_one_trial_of_its_pairs() -> None:
    cfg = mep_config(train_pairs=3, test_pairs=2)
    assert trial_pairs(cfg) == [0, 3]
    assert split_pairs(cfg, 0) == [0, 1, 2] and split_pairs(cfg, 3) == [3, 4]
    assert trial_pairs(mep_config(test_pairs=0)) == [0]
    alone = mep_config(train_pairs=3, test_pairs=2, population_entropy=None)
    assert trial_pairs(alone) == [0, 1, 2, 3, 4] and split_pairs(alone, 3) == [3]
    assert SeatMapping(False)("player_1#2", None) == "seat@player_1#2" and SeatMapping(False)("player_1", None) == "seat@player_1"
    assert SeatMapping(True)("player_0#1", None) == "seat@all#1"


@pytest.mark.parametrize(
    ("sets", "message"),
    [
        (["population_entropy=-0.5"], "population_entropy: Input should be greater than or equal to 0"),
        (["population_entropy=lots"], "population_entropy: Input should be a valid number"),
        (["fcp=true"], "fcp and population_entropy cannot be combined"),
    ],
)
def test_bad_values_are_one_clear_error(sets, message, capsys, tmp_path) -> None:
    argv = ["partners", "train", MEP_YAML, "--out", str(tmp_path / "pops"), "--storage", str(tmp_path / "runs")]
    for s in sets:
        argv += ["--set", s]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and err[0].startswith("rllib-conv: error: ")
    assert not any(tmp_path.iterdir())


@pytest.mark.slow
@pytest.mark.parametrize("yaml, bonus", [(MEP_YAML, "population_entropy"), (TRAJEDI_YAML, "trajectory_diversity")])
def test_a_zero_bonus_trains_each_pair_as_a_population_of_one(ray_session, yaml: str, bonus: str) -> None:
    """Known answer: with no bonus (MEP's alpha, TrajeDi's beta), pairs packed into one algorithm are independent runs, to
    the bit (TrajeDi's JSD is only logged); with the bonus the same run ends elsewhere."""
    config = lambda seed, pairs, weight: joint_config(yaml, train_pairs=pairs, test_pairs=0, seed=seed, **{bonus: weight})  # noqa: E731
    before, joint = trained_weights(config(0, 2, 0.0), 3)
    for k in (0, 1):
        _, alone = trained_weights(config(k, 1, 0.0), 3)
        for seat in ("seat@player_0", "seat@player_1"):
            for name, value in joint[f"{seat}#{k}"].items():
                torch.testing.assert_close(value, alone[f"{seat}#0"][name], rtol=0, atol=1e-7)
                assert not torch.equal(value, before[f"{seat}#{k}"][name]) or name.endswith("bias")
    _, weighted = trained_weights(config(0, 2, 1.0), 3)
    for mid in joint:
        assert not torch.allclose(weighted[mid]["pi_out.0.weight"], joint[mid]["pi_out.0.weight"], atol=1e-4)


@pytest.mark.slow
def test_a_large_bonus_sends_the_pairs_to_different_good_arms(ray_session) -> None:
    """Obvious answer: 4 contexts with two good arms each; alpha 1 makes two pairs settle on different arms in every
    context, both still coordinated. Without the bonus the same seeds share an arm somewhere (each context 1/2 by chance)."""
    good = good_arms(paper_prizes(4))
    shared_without_bonus = 0
    for seed in (0, 10, 20):
        for alpha in (1.0, 0.0):
            cfg = mep_config(train_pairs=2, test_pairs=0, seed=seed, population_entropy=alpha)
            algo = build_joint_config(cfg).build_algo()
            try:
                for _ in range(30):
                    algo.train()
                module = algo.env_runner.module
                arms = [greedy_arms(module, k) for k in (0, 1)]
                scores = [selfplay_score(module, cfg, 200, seed=7, member=k) for k in (0, 1)]
            finally:
                algo.stop()
            for k in (0, 1):
                assert arms[k][0] == arms[k][1], "each pair's seats agree (one convention per context)"
                assert all(a in good[c] for c, a in enumerate(arms[k][0]))
            if alpha > 0:
                assert all(a != b for a, b in zip(arms[0][0], arms[1][0])), (seed, arms)
                assert min(scores) >= 0.95, (seed, scores)
            else:
                shared_without_bonus += sum(a == b for a, b in zip(arms[0][0], arms[1][0]))
    assert shared_without_bonus > 0


@pytest.mark.slow
def test_the_pairs_export_as_a_population(ray_session, tmp_path) -> None:
    """`partners train` with population_entropy: one trial per split, every passing pair a partner with its counterpart."""
    config = config_files.checked(
        config_files.load(MEP_YAML, ["train_pairs=2", "test_pairs=1", "name=mep-test"], schema=SelfPlayConfig), SelfPlayConfig
    )
    population, report = train_population(config, out=tmp_path / "pops", storage=tmp_path / "runs")
    assert report["pair"].tolist() == [0, 1, 2] and report["member"].tolist() == [0, 1, 0]
    assert report["passed"].all(), report
    assert [(e.name, e.split) for e in population.partners] == [("sp00", "train"), ("sp01", "train"), ("sp02", "test")]
    assert "MEP" in population.description
    loaded = partners.get(str(tmp_path / "pops" / "mep-test"))
    obs, mask = OBS, MASK
    for entry in loaded.partners:
        arms = entry.build().act_batch(obs, mask)
        counterpart = partners.partner_from_spec(entry.counterpart).act_batch(obs, mask)
        assert arms.tolist() == counterpart.tolist() and entry.score >= 0.95
    # The two train pairs trained together with the bonus: different good arms somewhere at least.
    first, second = (loaded.partners[i].build().act_batch(obs, mask) for i in (0, 1))
    assert not np.array_equal(first, second)
    assert len(list((tmp_path / "runs").glob("*/*/result.json"))) == 2  # one trial per split
