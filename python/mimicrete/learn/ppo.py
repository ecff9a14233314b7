"""PPO with ML-Agents' semantics (``ppo/optimizer_torch.py``, ``ppo/trainer.py``).

- One Adam over actor + critic; loss = policy_loss + 0.5 * value_loss - beta * entropy.
- Clipped surrogate with the ratio taken *per action component* (ML-Agents flattens the hybrid
  action's log-probs, one per Gaussian dim and one per command branch, and clips each against the
  same advantage), averaged.
- Clipped value loss per reward signal head, averaged over heads.
- Linear schedules over ``max_steps``: lr -> 1e-10, epsilon -> 0.1, beta -> 1e-5.
- Per-signal GAE with the signal's own gamma; combined advantage = mean over signals, then
  z-normalised over the whole update buffer.
- CleanRL's diagnostics beside the losses: approx_kl, clipfrac, explained_variance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from .networks import Actor, Critic


def linear_decay(initial: float, final: float, step: int, max_steps: int) -> float:
    """ML-Agents' LinearDecaySchedule: initial -> final linearly over max_steps, then final."""
    if max_steps <= 0:
        return initial
    frac = min(max(step / max_steps, 0.0), 1.0)
    return (initial - final) * (1.0 - frac) + final


def scheduled(
    kind: str | None, default_kind: str, initial: float, final: float, step: int, max_steps: int
) -> float:
    kind = kind or default_kind
    if kind == "constant":
        return initial
    return linear_decay(initial, final, step, max_steps)


@dataclass
class PPOBatch:
    """One minibatch of the update buffer, as PPO's loss reads it. Shapes: obs (B, D),
    u (B, n_cont), k (B, n_branches), old_logp (B, n_cont + n_branches), adv (B,), old_values /
    returns (B, n_signals)."""

    obs: torch.Tensor
    u: torch.Tensor  # the Gaussian sample (pre-clip) of the joint motions
    k: torch.Tensor  # each command branch's index (end effector; spin)
    old_logp: torch.Tensor  # per action component, at collection time
    adv: torch.Tensor  # combined, z-normalised advantage
    old_values: torch.Tensor  # per value head, at collection time
    returns: torch.Tensor  # per value head (GAE targets)


@dataclass
class PPOLossInfo:
    """What one minibatch's loss reports, as floats."""

    policy_loss: float
    value_loss: float
    entropy: float
    approx_kl: float  # mean of (r - 1) - log r over action components (CleanRL's approx_kl)
    clipfrac: float  # share of action components with |r - 1| > epsilon


@dataclass
class PPOStats:
    """Sums of :class:`PPOLossInfo` over an update's minibatches."""

    policy_loss: float = 0.0
    value_loss: float = 0.0
    entropy: float = 0.0
    approx_kl: float = 0.0
    clipfrac: float = 0.0
    n: int = 0

    def add(self, info: PPOLossInfo) -> None:
        self.policy_loss += info.policy_loss
        self.value_loss += info.value_loss
        self.entropy += info.entropy
        self.approx_kl += info.approx_kl
        self.clipfrac += info.clipfrac
        self.n += 1

    def mean(self) -> dict[str, float]:
        n = max(self.n, 1)
        return {
            "policy_loss": self.policy_loss / n,
            "value_loss": self.value_loss / n,
            "entropy": self.entropy / n,
            "approx_kl": self.approx_kl / n,
            "clipfrac": self.clipfrac / n,
        }


def combine_advantages(advs: list[np.ndarray]) -> np.ndarray:
    """ML-Agents: mean over reward signals, then z-normalise over the buffer."""
    a = np.mean(np.stack(advs, 0), 0)
    return (a - a.mean()) / (a.std() + 1e-10)


def explained_variance(values: np.ndarray, returns: np.ndarray) -> float:
    """1 - Var(returns - values) / Var(returns) (CleanRL); NaN when the returns do not vary."""
    var = float(np.var(returns))
    return math.nan if var == 0 else 1.0 - float(np.var(returns - values)) / var


def ppo_loss(
    actor: Actor, critic: Critic, b: PPOBatch, epsilon: float, beta: float
) -> tuple[torch.Tensor, PPOLossInfo]:
    """Total loss (policy + 0.5 value - beta entropy) and its parts."""
    logp, entropy = actor.evaluate(b.obs, b.u, b.k)
    log_ratio = logp - b.old_logp
    ratio = torch.exp(log_ratio)
    a = b.adv.unsqueeze(-1)
    surr = torch.min(ratio * a, torch.clamp(ratio, 1.0 - epsilon, 1.0 + epsilon) * a)
    policy_loss = -surr.mean()
    values = critic(b.obs)
    v_clipped = b.old_values + torch.clamp(values - b.old_values, -epsilon, epsilon)
    v_loss = torch.max((b.returns - values).pow(2), (b.returns - v_clipped).pow(2)).mean(0).mean()
    ent = entropy.mean()
    loss = policy_loss + 0.5 * v_loss - beta * ent
    with torch.no_grad():
        approx_kl = ((ratio - 1.0) - log_ratio).mean().item()
        clipfrac = ((ratio - 1.0).abs() > epsilon).float().mean().item()
    return loss, PPOLossInfo(policy_loss.item(), v_loss.item(), ent.item(), approx_kl, clipfrac)
