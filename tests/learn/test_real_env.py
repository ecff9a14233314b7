"""The trainer on the Rust-backed TileSuction-v0 (skipped when the native simulator is not built):
a short BC-warm-started run, evaluation, and the ONNX policy on real observations."""

import json

import numpy as np
import torch

from mimicrete import learn
from mimicrete.learn import config, demo_data, evaluate

from ._expert_demos import scripted_demos
from ._rollout import evaluated_first_episode, first_episode
from ._small import SMALL_RUN


def test_short_run_on_tile_suction(tmp_path):
    demos = scripted_demos(6, seed=100)
    assert set(np.unique(demos["actions"][:, 6])) <= {-1.0, 0.0, 1.0}
    assert demos["terminated"].sum() == 6  # every scripted episode installs
    np.savez(tmp_path / "d.npz", **demos)
    cfg = config.load(config.find_config_dir() / "group4.yaml")
    cfg = config.with_overrides(
        cfg,
        [
            *SMALL_RUN,
            "behavior.reward_signals.gail.network_settings.hidden_units=32",
            "behavior.demo_episodes=6",
            "behavior.max_steps=2048",
            "behavior.summary_freq=1024",
            "behavior.checkpoint_interval=1024",
            "env_settings.num_envs=8",
        ],
    )
    run = tmp_path / "run"
    tr = learn.train(cfg, run, demos=str(tmp_path / "d.npz"), progress=False)
    assert tr.step == 2048 and tr.state.signals == ["extrinsic", "gail"]
    # group 4 leaves the expert's pauses out of BC and GAIL (demo_drop_idle 0.1), and says so
    info = json.loads((run / "run.json").read_text())
    idle = demo_data.idle_steps(demos["actions"], demos["episode"], 0.1)
    assert info["demo_steps_loaded"] == len(demos["actions"])
    assert (
        info["demo_steps_idle_dropped"]
        == idle.sum()
        == len(demos["actions"]) - len(tr.state.bc.obs)
    )
    assert tr.state.gail is not None and len(tr.state.gail.expert) == len(tr.state.bc.obs)
    res = evaluate.evaluate_run(run, 8)
    assert res["episodes"] == 8
    # the length eval reports is the policy's: its first episode counted by stepping it by hand
    one = evaluated_first_episode(run, res["seed"])
    assert one["mean_episode_length"] == first_episode(run, res["seed"])[0]
    assert json.loads((run / "eval.json").read_text())["env_id"] == "TileSuction-v0"
    # the robust evaluation (wider starts) through the CLI: its own file, the same row shape
    from mimicrete import cli

    assert cli.main(["eval", str(run), "--episodes", "8", "--robust"]) == 0
    rob = json.loads((run / "eval_robust.json").read_text())
    assert rob["starts"] == "robust" and rob["episodes"] == 8
    assert json.loads((run / "eval.json").read_text()) == {**res, "starts": "training"}
    # the exported ONNX runs to the same actions on real observations
    import onnxruntime as ort

    sess = ort.InferenceSession(str(run / "policy.onnx"), providers=["CPUExecutionProvider"])
    obs = demos["obs"][:200]
    (out,) = sess.run(["actions"], {"obs": obs})
    with torch.no_grad():
        ref = tr.state.actor.deterministic(torch.from_numpy(obs)).numpy()
    np.testing.assert_allclose(out[:, :6], ref[:, :6], atol=1e-5)
    np.testing.assert_array_equal(out[:, 6], ref[:, 6])
