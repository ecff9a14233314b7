"""`mimicrete eval RUN_DIR --video N`: videos of evaluation episodes with a status band whose
step, reward and picked / installed badges follow the episode."""

import json
import shutil
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from mimicrete.learn import video

POLICY = Path(__file__).parent / "data" / "group3_policy.pt"
H, W = 320 + video.BAND_H, 640  # the env's render (640 x 320) and the band


def _band(frame):
    return frame[H - video.BAND_H :].astype(int)


def _badge(frame, box):
    x0, x1 = box
    return _band(frame)[8:-8, x0 + 6 : x1 - 6]


def _is_green(px):
    r, g, b = px.reshape(-1, 3).mean(0)
    return g > r + 40 and g > b + 40


def _read_mp4(path):
    import imageio_ffmpeg

    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    w, h = meta["size"]
    return meta, [np.frombuffer(f, np.uint8).reshape(h, w, 3).copy() for f in gen]


def _read_gif(path):
    from PIL import Image

    with Image.open(path) as im:
        out, durations = [], []
        for i in range(im.n_frames):
            im.seek(i)
            durations.append(im.info["duration"])
            out.append(np.asarray(im.convert("RGB")))
    return durations, out


def test_status_band_badges_and_text():
    frame = np.full((320, 640, 3), 255, np.uint8)
    kw = dict(episode=0, seed=5, ret=0.0, fell=False)
    a = video.draw_status(frame, step=3, reward=0.0, picked=False, installed=False, **kw)
    b = video.draw_status(frame, step=4, reward=0.0, picked=False, installed=False, **kw)
    c = video.draw_status(frame, step=4, reward=1.0, picked=True, installed=False, **kw)
    d = video.draw_status(frame, step=4, reward=1.0, picked=True, installed=True, **kw)
    e = video.draw_status(
        frame, step=4, reward=-0.5, picked=True, installed=False, **{**kw, "fell": True}
    )
    assert a.shape == (H, W, 3) and a.dtype == np.uint8
    np.testing.assert_array_equal(a[:320], frame)  # the render itself is untouched
    # the step number changes the text, nothing else
    assert (a != b).any() and (a[:, video.PICKED_BOX[0] :] == b[:, video.PICKED_BOX[0] :]).all()
    assert not _is_green(_badge(a, video.PICKED_BOX)) and _is_green(_badge(c, video.PICKED_BOX))
    assert not _is_green(_badge(c, video.INSTALLED_BOX))
    assert _is_green(_badge(d, video.INSTALLED_BOX))
    r, g, _ = _badge(e, video.INSTALLED_BOX).reshape(-1, 3).mean(0)
    assert r > g + 60  # a fall shows red


def test_expert_episode_gif_follows_the_state(tmp_path):
    """The scripted expert picks and installs: the GIF's badges turn green on the steps where the
    env reports it, the step text changes every frame."""
    from mimicrete import _native

    env = gym.make("mimicrete/TileSuction-v0", render_mode="rgb_array")
    expert = _native.SimExpert("TileSuction")
    sim = env.unwrapped.sim
    picked_at = []

    def policy(obs):
        if not picked_at:
            expert.reset()
        picked_at.append(bool(sim.snapshot()["picked"]))
        return expert.act(sim)

    rec = video.record_episode(env, policy, 7, tmp_path / "e.gif", "gif")
    env.close()
    assert rec.installed and rec.picked and not rec.fell and rec.ret == pytest.approx(2.0)
    durations, frames = _read_gif(tmp_path / "e.gif")
    assert len(frames) == rec.frames == rec.length + 1
    assert frames[0].shape == (H, W, 3) and (rec.width, rec.height) == (W, H)
    assert durations == [40] * rec.length + [1000]  # 25 fps, the control rate; the end held 1 s
    # picked_at[t] is the state before action t, i.e. the state of frame t
    first_picked = picked_at.index(True)
    green = [_is_green(_badge(f, video.PICKED_BOX)) for f in frames]
    assert green == [t >= first_picked for t in range(len(frames))]
    installed = [_is_green(_badge(f, video.INSTALLED_BOX)) for f in frames]
    assert installed == [False] * rec.length + [True]
    steps = [_band(f)[:, :300] for f in frames]
    assert all(np.abs(a - b).sum() > 0 for a, b in zip(steps, steps[1:], strict=False))


def _run_dir(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(POLICY, run / "policy.pt")
    return run


def test_eval_video_through_cli(tmp_path, capsys):
    from mimicrete import cli

    run = _run_dir(tmp_path)
    fmt = "mp4" if video.mp4_available() else "gif"
    argv = ["eval", str(run), "--episodes", "1", "--video", "1", "--video-format", fmt]
    assert cli.main(argv) == 0
    out = capsys.readouterr().out
    path = run / "videos" / f"episode_000.{fmt}"
    assert f"wrote {path}" in out
    info = json.loads((run / "videos" / "episodes.json").read_text())
    ev = json.loads((run / "eval.json").read_text())
    (ep,) = info["episodes"]
    # video 0 is the evaluation's first episode (seed run seed + 10000)
    assert info["eval_seed"] == ev["seed"] == ep["episode_seed"] == 10_000
    assert ep["length"] == ev["mean_episode_length"] and ep["installed"]
    assert ev["installed_rate"] == 1
    if fmt == "mp4":
        meta, frames = _read_mp4(path)
        assert meta["codec"] == "h264" and meta["fps"] == 25
    else:
        _, frames = _read_gif(path)
    assert len(frames) == ep["frames"] == ep["length"] + 1
    assert frames[0].shape == (H, W, 3)
    # the badges, through the lossy encoding: grey at the start, green at the end
    assert not _is_green(_badge(frames[0], video.PICKED_BOX))
    assert not _is_green(_badge(frames[0], video.INSTALLED_BOX))
    assert _is_green(_badge(frames[-1], video.PICKED_BOX))
    assert _is_green(_badge(frames[-1], video.INSTALLED_BOX))
    assert not _is_green(_badge(frames[-2], video.INSTALLED_BOX))
    # the step / reward text changes between consecutive frames (pixels that flip between text
    # and background; the encoding's noise stays far below 100), the robot moves
    text = [_band(f)[:, :400] for f in frames]
    flips = [int((np.abs(a - b).max(-1) > 100).sum()) for a, b in zip(text, text[1:], strict=False)]
    assert min(flips) >= 5, flips
    assert np.abs(frames[0][:320].astype(int) - frames[-1][:320]).mean() > 1.0


def test_eval_video_bad_input(tmp_path, capsys, monkeypatch):
    import sys

    import torch

    from mimicrete import cli
    from mimicrete.learn.networks import Actor
    from mimicrete.testing.toyenv import OBS_DIM, toy_config

    run = _run_dir(tmp_path)
    assert cli.main(["eval", str(run), "--video", "-1"]) == 2
    assert "--video: 0 or more" in capsys.readouterr().err
    # a toy run has nothing to render: one line, before any evaluation
    cfg = toy_config(tmp_path)
    toy = tmp_path / "toy"
    toy.mkdir()
    ns = cfg.behavior.network_settings
    actor = Actor(OBS_DIM, 6, ns.hidden_units, ns.num_layers, ns.normalize)
    torch.save(
        {"actor": actor.state_dict(), "obs_dim": OBS_DIM, "step": 0, "config": cfg.to_dict()},
        toy / "policy.pt",
    )
    # no encoder: auto falls back to GIF, mp4 says what to install
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)
    assert not video.mp4_available() and video.resolve_format("auto") == "gif"
    argv = ["eval", str(run), "--episodes", "1", "--video", "1", "--video-format", "mp4"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "imageio-ffmpeg" in err and len(err.strip().splitlines()) == 1
    assert not (run / "videos").exists() and not (run / "eval.json").exists()
    argv = ["eval", str(toy), "--episodes", "1", "--video", "1", "--video-format", "gif"]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "has no renderer" in err and len(err.strip().splitlines()) == 1
    assert not (toy / "eval.json").exists()
