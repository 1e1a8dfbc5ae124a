"""Scoring a series of episodes one game at a time (`play_episodes`) against games side by side (`play_batched`).

Every evaluation of fixed players (an adaptation curve's points, `evaluate`, the held-out
sets, self-play's gate, cross-play, `pair`) scores a series of episodes. Played one game at
a time, each move is one forward pass of a network on one row; Hanabi's adapt stage spent
~70% of its core-seconds there (200 episodes at each of a curve's ~45 points). `play_batched`
steps up to 64 games together, one forward pass per seat and step. Per game, two networks
the size of the game's ego (two hidden layers of the record's width, random weights,
sampling) play `--episodes` episodes each way, alternating, medians of `--rounds`; with
`--hanabi-run` (a `reproduce hanabi` folder past its train stage) also a trained ego's head
with a trained self-play partner, as an adaptation curve's point plays them; and a network ego
with scripted partners (blocks, Hanabi, Level-Based Foraging), whose rules still run one game
at a time inside a batched series; and blocks' convention posterior playing its plan. Writes
`benchmarks/results/batched_play.json`.

    OMP_NUM_THREADS=1 python -m benchmarks.batched_play --hanabi-run /work/repro/h1/hanabi
"""

from __future__ import annotations

import argparse
import functools
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from benchmarks._common import median_seconds, write_result
from rllib_conv import envs, partners
from rllib_conv.adaptation.convention_posterior import ConventionPosterior, PosteriorPlayer
from rllib_conv.envs.blocks.keys import blocks_observation
from rllib_conv.partners.base import Partner
from rllib_conv.partners.blocks import TEST_PERMUTATIONS, TRAIN_PERMUTATIONS, BlocksLeader, PermutationPartner
from rllib_conv.partners.episodes import episode_stream, play_batched, play_episodes
from rllib_conv.partners.trained import PolicyPartner, TrainedPolicyPartner
from rllib_conv.training.evaluate import ego_head_partner, load_module

GAMES = {"bandit": {}, "blocks": {}, "hanabi": {}, "lbf": {"players": 3}, "overcooked": {}}


def mlp_seat(name: str, obs_dim: int, actions: int, hidden: int, seed: int) -> PolicyPartner:
    """A sampling player: two tanh layers of `hidden` units, random weights (seeded)."""
    torch.manual_seed(seed)
    net = torch.nn.Sequential(
        torch.nn.Linear(obs_dim, hidden), torch.nn.Tanh(), torch.nn.Linear(hidden, hidden), torch.nn.Tanh(),
        torch.nn.Linear(hidden, actions),
    )  # fmt: skip
    return PolicyPartner(name, lambda obs, mask: net(obs).masked_fill(mask == 0, -1e9), greedy=False, seed=seed)


Case = tuple[functools.partial, Callable[[], dict[str, Partner]]]  # an env factory, a factory of fresh seats


def random_network_case(game: str, env_config: dict) -> Case:
    """`game` with a network of the ego's width in every seat."""
    make = functools.partial(envs.make_scored, game, **env_config)
    env, hidden = make(), envs.game(game).training.hidden

    def seats() -> dict[str, PolicyPartner]:
        return {
            agent: mlp_seat(agent, env.observation_space(agent)["observation"].shape[0], env.action_space(agent).n, hidden, i)
            for i, agent in enumerate(env.possible_agents)
        }

    return make, seats


SCRIPTED = ("blocks-perm", "hanabi-scripted", "lbf-heuristics")  # populations whose first member is scripted


def scripted_case(population: str) -> Case:
    """A network of the ego's width in the ego's seat, the population's first (scripted) member in every partner seat."""
    pop = partners.get(population)
    make = functools.partial(envs.make_scored, pop.env, **pop.env_config)
    env, hidden = make(), envs.game(pop.env).training.hidden
    ego = next(a for a in env.possible_agents if a not in pop.partner_agents)
    obs_dim, actions = env.observation_space(ego)["observation"].shape[0], env.action_space(ego).n

    def seats() -> dict[str, PolicyPartner]:
        member = pop.partners[0].build()
        return {a: mlp_seat(a, obs_dim, actions, hidden, 0) if a == ego else member for a in env.possible_agents}

    return make, seats


def posterior_case() -> Case:
    """Blocks: the convention posterior's player with its planner (no evidence yet: the plan against the training
    partners' mixture; the heads are scripted leaders, the adapting head a network) with a held-out permutation partner.

    It learned within an episode until its plan was seen to fix every move (2026-12-08); now it plays batched."""
    models = [PermutationPartner(f"t{i}", list(p)) for i, p in enumerate(TRAIN_PERMUTATIONS)]
    leaders = [BlocksLeader(f"l{i}", list(p)) for i, p in enumerate(TRAIN_PERMUTATIONS)]
    planner, make = envs.best_response("blocks", {}, "player_0"), functools.partial(envs.make_scored, "blocks")
    env = make()
    obs_dim, actions = env.observation_space("player_0")["observation"].shape[0], env.action_space("player_0").n

    def seats() -> dict[str, Partner]:
        adapting = mlp_seat("adapting", obs_dim, actions, envs.game("blocks").training.hidden, 0)
        posterior = ConventionPosterior(models, blocks_observation)
        player = PosteriorPlayer("ego", posterior, leaders, adapting, planner=planner)
        return {"player_0": player, "player_1": PermutationPartner("new", list(TEST_PERMUTATIONS[0]))}

    return make, seats


def trained_hanabi_case(run: Path) -> Case:
    """The first ours (lam 0.5) ego of a Hanabi reproduction, its first head, with the population's last partner (a test one).

    Fresh players per series, as an adaptation curve's point builds them: the ego's memo of probabilities per state
    (`PolicyPartner(memo=True)`, one game at a time) starts empty."""
    checkpoint = sorted(run.glob("runs/*__modular-lam0.5/point_0/seed=0/checkpoint_000000"))[0]
    module = load_module(checkpoint)
    population = checkpoint.parents[2].name.split("__")[0]
    partner = sorted((run / "populations" / population / "partners").iterdir())[-1]
    other = TrainedPolicyPartner(partner.name, str(partner), greedy=True)

    def seats() -> dict[str, PolicyPartner]:
        return {"player_0": ego_head_partner(module, module.head_ids()[0]), "player_1": other}

    return functools.partial(envs.make_scored, "hanabi"), seats


def measure(case: Case, episodes: int, rounds: int) -> dict[str, float]:
    """Median seconds of a series one game at a time and batched, their ratio, and each one's mean score."""
    make, seats = case
    scores: dict[str, np.ndarray] = {}

    def ways(name: str) -> Callable[[], None]:
        def run() -> None:
            play = play_episodes(make(), seats(), episodes) if name == "one_by_one" else play_batched(make, seats(), episodes)
            scores[name] = play

        return run

    times = median_seconds({name: ways(name) for name in ("one_by_one", "batched")}, rounds)
    moves = sum(episode_lengths(make, seats(), episodes))
    return {
        "episodes": episodes,
        "moves_per_episode": moves / episodes,
        "one_by_one_s": times["one_by_one"],
        "batched_s": times["batched"],
        "speedup": times["one_by_one"] / times["batched"],
        "mean_one_by_one": float(scores["one_by_one"].mean()),
        "mean_batched": float(scores["batched"].mean()),
    }


def episode_lengths(make: functools.partial, seats: dict, episodes: int) -> list[int]:
    """The env steps of each episode of the series (one game at a time)."""
    stream = episode_stream(make(), seats, 0)
    return [steps for _, (_, steps) in zip(range(episodes), stream)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=200, help="episodes per series (an adaptation point's default)")
    parser.add_argument("--rounds", type=int, default=5, help="timed series per way, alternating")
    parser.add_argument("--hanabi-run", type=Path, help="a `reproduce hanabi` game folder past its train stage")
    args = parser.parse_args()
    torch.set_num_threads(1)
    cases = {f"{game}, random networks": random_network_case(game, env_config) for game, env_config in GAMES.items()}
    cases |= {f"{population}: network ego, scripted partners": scripted_case(population) for population in SCRIPTED}
    cases["blocks: convention posterior, planned"] = posterior_case()
    if args.hanabi_run:
        cases["hanabi, trained ego and partner"] = trained_hanabi_case(args.hanabi_run)
    rows = {name: measure(case, args.episodes, args.rounds) for name, case in cases.items()}
    print(f"{'case':48} {'moves/ep':>8} {'one by one s':>12} {'batched s':>9} {'speedup':>7} {'means':>13}")
    for name, r in rows.items():
        print(
            f"{name:48} {r['moves_per_episode']:8.1f} {r['one_by_one_s']:12.3f} {r['batched_s']:9.3f} "
            f"{r['speedup']:7.2f} {r['mean_one_by_one']:6.2f}/{r['mean_batched']:.2f}"
        )
    write_result("batched_play", {"episodes": args.episodes, "rounds": args.rounds, "cases": rows})


if __name__ == "__main__":
    main()
