"""The fine-tune guard (`guard: true`, not in the paper): its test by hand, then through adaptation on the bandit."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from rllib_conv.adaptation.fine_tune_guard import FineTuneGuard, measured_better
from rllib_conv.common.config_files import checked
from rllib_conv.pipelines.adapt import run_adaptation
from rllib_conv.pipelines.adapt_config import AdaptConfig


def test_measured_better_by_hand() -> None:
    # Means 0.75 and 0.25, sample variances 0.25 each: se = sqrt(0.25 / 4 + 0.25 / 4) = 0.3536,
    # so the difference 0.5 is 1.41 standard errors: above z = 1, not above z = 1.645.
    new, old = [1, 1, 1, 0], [0, 0, 1, 0]
    assert measured_better(new, old, z=1.0) and measured_better(new, old)  # the default margin is half an error
    assert not measured_better(new, old, z=1.645)
    assert not measured_better(old, new, z=0.0)  # lower is never better
    assert measured_better([1, 1], [0, 0]) and not measured_better([1, 1], [1, 1])  # no spread: any higher mean
    assert not measured_better([1], [0, 0]) and not measured_better([1, 1], [0])  # one return shows nothing


def test_the_guard_keeps_the_first_batch_as_the_prior_and_decides_on_the_latest() -> None:
    guard = FineTuneGuard(z=1.0)
    assert not guard.observe([])  # nothing finished: still no prior
    assert guard.prior is None
    assert not guard.observe([0, 0, 1, 0])  # the prior's own batch
    assert guard.prior == [0.0, 0.0, 1.0, 0.0]
    assert guard.observe([1, 1, 1, 0])  # 1.41 standard errors above it
    assert guard.observe([])  # an empty batch changes nothing
    assert not guard.observe([0, 1, 0, 0])  # no longer better: distrusted again
    assert guard.prior == [0.0, 0.0, 1.0, 0.0]


def test_a_guard_with_a_picked_head_is_refused() -> None:
    with pytest.raises(ValueError, match="guard: true .* head_init 'pick'"):
        AdaptConfig(runs=["x"], head_init="pick", guard=True)


def _curves(raw: dict, tmp_path: Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """The adaptation CSV of `raw` and its pack's own rows (which say whether the prior was kept)."""
    curves = run_adaptation(checked(raw, AdaptConfig), out=tmp_path, storage=tmp_path / "runs")
    (rows,) = [pd.read_csv(f) for f in (tmp_path / "runs" / f"adapt-{raw['name']}").glob("*/curves.csv")]
    return curves, rows


@pytest.mark.parametrize("ppo", [{}, {"entropy_coeff": 1.0, "lr": 0.01}], ids=["fine-tuning-pays", "fine-tuning-hurts"])
@pytest.mark.slow
def test_the_guarded_curve_is_the_prior_until_fine_tuning_is_measured_better(bandit_egos, tmp_path, ppo) -> None:
    trial = Path(bandit_egos["bandit-s2-hand"].path)
    common = {"runs": [str(trial)], "partners": ["hand-test-1"], "steps": 240, "seed": 3, "ppo": ppo}
    plain, _ = _curves({"name": "plain", **common}, tmp_path)
    guarded, rows = _curves({"name": "guarded", "guard": True, **common}, tmp_path)
    # Training is the same; only what is evaluated differs: the prior (the ego at step 0) or the adapting ego.
    start = plain["exact_return"].iloc[0]
    expected = [start if kept else value for kept, value in zip(rows["prior_kept"], plain["exact_return"])]
    assert guarded["exact_return"].tolist() == pytest.approx(expected, abs=1e-9)
    assert bool(rows["prior_kept"].iloc[0])  # nothing measured at step 0
    if not ppo:
        # PPO learns this partner's convention (0.75 -> ~1); its rollouts show it (here from the 9th update on), then it is kept.
        assert plain["exact_return"].iloc[-1] > start + 0.15
        assert not rows["prior_kept"].iloc[-3:].any()
        assert guarded["exact_return"].iloc[-1] == pytest.approx(plain["exact_return"].iloc[-1])
    else:
        # A large entropy bonus drives the ego towards uniform play: the plain curve falls, the guarded one stays at its start.
        assert plain["exact_return"].iloc[-1] < start - 0.1
        assert rows["prior_kept"].iloc[-3:].all()
        assert guarded["exact_return"].iloc[-1] == pytest.approx(start)
        assert guarded["exact_return"].mean() > plain["exact_return"].mean() + 0.05  # a higher AUC
