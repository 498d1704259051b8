"""The population SPN: fixed random weights, per-individual genomes, as a TensorDictModule."""

from __future__ import annotations

import math

import torch
from torch import nn

from spn_torchrl.config import SNNConfig
from spn_torchrl.envs import TaskSpec
from spn_torchrl.snn import neurons
from spn_torchrl.snn.observations import Norm, normalize

GENOME_KINDS = ("connections", "weights")


def init_fixed_weights(
    n_obs: int, n_act: int, hidden: int, generator: torch.Generator
) -> tuple[torch.Tensor, torch.Tensor]:
    """Kaiming-normal (fan_in, relu) weights W1 [hidden, n_obs] and W2 [n_act, hidden], no bias."""
    w1 = torch.empty(hidden, n_obs)
    w2 = torch.empty(n_act, hidden)
    nn.init.kaiming_normal_(w1, mode="fan_in", nonlinearity="relu", generator=generator)
    nn.init.kaiming_normal_(w2, mode="fan_in", nonlinearity="relu", generator=generator)
    return w1, w2


def genome_size(w1: torch.Tensor, w2: torch.Tensor) -> int:
    """Number of genes: one per synapse of both layers."""
    return w1.numel() + w2.numel()


class PopulationSPN(nn.Module):
    """The SPN of SPEC.md for a population of genomes [P, D].

    The fixed weights are one pair, W1 [h, n] and W2 [m, h], or one pair for each of R runs evolved in lockstep
    ([R, h, n] and [R, m, h]); then each genome uses the pair of its run (``runs`` of :meth:`set_genomes`).
    ``genome_kind="connections"``: genes are connection scores, a synapse exists where
    ``sigmoid(score) >= snn.score_threshold``, and its weight is the fixed one. ``"weights"``: genes are the
    weights themselves (no mask). Call :meth:`set_genomes` once per genome set (and
    :meth:`set_observation_norm` where observations are normalised); :meth:`forward` maps observations [P, n]
    to actions ([P, m] clipped, or [P] indices when ``discrete``) and the hidden
    spike count [P] of that environment step.
    """

    def __init__(
        self,
        w1: torch.Tensor,
        w2: torch.Tensor,
        *,
        genome_kind: str = "connections",
        snn: SNNConfig = neurons.SNN,
        discrete: bool = False,
        action_low: torch.Tensor | None = None,
        action_high: torch.Tensor | None = None,
    ) -> None:
        super().__init__()
        if genome_kind not in GENOME_KINDS:
            raise ValueError(f"genome_kind must be one of {GENOME_KINDS}, got {genome_kind!r}")
        stacked = w1.ndim == 3 and w2.ndim == 3 and w1.shape[0] == w2.shape[0]
        if not (stacked or (w1.ndim == 2 and w2.ndim == 2)) or w2.shape[-1] != w1.shape[-2]:
            raise ValueError(
                f"fixed weights must be [h, n] and [m, h] (or [R, h, n] and [R, m, h]), got {tuple(w1.shape)} and "
                f"{tuple(w2.shape)}"
            )
        self.register_buffer("w1", w1.detach().clone().float())
        self.register_buffer("w2", w2.detach().clone().float())
        m = w2.shape[-2]
        low = torch.full((m,), -math.inf) if action_low is None else torch.as_tensor(action_low, dtype=torch.float32)
        high = torch.full((m,), math.inf) if action_high is None else torch.as_tensor(action_high, dtype=torch.float32)
        self.register_buffer("action_low", low.reshape(m).clone())
        self.register_buffer("action_high", high.reshape(m).clone())
        self.genome_kind = genome_kind
        self.snn = snn
        self.score_threshold = snn.score_threshold
        self.discrete = discrete
        self.time_steps, self.decay, self.v_th = snn.time_steps, snn.decay, snn.v_threshold
        self.w1_eff: torch.Tensor | None = None
        self.w2_eff: torch.Tensor | None = None
        self.obs_norm: Norm | None = None  # (mean, inv_std) [P or 1, n] applied to observations, or None
        # the hidden layer's spikes from thresholds on its current (neurons.threshold_spikes): derived, not saved
        thresholds = neurons.spike_thresholds(self.time_steps, self.decay, self.v_th)
        self.register_buffer("spike_thresholds", thresholds, persistent=False)
        self.register_buffer("spike_pattern", neurons.spike_pattern(self.time_steps), persistent=False)

    @property
    def genome_size(self) -> int:
        return self.w1.shape[-2:].numel() + self.w2.shape[-2:].numel()

    @property
    def runs(self) -> int | None:
        """How many runs' fixed weights it holds (None: one pair, shared by every genome)."""
        return self.w1.shape[0] if self.w1.ndim == 3 else None

    def masks(self, genomes: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Connection masks [P, h, n] and [P, m, h] (all ones for weight genomes)."""
        g1, g2 = self._split(genomes)
        if self.genome_kind == "weights":
            return torch.ones_like(g1, dtype=torch.bool), torch.ones_like(g2, dtype=torch.bool)
        return torch.sigmoid(g1) >= self.score_threshold, torch.sigmoid(g2) >= self.score_threshold

    def effective_weights(
        self, genomes: torch.Tensor, runs: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Per-individual weights [P, h, n] and [P, m, h] that the forward pass uses; ``runs`` [P] names each
        genome's run where the SPN holds several runs' fixed weights (the same products as one run's SPN)."""
        if (runs is None) != (self.runs is None):
            raise ValueError(
                f"runs must be given exactly when the SPN holds several runs' fixed weights (it holds {self.runs})"
            )
        if runs is not None:
            runs = torch.as_tensor(runs, dtype=torch.long, device=self.w1.device)
            if runs.shape != (genomes.shape[0],):
                raise ValueError(
                    f"runs must be [{genomes.shape[0]}], one run index per genome, got {tuple(runs.shape)}"
                )
        if self.genome_kind == "weights":
            return self._split(genomes.to(self.w1))
        x1, x2 = self.masks(genomes)
        if runs is None:
            return self.w1 * x1, self.w2 * x2
        return self.w1[runs] * x1, self.w2[runs] * x2

    def set_genomes(self, genomes: torch.Tensor, runs: torch.Tensor | None = None) -> None:
        """Compute the effective weights of a genome set (of the ``runs`` named, see :meth:`effective_weights`)
        once, for every later forward call."""
        w1, w2 = self.effective_weights(genomes.to(self.w1.device), runs)
        # input-major [P, n, h] and [P, h, m], the layout neurons.spn_dynamics multiplies fastest
        self.w1_eff, self.w2_eff = w1.transpose(1, 2).contiguous(), w2.transpose(1, 2).contiguous()

    def set_observation_norm(self, norm: Norm | None) -> None:
        """The normalisation ``(x - mean) * inv_std`` of every later forward call (each [P, n] or [1, n]), or
        None for raw observations."""
        self.obs_norm = None if norm is None else tuple(t.to(self.w1.device, torch.float32) for t in norm)

    def forward(self, observation: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if self.w1_eff is None:
            raise RuntimeError("PopulationSPN.set_genomes(genomes) must be called before the forward pass")
        obs = normalize(observation.to(self.w1_eff.dtype), self.obs_norm)
        if obs.shape[0] != self.w1_eff.shape[0]:
            raise ValueError(f"observation batch {obs.shape[0]} != number of genomes {self.w1_eff.shape[0]}")
        out, spikes = neurons.spn_dynamics(
            self.w1_eff, self.w2_eff, obs, self.time_steps, self.decay, self.v_th, hidden_spikes=self._hidden_spikes
        )
        action = out.argmax(-1) if self.discrete else torch.clamp(out, self.action_low, self.action_high)
        return action, spikes

    def _hidden_spikes(self, current: torch.Tensor) -> torch.Tensor:
        return neurons.threshold_spikes(current, self.spike_thresholds, self.spike_pattern)

    def _split(self, genomes: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if genomes.ndim != 2 or genomes.shape[1] != self.genome_size:
            raise ValueError(f"genomes must be [P, {self.genome_size}], got {tuple(genomes.shape)}")
        h, n = self.w1.shape[-2:]
        m = self.w2.shape[-2]
        p = genomes.shape[0]
        return genomes[:, : h * n].reshape(p, h, n), genomes[:, h * n :].reshape(p, m, h)


def spn_from_config(
    snn: SNNConfig, genome_kind: str, spec: TaskSpec, w1: torch.Tensor, w2: torch.Tensor
) -> PopulationSPN:
    """The SPN of ``snn`` and ``genome_kind`` for a task and its fixed weights."""
    return PopulationSPN(
        w1,
        w2,
        genome_kind=genome_kind,
        snn=snn,
        discrete=spec.discrete,
        action_low=spec.action_low,
        action_high=spec.action_high,
    )


def mask_density(x1: torch.Tensor, x2: torch.Tensor) -> float:
    """Fraction of the synapses of both layers that exist."""
    return float((x1.sum() + x2.sum()) / (x1.numel() + x2.numel()))


def build_spn(w1: torch.Tensor, w2: torch.Tensor, genomes: torch.Tensor | None = None, **kwargs) -> PopulationSPN:
    """Build the SPN from given fixed weights (e.g. a checkpoint or published run) and optional genomes."""
    spn = PopulationSPN(w1, w2, **kwargs)
    if genomes is not None:
        spn.set_genomes(genomes.reshape(-1, spn.genome_size))
    return spn


class TrainableSPN(nn.Module):
    """One SPN with trainable connection scores, for gradient training (Connections-PPO).

    Same fixed weights, mask rule and dynamics as :class:`PopulationSPN`; the mask passes gradients to the
    scores straight-through (forward: the hard mask; backward: d sigmoid(score)), the spikes through
    ``spike_fn`` (a surrogate derivative). Maps observations [..., n] to the output [..., m]: the
    clipped max potential for continuous tasks (the Gaussian mean), the raw max potential for discrete
    ones (the logits; argmax is PopulationSPN's action).
    """

    def __init__(self, spn: PopulationSPN, scores: torch.Tensor, spike_fn: neurons.SpikeFn) -> None:
        super().__init__()
        if spn.genome_kind != "connections" or spn.runs is not None:
            raise ValueError(
                "TrainableSPN trains connection scores: build it from a one-run 'connections' PopulationSPN"
            )
        self.spn = spn
        self.scores = nn.Parameter(scores.detach().clone().float().reshape(spn.genome_size))
        self.spike_fn = spike_fn

    def masks(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Straight-through masks [h, n] and [m, h]: values of the hard mask, gradient of the sigmoid."""
        g1, g2 = self.spn._split(self.scores[None])
        out = []
        for g in (g1[0], g2[0]):
            soft = torch.sigmoid(g)
            hard = (soft >= self.spn.score_threshold).to(soft.dtype)
            out.append(hard + (soft - soft.detach()))  # exactly the hard mask, d sigmoid backward
        return out[0], out[1]

    def forward(self, observation: torch.Tensor) -> torch.Tensor:
        x1, x2 = self.masks()
        w1, w2 = (self.spn.w1 * x1).t().contiguous(), (self.spn.w2 * x2).t().contiguous()
        batch = observation.shape[:-1]
        obs = observation.reshape(-1, observation.shape[-1]).to(w1.dtype)
        b = obs.shape[0]
        out, _ = neurons.spn_dynamics(
            w1.expand(b, *w1.shape),
            w2.expand(b, *w2.shape),
            obs,
            self.spn.time_steps,
            self.spn.decay,
            self.spn.v_th,
            self.spike_fn,
        )
        if not self.spn.discrete:
            out = torch.clamp(out, self.spn.action_low, self.spn.action_high)
        return out.reshape(*batch, out.shape[-1])
