"""``--resume`` is exact: a run interrupted at any update and resumed equals the uninterrupted
run bit for bit (every weight, optimiser and RNG state, the envs' state and every scalar except
the wall-clock rate), on the toy env and on the Rust simulator. Checkpoints do not change
training: the uninterrupted reference run checkpoints only at its end, the interrupted runs after
every update or every second one, and episodes run across the checkpoints (they are not cut).
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from mimicrete import learn
from mimicrete.learn import config as config_mod
from mimicrete.learn import run_files
from mimicrete.learn.checkpoint import ResumeError
from mimicrete.learn.run_files import WALL_CLOCK_TAGS
from mimicrete.testing.toyenv import toy_config

UPDATES = 5
WALL_CLOCK = set(WALL_CLOCK_TAGS)
ENVS = {
    # toy: 8 envs x 64 steps per update, episodes of up to 100 steps
    "toy": {"buffer": 512, "batch": 128, "num_envs": 8, "env_id": "Toy-v0"},
    # simulator: 4 envs x 200 steps per update; every env truncates at 750 (update 4) and
    # every checkpoint falls inside an episode
    "sim": {"buffer": 800, "batch": 200, "num_envs": 4, "env_id": "TileSuction-v0"},
}


def _config(tmp: Path, env: str, ckpt_updates: int) -> config_mod.TrainerConfig:
    e = ENVS[env]
    cfg = toy_config(
        tmp,
        max_steps=UPDATES * e["buffer"],
        buffer=e["buffer"],
        batch=e["batch"],
        num_envs=e["num_envs"],
        ckpt=ckpt_updates * e["buffer"],
        seed=3,
    )
    d = cfg.to_dict()
    d["env_settings"]["env_id"] = e["env_id"]  # the toy demos have the sim's obs / action dims
    return config_mod.from_dict(d)


def _tensors(x: Any, prefix: str = "") -> dict[str, torch.Tensor | np.ndarray]:
    """Every tensor and array in a nested state (dicts, lists), by path."""
    out: dict[str, torch.Tensor | np.ndarray] = {}
    if isinstance(x, dict):
        for k, v in x.items():
            out |= _tensors(v, f"{prefix}.{k}")
    elif isinstance(x, (list, tuple)):
        for i, v in enumerate(x):
            out |= _tensors(v, f"{prefix}[{i}]")
    elif isinstance(x, (torch.Tensor, np.ndarray)):
        out[prefix] = x
    return out


def _scalars(run: Path) -> list[dict[str, str]]:
    with open(run / "scalars.csv", newline="") as f:
        return [{k: v for k, v in r.items() if k not in WALL_CLOCK} for r in csv.DictReader(f)]


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, dict]]:
    """The uninterrupted run of each env, checkpointing only at its end."""
    out = {}
    for env in ENVS:
        tmp = tmp_path_factory.mktemp(f"ref-{env}")
        tr = learn.train(_config(tmp, env, UPDATES), tmp / "run", progress=False)
        assert tr.state.update_idx == UPDATES
        out[env] = (tmp / "run", tr.state_dict())
    return out


@pytest.mark.parametrize("env", list(ENVS))
@pytest.mark.parametrize(
    ("ckpt_updates", "stop"),
    [(1, 1), (1, 3), (2, 3)],  # (2, 3): the crash loses update 3, which the resume redoes
    ids=["ckpt1-stop1", "ckpt1-stop3", "ckpt2-stop3"],
)
def test_interrupted_and_resumed_equals_uninterrupted(
    tmp_path: Path, reference: dict, env: str, ckpt_updates: int, stop: int
) -> None:
    ref_dir, ref = reference[env]
    cfg = _config(tmp_path, env, ckpt_updates)
    run = tmp_path / "run"
    first = learn.train(cfg, run, progress=False, stop_after_updates=stop)
    assert first.state.update_idx == stop
    ck = run_files.latest_checkpoint(run)
    assert ck is not None
    saved = run_files.load_checkpoint(ck)
    assert saved["update_idx"] == stop - stop % ckpt_updates
    envs = saved["envs"]["env"]
    if env == "sim":  # the checkpoint holds running episodes, replayed on resume
        assert all(len(a) > 0 for a in envs["actions"])
    tr = learn.train(cfg, run, progress=False, resume=True)
    assert tr.state.update_idx == UPDATES and tr.step == ref["step"]
    got = tr.state_dict()
    if env == "sim":  # every env had an auto-reset (episode count 1) during the run
        assert list(got["envs"]["env"]["episodes"]) == [1] * ENVS["sim"]["num_envs"]
    for part in ("actor", "critic", "opt", "gail", "bc_opt", "torch_rng", "envs"):
        a, b = _tensors(ref[part]), _tensors(got[part])
        assert a.keys() == b.keys() and a, part
        for k in a:
            if isinstance(a[k], torch.Tensor):
                assert torch.equal(a[k], b[k]), (part, k)
            else:
                np.testing.assert_array_equal(a[k], b[k], err_msg=f"{part}{k}")
    assert got["rng"] == ref["rng"] and got["py_rng"] == ref["py_rng"]
    assert str(got["np_global_rng"]) == str(ref["np_global_rng"])
    assert _scalars(run) == _scalars(ref_dir) and len(_scalars(run)) == UPDATES
    # the comparison is not vacuous: training moved the weights, episodes finished
    assert not torch.equal(ref["actor"]["mu.weight"], first.state_dict()["actor"]["mu.weight"])
    assert any(r["Environment/Episodes"] for r in _scalars(run)[-2:])


def _stopped(tmp: Path, env: str, updates: int):
    """A run of ``env`` stopped after ``updates`` updates (a checkpoint after each): its config,
    its dir, its latest checkpoint's path and that checkpoint's state."""
    cfg = _config(tmp, env, 1)
    run = tmp / "run"
    learn.train(cfg, run, progress=False, stop_after_updates=updates)
    ck = run_files.latest_checkpoint(run)
    assert ck is not None
    return cfg, run, ck, run_files.load_checkpoint(ck)


def test_a_checkpoint_that_does_not_replay_is_refused(tmp_path: Path) -> None:
    """A checkpoint whose stored observations differ from the replay (another simulator) stops
    the resume with a clear error instead of continuing inexactly."""
    cfg, run, ck, s = _stopped(tmp_path, "sim", 1)
    s["envs"]["obs"][2, -1] += 1e-3
    torch.save(s, ck)
    with pytest.raises(ResumeError, match="env 2's observation: the simulator is not the one"):
        learn.train(cfg, run, progress=False, resume=True)


def test_a_checkpoint_of_an_older_version_resumes_with_a_warning(tmp_path: Path) -> None:
    """Checkpoints written before the env state was stored still resume (the envs restart from
    a derived seed, as that version did), and say the resume is not exact."""
    cfg, run, ck, s = _stopped(tmp_path, "toy", 2)
    del s["envs"]
    torch.save(s, ck)
    with pytest.warns(UserWarning, match="older version .* not exact"):
        tr = learn.train(cfg, run, progress=False, resume=True)
    assert tr.state.update_idx == UPDATES
    assert learn.ResumeError is ResumeError
