"""`plot_folder` on small folders written here: which PNGs it writes for each kind of folder, and what the heat map holds."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from analysis import figures, loaders
from analysis.plots import plot_folder, sweep_table, swept_keys

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def write_trial(
    experiment: Path,
    name: str,
    population: str,
    lam: float,
    seed: int,
    finals: tuple[float, float],
    distance: float | None = None,
) -> Path:
    """A trained ego of Tune trial `name`, `<trial>/seed=<seed>/` as training exports it: config.yaml, three
    iterations of progress.csv with two partners, and eval.json."""
    trial = experiment / name / f"seed={seed}"
    trial.mkdir(parents=True)
    (trial / "config.yaml").write_text(
        f"name: {experiment.name}\nenv: bandit\npopulation: {population}\nmethod: modular\nlam: {lam}\nseed: {seed}\nmodel:\n  hidden: 30\n  z_dim: null\nppo:\n  lr: 0.0003\n"
    )
    a, b = finals
    lines = ["env_steps,return_mean,return/p0,return/p1,training_iteration"]
    lines += [f"{256 * i},{(a + b) / 2 * i / 3},{a * i / 3},{b * i / 3},{i}" for i in (1, 2, 3)]
    (trial / "progress.csv").write_text("\n".join(lines) + "\n")
    ev = {"eval/mean/p0": a, "eval/mean/p1": b} | ({"eval/marginal_distance/paper": distance} if distance is not None else {})
    (trial / "eval.json").write_text(json.dumps(ev))
    return trial


def check_png(path: Path) -> None:
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > 2000


@pytest.fixture()
def sweep(tmp_path: Path) -> Path:
    """A lam x population sweep, two seeds each; final return_mean = the mean of the two partners' finals."""
    experiment = tmp_path / "runs" / "my-sweep"
    finals = {
        ("bandit-s2-hand", 0.0): ((0.4, 0.6), (0.5, 0.7)),  # return_mean 0.5 and 0.6 -> 0.55
        ("bandit-s2-hand", 0.5): ((0.8, 1.0), (0.9, 0.9)),  # 0.9 and 0.9 -> 0.9
        ("bandit-s3-hand", 0.0): ((0.2, 0.2), (0.3, 0.3)),  # 0.2 and 0.3 -> 0.25
        ("bandit-s3-hand", 0.5): ((0.7, 0.9), (0.6, 0.6)),  # 0.8 and 0.6 -> 0.7
    }
    for i, ((population, lam), per_seed) in enumerate(finals.items()):
        for seed, pair in enumerate(per_seed):
            write_trial(
                experiment, f"EgoTrainable_{i}", population, lam, seed, pair, distance=0.1 * (i + 1) + 0.02 * seed
            )  # seeds: one trial's replicas
    (experiment / "experiment.yaml").write_text("name: my-sweep\n")
    return experiment


def test_a_sweep_gets_learning_curves_and_a_heat_map(sweep: Path) -> None:
    written = plot_folder(sweep)
    assert written == [sweep / "learning_curves.png", sweep / "sweep.png"]
    for png in written:
        check_png(png)
    assert plot_folder(sweep) == written  # drawn again: the same files, overwritten


def test_the_heat_map_holds_the_mean_over_seeds_of_each_final_value(sweep: Path) -> None:
    summaries = loaders.load_trial_summaries(sorted(p.parent for p in sweep.glob("*/seed=*/config.yaml")))
    assert swept_keys(summaries) == ["population", "lam"]  # the seed is replicated, not swept
    table = sweep_table(summaries, "return_mean")
    assert list(table.index) == ["bandit-s2-hand", "bandit-s3-hand"] and list(table.columns) == ["0.0", "0.5"]
    assert table.to_numpy().ravel().tolist() == pytest.approx([0.55, 0.9, 0.25, 0.7])
    # eval.json's distance: trial i has 0.1 * (i + 1) + 0.02 * seed -> 0.11, 0.21, 0.31, 0.41.
    distance = sweep_table(summaries, "eval/marginal_distance/paper")
    assert distance.to_numpy().ravel().tolist() == pytest.approx([0.11, 0.21, 0.31, 0.41])
    assert sweep_table(summaries[summaries["config/population"] == "bandit-s2-hand"], "return_mean").columns.tolist() == [
        "return_mean"
    ]
    # A third swept key (the learning rate, 0.001 on seed 0 and 0.0003 on seed 1): columns name each combination.
    three = summaries.assign(**{"config/ppo.lr": [0.001 if i % 2 == 0 else 0.0003 for i in range(len(summaries))]})
    assert swept_keys(three) == ["population", "lam", "ppo.lr"]
    table = sweep_table(three, "return_mean")
    assert table.columns.tolist() == [
        "lam=0.0, ppo.lr=0.0003",
        "lam=0.0, ppo.lr=0.001",
        "lam=0.5, ppo.lr=0.0003",
        "lam=0.5, ppo.lr=0.001",
    ]
    assert table.loc["bandit-s3-hand"].tolist() == pytest.approx([0.3, 0.2, 0.6, 0.8])
    assert sweep_table(
        summaries[(summaries["config/population"] == "bandit-s2-hand") & (summaries["config/lam"] == 0.5)], "return_mean"
    ).empty


def test_a_training_run_over_seeds_gets_learning_curves_only(tmp_path: Path) -> None:
    experiment = tmp_path / "runs" / "train"
    for seed in (0, 1, 2):
        write_trial(experiment, "T", "bandit-s2-hand", 0.5, seed, (0.9, 0.6))
    assert plot_folder(experiment) == [experiment / "learning_curves.png"]
    check_png(experiment / "learning_curves.png")
    ego = experiment / "T" / "seed=1"
    assert plot_folder(ego) == [ego / "learning_curves.png"]  # one trained ego


def test_partner_curves_draw_each_partner_per_trial(tmp_path: Path) -> None:
    trials = [write_trial(tmp_path / "e", f"T{s}", "bandit-s2-hand", 0.5, s, (0.9, 0.6)) for s in (0, 1)]
    fig = figures.partner_curves(loaders.load_trial_curves(trials))
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 2 and all(ax.get_title().endswith(f"seed {s}") for ax, s in zip(axes, (0, 1)))
    lines = {line.get_label(): line for line in axes[0].get_lines()}
    assert set(lines) == {"p0", "p1", "mean over partners"}
    assert list(lines["p0"].get_ydata()) == pytest.approx([0.3, 0.6, 0.9]) and list(lines["p0"].get_xdata()) == [256, 512, 768]


def write_csvs(folder: Path) -> None:
    """An adaptation CSV (two methods, two seeds, one partner), a zero-shot CSV and an unrelated CSV."""
    folder.mkdir(parents=True)
    rows = ["run,method,lam,z_dim,seed,partner,steps,mean_return,stderr,exact_return"]
    for method, lam, base in (("modular", 0.5, 0.6), ("agg", 0.0, 0.4)):
        rows += [
            f"runs/e/T{s},{method},{lam},30,{s},p0,{step},{base + step / 100 + s / 50},0.01,"
            for s in (0, 1)
            for step in (0, 16, 32)
        ]
    (folder / "my-adapt.csv").write_text("\n".join(rows) + "\n")
    rows = ["run,method,lam,seed,partner,mean_return,stderr,exact_return"]
    rows += [
        f"runs/e/T{s},{method},{lam},{s},p{k},{v + 0.1 * k},0.01,{v + 0.1 * k}"
        for method, lam, v in (("modular", 0.5, 0.8), ("no_task_logits", 0.0, 0.3))
        for s in (0, 1)
        for k in (0, 1)
    ]
    (folder / "my-zeroshot.csv").write_text("\n".join(rows) + "\n")
    (folder / "notes.csv").write_text("a,b\n1,2\n")
    (folder / "failed.csv").write_text(
        "run,method,lam,seed,partner,mean_return,stderr,exact_return\n"
    )  # a stage that wrote no row


def test_adaptation_and_zeroshot_csvs_get_a_png_each(tmp_path: Path) -> None:
    write_csvs(tmp_path / "out")
    written = plot_folder(tmp_path / "out")
    assert written == [
        tmp_path / "out" / "my-adapt.png",
        tmp_path / "out" / "my-zeroshot.png",
    ]  # notes.csv, failed.csv: nothing to draw
    for png in written:
        check_png(png)
    assert plot_folder(tmp_path / "out" / "my-adapt.csv") == [tmp_path / "out" / "my-adapt.png"]


def test_the_csv_figures_show_each_method(tmp_path: Path) -> None:
    write_csvs(tmp_path / "out")
    adapt = loaders.read_stage_csv(tmp_path / "out" / "my-adapt.csv")
    assert sorted(adapt["label"].unique()) == ["agg", "modular-lam0.5"]  # labels as reproduce names them
    fig = figures.adaptation_curves(adapt)
    assert sorted(line.get_label() for line in fig.axes[0].get_lines()) == ["BaselineAgg", "ours λ=0.5"]
    zeroshot = loaders.read_stage_csv(tmp_path / "out" / "my-zeroshot.csv")
    fig = figures.partner_bars(zeroshot)
    heights = sorted(round(p.get_height(), 3) for p in fig.axes[0].patches)
    assert heights == [0.3, 0.4, 0.8, 0.9]  # per partner and method, the mean over the two seeds


def test_anything_else_is_refused_with_what_was_expected(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    (tmp_path / "notes.csv").write_text("a,b\n1,2\n")
    for path in (tmp_path / "empty", tmp_path / "notes.csv", tmp_path / "missing"):
        with pytest.raises(ValueError, match=rf"{path.name}.*expected a training or sweep folder"):
            plot_folder(path)
    not_started = tmp_path / "runs" / "new"
    (not_started / "T0").mkdir(parents=True)
    (not_started / "T0" / "config.yaml").write_text("name: new\nseed: 0\n")
    with pytest.raises(ValueError, match="no training progress yet"):
        plot_folder(not_started)
    assert not list(tmp_path.rglob("*.png"))


def test_summaries_read_config_last_iteration_and_eval(tmp_path: Path) -> None:
    trial = write_trial(tmp_path / "e", "T0", "bandit-s2-hand", 0.5, 3, (0.9, 0.6), distance=0.02)
    row = loaders.load_trial_summaries([trial]).iloc[0]
    assert (row["config/lam"], row["config/seed"], row["config/ppo.lr"], row["config/model.hidden"]) == (0.5, 3, 0.0003, 30)
    assert row["return_mean"] == pytest.approx(0.75) and row["training_iteration"] == 3
    assert row["eval/marginal_distance/paper"] == 0.02 and pd.isna(row["config/model.z_dim"])
