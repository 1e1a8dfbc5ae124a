"""Small MLP builder with the orthogonal initialisation the paper's code used (SB3 style)."""

from __future__ import annotations

import math

import torch
from torch import nn


def mlp(
    sizes: list[int], out_gain: float | None = None, final_relu: bool = False, generator: torch.Generator | None = None
) -> nn.Sequential:
    """Return Linear/ReLU layers through `sizes` (input first), orthogonally initialised.

    Hidden layers use gain sqrt(2); the last layer uses `out_gain` (SB3: 0.01 for policy
    logits, 1.0 for values) or sqrt(2) if it is followed by a ReLU. Biases start at 0.
    `generator` draws the initial weights (default: torch's global RNG).
    """
    layers: list[nn.Module] = []
    for i, (n_in, n_out) in enumerate(zip(sizes[:-1], sizes[1:])):
        last = i == len(sizes) - 2
        linear = nn.Linear(n_in, n_out)
        gain = math.sqrt(2) if not last or final_relu or out_gain is None else out_gain
        nn.init.orthogonal_(linear.weight, gain=gain, generator=generator)
        nn.init.zeros_(linear.bias)
        layers.append(linear)
        if not last or final_relu:
            layers.append(nn.ReLU())
    return nn.Sequential(*layers)


def masked_logits(logits: torch.Tensor, action_mask: torch.Tensor | None) -> torch.Tensor:
    """Push illegal actions' logits to the float minimum, so they get zero probability."""
    if action_mask is None:
        return logits
    return logits + torch.clamp(torch.log(action_mask), min=torch.finfo(logits.dtype).min)


def seeded_generator(seed: int | None) -> torch.Generator | None:
    """A torch generator seeded with `seed`, or None (torch's global RNG) without one."""
    return None if seed is None else torch.Generator().manual_seed(int(seed))
