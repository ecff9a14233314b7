"""``mimicrete eval RUN_DIR --episodes 100``: the paper's Table 5 row for a trained run.

The deterministic policy (Gaussian mean clipped to [-1, 1], most likely end-effector command) runs
on fresh envs (seed = the run's seed + 10,000 unless ``--seed``). To avoid favouring short episodes,
``episodes`` is split evenly over the envs and each env contributes exactly its first
``episodes / num_envs`` episodes. Prints the row and writes ``eval.json`` into the run dir.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import torch

from . import config as config_mod
from .networks import Actor
from .train import N_CONT, episode_flags, make_env


def load_policy(run_dir: Path) -> tuple[Actor, config_mod.TrainerConfig]:
    s = torch.load(run_dir / "policy.pt", weights_only=False)
    cfg = config_mod.from_dict(s["config"])
    ns = cfg.behavior.network_settings
    actor = Actor(int(s["obs_dim"]), N_CONT, ns.hidden_units, ns.num_layers, ns.normalize)
    actor.load_state_dict(s["actor"])
    actor.eval()
    return actor, cfg


def _num_envs_for(episodes: int, cap: int = 32) -> int:
    return max(d for d in range(1, min(cap, episodes) + 1) if episodes % d == 0)


@torch.no_grad()
def run_episodes(
    actor: Actor, env_id: str, episodes: int, seed: int, max_envs: int = 32
) -> dict[str, float]:
    n = _num_envs_for(episodes, max_envs)
    per_env = episodes // n
    env = make_env(env_id, n, seed)
    obs, _ = env.reset(seed=seed)
    obs = np.asarray(obs, np.float32)
    done_count = np.zeros(n, np.int64)
    ep_len = np.zeros(n, np.int64)
    ep_ret = np.zeros(n)
    ep_picked = np.zeros(n, bool)
    ep_installed = np.zeros(n, bool)
    results: list[tuple[bool, bool, int, float]] = []
    while (done_count < per_env).any():
        act = actor.deterministic(torch.from_numpy(obs)).numpy()
        obs, r, term, trunc, infos = env.step(act)
        obs = np.asarray(obs, np.float32)
        r = np.asarray(r, np.float32)
        term = np.asarray(term, bool)
        trunc = np.asarray(trunc, bool)
        picked, installed = episode_flags(infos, r, term)
        ep_len += 1
        ep_ret += r
        ep_picked |= picked
        ep_installed |= installed
        for i in np.flatnonzero(term | trunc):
            if done_count[i] < per_env:
                results.append(
                    (bool(ep_picked[i]), bool(ep_installed[i]), int(ep_len[i]), float(ep_ret[i]))
                )
                done_count[i] += 1
            ep_len[i] = 0
            ep_ret[i] = 0.0
            ep_picked[i] = False
            ep_installed[i] = False
    env.close()
    p, ins, lens, rets = zip(*results, strict=True)
    return {
        "episodes": len(results),
        "picked_rate": float(np.mean(p)),
        "installed_rate": float(np.mean(ins)),
        "mean_episode_length": float(np.mean(lens)),
        "mean_cumulative_reward": float(np.mean(rets)),
    }


def evaluate_run(run_dir: Path, episodes: int, seed: int | None = None) -> dict[str, float]:
    actor, cfg = load_policy(run_dir)
    s = cfg.env_settings.seed + 10_000 if seed is None else seed
    res = run_episodes(actor, cfg.env_settings.env_id, episodes, s)
    res = {**res, "seed": s, "env_id": cfg.env_settings.env_id}
    (run_dir / "eval.json").write_text(json.dumps(res, indent=1))
    return res


def format_row(name: str, res: dict) -> str:
    head = f"{'run':<24} {'Picked rate':>12} {'Installed rate':>15} {'Average episode length':>23}"
    row = (
        f"{name:<24} {res['picked_rate']:>12.0%} {res['installed_rate']:>15.0%} "
        f"{res['mean_episode_length']:>23.1f}"
    )
    return f"{head}\n{row}"


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", help="a run directory written by `mimicrete train`")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, help="eval env seed (default: run seed + 10000)")


def main(args: argparse.Namespace) -> int:
    torch.set_num_threads(1)
    run_dir = Path(args.run_dir)
    res = evaluate_run(run_dir, args.episodes, args.seed)
    print(format_row(run_dir.name, res))
    print(f"wrote {run_dir / 'eval.json'}")
    return 0
