"""PPO with ML-Agents' semantics (``ppo/optimizer_torch.py``, ``ppo/trainer.py``).

- One Adam over actor + critic; loss = policy_loss + 0.5 * value_loss - beta * entropy.
- Clipped surrogate with the ratio taken *per action component* (ML-Agents flattens the hybrid
  action's log-probs and clips each against the same advantage), averaged.
- Clipped value loss per reward signal head, averaged over heads.
- Linear schedules over ``max_steps``: lr -> 1e-10, epsilon -> 0.1, beta -> 1e-5.
- Per-signal GAE with the signal's own gamma; combined advantage = mean over signals, then
  z-normalised over the whole update buffer.
"""

from __future__ import annotations

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
class PPOStats:
    policy_loss: float = 0.0
    value_loss: float = 0.0
    entropy: float = 0.0
    n: int = 0

    def add(self, p: float, v: float, e: float) -> None:
        self.policy_loss += p
        self.value_loss += v
        self.entropy += e
        self.n += 1

    def mean(self) -> dict[str, float]:
        n = max(self.n, 1)
        return {
            "policy_loss": self.policy_loss / n,
            "value_loss": self.value_loss / n,
            "entropy": self.entropy / n,
        }


def combine_advantages(advs: list[np.ndarray]) -> np.ndarray:
    """ML-Agents: mean over reward signals, then z-normalise over the buffer."""
    a = np.mean(np.stack(advs, 0), 0)
    return (a - a.mean()) / (a.std() + 1e-10)


def ppo_loss(
    actor: Actor,
    critic: Critic,
    obs: torch.Tensor,
    u: torch.Tensor,
    k: torch.Tensor,
    old_logp: torch.Tensor,
    adv: torch.Tensor,
    old_values: torch.Tensor,
    returns: torch.Tensor,
    epsilon: float,
    beta: float,
) -> tuple[torch.Tensor, tuple[float, float, float]]:
    """Total loss and (policy loss, value loss, entropy) as floats.

    Shapes: obs (B, D), u (B, n_cont), k (B,), old_logp (B, n_cont + 1), adv (B,),
    old_values / returns (B, n_signals)."""
    logp, entropy = actor.evaluate(obs, u, k)
    ratio = torch.exp(logp - old_logp)
    a = adv.unsqueeze(-1)
    surr = torch.min(ratio * a, torch.clamp(ratio, 1.0 - epsilon, 1.0 + epsilon) * a)
    policy_loss = -surr.mean()
    values = critic(obs)
    v_clipped = old_values + torch.clamp(values - old_values, -epsilon, epsilon)
    v_loss = torch.max((returns - values).pow(2), (returns - v_clipped).pow(2)).mean(0).mean()
    ent = entropy.mean()
    loss = policy_loss + 0.5 * v_loss - beta * ent
    return loss, (policy_loss.item(), v_loss.item(), ent.item())
