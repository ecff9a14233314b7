"""Demonstrations as the trainer uses them: loading (MCAP file or directory, or ``.npz``), the first
``demo_episodes`` episodes, the demonstrator's idle steps left out, and making the demos when a
fresh checkout has none (``ensure_demos``: the same synth-hands + convert as ``make demos``).
"""

from __future__ import annotations

import json
import logging
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete._native import MimicreteError

from .config import ConfigError
from .env import N_CONT, sim_task_of

logger = logging.getLogger(__name__)

DEMO_KEYS = ("obs", "actions", "rewards", "terminated", "truncated", "episode")


class DemoDataError(MimicreteError, ValueError):
    """A demo path that cannot be trained on (missing, cut, empty, not MCAP); names the file."""


@dataclass
class LoadedDemos:
    """The demo arrays (keys :data:`DEMO_KEYS`) and what loading them skipped."""

    arrays: dict[str, np.ndarray]
    skipped: list[str] = field(default_factory=list)  # "file: reason" of each bad file skipped
    #: (file, the simulator task its metadata names, or None) of each loaded MCAP demo, by the
    #: episode index of ``arrays["episode"]``
    tasks: list[tuple[str, str | None]] = field(default_factory=list)
    #: each loaded MCAP demo's ``episode`` metadata record (its ``seed``), by episode index
    metas: list[dict[str, str]] = field(default_factory=list)

    def check_task(self, sim: str, path: str | os.PathLike[str]) -> None:
        """:class:`DemoDataError` naming the first demo file recorded on another task than ``sim``
        (``TileSuction``, ``BlockGrip``, ``Screw``): its sizes may match, its meaning does not."""
        from mimicrete import tasks

        for file, task in self.tasks:
            if task is None:
                continue
            try:
                theirs = tasks.get(task).sim
            except ValueError:
                theirs = task
            if theirs != sim:
                others = sum(1 for _, t in self.tasks if t is not None and t != task)
                raise DemoDataError(
                    f"{file}: a demo of task {theirs}, the config trains {sim} (demo path "
                    f"{path}; {len(self.tasks) - others} of {len(self.tasks)} files are {theirs})"
                )

    def check_spec(self, sim: str, task_file: str | None, path: str | os.PathLike[str]) -> None:
        """:class:`DemoDataError` naming the first demo file recorded in another task spec than
        the run's (``task_file``'s spec, or ``sim``'s built-in one): a demo names the spec file it
        ran in (``task_spec``; none: its task's built-in spec)."""
        from mimicrete import tasks

        def plain(spec: dict[str, Any]) -> dict[str, Any]:  # as JSON keeps it
            return json.loads(json.dumps(spec))

        builtin = plain(tasks.get(sim).builtin_spec())
        ours = builtin if task_file is None else plain(tasks.load_task_file(task_file)[1])
        for (file, _), meta in zip(self.tasks, self.metas, strict=False):
            raw = meta.get("task_spec")
            if (builtin if raw is None else json.loads(raw)) != ours:
                where = meta.get("task_file") or f"{sim}'s built-in spec"
                run = task_file or f"{sim}'s built-in spec"
                hint = "" if task_file else " (train it with --task-file)"
                raise DemoDataError(
                    f"{file}: a demo recorded in {where}, the run trains in {run}{hint} (demo "
                    f"path {path})"
                )


def load_demos(
    path: str | os.PathLike[str], episodes: int | None, *, skip_bad: bool = False
) -> dict[str, np.ndarray]:
    """Demo arrays from an ``.npz`` (same keys as ``mimicrete.demos.load``) or MCAP file/dir,
    restricted to the first ``episodes`` episodes (in file / episode-index order)."""
    return read_demos(path, episodes, skip_bad=skip_bad).arrays


def read_demos(
    path: str | os.PathLike[str], episodes: int | None, *, skip_bad: bool = False
) -> LoadedDemos:
    """:func:`load_demos` with the list of skipped files. A damaged, cut, empty or non-MCAP file
    is a :class:`DemoDataError` naming it, unless ``skip_bad``: then the directory's other files are
    used and the bad ones listed in ``skipped``."""
    p = Path(path)
    skipped: list[str] = []
    file_tasks: list[tuple[str, str | None]] = []
    metas: list[dict[str, str]] = []
    if p.suffix == ".npz":
        d = _npz_arrays(p)
    else:
        if not p.exists():
            raise FileNotFoundError(
                f"demo path {p} does not exist (make demos with `mimicrete synth-hands` and "
                "`mimicrete convert`, or `make demos`, or pass --demos DIR)"
            )
        d, skipped, file_tasks, metas = _mcap_read(p, skip_bad)
    ep = np.asarray(d["episode"])
    if episodes is not None:
        uniq = np.unique(ep)
        if len(uniq) < episodes:
            raise ConfigError(f"{path}: {len(uniq)} demo episodes, the config asks for {episodes}")
        keep = np.isin(ep, uniq[:episodes])
        d = {k: np.asarray(v)[keep] for k, v in d.items()}
    return LoadedDemos(d, skipped, file_tasks, metas)


def _npz_arrays(p: Path) -> dict[str, np.ndarray]:
    try:
        with np.load(p) as z:
            d = {k: z[k] for k in z.files}
    except (OSError, ValueError) as e:
        raise DemoDataError(f"{p}: not a readable .npz of demos ({e})") from e
    missing = [k for k in DEMO_KEYS if k not in d]
    if missing:
        raise DemoDataError(f"{p}: demo .npz without {missing}")
    return d


def _file_tasks(loaded: Any) -> list[tuple[str, str | None]]:
    files = list(getattr(loaded, "files", []) or [])
    return [(f, m.get("task") or None) for f, m in zip(files, _file_metas(loaded), strict=False)]


def _file_metas(loaded: Any) -> list[dict[str, str]]:
    return [dict(m or {}) for m in getattr(loaded, "metas", []) or []]


def _mcap_arrays(p: Path, skip_bad: bool) -> tuple[dict[str, np.ndarray], list[str]]:
    """The demo arrays of an MCAP file or directory and the bad files skipped."""
    d, skipped, _, _ = _mcap_read(p, skip_bad)
    return d, skipped


def _mcap_read(
    p: Path, skip_bad: bool
) -> tuple[dict[str, np.ndarray], list[str], list[tuple[str, str | None]], list[dict[str, str]]]:
    """The demo arrays of an MCAP file or directory, the bad files skipped, and the task and
    ``episode`` metadata of each file loaded (by episode index)."""
    from mimicrete import LogFormatError, demos

    try:
        loaded = demos.load(str(p))
        return demo_arrays(loaded), [], _file_tasks(loaded), _file_metas(loaded)
    except (LogFormatError, OSError) as e:
        if not skip_bad or not p.is_dir():
            hint = " (--skip-bad-demos trains on the other files)" if p.is_dir() else ""
            raise DemoDataError(f"{e}{hint}") from e
    # one file at a time, leaving out the bad ones; episodes renumbered in file order
    parts, skipped, file_tasks, metas = [], [], [], []
    for f in sorted(p.glob("*.mcap")):
        try:
            loaded = demos.load(str(f))
        except (LogFormatError, OSError) as e:
            skipped.append(str(e))
            continue
        parts.append(demo_arrays(loaded))
        file_tasks += _file_tasks(loaded)
        metas += _file_metas(loaded)
    if not parts:
        raise DemoDataError(f"{p}: no loadable demo file ({len(skipped)} bad)")
    for i, part in enumerate(parts):
        part["episode"] = np.full_like(part["episode"], i)
    arrays = {k: np.concatenate([q[k] for q in parts]) for k in DEMO_KEYS}
    return arrays, skipped, file_tasks, metas


@dataclass
class TrainingDemos:
    """A run's demos, read once: as recorded (:attr:`loaded`: the curriculum replays every
    step of them) and without the demonstrator's idle steps (:attr:`arrays`: what BC and GAIL
    learn from)."""

    loaded: LoadedDemos
    arrays: dict[str, np.ndarray]  # keys DEMO_KEYS, idle steps dropped

    @property
    def steps_loaded(self) -> int:
        return len(self.loaded.arrays["actions"])

    @property
    def skipped(self) -> list[str]:
        return self.loaded.skipped


def read_training_demos(
    path: str | None,
    episodes: int | None,
    drop_idle: float,
    env_id: str,
    action_dims: int,
    *,
    skip_bad: bool = False,
    task_file: str | None = None,
) -> TrainingDemos:
    """The first ``episodes`` demos at ``path`` for a run on ``env_id`` (whose actions have
    ``action_dims`` dimensions; ``Task-v0``: in the spec file ``task_file``): :class:`ConfigError`
    without a path or for actions of another size, :class:`DemoDataError` for demos recorded on
    another simulator task or in another task spec."""
    if not path:
        raise ConfigError("gail/behavioral_cloning/demo_curriculum need a demo_path or --demos")
    loaded = read_demos(path, episodes, skip_bad=skip_bad)
    arrays = drop_idle_steps(loaded.arrays, drop_idle)
    got = arrays["actions"].shape[1]
    if got != action_dims:
        raise ConfigError(
            f"{path}: demo actions of {got} dims, {env_id} takes {action_dims} (demos of "
            "another task?)"
        )
    sim = sim_task_of(env_id, task_file)
    if sim is not None:  # the sizes can match across tasks (grip and suction do)
        loaded.check_task(sim, path)
        loaded.check_spec(sim, task_file, path)
    return TrainingDemos(loaded, arrays)


def demo_arrays(loaded: Any) -> dict[str, np.ndarray]:
    """The :data:`DEMO_KEYS` arrays of ``mimicrete.demos.load``'s result. Accepts a dict, a
    NamedTuple, an object with those attributes, or a plain tuple in that order."""
    if isinstance(loaded, dict):
        src = loaded
    elif hasattr(loaded, "_asdict"):
        src = loaded._asdict()
    elif all(hasattr(loaded, k) for k in DEMO_KEYS):
        src = {k: getattr(loaded, k) for k in DEMO_KEYS}
    elif isinstance(loaded, (tuple, list)) and len(loaded) >= len(DEMO_KEYS):
        src = dict(zip(DEMO_KEYS, loaded, strict=False))
    else:
        raise TypeError(f"mimicrete.demos.load returned {type(loaded).__name__}")
    return {k: np.asarray(src[k]) for k in DEMO_KEYS}


def idle_steps(actions: np.ndarray, episode: np.ndarray, threshold: float) -> np.ndarray:
    """Mask of the demo steps in which the demonstrator was idle: every joint motion ``|a[0:6]|``
    below ``threshold`` (a fraction of the env's joint step), the end-effector command either 0
    ("fixed") or the same as the previous step's in the episode, so it changes nothing, and any
    further command (Screw's spin) 0: a spin held at "tighten" turns the nut every step, so the
    steps of a screwing hand that holds still are work, not a pause (leaving them out left BC
    without the screwing phase: 0 % screwed on 3 seeds). A human pauses: after the pick, before the
    place, while deciding. Those steps teach a policy that standing still is what the expert does
    in a state it cannot tell from the moment before moving on, and a five-frame observation cannot
    tell how long a pause has lasted; the policy then freezes there. ``threshold <= 0`` marks
    nothing."""
    a = np.asarray(actions)
    idle = np.zeros(len(a), bool)
    if threshold <= 0 or len(a) == 0:
        return idle
    ep = np.asarray(episode)
    cmd = a[:, N_CONT:]
    prev = np.vstack([np.full((1, cmd.shape[1]), np.nan), cmd[:-1]])
    prev[np.r_[True, ep[1:] != ep[:-1]]] = np.nan  # no previous command at an episode's start
    no_change = ((cmd == 0) | (cmd == prev))[:, 0] & (cmd[:, 1:] == 0).all(axis=1)
    return (np.abs(a[:, :N_CONT]).max(axis=1) < threshold) & no_change


def drop_idle_steps(d: dict[str, np.ndarray], threshold: float) -> dict[str, np.ndarray]:
    """``d`` without its :func:`idle_steps` (behaviours.<name>.demo_drop_idle, an extension).
    Every kept step keeps the observation it was recorded with, so BC's (obs, action) pairs and
    GAIL's expert states stay true; only the pauses leave."""
    keep = ~idle_steps(d["actions"], d["episode"], threshold)
    return {k: np.asarray(v)[keep] for k, v in d.items()}


# ----------------------------------------------------------------------------------------------
# making demos where there are none
# ----------------------------------------------------------------------------------------------


def count_demo_episodes(path: Path) -> int:
    """Demo episodes at ``path``: 1 for an ``.mcap`` / ``.npz`` file, the ``*.mcap`` files of a
    directory, 0 when there is nothing."""
    if path.is_file():
        return 1 if path.suffix in (".mcap", ".npz") else 0
    if not path.is_dir():
        return 0
    return len(list(path.glob("*.mcap")))


def default_hand_dir(demo_dir: Path) -> Path:
    """Where :func:`ensure_demos` writes the hand logs of ``demo_dir``: ``data/hands/<name>`` for
    the repo's ``demos/<name>`` (as ``make demos``), else ``<demo_dir>_handlogs`` beside it."""
    if demo_dir.parent.name == "demos":
        return demo_dir.parent.parent / "data" / "hands" / demo_dir.name
    return demo_dir.parent / f"{demo_dir.name}_handlogs"


def ensure_demos(
    demo_dir: Path,
    episodes: int,
    *,
    task: str = "suction",
    hand_dir: Path | None = None,
    seed: int = 0,
    at_least: int = 60,
    log: Any = None,
) -> Path:
    """Make ``max(episodes, at_least)`` demos in ``demo_dir`` when it holds fewer than ``episodes``:
    a scripted person's hand logs (``synth-hands``), turned into MCAP demos through the real
    teleoperation path (``convert``), exactly what ``make demos`` runs. Says so through ``log``
    (default: this module's logger, at INFO)."""
    demo_dir = Path(demo_dir)
    have = count_demo_episodes(demo_dir)
    if demo_dir.suffix == ".npz" or have >= episodes:
        return demo_dir
    hand_dir = Path(hand_dir) if hand_dir is not None else default_hand_dir(demo_dir)
    n = max(episodes, at_least)
    (log or logger.info)(
        f"demos: {demo_dir} has {have} episodes, making {n} (synth-hands into {hand_dir}, then "
        f"convert into {demo_dir}, as `make demos`)"
    )
    from mimicrete.demonstrator import synth_hands
    from mimicrete.teleop import convert as cv
    from mimicrete.teleop.look import offset_seen

    logs = synth_hands(task, n, seed, hand_dir, progress=True, see=offset_seen)
    plan = cv.plan_outputs(logs, demo_dir, overwrite=True)  # the same logs give the same demos
    for i, path in enumerate(logs):
        cv.convert_log(path, task, plan[path], episode_index=i)
    got = count_demo_episodes(demo_dir)
    if got < episodes:
        raise RuntimeError(f"{demo_dir}: {got} demo episodes after convert, need {episodes}")
    return demo_dir


def ensure_generated_demos(
    demo_dir: Path,
    count: int,
    sources: Path,
    source_count: int,
    *,
    task: str = "suction",
    log: Any = None,
    speed: float = 1.0,
) -> Path:
    """Fill ``demo_dir`` with ``count`` demos generated at the wide starts by ``mimicrete demogen``
    (seed 0, played ``speed`` times faster) from the first ``source_count`` demos of ``sources``
    (made first by :func:`ensure_demos` when missing), unless it holds ``count`` already. Says so
    through ``log``."""
    demo_dir, sources = Path(demo_dir), Path(sources)
    have = count_demo_episodes(demo_dir)
    if have >= count:
        return demo_dir
    ensure_demos(sources, source_count, task=task, log=log)
    (log or logger.info)(
        f"demos: {demo_dir} has {have} episodes, generating {count} at the wide starts from the "
        f"first {source_count} of {sources} (as `mimicrete demogen --demos {sources} "
        f"--source-count {source_count} --count {count} --starts wide --out {demo_dir} --seed 0"
        + (f" --speed {speed:g}" if speed != 1.0 else "")
        + "`)"
    )
    from mimicrete import demogen

    for old in demo_dir.glob("*.mcap"):  # a generation cut short: start it again, whole
        old.unlink()
    from tqdm import tqdm

    with tqdm(total=count, desc="demogen", unit="demo") as bar:

        def shown(rep: demogen.Report) -> None:
            bar.n = rep.kept
            bar.set_postfix(attempts=rep.attempts, refresh=False)
            bar.refresh()

        rep = demogen.generate(
            demogen.load_sources(sources, source_count),
            count,
            demo_dir,
            progress=shown,
            speed=speed,
        )
    if rep.kept < count:
        raise RuntimeError(
            f"{demo_dir}: {rep.kept} of {count} demos generated in {rep.attempts} attempts "
            f"({rep.failures})"
        )
    return demo_dir
