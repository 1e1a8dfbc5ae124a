"""Method records and labels: built with keywords, every label written once (`rllib_conv.common.methods`) and read everywhere."""

from __future__ import annotations

import re

import pytest
import yaml

from analysis import figures, paper
from rllib_conv.common import methods
from rllib_conv.common.resources import config_file

GAMES = ("bandit", "blocks", "hanabi", "overcooked", "lbf")


def test_method_records_take_keywords_only() -> None:
    record = methods.method("modular")
    with pytest.raises(TypeError):
        methods.Method("modular", "ours", "learned", False, True, True, False, True, "task", "task")  # type: ignore[misc]
    assert methods.Method(**{f: getattr(record, f) for f in record.__dataclass_fields__}) == record


@pytest.mark.parametrize("game", GAMES)
def test_every_label_of_a_shipped_plan_is_defined_once_and_says_its_lam(game: str) -> None:
    plan = yaml.safe_load(config_file(f"plan_{game}.yaml").read_text())
    assert plan["paper_method"] == methods.PAPER_METHOD
    for label in [*plan["methods"], *plan.get("adapt_variants", {})]:
        assert label in methods.LABELS, label
    for label, settings in plan["methods"].items():
        lam = re.fullmatch(r"\w+-lam([\d.]+)(-.*)?", label)
        if lam:
            assert float(settings["lam"]) == float(lam.group(1)), label


def test_a_rows_label_without_a_file_name() -> None:
    assert methods.row_label("modular", 0.5) == methods.PAPER_METHOD == "modular-lam0.5"
    assert methods.row_label("modular", 0.0) == "modular"  # lam 0 rows keep the method's name
    assert methods.row_label("no_task_logits", 0.5) == "no_task_logits"  # not regularised
    assert methods.row_label("my_method", 0.5) == "my_method"  # unknown methods: their own name
    assert methods.lam_label(0.0) == methods.LAM0 == "modular-lam0" and methods.LOW_Z == "lowz-lam0.5"


def test_figures_and_the_report_read_the_labels_from_the_registry() -> None:
    assert figures.LABEL_ORDER is methods.LABELS
    assert figures.PAPER_METHOD is methods.PAPER_METHOD
    assert set(figures.LABEL_STYLES) == set(methods.LABELS)
    assert set(paper.LABEL_NAMES) == set(methods.LABELS)
    assert len(set(methods.LABELS)) == len(methods.LABELS)
    assert set(methods.EXTENSIONS) < set(methods.LABELS) and methods.PAPER_METHOD not in methods.EXTENSIONS


@pytest.mark.parametrize("game", GAMES)
def test_the_adapters_behind_each_label_are_those_its_plan_settings_choose(game: str) -> None:
    plan = yaml.safe_load(config_file(f"plan_{game}.yaml").read_text())
    for label, variant in plan.get("adapt_variants", {}).items():
        settings = variant["settings"]
        chosen = (settings.get("head_init", "fresh"), *(["guard"] if settings.get("guard") else []))
        assert methods.ADAPTED_BY.get(label, ("fresh",)) == chosen, label
