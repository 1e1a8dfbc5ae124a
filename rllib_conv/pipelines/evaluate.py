"""`rllib-conv evaluate`: trained egos against an evaluation set, scored as the field scores zero-shot coordination.

For every (ego, partner) of the set (`partners.evaluation_sets`):

- the **return**: exact where the game's record has `exact_return` (the bandit, blocks: from
  both players' action probabilities), else the mean of `episodes` sampled episodes (64, as
  jax-aht);
- the partner's **best-response bound**: the expected score of the best ego against that
  partner, computed exactly by the game (`envs.best_response_return`), or, where the game has
  none, the bound the set declares (`bounds`: a best response trained against that partner,
  as jax-aht's; `bound_source` says which);
- the **normalised score**, return / bound. A partner whose bound is 0 (no ego can score
  with it) measures nothing and is refused, as is one without any bound.

With several partner seats (Level-Based Foraging) a "partner" is a team, one of the set's
partners per partner seat, and the ego meets every team (`Population.teams`).

Per agent (one RUNS argument; its egos are the seeds) the mean and the IQM of the normalised
scores, each with a bootstrap interval that resamples seeds (`common.aggregates`). The
outputs: `scores.csv` (one row per ego and partner), `summary.json` (the aggregates, each
seed's mean, the partners' bounds, the command and the resolved config), `summary.png`.
"""

from __future__ import annotations

import json
import math
import shlex
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")  # files only; no display on servers and CI
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from rllib_conv import envs  # noqa: E402
from rllib_conv.common import aggregates  # noqa: E402
from rllib_conv.common.atomic_files import replaced_atomically, write_text_atomically  # noqa: E402
from rllib_conv.common.run_folders import trial_name  # noqa: E402
from rllib_conv.modules.multi import AGG_HEAD_ID, TASK_ID  # noqa: E402
from rllib_conv.partners.base import Partner  # noqa: E402
from rllib_conv.partners.population import PartnerEntry, Population  # noqa: E402
from rllib_conv.pipelines.evaluate_config import EvaluateConfig, Evaluation, TrainedEgo  # noqa: E402
from rllib_conv.pipelines.pair import module_player  # noqa: E402
from rllib_conv.training.checkpoints import last_checkpoint  # noqa: E402
from rllib_conv.training.evaluate import load_module, seated_return  # noqa: E402

SCORES_FILE, SUMMARY_FILE, FIGURE_FILE = "scores.csv", "summary.json", "summary.png"
SCORE_COLUMNS = [
    "agent",
    "ego",
    "seed",
    "module",
    "partner",
    "kind",
    "return",
    "source",
    "episodes",
    "stderr",
    "bound",
    "bound_source",
    "normalised",
]
SUMMARY_COLUMNS = ["agent", "seeds", "partners", "mean", "mean_low", "mean_high", "iqm", "iqm_low", "iqm_high", "return"]


@dataclass(frozen=True)
class Player:
    """A trained ego as the fixed player that meets the set."""

    ego: TrainedEgo
    module: str
    player: Partner


def load_player(ego: TrainedEgo, module_id: str | None, seed: int) -> Player:
    """The module `module_id` of `ego`'s last checkpoint as a player (None: its one head, else its task module)."""
    module = load_module(last_checkpoint(ego.trial))
    heads = module.head_ids()
    # A modular ego has a head per training partner and none for a partner it never met: what
    # it brings to a new one is its task module, its estimate of the marginal best response.
    chosen = module_id or (AGG_HEAD_ID if AGG_HEAD_ID in heads else TASK_ID)
    if chosen not in (TASK_ID, *heads):
        raise ValueError(f"--module {chosen!r}: the ego in {str(ego.trial)!r} has no such module; it has {[TASK_ID, *heads]}")
    return Player(ego, chosen, module_player(module, chosen, trial_name(ego.trial), seed))


def bounds(
    partners: Population, ego_agent: str, where: str, declared: dict[str, float] | None = None
) -> dict[str, tuple[float, str]]:
    """(bound, "exact" or "declared") per partner (team); ValueError naming the set and partner where it is unknown or 0."""
    declared = declared or {}
    out = {}
    for name, members in partners.teams():
        if name in declared:
            bound, source = declared[name], "declared"
        else:  # exact, for one partner seat where the game knows it
            one = len(members) == 1
            bound = envs.best_response_return(partners.env, partners.env_config, ego_agent, members[0].build()) if one else None
            source = "exact"
        if bound is None:
            raise ValueError(
                f"{where}: partner {name!r} (kind {_kind(members)}) has no exact best-response bound on {partners.env} "
                "(it does not say what its actions are drawn from, or learns while it plays, or the game has none) "
                "and the set declares none (`bounds:`)"
            )
        if bound <= 0:
            raise ValueError(f"{where}: partner {name!r} has a best-response bound of {bound:g}: no ego can score with it")
        out[name] = (bound, source)
    return out


def _kind(members: list[PartnerEntry]) -> str:
    return "+".join(e.kind for e in members)


def score_table(
    players: list[Player],
    partners: Population,
    episodes: int,
    seed: int,
    where: str = "set",
    declared: dict[str, float] | None = None,
) -> pd.DataFrame:
    """One row per (player, partner or team): the return (exact where the game has one), the bound and the normalised score."""
    env = envs.make_scored(partners.env, **partners.env_config)
    ego_agent = partners.ego_agent(env.possible_agents)
    bound = bounds(partners, ego_agent, where, declared)
    exact_return = envs.game(partners.env).exact_return
    rows = []
    for p in players:
        for name, members in partners.teams():
            seated = {ego_agent: p.player, **partners.seated(members)}
            exact = exact_return(seated, partners.env_config) if exact_return else None
            if exact is not None:
                value, source, played, stderr = exact, "exact", 0, 0.0
            else:  # a game, or a player, without an exact return: sampled episodes
                out = seated_return(seated, partners.env, partners.env_config, episodes, seed)
                value, source, played, stderr = out["mean"], "sampled", episodes, out["stderr"]
            rows.append(
                [p.ego.agent, trial_name(p.ego.trial), p.ego.seed, p.module, name, _kind(members)]
                + [value, source, played, stderr, *bound[name], value / bound[name][0]]
            )
    return pd.DataFrame(rows, columns=SCORE_COLUMNS)


def summarise(table: pd.DataFrame, resamples: int = 9999, confidence: float = 0.95, seed: int = 0) -> pd.DataFrame:
    """Per agent: mean and IQM of the normalised scores with bootstrap intervals over its egos (seeds), and the mean return."""
    rows = []
    for agent, group in table.groupby("agent", sort=False):
        matrix = group.pivot_table(index="ego", columns="partner", values="normalised", aggfunc="first")
        scores = matrix.to_numpy()
        stats = {
            name: aggregates.over_seeds(scores, statistic, resamples, confidence, seed)
            for name, statistic in (("mean", aggregates.mean), ("iqm", aggregates.iqm))
        }
        rows.append(
            [agent, len(matrix), matrix.shape[1]]
            + [x for s in stats.values() for x in (s.value, s.low, s.high)]
            + [float(group["return"].mean())]
        )
    return pd.DataFrame(rows, columns=SUMMARY_COLUMNS)


def evaluate(cfg: EvaluateConfig, found: Evaluation) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Score every ego `check` found against its set; the per-(ego, partner) table and the per-agent summary."""
    players = [load_player(ego, cfg.module, cfg.seed) for ego in found.egos]
    where = f"--eval-set {cfg.eval_set!r}"
    table = score_table(players, found.partners, cfg.episodes, cfg.seed, where, found.eval_set.bounds)
    return table, summarise(table, cfg.resamples, cfg.confidence, cfg.seed)


def _json_value(x: Any) -> Any:
    return None if isinstance(x, float) and math.isnan(x) else x


def summary_record(
    table: pd.DataFrame, summary: pd.DataFrame, cfg: EvaluateConfig, found: Evaluation, command: list[str]
) -> dict[str, Any]:
    """What `summary.json` holds: the command, the resolved config and set, the bounds, each seed's mean and the aggregates."""
    per_seed = table.groupby(["agent", "ego", "seed"], sort=False)["normalised"].mean().reset_index()
    return {
        "command": shlex.join(command),
        "config": cfg.model_dump(),
        "env": found.env,
        "env_config": found.env_config,
        "eval_set": {
            **found.eval_set.model_dump(),
            "file": found.eval_set.source,
            "partners": [e.model_dump(exclude={"split"}, exclude_none=True) for e in found.partners.partners],
        },
        "bounds": table.drop_duplicates("partner").set_index("partner")["bound"].to_dict(),
        "per_seed": per_seed.rename(columns={"normalised": "mean_normalised"}).to_dict("records"),
        "aggregates": [{k: _json_value(v) for k, v in row.items()} for row in summary.to_dict("records")],
        "method": "normalised = return / best-response bound (exact, or as the set declares: `bounds_by`); mean and IQM (25% trimmed) of every (seed, partner) score; "
        f"{cfg.confidence:.0%} percentile bootstrap intervals resampling seeds ({cfg.resamples} resamples, seed {cfg.seed})",
    }


def draw(summary: pd.DataFrame, title: str, path: Path) -> None:
    """Mean and IQM of the normalised score per agent, with their intervals over seeds, as a PNG at `path`."""
    fig, axes = plt.subplots(1, 2, figsize=(9, 0.5 * len(summary) + 2), sharey=True)
    y = np.arange(len(summary))
    for ax, stat in zip(axes, ("mean", "iqm")):
        value = summary[stat].to_numpy()
        low, high = summary[f"{stat}_low"].to_numpy(), summary[f"{stat}_high"].to_numpy()
        # A percentile interval need not hold its point (the IQM of a few seeds can lie outside the resampled IQMs'
        # middle 95%), so it is drawn from its ends, not as errors around the point; one seed: no interval drawn.
        ax.hlines(y, low, high, color="C0")
        ax.plot(value, y, "o", color="C0")
        ax.axvline(1.0, color="grey", linestyle=":", linewidth=1)  # the best response's score
        ax.set_xlabel(f"{'IQM' if stat == 'iqm' else 'mean'} normalised score")
        ax.set_yticks(y, summary["agent"])
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write_evaluation(
    cfg: EvaluateConfig, found: Evaluation, out: str | Path, command: list[str]
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Evaluate (`evaluate`), then write `scores.csv`, `summary.json` and `summary.png` under `out`; nothing is written if it fails."""
    table, summary = evaluate(cfg, found)
    record = summary_record(table, summary, cfg, found, command)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with replaced_atomically(out / SCORES_FILE) as tmp:
        table.to_csv(tmp, index=False)
    write_text_atomically(out / SUMMARY_FILE, json.dumps(record, indent=2, default=str) + "\n")
    draw(summary, f"{found.eval_set.name} ({found.env}): normalised by each partner's best-response bound", out / FIGURE_FILE)
    return table, summary
