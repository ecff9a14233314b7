"""GAIL as a reward signal (ML-Agents ``gail_reward_provider.py``).

- Discriminator D(s) (or D(s, a) with ``use_actions``): an MLP of the config's size whose output
  layer has gain 0.2, sigmoid on top; D = 1 means "expert".
- Loss: -[log D(expert) + log(1 - D(policy))] + 10 * mean((||grad_x D(x_hat)|| - 1)^2) on random
  interpolates x_hat of an expert and a policy sample (the gradient penalty, always on).
- Updated once per PPO minibatch, against an expert minibatch of the same size.
- Reward: -log(1 - D * (1 - 1e-7)), which is >= 0.
- Inputs are normalised only with ``gail.network_settings.normalize: true`` (ML-Agents' default is
  false: raw inputs), and then by the expert demos' fixed mean/std. ML-Agents, with the switch on,
  updates a running normaliser from every expert minibatch it trains on; the expert data is fixed,
  so its statistics converge to these.

Survivor bias (``survivor_bias``): the reward above is never negative, so every extra step alive
earns GAIL reward; an episode that ends early (here: installing the tile, the success!) forfeits
it. With strength 0.1 and gamma 0.99 the forfeited GAIL return (about 0.1 * 0.69 / (1 - 0.99)
~= 7) outweighs the +1 for installing, which is what Table 5's group 5 shows (93 % picked, 0 %
installed). ``"none"`` keeps ML-Agents' behaviour. ``"bootstrap"`` (our default) treats a
termination as a non-event *for the GAIL signal only*: its GAE bootstraps from V_gail(final_obs)
as for a truncation, i.e. the terminal state is an absorbing state whose GAIL value is what the
critic predicts from it (the idea of DAC's absorbing states, Kostrikov et al. 2019, with the
absorbing reward taken from the terminal observation instead of a learned extra state). Ending an
episode then neither earns nor forfeits imitation reward, so termination is judged by the
extrinsic signal alone (+1 install, -0.5 fall).
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from .networks import mlp
from .normalizer import FixedNorm

GRADIENT_PENALTY_WEIGHT = 10.0
EPS = 1e-7


def signal_terminated(terminated: np.ndarray, survivor_bias: str) -> np.ndarray:
    """The termination mask the GAIL signal's GAE uses: the env's (``"none"``) or none at all
    (``"bootstrap"``: terminal steps bootstrap from V_gail(final_obs) like truncations)."""
    if survivor_bias == "none":
        return terminated
    if survivor_bias == "bootstrap":
        return np.zeros_like(terminated, dtype=bool)
    raise ValueError(f"survivor_bias {survivor_bias!r}")


class Discriminator(nn.Module):
    def __init__(
        self,
        in_mean: torch.Tensor,
        in_std: torch.Tensor,
        hidden: int,
        layers: int,
        normalize: bool = True,
    ):
        super().__init__()
        n_in = in_mean.shape[0]
        self.norm: nn.Module = FixedNorm(in_mean, in_std) if normalize else nn.Identity()
        self.body = mlp(n_in, hidden, layers)
        self.out = nn.Linear(hidden, 1)
        nn.init.kaiming_normal_(self.out.weight, nonlinearity="linear")
        self.out.weight.data.mul_(0.2)
        nn.init.zeros_(self.out.bias)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """D(x) in (0, 1), shape (B,)."""
        return torch.sigmoid(self.out(self.body(self.norm(x)))).squeeze(-1)


def gail_reward(d: torch.Tensor) -> torch.Tensor:
    """ML-Agents' GAIL reward -log(1 - D (1 - 1e-7)), >= 0."""
    return -torch.log(1.0 - d * (1.0 - EPS))


def discriminator_loss(
    disc: Discriminator,
    expert: torch.Tensor,
    policy: torch.Tensor,
    alpha: torch.Tensor | None = None,
) -> tuple[torch.Tensor, dict[str, float]]:
    """Total loss (BCE + gradient penalty) for one expert and one policy minibatch (B, D_in);
    ``alpha`` (B, 1) are the interpolation weights of the penalty (drawn here when None)."""
    d_e = disc(expert)
    d_p = disc(policy)
    bce = -(torch.log(d_e + EPS) + torch.log(1.0 - d_p + EPS)).mean()
    if alpha is None:
        alpha = torch.rand(expert.shape[0], 1, dtype=expert.dtype)
    x_hat = (alpha * expert + (1.0 - alpha) * policy).requires_grad_(True)
    d_hat = disc(x_hat)
    (grad,) = torch.autograd.grad(d_hat.sum(), x_hat, create_graph=True)
    gp = (grad.norm(dim=1) - 1.0).pow(2).mean()
    loss = bce + GRADIENT_PENALTY_WEIGHT * gp
    stats = {
        "loss": bce.item(),
        "grad_penalty": gp.item(),
        "expert_estimate": d_e.mean().item(),
        "policy_estimate": d_p.mean().item(),
    }
    return loss, stats


class Gail:
    """The reward provider: discriminator, its optimiser and the expert data."""

    def __init__(
        self,
        expert_inputs: np.ndarray,
        hidden: int,
        layers: int,
        lr: float,
        normalize: bool = True,
    ):
        x = torch.as_tensor(expert_inputs, dtype=torch.float32)
        self.expert = x
        self.disc = Discriminator(x.mean(0), x.std(0), hidden, layers, normalize)
        self.opt = torch.optim.Adam(self.disc.parameters(), lr=lr)

    @torch.no_grad()
    def rewards(self, inputs: torch.Tensor, chunk: int = 8192) -> np.ndarray:
        out = [gail_reward(self.disc(inputs[i : i + chunk])) for i in range(0, len(inputs), chunk)]
        return torch.cat(out).numpy()

    def draw(self, n: int, rng: np.random.Generator) -> tuple[torch.Tensor, torch.Tensor]:
        """The randomness of one discriminator step of ``n`` rows: which expert rows (from
        ``rng``) and the penalty's interpolation weights (from torch's generator). Drawn apart
        from :meth:`step` so that steps can run on another thread without touching either
        generator."""
        idx = torch.as_tensor(rng.integers(0, self.expert.shape[0], n))
        return idx, torch.rand(n, 1, dtype=self.expert.dtype)

    def update(self, policy_inputs: torch.Tensor, rng: np.random.Generator) -> dict[str, float]:
        return self.step(policy_inputs, self.draw(policy_inputs.shape[0], rng))

    def step(
        self, policy_inputs: torch.Tensor, draw: tuple[torch.Tensor, torch.Tensor]
    ) -> dict[str, float]:
        """One discriminator step with the randomness of :meth:`draw`."""
        idx, alpha = draw
        loss, stats = discriminator_loss(self.disc, self.expert[idx], policy_inputs, alpha)
        self.opt.zero_grad()
        loss.backward()
        self.opt.step()
        return stats

    def state_dict(self) -> dict:
        return {"disc": self.disc.state_dict(), "opt": self.opt.state_dict()}

    def load_state_dict(self, s: dict) -> None:
        self.disc.load_state_dict(s["disc"])
        self.opt.load_state_dict(s["opt"])
