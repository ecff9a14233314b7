"""Rollout videos of a trained policy (``mimicrete eval RUN_DIR --video N``).

Video ``k`` is the episode with episode seed ``eval seed + k``: the first episode of evaluation
env ``k`` (``evaluate.run_episodes`` resets env ``i`` to seed ``eval seed + i``), so for
``k < num_envs`` the video shows an episode the evaluation counted. The deterministic policy runs
in one :class:`mimicrete.envs.MimicreteEnv` with ``render_mode="rgb_array"``; each frame is the
env's own render (top and side views) with a status band under it: episode, seed, step, the
step's reward, the return so far, and a *picked* and an *installed* badge that turn green when
the tile is picked / installed (grey before, red *fell* when it falls). One frame per state: the
reset state, then one after every step, so an episode of ``T`` steps has ``T + 1`` frames, played
at the control rate (25 fps); a GIF holds its last frame for a second before it loops.

Written into ``RUN_DIR/videos/``: ``episode_<k>.mp4`` (H.264 by the ffmpeg binary of the
``imageio-ffmpeg`` wheel) or, where that is not installed or ``fmt="gif"``, ``episode_<k>.gif``
(Pillow), and ``episodes.json`` (per video: file, seed, length, return, picked, installed,
frames, size).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete._native import MimicreteError

VIDEO_DIR = "videos"
FORMATS = ("auto", "mp4", "gif")

#: height of the status band added under the env's render (the frame stays a multiple of 16
#: high, as H.264 wants, for the 320-pixel-high render)
BAND_H = 32
#: x ranges (pixels, from the left) of the picked and installed badges in the band
PICKED_BOX = (470, 548)
INSTALLED_BOX = (552, 636)
_BAND_BG = (32, 36, 44)
_TEXT = (235, 235, 235)
_OFF = (90, 94, 102)
_ON = (46, 160, 67)
_FELL = (200, 50, 50)


class VideoError(MimicreteError, ValueError):
    """A video that cannot be made as asked (no encoder for mp4, an env that does not render)."""


@dataclass(frozen=True)
class RecordedEpisode:
    file: str
    episode_seed: int
    length: int
    ret: float
    picked: bool
    installed: bool
    fell: bool
    frames: int
    width: int
    height: int

    @property
    def outcome(self) -> str:
        if self.installed:
            return "installed"
        if self.fell:
            return "fell"
        return "picked, not installed" if self.picked else "not picked"


def mp4_available() -> bool:
    """True if ``imageio-ffmpeg`` (with its ffmpeg binary) is installed."""
    try:
        import imageio_ffmpeg

        return Path(imageio_ffmpeg.get_ffmpeg_exe()).exists()
    except (ImportError, RuntimeError):
        return False


def resolve_format(fmt: str) -> str:
    """``auto`` -> ``mp4`` where an encoder is installed, else ``gif``."""
    if fmt not in FORMATS:
        raise VideoError(f"video format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    if fmt == "auto":
        return "mp4" if mp4_available() else "gif"
    if fmt == "mp4" and not mp4_available():
        raise VideoError(
            "mp4 needs the ffmpeg binary of the imageio-ffmpeg package (pip install "
            "imageio-ffmpeg); --video-format gif needs nothing more"
        )
    return fmt


@lru_cache(maxsize=4)
def _font(size: int) -> Any:
    from matplotlib import font_manager
    from PIL import ImageFont

    return ImageFont.truetype(font_manager.findfont("DejaVu Sans"), size)


def draw_status(
    frame: np.ndarray,
    *,
    episode: int,
    seed: int,
    step: int,
    reward: float | None,
    ret: float,
    picked: bool,
    installed: bool,
    fell: bool = False,
) -> np.ndarray:
    """``frame`` (H, W, 3) uint8 with the status band appended below -> (H + BAND_H, W, 3)."""
    from PIL import Image, ImageDraw

    h, w = frame.shape[:2]
    if w < INSTALLED_BOX[1] + 4:
        raise VideoError(f"frames must be at least {INSTALLED_BOX[1] + 4} pixels wide, got {w}")
    img = Image.new("RGB", (w, h + BAND_H), _BAND_BG)
    img.paste(Image.fromarray(np.ascontiguousarray(frame[..., :3])), (0, 0))
    d = ImageDraw.Draw(img)
    font, small = _font(13), _font(11)
    r = "   -" if reward is None else f"{reward:+.1f}"
    text = f"ep {episode}  seed {seed}  step {step:3d}  reward {r}  return {ret:+.1f}"
    d.text((8, h + BAND_H // 2), text, fill=_TEXT, font=font, anchor="lm")
    for (x0, x1), label, on in (
        (PICKED_BOX, "picked", picked),
        (INSTALLED_BOX, "fell" if fell and not installed else "installed", installed or fell),
    ):
        color = (_FELL if label == "fell" else _ON) if on else _OFF
        d.rounded_rectangle((x0, h + 5, x1, h + BAND_H - 6), radius=5, fill=color)
        d.text(((x0 + x1) // 2, h + BAND_H // 2), label, fill=_TEXT, font=small, anchor="mm")
    return np.asarray(img)


class _Writer:
    """One video, written under a hidden temporary name and renamed once complete (a failure or
    an interruption leaves no partial video under the final name)."""

    def __init__(self, path: Path, fmt: str, fps: int):
        self.final, self.fmt, self.fps = path, fmt, fps
        self.path = path.with_name(f".{path.name}.partial")
        self.frames: list[np.ndarray] = []
        self._gen: Any = None

    def add(self, frame: np.ndarray) -> None:
        if self.fmt == "gif":
            self.frames.append(frame)
            return
        if self._gen is None:
            import imageio_ffmpeg

            h, w = frame.shape[:2]
            self._gen = imageio_ffmpeg.write_frames(
                str(self.path),
                (w, h),
                fps=self.fps,
                codec="libx264",
                pix_fmt_out="yuv420p",
                quality=7,
                macro_block_size=16,
                ffmpeg_log_level="error",
                output_params=["-movflags", "+faststart", "-f", "mp4"],
            )
            self._gen.send(None)
        self._gen.send(np.ascontiguousarray(frame))

    def close(self) -> None:
        from mimicrete.safe_io import write_error

        try:
            if self.fmt == "gif":
                write_gif(self.path, self.frames, self.fps)
            elif self._gen is not None:
                self._gen.close()
            if self.path.exists():
                os.replace(self.path, self.final)
        except OSError as e:
            self.path.unlink(missing_ok=True)
            raise write_error(self.final, e) from e
        except BaseException:
            self.path.unlink(missing_ok=True)
            raise


def write_gif(
    path: Path, frames: list[np.ndarray], fps: int, colors: int = 64, hold_last: float = 1.0
) -> None:
    """Frames as a looping GIF (Pillow), each frame with its own adaptive palette, shown for
    ``1 / fps`` s; the last frame (the episode's end) for ``hold_last`` s before the loop."""
    from PIL import Image

    if not frames:
        raise VideoError("no frames to write")
    images = [
        Image.fromarray(f).quantize(
            colors, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE
        )
        for f in frames
    ]
    images[0].save(
        path,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=[round(1000 / fps)] * (len(images) - 1) + [round(1000 * max(hold_last, 1 / fps))],
        loop=0,
        optimize=True,
    )


def record_episode(
    env: Any,
    policy: Callable[[np.ndarray], np.ndarray],
    episode_seed: int,
    path: Path,
    fmt: str,
    episode: int = 0,
    fps: int | None = None,
) -> RecordedEpisode:
    """Run one episode of ``policy`` (obs (obs_dim,) -> action) in ``env`` (a
    ``MimicreteEnv`` with ``render_mode="rgb_array"``) from ``episode_seed`` and write its
    video to ``path``."""
    base = getattr(env, "unwrapped", env)
    if getattr(base, "render_mode", None) != "rgb_array":
        raise VideoError("the env must be made with render_mode='rgb_array'")
    fps = fps or int(base.metadata.get("render_fps", 25))
    obs, info = env.reset(options={"episode_seed": int(episode_seed)})
    writer = _Writer(path, fmt, fps)
    ret, length, frames = 0.0, 0, 0
    picked = installed = fell = False
    size = (0, 0)

    def add(reward: float | None) -> None:
        nonlocal frames, size
        img = draw_status(
            env.render(),
            episode=episode,
            seed=int(episode_seed),
            step=length,
            reward=reward,
            ret=ret,
            picked=picked,
            installed=installed,
            fell=fell,
        )
        size = (img.shape[1], img.shape[0])
        writer.add(img)
        frames += 1

    try:
        add(None)
        while True:
            action = np.asarray(policy(np.asarray(obs, np.float32)), np.float32)
            obs, r, term, trunc, info = env.step(action)
            ret += float(r)
            length += 1
            picked |= bool(info.get("picked", False))
            installed |= bool(info.get("installed", False))
            fell |= bool(info.get("fell", False))
            add(float(r))
            if term or trunc:
                break
    finally:
        writer.close()
    return RecordedEpisode(
        path.name, int(episode_seed), length, ret, picked, installed, fell, frames, *size
    )


def check_renderable(env_id: str) -> None:
    """A :class:`VideoError` unless ``env_id`` names a simulator env (the toy env cannot draw)."""
    from .env import TOY_PREFIX

    if env_id.startswith(TOY_PREFIX):
        raise VideoError(f"{env_id} has no renderer: videos need a simulator env")


def record_run_videos(
    run_dir: str | Path, count: int, seed: int | None = None, fmt: str = "auto"
) -> list[RecordedEpisode]:
    """Videos of the first ``count`` evaluation episodes of ``run_dir/policy.pt`` (seeds
    ``eval seed + k``) into ``run_dir/videos/``, with ``episodes.json``."""
    import torch

    from mimicrete import envs

    from .run_files import load_policy

    if count < 1:
        raise ValueError(f"video count: at least 1, got {count}")
    fmt = resolve_format(fmt)
    run_dir = Path(run_dir)
    actor, cfg = load_policy(run_dir)
    env_id = cfg.env_settings.env_id
    check_renderable(env_id)
    s = cfg.env_settings.seed + 10_000 if seed is None else seed
    out = run_dir / VIDEO_DIR
    out.mkdir(exist_ok=True)
    for old in [*out.glob("episode_*.mp4"), *out.glob("episode_*.gif")]:
        old.unlink()  # videos/ holds the last call's videos only

    @torch.no_grad()
    def policy(obs: np.ndarray) -> np.ndarray:
        return actor.deterministic(torch.from_numpy(obs)[None])[0].numpy()

    task_file = cfg.env_settings.task_file
    if task_file is not None:
        env = envs.MimicreteEnv(render_mode="rgb_array", spec=task_file)
    else:
        env = envs.MimicreteEnv(envs.task_of(env_id), render_mode="rgb_array")
    done = []
    try:
        for k in range(count):
            path = out / f"episode_{k:03d}.{fmt}"
            done.append(record_episode(env, policy, s + k, path, fmt, episode=k))
    finally:
        env.close()
    info = {
        "env_id": env_id,
        "eval_seed": s,
        "format": fmt,
        "fps": envs.MimicreteEnv.metadata["render_fps"],
        "episodes": [asdict(e) for e in done],
    }
    from mimicrete.safe_io import atomic_write

    atomic_write(out / "episodes.json", json.dumps(info, indent=1))
    return done
