"""Spike functions with surrogate derivatives: the Heaviside step forward, a smooth derivative backward."""

from __future__ import annotations

import math

import torch

from spn_torchrl.snn.neurons import SpikeFn


class _Spike(torch.autograd.Function):
    """``v > v_th`` forward; ``grad * derivative(v - v_th, alpha)`` backward."""

    @staticmethod
    def forward(ctx, v: torch.Tensor, v_th: float, kind: str, alpha: float) -> torch.Tensor:
        ctx.save_for_backward(v)
        ctx.v_th, ctx.kind, ctx.alpha = v_th, kind, alpha
        return (v > v_th).to(v.dtype)

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        (v,) = ctx.saved_tensors
        x, a = v - ctx.v_th, ctx.alpha
        if ctx.kind == "fast_sigmoid":
            # derivative of x / (1 + a|x|) scaled to 1 at 0 (SuperSpike)
            d = 1.0 / (1.0 + a * x.abs()) ** 2
        else:
            # derivative of atan(pi/2 * a * x) / pi + 1/2
            d = (a / 2.0) / (1.0 + (math.pi / 2.0 * a * x) ** 2)
        return grad * d, None, None, None


SURROGATES = ("fast_sigmoid", "atan")


def surrogate_spike(kind: str, alpha: float = 2.0) -> SpikeFn:
    """A spike function for :func:`spn_torchrl.snn.neurons.spn_dynamics` whose backward pass is ``kind``."""
    if kind not in SURROGATES:
        raise ValueError(f"surrogate must be one of {SURROGATES}, got {kind!r}")

    def spike(v: torch.Tensor, v_th: float) -> torch.Tensor:
        return _Spike.apply(v, v_th, kind, alpha)

    return spike
