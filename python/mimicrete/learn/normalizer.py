"""Running observation normaliser (ML-Agents ``normalize: true``).

Mean and variance are accumulated over every observation seen so far with Chan et al.'s parallel
update, stored as module buffers (so they live in the checkpoint and in the ONNX graph), and applied
as ``clamp((x - mean) / sqrt(var + eps), -5, 5)``.
"""

from __future__ import annotations

import torch
from torch import nn


class RunningNorm(nn.Module):
    def __init__(self, size: int, eps: float = 1e-5, clip: float = 5.0, enabled: bool = True):
        super().__init__()
        self.enabled = enabled
        self.eps = eps
        self.clip = clip
        self.register_buffer("count", torch.zeros((), dtype=torch.float64))
        self.register_buffer("mean", torch.zeros(size, dtype=torch.float64))
        self.register_buffer("var", torch.ones(size, dtype=torch.float64))

    @torch.no_grad()
    def update(self, x: torch.Tensor) -> None:
        """Fold a batch ``x`` of shape (B, size) into the running statistics."""
        if not self.enabled or x.shape[0] == 0:
            return
        x = x.reshape(-1, self.mean.shape[0]).to(torch.float64)
        b = float(x.shape[0])
        b_mean = x.mean(0)
        b_var = x.var(0, unbiased=False)
        n = self.count + b
        delta = b_mean - self.mean
        self.mean += delta * (b / n)
        m2 = self.var * self.count + b_var * b + delta.pow(2) * self.count * b / n
        self.var.copy_(m2 / n)
        self.count.copy_(n)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.enabled:
            return x
        mean = self.mean.to(x.dtype)
        std = torch.sqrt(self.var.to(x.dtype) + self.eps)
        return torch.clamp((x - mean) / std, -self.clip, self.clip)


class FixedNorm(nn.Module):
    """Normalisation by fixed statistics (the discriminator's: those of the expert demos)."""

    def __init__(self, mean: torch.Tensor, std: torch.Tensor, clip: float = 5.0):
        super().__init__()
        self.register_buffer("mean", mean.to(torch.float32).clone())
        self.register_buffer("std", std.to(torch.float32).clamp_min(1e-2).clone())
        self.clip = clip

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.clamp((x - self.mean) / self.std, -self.clip, self.clip)
