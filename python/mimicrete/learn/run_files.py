"""What a training run writes into its directory, and reading it back.

    run_dir/
      resolved_config.yaml   the config as trained (defaults and overrides applied)
      run.json               budget, demo path, demo steps loaded / idle-dropped / files skipped
      scalars.csv            one row per summary: ``step`` then :data:`TAGS` (ML-Agents' names)
      tensorboard/           the same scalars as TensorBoard events
      checkpoints/           step_<step>.pt (full trainer state, exact resume), last K kept
      policy.pt, policy.onnx the final policy (``mimicrete eval`` reads policy.pt)
      eval.json, plots/      written by the evaluation and the plots
      videos/                ``mimicrete eval --video N``: episode_<k>.mp4 / .gif, episodes.json

torch is imported inside the functions that need it, so reading scalars (the report) does not.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from .config import TrainerConfig
    from .networks import Actor

# Scalars written to TensorBoard and to the CSV (ML-Agents' tag names + ours). New tags go at the
# end, so the columns of older runs keep their places.
TAGS = [
    "Environment/Cumulative Reward",
    "Environment/Episode Length",
    "Environment/Picked Rate",
    "Environment/Installed Rate",
    "Environment/Episodes",
    "Policy/Extrinsic Reward",
    "Policy/GAIL Reward",
    "Policy/Extrinsic Value Estimate",
    "Policy/GAIL Value Estimate",
    "Policy/GAIL Expert Estimate",
    "Policy/GAIL Policy Estimate",
    "Policy/GAIL Grad Mag Loss",
    "Policy/Learning Rate",
    "Policy/Epsilon",
    "Policy/Beta",
    "Policy/Entropy",
    "Losses/Policy Loss",
    "Losses/Value Loss",
    "Losses/GAIL Loss",
    "Losses/Pretraining Loss",
    "Losses/Pretraining Learning Rate",
    "Environment/Steps Per Second",
    # CleanRL's PPO diagnostics
    "Policy/Approx KL",  # mean of (r - 1) - log r over the minibatches (Schulman's k3 estimator)
    "Policy/Clip Fraction",  # share of action components whose ratio left [1 - eps, 1 + eps]
    "Policy/Extrinsic Explained Variance",  # 1 - Var(returns - V) / Var(returns), per value head
    "Policy/GAIL Explained Variance",
    # demo_curriculum (curriculum.py); episodes started inside a demo are counted here only
    "Curriculum/Progress",  # mean over demos of how far back the start has moved (1 = solved)
    "Curriculum/Demos Solved",
    "Curriculum/Installed Rate",
    "Curriculum/Episodes",
    "Curriculum/Replayed Steps",  # simulator steps spent replaying demos (not agent steps)
    "Environment/Elapsed Seconds",  # wall clock since this process started training
]

CSV_NAME = "scalars.csv"
RUN_INFO = "run.json"
CHECKPOINTS = "checkpoints"
#: what a training run writes (``--force`` removes these and nothing else)
RUN_ENTRIES = (
    "resolved_config.yaml",
    RUN_INFO,
    CSV_NAME,
    "tensorboard",
    CHECKPOINTS,
    "policy.pt",
    "policy.onnx",
    "eval.json",
    "plots",
    "videos",
)


class RunDirError(ValueError):
    """A run directory that cannot be used as asked (holds another run, nothing to resume)."""


#: Tags measured by the wall clock: they differ between two runs that compute the same things.
WALL_CLOCK_TAGS: tuple[str, ...] = ("Environment/Steps Per Second", "Environment/Elapsed Seconds")


def prepare_run_dir(run_dir: Path, *, resume: bool, force: bool) -> None:
    """Make ``run_dir``. One that already holds a run is refused unless ``resume`` (continue it)
    or ``force`` (its run files are deleted first), so an old run's checkpoints never come back
    into a new one."""
    run_dir.mkdir(parents=True, exist_ok=True)
    present = [e for e in RUN_ENTRIES if (run_dir / e).exists()]
    if resume:
        if latest_checkpoint(run_dir) is None:
            raise RunDirError(f"--resume: no checkpoint in {run_dir / CHECKPOINTS}")
        return
    if not present:
        return
    if not force:
        raise RunDirError(
            f"{run_dir} holds another run ({', '.join(present)}): --resume continues it, "
            "--force replaces it, or choose another --run-dir"
        )
    for e in present:
        p = run_dir / e
        if p.is_dir():
            shutil.rmtree(p)
        else:
            p.unlink()


def read_run_info(run_dir: Path) -> dict[str, Any]:
    """``run.json`` of a run dir ({} when there is none or it is not a JSON object)."""
    try:
        info = json.loads((run_dir / RUN_INFO).read_text())
    except (OSError, ValueError):
        return {}
    return info if isinstance(info, dict) else {}


def write_run_info(run_dir: Path, info: dict[str, Any]) -> None:
    atomic_write(run_dir / RUN_INFO, json.dumps(info, indent=1))


def atomic_write(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


# ----------------------------------------------------------------------------------------------
# scalars
# ----------------------------------------------------------------------------------------------


class ScalarLog:
    """TensorBoard + CSV writer of the same scalars. On resume from a checkpoint at step ``S``,
    CSV rows after ``S`` (logged by the interrupted run after its last checkpoint, and about to be
    logged again) are dropped first, so the CSV never holds a step twice."""

    def __init__(self, run_dir: Path, resume_step: int | None = None):
        from torch.utils.tensorboard import SummaryWriter

        self.csv_path = run_dir / CSV_NAME
        if resume_step is not None and self.csv_path.exists():
            self._keep_rows_up_to(resume_step)
        else:
            with open(self.csv_path, "w", newline="") as f:
                csv.writer(f).writerow(["step", *TAGS])
        self.tb = SummaryWriter(str(run_dir / "tensorboard"))

    def _keep_rows_up_to(self, step: int) -> None:
        with open(self.csv_path, newline="") as f:
            rows = list(csv.DictReader(f))
        kept = {}
        for row in rows:
            try:
                s = int(float(row.get("step") or ""))
            except ValueError:
                continue  # a row cut by a crash mid-write
            if s <= step:
                kept[s] = row  # a step written twice by an older version: its last row
        tmp = self.csv_path.with_name(CSV_NAME + ".tmp")
        with open(tmp, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["step", *TAGS])
            for s in sorted(kept):
                w.writerow([s, *[kept[s].get(t) or "" for t in TAGS]])
        os.replace(tmp, self.csv_path)

    def write(self, step: int, row: dict[str, float]) -> None:
        for k, v in row.items():
            self.tb.add_scalar(k, v, step)
        self.tb.flush()
        with open(self.csv_path, "a", newline="") as f:
            csv.writer(f).writerow([step, *[_fmt(row.get(t)) for t in TAGS]])

    def close(self) -> None:
        self.tb.close()


def _fmt(v: float | None) -> str:
    return "" if v is None or not math.isfinite(v) else repr(float(v))


def read_scalars(path: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``scalars.csv`` (or the run dir holding it) -> tag -> (steps, values), sorted by step,
    empty and non-finite cells skipped. A step written twice keeps its last row."""
    path = Path(path)
    if path.is_dir():
        path = path / CSV_NAME
    rows: dict[int, dict[str, str]] = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            try:
                step = int(float(row["step"]))
            except (KeyError, TypeError, ValueError):
                continue
            rows[step] = row
    out: dict[str, tuple[list[int], list[float]]] = {}
    for step in sorted(rows):
        for k, v in rows[step].items():
            if k == "step" or v in ("", None):
                continue
            try:
                x = float(v)
            except (TypeError, ValueError):
                continue
            if math.isfinite(x):
                s, vals = out.setdefault(k, ([], []))
                s.append(step)
                vals.append(x)
    return {k: (np.asarray(s, np.int64), np.asarray(v, np.float64)) for k, (s, v) in out.items()}


# ----------------------------------------------------------------------------------------------
# checkpoints, the final policy, ONNX
# ----------------------------------------------------------------------------------------------


def latest_checkpoint(run_dir: Path) -> Path | None:
    ckpts = sorted((Path(run_dir) / CHECKPOINTS).glob("step_*.pt"))
    return ckpts[-1] if ckpts else None


def save_checkpoint(run_dir: Path, step: int, state: dict[str, Any], keep: int) -> Path:
    """``checkpoints/step_<step>.pt``, written atomically; all but the last ``keep`` checkpoints
    are deleted. (No ONNX per checkpoint: torch's dynamo exporter takes seconds, and only the
    final ``policy.onnx`` is read; export any checkpoint with :func:`export_onnx` if needed.)"""
    import torch

    ck_dir = run_dir / CHECKPOINTS
    ck_dir.mkdir(parents=True, exist_ok=True)
    path = ck_dir / f"step_{step:09d}.pt"
    tmp = path.with_suffix(".tmp")
    torch.save(state, tmp)
    os.replace(tmp, path)
    ckpts = sorted(ck_dir.glob("step_*.pt"))
    for old in ckpts[: max(0, len(ckpts) - max(1, keep))]:
        old.unlink()
        old.with_suffix(".onnx").unlink(missing_ok=True)  # left by runs of older versions
    return path


def load_checkpoint(path: Path) -> dict[str, Any]:
    import torch

    return torch.load(path, weights_only=False)


def save_policy(run_dir: Path, actor: Actor, obs_dim: int, step: int, cfg: TrainerConfig) -> None:
    """The final policy: ``policy.onnx`` and ``policy.pt`` (actor weights, obs size, config)."""
    import torch

    export_onnx(actor, obs_dim, run_dir / "policy.onnx")
    torch.save(
        {"actor": actor.state_dict(), "obs_dim": obs_dim, "step": step, "config": cfg.to_dict()},
        run_dir / "policy.pt",
    )


class PolicyFileError(ValueError):
    """A ``policy.pt`` that is missing, unreadable or not a policy; names the file."""


def load_policy(run_dir: Path) -> tuple[Actor, TrainerConfig]:
    """The actor of ``run_dir/policy.pt`` (eval mode) and the config it was trained with."""
    import pickle

    import torch

    from . import config as config_mod
    from .env import N_CONT
    from .networks import Actor, n_branches_of

    path = Path(run_dir) / "policy.pt"
    if not Path(run_dir).is_dir():
        raise FileNotFoundError(f"{run_dir}: no such run directory")
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist (is {run_dir} a finished training run?)")
    try:
        s = torch.load(path, weights_only=False)
        cfg = config_mod.from_dict(s["config"])
        ns = cfg.behavior.network_settings
        nb = n_branches_of(s["actor"])  # 1 (end effector), Screw 2 (+ spin)
        actor = Actor(int(s["obs_dim"]), N_CONT, ns.hidden_units, ns.num_layers, ns.normalize, nb)
        actor.load_state_dict(s["actor"])
    except (pickle.UnpicklingError, RuntimeError, EOFError, KeyError, TypeError, ValueError) as e:
        why = str(e).split(". ")[0][:160]
        raise PolicyFileError(f"{path}: not a readable policy ({type(e).__name__}: {why})") from e
    actor.eval()
    return actor, cfg


#: ONNX opset of the exported policies (onnxruntime >= 1.14 runs it)
ONNX_OPSET = 18


def require_onnx_exporter() -> None:
    """``ModuleNotFoundError`` naming the package if the ONNX exporter's onnxscript is missing
    (checked before training, so a run does not fail at its first checkpoint)."""
    import importlib.util

    if importlib.util.find_spec("onnxscript") is None:
        raise ModuleNotFoundError(
            "policy.onnx is written by torch's dynamo-based ONNX exporter, which needs onnxscript: "
            "pip install onnxscript==0.7.2 (requirements/base.txt)",
            name="onnxscript",
        )


def export_onnx(actor: Actor, obs_dim: int, path: Path) -> None:
    """The deterministic policy as ONNX: input ``obs`` (B, obs_dim) float32 -> ``actions``
    (B, 6 + n_branches) float32 (6 joint motions in [-1, 1], then each command in {-1, 0, 1}:
    the end effector; for Screw also the spin), any batch size B.

    Exported by torch's current exporter (``torch.onnx.export(..., dynamo=True)``: torch.export
    then onnxscript), opset :data:`ONNX_OPSET`; the observation normaliser's statistics are folded
    into constants. Written atomically."""
    import copy
    import logging

    import torch

    from .networks import DeterministicPolicy

    require_onnx_exporter()
    model = DeterministicPolicy(copy.deepcopy(actor)).eval()
    # a batch of 2: torch.export specialises a dimension traced at size 1 to the constant 1
    example = torch.zeros(2, obs_dim)
    # the exporter logs a warning per torchvision operator it cannot register (torchvision is
    # not installed, and not needed)
    registration = logging.getLogger("torch.onnx._internal.exporter._registration")
    level = registration.level
    registration.setLevel(logging.ERROR)
    try:
        program = torch.onnx.export(
            model,
            (example,),
            input_names=["obs"],
            output_names=["actions"],
            dynamic_shapes=({0: torch.export.Dim("batch")},),
            opset_version=ONNX_OPSET,
            dynamo=True,
            optimize=True,
            verbose=False,
        )
    finally:
        registration.setLevel(level)
    if program is None or program.model_proto is None:
        raise RuntimeError("torch.onnx.export returned no model")
    data = program.model_proto.SerializeToString()
    tmp = path.with_suffix(".onnx.tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)
