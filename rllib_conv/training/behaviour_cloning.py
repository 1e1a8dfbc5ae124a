"""Behaviour cloning: a policy module trained by cross-entropy on logged (observation, action) pairs.

Used for Carroll et al.'s human proxies (`pipelines/human_proxies.py`): the 2019 human
trajectories (`envs/overcooked/human_data.py`) are encoded with our env's own observation
(`GridEncoder`, each row from its seat's point of view, that seat's player first), and a
`TaskModule` (the policy tower and logits; its value tower is left untouched) learns to
predict the logged action. The result is saved with `save_to_path`, so
`partners.trained.TrainedPolicyPartner` loads it as any other trained partner, and it plays
either seat.

Why our own trainer, not RLlib's offline `BC` (`ray.rllib.algorithms.bc.BCConfig` with
`.offline_data(input_=...)`), measured on cramped_room's train rows on 2 cores (AMD EPYC):
with `ray.init(num_cpus=2)` (the real cores, as the tests' Ray session) RLlib's BC never
trained: its Ray Data pipeline (read parquet -> `OfflinePreLearner` actor pool) waited for 2
free CPUs and made no progress for 60 s. With 4 logical CPUs it ran: 9.3 s to build, 15.8 s
for the first iteration (the data pipeline starting), then 0.2 s per 63 batches of 64 (one
pass over the ~4 000 non-STAY rows). Our loop trains the same network on the same rows, 30
passes with early stopping on held-out trials, in 2-3 s in all, needs no Ray, and gives the
same weights for the same seed (tested). The ~20 000 rows of one layout and split fit in
memory as one float32 array, so nothing is gained by streaming them.

Carroll et al.'s settings (upstream `behavior_cloning_tf2.py`): a 64-64 MLP, Adam with
learning rate 1e-3, batches of 64, up to 100 epochs, 15% held out; we keep the weights of
the epoch with the best held-out loss (upstream stops early on it) and hold out whole
trials, not random rows (rows of one trial repeat the same states).

"Stay": about 70% of logged actions are STAY because the game was logged faster than people
press keys, so one wait shows as a run of identical STAY rows. `stay_rows` chooses what
training sees (`STAY_RULES`): every row (`keep`), the first STAY of each run (`collapse`:
the decision to wait, once), or no STAY (`drop`). The choice and its measured effect are in
`pipelines/human_proxies.py`.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import torch
from gymnasium import spaces
from overcooked.mdp.overcooked_mdp import OvercookedState
from ray.rllib.core.rl_module.rl_module import RLModuleSpec

from rllib_conv.envs.overcooked.encoding import GridEncoder
from rllib_conv.envs.overcooked.env import HORIZON, NUM_ACTIONS, STAY, build_mdp
from rllib_conv.envs.rllib_adapter import RLLIB_MASK_KEY, RLLIB_OBS_KEY
from rllib_conv.modules.task_module import TaskModule

STAY_RULES = ("keep", "collapse", "drop")
# Columns `encode_trajectories` reads (the human-data format of `envs/overcooked/human_data.py`).
NEEDED = ("trial", "seat", "t", "state", "action")


@dataclass(frozen=True)
class BCSettings:
    """How one BC model is trained (defaults: Carroll et al.'s, see the module docstring)."""

    hidden: int = 64
    lr: float = 1e-3
    batch_size: int = 64
    epochs: int = 100
    patience: int = 10  # stop after this many epochs without a better held-out loss
    holdout: float = 0.15  # fraction of trials held out (at least one when there are two or more)
    stay: str = "drop"  # measured choice: see pipelines/human_proxies.py

    def __post_init__(self) -> None:
        if self.stay not in STAY_RULES:
            raise ValueError(f"stay must be one of {', '.join(STAY_RULES)}, got {self.stay!r}")
        for name in ("hidden", "batch_size", "epochs", "patience"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if not 0.0 <= self.holdout < 1.0:
            raise ValueError(f"holdout must be in [0, 1), got {self.holdout!r}")
        if not self.lr > 0:
            raise ValueError(f"lr must be > 0, got {self.lr!r}")


@dataclass
class Steps:
    """Encoded rows: observations [N, d] float32, actions [N] int64, and each row's trial, seat and step."""

    obs: np.ndarray
    actions: np.ndarray
    trial: np.ndarray
    seat: np.ndarray
    t: np.ndarray

    def __len__(self) -> int:
        return len(self.actions)

    def take(self, rows: np.ndarray) -> "Steps":
        """The rows selected by a boolean mask or index array."""
        return Steps(self.obs[rows], self.actions[rows], self.trial[rows], self.seat[rows], self.t[rows])


@dataclass
class BCResult:
    """A trained module and how its training went."""

    module: TaskModule
    settings: BCSettings
    seed: int
    train_rows: int
    holdout_trials: list[int]
    epochs_run: int
    best_epoch: int
    holdout_loss: float
    seconds: float
    history: list[float] = field(default_factory=list)

    def summary(self) -> dict:
        """What a checkpoint's `bc.json` records (JSON-able)."""
        out = {k: v for k, v in asdict(self).items() if k not in ("module", "settings")}
        return {**out, "settings": asdict(self.settings)}


def encode_trajectories(frame: pd.DataFrame, layout: str, horizon: int = HORIZON) -> Steps:
    """Each row's state as our env's observation from the row's seat (that seat's player first).

    The logs carry no episode clock, and the encoding's last channel flags the final 40 steps
    of an episode: a row gets that flag when fewer than 40 logged steps of its trial remain,
    so the proxy has seen it when it meets it at the end of an episode.
    """
    missing = [c for c in NEEDED if c not in frame.columns]
    if missing:
        raise ValueError(f"trajectories of {layout!r} lack the columns {missing}")
    encoder = GridEncoder(build_mdp(layout), horizon)
    length = frame.groupby(["trial", "seat"])["t"].transform("max").to_numpy() + 1
    left = length - frame["t"].to_numpy()
    timestep = np.maximum(horizon - left, 0)
    memo: dict[tuple[str, int], tuple[np.ndarray, np.ndarray]] = {}
    obs = np.empty((len(frame), encoder.size), dtype=np.float32)
    for i, (text, step, seat) in enumerate(zip(frame["state"], timestep, frame["seat"])):
        key = (text, int(step))
        if key not in memo:
            state = OvercookedState.from_dict(json.loads(text))
            state.timestep = int(step)
            memo[key] = encoder.encode(state)
        obs[i] = memo[key][int(seat)]
    return Steps(
        obs,
        frame["action"].to_numpy(dtype=np.int64),
        frame["trial"].to_numpy(dtype=np.int64),
        frame["seat"].to_numpy(dtype=np.int64),
        frame["t"].to_numpy(dtype=np.int64),
    )


def stay_rows(steps: Steps, rule: str) -> np.ndarray:
    """Boolean mask of the rows training uses under `rule` (`STAY_RULES`; rows sorted by trial, seat, t)."""
    if rule not in STAY_RULES:
        raise ValueError(f"stay must be one of {', '.join(STAY_RULES)}, got {rule!r}")
    stay = steps.actions == STAY
    if rule == "keep":
        return np.ones(len(steps), dtype=bool)
    if rule == "drop":
        return ~stay
    # A row continues a run when the same seat of the same trial stayed on the step before.
    same = np.zeros(len(steps), dtype=bool)
    same[1:] = (steps.trial[1:] == steps.trial[:-1]) & (steps.seat[1:] == steps.seat[:-1]) & (steps.t[1:] == steps.t[:-1] + 1)
    continues = np.zeros(len(steps), dtype=bool)
    continues[1:] = same[1:] & stay[:-1]
    return ~(stay & continues)


def holdout_trials(trials: np.ndarray, fraction: float, seed: int) -> list[int]:
    """The trials held out for early stopping: `ceil(fraction * n)` of them (at least 1 when n >= 2), drawn by `seed`."""
    unique = np.unique(trials)
    if fraction <= 0 or len(unique) < 2:
        return []
    count = min(max(int(np.ceil(fraction * len(unique))), 1), len(unique) - 1)
    return sorted(int(t) for t in np.random.default_rng(seed).choice(unique, size=count, replace=False))


def new_module(obs_dim: int, hidden: int, seed: int) -> TaskModule:
    """A fresh `TaskModule` for observations of size `obs_dim` as the RLlib adapter gives them (obs + action mask)."""
    box = spaces.Box(0.0, 1.0, shape=(obs_dim,), dtype=np.float32)
    observation_space = spaces.Dict({RLLIB_OBS_KEY: box, RLLIB_MASK_KEY: spaces.Box(0.0, 1.0, (NUM_ACTIONS,), np.float32)})
    spec = RLModuleSpec(
        module_class=TaskModule,
        observation_space=observation_space,
        action_space=spaces.Discrete(NUM_ACTIONS),
        model_config={"hidden": hidden, "init_seed": seed},
    )
    return spec.build()


def _logits(module: TaskModule, obs: torch.Tensor) -> torch.Tensor:
    return module.policy(obs, None).logits


def _loss(module: TaskModule, obs: torch.Tensor, actions: torch.Tensor, batch: int = 4096) -> float:
    with torch.no_grad():
        total = sum(
            float(torch.nn.functional.cross_entropy(_logits(module, obs[i : i + batch]), actions[i : i + batch], reduction="sum"))
            for i in range(0, len(actions), batch)
        )
    return total / max(len(actions), 1)


def train(steps: Steps, settings: BCSettings | None = None, seed: int = 0) -> BCResult:
    """Clone the actions of `steps` into a fresh `TaskModule` (same steps, settings and seed: the same weights)."""
    if len(steps) == 0:
        raise ValueError("behaviour cloning needs at least one row of (observation, action)")
    settings = settings or BCSettings()
    started = time.perf_counter()
    held = holdout_trials(steps.trial, settings.holdout, seed)
    is_held = np.isin(steps.trial, held)
    use = stay_rows(steps, settings.stay)
    fit, check = steps.take(use & ~is_held), steps.take(~is_held if not held else is_held)
    if len(fit) == 0:
        raise ValueError(f"behaviour cloning: no training rows are left after the stay rule {settings.stay!r}")
    module = new_module(steps.obs.shape[1], settings.hidden, seed)
    module.train()
    params = [*module.pi_tower.parameters(), *module.pi_out.parameters()]
    optimiser = torch.optim.Adam(params, lr=settings.lr)
    obs, actions = torch.as_tensor(fit.obs), torch.as_tensor(fit.actions)
    # Early stopping looks at the held-out trials' rows under the same stay rule training uses.
    check = check.take(stay_rows(check, settings.stay))
    check_obs, check_actions = torch.as_tensor(check.obs), torch.as_tensor(check.actions)
    order = torch.Generator().manual_seed(seed)
    best, best_epoch, best_state, history, waited = float("inf"), 0, None, [], 0
    epoch = 0
    for epoch in range(1, settings.epochs + 1):
        for rows in torch.randperm(len(actions), generator=order).split(settings.batch_size):
            loss = torch.nn.functional.cross_entropy(_logits(module, obs[rows]), actions[rows])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
        held_loss = _loss(module, check_obs, check_actions)
        history.append(held_loss)
        if held_loss < best:
            best, best_epoch, waited = held_loss, epoch, 0
            best_state = {k: v.clone() for k, v in module.state_dict().items()}
        else:
            waited += 1
            if waited >= settings.patience:
                break
    module.load_state_dict(best_state)
    module.eval()
    return BCResult(module, settings, seed, len(fit), held, epoch, best_epoch, best, time.perf_counter() - started, history)


def predict(module: TaskModule, obs: np.ndarray, batch: int = 4096) -> np.ndarray:
    """The module's most likely action per row of `obs` [N, d]."""
    with torch.no_grad():
        parts = [_logits(module, torch.as_tensor(obs[i : i + batch])).argmax(dim=1).numpy() for i in range(0, len(obs), batch)]
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)


def accuracy(module: TaskModule, steps: Steps) -> dict[str, float]:
    """Action-prediction accuracy (argmax vs logged action) on every row, on the non-STAY rows, and the rows' STAY share."""
    if len(steps) == 0:
        raise ValueError("accuracy needs at least one row")
    predicted = predict(module, steps.obs)
    hit = predicted == steps.actions
    moves = steps.actions != STAY
    return {
        "accuracy": float(hit.mean()),
        "accuracy_moves": float(hit[moves].mean()) if moves.any() else float("nan"),
        "predicted_stay": float((predicted == STAY).mean()),
        "rows": int(len(steps)),
    }


def save(result: BCResult, folder: str | Path) -> Path:
    """Write the module (`save_to_path`, loadable by `TrainedPolicyPartner`) and `bc.json` (how it was trained) to `folder`."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    result.module.save_to_path(folder)
    (folder / "bc.json").write_text(json.dumps(result.summary(), indent=2) + "\n")
    return folder
