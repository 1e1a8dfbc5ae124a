"""build_report on the fixture (and on small hand-made folders): the computed numbers and verdicts in report.md."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pandas as pd
import pytest

from analysis.paper import LABEL_NAMES
from analysis.report import build_report
from analysis.report.sections.status import trained_steps
from analysis.report.verdicts import (
    CONTRADICTED,
    NOT_SHOWN,
    SUPPORTED,
    VERDICTS,
    ClaimCheck,
    Comparison,
    Difference,
    Judgement,
    all_hold,
    beats_all,
    beats_every,
    no_worse,
    no_worse_margin,
)
from analysis.summaries import uniform_prior_return

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
    assert {Path(x).stem for x in links} >= {
        "adapt_armsexp",
        "zeroshot",
        "marginals",
        "userstudy",
        "training_bandit",
        "selfplay",
        "crossplay_bandit-s2-hand__bandit-s2-hand",
    }
    for link in links:
        png = report.parent / link
        assert png.read_bytes()[:8] == PNG_MAGIC
        assert png.with_suffix(".pdf").is_file()


def test_every_figure_with_a_band_says_what_the_band_is(text: str) -> None:
    def caption(name: str) -> str:
        return text.split(f"![{name}](figures/{name}.png)")[1].split("\n\n")[1]

    for name in ("adapt_armsexp", "zeroshot", "marginals", "training_bandit"):
        assert caption(name).startswith("*") and "95% t-interval over seeds" in caption(name), name
        assert "n = 1 seed per method; no band where n = 1" in caption(name), name  # the fixture has one seed
    assert "(each seed averaged over its test partners first)" in caption("adapt_armsexp")
    assert "standard error of the share over the pairs (n = 23 pairs)" in caption("userstudy")
    assert (
        "the replicated unit is the training seed" in text and "A hierarchical bootstrap is not used" in text
    )  # the header says which interval


def test_status_names_the_env_steps_each_ego_trained_for(text: str) -> None:
    # The fixture's 4 trials each end their progress.csv at 2048 env steps.
    assert "| none | 4 | 2,048 |" in text
    curves = pd.DataFrame({"run": ["a", "a", "b", "b"], "steps": [0, 301_440, 0, 1_000_320]})
    assert trained_steps(curves) == "301,440–1,000,320"
    assert trained_steps(curves.iloc[:0]) == "—"


def test_zeroshot_numbers_and_flags(text: str) -> None:
    # ours λ=0.5 on Arms 1: one seed, exact returns 0.27873, 0.30279, 0.29955, 0.30089 with its 4 test partners
    # -> 0.29549 and no interval (the four partners share one trained ego); the paper's 0.99 is 0.695 away.
    assert "| Arms 1 | ours λ=0.5 | 0.99 | 0.295 (n=1, no interval) | **differs** (one seed): ours lower by 0.695 |" in text
    # BaselineModular: 0.14514, 0.15091, 0.11426, 0.10625 -> 0.12914, one seed.
    assert "| Arms 1 | BaselineModular | 0.3 | 0.129 (n=1, no interval) | **differs** (one seed): ours lower by 0.171 |" in text
    # Paired on the seed's four partners: 0.29549 - 0.12914 = +0.166, one seed: not shown.
    assert "| Arms 1 | not shown | ours λ=0.5 − BaselineModular +0.166 (n=1, no interval) |" in text


def test_adaptation_auc_row(text: str) -> None:
    # Exact returns at steps 0, 16, 32, 48, 64: 0.4647, 0.5509, 0.6729, 0.7732, 0.8366 -> AUC 0.660.
    assert (
        "| Arms 2 | ours λ=0.5 | 5 | 64 | 1 | 0.465 (n=1, no interval) | 0.837 (n=1, no interval) | 0.660 (n=1, no interval) "
        "| 0.195 (n=1, no interval) | exact |" in text  # gain over not adapting: 0.6597 - 0.4647
    )
    # BaselineAgg: 0.7218, 0.8645, 0.7068, 0.8681, 0.9621 -> 0.8247; 0.6597 - 0.8247 = -0.165 on one seed: not shown,
    # and the fixture has neither BaselineModular nor MAML, which the claim names.
    assert (
        "| Arms 2 | not shown (missing: BaselineModular, First-Order MAML) | AUC ours λ=0.5 − BaselineAgg -0.165 (n=1, no interval) |"
        in text
    )


@pytest.mark.parametrize(
    ("lo", "hi", "verdict"),
    [
        (0.004, 0.020, SUPPORTED),
        (-0.020, -0.004, CONTRADICTED),
        (-0.004, 0.020, NOT_SHOWN),  # the bandit Arms 3 case: a higher or lower mean inside an interval that holds 0
        (0.0, 0.02, NOT_SHOWN),  # "the whole interval above 0": touching 0 is not enough
        (0.1, 0.1, SUPPORTED),  # identical seeds: a zero-width interval
        (float("nan"), float("nan"), NOT_SHOWN),  # one seed
    ],
)
def test_a_claim_is_supported_only_when_the_whole_interval_is_above_zero(lo, hi, verdict) -> None:
    assert Difference("A", "B", (lo + hi) / 2 if hi == hi else 0.1, lo, hi, 3).verdict == verdict


@pytest.mark.parametrize(
    ("verdicts", "missing", "overall"),
    [
        ([SUPPORTED, SUPPORTED], (), SUPPORTED),
        ([SUPPORTED, NOT_SHOWN], (), NOT_SHOWN),
        ([NOT_SHOWN, CONTRADICTED, SUPPORTED], (), CONTRADICTED),
        ([], (), NOT_SHOWN),
        ([SUPPORTED], ("BaselineModular", "First-Order MAML"), NOT_SHOWN),  # the Hanabi 5-seed report: BaselineAgg alone
        ([SUPPORTED, CONTRADICTED], ("First-Order MAML",), CONTRADICTED),  # one loss refutes "beats every one"
        ([], ("BaselineAgg",), NOT_SHOWN),
    ],
)
def test_a_beats_every_b_needs_every_difference_and_every_b(verdicts, missing, overall) -> None:
    assert all_hold(verdicts, missing) == overall


@pytest.mark.parametrize(
    ("lo", "hi", "margin", "verdict"),
    [
        (-0.15, 0.30, 0.2, SUPPORTED),  # holds 0, but no lower than -margin
        (-0.50, 0.30, 0.2, NOT_SHOWN),  # holds 0 and reaches below -margin: the case the old rule called supported
        (-0.50, 0.30, 0.0, NOT_SHOWN),
        (0.01, 0.30, 0.0, SUPPORTED),  # margin 0: "no worse" is "above"
        (-0.50, -0.25, 0.2, CONTRADICTED),  # worse by more than the margin, wholly
        (-0.50, -0.10, 0.2, NOT_SHOWN),  # worse, but maybe by less than the margin
        (-0.20, 0.10, 0.2, NOT_SHOWN),  # touching -margin is not above it
        (float("nan"), float("nan"), 0.2, NOT_SHOWN),  # one seed
        (-0.10, 0.10, float("nan"), NOT_SHOWN),  # no margin known (a game without a maximum score)
    ],
)
def test_no_worse_is_judged_against_the_declared_margin(lo, hi, margin, verdict) -> None:
    assert no_worse(Difference("A", "B", 0.0, lo, hi, 3), margin) == verdict


def test_a_negative_margin_is_an_error() -> None:
    with pytest.raises(ValueError, match="no_worse_margin"):
        no_worse(Difference("A", "B", 0.0, -0.1, 0.1, 3), -0.2)


@pytest.mark.parametrize(
    ("plan", "margin"),
    [
        ({"game": "blocks", "no_worse_margin": 0.5}, 0.5),  # declared in the plan
        ({"game": "blocks", "no_worse_margin": 0}, 0.0),
        ({"game": "blocks"}, 0.2),  # default: 1% of 20
        ({"game": "hanabi"}, 0.05),
        ({"game": "bandit", "report": {"max_score": 3.0}}, 0.03),  # the game's own maximum, from plan.json
    ],
)
def test_the_no_worse_margin_comes_from_the_plan_or_the_games_maximum(plan, margin) -> None:
    assert no_worse_margin(plan) == pytest.approx(margin)
    assert math.isnan(no_worse_margin({"game": "unknown-game"}))


def test_beats_every_names_what_is_missing() -> None:
    # Two seeds x one partner: A is 1.0 above B on both seeds; C was never run.
    df = pd.DataFrame(
        [
            {"label": lab, "seed": s, "partner": "p", "auc": v + s}
            for s in (0, 1)
            for lab, v in (("modular-lam0.5", 2.0), ("agg", 1.0))
        ]
    )
    found = beats_every(df, "modular-lam0.5", ("agg", "maml"), "auc", ("partner",))
    assert (found.verdict, found.missing) == (NOT_SHOWN, ("First-Order MAML",))
    assert found.cell == "not shown (missing: First-Order MAML)"
    assert found.evidence == "ours λ=0.5 − BaselineAgg +1.000 [+1.000, +1.000] (n=2)"
    assert beats_every(df, "modular-lam0.5", ("agg",), "auc", ("partner",)).cell == SUPPORTED
    assert beats_every(df, "maml", ("agg",), "auc", ("partner",)) == Judgement(
        NOT_SHOWN, "nothing to compare", ("First-Order MAML",)
    )
    # The tuple form keeps a plain verdict and names the missing in its evidence.
    assert beats_all(df, "modular-lam0.5", ("agg", "maml"), "auc", ("partner",)) == (
        NOT_SHOWN,
        "missing: First-Order MAML; " + found.evidence,
    )


def test_a_claim_gets_one_of_three_verdicts() -> None:
    assert VERDICTS == ("supported", "not shown", "contradicted")
    with pytest.raises(ValueError, match="not one of"):
        ClaimCheck(claim=None, scope="x", verdict="supported (intervals overlap)", evidence="")  # type: ignore[arg-type]


def test_user_study_section(text: str) -> None:
    # Test-C - Test-B per pair: 11 pairs +1, 12 pairs 0: mean 0.4783, sd 0.5108, half-width t(0.975, 22) 2.0739 * 0.5108 / sqrt(23) = 0.2209.
    assert "| supported | Test-C 0.957, Test-B 0.478; Test-C − Test-B +0.478 [+0.257, +0.699] (n=23) |" in text
    assert "| Train-A | 22/23 = 0.957 ± 0.043 | 0.9545 ± 0.044 | 21/22 = 0.9545 ± 0.0444 | no | yes |" in text
    assert "| Test-A | 21/23 = 0.913 ± 0.060 | 1 ± 0 | 22/22 = 1.0000 ± 0.0000 | no | yes |" in text
    assert "Under it the table gives every bar and error bar of the paper's figure" in text
    assert "user study: the numbers computed from the appendix table differ from the paper's figure" in text


def test_differences_and_absences_are_explained(text: str) -> None:
    summary = text.split("## Where ours differs from the paper, and why")[1].split("## Adapting")[0]
    assert "quick plan" in summary
    assert "ours 0.295 (n=1, no interval), ours is worse." in summary  # zero-shot Arms 1 vs the paper's 0.99
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
    # Seed means over the 4 partners 0.875, 0.885, 0.895: mean 0.885, sd 0.01, half-width 4.3027 * 0.01 / sqrt(3) = 0.0248
    # (n = 3 seeds, not the 12 curves): 0.89 is inside.
    assert "| Arms 2 | ours λ=0.5 | 0.89 | 0.885 [0.860, 0.910] (n=3) | paper inside our 95% CI |" in text
    # All twelve 0.2: a zero-width interval, and the paper's 0.55 outside it with no cause visible in the data.
    assert "| Arms 2 | BaselineModular | 0.55 | 0.200 [0.200, 0.200] (n=3) | **differs**: ours lower by 0.350 |" in text
    assert "(n=3), ours is worse. Why: no cause visible in the data" in text
    # Paired per seed: 0.675, 0.685, 0.695 -> 0.685 with the same half-width 0.0248: supported.
    assert "| Arms 2 | supported | ours λ=0.5 − BaselineModular +0.685 [+0.660, +0.710] (n=3) |" in text
    assert "stage(s) not finished: selfplay, train, adapt, zeroshot, marginals" in text
    assert "No adaptation curves" in text and "No marginals.csv found." in text


def test_methods_beyond_the_paper_are_listed_but_left_out_of_its_claims(tmp_path: Path) -> None:
    game = tmp_path / "repro" / "blocks"
    game.mkdir(parents=True)
    (game / "plan.json").write_text('{"game": "blocks", "seeds": [0, 1, 2], "quick": false}')
    header = "run,env,env_config,population,method,lam,z_dim,seed,distance,distance_all_states,states,experiment"
    rows = [header]
    # Ours 0.10, BaselineAgg 1.0, ours with the head penalty 0.02: the closest, but not a method of the paper.
    for label, method, distance in (
        ("modular-lam0.5", "modular", 0.10),
        ("agg", "agg", 1.0),
        ("modular-lam0.5-hl0.01", "modular", 0.02),
    ):
        for s in range(3):
            exp = f"blocks-perm__{label}"
            rows.append(f"runs/{exp}/T{s},blocks,{{}},blocks-perm,{method},0.5,80,{s},{distance},{distance},10,{exp}")
    (game / "marginals.csv").write_text("\n".join(rows) + "\n")
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    assert "| Blocks (hand-designed) | ours λ=0.5 + head penalty | — | 0.020 [0.020, 0.020] (n=3) |" in text
    # Distances paired on the seed: BaselineAgg - ours = 0.9 on each of the 3 seeds.
    assert "| Blocks (hand-designed) | supported | distance BaselineAgg − ours λ=0.5 +0.900 [+0.900, +0.900] (n=3) |" in text
    # The variant is judged against every baseline with a task output: First-Order MAML was not run, so not shown.
    assert (
        "| Blocks (hand-designed) | ours λ=0.5 + head penalty | not shown (missing: First-Order MAML) | "
        "BaselineAgg − ours λ=0.5 + head penalty +0.980 [+0.980, +0.980] (n=3) |"
    ) in text
    assert "ours λ=0.5 + head penalty (`modular-lam0.5-hl0.01`) is not in the paper" in text


def test_extensions_are_judged_against_the_baselines_apart_from_the_papers_claim(tmp_path: Path) -> None:
    game = tmp_path / "repro" / "blocks"
    (game / "adaptation").mkdir(parents=True)
    (game / "plan.json").write_text('{"game": "blocks", "seeds": [0, 1, 2], "quick": false}')
    # Flat curves (AUC = the return), three seeds x two partners per method: value - 0.1 with sp06, value + 0.1 with sp07,
    # so each seed's mean is the value and every interval has zero width.
    methods = (
        ("modular-lam0.5", "modular", 14.5),
        ("agg", "agg", 15.0),
        ("oracle", "oracle", 15.5),
        ("modular-lam0.5-pick", "modular", 16.0),
    )
    for label, method, value in methods:
        rows = ["run,method,lam,z_dim,seed,partner,steps,mean_return,stderr,exact_return"]
        for i in range(6):
            r = value + (0.1 if i % 2 else -0.1)
            rows += [
                f"runs/blocks-selfplay__{label}/T{i // 2},{method},0.5,80,{i // 2},sp0{6 + i % 2},{step},{r},0.1,"
                for step in (0, 640)
            ]
        (game / "adaptation" / f"blocks-selfplay__{label}.csv").write_text("\n".join(rows) + "\n")
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    # Losing to one baseline refutes "beats all three" whatever is missing; winning against the one present shows nothing.
    assert (
        "| Blocks (self-play) | contradicted (missing: BaselineModular, First-Order MAML) | AUC ours λ=0.5 − BaselineAgg -0.50 [-0.50, -0.50] (n=3) |"
        in text
    )
    assert (
        "| Blocks (self-play) | ours λ=0.5, adapting from a picked head | not shown (missing: BaselineModular, First-Order MAML) | "
        "ours λ=0.5, adapting from a picked head − BaselineAgg +1.00 [+1.00, +1.00] (n=3) |"
    ) in text
    # The oracle claim is about the paper's methods: the picked-head variant above it does not count.
    assert (
        "| Blocks (self-play) | supported | AUC oracle marginals − ours λ=0.5 +1.00 [+1.00, +1.00] (n=3); oracle marginals − BaselineAgg +0.50 [+0.50, +0.50] (n=3) |"
        in text
    )
    assert "(`modular-lam0.5-pick`) is not in the paper" in text
    assert "| Blocks (self-play) | BaselineAgg | 2 | 640 | 2 | 15.00 [15.00, 15.00] (n=3) |" in text  # 2 test partners, 3 seeds


def write_bandit_adaptation(root: Path) -> None:
    """Flat adaptation curves (AUC = the value) of a bandit reproduction: 3 seeds x 2 test partners per method.

    Arms 2: seed levels 0.70, 0.80, 0.90 (partners at -0.01 and +0.01). Ours λ=0.5 is BaselineAgg + 0.02 on every
    (seed, partner); ours minus MAML is +0.05, -0.01, +0.02 by seed; λ=0.3 is BaselineAgg + 0.10. Arms 3: ours λ=0.5
    0.10 below its Arms 2 values, and no baseline.
    """
    game = root / "bandit"
    (game / "adaptation").mkdir(parents=True)
    (game / "plan.json").write_text('{"game": "bandit", "seeds": [0, 1, 2], "quick": false}')
    levels = (0.70, 0.80, 0.90)
    methods = {
        ("bandit-s2-hand", "agg", "agg"): (0.0, 0.0, 0.0),
        ("bandit-s2-hand", "modular-lam0.5", "modular"): (0.02, 0.02, 0.02),
        ("bandit-s2-hand", "maml", "maml"): (-0.03, 0.03, 0.0),
        ("bandit-s2-hand", "modular-lam0.3", "modular"): (0.10, 0.10, 0.10),
        ("bandit-s3-hand", "modular-lam0.5", "modular"): (-0.08, -0.08, -0.08),
    }
    for (population, label, method), offsets in methods.items():
        rows = ["run,method,lam,z_dim,seed,partner,steps,mean_return,stderr,exact_return"]
        for seed, (level, offset) in enumerate(zip(levels, offsets)):
            for k, spread in enumerate((-0.01, 0.01)):
                v = level + offset + spread
                rows += [
                    f"runs/{population}__{label}/T{seed},{method},0.5,30,{seed},hand-test-{k},{step},{v},0.01,{v}"
                    for step in (0, 16)
                ]
        (game / "adaptation" / f"{population}__{label}.csv").write_text("\n".join(rows) + "\n")


def test_adaptation_claims_are_paired_over_seeds_on_the_papers_method(tmp_path: Path) -> None:
    write_bandit_adaptation(tmp_path / "repro")
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    # Seed-level AUC of ours: seed means 0.72, 0.82, 0.92 -> 0.820, half-width 4.3027 * 0.1 / sqrt(3) = 0.2484.
    assert (
        "| Arms 2 | ours λ=0.5 | 2 | 16 | 2 | 0.820 [0.572, 1.068] (n=3) | 0.820 [0.572, 1.068] (n=3) | 0.820 [0.572, 1.068] (n=3) "
        "| 0.000 [0.000, 0.000] (n=3) | exact |" in text  # flat curves: adapting gained nothing over step 0
    )
    # Ours - BaselineAgg: +0.02 on every unit (supported although the seed-level intervals overlap widely);
    # ours - MAML by seed +0.05, -0.01, +0.02: mean 0.02, sd 0.03, half-width 4.3027 * 0.03 / sqrt(3) = 0.0745: not shown.
    # BaselineModular was not run: the claim names it, so it is not shown whatever the other two say.
    assert (
        "| Arms 2 | not shown (missing: BaselineModular) | AUC ours λ=0.5 − BaselineAgg +0.020 [+0.020, +0.020] (n=3); "
        "ours λ=0.5 − First-Order MAML +0.020 [-0.055, +0.095] (n=3) |"
    ) in text
    # λ=0.3 beats both baselines present but is a variant: it has its own table, does not make the paper's claim supported,
    # and is not shown either, BaselineModular being missing.
    assert (
        "| Arms 2 | ours λ=0.3 | not shown (missing: BaselineModular) | ours λ=0.3 − BaselineAgg +0.100 [+0.100, +0.100] (n=3); ours λ=0.3 − First-Order MAML +0.100"
        in text
    )
    assert "| Arms 3 | not shown (missing: BaselineAgg, BaselineModular, First-Order MAML) | AUC nothing to compare |" in text
    # Arms 2 against Arms 3 share no partners: Welch over seed means 0.72, 0.82, 0.92 and 0.62, 0.72, 0.82:
    # difference 0.10, se sqrt(2 * 0.01 / 3) = 0.0816, df 4, t 2.7764 -> half-width 0.2267. Arms 4 (named by the claim) is absent.
    assert (
        "| ours λ=0.5, hand partners | not shown (missing: Arms 4) | AUC Arms 2 − Arms 3 +0.100 [-0.127, +0.327] (n=3) |" in text
    )
    summary = text.split("## Where ours differs from the paper, and why")[1].split("## Adapting")[0]
    # The three above, not shown, and the user study's two claims, supported: the tallies count exactly the verdicts.
    assert "Claims checked: 5 (2 supported, 3 not shown, 0 contradicted)" in summary


def test_lists_of_method_names_read_unambiguously() -> None:
    # The report joins names with "; " (e.g. "have ours λ=0.5, low-dim z; oracle marginals"): no name may hold one.
    assert any("," in name for name in LABEL_NAMES.values())
    assert not [name for name in LABEL_NAMES.values() if ";" in name]


def test_the_convention_posterior_is_judged_against_its_own_targets(tmp_path: Path) -> None:
    write_bandit_adaptation(tmp_path / "repro")
    game = tmp_path / "repro" / "bandit"
    # Arms 2: the posterior returns exactly the uniform-prior adapter's expectation at steps 0 and 16 on every unit
    # (0.75, and 0.5 + 0.5 * (1 - 0.75**16 / 2) = 0.99749: AUC 0.874); Arms 3: 0.02 below its uniform-prior returns.
    for population, symmetric, offset in (("bandit-s2-hand", 2, 0.0), ("bandit-s3-hand", 3, -0.02)):
        rows = ["run,method,lam,z_dim,seed,partner,steps,mean_return,stderr,exact_return"]
        for seed in range(3):
            for k in range(2):
                for step in (0, 16):
                    v = uniform_prior_return(4, symmetric, step) + offset
                    rows.append(
                        f"runs/{population}__beyond-posterior/T{seed},modular,0.5,30,{seed},hand-test-{k},{step},{v},0.01,{v}"
                    )
        (game / "adaptation" / f"{population}__beyond-posterior.csv").write_text("\n".join(rows) + "\n")
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    beyond = text.split("## Beyond the paper: the convention-posterior adapter")[1]
    name = "convention posterior (beyond the paper)"
    assert (
        f"| Arms 2 | {name} | AUC within 0.01 of the uniform-prior adapter | supported | {name} − uniform-prior adapter (0.874) +0.000 [+0.000, +0.000] (n=3) |"
        in beyond
    )
    assert (
        f"| Arms 3 | {name} | AUC within 0.01 of the uniform-prior adapter | contradicted | {name} − uniform-prior adapter"
        in beyond
    )
    assert "![beyond_posterior](figures/beyond_posterior.png)" in beyond
    # Each row says what its adapter read besides the trained ego: the posterior far more than the paper's PPO.
    assert re.search(
        rf"\| Arms 2 \| {re.escape(name)} \| [^|]+ \| [^|]+ \| partner actions, partner situation, returns, training policies, "
        r"situation keys, game model \|",
        beyond,
    )
    assert re.search(r"\| Arms 2 \| ours λ=0\.5 \| [^|]+ \| [^|]+ \| returns \|", beyond)
    assert "beyond-guarded" not in beyond  # not run here
    # Not a claim of the paper: the tallies are those without it.
    assert "Claims checked: 5 (2 supported, 3 not shown, 0 contradicted)" in text


def test_both_adapters_beyond_the_paper_are_judged_on_hanabi(tmp_path: Path) -> None:
    game = tmp_path / "repro" / "hanabi"
    (game / "adaptation").mkdir(parents=True)
    (game / "plan.json").write_text('{"game": "hanabi", "seeds": [0, 1, 2], "quick": false}')
    # Flat curves over steps 0 and 640 (AUC = the value), two partners at value -/+ 0.1: each seed's mean is the value.
    # Ours 3.6 + 0.01 * seed, BaselineAgg 3.5, the posterior as ours, the guarded posterior 3.75 on every seed.
    values = {
        "modular-lam0.5": lambda s: 3.6 + 0.01 * s,
        "agg": lambda s: 3.5,
        "beyond-posterior": lambda s: 3.6 + 0.01 * s,
        "beyond-guarded": lambda s: 3.75,
    }
    methods = {"modular-lam0.5": "modular", "agg": "agg", "beyond-posterior": "modular", "beyond-guarded": "modular"}
    for label, value in values.items():
        rows = ["run,method,lam,z_dim,seed,partner,steps,mean_return,stderr,exact_return"]
        for seed in range(3):
            for k, shift in ((6, -0.1), (7, 0.1)):
                for step in (0, 640):
                    rows.append(
                        f"runs/hanabi-selfplay__{label}/T{seed},{methods[label]},0.5,500,{seed},sp0{k},{step},{value(seed) + shift},0.01,"
                    )
        (game / "adaptation" / f"hanabi-selfplay__{label}.csv").write_text("\n".join(rows) + "\n")
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    beyond = text.split("## Beyond the paper: the convention-posterior adapter")[1]
    assert "`beyond-guarded` is the same adapter with its fine-tuning guarded" in beyond
    posterior, guarded = "convention posterior (beyond the paper)", "guarded convention posterior (beyond the paper)"
    # The posterior equals ours on every seed: its difference is exactly 0, so "above" is not shown;
    # the guarded one is above ours by 0.15, 0.14, 0.13 (mean 0.14) and above BaselineAgg by 0.25 on every seed.
    assert f"| Hanabi (self-play) | {posterior} | above ours λ=0.5 and BaselineAgg | not shown |" in beyond
    assert f"| Hanabi (self-play) | {guarded} | above ours λ=0.5 and BaselineAgg | supported |" in beyond
    assert f"{guarded} − BaselineAgg +0.250 [+0.250, +0.250] (n=3)" in beyond
    # Both are named as not in the paper where the report says what it found.
    found = text.split("## What was found")[1].split("## Beyond the paper")[0]
    assert f"{guarded} (`beyond-guarded`) is not in the paper" in found
    assert f"{posterior} (`beyond-posterior`) is not in the paper" in found


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


def test_hanabi_is_judged_against_every_baseline_present(tmp_path: Path) -> None:
    game = tmp_path / "repro" / "hanabi"
    (game / "adaptation").mkdir(parents=True)
    (game / "plan.json").write_text('{"game": "hanabi", "seeds": [0, 1], "quick": false}')
    # Two seeds x one partner, flat curves: ours 3.0 and 3.2, each baseline 1.0 lower on both seeds.
    for label, method, drop in (
        ("modular-lam0.5", "modular", 0.0),
        ("agg", "agg", 1.0),
        ("no_task_logits", "no_task_logits", 1.0),
        ("maml", "maml", 1.0),
    ):
        rows = ["run,method,lam,z_dim,seed,partner,steps,mean_return,stderr,exact_return"]
        rows += [
            f"runs/hanabi-selfplay__{label}/T{s},{method},0.5,,{s},sp04,{step},{3.0 + 0.2 * s - drop},0.1,"
            for s in (0, 1)
            for step in (0, 1280)
        ]
        (game / "adaptation" / f"hanabi-selfplay__{label}.csv").write_text("\n".join(rows) + "\n")
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    assert (
        "| Hanabi (self-play) | supported | AUC ours λ=0.5 − BaselineAgg +1.000 [+1.000, +1.000] (n=2); "
        "ours λ=0.5 − BaselineModular +1.000 [+1.000, +1.000] (n=2); ours λ=0.5 − First-Order MAML +1.000 [+1.000, +1.000] (n=2) |"
    ) in text
    assert "![adapt_blockshanabiexp](figures/adapt_blockshanabiexp.png)" in text


def write_flat_curves(game_dir: Path, population: str, values: dict[str, float], seeds: int = 3, plan: str = "") -> None:
    """Flat adaptation curves (AUC = the value) of `population`: per label a value, + 0.1 * seed, two partners at -/+ 0.1.

    Every label's seed means are value + 0.1 * seed, so each paired difference is the same on every seed (zero width).
    `plan` adds keys to plan.json (e.g. `"no_worse_margin": 0.5`).
    """
    (game_dir / "adaptation").mkdir(parents=True, exist_ok=True)
    game = game_dir.name
    extra = f", {plan}" if plan else ""
    (game_dir / "plan.json").write_text(f'{{"game": "{game}", "seeds": {list(range(seeds))}, "quick": false{extra}}}')
    for label, value in values.items():
        method = label if label in ("agg", "maml", "no_task_logits") else "modular"
        rows = ["run,method,lam,z_dim,seed,partner,steps,mean_return,stderr,exact_return"]
        for seed in range(seeds):
            for k, shift in ((6, -0.1), (7, 0.1)):
                rows += [
                    f"runs/{population}__{label}/T{seed},{method},0.5,,{seed},sp0{k},{step},{value + 0.1 * seed + shift},0.01,"
                    for step in (0, 640)
                ]
        (game_dir / "adaptation" / f"{population}__{label}.csv").write_text("\n".join(rows) + "\n")


def test_a_claim_over_three_baselines_with_two_missing_is_not_shown(tmp_path: Path) -> None:
    # The Hanabi 5-seed report's case: ours and BaselineAgg alone, ours 0.175 above it on every seed.
    write_flat_curves(tmp_path / "repro" / "hanabi", "hanabi-selfplay", {"modular-lam0.5": 3.624, "agg": 3.449}, seeds=5)
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    assert (
        "| Hanabi (self-play) | not shown (missing: BaselineModular, First-Order MAML) | AUC ours λ=0.5 − BaselineAgg +0.175 [+0.175, +0.175] (n=5) |"
        in text
    )
    summary = text.split("## Where ours differs from the paper, and why")[1].split("## Adapting")[0]
    assert "Claims checked: 3 (2 supported, 1 not shown, 0 contradicted)" in summary  # with the user study's two
    assert "ours λ=0.5 − BaselineAgg +0.175 [+0.175, +0.175] (n=5); missing: BaselineModular, First-Order MAML. Why:" in summary


def test_a_claim_with_the_first_baseline_missing_is_not_shown(tmp_path: Path) -> None:
    # The Hanabi 5-seed baselines report's case: BaselineModular and MAML, no BaselineAgg.
    write_flat_curves(
        tmp_path / "repro" / "hanabi", "hanabi-selfplay", {"modular-lam0.5": 3.6, "no_task_logits": 2.8, "maml": 3.4}, seeds=5
    )
    text = build_report(tmp_path / "repro", tmp_path / "out").read_text()
    assert (
        "| Hanabi (self-play) | not shown (missing: BaselineAgg) | AUC ours λ=0.5 − BaselineModular +0.800 [+0.800, +0.800] (n=5); "
        in text
    )


def test_no_worse_uses_the_margin_the_plan_declares(tmp_path: Path) -> None:
    # Blocks, hand-designed partners: the posterior − ours is -0.5, 0.0, +0.5 by seed (mean 0, sd 0.5,
    # half-width 4.3027 * 0.5 / sqrt(3) = 1.242): an interval that holds 0 and reaches -1.24.
    def write(root: Path, plan: str) -> str:
        game = root / "blocks"
        write_flat_curves(game, "blocks-perm", {"modular-lam0.5": 18.0}, plan=plan)
        rows = ["run,method,lam,z_dim,seed,partner,steps,mean_return,stderr,exact_return"]
        for seed, offset in enumerate((-0.5, 0.0, 0.5)):
            for k, shift in ((6, -0.1), (7, 0.1)):
                rows += [
                    f"runs/blocks-perm__beyond-posterior/T{seed},modular,0.5,,{seed},sp0{k},{step},{18.0 + 0.1 * seed + offset + shift},0.01,"
                    for step in (0, 640)
                ]
        (game / "adaptation" / "blocks-perm__beyond-posterior.csv").write_text("\n".join(rows) + "\n")
        return build_report(root, root / "out").read_text().split("### Targets")[1]

    name = "convention posterior (beyond the paper)"
    evidence = f"{name} − ours λ=0.5 +0.00 [-1.24, +1.24] (n=3)"
    # The default margin, 1% of 20: -1.24 is below -0.2, so "no worse" is not shown (the old rule said supported).
    assert (
        f"| Blocks (hand-designed) | {name} | no worse than ours λ=0.5 by more than 0.2 (the plan's margin) | not shown | {evidence} |"
        in write(tmp_path / "a", "")
    )
    # A margin of 1.5 declared in the plan: the whole interval is above -1.5.
    assert (
        f"| Blocks (hand-designed) | {name} | no worse than ours λ=0.5 by more than 1.5 (the plan's margin) | supported | {evidence} |"
        in write(tmp_path / "b", '"no_worse_margin": 1.5')
    )


def test_a_target_over_two_methods_with_one_missing_is_not_shown(tmp_path: Path) -> None:
    # Hanabi: the guarded posterior is 0.3 above ours on every seed, but BaselineAgg (named by the target) was not run.
    write_flat_curves(tmp_path / "repro" / "hanabi", "hanabi-selfplay", {"modular-lam0.5": 3.6, "beyond-guarded": 3.9})
    beyond = build_report(tmp_path / "repro", tmp_path / "out").read_text().split("### Targets")[1]
    guarded = "guarded convention posterior (beyond the paper)"
    assert (
        f"| Hanabi (self-play) | {guarded} | above ours λ=0.5 and BaselineAgg | not shown (missing: BaselineAgg) | {guarded} − ours λ=0.5 +0.300 [+0.300, +0.300] (n=3) |"
        in beyond
    )


@pytest.mark.parametrize(
    ("mean", "lo", "hi", "n", "status", "verdict"),
    [
        (0.88, 0.86, 0.90, 3, "inside", "paper inside our 95% CI"),
        (0.80, 0.78, 0.886, 3, "inside", "paper inside our 95% CI"),  # 0.89 printed: widened by 0.005, 0.886 + 0.005 reaches it
        (0.80, 0.78, 0.88, 3, "outside", "**differs**: ours lower by 0.090"),
        (0.95, float("nan"), float("nan"), 1, "no interval", "close (one seed): ours higher by 0.060"),
        (0.70, float("nan"), float("nan"), 1, "no interval", "**differs** (one seed): ours lower by 0.190"),  # more than 0.1 away
        (float("nan"), float("nan"), float("nan"), 0, "not run", "not run"),
    ],
)
def test_a_paper_number_against_ours_known_answers(mean, lo, hi, n, status, verdict) -> None:
    c = Comparison("zero-shot", "Arms 2, ours", 0.89, "src", mean, lo, hi, n)
    assert (c.status, c.verdict) == (status, verdict)
