"""An acting step's head layers on a subset of a stack's heads: on a copy of the picked weights, or on views of them.

At each step of sampling a packed ego runs only the heads whose partners' games wait on the
ego (`StackedEgoMultiRLModule._forward_acting`): a subset of its K x H heads, a row or two
each. Picking them by `index_select` copies every picked layer; on Hanabi's 500 x 500 heads
that copy was 19% of a training trial's samples (py-spy, `reproduce hanabi`'s train stage,
3 self-play populations). `ego_stack.subset_linear` runs layers of `VIEWS_FROM` weights and
more as one matmul per run of consecutive heads on views instead. Per game shape (the
game's ego width, K = 3 replicas, H = 4 heads, 8 games per replica, each with one of the 4
partners, the ego to move in about half of them), the policy heads of `--steps` such acting
steps, both ways in one process, alternating, medians of `--rounds`; whether the outputs
are equal. Writes `benchmarks/results/subset_layers.json`.

    OMP_NUM_THREADS=1 python -m benchmarks.subset_layers
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np
import torch

from benchmarks._common import median_seconds, write_result
from rllib_conv import envs
from rllib_conv.modules.packed import ego_stack
from rllib_conv.modules.packed.ego_stack import HEAD_POLICY, EgoStack

REPLICAS, HEADS, GAMES_PER_REPLICA = 3, 4, 8


def stack_for(game: str) -> EgoStack:
    """A K x H ego stack of `game`'s shapes (its record's width; random weights)."""
    env = envs.make(game)
    agent = env.possible_agents[0]
    obs_dim, actions = env.observation_space(agent)["observation"].shape[0], env.action_space(agent).n
    hidden = envs.game(game).training.hidden
    return EgoStack(
        observation_space=gym.spaces.Box(-1.0, 1.0, (obs_dim,), np.float32),
        action_space=gym.spaces.Discrete(actions),
        model_config={
            "replicas": REPLICAS,
            "heads": HEADS,
            "task": {"hidden": hidden},
            "head": {"hidden": hidden, "use_task_logits": True},
            "task_seeds": list(range(REPLICAS)),
            "head_seeds": [[10 * r + h for h in range(HEADS)] for r in range(REPLICAS)],
            "sample_seeds": list(range(REPLICAS)),
        },
    )


def acting_steps(stack: EgoStack, steps: int, seed: int = 0) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """`steps` acting steps: (head ids, latent rows padded per head [G, rows, z]) for the heads with a waiting game."""
    rng = np.random.default_rng(seed)
    z_dim = stack.task_forward(torch.zeros(1, 1, stack.observation_space.shape[0]), None, torch.tensor([0])).z.shape[-1]
    out = []
    for _ in range(steps):
        counts = np.zeros(REPLICAS * HEADS, dtype=int)
        for r in range(REPLICAS):
            for partner in rng.integers(0, HEADS, GAMES_PER_REPLICA):
                counts[r * HEADS + partner] += rng.random() < 0.5  # the ego to move in about half the games
        heads = np.flatnonzero(counts)
        if len(heads):
            z = torch.relu(
                torch.randn(
                    len(heads), int(counts.max()), z_dim, generator=torch.Generator().manual_seed(int(rng.integers(1 << 31)))
                )
            )
            out.append((torch.as_tensor(heads), z))
    return out


@torch.no_grad()
def run(stack: EgoStack, steps: list[tuple[torch.Tensor, torch.Tensor]], views_from: int) -> list[torch.Tensor]:
    """The policy heads' outputs of every step with `VIEWS_FROM` set to `views_from`."""
    ego_stack.VIEWS_FROM = views_from
    return [stack._heads("head_pi", HEAD_POLICY, z, heads) for heads, z in steps]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200, help="acting steps per timed run")
    parser.add_argument("--rounds", type=int, default=5, help="timed runs per way, alternating")
    parser.add_argument("--games", nargs="+", default=["bandit", "blocks", "overcooked", "hanabi"])
    args = parser.parse_args()
    torch.set_num_threads(1)
    shipped, rows = ego_stack.VIEWS_FROM, {}
    for game in args.games:
        stack = stack_for(game)
        steps = acting_steps(stack, args.steps)
        ways = {"copy": lambda: run(stack, steps, 1 << 62), "views": lambda: run(stack, steps, 0)}
        times = median_seconds(ways, args.rounds)
        equal = all(torch.equal(a, b) for a, b in zip(run(stack, steps, 1 << 62), run(stack, steps, 0)))
        hidden = envs.game(game).training.hidden
        rows[game] = {
            "hidden": hidden,
            "copy_ms_per_step": 1e3 * times["copy"] / len(steps),
            "views_ms_per_step": 1e3 * times["views"] / len(steps),
            "copy_over_views": times["copy"] / times["views"],
            "equal": equal,
            "shipped_way": "views" if hidden * hidden >= shipped else "copy",
        }
    ego_stack.VIEWS_FROM = shipped
    print(f"{'game':11} {'hidden':>6} {'copy ms/step':>12} {'views ms/step':>13} {'copy/views':>10} {'equal':>5} {'shipped':>7}")
    for game, r in rows.items():
        print(
            f"{game:11} {r['hidden']:6d} {r['copy_ms_per_step']:12.3f} {r['views_ms_per_step']:13.3f} "
            f"{r['copy_over_views']:10.2f} {str(r['equal']):>5} {r['shipped_way']:>7}"
        )
    write_result(
        "subset_layers",
        {"replicas": REPLICAS, "heads": HEADS, "games_per_replica": GAMES_PER_REPLICA, "steps": args.steps, "games": rows},
    )


if __name__ == "__main__":
    main()
