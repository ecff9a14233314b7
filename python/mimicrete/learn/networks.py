"""Actor and critic networks (ML-Agents' shapes: separate MLPs of ``hidden_units`` x
``num_layers`` with Swish/SiLU activations, observation normaliser in front).

The action is ML-Agents' hybrid action: a diagonal Gaussian over the ``n_cont`` joint motions with a
state-independent sigma (``condition_sigma_on_obs=False`` for PPO) and ``n_branches`` categorical
branches of three commands each, mapped to ``{-1, 0, +1}`` in the env's action dimensions after the
joints: one branch for TileSuction / BlockGrip (the end effector: drop, fixed, suction or grip), two
for Screw (the gripper, then the spin: loosen, stop, tighten). Like ML-Agents' multi-branch discrete
actions, each branch is its own categorical (one head ``logits`` of ``3 * n_branches`` outputs, cut
into branches of three), sampled independently.

The env receives ``clip(u, -1, 1)`` for the Gaussian sample ``u``; ML-Agents sends
``clamp(u, -3, 3) / 3`` instead (a departure: ours keeps the Gaussian mean in the demo actions'
units, so BC's MSE and the env see the same scale; sigma starts at 1/3 so that the initial
exploration noise in action units is ML-Agents').

Log-probabilities are returned *per action component* (``n_cont`` Gaussian dims + one per branch),
because ML-Agents' PPO clips the probability ratio per component. Command indices ``k`` are
shaped (B, n_branches).
"""

from __future__ import annotations

import math

import torch
from torch import nn

from .normalizer import RunningNorm

N_EE = 3  # commands per branch: index 0 -> -1 (drop / loosen), 1 -> 0 (fixed / stop), 2 -> +1


def mlp(n_in: int, hidden: int, layers: int) -> nn.Sequential:
    mods: list[nn.Module] = []
    d = n_in
    for _ in range(layers):
        lin = nn.Linear(d, hidden)
        nn.init.kaiming_normal_(lin.weight, nonlinearity="linear")
        nn.init.zeros_(lin.bias)
        mods += [lin, nn.SiLU()]
        d = hidden
    return nn.Sequential(*mods)


def _head(n_in: int, n_out: int, gain: float) -> nn.Linear:
    lin = nn.Linear(n_in, n_out)
    nn.init.kaiming_normal_(lin.weight, nonlinearity="linear")
    lin.weight.data.mul_(gain)
    nn.init.zeros_(lin.bias)
    return lin


def ee_index_to_value(k: torch.Tensor) -> torch.Tensor:
    return k.to(torch.float32) - 1.0


def ee_value_to_index(v: torch.Tensor) -> torch.Tensor:
    """Demo/env value in [-1, 1] -> command index (<= -0.5 drop, >= 0.5 suction, else fixed)."""
    return (v >= 0.5).long() * 2 + ((v > -0.5) & (v < 0.5)).long()


def n_branches_of(actor_state: dict[str, torch.Tensor]) -> int:
    """The number of command branches of a saved actor (from its ``logits`` head's size)."""
    return int(actor_state["logits.weight"].shape[0]) // N_EE


def branch_logits(logits: torch.Tensor) -> torch.Tensor:
    """(..., 3 * n_branches) head output -> (..., n_branches, 3)."""
    return logits.unflatten(-1, (logits.shape[-1] // N_EE, N_EE))


class Actor(nn.Module):
    def __init__(
        self,
        obs_dim: int,
        n_cont: int,
        hidden: int,
        layers: int,
        normalize: bool,
        n_branches: int = 1,
        init_std: float = 1.0 / 3.0,
    ):
        super().__init__()
        if n_branches < 1:
            raise ValueError(f"n_branches: at least 1, got {n_branches}")
        self.n_cont = n_cont
        self.n_branches = n_branches
        self.norm = RunningNorm(obs_dim, enabled=normalize)
        self.body = mlp(obs_dim, hidden, layers)
        self.mu = _head(hidden, n_cont, 0.2)
        # sigma starts at 1/3 by default: ML-Agents starts at sigma 1 but sends clamp(u, -3, 3) / 3
        # to the env, i.e. an initial exploration sigma of 1/3 in action units; ours is the same.
        self.log_std = nn.Parameter(torch.full((n_cont,), math.log(init_std)))
        self.logits = _head(hidden, N_EE * n_branches, 0.1)

    def forward(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(mu, log_std broadcast to mu, command logits (B, 3 * n_branches), branch by branch)."""
        h = self.body(self.norm(obs))
        mu = self.mu(h)
        return mu, self.log_std.expand_as(mu), self.logits(h)

    @staticmethod
    def _log_probs(mu, log_std, logits, u, k):
        """(B, n_cont + n_branches): each Gaussian dim's, then each branch's chosen command's."""
        lp_c = -0.5 * ((u - mu) / log_std.exp()).pow(2) - log_std - 0.5 * math.log(2 * math.pi)
        lp_d = torch.log_softmax(branch_logits(logits), -1).gather(-1, k.unsqueeze(-1))
        return torch.cat([lp_c, lp_d.squeeze(-1)], -1)

    @staticmethod
    def _entropy(log_std, logits):
        """ML-Agents' entropy: the Gaussian's is the *mean* over action dims ("equivalent
        behavior to TF" in its GaussianDistInstance), plus the sum of the categorical branches'
        (its entropies are concatenated per branch and summed)."""
        ent_c = (0.5 + 0.5 * math.log(2 * math.pi) + log_std).mean(-1)
        bl = branch_logits(logits)
        p = torch.softmax(bl, -1)
        ent_d = -(p * torch.log_softmax(bl, -1)).sum(-1).sum(-1)
        return ent_c + ent_d

    @torch.no_grad()
    def sample(self, obs: torch.Tensor):
        """Stochastic action: (u (B, n_cont) raw Gaussian sample, k (B, n_branches) command
        indices, per-component log-probs (B, n_cont + n_branches))."""
        mu, log_std, logits = self(obs)
        u = mu + log_std.exp() * torch.randn_like(mu)
        p = torch.softmax(logits.reshape(-1, N_EE), -1)  # (B * n_branches, 3), branch-minor
        k = torch.multinomial(p, 1).reshape(-1, self.n_branches)
        return u, k, self._log_probs(mu, log_std, logits, u, k)

    def evaluate(self, obs: torch.Tensor, u: torch.Tensor, k: torch.Tensor):
        """(per-component log-probs (B, n_cont + n_branches), entropy (B,)) of given actions."""
        mu, log_std, logits = self(obs)
        return self._log_probs(mu, log_std, logits, u, k), self._entropy(log_std, logits)

    def deterministic(self, obs: torch.Tensor) -> torch.Tensor:
        """Env action (B, n_cont + n_branches): clip(mu, -1, 1) and each branch's most likely
        command."""
        mu, _, logits = self(obs)
        k = torch.argmax(branch_logits(logits), -1)
        return torch.cat([mu.clamp(-1.0, 1.0), ee_index_to_value(k)], -1)


def env_action(u: torch.Tensor, k: torch.Tensor) -> torch.Tensor:
    """(B, n_cont + n_branches) env action of a Gaussian sample ``u`` and command indices ``k``
    (B, n_branches)."""
    return torch.cat([u.clamp(-1.0, 1.0), ee_index_to_value(k)], -1)


class Critic(nn.Module):
    """One value head per reward signal on a shared body (ML-Agents' ValueNetwork)."""

    def __init__(self, obs_dim: int, n_heads: int, hidden: int, layers: int, normalize: bool):
        super().__init__()
        self.norm = RunningNorm(obs_dim, enabled=normalize)
        self.body = mlp(obs_dim, hidden, layers)
        self.heads = _head(hidden, n_heads, 1.0)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.heads(self.body(self.norm(obs)))


class DeterministicPolicy(nn.Module):
    """What the ONNX file holds: obs (B, obs_dim) -> deterministic env action
    (B, n_cont + n_branches)."""

    def __init__(self, actor: Actor):
        super().__init__()
        self.actor = actor

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.actor.deterministic(obs)
