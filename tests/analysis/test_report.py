"""build_report on the fixture (and on small hand-made folders): the computed numbers and verdicts in report.md."""

from __future__ import annotations

import re
from pathlib import Path

import pandas as pd
import pytest

from analysis.report import build_report
from analysis.report.sections.status import trained_steps
from analysis.report.verdicts import compare, overall_verdict

FIXTURE = Path(__file__).parent / "fixtures" / "repro"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> Path:
    return build_report(FIXTURE, tmp_path_factory.mktemp("report"))


@pytest.fixture(scope="module")
def text(report: Path) -> str:
    return report.read_text()


def test_report_and_every_linked_figure_exist(report: Path, text: str) -> None:
    assert report.name == "report.md" and report.is_file()
    links = re.findall(r"\]\((figures/[^)]+\.png)\)", text)
    assert {Path(x).stem for x in links} >= {"adapt_armsexp", "zeroshot", "marginals", "userstudy", "training_bandit", "selfplay", "crossplay_bandit-s2-hand__bandit-s2-hand"}
    for link in links:
        png = report.parent / link
        assert png.read_bytes()[:8] == PNG_MAGIC
        assert png.with_suffix(".pdf").is_file()


def test_status_names_the_env_steps_each_ego_trained_for(text: str) -> None:
    # The fixture's 4 trials each end their progress.csv at 2048 env steps.
    assert "| none | 4 | 2,048 |" in text
    curves = pd.DataFrame({"run": ["a", "a", "b", "b"], "steps": [0, 301_440, 0, 1_000_320]})
    assert trained_steps(curves) == "301,440–1,000,320"
    assert trained_steps(curves.iloc[:0]) == "—"


def test_zeroshot_numbers_and_flags(text: str) -> None:
    # ours λ=0.5 on Arms 1: exact returns 0.27873, 0.30279, 0.29955, 0.30089 -> mean 0.29549,
    # sd 0.01125, half-width 3.182 * 0.01125 / 2 = 0.01790 -> [0.2776, 0.3134]; the paper's 0.99 is outside.
    assert "| Arms 1 | ours λ=0.5 | 0.99 | 0.295 [0.278, 0.313] (n=4) | **differs**: ours lower by 0.695 |" in text
    # BaselineModular: 0.14514, 0.15091, 0.11426, 0.10625 -> 0.129 [0.094, 0.164]; the paper's 0.30 is outside.
    assert "| Arms 1 | BaselineModular | 0.3 | 0.129 [0.094, 0.164] (n=4) | **differs**: ours lower by 0.171 |" in text
    assert "| Arms 1 | supported | ours λ=0.5 0.295 vs BaselineModular 0.129 |" in text


def test_adaptation_auc_row(text: str) -> None:
    # Exact returns at steps 0, 16, 32, 48, 64: 0.4647, 0.5509, 0.6729, 0.7732, 0.8366 -> AUC 0.660.
    assert "| Arms 2 | ours λ=0.5 | 5 | 64 | 0.465 (n=1, no interval) | 0.837 (n=1, no interval) | 0.660 (n=1, no interval) | exact |" in text
    assert "| Arms 2 | contradicted | best regularised: ours λ=0.5 AUC 0.660; BaselineAgg 0.825; not above BaselineAgg |" in text


@pytest.mark.parametrize(
    ("a", "b", "outcome"),
    [
        ((0.9, 0.85, 0.95), (0.7, 0.6, 0.8), "clear"),
        ((0.9, 0.85, 0.95), (0.88, 0.8, 0.96), "mean"),
        ((0.924, 0.916, 0.932), (0.928, 0.906, 0.950), "tie"),  # the bandit Arms 3 numbers: a lower mean, overlapping
        ((0.7, 0.6, 0.8), (0.9, 0.85, 0.95), "no"),
        ((0.66, float("nan"), float("nan")), (0.82, float("nan"), float("nan")), "no"),  # one run each: nothing to overlap
    ],
)
def test_better_tells_a_tie_inside_overlapping_intervals_from_a_loss(a, b, outcome) -> None:
    assert compare(a, b) == outcome


@pytest.mark.parametrize(
    ("outcomes", "verdict"),
    [
        (["clear", "clear"], "supported"),
        (["clear", "mean"], "supported (intervals overlap)"),
        (["clear", "tie"], "not shown (intervals overlap)"),
        (["tie", "no"], "contradicted"),
    ],
)
def test_verdict_counts_a_tie_as_not_shown_and_a_loss_as_contradicted(outcomes, verdict) -> None:
    assert overall_verdict(outcomes) == verdict


def test_user_study_section(text: str) -> None:
    assert "| Train-A | 22/23 = 0.957 ± 0.043 | 0.9545 ± 0.044 | 21/22 = 0.9545 ± 0.0444 | no | yes |" in text
    assert "| Test-A | 21/23 = 0.913 ± 0.060 | 1 ± 0 | 22/22 = 1.0000 ± 0.0000 | no | yes |" in text
    assert "Under it the table gives every bar and error bar of the paper's figure" in text
    assert "user study: the numbers computed from the appendix table differ from the paper's figure" in text


def test_differences_and_absences_are_explained(text: str) -> None:
    summary = text.split("## Where ours differs from the paper, and why")[1].split("## Adapting")[0]
    assert "quick plan" in summary
    assert "ours 0.295 [0.278, 0.313] (n=4), ours is worse." in summary  # zero-shot Arms 1 vs the paper's 0.99
    assert "the trained ego is under-trained: 0.861 of a possible 1" in summary  # eval.json mean over 4 partners
    assert "blocks: no folder under the root" in summary and "hanabi: no folder under the root" in summary
    assert "fig:armsexp: panel(s) Arms 3, Arms 4, Arms User Study absent" in summary


def test_selfplay_and_crossplay_numbers(text: str) -> None:
    assert "| bandit-s2-selfplay | train | 10 | 10 | 10 |" in text
    # Each row of the 8 x 8 matrix holds 1.0, 0.88, 0.74, 0.62 twice: off-diagonal mean (6.48 - 1) / 7 = 0.783.
    assert "self-play (diagonal) 1.000, cross-play (off-diagonal) 0.783" in text


def write_zeroshot(root: Path) -> None:
    """A bandit game folder holding only zero-shot results: 3 seeds x 4 test partners for two methods."""
    game = root / "bandit"
    (game / "zeroshot").mkdir(parents=True)
    (game / "plan.json").write_text('{"game": "bandit", "seeds": [0, 1, 2], "quick": false}')
    header = "run,method,lam,seed,partner,mean_return,stderr,exact_return"
    modular, baseline = [header], [header]
    for s in range(3):
        for k in range(4):
            v = 0.86 + 0.01 * k + 0.01 * s  # 0.86 .. 0.91, mean 0.885
            modular.append(f"runs/bandit-s2-hand__modular-lam0.5/T{s},modular,0.5,{s},hand-test-{k},{v},0.01,{v}")
            baseline.append(f"runs/bandit-s2-hand__no_task_logits/T{s},no_task_logits,0.0,{s},hand-test-{k},0.2,0.01,0.2")
    (game / "zeroshot" / "bandit-s2-hand__modular-lam0.5.csv").write_text("\n".join(modular) + "\n")
    (game / "zeroshot" / "bandit-s2-hand__no_task_logits.csv").write_text("\n".join(baseline) + "\n")


def test_paper_inside_and_outside_our_interval(tmp_path: Path) -> None:
    write_zeroshot(tmp_path / "repro")
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    # 12 values 0.86..0.91 (mean 0.885, sd 0.01446, half-width 2.201 * 0.01446 / sqrt(12) = 0.00919): 0.89 is inside.
    assert "| Arms 2 | ours λ=0.5 | 0.89 | 0.885 [0.876, 0.894] (n=12) | paper inside our 95% CI |" in text
    # All twelve 0.2: a zero-width interval, and the paper's 0.55 outside it with no cause visible in the data.
    assert "| Arms 2 | BaselineModular | 0.55 | 0.200 [0.200, 0.200] (n=12) | **differs**: ours lower by 0.350 |" in text
    assert "(n=12), ours is worse. Why: no cause visible in the data" in text
    assert "stage(s) not finished: selfplay, train, adapt, zeroshot, marginals" in text
    assert "No adaptation curves" in text and "No marginals.csv found." in text


def test_methods_beyond_the_paper_are_listed_but_left_out_of_its_claims(tmp_path: Path) -> None:
    game = tmp_path / "repro" / "blocks"
    game.mkdir(parents=True)
    (game / "plan.json").write_text('{"game": "blocks", "seeds": [0, 1, 2], "quick": false}')
    header = "run,env,env_config,population,method,lam,z_dim,seed,distance,distance_all_states,states,experiment"
    rows = [header]
    # Ours 0.10, BaselineAgg 1.0, ours with the head penalty 0.02: the closest, but not a method of the paper.
    for label, method, distance in (("modular-lam0.5", "modular", 0.10), ("agg", "agg", 1.0), ("modular-lam0.5-hl0.01", "modular", 0.02)):
        for s in range(3):
            exp = f"blocks-perm__{label}"
            rows.append(f"runs/{exp}/T{s},blocks,{{}},blocks-perm,{method},0.5,80,{s},{distance},{distance},10,{exp}")
    (game / "marginals.csv").write_text("\n".join(rows) + "\n")
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    assert "| Blocks (hand-designed) | ours λ=0.5 + head penalty | — | 0.020 [0.020, 0.020] (n=3) |" in text
    assert "| Blocks (hand-designed) | supported | ours λ=0.5 0.100, BaselineAgg 1.000 |" in text
    assert "ours λ=0.5 + head penalty (`modular-lam0.5-hl0.01`) is not in the paper" in text


def test_extensions_are_judged_against_the_baselines_apart_from_the_papers_claim(tmp_path: Path) -> None:
    game = tmp_path / "repro" / "blocks"
    (game / "adaptation").mkdir(parents=True)
    (game / "plan.json").write_text('{"game": "blocks", "seeds": [0, 1, 2], "quick": false}')
    # Flat curves (AUC = the return), six per method: three at value - 0.1, three at value + 0.1.
    # Mean = value, sd = 0.10954, half-width 2.5706 * 0.10954 / sqrt(6) = 0.115.
    methods = (("modular-lam0.5", "modular", 14.5), ("agg", "agg", 15.0), ("oracle", "oracle", 15.5), ("modular-lam0.5-pick", "modular", 16.0))
    for label, method, value in methods:
        rows = ["run,method,lam,z_dim,seed,partner,steps,mean_return,stderr,exact_return"]
        for i in range(6):
            r = value + (0.1 if i % 2 else -0.1)
            rows += [f"runs/blocks-selfplay__{label}/T{i // 2},{method},0.5,80,{i // 2},sp0{6 + i % 2},{step},{r},0.1," for step in (0, 640)]
        (game / "adaptation" / f"blocks-selfplay__{label}.csv").write_text("\n".join(rows) + "\n")
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    assert "| Blocks (self-play) | contradicted | best regularised: ours λ=0.5 AUC 14.500; BaselineAgg 15.000; not above BaselineAgg |" in text
    assert (
        "| Blocks (self-play) | ours λ=0.5, adapting from a picked head | supported | AUC 16.00 [15.89, 16.11] (n=6); "
        "BaselineAgg 15.00 [14.89, 15.11] (n=6) |"
    ) in text
    assert "| Blocks (self-play) | supported | oracle AUC 15.500; no method above it |" in text  # the extension is not the paper's
    assert "(`modular-lam0.5-pick`) is not in the paper" in text


def test_empty_root_and_recorded_sessions(tmp_path: Path) -> None:
    sessions = tmp_path / "sessions"
    sessions.mkdir()
    (sessions / "s1.csv").write_text("pair,task,context,try,action_1,action_2\n1,test,C,1,2,2\n2,test,C,1,4,2\n")
    (tmp_path / "nothing").mkdir()
    text = build_report(tmp_path / "nothing", tmp_path / "out", user_study=[sessions]).read_text()
    assert "No game folder" in text
    assert "## User study (fig:userstudy)" in text
    assert "### Recorded sessions (2 pairs in 1 file(s))" in text
    assert "| Test-C | 1/2 = 0.500 ± 0.500 | 2 |" in text  # pair 1 scores (2/2), pair 2 does not (4/2)
    assert (tmp_path / "out" / "figures" / "userstudy_live.png").is_file()


def test_a_missing_root_is_an_error_and_writes_nothing(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="is not a folder"):
        build_report(tmp_path / "missing")
    assert not (tmp_path / "missing").exists()


def test_direction_knows_that_smaller_distances_are_better() -> None:
    from analysis.report.verdicts import Comparison

    distance = Comparison("marginals", "Arms 2, ours", 0.02, "src", 0.003, 0.001, 0.005, 3, higher_is_better=False)
    ret = Comparison("zero-shot", "Arms 2, ours", 0.89, "src", 0.996, 0.995, 0.998, 12)
    assert distance.differs and distance.direction == "ours is better"
    assert ret.direction == "ours is better"
    assert Comparison("zero-shot", "x", 0.55, "src", 0.465, 0.423, 0.508, 12).direction == "ours is worse"
