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
import io
import json
import math
import shutil
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from mimicrete._native import MimicreteError

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
    "Curriculum/Forward Scale",  # how far the own starts have widened (0 = paper, 1 = wide)
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


class RunDirError(MimicreteError, ValueError):
    """A run directory that cannot be used as asked (holds another run, nothing to resume)."""


#: Tags measured by the wall clock: they differ between two runs that compute the same things.
WALL_CLOCK_TAGS: tuple[str, ...] = ("Environment/Steps Per Second", "Environment/Elapsed Seconds")


LOCK_NAME = ".lock"


def run_dir_lock(run_dir: Path) -> Any:
    """The lock of a run dir (``run_dir/.lock``): one process trains in it at a time; a lock
    left by a killed process is taken over (:class:`mimicrete.safe_io.FileLock`)."""
    from mimicrete.safe_io import FileLock

    return FileLock(Path(run_dir) / LOCK_NAME, "this run directory", RunDirError)


def check_run_dir(run_dir: Path, *, resume: bool, force: bool) -> list[str]:
    """What :func:`prepare_run_dir` would do, without doing it: the run entries of ``run_dir``
    that ``force`` will delete. A dir that holds a run is refused unless ``resume`` (continue it)
    or ``force``, so an old run's checkpoints never come back into a new one."""
    present = [e for e in RUN_ENTRIES if (run_dir / e).exists()]
    if resume:
        if latest_checkpoint(run_dir) is None:
            raise RunDirError(f"--resume: no checkpoint in {run_dir / CHECKPOINTS}")
        return []
    if present and not force:
        raise RunDirError(
            f"{run_dir} holds another run ({', '.join(present)}): --resume continues it, "
            "--force replaces it, or choose another --run-dir"
        )
    return present


def clear_run_entries(run_dir: Path, entries: list[str]) -> None:
    for e in entries:
        p = run_dir / e
        if p.is_dir():
            shutil.rmtree(p)
        else:
            p.unlink(missing_ok=True)


def prepare_run_dir(run_dir: Path, *, resume: bool, force: bool) -> None:
    """Make ``run_dir`` ready: :func:`check_run_dir`, then the old run's files deleted with
    ``force``."""
    run_dir.mkdir(parents=True, exist_ok=True)
    clear_run_entries(run_dir, check_run_dir(run_dir, resume=resume, force=force))


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
    """``path`` written whole or not at all (:func:`mimicrete.safe_io.atomic_write`)."""
    from mimicrete.safe_io import atomic_write as write

    write(path, text)


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
            atomic_write(self.csv_path, _csv_line(["step", *TAGS]))
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
        lines = [_csv_line(["step", *TAGS])]
        for s in sorted(kept):
            lines.append(_csv_line([s, *[kept[s].get(t) or "" for t in TAGS]]))
        atomic_write(self.csv_path, "".join(lines))

    def write(self, step: int, row: dict[str, float]) -> None:
        from mimicrete.safe_io import append_text

        for k, v in row.items():
            self.tb.add_scalar(k, v, step)
        self.tb.flush()
        append_text(self.csv_path, _csv_line([step, *[_fmt(row.get(t)) for t in TAGS]]))

    def close(self) -> None:
        self.tb.close()


def _csv_line(cells: list[Any]) -> str:
    buf = io.StringIO()
    csv.writer(buf).writerow(cells)
    return buf.getvalue()


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


def checkpoints(run_dir: Path) -> list[Path]:
    """``checkpoints/step_*.pt`` of a run, oldest first."""
    return sorted((Path(run_dir) / CHECKPOINTS).glob("step_*.pt"))


def latest_checkpoint(run_dir: Path) -> Path | None:
    ckpts = checkpoints(run_dir)
    return ckpts[-1] if ckpts else None


def save_checkpoint(run_dir: Path, step: int, state: dict[str, Any], keep: int) -> Path:
    """``checkpoints/step_<step>.pt``, written whole or not at all; all but the last ``keep``
    checkpoints are deleted. (No ONNX per checkpoint: torch's dynamo exporter takes seconds,
    and only the final ``policy.onnx`` is read; export any checkpoint with :func:`export_onnx`
    if needed.)"""
    from mimicrete.safe_io import torch_save

    ck_dir = run_dir / CHECKPOINTS
    ck_dir.mkdir(parents=True, exist_ok=True)
    path = ck_dir / f"step_{step:09d}.pt"
    torch_save(state, path)
    ckpts = sorted(ck_dir.glob("step_*.pt"))
    for old in ckpts[: max(0, len(ckpts) - max(1, keep))]:
        old.unlink()
        old.with_suffix(".onnx").unlink(missing_ok=True)  # left by runs of older versions
    return path


class CheckpointError(RunDirError):
    """A checkpoint that cannot be read (names the file and why)."""

    def __init__(self, message: str, why: str = "") -> None:
        super().__init__(message)
        self.why = why or message


#: what every trainer checkpoint holds (a file without them is not one)
CHECKPOINT_KEYS = ("actor", "critic", "opt", "step", "update_idx", "config")


def load_checkpoint(path: Path) -> dict[str, Any]:
    """A trainer checkpoint; :class:`CheckpointError` naming the file when it is damaged, cut or
    not a checkpoint."""
    import pickle
    import zipfile

    import torch

    path = Path(path)
    try:
        s = torch.load(path, weights_only=False)
    except (
        pickle.UnpicklingError, EOFError, RuntimeError, ValueError, KeyError, TypeError,
        AttributeError, ImportError, IndexError, zipfile.BadZipFile, UnicodeDecodeError,
    ) as e:  # fmt: skip
        why = f"damaged ({type(e).__name__}: {(str(e).splitlines() or [''])[0][:120]})"
        raise CheckpointError(f"{path}: {why}", why) from e
    if not isinstance(s, dict) or any(k not in s for k in CHECKPOINT_KEYS):
        raise CheckpointError(f"{path}: not a trainer checkpoint", "not a trainer checkpoint")
    return s


def load_latest_intact(run_dir: Path, log: Any = None) -> tuple[Path, dict[str, Any]]:
    """The newest checkpoint of ``run_dir`` that loads, and its state. Damaged newer ones are
    reported through ``log`` (one line each, naming the file) and passed over; when none loads,
    :class:`CheckpointError` lists them."""
    bad: list[CheckpointError] = []
    names: list[str] = []
    for path in reversed(checkpoints(run_dir)):
        try:
            s = load_checkpoint(path)
        except CheckpointError as e:
            bad.append(e)
            names.append(path.name)
            continue
        for e in bad:
            if log is not None:
                log(f"{e}; resuming from the one before it, {path.name}")
        return path, s
    ck_dir = Path(run_dir) / CHECKPOINTS
    if not bad:
        raise RunDirError(f"--resume: no checkpoint in {ck_dir}")
    shown = "; ".join(f"{n}: {e.why[:80]}" for n, e in zip(names[:3], bad, strict=False))
    more = f"; and {len(bad) - 3} more" if len(bad) > 3 else ""
    raise CheckpointError(f"--resume: no intact checkpoint in {ck_dir} ({shown}{more})")


def save_policy(run_dir: Path, actor: Actor, obs_dim: int, step: int, cfg: TrainerConfig) -> None:
    """The final policy: ``policy.onnx`` and ``policy.pt`` (actor weights, obs size, config),
    each written whole or not at all."""
    from mimicrete.safe_io import torch_save

    export_onnx(actor, obs_dim, run_dir / "policy.onnx")
    torch_save(
        {"actor": actor.state_dict(), "obs_dim": obs_dim, "step": step, "config": cfg.to_dict()},
        run_dir / "policy.pt",
    )


class PolicyFileError(MimicreteError, ValueError):
    """A ``policy.pt`` that is missing, unreadable or not a policy; names the file."""


def load_policy(run_dir: Path) -> tuple[Actor, TrainerConfig]:
    """The actor of ``run_dir/policy.pt`` (eval mode) and the config it was trained with."""
    path = Path(run_dir) / "policy.pt"
    if not Path(run_dir).is_dir():
        raise FileNotFoundError(f"{run_dir}: no such run directory")
    if not path.exists():
        raise FileNotFoundError(f"{path} does not exist (is {run_dir} a finished training run?)")
    return load_policy_file(path)


def load_policy_file(path: Path) -> tuple[Actor, TrainerConfig]:
    """:func:`load_policy` of a policy file wherever it lies (``PolicyFileError`` naming it when
    it is not one)."""
    import pickle

    import torch

    from . import config as config_mod
    from .env import N_CONT
    from .networks import Actor, n_branches_of

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
    from mimicrete.safe_io import atomic_write as write

    write(path, program.model_proto.SerializeToString())
