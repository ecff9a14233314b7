"""Run a trained policy's ONNX file in the simulator, with onnxruntime and no torch.

    python examples/onnx_policy.py runs/group3-seed0/policy.onnx --episodes 5 --seed 10000

``policy.onnx`` (written by ``mimicrete train``) maps ``obs`` (B, obs_dim) float32 to ``actions``
(B, 7) float32: six joint motions in [-1, 1] and the suction command in {-1, 0, 1} (Screw-v0:
(B, 8), the gripper and the spin command), the deterministic policy ``mimicrete eval`` runs.
The observation normaliser is inside the graph, so the env's observation goes in as it is.
Needs numpy, gymnasium, onnxruntime and mimicrete's simulator (``mimicrete.envs``); torch is not
imported.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np
import onnxruntime as ort

import mimicrete.envs  # noqa: F401  (registers mimicrete/TileSuction-v0, ...)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("policy", help="a policy.onnx written by `mimicrete train`")
    p.add_argument("--env", default="mimicrete/TileSuction-v0")
    p.add_argument("--episodes", type=int, default=5)
    p.add_argument("--seed", type=int, default=10_000, help="episode k starts from seed + k")
    args = p.parse_args()

    sess = ort.InferenceSession(args.policy, providers=["CPUExecutionProvider"])
    env = gym.make(args.env)
    installed = 0
    for k in range(args.episodes):
        obs, _ = env.reset(options={"episode_seed": args.seed + k})
        ret, steps, done = 0.0, 0, False
        info: dict = {}
        while not done:
            (action,) = sess.run(["actions"], {"obs": obs[None].astype(np.float32)})
            obs, reward, terminated, truncated, info = env.step(action[0])
            ret += float(reward)
            steps += 1
            done = terminated or truncated
        installed += bool(info.get("installed"))
        result = "installed" if info.get("installed") else "not installed"
        print(f"episode {k}: seed {args.seed + k}, {steps} steps, return {ret:+.1f}, {result}")
    env.close()
    print(f"installed {installed} of {args.episodes}")


if __name__ == "__main__":
    main()
