"""A resumed run equals an uninterrupted one; the ONNX policy equals the torch policy."""

import numpy as np
import onnxruntime as ort
import torch

from mimicrete import learn
from mimicrete.learn.networks import Actor
from mimicrete.learn.run_files import export_onnx
from mimicrete.learn.trainer import Trainer
from mimicrete.testing.toyenv import toy_config


def _flat(sd: dict) -> dict:
    out = {}
    for k, v in sd.items():
        if isinstance(v, dict):
            out.update({f"{k}.{kk}": vv for kk, vv in _flat(v).items()})
        elif isinstance(v, torch.Tensor):
            out[k] = v
    return out


def test_resume_equals_uninterrupted(tmp_path):
    cfg = toy_config(tmp_path)  # 4 updates of 512 steps, checkpoint every 2
    a = learn.train(cfg, tmp_path / "a", progress=False)
    b1 = learn.train(cfg, tmp_path / "b", progress=False, stop_after_updates=2)
    assert b1.step == 1024 and (tmp_path / "b/checkpoints/step_000001024.pt").exists()
    b = learn.train(cfg, tmp_path / "b", progress=False, resume=True)
    assert a.step == b.step == 2048 and a.state.update_idx == b.state.update_idx == 4
    sa, sb = a.state_dict(), b.state_dict()
    for part in ("actor", "critic", "opt", "gail", "bc_opt"):
        fa, fb = _flat(sa[part]), _flat(sb[part])
        assert fa.keys() == fb.keys()
        for k in fa:
            assert torch.allclose(fa[k].double(), fb[k].double(), atol=1e-6, rtol=0), (part, k)
    assert torch.equal(sa["torch_rng"], sb["torch_rng"])
    # the run actually changed the weights (not a trivially equal comparison)
    b0 = Trainer(cfg, tmp_path / "c", None, 2048)
    assert not torch.allclose(b0.state.actor.mu.weight, a.state.actor.mu.weight)
    # and the logs of the two runs agree after the resume point
    rows_a = (tmp_path / "a/scalars.csv").read_text().splitlines()
    rows_b = (tmp_path / "b/scalars.csv").read_text().splitlines()
    assert rows_a[0] == rows_b[0] and len(rows_a) == len(rows_b) == 5


def test_onnx_matches_torch(tmp_path):
    torch.manual_seed(0)
    actor = Actor(80, 6, 64, 3, normalize=True)
    actor.norm.update(torch.randn(500, 80) * 3 + 1)
    path = tmp_path / "p.onnx"
    export_onnx(actor, 80, path)
    sess = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    obs = (np.random.default_rng(0).normal(size=(257, 80)) * 3).astype(np.float32)
    (out,) = sess.run(["actions"], {"obs": obs})
    with torch.no_grad():
        ref = actor.deterministic(torch.from_numpy(obs)).numpy()
    assert out.shape == (257, 7)
    np.testing.assert_allclose(out[:, :6], ref[:, :6], atol=1e-5)
    np.testing.assert_array_equal(out[:, 6], ref[:, 6])
    assert set(np.unique(out[:, 6])) <= {-1.0, 0.0, 1.0}
    assert np.abs(out[:, :6]).max() <= 1.0
