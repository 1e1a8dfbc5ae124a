"""The modular ego inside a real RLlib PPO algorithm: what it trains on, spreading, determinism, checkpoints."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import torch

from rllib_conv import partners
from rllib_conv.envs.bandit.oracle import bandit_states
from rllib_conv.envs.blocks import decode_observation
from rllib_conv.learners.marginal_learner import HEAD_L2_KEY, MARGINAL_REG_KEY, MarginalPPOLearner
from rllib_conv.modules import ego_id, partner_id
from rllib_conv.modules.multi import replica_id
from rllib_conv.modules.packed.stacked_multi import STACK_ID
from rllib_conv.pipelines.train import summarize
from rllib_conv.training.algorithm import Replica, build_algorithm, build_ppo_config
from rllib_conv.training.ego_setup import resolve
from rllib_conv.training.evaluate import head_probs
from rllib_conv.training.experiment import ExperimentConfig
from rllib_conv.training.maml import MetaTrainer
from rllib_conv.training.replica_export import replica_module
from rllib_conv.training.weights import learner_module

pytestmark = pytest.mark.slow  # every test here trains (RLlib, Tune or `rllib-conv` subprocesses)

SEEN: dict[str, list] = {}


class RecordingLearner(MarginalPPOLearner):
    """Records which modules and which observations reach the learner's minibatch loop."""

    def _stacked_epochs(self, data, plan):
        for mid, b in data.items():
            SEEN.setdefault(mid, []).append(b["obs"]["observations"].detach().numpy().copy())
        return super()._stacked_epochs(data, plan)


def small(population: str, **overrides) -> ExperimentConfig:
    """A quick experiment: small networks and batches, a few iterations' worth of steps."""
    base = {
        "population": population,
        "lam": 0.5,
        "model": {"hidden": 16},
        "ppo": {"rollout_per_partner": 60, "minibatch_size": 30, "num_epochs": 2},
    }
    return ExperimentConfig.model_validate({**base, **overrides})


def test_ego_never_trains_on_partner_moves(ray_session) -> None:
    SEEN.clear()
    setup = resolve(small("blocks-perm"))
    algo = build_ppo_config(setup).learners(learner_class=RecordingLearner).build_algo()
    try:
        algo.train()
    finally:
        algo.stop()
    assert set(SEEN) == {replica_id(ego_id(e.name), 0) for e in setup.train}  # no partner module, no stack-only batch
    moves = {decode_observation(o)["move"] for rows in SEEN.values() for obs in rows for o in obs}
    assert moves == {0, 2, 4}  # P1's own turns only: the partner moves on 1, 3, 5


def test_episodes_are_spread_evenly_over_partners(ray_session) -> None:
    setup = resolve(small("bandit-s2-hand"))
    algo = build_ppo_config(setup).build_algo()
    try:
        result = algo.train()
    finally:
        algo.stop()
    sampled = result["env_runners"]["num_module_steps_sampled_lifetime"]
    counts = [sampled[replica_id(ego_id(e.name), 0)] for e in setup.train]
    assert counts == [sampled[replica_id(partner_id(e.name), 0)] for e in setup.train]
    assert max(counts) - min(counts) <= 8  # round robin: at most one episode per vector sub-env apart
    assert sum(counts) >= 240


def _run(exps: list[ExperimentConfig], iterations: int, replica: int = 0):
    """Train `exps` packed as replicas of one algorithm; return replica `replica`'s metrics per iteration and final task weights."""
    replicas = [Replica(resolve(exp)) for exp in exps]
    algo = build_algorithm(replicas)
    try:
        metrics = [summarize(algo.train(), replicas[replica].setup, replica) for _ in range(iterations)]
        return metrics, learner_module(algo)[STACK_ID].task_state(replica)
    finally:
        algo.stop()


def _meta_run(exps: list[ExperimentConfig], outer_steps: int, replica: int = 0):
    """`_run` for MAML egos: `outer_steps` outer steps of `MetaTrainer`, as `EgoTrainable` takes them."""
    replicas = [Replica(resolve(exp)) for exp in exps]
    algo = build_algorithm(replicas)
    meta = MetaTrainer(algo, [e.name for e in replicas[0].setup.train], exps[0].maml.inner_iterations, exps[0].maml.outer_step)
    try:
        metrics = [summarize(meta.step(), replicas[replica].setup, replica) for _ in range(outer_steps)]
        return metrics, learner_module(algo)[STACK_ID].task_state(replica)
    finally:
        algo.stop()


def test_same_seed_same_metrics_different_seed_differs(ray_session) -> None:
    m1, w1 = _run([small("bandit-s2-hand", seed=3)], 3)
    m2, w2 = _run([small("bandit-s2-hand", seed=3)], 3)
    m3, w3 = _run([small("bandit-s2-hand", seed=4)], 3)
    assert m1 == m2
    assert all(torch.equal(w1[k], w2[k]) for k in w1)
    assert m1 != m3 or any(not torch.equal(w1[k], w3[k]) for k in w1)


def test_a_replica_trains_as_it_would_alone(ray_session) -> None:
    """Seed 3 packed between seeds 5 and 7 gets the returns and the weights seed 3 gets alone (float tolerance)."""
    alone, w_alone = _run([small("bandit-s2-hand", seed=3)], 3)
    packed, w_packed = _run([small("bandit-s2-hand", seed=s) for s in (5, 3, 7)], 3, replica=1)
    for a, p in zip(alone, packed):
        assert a.keys() == p.keys()
        np.testing.assert_allclose([p[k] for k in a], [a[k] for k in a], rtol=1e-5, atol=1e-6)
    for k in w_alone:
        torch.testing.assert_close(w_packed[k], w_alone[k], rtol=1e-4, atol=1e-5)
    others, _ = _run([small("bandit-s2-hand", seed=s) for s in (5, 3, 7)], 3, replica=0)
    assert others != packed  # the neighbours are other runs


def test_replicas_of_a_lambda_sweep_train_as_they_would_alone(ray_session) -> None:
    """Egos of lam 0.5, 0 and 0.3 packed in one algorithm (each replica its own regulariser weight) get each its lone
    run's returns and weights; the lam-0 ego's regulariser gradient is 0, though the pack computes every head.

    Only the lam-0 ego's logged D and H differ: alone it skips them in its loss and logs them from each update's
    last minibatch; in the pack they are computed on every minibatch and logged as their mean."""
    sweep = [
        small("bandit-s2-hand", seed=5, lam=0.5),
        small("bandit-s2-hand", seed=3, lam=0.0),
        small("bandit-s2-hand", seed=7, lam=0.3),
    ]
    gaps = []
    for r in (0, 1):
        alone, w_alone = _run([sweep[r]], 3)
        packed, w_packed = _run(sweep, 3, replica=r)
        keys = [k for k in alone[0] if sweep[r].lam > 0 or k not in (MARGINAL_REG_KEY, HEAD_L2_KEY)]
        for a, p in zip(alone, packed):
            np.testing.assert_allclose([p[k] for k in keys], [a[k] for k in keys], rtol=1e-4, atol=1e-5)
        gaps.append(max((w_packed[k] - w_alone[k]).abs().max().item() for k in w_alone))
    # The weights reach the loss: the lam-0 ego's seed under lam 0.5 ends much further from it than packing moves it.
    _, w_lam0 = _run([sweep[1]], 3)
    _, w_other = _run([small("bandit-s2-hand", seed=3, lam=0.5)], 3)
    assert max(gaps) < max((w_other[k] - w_lam0[k]).abs().max().item() for k in w_lam0) / 10


def test_maml_egos_of_two_populations_packed_each_step_through_their_own_partners(ray_session, tmp_path) -> None:
    """MAML's outer steps focus each replica on its own k-th training partner: an ego of the Arms 2 partners listed in
    reverse packs beside one of the usual order and trains as it would alone."""
    pop = partners.get("bandit-s2-hand")
    reverse = pop.model_copy(update={"name": "s2-reversed", "partners": pop.entries("train")[::-1] + pop.entries("test")})
    path = str(reverse.save(tmp_path / "s2-reversed" / "population.json"))
    maml = {"method": "maml", "lam": 0.0, "maml": {"inner_iterations": 1}}
    alone, w_alone = _meta_run([small(path, seed=4, **maml)], 3)
    packed, w_packed = _meta_run([small("bandit-s2-hand", seed=3, **maml), small(path, seed=4, **maml)], 3, replica=1)
    for a, p in zip(alone, packed):
        np.testing.assert_allclose([p[k] for k in a], [a[k] for k in a], rtol=1e-5, atol=1e-6)
    for k in w_alone:
        torch.testing.assert_close(w_packed[k], w_alone[k], rtol=1e-4, atol=1e-5)
    _, w_usual = _meta_run([small("bandit-s2-hand", seed=4, **maml)], 3)  # the order matters: it is each replica's own
    assert any(not torch.allclose(w_usual[k], w_alone[k], rtol=1e-4, atol=1e-5) for k in w_alone)


def test_partner_modules_never_change(ray_session) -> None:
    setup = resolve(small("bandit-s2-hand"))
    algo = build_ppo_config(setup).build_algo()
    obs, mask = bandit_states(setup.env_config)
    batch = {"obs": {"observations": torch.as_tensor(obs), "action_mask": torch.as_tensor(mask, dtype=torch.float32)}}
    try:
        partners = {e.name: replica_id(partner_id(e.name), 0) for e in setup.train}
        before = {n: algo.env_runner.module[mid].forward_inference(batch)["actions"].tolist() for n, mid in partners.items()}
        algo.train()
        algo.train()
        after = {n: algo.env_runner.module[mid].forward_inference(batch)["actions"].tolist() for n, mid in partners.items()}
        learner = algo.learner_group._learner
        # `_module_optimizers` is a defaultdict: a module may be listed with no optimizer.
        assert not any(names for mid, names in learner._module_optimizers.items() if mid.startswith("partner@"))
    finally:
        algo.stop()
    assert before == after == {e.name: e.params["arms"] for e in setup.train}


def test_checkpoint_round_trip_in_a_fresh_process(ray_session, tmp_path) -> None:
    setup = resolve(small("bandit-s2-hand"))
    algo = build_ppo_config(setup).build_algo()
    try:
        algo.train()
        algo.save_to_path(str(tmp_path))
        obs, _ = bandit_states(setup.env_config)
        heads = setup.head_ids
        plain = replica_module(algo.env_runner.module, 0, Replica(setup))
        expected = {h: head_probs(plain, h, obs).tolist() for h in heads}
    finally:
        algo.stop()
    # The weights are stored once (the stack), beside a (weightless) view per head.
    stored = sorted(p.name for p in (tmp_path / "learner_group" / "learner" / "rl_module").iterdir() if p.is_dir())
    assert STACK_ID in stored and all(replica_id(h, 0) in stored for h in heads)
    script = textwrap.dedent(
        f"""
        import json, ray
        from ray.rllib.algorithms.algorithm import Algorithm
        from rllib_conv.training.algorithm import Replica
        from rllib_conv.training.ego_setup import resolve
        from rllib_conv.training.experiment import ExperimentConfig
        from rllib_conv.envs.bandit.oracle import bandit_states
        from rllib_conv.training.evaluate import head_probs
        from rllib_conv.training.replica_export import replica_module
        ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
        algo = Algorithm.from_checkpoint({str(tmp_path)!r})
        setup = resolve(ExperimentConfig.model_validate({setup.exp.model_dump()!r}))
        plain = replica_module(algo.env_runner.module, 0, Replica(setup))
        obs, _ = bandit_states({setup.env_config!r})
        print("RESULT" + json.dumps({{h: head_probs(plain, h, obs).tolist() for h in {heads!r}}}))
        algo.stop()
        """
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    line = next((ln for ln in out.stdout.splitlines() if ln.startswith("RESULT")), None)
    assert line is not None, out.stderr[-3000:]
    loaded = json.loads(line[len("RESULT") :])
    for h in heads:
        np.testing.assert_allclose(loaded[h], expected[h], atol=1e-6)
        assert np.argmax(loaded[h], axis=1).tolist() == np.argmax(expected[h], axis=1).tolist()
