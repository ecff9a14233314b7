"""The ONNX policy (torch's dynamo-based exporter) against torch on 1,000 recorded simulator
observations, and `examples/onnx_policy.py` running it in the sim without torch."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import torch

from mimicrete.learn.run_files import ONNX_OPSET, export_onnx, load_policy

DATA = Path(__file__).parent / "data"
EXAMPLE = Path(__file__).parents[2] / "examples" / "onnx_policy.py"


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """The group-3 policy of tests/learn/data and its ONNX export."""
    run = tmp_path_factory.mktemp("run")
    (run / "policy.pt").write_bytes((DATA / "group3_policy.pt").read_bytes())
    actor, _ = load_policy(run)
    export_onnx(actor, 80, run / "policy.onnx")
    return actor, run / "policy.onnx"


@torch.no_grad()
def _rollout_obs(actor, n: int, num_envs: int = 8) -> np.ndarray:
    """``n`` observations of an evaluation rollout of ``actor`` in TileSuction-v0 (every state
    of its episodes: reach, pick, carry, place)."""
    from mimicrete import envs

    env = envs.make_vec("TileSuction-v0", num_envs, seed=20_000)
    obs, _ = env.reset(seed=20_000)
    rows = []
    while len(rows) * num_envs < n:
        rows.append(obs.copy())
        obs, *_ = env.step(actor.deterministic(torch.from_numpy(obs)).numpy())
    env.close()
    return np.concatenate(rows)[:n]


def test_onnx_matches_torch_on_recorded_observations(trained):
    import onnx
    import onnxruntime as ort

    actor, path = trained
    obs = _rollout_obs(actor, 1000)
    assert obs.shape == (1000, 80) and obs.dtype == np.float32
    model = onnx.load(str(path))
    onnx.checker.check_model(model)
    assert [i.name for i in model.graph.input] == ["obs"]
    assert [o.name for o in model.graph.output] == ["actions"]
    (dim0, dim1) = model.graph.input[0].type.tensor_type.shape.dim
    assert dim0.dim_param and dim1.dim_value == 80  # any batch size
    assert {o.domain: o.version for o in model.opset_import}[""] == ONNX_OPSET

    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    (out,) = sess.run(["actions"], {"obs": obs})
    with torch.no_grad():
        ref = actor.deterministic(torch.from_numpy(obs)).numpy()
    assert out.shape == (1000, 7) and out.dtype == np.float32
    np.testing.assert_allclose(out, ref, atol=1e-5, rtol=0)
    # the policy does something on these states: it switches the suction on (1) and holds (0)
    assert {0.0, 1.0} <= set(np.unique(out[:, 6])) <= {-1.0, 0.0, 1.0}
    assert np.abs(out[:, :6]).max() <= 1.0 and (np.abs(out[:, :6]) < 0.99).mean() > 0.5
    # one observation at a time (what a controller does) gives the same actions
    one = np.concatenate([sess.run(["actions"], {"obs": obs[i : i + 1]})[0] for i in range(50)])
    np.testing.assert_allclose(one, ref[:50], atol=1e-5, rtol=0)


_NO_TORCH = """
import importlib.abc, runpy, sys

tried = []

class NoTorch(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "torch" or name.startswith("torch."):
            tried.append(name)
            raise ImportError(f"{{name}}: torch is not installed (blocked by the test)")
        return None

sys.meta_path.insert(0, NoTorch())
sys.argv = [{example!r}, {policy!r}, "--episodes", "2", "--seed", "10000"]
runpy.run_path({example!r}, run_name="__main__")
assert not tried, f"imported torch: {{tried}}"
assert "torch" not in sys.modules
print("torch not imported")
"""


def test_example_runs_the_onnx_policy_without_torch(trained):
    _, path = trained
    code = textwrap.dedent(_NO_TORCH.format(example=str(EXAMPLE), policy=str(path)))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(p for p in sys.path if p)  # this test's mimicrete
    r = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300
    )
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    # the group-3 policy installs both tiles, in the episodes `mimicrete eval` runs first
    assert lines[0].startswith("episode 0: seed 10000, ") and lines[0].endswith("installed")
    assert lines[-2:] == ["installed 2 of 2", "torch not imported"]
