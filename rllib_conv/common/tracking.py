"""The experiment trackers `--log` can name (light: the command line reads it before Ray loads).

`tensorboard`: event files in every trial folder (Tune writes them anyway); `wandb`:
Weights & Biases, offline unless $WANDB_MODE says otherwise, files in the experiment folder's
`wandb/`; `mlflow`: a local MLflow file store in the experiment folder's `mlruns/`. The last
two need the `tracking` extra (`pip install 'rllib-conv[tracking]'`);
`rllib_conv.training.tuning.logger_callbacks` builds their Tune callbacks.
"""

from __future__ import annotations

LOGGERS: tuple[str, ...] = ("tensorboard", "wandb", "mlflow")
DEFAULT_LOGGERS: tuple[str, ...] = ("tensorboard",)
