"""The command line's help: every option of every command has a help text, `--version`, the `--set` keys listed, fast answers."""

from __future__ import annotations

import argparse
import subprocess
import sys
import time

import pytest

from rllib_conv.cli import ADAPT_SET_KEYS, ZEROSHOT_SET_KEYS, build_parser, main
from rllib_conv.pipelines.adapt_config import AdaptConfig
from rllib_conv.pipelines.zeroshot_config import ZeroShotConfig


def commands(
    parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()
) -> list[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    """(words, parser) of every command, nested ones (`partners show`) included."""
    out = [(prefix, parser)]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out += commands(sub, (*prefix, name))
    return out


COMMANDS = commands(build_parser())


def test_every_command_is_reached() -> None:
    names = {" ".join(words) for words, _ in COMMANDS}
    expected = {"demo", "train", "sweep", "envs", "partners list", "partners show", "partners train", "adapt", "zeroshot"}
    expected |= {"marginals", "pair", "reproduce", "play", "report", "plot", "crossplay", "evaluate"}
    assert expected <= names


@pytest.mark.parametrize(("words", "parser"), COMMANDS, ids=[" ".join(w) or "rllib-conv" for w, _ in COMMANDS])
def test_help_lists_a_help_text_for_every_option(words, parser, capsys) -> None:
    with pytest.raises(SystemExit) as exit_:
        main([*words, "--help"])
    assert exit_.value.code == 0
    shown = " ".join(capsys.readouterr().out.split())
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            continue
        assert action.help and action.help != argparse.SUPPRESS, (
            f"{' '.join(words)} {action.option_strings or action.dest} has no help"
        )
        assert " ".join(action.help.split()[:4]) in shown
        for option in action.option_strings:
            assert option in shown
    assert "Undefined" not in shown  # a required field's missing default is not a default to show


def test_version(capsys) -> None:
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.startswith("rllib-conv 0.")


@pytest.mark.parametrize(
    ("listed", "schema", "options"),
    [
        (
            ADAPT_SET_KEYS,
            AdaptConfig,
            {"name", "runs", "population", "split", "partners", "method", "train_task", "head_init", "pick_steps", "guard"},
        ),
        (ZEROSHOT_SET_KEYS, ZeroShotConfig, {"name", "runs", "new_population"}),
    ],
    ids=["adapt", "zeroshot"],
)
def test_the_set_keys_in_the_help_are_exactly_those_no_option_sets(listed, schema, options) -> None:
    per_trial = {"run", "partner"}  # filled in for each Tune trial, not by users
    assert set(listed) == set(schema.model_fields) - options - per_trial


def test_the_set_keys_appear_in_the_help(capsys) -> None:
    for command, keys in (("adapt", ADAPT_SET_KEYS), ("zeroshot", ZEROSHOT_SET_KEYS)):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        out = capsys.readouterr().out
        assert all(f"  {key} " in out for key in keys), command


HELP_IMPORTS = """
import sys
from rllib_conv.cli import main
try:
    main(["train", "--help"])
except SystemExit:
    pass
print("heavy:", sorted(m for m in ("ray", "torch") if m in sys.modules))
"""


def test_help_answers_in_well_under_a_second() -> None:
    begin = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "rllib_conv.cli", "train", "--help"], capture_output=True, text=True, timeout=60)
    elapsed = time.perf_counter() - begin
    assert done.returncode == 0 and "experiment YAML" in done.stdout
    # What made help slow (Ray and torch took 4-5 s) is not imported at all; the wall-time bound is loose, since
    # beside a training test on the other pytest worker of a 2-core machine it took up to 2.04 s.
    imports = subprocess.run([sys.executable, "-c", HELP_IMPORTS], capture_output=True, text=True, timeout=60)
    assert "heavy: []" in imports.stdout, imports.stdout + imports.stderr
    assert elapsed < 4.0  # it answers in about 0.1 s alone
