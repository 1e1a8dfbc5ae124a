"""Self-play populations: learning, the score gate, save/load, use as fixed partners, cross-play."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from collections import defaultdict

import numpy as np
import pandas as pd
import pytest
import yaml

from rllib_conv import partners
from rllib_conv.common import config_files
from rllib_conv.envs.bandit import good_arms, paper_prizes
from rllib_conv.envs.bandit.oracle import bandit_states
from rllib_conv.modules import partner_id
from rllib_conv.modules.multi import replica_id
from rllib_conv.partners.trained import TrainedPolicyPartner
from rllib_conv.pipelines import selfplay
from rllib_conv.pipelines.crossplay import crossplay, crossplay_gap, write_crossplay
from rllib_conv.pipelines.selfplay import fcp_members, train_population
from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
from rllib_conv.training.algorithm import build_ppo_config
from rllib_conv.training.ego_setup import resolve
from rllib_conv.training.experiment import ExperimentConfig

OBS, MASK = bandit_states({"symmetric": 2})


def selfplay_raw(**overrides) -> dict:
    raw = config_files.load(
        "tune_configs/selfplay_bandit.yaml", ["train_pairs=2", "test_pairs=1", "run.timesteps=12000"], schema=SelfPlayConfig
    )
    raw.update(overrides)
    return raw


@pytest.fixture(scope="module")
def trained(ray_session, tmp_path_factory):
    """A 3-pair bandit self-play population (2 train, 1 test), trained once for this module."""
    root = tmp_path_factory.mktemp("selfplay")
    config = config_files.checked(selfplay_raw(name="sp-test"), SelfPlayConfig)
    population, report = train_population(config, out=root / "pops", storage=root / "runs")
    return root, population, report


@pytest.mark.slow
def test_pairs_pass_the_gate_with_one_convention_per_context(trained) -> None:
    root, population, report = trained
    assert report["passed"].all() and len(population.partners) == 3
    assert [e.split for e in population.partners] == ["train", "train", "test"]
    good = good_arms(paper_prizes(2))
    for entry in population.partners:
        assert entry.score >= 0.95 and entry.steps_to_gate if hasattr(entry, "steps_to_gate") else entry.score >= 0.95
        partner = entry.build()
        counterpart = partners.partner_from_spec(entry.counterpart)
        arms, answer = partner.act_batch(OBS, MASK), counterpart.act_batch(OBS, MASK)
        # One convention per context: a good arm, and the pair's other seat picks the same one.
        assert all(a in good[c] for c, a in enumerate(arms)) and arms.tolist() == answer.tolist()
    assert (report["steps_to_gate"] <= 12000).all()


@pytest.mark.slow
def test_population_folder_is_self_contained_and_loads_in_a_fresh_process(trained, tmp_path) -> None:
    root, population, _ = trained
    moved = tmp_path / "moved"
    shutil.copytree(root / "pops" / "sp-test", moved)  # relative paths: the folder can move
    here = {e.name: TrainedPolicyPartner(e.name, e.params["checkpoint"]).probs(OBS, MASK).tolist() for e in population.partners}
    script = textwrap.dedent(
        f"""
        import json
        from rllib_conv import partners
        from rllib_conv.envs.bandit.oracle import bandit_states
        obs, mask = bandit_states({{"symmetric": 2}})
        pop = partners.get({str(moved)!r})
        print("RESULT" + json.dumps({{e.name: e.build().probs(obs, mask).tolist() for e in pop.partners}}))
        """
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    line = next((ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")), None)
    assert line is not None, out.stderr[-2000:]
    there = json.loads(line[len("RESULT") :])
    assert there.keys() == here.keys()
    for name in here:
        np.testing.assert_allclose(there[name], here[name], atol=1e-7)
    manifest = json.loads((moved / "population.json").read_text())
    assert all(not p["params"]["checkpoint"].startswith("/") for p in manifest["partners"])


@pytest.mark.slow
def test_trained_population_plugs_into_ego_training(trained) -> None:
    root, population, _ = trained
    exp = ExperimentConfig(
        population=str(root / "pops" / "sp-test"), lam=0.5, model={"hidden": 8}, ppo={"rollout_per_partner": 32, "num_epochs": 1}
    )
    setup = resolve(exp)
    algo = build_ppo_config(setup).build_algo()
    batch = {"obs": {"observations": OBS, "action_mask": MASK.astype(np.float32)}}
    try:
        modules = {e.name: algo.env_runner.module[replica_id(partner_id(e.name), 0)] for e in setup.train}  # replica 0's partners
        before = {name: m.forward_inference(batch)["actions"].tolist() for name, m in modules.items()}
        algo.train()
        after = {name: m.forward_inference(batch)["actions"].tolist() for name, m in modules.items()}
        assert isinstance(modules[setup.train[0].name].partner, TrainedPolicyPartner)
    finally:
        algo.stop()
    assert before == after == {e.name: e.build().act_batch(OBS, MASK).tolist() for e in setup.train}


@pytest.mark.slow
def test_pairs_that_miss_the_gate_are_reported_not_kept(ray_session, tmp_path) -> None:
    raw = selfplay_raw(name="too-short")
    raw.update(
        {
            "train_pairs": 1,
            "test_pairs": 0,
            "run": {"timesteps": 128},
            "gate": {"score": 0.95, "episodes": 100, "check_every": 1, "check_episodes": 50},
        }
    )
    config = config_files.checked(raw, SelfPlayConfig)
    population, report = train_population(config, out=tmp_path / "pops", storage=tmp_path / "runs")
    assert report["passed"].tolist() == [False] and population.partners == []
    assert pd.read_csv(tmp_path / "pops" / "too-short" / "selfplay_report.csv")["passed"].tolist() == [False]
    # An existing population is never replaced by accident.
    with pytest.raises(ValueError, match="already exists"):
        train_population(config, out=tmp_path / "pops", storage=tmp_path / "runs")


@pytest.mark.slow
def test_a_pair_trains_the_same_in_a_reused_worker(trained, tmp_path) -> None:
    """Tune runs trial after trial in one worker (`reuse_actors`); nothing of a trial carries into the next."""
    root, population, _ = trained
    by_worker = defaultdict(list)
    for f in (root / "runs").glob("*/*/result.json"):
        result = json.loads(f.read_text().strip().splitlines()[-1])
        by_worker[result["pid"]].append(result)
    later = [r for runs in by_worker.values() for r in sorted(runs, key=lambda r: r["timestamp"])[1:]]
    assert later, "3 pairs on 2 CPUs: one worker should have run two of them"
    seed = later[0]["seed"]
    # The same pair (same seed) alone, in a fresh worker.
    config = config_files.checked(selfplay_raw(name="alone", seed=seed, train_pairs=1, test_pairs=0), SelfPlayConfig)
    alone, _ = train_population(config, out=tmp_path / "pops", storage=tmp_path / "runs")
    before, after = next(e for e in population.partners if e.seed == seed), alone.partners[0]
    for seat in (lambda e: e.build(), lambda e: partners.partner_from_spec(e.counterpart)):
        np.testing.assert_array_equal(seat(after).probs(OBS, MASK), seat(before).probs(OBS, MASK))


@pytest.mark.slow
def test_a_pair_trains_the_same_in_any_process() -> None:
    """Two seats moving at once (the bandit): RLlib's own sampling order follows the string hash
    seed, which differs per process; with batched sampling the pair is the same in every one."""
    script = textwrap.dedent(
        """
        import hashlib, ray
        from rllib_conv.common import config_files
        from rllib_conv.pipelines.selfplay import build_selfplay_config
        from rllib_conv.pipelines.selfplay_config import SelfPlayConfig
        raw = config_files.load("tune_configs/selfplay_bandit.yaml", [], schema=SelfPlayConfig)
        ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
        algo = build_selfplay_config(SelfPlayConfig.model_validate(raw).resolve()).build_algo()
        for _ in range(2):
            algo.train()
        module, digest = algo.learner_group._learner.module, hashlib.sha1()
        for mid in sorted(module.keys()):
            for name, value in sorted(module[mid].state_dict().items()):
                digest.update(value.numpy().tobytes())
        print("WEIGHTS", digest.hexdigest())
        """
    )
    digests = []
    for hash_seed in ("1", "2"):  # sets of the two seat names iterate in opposite orders under these seeds
        env = {**os.environ, "PYTHONHASHSEED": hash_seed, "OMP_NUM_THREADS": "1"}
        out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300, env=env)
        assert out.returncode == 0, out.stderr[-2000:]
        digests.append(next(line for line in out.stdout.splitlines() if line.startswith("WEIGHTS")))
    assert digests[0] == digests[1]


@pytest.mark.slow
def test_missing_partner_checkpoint_is_a_clear_error(trained, tmp_path) -> None:
    root, _, _ = trained
    broken = tmp_path / "broken"
    shutil.copytree(root / "pops" / "sp-test", broken)
    shutil.rmtree(broken / "partners" / "sp01")
    with pytest.raises(ValueError, match=r"partner 'sp01': checkpoint .*sp01.* does not exist"):
        partners.get(str(broken))


def test_crossplay_matrix_shape_labels_and_diagonal(tmp_path) -> None:
    pop = partners.get("bandit-s2-hand")
    matrix = crossplay(pop, pop, episodes=400, seed=0)
    names = [e.name for e in pop.partners]
    assert list(matrix.index) == names and list(matrix.columns) == names and matrix.shape == (8, 8)
    arms = {e.name: np.array(e.params["arms"]) for e in pop.partners}
    for a in names:
        for b in names:
            agree = float(np.mean(arms[a] == arms[b]))  # contexts are uniform: expected score by hand
            assert abs(matrix.loc[a, b] - agree) < 0.1, (a, b)
    assert (np.diag(matrix.to_numpy()) == 1.0).all()
    csv, png = write_crossplay(matrix, tmp_path, "hand")
    assert pd.read_csv(csv, index_col=0).shape == (8, 8) and png.stat().st_size > 5000


def test_crossplay_gap_is_the_diagonal_mean_minus_the_off_diagonal_mean() -> None:
    names = ["a", "b", "c"]
    matrix = pd.DataFrame([[1.0, 0.5, 0.0], [0.25, 0.8, 0.5], [0.0, 0.25, 0.9]], index=names, columns=names)
    gap = crossplay_gap(matrix)
    assert gap["selfplay"] == pytest.approx(0.9) and gap["crossplay"] == pytest.approx(0.25)
    assert gap["gap"] == pytest.approx(0.65)
    assert crossplay_gap(matrix[["b", "a", "c"]]) is None  # not one population against itself, member for member
    assert crossplay_gap(matrix.loc[["a"], ["a"]]) is None  # one member: no cross-play


def test_the_hand_population_pays_its_conventions_in_cross_play() -> None:
    pop = partners.get("bandit-s2-hand")
    arms = np.array([e.params["arms"] for e in pop.partners])
    agree = (arms[:, None, :] == arms[None, :, :]).mean(-1)  # exact expected score: contexts are uniform
    off = agree[~np.eye(len(arms), dtype=bool)].mean()
    gap = crossplay_gap(crossplay(pop, pop, episodes=400, seed=0))
    assert gap["selfplay"] == 1.0 and abs(gap["gap"] - (1.0 - off)) < 0.03 and gap["gap"] > 0.2


@pytest.mark.slow
def test_crossplay_of_trained_population_has_self_play_on_the_diagonal(trained) -> None:
    root, population, _ = trained
    matrix = crossplay(population, population, episodes=200)
    assert (np.diag(matrix.to_numpy()) >= 0.95).all()


def test_crossplay_refuses_different_games() -> None:
    with pytest.raises(ValueError, match="different games or seats"):
        crossplay(partners.get("bandit-s2-hand"), partners.get("bandit-s3-hand"))


def test_selfplay_configs_are_valid() -> None:
    for name in ("selfplay_bandit", "selfplay_blocks", "selfplay_hanabi"):
        path = f"tune_configs/{name}.yaml"
        cfg = config_files.load_checked(path, schema=SelfPlayConfig).first
        assert cfg.gate.episodes == 1000
    assert yaml.safe_load(open("tune_configs/selfplay_blocks.yaml"))["gate"]["score"] == 19.0


def test_the_gate_scores_pairs_as_every_score_is_measured(monkeypatch) -> None:
    # On Overcooked the training reward includes the shaped reward; the gate must see soups alone (envs.make_scored).
    class Scored(Exception):
        pass

    def make_scored(name, **config):
        raise Scored(name, config)

    monkeypatch.setattr(selfplay.envs, "make_scored", make_scored)
    cfg = SelfPlayConfig.model_validate(selfplay_raw())
    with pytest.raises(Scored) as found:
        selfplay.selfplay_score(None, cfg, episodes=1, seed=0)
    assert found.value.args == ("bandit", cfg.env_config)


def test_fcp_keeps_the_start_and_the_check_nearest_half_the_final_score() -> None:
    # The last snapshot is the passing check: the final seat itself, never the midpoint (0.50 is not a candidate).
    snaps = [{"folder": f"it{i}", "score": v} for i, v in enumerate([0.10, 0.30, 0.53, 0.47, 0.50])]
    assert {k: s["folder"] for k, s in fcp_members(snaps, final_score=0.98).items()} == {"init": "it0", "mid": "it3"}
    assert {k: s["folder"] for k, s in fcp_members(snaps[:2], final_score=0.98).items()} == {"init": "it0"}
    assert fcp_members([], 1.0) == {}


@pytest.mark.slow
def test_an_fcp_population_holds_each_pair_at_its_start_midway_and_end(ray_session, tmp_path) -> None:
    raw = selfplay_raw(name="fcp", train_pairs=1, test_pairs=1, fcp=True)
    raw["gate"] = {**raw["gate"], "check_episodes": 100, "episodes": 200}
    population, report = train_population(
        config_files.checked(raw, SelfPlayConfig), out=tmp_path / "pops", storage=tmp_path / "runs"
    )
    assert report["passed"].all()
    names = [e.name for e in population.partners]
    assert names[:2] == ["sp00-init", "sp00-mid"] and names[-1] == "sp01" and len(names) == 6
    by_name = {e.name: e for e in population.partners}
    for pair in ("sp00", "sp01"):
        start, mid, end = (by_name[n] for n in (f"{pair}-init", f"{pair}-mid", pair))
        assert start.split == mid.split == end.split
        # Before training a pair coordinates only by chance; it ends above the gate; the midpoint lies between.
        assert start.score < mid.score < end.score
    # The snapshots are partners like any other: they load from the folder and act.
    reloaded = partners.get(str(tmp_path / "pops" / "fcp"))
    assert [e.name for e in reloaded.partners] == names
    assert reloaded.partners[0].build().act_batch(OBS, MASK).shape == (len(OBS),)
