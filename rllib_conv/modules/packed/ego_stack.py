"""`EgoStack`: the weights of K replica egos (task module + H heads each) as stacked tensors, run as batched matmuls.

Replicas (the seeds of one experiment, or the curves of one adaptation) train in one
algorithm. Were each its own set of small torch modules, every forward and backward pass
and every optimizer step would cost one Python-level op per layer per module per replica;
on our 30-500-unit networks that overhead is nearly all the time. Here every layer of
every replica's task module is one tensor `[K, out, in]` and every layer of every head one
tensor `[K, H, out, in]`, so one `baddbmm` runs a layer for all of them.

The stacked tensors hold exactly the weights of K independent `TaskModule`s and K x H
`PartnerHeadModule`s: `task_state(r)` / `head_state(r, h)` read one out under the plain
modules' parameter names, `load_task` / `load_head` write one in, and initialisation copies
freshly built plain modules (their own seeds), so a replica starts, and through the
elementwise Adam and per-replica gradient clipping of the learner also trains, exactly as
it would alone.

The module has no agent mapped to it (it is the `stack` module of `StackedEgoMultiRLModule`);
`HeadView`s, one per (replica, head), are what agents map to.

The H heads the views see may add the outputs of other heads that hold the weights
(`head_members`: the ego with one head per partner seat and partner, `model.heads: seat`):
head h's logits and values are then the sum over its S members, which are what trains.
`head_state` hands such a head out as one plain head of S times the width whose layers are
its members' side by side (`summed_head_state`): the same outputs, so everything that reads
a saved ego reads it unchanged.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import torch
from ray.rllib.core.rl_module.torch import TorchRLModule
from torch import nn

from rllib_conv.envs.oracles import oracle_for
from rllib_conv.modules.mlp import masked_logits
from rllib_conv.modules.partner_head import PartnerHeadModule
from rllib_conv.modules.task_module import TaskModule

# The Linear layers of the plain modules, by their parameter-name prefix (mlp() puts a ReLU between each).
TASK_POLICY = ("pi_tower.0", "pi_tower.2")
TASK_LOGITS_LAYER = "pi_out.0"
TASK_VALUE = ("vf.0", "vf.2", "vf.4")
HEAD_POLICY = ("pi.0", "pi.2", "pi.4")
HEAD_VALUE = ("vf.0", "vf.2", "vf.4")


def _name(kind: str, layer: str, part: str) -> str:
    return f"{kind}__{layer.replace('.', '_')}__{part}"


def _linear(x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
    """x [G, N, in] through G stacked Linear layers (weight [G, out, in], bias [G, out]) -> [G, N, out]."""
    return torch.baddbmm(bias.unsqueeze(1), x, weight.transpose(1, 2))


# From this many weights per group (a 256 x 256 layer) a subset of stacked layers runs as one matmul per run of
# consecutive groups on views of the weights, not on a copy of the picked ones: an acting step of a Hanabi ego uses
# some of its 500 x 500 heads, and copying them was 19% of a training trial (`benchmarks/subset_layers.py`); on
# smaller layers the copy costs less than the extra calls. The same products either way.
VIEWS_FROM = 256 * 256


def group_runs(groups: list[int]) -> list[tuple[int, int, int]]:
    """Runs of consecutive ids in `groups`: (position in `groups`, first id, length) each."""
    runs: list[tuple[int, int, int]] = []
    for i, g in enumerate(groups):
        if runs and g == runs[-1][1] + runs[-1][2]:
            runs[-1] = (runs[-1][0], runs[-1][1], runs[-1][2] + 1)
        else:
            runs.append((i, g, 1))
    return runs


def subset_linear(x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor, groups: torch.Tensor | None) -> torch.Tensor:
    """`_linear` of x [len(groups), N, in] through the stacked layers `groups` of weight [G, out, in] (None: all G in order)."""
    if groups is None:
        return _linear(x, weight, bias)
    if weight[0].numel() < VIEWS_FROM:
        return _linear(x, weight.index_select(0, groups), bias.index_select(0, groups))
    parts = [_linear(x[i : i + n], weight[g : g + n], bias[g : g + n]) for i, g, n in group_runs(groups.tolist())]
    return parts[0] if len(parts) == 1 else torch.cat(parts)


def summed_head_state(states: list[dict[str, torch.Tensor]]) -> dict[str, torch.Tensor]:
    """One `PartnerHeadModule` state, `hidden` S times the members', whose outputs are the sum of the S heads `states`.

    Each MLP's first layer stacks the members' rows (all read z), the middle ones are
    block-diagonal (ReLU acts per unit, so the blocks stay apart) and the last one puts the
    members' columns side by side with their biases added.
    """
    if len(states) == 1:
        return dict(states[0])
    out = {}
    for first, *middle, last in (HEAD_POLICY, HEAD_VALUE):
        out[f"{first}.weight"] = torch.cat([s[f"{first}.weight"] for s in states])
        for layer in middle:
            out[f"{layer}.weight"] = torch.block_diag(*[s[f"{layer}.weight"] for s in states])
        for layer in (first, *middle):
            out[f"{layer}.bias"] = torch.cat([s[f"{layer}.bias"] for s in states])
        out[f"{last}.weight"] = torch.cat([s[f"{last}.weight"] for s in states], dim=1)
        out[f"{last}.bias"] = torch.stack([s[f"{last}.bias"] for s in states]).sum(0)
    return out


class StackedTask(NamedTuple):
    """The task modules' output on rows [K, N]: latent z, masked task logits, task value (None where not asked for)."""

    z: torch.Tensor
    logits: torch.Tensor
    value: torch.Tensor | None


class EgoStack(TorchRLModule):
    """K replicas' task modules and H heads each, stacked (see the module docstring).

    `model_config`: `replicas` (K), `heads` (H), `task` and `head` (the plain modules'
    model configs, e.g. sizes and `oracle`/`use_task_logits`), `task_seeds` ([K] init
    seeds), `head_seeds` ([K][W] init seeds of the W heads holding weights), `head_members`
    (per head, the S of the W it adds; default: head h is weight head h), `sample_seeds`
    ([K]: the generator each replica's exploration draws its actions from), `few_situations`
    (default False: the game has few distinct observations, so training forwards run once per
    distinct one).
    """

    def setup(self) -> None:
        cfg = self.model_config
        self.replicas, self.heads = int(cfg["replicas"]), int(cfg["heads"])
        weight_heads = len(cfg["head_seeds"][0])
        members = [list(m) for m in cfg.get("head_members") or [[h] for h in range(self.heads)]]
        if (
            len(members) != self.heads
            or len({len(m) for m in members}) != 1
            or not all(0 <= w < weight_heads for m in members for w in m)
        ):
            raise ValueError(
                f"head_members must give each of the {self.heads} heads as many of the {weight_heads} weight heads; got {members}"
            )
        self.members, self.seats = members, len(members[0])
        # Which weight heads (of all K x W) each of the K x H heads adds; None: head h is weight head h.
        self._weights_of = None
        if members != [[h] for h in range(weight_heads)]:
            replica_offsets = torch.arange(self.replicas).view(-1, 1, 1) * weight_heads
            self._weights_of = (replica_offsets + torch.tensor(members)).reshape(-1, self.seats)
        task_cfg, head_cfg = dict(cfg["task"]), dict(cfg["head"])
        self.use_task_logits = bool(head_cfg.get("use_task_logits", True))
        self.few_situations = bool(cfg.get("few_situations", False))
        self._oracle = (
            oracle_for(task_cfg["oracle"]["env"], task_cfg["oracle"].get("env_config", {})) if task_cfg.get("oracle") else None
        )
        self.samplers = [torch.Generator().manual_seed(int(seed)) for seed in cfg["sample_seeds"]]
        tasks = [self._plain(TaskModule, {**task_cfg, "init_seed": seed}) for seed in cfg["task_seeds"]]
        heads = [[self._plain(PartnerHeadModule, {**head_cfg, "init_seed": seed}) for seed in row] for row in cfg["head_seeds"]]
        for layer in (*TASK_POLICY, TASK_LOGITS_LAYER, *TASK_VALUE):
            for part in ("weight", "bias"):
                value = torch.stack([t.state_dict()[f"{layer}.{part}"] for t in tasks])
                self.register_parameter(_name("task", layer, part), nn.Parameter(value))
        for kind, layers in (("head_pi", HEAD_POLICY), ("head_vf", HEAD_VALUE)):
            for layer in layers:
                for part in ("weight", "bias"):
                    key = f"{layer}.{part}"
                    value = torch.stack([torch.stack([h.state_dict()[key] for h in row]) for row in heads])
                    self.register_parameter(_name(kind, layer, part), nn.Parameter(value))

    def _plain(self, cls: type, model_config: dict[str, Any]) -> Any:
        """A freshly built plain module (its weights initialised from its own seed)."""
        return cls(observation_space=self.observation_space, action_space=self.action_space, model_config=model_config)

    # --- parameters by role (freezing, learning rates, clipping) ---------------------------------------

    def task_parameters(self, z_only: bool = False) -> list[nn.Parameter]:
        """The task modules' stacked parameters ([K, ...]); `z_only`: just the policy tower's (the layers making z)."""
        layers = TASK_POLICY if z_only else (*TASK_POLICY, TASK_LOGITS_LAYER, *TASK_VALUE)
        return [getattr(self, _name("task", layer, part)) for layer in layers for part in ("weight", "bias")]

    def head_parameters(self) -> list[nn.Parameter]:
        """The heads' stacked parameters ([K, H, ...])."""
        return [
            getattr(self, _name(kind, layer, part))
            for kind, layers in (("head_pi", HEAD_POLICY), ("head_vf", HEAD_VALUE))
            for layer in layers
            for part in ("weight", "bias")
        ]

    # --- one replica's weights under the plain modules' names ---------------------------------------------

    def task_state(self, replica: int) -> dict[str, torch.Tensor]:
        """Replica `replica`'s task module weights, as a `TaskModule` state dict."""
        return {
            f"{layer}.{part}": getattr(self, _name("task", layer, part))[replica].detach().clone()
            for layer in (*TASK_POLICY, TASK_LOGITS_LAYER, *TASK_VALUE)
            for part in ("weight", "bias")
        }

    def head_state(self, replica: int, head: int) -> dict[str, torch.Tensor]:
        """Head `head` of replica `replica`, as a `PartnerHeadModule` state dict (the sum of its members: `summed_head_state`)."""
        return summed_head_state([self.weight_head_state(replica, w) for w in self.members[head]])

    def weight_head_state(self, replica: int, weight_head: int) -> dict[str, torch.Tensor]:
        """Weight head `weight_head` of replica `replica` (a team head, or one seat head of `head_members`), as a plain head's state."""
        return {
            f"{layer}.{part}": getattr(self, _name(kind, layer, part))[replica, weight_head].detach().clone()
            for kind, layers in (("head_pi", HEAD_POLICY), ("head_vf", HEAD_VALUE))
            for layer in layers
            for part in ("weight", "bias")
        }

    @torch.no_grad()
    def load_task(self, replica: int, state: dict[str, torch.Tensor]) -> None:
        """Write a `TaskModule` state dict into replica `replica`'s task module (in place: optimizers keep their tensors)."""
        for layer in (*TASK_POLICY, TASK_LOGITS_LAYER, *TASK_VALUE):
            for part in ("weight", "bias"):
                getattr(self, _name("task", layer, part))[replica].copy_(state[f"{layer}.{part}"])

    @torch.no_grad()
    def load_head(self, replica: int, head: int, state: dict[str, torch.Tensor]) -> None:
        """Write a `PartnerHeadModule` state dict into head `head` of replica `replica` (in place; a head of one member)."""
        if self._weights_of is not None:
            raise ValueError(f"head {head} adds weight heads {self.members[head]}: a plain head's state does not split into them")
        self.load_weight_head(replica, head, state)

    @torch.no_grad()
    def load_weight_head(self, replica: int, weight_head: int, state: dict[str, torch.Tensor]) -> None:
        """Write a `PartnerHeadModule` state dict into weight head `weight_head` of replica `replica` (a seat head, or a team head of one member)."""
        for kind, layers in (("head_pi", HEAD_POLICY), ("head_vf", HEAD_VALUE)):
            for layer in layers:
                for part in ("weight", "bias"):
                    getattr(self, _name(kind, layer, part))[replica, weight_head].copy_(state[f"{layer}.{part}"])

    # --- batched forward passes ----------------------------------------------------------------------------

    def task_forward(
        self, obs: torch.Tensor, mask: torch.Tensor | None, replicas: torch.Tensor | None = None, value: bool = True
    ) -> StackedTask:
        """Task modules on rows: obs [G, N, d], mask [G, N, A] -> z [G, N, z], logits [G, N, A], value [G, N].

        Group g runs replica `replicas[g]`'s task module (default: all K replicas, in order).
        `value=False` leaves out the value tower (`value` is then None): acting reads no values,
        and at Hanabi's width the tower is as much arithmetic as the policy's.
        """

        def layer_of(x: torch.Tensor, layer: str) -> torch.Tensor:
            weight, bias = (getattr(self, _name("task", layer, part)) for part in ("weight", "bias"))
            return subset_linear(x, weight, bias, replicas)

        h = obs
        for layer in TASK_POLICY:
            h = torch.relu(layer_of(h, layer))
        z = h
        if self._oracle is not None:
            flat = obs.detach().reshape(-1, obs.shape[-1]).cpu().numpy()
            optimal = torch.as_tensor(self._oracle(flat), device=obs.device).reshape(*obs.shape[:-1], -1)
            logits = torch.clamp(torch.log(optimal), min=torch.finfo(obs.dtype).min)
        else:
            logits = layer_of(z, TASK_LOGITS_LAYER)
        if not value:
            return StackedTask(z, masked_logits(logits, mask), None)
        v = obs
        for i, layer in enumerate(TASK_VALUE):
            v = layer_of(v, layer)
            if i < len(TASK_VALUE) - 1:
                v = torch.relu(v)
        return StackedTask(z, masked_logits(logits, mask), v.squeeze(-1))

    def _heads(self, kind: str, layers: tuple[str, ...], z: torch.Tensor, heads: torch.Tensor | None = None) -> torch.Tensor:
        """Head MLPs `kind` on z [K*H or G, M, z]; `heads` [G] picks which (replica*H + head) each group is (default: all, in order).

        A head of several members (`head_members`) runs each of them on its rows and adds their outputs.
        """
        if self._weights_of is None:
            return self._weight_heads(kind, layers, z, heads)
        members = self._weights_of if heads is None else self._weights_of.index_select(0, heads)
        g, m, d = z.shape
        zz = z.unsqueeze(1).expand(g, self.seats, m, d).reshape(g * self.seats, m, d)
        return self._weight_heads(kind, layers, zz, members.reshape(-1)).reshape(g, self.seats, m, -1).sum(1)

    def _weight_heads(self, kind: str, layers: tuple[str, ...], z: torch.Tensor, heads: torch.Tensor | None) -> torch.Tensor:
        """The weight heads' MLPs `kind` on z [G, M, z]; `heads` [G] picks which (replica*W + weight head) each group is (default: all)."""
        x = z
        for i, layer in enumerate(layers):
            w, b = getattr(self, _name(kind, layer, "weight")), getattr(self, _name(kind, layer, "bias"))
            x = subset_linear(x, w.reshape(-1, *w.shape[2:]), b.reshape(-1, *b.shape[2:]), heads)
            if i < len(layers) - 1:
                x = torch.relu(x)
        return x

    def head_outputs(self, z: torch.Tensor) -> torch.Tensor:
        """Every head's own output on every row of its replica: z [K, N, z] -> [K, H, N, A] (before the task logits are added)."""
        k, n, d = z.shape
        zz = z.unsqueeze(1).expand(k, self.heads, n, d).reshape(k * self.heads, n, d)
        return self._heads("head_pi", HEAD_POLICY, zz).reshape(k, self.heads, n, -1)

    def head_values(self, z: torch.Tensor, heads: torch.Tensor | None = None) -> torch.Tensor:
        """Head values on rows z [G, M, z] (group g = head `heads[g]`; default all K*H heads in order) -> [G, M]."""
        return self._heads("head_vf", HEAD_VALUE, z, heads).squeeze(-1)

    def policy_logits(self, head_out: torch.Tensor, task_logits: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor:
        """The ego's masked policy logits from a head's output and the task logits (BaselineModular: the head's alone)."""
        return masked_logits(task_logits + head_out if self.use_task_logits else head_out, mask)

    def _forward(self, batch: dict[str, Any], **kwargs: Any) -> dict[str, Any]:
        raise RuntimeError("the ego stack has no agent of its own; its heads act through their HeadView modules")


def pad_rows(parts: list[torch.Tensor]) -> tuple[torch.Tensor, list[int]]:
    """Stack row blocks of different lengths into [G, max rows, ...] (zero rows at the end); return it and the lengths."""
    sizes = [len(p) for p in parts]
    longest = max(sizes) if sizes else 0
    out = parts[0].new_zeros((len(parts), longest, *parts[0].shape[1:]))
    for i, p in enumerate(parts):
        out[i, : len(p)] = p
    return out, sizes


def unpad(stacked: torch.Tensor, sizes: list[int]) -> list[torch.Tensor]:
    """The inverse of `pad_rows` for its output's leading two dims."""
    return [stacked[i, :n] for i, n in enumerate(sizes)]
