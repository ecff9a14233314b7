"""A trained LeRobot policy (ACT or Diffusion) stepped in our env: run by
:mod:`mimicrete.experiments.peers` in the lerobot venv (``.venv-export``), never in ours.

    .venv-export/bin/python python/mimicrete/experiments/peer_adapter.py \\
        --checkpoint RUN/train/act-n5/checkpoints/last/pretrained_model --starts training \\
        --episodes 100 --seed 10000 --mimicrete-path /work/main/python --out result.json

Our package comes from ``--mimicrete-path`` (the folder holding ``mimicrete/``, with the native
module built for CPython 3.11, the interpreter of both venvs); nothing else of our venv is put on
the path, so numpy, torch and gymnasium are lerobot's.

The policy runs as lerobot runs it (its saved pre-processor normalises the observation, its
post-processor un-normalises the actions), batched over the envs, with an action queue per env so
an env that ends and restarts drops the rest of its chunk: ACT keeps ``n_action_steps`` of each
predicted chunk (``predict_action_chunk``), Diffusion keeps ``n_obs_steps`` observations per env
(the first one repeated at an episode's start, as lerobot's queues do) and generates
``n_action_steps`` actions from them with seeded noise. Episodes are split over
``n`` envs (the largest divisor of ``--episodes`` up to ``--max-envs``) and each env counts only
its first ``episodes / n`` episodes, as ``mimicrete eval`` does.

The policy's actions are in the dataset's layout (its ``info.json``'s action names): a dataset
exported with the suction command as a level (``suction_level``, docs/formats.md section 4) gets
its level mapped back to the env's command by :func:`mimicrete.export.levels.to_env` (its sign:
on / off); a checkpoint trained on the old layout (``suction_command``, one-step switches) is
stepped with its actions as they are, as before.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import deque
from pathlib import Path
from typing import Any

if sys.path and Path(sys.path[0]).resolve() == Path(__file__).resolve().parent:
    sys.path.pop(0)  # this folder's modules (stats, figures, ...) must not shadow packages


STARTS = ("training", "robust", "wide")
STATE, ENV_STATE = "observation.state", "observation.environment_state"


def _num_envs(episodes: int, cap: int) -> int:
    return max(d for d in range(1, min(cap, episodes) + 1) if episodes % d == 0)


def set_starts(vec, starts: str) -> None:
    """Apply a start set to a ``MimicreteVecEnv`` (before its reset)."""
    sim = vec.sim
    if starts == "training":
        return
    if starts == "robust":
        sim.set_variation(robust=True)
        return
    if starts == "wide":
        try:
            sim.set_variation(starts="wide")
        except TypeError:
            raise SystemExit("no wide starts in this simulator yet") from None
        return
    raise SystemExit(f"unknown start set {starts!r}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--checkpoint", required=True, help="a lerobot pretrained_model folder")
    p.add_argument("--starts", nargs="+", default=["training"], choices=STARTS)
    p.add_argument("--episodes", type=int, default=100)
    p.add_argument("--seed", type=int, default=10_000)
    p.add_argument("--max-envs", type=int, default=25)
    p.add_argument(
        "--max-steps",
        type=int,
        help="cut every episode after this many steps (not installed then); for smoke tests",
    )
    p.add_argument("--mimicrete-path", required=True)
    p.add_argument(
        "--out", required=True, help="the result JSON; with several start sets a name with {starts}"
    )
    args = p.parse_args(argv)
    if len(args.starts) > 1 and "{starts}" not in args.out:
        p.error("--out needs {starts} in its name when several start sets are given")
    sys.path.insert(0, str(Path(args.mimicrete_path).resolve()))

    import lerobot
    import torch
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    ck = Path(args.checkpoint)
    cfg = PreTrainedConfig.from_pretrained(ck)
    cfg.device = "cpu"
    policy = get_policy_class(cfg.type).from_pretrained(ck, config=cfg)
    policy.eval()
    pre, post = make_pre_post_processors(cfg, pretrained_path=str(ck))
    cols = _env_state_columns(ck, int(cfg.input_features[ENV_STATE].shape[0]))
    action_names = _action_names(ck)
    from mimicrete.export.levels import layout_of

    for starts in args.starts:
        t0 = time.perf_counter()
        res = run_episodes(policy, pre, post, cfg, cols, starts, args.episodes, args.seed,
                           args.max_envs, args.max_steps, action_names)  # fmt: skip
        res.update(
            action_layout=layout_of(action_names),
            policy_type=cfg.type,
            checkpoint=str(ck),
            eval_loop_s=round(time.perf_counter() - t0, 1),
            lerobot_version=lerobot.__version__,
            torch_version=torch.__version__,
            env_state_columns=cols,
        )
        Path(args.out.replace("{starts}", starts)).write_text(json.dumps(res, indent=1))
    return 0


def run_episodes(
    policy: Any,
    pre: Any,
    post: Any,
    cfg: Any,
    cols: list[int],
    starts: str,
    episodes: int,
    seed: int,
    max_envs: int,
    max_steps: int | None = None,
    action_names: list[str] | None = None,
) -> dict[str, Any]:
    """``episodes`` deterministic episodes of ``policy`` from ``starts`` → the mean statistics.
    ``action_names``: the dataset's (None: the actions go to the env as they are)."""
    import numpy as np
    import torch

    from mimicrete import envs

    torch.manual_seed(seed)
    n = _num_envs(episodes, max_envs)
    per_env = episodes // n
    vec = envs.make_vec("TileSuction-v0", n, seed)
    set_starts(vec, starts)
    obs, _ = vec.reset(seed=seed)

    is_diffusion = cfg.type == "diffusion"
    n_obs = int(getattr(cfg, "n_obs_steps", 1))
    n_act = int(cfg.n_action_steps)
    keys = (STATE, ENV_STATE)
    queues: list[deque] = [deque() for _ in range(n)]
    history: list[deque] = [deque(maxlen=n_obs) for _ in range(n)]
    gen = torch.Generator().manual_seed(seed)

    ret = np.zeros(n)
    length = np.zeros(n, np.int64)
    picked = np.zeros(n, bool)
    done_count = np.zeros(n, np.int64)
    results: list[dict[str, Any]] = []
    calls = 0
    while (done_count < per_env).any():
        o = np.asarray(obs, np.float32)
        env_state = np.ascontiguousarray(o[:, cols])
        batch = pre({STATE: torch.from_numpy(o), ENV_STATE: torch.from_numpy(env_state)})
        for i in range(n):
            item = {k: batch[k][i] for k in keys}
            if not history[i]:  # an episode's first observation fills the history
                history[i].extend([item] * n_obs)
            else:
                history[i].append(item)
        need = [i for i in range(n) if not queues[i]]
        if need:
            calls += 1
            with torch.no_grad():
                if is_diffusion:
                    stacked = {
                        k: torch.stack([torch.stack([h[k] for h in history[i]]) for i in need])
                        for k in keys
                    }
                    shape = (len(need), cfg.horizon, cfg.action_feature.shape[0])
                    noise = torch.randn(shape, generator=gen)
                    chunk = policy.diffusion.generate_actions(stacked, noise=noise)
                else:
                    chunk = policy.predict_action_chunk({k: batch[k][need] for k in keys})
                    chunk = chunk[:, :n_act]
            chunk = post(chunk)
            for j, i in enumerate(need):
                queues[i].extend(np.asarray(chunk[j].cpu().numpy(), np.float32))
        act = env_actions(np.stack([queues[i].popleft() for i in range(n)]), action_names)
        obs, r, term, trunc, infos = vec.step(act)
        ret += r
        length += 1
        picked |= np.asarray(infos["picked"], bool)
        ended = np.asarray(term, bool) | np.asarray(trunc, bool)
        cut = np.zeros(n, bool) if max_steps is None else (length >= max_steps) & ~ended
        for i in np.flatnonzero(ended | cut):
            if done_count[i] < per_env:
                final = infos["final_info"] if ended[i] else infos
                results.append(
                    {
                        "length": int(length[i]),
                        "return": float(ret[i]),
                        "picked": bool(picked[i] or final["picked"][i]),
                        "installed": bool(ended[i] and final["installed"][i]),
                    }
                )
                done_count[i] += 1
            ret[i], length[i], picked[i] = 0.0, 0, False
            queues[i].clear()
            history[i].clear()
        if cut.any():  # a cut episode's env starts its next episode
            obs = vec.reset(options={"reset_mask": cut})[0]
    vec.close()
    return {
        "starts": starts,
        "seed": seed,
        "episodes": len(results),
        "num_envs": n,
        "installed_rate": float(np.mean([e["installed"] for e in results])),
        "picked_rate": float(np.mean([e["picked"] for e in results])),
        "mean_episode_length": float(np.mean([e["length"] for e in results])),
        "mean_cumulative_reward": float(np.mean([e["return"] for e in results])),
        "policy_calls": calls,
        "max_steps": max_steps,
    }


def env_actions(act: Any, action_names: list[str] | None) -> Any:
    """A batch of the policy's actions (n, act_dim) as the env takes them: clipped to [-1, 1],
    a suction level (``suction_level``) by its sign (:func:`mimicrete.export.levels.to_env`);
    an old-layout or unnamed action only clipped."""
    import numpy as np

    act = np.clip(np.asarray(act, np.float32), -1.0, 1.0)
    if action_names is None:
        return act
    from mimicrete.export.levels import to_env

    return to_env(act, action_names)


def _dataset_info(ck: Path) -> dict[str, Any]:
    """The info.json of the dataset the checkpoint was trained on (through its training config)."""
    cfg = json.loads((ck / "train_config.json").read_text())
    return json.loads((Path(cfg["dataset"]["root"]) / "meta" / "info.json").read_text())


def _action_names(ck: Path) -> list[str]:
    """The action's names in the checkpoint's dataset: its layout (level or the old switch)."""
    return list(_dataset_info(ck)["features"]["action"]["names"])


def _env_state_columns(ck: Path, width: int) -> list[int]:
    """Where the policy's environment state sits in the env's observation: the dataset's names
    (``t.target_x`` ...) looked up among ``observation.state``'s (both from the dataset's
    info.json, found through the training config the checkpoint was saved with)."""
    info = _dataset_info(ck)
    names = info["features"]["observation.state"]["names"]
    env = info["features"]["observation.environment_state"]["names"]
    if len(env) != width:
        raise SystemExit(f"{ck}: environment state of {width} floats, the dataset's {len(env)}")
    return [names.index(e) for e in env]


if __name__ == "__main__":
    raise SystemExit(main())
