"""Experiment tracking (`--log`): TensorBoard event files, Weights & Biases offline runs and an MLflow file store, through Tune's loggers."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from tensorboardX.proto import event_pb2

from rllib_conv.cli import main
from rllib_conv.pipelines.train import run
from rllib_conv.training import experiment
from rllib_conv.training.tuning import logger_callbacks
from tests.helpers import tiny_experiment

TINY = tiny_experiment("tracked", timesteps=128)


def scalar_tags(event_file: Path) -> set[str]:
    """The scalar tags of a TensorBoard event file (TFRecord framing: length, its CRC, an Event proto, its CRC)."""
    data, tags, i = event_file.read_bytes(), set(), 0
    while i < len(data):
        (length,) = struct.unpack("<Q", data[i : i + 8])
        event = event_pb2.Event.FromString(data[i + 12 : i + 12 + length])
        tags |= {v.tag for v in event.summary.value}
        i += 12 + length + 4
    return tags


@pytest.fixture(scope="module")
def tracked(ray_session, tmp_path_factory) -> Path:
    storage = tmp_path_factory.mktemp("tracking")
    results = run(experiment.checked(TINY), storage=storage, loggers=("tensorboard", "wandb", "mlflow"))
    assert not results.errors
    return storage / "tracked"


@pytest.mark.slow
def test_tensorboard_event_files_hold_the_regulariser_and_every_partners_return(tracked) -> None:
    events = list(tracked.glob("*/events.out.tfevents.*"))
    assert events, sorted(p.name for p in tracked.rglob("*"))[:40]
    tags = set().union(*(scalar_tags(e) for e in events))
    assert any(t.endswith("/marginal_reg") for t in tags), sorted(tags)[:40]
    for partner in ("hand-train-0", "hand-train-1"):
        assert any(t.endswith(f"/return/{partner}") for t in tags), sorted(tags)[:40]


@pytest.mark.slow
def test_wandb_writes_an_offline_run_in_the_experiment_folder(tracked) -> None:
    runs = list((tracked / "wandb").glob("offline-run-*"))
    assert len(runs) == 1 and list(runs[0].glob("run-*.wandb")), sorted(p.name for p in (tracked / "wandb").rglob("*"))[:40]


@pytest.mark.slow
def test_mlflow_keeps_the_results_in_a_local_file_store(tracked) -> None:
    metrics = list((tracked / "mlruns").glob("*/*/metrics/marginal_reg"))
    assert len(metrics) == 1
    values = [float(line.split()[1]) for line in metrics[0].read_text().splitlines()]
    assert len(values) == 2  # one per iteration: 128 env steps, 64 a batch


def test_an_unknown_tracker_is_one_line_and_exit_2(tmp_path, capsys) -> None:
    with pytest.raises(ValueError, match=r"--log: expected one of \['tensorboard', 'wandb', 'mlflow'\], got 'neptune'"):
        logger_callbacks(["neptune"], tmp_path, "x")
    with pytest.raises(SystemExit) as exit_:
        main(["train", "tune_configs/bandit_modular.yaml", "--log", "neptune", "--storage", str(tmp_path)])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "argument --log: invalid choice: 'neptune'" in err and "Traceback" not in err
    assert not any(tmp_path.iterdir())
