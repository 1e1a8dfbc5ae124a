"""The ground floor: the method registry, the run-folder names, the shipped data and the plan files."""

from __future__ import annotations

import numpy as np
import pytest
import torch
import yaml

from rllib_conv.cli import main
from rllib_conv.common import methods, resources
from rllib_conv.common.arrays import to_numpy
from rllib_conv.common.atomic_files import folder_replaced_atomically, replaced_atomically, write_text_atomically
from rllib_conv.common.run_folders import experiment_name, read_marker, split_experiment, write_marker
from rllib_conv.common.sealed import digest_path, seal_file, verify_file
from rllib_conv.pipelines.plans import plan_for, read_plan_file, shipped_plan
from rllib_conv.training.experiment import ExperimentConfig


def test_the_registry_answers_what_the_pipelines_ask() -> None:
    assert methods.names(single_head=True) == ["agg", "maml"]
    assert methods.names(composable=True) == ["modular", "no_task_logits", "oracle"]
    assert methods.names(regularised=True) == ["modular", "agg"]
    assert methods.names(head_penalty=True) == ["modular"]
    assert [m.name for m in methods.METHODS.values() if m.marginals] == ["modular", "agg", "maml"]
    assert [m.name for m in methods.METHODS.values() if m.prior is None] == ["no_task_logits"]
    assert methods.method("oracle").task_logits == "oracle" and methods.method("no_task_logits").task_logits == "unused"
    with pytest.raises(ValueError, match="unknown method 'reptile'; known methods: modular, agg, no_task_logits, oracle, maml"):
        methods.method("reptile")


def test_configs_accept_exactly_the_registered_methods() -> None:
    for name in methods.METHODS:
        assert ExperimentConfig(population="p", method=name).method == name
    with pytest.raises(ValueError, match="method"):
        ExperimentConfig(population="p", method="reptile")
    # What a method does not support is refused by the config, from the registry.
    with pytest.raises(ValueError, match="lam must be 0 for method 'maml'"):
        ExperimentConfig(population="p", method="maml", lam=0.5)
    assert ExperimentConfig(population="p", method="agg", lam=0.5).lam == 0.5


def test_experiment_names_split_back_into_population_and_label() -> None:
    name = experiment_name("some/folder/blocks-selfplay", "modular-lam0.5")
    assert name == "blocks-selfplay__modular-lam0.5"
    assert split_experiment(name) == ("blocks-selfplay", "modular-lam0.5")
    assert split_experiment("sweep-bandit") == ("sweep-bandit", "")


def test_markers_round_trip(tmp_path) -> None:
    marker = tmp_path / "train.done"
    write_marker(marker, 12.345, ["a seeds=0", "b seeds=0"])
    assert marker.read_text() == "12.3 s\na seeds=0\nb seeds=0\n"
    assert read_marker(marker) == (12.3, ["a seeds=0", "b seeds=0"])
    assert read_marker(tmp_path / "absent.done") == (0.0, [])


def test_shipped_files_are_found_and_unknown_ones_named() -> None:
    assert resources.user_study_csv().read_text().startswith("pair,task,context,try,action_1,action_2")
    assert {"plan_bandit.yaml", "plan_blocks.yaml", "plan_hanabi.yaml", "bandit_modular.yaml"} <= set(resources.available())
    with pytest.raises(ValueError, match="'nope.yaml' is not among the files of rllib_conv.tune_configs"):
        resources.config_file("nope.yaml")


def test_a_plan_file_naming_an_undefined_label_is_refused(tmp_path) -> None:
    plan = yaml.safe_load(shipped_plan("bandit").read_text())
    plan["full"]["populations"]["bandit-s2-hand"].append("reptile")
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(plan))
    with pytest.raises(ValueError, match=r"full.populations.bandit-s2-hand: \['reptile'\] not defined"):
        read_plan_file(path)
    with pytest.raises(ValueError, match="is a plan for 'bandit', not 'blocks'"):
        plan_for("blocks", path=shipped_plan("bandit"))


def test_an_edited_plan_copy_runs_in_place_of_the_shipped_one(tmp_path) -> None:
    plan = yaml.safe_load(shipped_plan("bandit").read_text())
    plan["full"]["populations"] = {"bandit-s2-hand": ["modular-lam0.5", "agg"]}
    path = tmp_path / "plan.yaml"
    path.write_text(yaml.safe_dump(plan))
    edited = plan_for("bandit", seeds=2, path=path)
    assert {p: [m.label for m in ms] for p, ms in edited.populations.items()} == {"bandit-s2-hand": ["modular-lam0.5", "agg"]}
    assert edited.seeds == [0, 1] and not edited.quick


def test_reproduce_refuses_a_plan_file_for_every_game_at_once(tmp_path, capsys) -> None:
    assert main(["reproduce", "all", "--plan", str(shipped_plan("bandit")), "--out", str(tmp_path / "out")]) == 2
    assert "--plan: a plan file is for one game" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_to_numpy_takes_tensors_with_gradients_and_plain_sequences() -> None:
    t = torch.tensor([1.5, -2.0], requires_grad=True) * 2
    out = to_numpy(t)
    assert isinstance(out, np.ndarray) and out.dtype == np.float32 and out.tolist() == [3.0, -4.0]
    assert to_numpy([1, 2]).tolist() == [1, 2] and to_numpy(np.int64(3)).shape == ()


def test_a_file_is_replaced_whole_or_left_as_it_was(tmp_path) -> None:
    target = tmp_path / "curves.csv"
    assert write_text_atomically(target, "a\n1\n") == target and target.read_text() == "a\n1\n"
    with pytest.raises(RuntimeError, match="killed mid-write"):
        with replaced_atomically(target) as tmp:
            tmp.write_text("a\n")  # half of the new content
            raise RuntimeError("killed mid-write")
    assert target.read_text() == "a\n1\n"  # the old file, whole
    assert sorted(p.name for p in tmp_path.iterdir()) == ["curves.csv"]  # and no half-written file beside it
    (tmp_path / ".curves.csv.tmp").write_text("left by a killed process")
    write_text_atomically(target, "a\n2\n")
    assert target.read_text() == "a\n2\n" and sorted(p.name for p in tmp_path.iterdir()) == ["curves.csv"]


def test_a_sealed_file_is_read_only_unchanged_and_an_unsealed_one_as_it_is(tmp_path) -> None:
    path = tmp_path / "config.yaml"
    path.write_text("lam: 0.5\nseed: 0\n")
    verify_file(path, "trial config")  # never sealed (a run from before sealing): read as it is
    assert seal_file(path) == digest_path(path) == tmp_path / "config.yaml.sha256"
    assert digest_path(path).read_text().endswith("  config.yaml\n")  # sha256sum's format: `sha256sum -c` checks it too
    verify_file(path, "trial config")
    path.write_text("lam: 0\nseed: 0\n")
    with pytest.raises(ValueError, match=r"trial config '.*config.yaml' is corrupt"):
        verify_file(path, "trial config")
    path.unlink()
    with pytest.raises(ValueError, match="is missing"):
        verify_file(path, "trial config")


def test_a_folder_is_replaced_whole_or_left_as_it_was(tmp_path) -> None:
    target = tmp_path / "pop"
    target.mkdir()
    (target / "old.txt").write_text("old")
    with pytest.raises(RuntimeError):
        with folder_replaced_atomically(target) as staging:
            (staging / "new.txt").write_text("half")
            raise RuntimeError("killed while writing")
    assert [p.name for p in tmp_path.iterdir()] == ["pop"] and [p.name for p in target.iterdir()] == ["old.txt"]
    with folder_replaced_atomically(target) as staging:
        (staging / "new.txt").write_text("new")
    assert [p.name for p in tmp_path.iterdir()] == ["pop"] and [p.name for p in target.iterdir()] == ["new.txt"]
