"""Behavioural cloning beside PPO (ML-Agents ``components/bc/module.py``).

A second Adam on the actor's parameters only, learning rate = strength x PPO's initial learning
rate, decayed linearly to 1e-10 over ``steps`` env steps (``steps: 0`` = constant for the whole
run). After every PPO update it makes ``num_epoch`` passes over the demo buffer in minibatches of
``batch_size`` (capped by ``samples_per_update``). As in ML-Agents, a round runs at the rate the
previous round computed and then sets the rate for the next one from the current env step: the
first round runs at the initial rate, and BC stops once the rate it holds has reached 1e-10 (with
``steps`` 100,000 and 10,240 steps per update: 10 rounds, at 1.0, 0.90, ..., 0.08 x).
Loss: MSE between the policy's *sampled* (reparameterised) continuous action and the demo's, plus
the command branches' cross-entropy: ML-Agents' ``_behavioral_cloning_loss`` takes the mean over
branches of each branch's one-hot cross-entropy, averaged over the batch (one branch: the end
effector; Screw: the gripper and the spin). The observation normaliser is not touched by BC.
"""

from __future__ import annotations

import numpy as np
import torch

from .networks import N_EE, Actor, ee_value_to_index

MIN_LR = 1e-10


def bc_learning_rate(initial: float, steps: int, step: int) -> float:
    """strength x lr at step 0, linearly to 1e-10 at ``steps`` (constant if steps == 0)."""
    if steps <= 0:
        return initial
    frac = min(max(step / steps, 0.0), 1.0)
    return (initial - MIN_LR) * (1.0 - frac) + MIN_LR


def ee_class_weights(actions: np.ndarray, n_cont: int, balance: float) -> torch.Tensor | None:
    """Cross-entropy weights (3,) of the end-effector commands (drop, fixed, on) in the action
    column ``n_cont``, each ``(share of that command in the demos) ** -balance``, scaled so the
    demo steps' mean weight is 1; an absent command gets weight 1. ``balance`` 0 (ML-Agents):
    None, the plain mean. :func:`branch_class_weights` does this for every command branch.

    Why (``behavioral_cloning.ee_class_balance``, an extension): a demonstrator switches the
    suction on once per episode, so "on" is about 1 demo step in 230. Its argmax never wins, and
    the deterministic policy (the evaluation's) never picks, although the sampled one does (10
    demos, PPO + BC + curriculum, 300k steps: 0 % picked deterministic, 91 % with the command
    sampled). Weighting by inverse frequency (``balance`` 1) makes "on" the most likely command
    in the states like those where the demonstrator switched it on."""
    if balance <= 0:
        return None
    k = ee_value_to_index(torch.as_tensor(actions[:, n_cont], dtype=torch.float32))
    counts = torch.bincount(k, minlength=3).double()
    share = counts / counts.sum()
    w = torch.where(
        counts > 0, share.clamp_min(1e-12) ** -balance, torch.ones(3, dtype=torch.float64)
    )
    w = w / (w * share).sum()  # mean weight over the demo steps = 1
    return w.float()


def branch_class_weights(actions: np.ndarray, n_cont: int, balance: float) -> torch.Tensor | None:
    """(n_branches, 3) cross-entropy weights: each command branch (the action columns after
    ``n_cont``) weighted by its own commands' shares in the demos (:func:`ee_class_weights`), or
    None for ``balance`` 0."""
    if balance <= 0:
        return None
    ws = [ee_class_weights(actions, c, balance) for c in range(n_cont, actions.shape[1])]
    return torch.stack([w for w in ws if w is not None])


def bc_loss(
    actor: Actor, obs: torch.Tensor, actions: torch.Tensor, ee_weight: torch.Tensor | None = None
) -> torch.Tensor:
    """MSE of the sampled joint motions + the branches' cross-entropy, the mean over branches and
    the batch; ``ee_weight`` (n_branches, 3) (or (3,) for one branch) weights each branch's
    commands."""
    n = actor.n_cont
    mu, log_std, logits = actor(obs)
    sampled = mu + log_std.exp() * torch.randn_like(mu)
    mse = (sampled - actions[:, :n]).pow(2).mean()
    k = ee_value_to_index(actions[:, n:]).reshape(-1)  # (B * n_branches,), branch-minor
    flat = logits.reshape(-1, N_EE)
    if ee_weight is None:
        ce = torch.nn.functional.cross_entropy(flat, k)
    else:  # weighted sum over the batch / batch size (not / sum of weights: no batch reweighting)
        w = ee_weight.reshape(-1, N_EE)  # (n_branches, 3)
        branch = torch.arange(len(k)) % w.shape[0]
        ce = (torch.nn.functional.cross_entropy(flat, k, reduction="none") * w[branch, k]).mean()
    return mse + ce


class BehavioralCloning:
    def __init__(
        self,
        actor: Actor,
        obs: np.ndarray,
        actions: np.ndarray,
        initial_lr: float,
        steps: int,
        batch_size: int,
        num_epoch: int,
        samples_per_update: int,
        ee_class_balance: float = 0.0,
    ):
        self.actor = actor
        self.obs = torch.as_tensor(obs, dtype=torch.float32)
        self.actions = torch.as_tensor(actions, dtype=torch.float32)
        self.initial_lr = initial_lr
        self.steps = steps
        self.batch_size = batch_size
        self.num_epoch = num_epoch
        self.samples_per_update = samples_per_update
        self.ee_weight = branch_class_weights(actions, actor.n_cont, ee_class_balance)
        self.opt = torch.optim.Adam(actor.parameters(), lr=initial_lr)
        self.current_lr = initial_lr  # the rate of the next round (in the checkpoint)

    def update(self, step: int, rng: np.random.Generator) -> tuple[float, float] | None:
        """One BC round after the update that ended at env step ``step``: at :attr:`current_lr`,
        which is then set to the schedule's value at ``step``. (mean loss, lr of the round), or
        None once the rate has annealed out."""
        lr = self.current_lr
        if lr <= MIN_LR * 1.0001:
            return None
        for g in self.opt.param_groups:
            g["lr"] = lr
        n = self.obs.shape[0]
        if self.samples_per_update > 0:
            n = min(n, self.samples_per_update)
        losses = []
        for _ in range(self.num_epoch):
            perm = torch.as_tensor(rng.permutation(self.obs.shape[0])[:n])
            for i in range(
                0, n - self.batch_size + 1 if n >= self.batch_size else 1, self.batch_size
            ):
                idx = perm[i : i + self.batch_size]
                loss = bc_loss(self.actor, self.obs[idx], self.actions[idx], self.ee_weight)
                self.opt.zero_grad()
                loss.backward()
                self.opt.step()
                losses.append(loss.item())
        self.current_lr = bc_learning_rate(self.initial_lr, self.steps, step)
        return float(np.mean(losses)), lr

    def batches_per_pass(self) -> int:
        """Minibatches in one pass of the warm start over the demo steps."""
        n = self.obs.shape[0]
        return max(n // min(self.batch_size, n), 1)

    def pretrain(self, grad_steps: int, rng: np.random.Generator) -> list[float]:
        """Offline warm start (extension ``pretrain_passes`` / ``pretrain_steps``; the paper's
        "BC is used for pre-training"): ``grad_steps`` minibatch steps at the initial BC learning
        rate before the first rollout, in passes over the shuffled demo steps
        (:meth:`batches_per_pass` steps each). Returns the loss of every step."""
        for g in self.opt.param_groups:
            g["lr"] = self.initial_lr
        n = self.obs.shape[0]
        bs = min(self.batch_size, n)
        losses: list[float] = []
        while len(losses) < grad_steps:
            perm = torch.as_tensor(rng.permutation(n))
            for i in range(0, n - bs + 1, bs):
                if len(losses) >= grad_steps:
                    break
                idx = perm[i : i + bs]
                loss = bc_loss(self.actor, self.obs[idx], self.actions[idx], self.ee_weight)
                self.opt.zero_grad()
                loss.backward()
                self.opt.step()
                losses.append(loss.item())
        return losses
