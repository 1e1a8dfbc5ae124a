"""`rllib-conv reproduce`: plans, narrowing them, and a small end-to-end run that builds the report."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
import yaml

from rllib_conv import partners
from rllib_conv.cli import main
from rllib_conv.common.resources import config_file
from rllib_conv.common.run_folders import CONFIG_FILE, EVAL_FILE, MARGINALS_FILE, read_marker
from rllib_conv.partners.overcooked import proxies_folder
from rllib_conv.pipelines import human_proxies
from rllib_conv.pipelines.plans import narrow, plan_for
from rllib_conv.pipelines.reproduce import Reproduction
from rllib_conv.training.behaviour_cloning import BCSettings


def test_narrow_keeps_the_named_populations_and_methods() -> None:
    plan = narrow(plan_for("bandit", seeds=3), ["bandit-s2-hand", "bandit-s1-hand", "bandit-s3-selfplay"], ["agg"])
    assert list(plan.populations) == ["bandit-s2-hand"]
    assert [m.label for m in plan.populations["bandit-s2-hand"]] == ["modular-lam0.5", "agg"]  # modular-lam0.5 always kept
    # A self-play entry of three populations is named by its entry name: all three are kept.
    assert [sp["name"] for sp in plan.selfplay] == [f"bandit-s3-selfplay-p{p}" for p in range(3)]
    assert plan.population_groups == {"bandit-s3-selfplay": [f"bandit-s3-selfplay-p{p}" for p in range(3)]}
    assert plan.zeroshot_populations == ["bandit-s1-hand", "bandit-s2-hand"]  # s3 not named: dropped
    assert [m.label for m in plan.selfplay_methods] == ["modular-lam0.5", "agg"]


def test_blocks_plan_adds_ours_with_the_head_penalty() -> None:
    plan = plan_for("blocks")
    assert [m.label for m in plan.zeroshot_methods] == ["modular-lam0.5", "no_task_logits", "modular-lam0.5-hl0.01"]
    assert [m.label for m in plan_for("bandit", seeds=3).zeroshot_methods] == ["modular-lam0.5", "no_task_logits"]
    assert [m.label for m in plan.selfplay_methods] == [
        "modular-lam0.5",
        "agg",
        "no_task_logits",
        "maml",
        "modular-lam0.5-hl0.01",
    ]
    penalised = next(m for m in plan.populations["blocks-perm"] if m.label == "modular-lam0.5-hl0.01")
    assert penalised.settings == {"method": "modular", "lam": 0.5, "head_l2": 0.01}
    narrowed = Reproduction(narrow(plan_for("blocks"), ["blocks-perm"], ["agg"]), Path("unused"))
    assert [m.label for _, m in narrowed.trained()] == ["modular-lam0.5", "agg"]
    # Zero-shot compares its methods with each other: --methods does not narrow them.
    assert narrowed.stage_experiments("zeroshot") == [
        f"blocks-perm__{m}" for m in ("modular-lam0.5", "no_task_logits", "modular-lam0.5-hl0.01")
    ]


def test_hanabi_plan_compares_ours_with_every_baseline_the_other_games_have() -> None:
    plan = plan_for("hanabi")
    assert [m.label for m in plan.selfplay_methods] == ["modular-lam0.5", "agg", "no_task_logits", "maml"]
    assert {m.label: m.settings for m in plan.selfplay_methods}["maml"] == {"method": "maml"}


def test_blocks_plan_adapts_ours_from_a_picked_head_and_by_the_plain_and_guarded_convention_posterior_too() -> None:
    plan = plan_for("blocks")
    assert [(v.label, v.base.label, v.settings) for v in plan.adapt_variants] == [
        ("scratch", "modular-lam0.5", {"method": "scratch"}),
        ("modular-lam0.5-pick", "modular-lam0.5", {"head_init": "pick"}),
        ("modular-lam0.5-hl0.01-pick", "modular-lam0.5-hl0.01", {"head_init": "pick"}),
        ("beyond-posterior", "modular-lam0.5", {"head_init": "posterior"}),
        ("beyond-guarded", "modular-lam0.5", {"head_init": "posterior", "guard": True}),
        ("control-counts-planner", "modular-lam0.5", {"head_init": "counts-planner"}),
        ("control-prior-planner", "modular-lam0.5", {"head_init": "prior-planner"}),
    ]
    # The posterior and the guarded posterior run where the partner sees nothing the ego does not (not on Hanabi,
    # which guards the paper's adapter instead); picking only on blocks.
    assert [(v.label, v.settings) for v in plan_for("bandit", seeds=3).adapt_variants] == [
        ("scratch", {"method": "scratch"}),
        ("beyond-posterior", {"head_init": "posterior"}),
        ("beyond-guarded", {"head_init": "posterior", "guard": True}),
        ("control-lookup", {"head_init": "lookup"}),
    ]
    assert [(v.label, v.settings) for v in plan_for("hanabi").adapt_variants][1:] == [("modular-lam0.5-guarded", {"guard": True})]
    # Adapt-only variants train nothing; each runs where its base egos are in the (narrowed) plan.
    narrowed = Reproduction(narrow(plan, ["blocks-perm", "blocks-selfplay-p1"], ["agg"]), Path("unused"))
    trained = [f"{p}__{m}" for p in ("blocks-perm", "blocks-selfplay-p1") for m in ("modular-lam0.5", "agg")]
    assert narrowed.stage_experiments("adapt") == [
        *trained,
        *(
            f"{p}__{v}"
            for p in ("blocks-perm", "blocks-selfplay-p1")
            for v in (
                "scratch",
                "modular-lam0.5-pick",
                "beyond-posterior",
                "beyond-guarded",
                "control-counts-planner",
                "control-prior-planner",
            )
        ),
    ]
    full = Reproduction(plan_for("blocks"), Path("unused")).stage_experiments("adapt")
    assert "blocks-selfplay-p2__modular-lam0.5-hl0.01-pick" in full and "blocks-perm__modular-lam0.5-hl0.01-pick" in full


@pytest.mark.parametrize(
    ("populations", "methods", "match"),
    [
        (["bandit-s9-hand"], None, r"--populations: \['bandit-s9-hand'\] not in the bandit plan; choose from"),
        (None, ["reptile"], r"--methods: \['reptile'\] not in the bandit plan"),
    ],
)
def test_narrow_rejects_unknown_names(populations, methods, match) -> None:
    with pytest.raises(ValueError, match=match):
        narrow(plan_for("bandit", seeds=3), populations, methods)


def _train_only(monkeypatch, calls: list[str]) -> None:
    """Reproductions whose only stage is a stand-in `train` that records each call."""
    monkeypatch.setattr(Reproduction, "stages", lambda self: [("train", lambda: calls.append(self.plan.game))])


def test_egos_adapt_to_every_held_out_partner_and_with_several_partner_seats_to_every_team_of_them() -> None:
    bandit = Reproduction(plan_for("bandit"), Path("unused"))
    assert bandit.adapt_partners("bandit-s2-hand") == [e.name for e in partners.get("bandit-s2-hand").entries("test")]
    lbf = Reproduction(plan_for("lbf"), Path("unused"))
    assert lbf.adapt_partners("lbf-heuristics") == ["H3+H3", "H3+H4", "H4+H3", "H4+H4"]
    assert Reproduction(plan_for("lbf", quick=True), Path("unused")).adapt_partners("lbf-heuristics") == ["H3+H3"]


@pytest.mark.parametrize(
    ("evaluate", "message"),
    [
        ({"bandit-s9-hand": ["heldout"]}, r"full.evaluate: \['bandit-s9-hand'\] not defined"),
        ({"bandit-s3-hand": ["heldout"]}, r"evaluate.bandit-s3-hand: heldout: the set is for bandit \{'symmetric': 2\}"),
        ({"bandit-s2-hand": ["test"]}, r"full.evaluate.bandit-s2-hand.0: Input should be 'heldout' or 'validation'"),
    ],
)
def test_a_plan_that_evaluates_what_it_does_not_train_or_what_cannot_meet_the_set_is_refused(tmp_path, evaluate, message) -> None:
    raw = yaml.safe_load(config_file("plan_bandit.yaml").read_text())
    raw["full"]["evaluate"] = evaluate
    plan = tmp_path / "plan.yaml"
    plan.write_text(yaml.safe_dump(raw))
    with pytest.raises(ValueError, match=message):
        plan_for("bandit", path=plan)


def test_a_stage_reruns_only_when_the_plan_asks_for_more_than_its_marker_covers(tmp_path, monkeypatch) -> None:
    calls: list[str] = []
    _train_only(monkeypatch, calls)
    logs: list[str] = []
    narrowed = narrow(plan_for("bandit", seeds=3), ["bandit-s2-hand"], ["agg"])
    Reproduction(narrowed, tmp_path, log=logs.append).run()
    seconds, covered = read_marker(tmp_path / "train.done")
    # Zero-shot's own egos (bandit-s2-hand is a zero-shot population, no_task_logits a zero-shot method) train here too.
    trained = ["modular-lam0.5", "agg", "no_task_logits"]
    assert covered == [f"bandit-s2-hand__{m} seeds=0,1,2 steps=10000" for m in trained] and seconds >= 0
    assert json.loads((tmp_path / "plan.json").read_text())["items"] == {
        "train": covered
    }  # what a report checks the marker against

    Reproduction(narrow(plan_for("bandit", seeds=3), ["bandit-s2-hand"], ["agg"]), tmp_path, log=logs.append).run()
    assert len(calls) == 1 and logs[-1] == "[bandit] train: done before, skipped"

    Reproduction(narrow(plan_for("bandit", seeds=3), ["bandit-s2-hand"], ["maml"]), tmp_path, log=logs.append).run()
    assert len(calls) == 2 and "not covered before: bandit-s2-hand__maml seeds=0,1,2 steps=10000)" in logs[-2]
    assert read_marker(tmp_path / "train.done")[1][-1] == "bandit-s2-hand__maml seeds=0,1,2 steps=10000"

    Reproduction(narrow(plan_for("bandit", seeds=4), ["bandit-s2-hand"], ["agg"]), tmp_path, log=logs.append).run()
    assert len(calls) == 3  # a fourth seed is more than the marker covers


def test_egos_train_for_the_papers_budget_unless_train_steps_sets_another(tmp_path, monkeypatch) -> None:
    default = Reproduction(narrow(plan_for("blocks"), ["blocks-perm"], ["agg"]), tmp_path)
    assert "run" not in default.experiment("blocks-perm", default.plan.paper_method)  # the config default: the paper's 1M steps
    trained = ("modular-lam0.5", "agg", "no_task_logits", "modular-lam0.5-hl0.01")  # the zero-shot methods train too
    assert default.stage_items("train") == [f"blocks-perm__{m} seeds=0,1,2 steps=1000000" for m in trained]

    bandit = Reproduction(narrow(plan_for("bandit", seeds=3), ["bandit-s2-hand", "bandit-user-study"], ["agg"]), tmp_path)
    assert [i.rsplit(" ", 1)[1] for i in bandit.stage_items("train")] == ["steps=10000"] * 2 + ["steps=40000"] * 2 + [
        "steps=10000"
    ]  # the user-study override

    short = Reproduction(
        narrow(plan_for("bandit", seeds=3, train_steps=500), ["bandit-s2-hand", "bandit-user-study"], ["agg"]), tmp_path
    )
    assert all(short.experiment(p, m)["run"]["timesteps"] == 500 for p, m in short.trained())  # over the population override too
    assert short.experiment("bandit-user-study", short.plan.paper_method)["ppo"] == {
        "rollout_per_partner": 16
    }  # the rest of it kept

    # A folder trained with one budget is not done for another: the train stage runs again.
    calls: list[str] = []
    _train_only(monkeypatch, calls)
    Reproduction(
        narrow(plan_for("bandit", seeds=3, train_steps=500), ["bandit-s2-hand"], ["agg"]), tmp_path, log=lambda _: None
    ).run()
    Reproduction(narrow(plan_for("bandit", seeds=3), ["bandit-s2-hand"], ["agg"]), tmp_path, log=lambda _: None).run()
    assert calls == ["bandit", "bandit"]
    assert json.loads((tmp_path / "plan.json").read_text())["train_steps"] is None


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--train-steps", "0"], "argument --train-steps: expected a whole number >= 1, got '0'"),
        (["--seeds", "0"], "argument --seeds: expected a whole number >= 1, got '0'"),
    ],
)
def test_reproduce_rejects_bad_budgets_before_running_anything(tmp_path, capsys, args, message) -> None:
    with pytest.raises(SystemExit) as exit_:  # argparse's own check of the number
        main(["reproduce", "bandit", "--out", str(tmp_path / "out"), *args])
    assert exit_.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_marker_without_items_covers_nothing(tmp_path, monkeypatch) -> None:
    calls: list[str] = []
    _train_only(monkeypatch, calls)
    (tmp_path / "train.done").write_text("12.5 s\n")  # written before markers listed their experiments
    assert read_marker(tmp_path / "train.done") == (12.5, [])
    Reproduction(narrow(plan_for("bandit", seeds=3), ["bandit-s2-hand"], ["agg"]), tmp_path, log=lambda _: None).run()
    seconds, covered = read_marker(tmp_path / "train.done")
    assert calls == ["bandit"] and seconds >= 12.5 and len(covered) == 3


def test_marginals_leave_out_unfinished_or_unbegun_trials_and_populations_whose_conventions_are_not_uniform(
    tmp_path, monkeypatch
) -> None:
    plan = narrow(plan_for("bandit", seeds=3), ["bandit-s2-hand", "bandit-user-study"], ["agg"])
    repro = Reproduction(plan, tmp_path, log=lambda _: None)
    assert repro.stage_items("marginals") == [
        f"bandit-s2-hand__{m} seeds=0,1,2" for m in ("agg", "modular-lam0.5", "no_task_logits")
    ]
    assert len(repro.stage_items("train")) == 5  # the user-study egos are still trained and adapted
    for name in ("bandit-s2-hand__agg", "bandit-user-study__agg", "bandit-s2-hand__maml"):
        (tmp_path / "runs" / name / "point_0" / "seed=0").mkdir(parents=True)
        (tmp_path / "runs" / name / "point_0" / "seed=0" / CONFIG_FILE).write_text("{}")
    for name in ("bandit-s2-hand__agg", "bandit-user-study__agg"):  # maml is still training: no eval.json yet
        (tmp_path / "runs" / name / "point_0" / "seed=0" / EVAL_FILE).write_text("{}")
    # An experiment a killed wider run set up but never trained: no trial folder at all.
    (tmp_path / "runs" / "bandit-s2-hand__oracle").mkdir()
    (tmp_path / "runs" / "bandit-s2-hand__oracle" / "experiment.yaml").write_text("{}")
    seen: list[str] = []
    monkeypatch.setattr(
        "rllib_conv.pipelines.reproduce.marginal_report",
        lambda trials: seen.extend(t.parent.parent.name for t in trials) or pd.DataFrame({"run": [str(t) for t in trials]}),
    )
    repro.stage_marginals()
    assert seen == ["bandit-s2-hand__agg"]


def test_marginals_of_a_plan_with_none_to_measure_write_an_empty_table(tmp_path) -> None:
    """Every population in `no_marginals` (the user study alone): the stage writes the table's header, no crash."""
    plan = narrow(plan_for("bandit", seeds=3), ["bandit-user-study"], ["agg"])
    repro = Reproduction(plan, tmp_path, log=lambda _: None)
    assert repro.stage_items("marginals") == []
    (tmp_path / "runs" / "bandit-user-study__agg" / "point_0" / "seed=0").mkdir(parents=True)
    (tmp_path / "runs" / "bandit-user-study__agg" / "point_0" / "seed=0" / EVAL_FILE).write_text("{}")
    repro.stage_marginals()
    table = pd.read_csv(tmp_path / MARGINALS_FILE)
    assert table.empty and {"run", "distance", "experiment"} <= set(table.columns)


@pytest.mark.slow
def test_quick_reproduction_runs_every_stage_and_builds_the_report(ray_session, tmp_path, capsys) -> None:
    out = tmp_path / "repro"
    args = ["reproduce", "bandit", "--quick", "--populations", "bandit-s2-hand", "--out", str(out)]
    assert main(args) == 0
    game = out / "bandit"
    assert sorted(p.stem for p in game.glob("*.done")) == ["adapt", "marginals", "selfplay", "train"]
    curves = pd.read_csv(game / "adaptation" / "bandit-s2-hand__modular-lam0.5.csv")
    assert curves["steps"].min() == 0 and curves["steps"].max() >= 64
    assert set(pd.read_csv(game / "marginals.csv")["method"]) == {"modular", "agg"}
    report = (out / "report" / "report.md").read_text()
    assert "Arms 2" in report and (out / "report" / "figures" / "adapt_armsexp.png").stat().st_size > 0

    capsys.readouterr()
    assert main(args) == 0  # again: every stage is skipped, the report rebuilt
    assert "train: done before, skipped" in capsys.readouterr().out


POOLED_PLAN = """
game: bandit
paper_method: modular-lam0.5
methods:
  modular-lam0.5: {method: modular, lam: 0.5}
adapt_variants: {}
full: &scale
  populations: {}
  selfplay:
    - {name: bandit-s2-selfplay, env_config: {symmetric: 2}, train_pairs: 2, test_pairs: 1, run: {timesteps: 3000},
       populations: 2}
  selfplay_methods: [modular-lam0.5]
  zeroshot_populations: []
  zeroshot_methods: []
  adapt_variants: []
  train_overrides: {run: {timesteps: 1024}}
  adapt_overrides: {steps: 32, episodes: 0}
quick: *scale
"""


@pytest.mark.slow
def test_a_plan_of_two_selfplay_populations_trains_both_and_the_report_pools_them(ray_session, tmp_path) -> None:
    plan = tmp_path / "plan.yaml"
    plan.write_text(POOLED_PLAN)
    out = tmp_path / "repro"
    assert main(["reproduce", "bandit", "--quick", "--plan", str(plan), "--out", str(out)]) == 0
    game = out / "bandit"
    members = ["bandit-s2-selfplay-p0", "bandit-s2-selfplay-p1"]
    assert json.loads((game / "plan.json").read_text())["population_groups"] == {"bandit-s2-selfplay": members}
    assert all((game / "adaptation" / f"{m}__modular-lam0.5.csv").is_file() for m in members)
    # Both populations' pairs trained in one Tune run (no core idles at the first one's tail), each written whole.
    assert len(list(game.rglob("selfplay-stage-*"))) == 1 and not list(game.rglob("selfplay-bandit-s2-selfplay-p*"))
    assert all(len(pd.read_csv(game / "populations" / m / "selfplay_report.csv")) == 3 for m in members)
    report = (out / "report" / "report.md").read_text()
    assert "`bandit-s2-selfplay` pools 2 independently trained self-play populations" in report
    # One seed per population: the interval over the two populations' means is the only one there is.
    summary = next(line for line in report.splitlines() if line.startswith("| Arms 2 (self-play) | ours"))
    assert "(n=2)" in summary


@pytest.mark.slow
def test_quick_overcooked_reproduction_trains_adapts_to_cooks_and_human_proxies_and_plays_the_anchor(
    ray_session, tmp_path, short_human_cache
) -> None:
    # The shipped quick plan, with the built-in proxy names replaced by the folders of proxies trained here on the
    # short human data (the built-in names would read the user's cache).
    human_proxies.run(["cramped_room"], [0], short_human_cache, BCSettings(epochs=3), episodes=2)
    text = config_file("plan_overcooked.yaml").read_text()
    for kind in ("bc", "hproxy"):
        text = text.replace(f"overcooked-cramped_room-{kind}", str(proxies_folder("cramped_room", kind, short_human_cache)))
    plan = tmp_path / "plan.yaml"
    plan.write_text(text)
    out = tmp_path / "repro"
    assert main(["reproduce", "overcooked", "--quick", "--seeds", "1", "--plan", str(plan), "--out", str(out)]) == 0
    game = out / "overcooked"
    assert sorted(p.stem for p in game.glob("*.done")) == ["adapt", "heldout", "selfplay", "train"]  # no oracle: no marginals
    curves = pd.read_csv(game / "adaptation" / "overcooked-cramped_room-cooks__modular-lam0.5.csv")
    assert curves["steps"].min() == 0 and curves["steps"].max() == 1600
    # The egos trained with the cooks also adapt to the human proxies none of them trained with.
    to_people = pd.read_csv(game / "adaptation" / "hproxy__modular-lam0.5.csv")
    assert set(to_people["partner"]) == {"seed0"} and to_people["steps"].max() == 1600
    assert (game / "adaptation" / "hproxy__scratch.csv").is_file()
    heldout = pd.read_csv(game / "heldout.csv")
    assert sorted(heldout["agent"].unique()) == ["BC", "PPO_BC", "PPO_SP"] and (heldout["episodes"] == 2).all()
    report = (out / "report" / "report.md").read_text()
    assert "overcooked-cramped_room-cooks" in report and "| PPO_BC beats PPO_SP |" in report


@pytest.mark.slow
def test_quick_lbf_reproduction_trains_on_three_seats_and_adapts_to_a_held_out_team_fresh_from_scratch_and_by_plastic(
    ray_session, tmp_path
) -> None:
    out = tmp_path / "repro"
    assert main(["reproduce", "lbf", "--quick", "--out", str(out)]) == 0
    game = out / "lbf"
    # No new task or oracle on this game: self-play, train, adapt and the field's protocol are the stages with work.
    assert sorted(p.stem for p in game.glob("*.done")) == ["adapt", "evaluate", "selfplay", "train"]
    population = partners.get(str(game / "populations" / "lbf-selfplay"))
    assert [e.name for e in population.entries("test")] == ["sp02"] and population.partner_agents == ["player_1", "player_2"]
    # A new partner is a team, one held-out member per partner seat (the quick plan's first: H3 in both; the
    # self-play population's one test member in both).
    adapted = {
        "lbf-heuristics": ("H3+H3", ["modular-lam0.5", "agg", "scratch", "beyond-plastic"]),
        "lbf-selfplay": ("sp02+sp02", ["modular-lam0.5", "scratch", "beyond-plastic"]),
    }
    for population_name, (team, labels) in adapted.items():
        for label in labels:
            curves = pd.read_csv(game / "adaptation" / f"{population_name}__{label}.csv")
            assert set(curves["partner"]) == {team}, (population_name, label)
            assert curves["steps"].min() == 0 and curves["steps"].max() >= 1000, (population_name, label)
            assert curves["mean_return"].between(0, 1).all(), (population_name, label)
    # Every method's egos against every team of the held-out types, normalised by the set's declared bounds.
    scores = pd.read_csv(game / "evaluation" / "lbf-heuristics__heldout" / "scores.csv")
    assert set(scores["agent"]) == {"lbf-heuristics__modular-lam0.5", "lbf-heuristics__agg"}
    assert len(scores) == 2 * 4 and (scores["bound_source"] == "declared").all() and (scores["episodes"] == 4).all()
    report = (out / "report" / "report.md").read_text()
    assert (
        "| lbf-heuristics | PLASTIC-Policy (beyond the paper) |" in report and "| lbf | lbf-heuristics | ours λ=0.5 |" in report
    )
    assert "### lbf: lbf-heuristics egos against `lbf-heldout` (declared bounds)" in report


def test_redo_moves_a_stages_outputs_aside_and_runs_it_again(tmp_path, monkeypatch) -> None:
    logs: list[str] = []
    repro = Reproduction(narrow(plan_for("bandit", seeds=3), ["bandit-s2-hand"], ["agg"]), tmp_path, log=logs.append)
    items = repro.stage_items("zeroshot")
    names = [i.split(" seeds=")[0] for i in items]
    assert names == ["bandit-s2-hand__modular-lam0.5", "bandit-s2-hand__no_task_logits"]
    (tmp_path / "zeroshot").mkdir()
    for n in [*names, "bandit-s1-hand__modular-lam0.5"]:  # the last is outside the plan: left alone
        (tmp_path / "zeroshot" / f"{n}.csv").write_text(f"old {n}\n")
        (tmp_path / "runs" / f"zeroshot-{n}").mkdir(parents=True)
    other = "bandit-s1-hand__modular-lam0.5 seeds=0,1,2"
    (tmp_path / "zeroshot.done").write_text("\n".join(["42.0 s", *items, other]) + "\n")

    moved = repro.redo("zeroshot")
    assert len(moved) == 4 and all("superseded" in p.parts and p.exists() for p in moved)
    assert {p.name for p in moved} == {*(f"{n}.csv" for n in names), *(f"zeroshot-{n}" for n in names)}
    assert moved[0].read_text() == f"old {names[0]}\n"  # kept, not deleted
    assert [p.name for p in (tmp_path / "zeroshot").iterdir()] == ["bandit-s1-hand__modular-lam0.5.csv"]
    assert read_marker(tmp_path / "zeroshot.done") == (42.0, [other])

    calls: list[str] = []
    monkeypatch.setattr(Reproduction, "stages", lambda self: [("zeroshot", lambda: calls.append("zeroshot"))])
    repro.run()
    assert calls == ["zeroshot"] and set(read_marker(tmp_path / "zeroshot.done")[1]) == {other, *items}
    with pytest.raises(
        ValueError, match=r"--redo: expected one of \['adapt', 'evaluate', 'heldout', 'marginals', 'zeroshot'\], got 'train'"
    ):
        repro.redo("train")
