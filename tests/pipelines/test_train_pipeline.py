"""`rllib-conv train` pipeline through Ray Tune: learning, run folder contents, grids."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
import torch
import yaml

from rllib_conv import partners
from rllib_conv.common.run_folders import CONFIG_FILE, EVAL_FILE, SPEC_FILE
from rllib_conv.envs.bandit.oracle import bandit_states
from rllib_conv.envs.oracles import oracle_for
from rllib_conv.learners.head_penalty import head_size
from rllib_conv.modules.multi import ego_id
from rllib_conv.pipelines.train import run, train_stage
from rllib_conv.training import experiment
from rllib_conv.training.checkpoints import last_checkpoint
from rllib_conv.training.evaluate import load_module, task_probs
from rllib_conv.training.tuning import check_spec
from tests.helpers import tiny_experiment

PARTNERS = [f"hand-train-{k}" for k in range(4)]


@pytest.mark.slow
def test_modular_ego_learns_conventions_and_marginals_within_paper_budget(bandit_egos) -> None:
    """Bandit, 2 symmetric contexts, 4 hand-designed partners, lam 0.5, the paper's 10 000 steps."""
    ego = bandit_egos["bandit-s2-hand"]
    result = ego.result
    assert result.error is None
    m = result.metrics
    assert m["env_steps"] <= 10_000 + 256  # stops at the first iteration reaching the budget
    for name in PARTNERS:
        assert m[f"eval/exact/{name}"] >= 0.95, (name, m[f"eval/exact/{name}"])
    assert m["eval/marginal_distance/all"] <= 0.1
    trial = ego.path  # the trial's one replica, seed 0
    assert trial == f"{result.path}/seed=0"
    saved = yaml.safe_load(open(f"{trial}/{CONFIG_FILE}"))
    assert saved["lam"] == 0.5 and saved["model"]["hidden"] == 30 and saved["ppo"]["num_epochs"] == 20
    assert json.load(open(f"{trial}/{EVAL_FILE}"))["eval/marginal_distance/all"] == m["eval/marginal_distance/all"]
    progress = pd.read_csv(f"{trial}/progress.csv")
    assert {f"return/{n}" for n in PARTNERS} <= set(progress.columns) and len(progress) >= 30
    assert result.checkpoint is not None


@pytest.mark.slow
def test_one_progress_line_per_iteration(ray_session, tmp_path, capfd) -> None:
    config = experiment.load("tune_configs/bandit_modular.yaml", ["run.timesteps=512", "name=progress", "model.hidden=8"])
    run(config, storage=tmp_path)
    lines = [ln for ln in capfd.readouterr().out.splitlines() if "] iter" in ln]
    assert [ln.split("iter")[1].split()[0] for ln in lines] == ["1", "2"]
    assert "steps      256" in lines[0] and "steps      512" in lines[1] and "reg " in lines[1]


@pytest.mark.slow
def test_grid_over_lam_from_yaml(ray_session, tmp_path) -> None:
    path = tmp_path / "grid.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": "grid",
                "population": "bandit-s1-hand",
                "lam": {"grid_search": [0.0, 0.5]},
                "model": {"hidden": 8},
                "ppo": {"rollout_per_partner": 16, "num_epochs": 1},
                "run": {"timesteps": 64},
            }
        )
    )
    results = run(experiment.load(path), storage=tmp_path / "runs")
    assert len(results) == 2 and not results.errors
    lams = sorted(yaml.safe_load(open(f"{r.path}/seed=0/{CONFIG_FILE}"))["lam"] for r in results)
    assert lams == [0.0, 0.5]
    assert yaml.safe_load(open(tmp_path / "runs" / "grid" / "experiment.yaml"))["lam"] == {"grid_search": [0.0, 0.5]}


@pytest.mark.slow
def test_head_penalty_hands_the_rules_to_the_task_module_and_keeps_the_conventions(bandit_egos, tmp_path) -> None:
    """Bandit, 2 symmetric and 2 rule contexts: with `head_l2` the heads hold (almost) nothing in rule contexts.

    Three seeds (one packed trial): the structure holds on every seed; the returns are judged on
    their mean over seeds, the unit of replication (a single seed's 10 000-step trajectory differs
    between CPUs in its last float bits, and one partner's return with it).
    """
    pop = partners.get("bandit-s2-hand")
    obs, mask = bandit_states(pop.env_config)
    optimal = oracle_for(pop.env, pop.env_config)(obs)
    rule = optimal.sum(axis=1) == 1

    def head_sizes(trial: str) -> tuple[float, float, np.ndarray]:
        module = load_module(last_checkpoint(trial))
        with torch.no_grad():
            z = module.task.policy(torch.as_tensor(obs), None).z
            outputs = torch.stack([module[ego_id(e.name)].pi(z) for e in pop.entries("train")])
        return head_size(outputs[:, rule]).item(), head_size(outputs[:, ~rule]).item(), task_probs(module, obs, mask)

    plain_rule, _, _ = head_sizes(bandit_egos["bandit-s2-hand"].path)
    config = experiment.load(
        "tune_configs/bandit_modular.yaml", ["name=penalised", "head_l2=0.05", "seed={grid_search: [0, 1, 2]}"]
    )
    result = run(config, storage=tmp_path)[0]
    assert plain_rule > 1.0  # without the penalty the heads also push the rule arms
    for seed in (0, 1, 2):
        rule_size, convention_size, task = head_sizes(f"{result.path}/seed={seed}")
        assert rule_size < 0.01 * plain_rule and convention_size > 10 * rule_size, seed
        assert (task[rule] * optimal[rule]).sum(axis=1).min() >= 0.95, seed  # the task module alone plays the rules
    for name in PARTNERS:  # the plain keys of a packed trial are the mean over its seeds
        assert result.metrics[f"eval/exact/{name}"] >= 0.9, (name, result.metrics[f"eval/exact/{name}"])


def test_a_recorded_experiment_may_grow_its_seeds_but_not_change(tmp_path) -> None:
    spec = {"name": "e", "lam": 0.5, "seed": {"grid_search": [0, 1, 2]}}
    check_spec(tmp_path, spec, grows="seed")
    check_spec(tmp_path, {**spec, "seed": {"grid_search": [3, 4]}}, grows="seed")
    assert yaml.safe_load((tmp_path / SPEC_FILE).read_text())["seed"] == {"grid_search": [0, 1, 2, 3, 4]}
    check_spec(tmp_path, {**spec, "seed": 1}, grows="seed")  # fewer seeds: the record keeps them all
    assert yaml.safe_load((tmp_path / SPEC_FILE).read_text())["seed"] == {"grid_search": [0, 1, 2, 3, 4]}
    with pytest.raises(ValueError, match="already holds a different experiment"):
        check_spec(tmp_path, {**spec, "lam": 0.3}, grows="seed")
    with pytest.raises(ValueError, match="already holds a different experiment"):
        check_spec(tmp_path, {**spec, "seed": {"grid_search": [7]}})  # only the key named may differ


@pytest.mark.slow
def test_a_stage_job_is_cut_to_fill_the_cores_and_each_seed_trains_as_alone(ray_session, tmp_path) -> None:
    # One job of 2 seeds on the session's 2 CPUs runs as 2 trials (packs.spread_over_cores).
    raw = tiny_experiment("cut")
    assert train_stage([experiment.checked({**raw, "seed": {"grid_search": [0, 1]}})], storage=tmp_path / "both") == ["cut"]
    (stage,) = (tmp_path / "both").glob("train-stage-*")
    assert len([p for p in stage.iterdir() if p.is_dir() and p.name.startswith("EgoTrainable")]) == 2
    assert train_stage([experiment.checked({**raw, "seed": {"grid_search": [1]}})], storage=tmp_path / "alone") == ["cut"]

    def seed_eval(root, seed):
        (folder,) = [p for p in (root / "cut").rglob(f"seed={seed}") if p.is_dir()]
        return {k: v for k, v in json.loads((folder / EVAL_FILE).read_text()).items() if k.startswith("eval/")}

    alone = seed_eval(tmp_path / "alone", 1)
    assert seed_eval(tmp_path / "both", 1) == pytest.approx(alone, rel=1e-5, abs=1e-6)
    assert seed_eval(tmp_path / "both", 0) != pytest.approx(alone, rel=1e-5, abs=1e-6)


@pytest.mark.slow
def test_a_lambda_sweep_trains_in_shared_trials_and_each_ego_as_alone(ray_session, tmp_path) -> None:
    # 3 experiments x 2 seeds that can be replicas of one algorithm: one job of 6, cut into 2 trials of 3 on the
    # session's 2 CPUs, so a trial holds replicas of two experiments, each exported to its own experiment's folder.
    # The middle one's population names its partners otherwise: each trial's means take every replica's own partners.
    pop = partners.get("bandit-s1-hand")
    renamed = [e.model_copy(update={"name": f"other-{e.name}"}) for e in pop.partners]
    other = str(
        pop.model_copy(update={"name": "s1-renamed", "partners": renamed}).save(tmp_path / "s1-renamed" / "population.json")
    )
    sweep = [
        experiment.checked(
            {
                **tiny_experiment(f"sweep-{lam}"),
                "lam": lam,
                "seed": {"grid_search": [0, 1]},
                **({"population": other} if lam == 0.3 else {}),
            }
        )
        for lam in (0.0, 0.3, 0.5)
    ]
    assert train_stage(sweep, storage=tmp_path / "sweep") == ["sweep-0.0", "sweep-0.3", "sweep-0.5"]
    (stage,) = (tmp_path / "sweep").glob("train-stage-*")
    trials = [p for p in stage.iterdir() if p.is_dir() and p.name.startswith("EgoTrainable")]
    assert len(trials) == 2
    prefixes = [
        {k.rpartition("/seed=")[0] for k in json.loads((t / "result.json").read_text().splitlines()[-1]) if "/seed=" in k}
        for t in trials
    ]
    assert {"sweep-0.3/point_0"} < max(prefixes, key=len)  # the middle experiment's seeds are split between the trials
    alone = tmp_path / "alone"
    assert train_stage(
        [experiment.checked({**tiny_experiment("sweep-0.3"), "lam": 0.3, "population": other, "seed": {"grid_search": [1]}})],
        storage=alone,
    )

    def seed_eval(root, name, seed):
        folder = root / name / "point_0" / f"seed={seed}"
        return {k: v for k, v in json.loads((folder / EVAL_FILE).read_text()).items() if k.startswith("eval/")}

    assert seed_eval(tmp_path / "sweep", "sweep-0.3", 1) == pytest.approx(seed_eval(alone, "sweep-0.3", 1), rel=1e-4, abs=1e-5)
    for name in ("sweep-0.0", "sweep-0.5"):
        config = yaml.safe_load((tmp_path / "sweep" / name / "point_0" / "seed=0" / CONFIG_FILE).read_text())
        assert config["lam"] == float(name.split("-")[1])


@pytest.mark.slow
def test_a_train_stage_with_more_seeds_trains_the_new_seeds_only(ray_session, tmp_path) -> None:
    raw = tiny_experiment("grown")
    assert train_stage([experiment.checked({**raw, "seed": {"grid_search": [0]}})], storage=tmp_path) == ["grown"]
    first = tmp_path / "grown"
    (seed0,) = [p for p in first.rglob("seed=0") if p.is_dir()]
    before = {p: p.stat().st_mtime_ns for p in seed0.rglob("*") if p.is_file()}
    assert train_stage([experiment.checked({**raw, "seed": {"grid_search": [0, 1]}})], storage=tmp_path) == ["grown"]
    assert sorted(p.name for p in first.rglob("seed=*") if p.is_dir()) == ["seed=0", "seed=1"]
    assert {p: p.stat().st_mtime_ns for p in seed0.rglob("*") if p.is_file()} == before  # seed 0 was not trained again
    assert train_stage([experiment.checked({**raw, "seed": {"grid_search": [0, 1]}})], storage=tmp_path) == []


@pytest.mark.slow
def test_a_manifest_path_relative_to_the_working_folder_trains(ray_session, tmp_path, monkeypatch) -> None:
    # Tune runs each trial in its own folder, where a relative path names nothing (a reproduce
    # with its default relative --out failed this way on its self-play population).
    partners.get("bandit-s1-hand").save(tmp_path / "pop" / "population.json")
    monkeypatch.chdir(tmp_path)
    raw = {**tiny_experiment("relative"), "population": "pop"}
    assert train_stage([experiment.checked(raw)], storage="runs") == ["relative"]
    (config,) = (tmp_path / "runs" / "relative").rglob(CONFIG_FILE)
    assert yaml.safe_load(config.read_text())["population"] == str((tmp_path / "pop").resolve())
    grid = {**raw, "name": "relative-run", "population": {"grid_search": ["pop", "bandit-s1-hand"]}}
    results = run(experiment.checked(grid), storage="runs")
    assert len(results) == 2 and not results.errors
