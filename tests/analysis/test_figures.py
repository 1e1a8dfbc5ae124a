"""Each figure function on a tiny DataFrame: the saved PNG is a real, non-empty PNG and the plot holds what it should."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from analysis import figures

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def check_saved(fig: Figure, tmp_path: Path, name: str) -> None:
    png, pdf = figures.save(fig, tmp_path / "out" / name)
    assert png == tmp_path / "out" / f"{name}.png" and pdf == tmp_path / "out" / f"{name}.pdf"
    data = png.read_bytes()
    assert data[:8] == PNG_MAGIC and len(data) > 2000
    assert pdf.read_bytes()[:5] == b"%PDF-" and pdf.stat().st_size > 1000


def bars(ax) -> list[Rectangle]:
    return [p for p in ax.patches if isinstance(p, Rectangle)]


def crosses(ax) -> int:
    return sum(len(line.get_xdata()) for line in ax.get_lines() if line.get_marker() == "x")


@pytest.fixture()
def curves() -> pd.DataFrame:
    rows = []
    for population in ("bandit-s2-hand", "bandit-s3-hand"):
        for label, base in (("modular-lam0.5", 0.6), ("agg", 0.4)):
            for seed in (0, 1):
                for steps in (0, 16, 32):
                    r = base + steps / 100 + seed / 50
                    rows.append(
                        {
                            "game": "bandit",
                            "population": population,
                            "label": label,
                            "run": f"r{seed}",
                            "seed": seed,
                            "partner": "p0",
                            "steps": steps,
                            "mean_return": r,
                            "exact_return": r,
                        }
                    )
    return pd.DataFrame(rows)


def test_adaptation_curves(curves: pd.DataFrame, tmp_path: Path) -> None:
    fig = figures.adaptation_curves(curves, panels=["bandit-s2-hand", "bandit-s3-hand"], note="Bands: n = 2 seeds")
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 2
    for ax in axes:
        assert len(ax.get_lines()) == 2  # one line per method
        assert sum(isinstance(c, PolyCollection) for c in ax.collections) == 2  # one band per method (2 seeds)
        ours, agg = sorted(ax.get_lines(), key=lambda line: line.get_label() != "ours λ=0.5")
        assert ours.get_zorder() > agg.get_zorder() and ours.get_linewidth() > agg.get_linewidth()  # the paper's method on top
    assert [ax.get_title() for ax in axes] == ["Arms 2", "Arms 3"]
    assert [t.get_text() for t in fig.texts] == ["Bands: n = 2 seeds"]
    check_saved(fig, tmp_path, "adapt")


def test_every_method_has_its_own_colour_and_line_style() -> None:
    styles = [figures.LABEL_STYLES[label] for label in figures.LABEL_ORDER]
    colours = [c for c, _ in styles]
    assert len(set(colours)) == len(colours)
    dashed = [str(style) for label, (_, style) in figures.LABEL_STYLES.items() if style != "-"]
    assert len(set(dashed)) == len(dashed)  # solid lines only for the paper's method, the baselines and the oracle
    assert figures.colour(figures.PAPER_METHOD) == "#D55E00" and figures.colour("unknown") == figures.OTHER_STYLE[0]


def test_the_legend_stays_inside_the_figure_width() -> None:
    # One narrow panel and all twelve methods, some with long names: the legend takes fewer columns until it fits.
    rows = [
        {
            "game": "bandit",
            "population": "bandit-s2-hand",
            "label": label,
            "run": "r",
            "seed": 0,
            "partner": "p",
            "steps": step,
            "mean_return": 0.5,
        }
        for label in figures.LABEL_ORDER
        for step in (0, 16)
    ]
    fig = figures.adaptation_curves(pd.DataFrame(rows))
    (legend,) = fig.legends
    box = legend.get_window_extent(fig.canvas.get_renderer())
    assert box.x0 >= fig.bbox.x0 and box.x1 <= fig.bbox.x1
    assert len(legend.get_texts()) == len(figures.LABEL_ORDER)


def test_band_caption_names_the_interval_and_its_n() -> None:
    df = pd.DataFrame({"population": "p", "label": ["a"] * 3 + ["b"] * 2, "seed": [0, 1, 2, 0, 1]})
    assert (
        figures.band_caption(df)
        == "Bands: 95% t-interval over seeds (each seed averaged over its test partners first), n = 2–3 seeds per method."
    )
    one = figures.band_caption(df[df["seed"] == 0], "Error bars", averaged=None)
    assert one == "Error bars: 95% t-interval over seeds, n = 1 seed per method; no band where n = 1."


def test_training_curves(tmp_path: Path) -> None:
    df = pd.DataFrame(
        [
            {
                "population": "bandit-s2-hand",
                "label": label,
                "seed": s,
                "training_iteration": i,
                "steps": 256 * i,
                "return_mean": 0.1 * i + 0.01 * s,
            }
            for label in ("modular-lam0.5", "agg", "oracle")
            for s in (0, 1, 2)
            for i in (1, 2, 3)
        ]
    )
    fig = figures.training_curves(df)
    assert len(fig.axes[0].get_lines()) == 3
    check_saved(fig, tmp_path, "train")


def test_marginal_bars(tmp_path: Path) -> None:
    # Arms 2 has three methods, Blocks only two: no empty slot is drawn for the one not run there.
    df = pd.DataFrame(
        [
            {"population": pop, "label": label, "seed": s, "distance": d + 0.01 * s}
            for pop, methods in (
                ("bandit-s2-hand", ("modular-lam0", "modular-lam0.5", "agg")),
                ("blocks-perm", ("modular-lam0.5", "agg")),
            )
            for label, d in zip(methods, (0.5, 0.05, 1.0) if len(methods) == 3 else (0.05, 1.0))
            for s in (0, 1)
        ]
    )
    fig = figures.marginal_bars(df, paper={("bandit-s2-hand", "modular-lam0.5"): 0.02, ("blocks-perm", "modular-lam0.5"): 0.10})
    ax = fig.axes[0]
    assert len(bars(ax)) == 5 and crosses(ax) == 2
    blocks = sorted(b.get_x() + b.get_width() / 2 for b in bars(ax) if b.get_x() > 0.5)
    width = bars(ax)[0].get_width() / 0.95
    assert blocks == pytest.approx([1 - width / 2, 1 + width / 2])  # centred on its tick
    # Each bar's mean over its two seeds (d, d + 0.01) is printed on it.
    assert sorted(t.get_text() for t in ax.texts) == ["0.055", "0.055", "0.505", "1.005", "1.005"]
    assert ax.get_ylim()[0] == 0.0
    check_saved(fig, tmp_path, "marginals")


def test_zeroshot_bars(tmp_path: Path) -> None:
    df = pd.DataFrame(
        [
            {
                "game": "bandit",
                "population": "bandit-s1-hand",
                "label": label,
                "seed": 0,
                "partner": f"p{k}",
                "mean_return": v,
                "exact_return": v + 0.01,
            }
            for label, v in (("modular-lam0.5", 0.9), ("no_task_logits", 0.3))
            for k in range(4)
        ]
    )
    fig = figures.zeroshot_bars(
        df, paper={("bandit-s1-hand", "modular-lam0.5"): 0.99, ("bandit-s1-hand", "no_task_logits"): 0.30}
    )
    ax = fig.axes[0]
    assert len(bars(ax)) == 2 and crosses(ax) == 2
    assert sorted(round(b.get_height(), 3) for b in bars(ax)) == [0.31, 0.91]  # exact returns are plotted
    check_saved(fig, tmp_path, "zeroshot")


def test_crossplay_heatmap(tmp_path: Path) -> None:
    m = pd.DataFrame([[1.0, 0.5, 0.0], [0.5, 1.0, 0.5], [0.0, 0.5, 1.0]], index=["a", "b", "c"], columns=["a", "b", "c"])
    fig = figures.crossplay_heatmap(m)
    ax = fig.axes[0]
    assert len(ax.images) == 1 and len(ax.texts) == 9
    assert "self-play" in ax.get_title()
    check_saved(fig, tmp_path, "crossplay")


def test_selfplay_heatmap(tmp_path: Path) -> None:
    df = pd.DataFrame(
        {
            "population": ["p"] * 3,
            "partner": ["sp00", "sp01", "sp02"],
            "split": ["train", "train", "test"],
            "score": [1.0, 0.4, 1.0],
            "passed": [True, False, True],
        }
    )
    fig = figures.selfplay_heatmap(df)
    ax = fig.axes[0]
    frames = [p for p in ax.patches if isinstance(p, Rectangle) and p.get_edgecolor()[:3] == (1.0, 0.0, 0.0)]
    assert len(frames) == 1  # the one failed pair
    check_saved(fig, tmp_path, "selfplay")


def test_user_study_bars(tmp_path: Path) -> None:
    scores = pd.DataFrame(
        [
            {"task": t, "context": c, "score": 0.5, "sem": 0.1, "n": 23, "coordinated": 11}
            for t in ("train", "test")
            for c in "ABC"
        ]
    )
    fig = figures.user_study_bars(scores, paper={(t, c): 0.6 for t in ("train", "test") for c in "ABC"})
    ax = fig.axes[0]
    assert len(bars(ax)) == 6 and crosses(ax) == 6
    check_saved(fig, tmp_path, "userstudy")


def test_saved_figures_are_byte_identical_when_rebuilt(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    def build(stem: Path, epoch: str) -> tuple[Path, Path]:
        monkeypatch.setenv("SOURCE_DATE_EPOCH", epoch)  # matplotlib's clock for the PDF creation date
        fig = Figure()
        fig.add_subplot().plot([0, 1, 2], [1, 3, 2])
        return figures.save(fig, stem)

    first, second = build(tmp_path / "a", "1700000000"), build(tmp_path / "b", "1800000000")
    for x, y in zip(first, second):
        assert x.read_bytes() == y.read_bytes(), x.name
