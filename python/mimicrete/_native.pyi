"""Type stubs for ``mimicrete._native``, the pyo3 module built from ``crates/pyext``.

Written by hand from ``crates/pyext/src/{errors,kin,sim,demo}.rs`` and checked against the built
module by ``tests/test_stubs.py`` (``python -m mypy.stubtest mimicrete._native``).

Array arguments typed ``NDArray[np.float64]`` must really be float64 numpy arrays (the bindings
borrow them without conversion); arguments typed ``ArrayLike`` are converted (to float32 or bool).
Units: metres, radians, seconds; quaternions are ``[x, y, z, w]``.
"""

import os
from collections.abc import Sequence
from pathlib import Path
from types import TracebackType
from typing import Any, Final, Literal, NotRequired, TypedDict, final

import numpy as np
from numpy.typing import ArrayLike, NDArray

_StrPath = str | os.PathLike[str]
_F64 = NDArray[np.float64]
_F32 = NDArray[np.float32]
_Bool = NDArray[np.bool_]
# A calibration: (base_from_space (4, 4) or None for ur3-kin's default, scale, space name).
_Calibration = tuple[_F64 | None, float, str]

__version__: str

__all__ = [
    "__version__",
    "MimicreteError",
    "IkError",
    "SimError",
    "LogFormatError",
    "SimInputError",
    "ActionShapeError",
    "IoError",
    "log_format_error",
    "kin_models",
    "kin_dh",
    "kin_fk",
    "kin_fk_batch",
    "kin_fk_all",
    "kin_jacobian",
    "kin_ik",
    "kin_ik_gn",
    "kin_ik_all",
    "kin_ik_batch",
    "kin_hand_to_target",
    "kin_hand_to_target_batch",
    "kin_points_to_base",
    "kin_default_calibration",
    "kin_urdf",
    "kin_hand_layouts",
    "SimEnv",
    "SimVecEnv",
    "SimExpert",
    "sim_constants",
    "scene_entities",
    "scene_frames",
    "load_task_spec",
    "task_spec",
    "hand_scale",
    "joint_motion",
    "DemoWriter",
    "demo_parse_handlog",
    "demo_parse_handlog_str",
    "demo_write_handlog",
    "demo_read",
    "demo_load",
    "demo_salvage",
    "demo_salvage_to",
    "demo_verify",
    "demo_files",
    "DEMO_FORMAT_VERSION",
    "HANDLOG_VERSION",
    "TeleopSession",
    "teleop_gesture_commands",
    "TELEOP_BRANCH_JUMP",
]

# ---------------------------------------------------------------------------------------------
# Exceptions (errors.rs)

class MimicreteError(Exception):
    """Base class of every mimicrete error."""

class IkError(MimicreteError):
    """Inverse kinematics found no solution. ``reason``: why (the unreachable condition, or
    ``"did not converge"``); ``iters``, ``pos_residual_m``, ``rot_residual_rad``: the solver's
    iterations and best residuals when it did not converge, else None."""

    reason: str | None
    iters: int | None
    pos_residual_m: float | None
    rot_residual_rad: float | None

class SimError(MimicreteError):
    """The simulator refused an input or state (``reason``: what)."""

    reason: str | None

class LogFormatError(MimicreteError):
    """A hand log or demo file is malformed: ``str(e)`` is ``file:line: reason`` (``file: reason``
    when no line applies); the parts are ``file``, ``line`` (1-based, or None) and ``reason``."""

    file: str | None
    line: int | None
    reason: str | None

class SimInputError(SimError, ValueError):
    """The simulator refused the caller's input: an unknown task, a non-finite action, an invalid
    state or argument (a ``SimError`` and a ``ValueError``; ``reason``: what). A bad task spec
    also has ``field`` and ``value`` (a value out of range), or ``line``, ``column`` and ``text``
    (TOML or structure: where, and that line without its comment)."""

class ActionShapeError(SimInputError):
    """An action array of the wrong shape (``SimEnv.step``, ``SimVecEnv.step``): ``expected`` and
    ``got`` are shapes, e.g. ``(7,)`` and ``(6,)``; ``task`` the task whose ``act_dim`` it must
    match."""

    expected: tuple[int, ...] | None
    got: tuple[int, ...] | None
    task: str | None

class IoError(MimicreteError, OSError):
    """A file the Rust core could not read or write: an ``OSError`` with ``errno``, ``strerror``
    and ``filename``. An errno that Python maps to an ``OSError`` subclass (``ENOENT`` →
    ``FileNotFoundError``, ``EACCES`` → ``PermissionError``, ...) is raised as a class that is both
    this and that subclass, so ``except FileNotFoundError`` catches a missing file."""

def log_format_error(file: str, line: int | None, reason: str) -> LogFormatError:
    """A ``LogFormatError`` with these fields and the native message rule (for Python code that
    finds a malformed file itself)."""

# ---------------------------------------------------------------------------------------------
# Kinematics (kin.rs). `model_name` is one of `kin_models()`; poses are (4, 4) homogeneous
# matrices in the robot Base frame.

def kin_models() -> list[str]:
    """Names of the supported models."""

def kin_dh(model_name: str) -> dict[str, float]:
    """DH parameters: d1, a2, a3, d4, d5, d6 (m) and reach (m)."""

def kin_fk(q: _F64, model_name: str) -> _F64:
    """FK: q (6,) rad → tool0 in Base (4, 4)."""

def kin_fk_batch(q: _F64, model_name: str) -> _F64:
    """FK of many configurations: q (N, 6) → (N, 4, 4)."""

def kin_fk_all(q: _F64, model_name: str) -> _F64:
    """Every DH frame (Base, after joint 1, …, tool0): (7, 4, 4)."""

def kin_jacobian(q: _F64, model_name: str) -> _F64:
    """Geometric Jacobian at tool0 in Base: (6, 6), rows linear then angular."""

def kin_ik(t: _F64, seed: _F64 | None, model_name: str, tol: float | None = None) -> _F64:
    """IK nearest the seed: T (4, 4), seed (6,) or None → q (6,). Raises IkError / ValueError."""

def kin_ik_gn(
    t: _F64, seed: _F64, model_name: str, tol: float | None = None, max_iters: int = 100
) -> _F64:
    """Gauss-Newton alone from a seed: T (4, 4), seed (6,) → q (6,)."""

def kin_ik_all(t: _F64, model_name: str, q6_ref: float = 0.0) -> _F64:
    """Every closed-form solution: T (4, 4) → (k, 6), k ≤ 8 (k = 0 when unreachable)."""

def kin_ik_batch(
    ts: _F64, seeds: _F64 | None, model_name: str, threads: int = 0, tol: float | None = None
) -> tuple[_F64, _Bool]:
    """Batched IK: Ts (N, 4, 4), seeds (N, 6) or None → (q (N, 6), ok (N,)); failed rows NaN."""

def kin_hand_to_target(
    wrist: _F64,
    index_proximal: _F64,
    middle_proximal: _F64,
    handedness: str,
    calibration: _Calibration,
) -> _F64:
    """Hand joints (3,) each, in the calibration's space → tool0 target (4, 4) in Base."""

def kin_hand_to_target_batch(
    wrist: _F64,
    index_proximal: _F64,
    middle_proximal: _F64,
    handedness: str,
    calibration: _Calibration,
) -> tuple[_F64, _Bool]:
    """(N, 3) each → (T (N, 4, 4), ok (N,)); degenerate frames give ok False and identity T."""

def kin_points_to_base(points: _F64, calibration: _Calibration) -> _F64:
    """Points (N, 3) in the calibration's space → (N, 3) in the robot Base frame."""

def kin_default_calibration() -> tuple[_F64, float, str]:
    """The default calibration: (base_from_space (4, 4), scale, space name)."""

def kin_urdf(model_name: str) -> str:
    """The URDF text of a model, written from its DH table."""

def kin_hand_layouts() -> dict[str, dict[str, Any]]:
    """Every hand layout (ur3-kin's ``HandLayout``): name → ``joints`` (the runtime's joint names),
    ``openxr`` (each joint's OpenXR index, None where OpenXR has none), ``wrist``,
    ``index_proximal``, ``middle_proximal`` (the joints the hand frame reads)."""

# ---------------------------------------------------------------------------------------------
# Simulator (sim.rs). Tasks: "TileSuction" | "BlockGrip" | "Screw" | "TileRow" (or "suction" |
# "grip" | "screw" | "row"). Observations and actions are float32.

class _PoseRec(TypedDict):
    t: list[float]
    q: list[float]

class _Placement(TypedDict):
    held: bool
    height_above_rest: float
    xy_error: float
    yaw_error_deg: float
    hold_gaps: list[float]

class _Snapshot(TypedDict):
    task: str
    q: list[float]
    tool0: _PoseRec
    tcp: _PoseRec
    object: _PoseRec
    target: _PoseRec
    suction_on: bool
    held: bool
    gripper_width: float
    spin: int
    spin_angle: float
    step: int
    episode_seed: int
    picked: bool
    done: bool
    links: list[_PoseRec]
    row: NotRequired[list[_RowTile]]  # TileRow only: each tile of the row, in row order

class _RowTile(TypedDict):
    object: _PoseRec
    target: _PoseRec
    picked: bool
    installed: bool

class _StepInfo(TypedDict):
    picked: bool
    held: bool
    installed: bool
    fell: bool
    step: int

class _TaskDims(TypedDict):
    obs_frame_dim: int
    obs_dim: int
    act_dim: int

class _SimConstants(TypedDict):
    FRAME_STACK: int
    MAX_EPISODE_STEPS: int
    CONTROL_DT: float
    MAX_JOINT_STEP: float
    PHYSICS_SUBSTEPS: int
    PICK_DIST: float
    INSTALL_DIST: float
    HOME_Q: list[float]
    tasks: dict[str, _TaskDims]

class _Start(TypedDict):
    object_pose: list[float]
    target_offset: list[float]
    pad_offset: list[float]
    pad_yaw: NotRequired[float]  # rad, present when the pad is turned

@final
class SimEnv:
    """One simulated environment: ``SimEnv(task, seed=0)``."""

    # Read-only attributes.
    task: Final[str]
    obs_dim: Final[int]
    obs_frame_dim: Final[int]
    act_dim: Final[int]
    def __new__(cls, task: str, seed: int = 0) -> SimEnv: ...
    @staticmethod
    def from_spec_file(path: str, seed: int = 0) -> SimEnv:
        """An env of the task the spec file at ``path`` describes (``task`` follows from its
        effector); raises as ``load_task_spec``."""
    def spec(self) -> dict[str, Any]:
        """The task spec this env runs, as a dict (the spec file's tables and fields)."""
    @property
    def joint_step(self) -> float:
        """Joint motion (rad) per step at full action: the spec's ``robot.joint_step``, else
        ``MAX_JOINT_STEP`` (0.04)."""
    def reset(
        self,
        seed: int | None = None,
        object_pose: list[float] | None = None,
        target_offset: list[float] | None = None,
        pad_offset: list[float] | None = None,
        pad_yaw: float | None = None,
    ) -> _F32:
        """Start an episode (None: next seed from the env's RNG) → obs (obs_dim,); at
        ``object_pose`` [x, y, yaw] with the target (and pad) moved by ``target_offset`` when
        given (ValueError naming the field for a start off the table, on the pad, out of reach)."""
    def start(self) -> _Start:
        """Where the running episode started."""
    def set_variation(
        self,
        starts: str | None = None,
        towards_wide: float | None = None,
        object_x: tuple[float, float] | None = None,
        target_jitter: float = 0.0,
        robust: bool = False,
    ) -> None:
        """How episodes start from the next reset (see ``SimVecEnv.set_variation``)."""
    def step(self, action: ArrayLike) -> tuple[_F32, float, bool, bool, _StepInfo]:
        """action (act_dim,) → (obs, reward, terminated, truncated, info)."""
    def observation(self) -> _F32:
        """The current stacked observation (obs_dim,)."""
    def snapshot(self) -> _Snapshot:
        """State for demo recording (poses: t metres, q quaternion [x, y, z, w], Base frame)."""
    def scene(self) -> list[dict[str, Any]]:
        """Scene items: name, frame, kind (box | cylinder | capsule) and its sizes, translation,
        rotation [x, y, z, w], rgba."""
    def scene_entities(self) -> list[dict[str, Any]]:
        """The Foxglove scene entities of the current episode (its pad, target and plate)."""
    def scene_frames(self) -> dict[str, list[float]]:
        """``scene_frames`` of the current state (links at the joints, ``tile`` at the object, a
        row's ``tile_0`` … at its tiles)."""
    def placement(self) -> _Placement | None:
        """Where the object is now as a tiler would check it (held, height above its rest on
        the target, xy and yaw error, the lip-to-face gap of each hold); None for Screw."""
    def last_placement(self) -> _Placement | None:
        """``placement()`` at the end of the last finished episode (None before one)."""
    def action_toward(self, q_goal: ArrayLike) -> _F64:
        """The action's first six numbers (6,) that move the arm towards joint angles q_goal (6,)
        in one step, in the spec's action space (robot.action: joint motions or the TCP's motion
        and turn)."""
    def set_joints(self, q: _F64) -> None:
        """Test/tool API: teleport the arm to joint angles q (6,) rad."""
    def set_object_pose(
        self,
        t: tuple[float, float, float] | list[float],
        q: tuple[float, float, float, float] | list[float],
    ) -> None:
        """Test/tool API: teleport the object to translation t (3,) and quaternion q (4,)."""

@final
class SimVecEnv:
    """N environments stepped in one call with the interpreter lock released, same-step
    auto-reset: ``SimVecEnv(task, num_envs, seed=0, num_threads=2)``; env i starts episode
    seed + i, its later episodes tile-sim's ``episode_seed(seed, i, episode)``."""

    # Read-only attributes.
    task: Final[str]
    num_envs: Final[int]
    num_threads: Final[int]
    obs_dim: Final[int]
    act_dim: Final[int]
    def __new__(
        cls, task: str, num_envs: int, seed: int = 0, num_threads: int = 2
    ) -> SimVecEnv: ...
    @staticmethod
    def from_spec_file(
        path: str, num_envs: int, seed: int = 0, num_threads: int = 2
    ) -> SimVecEnv:
        """``num_envs`` envs of the task the spec file at ``path`` describes (as
        ``SimEnv.from_spec_file``); raises as ``load_task_spec``."""
    def spec(self) -> dict[str, Any]:
        """The task spec these envs run, as a dict."""
    @property
    def joint_step(self) -> float:
        """Joint motion (rad) per step at full action (as ``SimEnv.joint_step``)."""
    def reset(self, seed: int | None = None) -> _F32:
        """Reset all envs with base seed ``seed`` (episode counts restart) → obs (num_envs,
        obs_dim)."""
    def reset_mask(self, mask: ArrayLike) -> _F32:
        """Reset the envs where mask (num_envs,) is true → obs (num_envs, obs_dim)."""
    def state(self) -> dict[str, Any]:
        """``{"base_seed": int, "episodes": uint64 (num_envs,), "seeds": uint64 (num_envs,),
        "starts": float32 (num_envs, 8), "actions": [float32 (k_i, act_dim)]}``: the running
        episodes' seeds, starts (x, y, yaw, target dx, dy, pad dx, dy, pad yaw; rows of 7 from an
        older checkpoint restore with the pad square) and actions, what ``restore`` replays."""
    def restore(
        self,
        base_seed: int,
        episodes: list[int],
        seeds: list[int],
        actions: list[ArrayLike],
        starts: list[list[float]] | None = None,
    ) -> _F32:
        """Rebuild every env from ``state()``'s parts → obs (num_envs, obs_dim) as when taken
        (``starts`` None: a state from before starts were saved, the paper's start of each seed)."""
    def set_variation(
        self,
        starts: str | None = None,
        towards_wide: float | None = None,
        object_x: tuple[float, float] | None = None,
        target_jitter: float = 0.0,
        robust: bool = False,
    ) -> None:
        """How episodes start from the next reset: ``starts`` names one ("training" = the
        paper's, "robust", "wide"); ``towards_wide`` in [0, 1] goes that far from the paper's to
        the wide starts; else the object's x uniform in ``object_x`` (m; None: the paper's
        [0, 0.15]) and the target moved by up to ``target_jitter`` m in x and y; ``robust=True``:
        x in [-0.075, 0.225], jitter 0.02. ValueError out of range."""
    def reset_starts(
        self,
        seed: int,
        object_poses: list[list[float]],
        target_offsets: list[list[float]] | None = None,
        pad_offsets: list[list[float]] | None = None,
        pad_yaws: list[float] | None = None,
    ) -> _F32:
        """Reset every env with base seed ``seed``, env i at ``object_poses[i]`` [x, y, yaw] with
        its target (and pad) moved by ``target_offsets[i]`` → obs (num_envs, obs_dim). All starts
        are checked first (ValueError "env i: <field> …"); later episodes draw from the
        variation."""
    def reset_replay(
        self,
        i: int,
        seed: int,
        actions: ArrayLike,
        object_pose: list[float] | None = None,
        target_offset: list[float] | None = None,
        pad_offset: list[float] | None = None,
        pad_yaw: float | None = None,
    ) -> _F32:
        """Reset env i to episode ``seed`` (at ``object_pose`` when given, else the paper's start
        of ``seed``) and replay ``actions`` (k, act_dim) in it (a recorded episode's first k
        steps); the other envs do not move → env i's observation (obs_dim,). Raises ValueError
        if the replayed episode would end, for a bad index, shape or start."""
    def start(self, i: int) -> _Start:
        """Where env i's running episode started."""
    def step(
        self, actions: ArrayLike
    ) -> tuple[_F32, _F32, _Bool, _Bool, _F32, _Bool, _Bool, _Bool, _Bool]:
        """actions (num_envs, act_dim) → (obs, reward, terminated, truncated, final_obs,
        has_final, picked, installed, fell); obs (num_envs, obs_dim), the rest (num_envs,)
        except final_obs (num_envs, obs_dim)."""
    def last_placement(self, i: int) -> _Placement | None:
        """``SimEnv.last_placement`` of env i (kept through the same-step reset)."""
    def snapshot(self, i: int) -> _Snapshot:
        """Snapshot of env i (see ``SimEnv.snapshot``)."""

@final
class SimExpert:
    """The scripted expert for one env: ``SimExpert(task)``; ``reset()`` at each episode start."""

    def __new__(cls, task: str) -> SimExpert: ...
    def reset(self) -> None: ...
    def act(self, env: SimEnv) -> _F32:
        """Action (act_dim,) for env's current state."""

def sim_constants() -> _SimConstants:
    """Simulator constants and per-task dims."""

def joint_motion(spec: dict[str, Any], q: ArrayLike, action: ArrayLike) -> _F64:
    """The joint angles (6,) one step of ``action`` takes the arm to from ``q`` (6,) under the
    task spec ``spec`` (a dict as ``load_task_spec`` gives it; a bad one raises
    ``SimInputError``)."""

def load_task_spec(path: str) -> dict[str, Any]:
    """Read and check a task spec file (TOML, version 1; crates/tile-sim/src/spec/mod.rs
    documents the fields) → the spec as a dict. Raises ``IoError`` when the file cannot be read
    and ``SimInputError`` for a bad spec (``field``: dotted path and ``value`` for a bad value,
    None for a TOML or structure error; ``reason``: why)."""

def task_spec(task: str, as_toml: bool = False) -> Any:
    """The built-in spec of ``task`` as a dict (``as_toml=True``: the spec file's text, a str)."""

def hand_scale(task: str = "suction", task_file: str | None = None) -> float:
    """The hand → robot scale of live teleoperation in the spec file ``task_file`` (None:
    ``task``'s built-in spec, 1.0): its ``robot.hand_scale``, else its arm's workspace scale
    (|a2| + |a3| over the UR3's). Raises as :func:`load_task_spec`."""

def scene_entities(task: str, seed: int = 0, model: str = "ur3") -> list[dict[str, Any]]:
    """The Foxglove ``SceneEntity`` objects (JSON-ready dicts) a demo of episode ``seed`` of
    ``task`` carries on ``/scene``: the robot (the UR3 as the simulator's capsules, a cylinder and
    two spheres per entity; locked to the URDF links), table, pad, target, end
    effector (locked to ``tool0``) and object (locked to ``tile``)."""

def scene_frames(
    joints: list[float] | tuple[float, ...],
    tile_pose: list[float],
    model: str = "ur3",
    row: list[list[float]] | None = None,
) -> dict[str, list[float]]:
    """``{frame_id: [x, y, z, qx, qy, qz, qw]}`` in Base of the frames the scene entities are
    locked to: the URDF links (``shoulder_link`` … ``tool0``) at ``joints``, ``tile`` at
    ``tile_pose`` [x, y, z, qx, qy, qz, qw] and a row's ``tile_0`` … at ``row`` (in row
    order)."""

# ---------------------------------------------------------------------------------------------
# Demonstrations and hand logs (demo.rs)

DEMO_FORMAT_VERSION: Final[int]
HANDLOG_VERSION: Final[int]

class _ParseReport(TypedDict):
    frame_lines: int
    kept: int
    untracked_skipped: int
    invalid_skipped: int
    skipped: list[tuple[int, str]]
    sha256: str | None

class _HandLog(TypedDict):
    header: dict[str, Any]
    t: _F64
    tracked: _Bool
    joints: _F64
    orientations: _F64 | None
    report: _ParseReport

class _WriteStats(TypedDict):
    path: Path
    steps: int
    messages: int
    chunks: int
    bytes: int

class _DemoEpisode(TypedDict):
    obs: _F32
    actions: _F32
    rewards: _F32
    terminated: _Bool
    truncated: _Bool
    t: _F64
    meta: dict[str, str]

class _DemoDataset(TypedDict):
    obs: _F32
    actions: _F32
    rewards: _F32
    terminated: _Bool
    truncated: _Bool
    episode: NDArray[np.int64]
    files: list[Path]
    metas: list[dict[str, str]]

class _SalvagedMessage(TypedDict):
    topic: str
    schema_name: str
    log_time: int
    sequence: int
    data: bytes

class _ChunkCheck(TypedDict):
    index: int
    offset: int
    length: int | None
    messages: int | None
    log_time_start: int | None
    log_time_end: int | None
    error: str | None
    recoverable: bool

class _SalvageReport(TypedDict):
    bytes_total: int
    bytes_used: int
    chunks_ok: int
    chunks_lost: int
    messages: int
    metadata: int
    metadata_dropped: list[str]
    attachments: int
    complete: bool
    stopped_because: str | None
    magic_damaged: bool
    lost_chunks: list[_ChunkCheck]
    step_gaps: list[tuple[int, int]]
    messages_unattributed: int
    layout_assumed: bool

class _VerifyReport(TypedDict):
    ok: bool
    bytes: int
    complete: bool
    chunks: list[_ChunkCheck]
    skipped: list[tuple[int, int, str]]
    data_crc_ok: bool | None
    summary_problem: str | None
    messages_ok: int
    messages_lost: int | None
    problems: list[str]

def demo_parse_handlog(path: _StrPath, mode: str = "strict") -> _HandLog:
    """Parse a hand-log file (mode "strict" | "lenient").

    Raises LogFormatError("file:line: reason").
    """

def demo_parse_handlog_str(text: str, name: str = "<string>", mode: str = "strict") -> _HandLog:
    """Parse hand-log text; `name` is the file name used in error messages."""

def demo_write_handlog(
    path: _StrPath,
    header: dict[str, Any],
    t: _F64,
    tracked: _Bool,
    joints: _F64,
    orientations: _F64 | None = None,
) -> None:
    """Write a hand log atomically.

    t (T,), tracked (T,), joints (T, J, 3) m, orientations (T, J, 4) or None.
    """

@final
class DemoWriter:
    """Records one episode into an MCAP demo (``path + ".partial"`` until ``finish``).

    ``DemoWriter(path, meta, chunk_size=65536, flush_every_steps=50, env=None)``. The first
    ``/scene`` is the robot and the task's scene: ``env``'s (a ``SimEnv`` after the episode's
    reset: its own start and spec) when given, else the task's at its paper start for
    ``meta["seed"]``; ``meta["scene"]`` entities replace those of the same id. A context manager:
    a normal exit finishes with success=False if ``finish`` was not called; an exception abandons
    the file.
    """

    def __new__(
        cls,
        path: _StrPath,
        meta: dict[str, Any],
        chunk_size: int = 65536,
        flush_every_steps: int = 50,
        env: SimEnv | None = None,
    ) -> DemoWriter: ...
    def write_step(
        self,
        step: int,
        t: float,
        obs: _F32,
        action: _F32,
        reward: float,
        terminated: bool,
        truncated: bool,
        gesture: str,
        joints: tuple[float, float, float, float, float, float] | list[float] | _F64,
        ee_pose: list[float] | _F64,
        tile_pose: list[float] | _F64,
        events: list[str] | None = None,
        scene: list[dict[str, Any]] | None = None,
        row_poses: list[list[float] | _F64] | None = None,
    ) -> None:
        """Record one step; poses are [x, y, z, qx, qy, qz, qw] or (4, 4); ``row_poses``: a
        row's objects' poses (frames ``tile_0`` …), in row order."""
    def write_hand_frame(
        self,
        t: float,
        joints: _F64,
        tracked: bool = True,
        hand_t: float | None = None,
        orientations: _F64 | None = None,
    ) -> None:
        """Record a raw hand frame: joints (J, 3) m, orientations (J, 4) or None."""
    def write_event(self, t: float, name: str, properties: dict[str, Any] | None = None) -> None:
        """Record an event ("pick", "install", "fall", ...) at episode time t."""
    def write_stage_times(
        self,
        step: int,
        seq: int,
        capture_ms: float,
        sent_ms: float,
        server_recv_ms: float,
        state_sent_ms: float | None = None,
        page_recv_ms: float | None = None,
    ) -> None:
        """Record when live control step `step`'s hand frame passed each stage
        (/teleop/stage_times): client clock capture_ms, sent_ms, page_recv_ms (None: the state
        was not acknowledged); server clock server_recv_ms, state_sent_ms (None: the episode ended
        on this frame, before its state went out)."""
    def write_deploy_tick(self, tick: dict[str, Any]) -> None:
        """Record one deployment tick (``/deploy/tick``, ``mimicrete.DeployTick.v1``): a dict of
        every field of the schema and no other (step, t, robot_time, q_read, tcp_read,
        safety_mode, digital_out, tile_pose, tile_source, raw_action, command_q, suction, gates,
        sent, latency_ms); written after the tick's step."""
    @property
    def steps(self) -> int:
        """Steps written so far."""
    @property
    def path(self) -> Path:
        """The final path."""
    def finish(self, success: bool, extra: dict[str, Any] | None = None) -> _WriteStats:
        """End the episode and rename the file into place."""
    def abandon(self) -> None:
        """Close without finishing: the file stays as path + ".partial" (salvageable)."""
    def __enter__(self) -> DemoWriter: ...
    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        _exc: BaseException | None,
        _tb: TracebackType | None,
    ) -> Literal[False]: ...

def demo_read(path: _StrPath) -> _DemoEpisode:
    """Read one demo: obs (T, obs_dim), actions (T, act_dim); rewards, flags and t (T,)."""

def demo_load(path: _StrPath) -> _DemoDataset:
    """Read a demo file or every *.mcap of a directory (sorted by name), concatenated."""

def demo_salvage(path: _StrPath) -> tuple[list[_SalvagedMessage], _SalvageReport]:
    """Every complete message of a (possibly cut) demo, and the report."""

def demo_salvage_to(path_in: _StrPath, path_out: _StrPath) -> _SalvageReport:
    """Rewrite what can be recovered from path_in as a valid MCAP file path_out."""

def demo_verify(path: _StrPath) -> _VerifyReport:
    """Check every chunk's CRC, the data-section and summary CRCs and completeness."""

def demo_files(path: _StrPath) -> list[Path]:
    """The *.mcap entries of a directory, sorted by name, whatever they are."""

# ---------------------------------------------------------------------------------------------
# teleop-core (teleop.rs): the per-frame loop

TELEOP_BRANCH_JUMP: Final[float]

# (index, t, obs, action, reward, terminated, truncated, events, why)
_TeleopStep = tuple[int, float, _F32, _F32, float, bool, bool, list[str], str | None]

class _TeleopView(TypedDict):
    frames: dict[str, list[float]]
    snapshot: _Snapshot
    target: list[float] | None

class _TeleopCounts(TypedDict):
    frames: int
    untracked: int
    degenerate: int
    unreachable: int
    steps: int
    frames_after_end: int
    gesture_changes: int
    gestures: dict[str, int]

class _TeleopOutcome(TypedDict):
    steps: int
    picked: bool
    installed: bool
    fell: bool
    terminated: bool
    truncated: bool
    total_reward: float

def teleop_gesture_commands() -> list[tuple[str, float, float]]:
    """The gesture classes and their (command, spin), teleop-core's table."""

@final
class TeleopSession:
    """One teleoperation episode (teleop-core's ``Session``); every step is recorded into
    ``writer``."""

    def __new__(
        cls,
        task: str,
        layout: str,
        handedness: str,
        calibration: _Calibration,
        seed: int,
        writer: DemoWriter | None = None,
        mapping: str = "absolute",
        task_file: _StrPath | None = None,
    ) -> TeleopSession: ...
    def push(
        self,
        t: float,
        tracked: bool,
        joints: _F64,
        raw: str | None,
        gesture: str | None,
        view: bool = False,
        clutch: str | None = None,
    ) -> tuple[list[_TeleopStep], _TeleopView | None]:
        """One hand frame → (the control steps that fell due, the page's view or None)."""
    def observe(
        self,
        t: float,
        tracked: bool,
        joints: _F64,
        raw: str | None,
        gesture: str | None,
        clutch: str | None = None,
    ) -> None:
        """The hand half of ``push`` alone: the gesture and the target, no steps."""
    def finish(self) -> list[_TeleopStep]:
        """The hand stream has ended: the steps up to one control period past the last frame."""
    def view(self) -> _TeleopView:
        """What the page draws now: frames (one FK), the snapshot, the target."""
    def set_calibration(
        self, calibration: _Calibration, shift: Sequence[float] | None = None
    ) -> None:
        """Use ``calibration`` from the next frame on; ``shift`` moves the current target."""
    @property
    def counts(self) -> _TeleopCounts: ...
    @property
    def target(self) -> _F64 | None: ...
    @property
    def engaged(self) -> bool: ...
    @property
    def gesture(self) -> str | None: ...
    @property
    def command(self) -> tuple[float, float]: ...
    @property
    def step_index(self) -> int: ...
    @property
    def last_why(self) -> str | None: ...
    @property
    def last_tracked(self) -> bool | None: ...
    @property
    def observation(self) -> _F32: ...
    @property
    def outcome(self) -> _TeleopOutcome: ...
    def snapshot(self) -> _Snapshot:
        """The simulator's state now."""
    def set_joints(self, q: Sequence[float] | _F64) -> None:
        """Test/tool API: teleport the arm to joint angles ``q`` (6,) rad."""
    def scene_frames(self) -> dict[str, list[float]]:
        """``scene_frames`` of the current state."""
    def scene_entities(self) -> list[dict[str, Any]]:
        """The Foxglove ``SceneEntity`` list of the episode."""
