"""Demos → a Minari dataset (``minari.create_dataset_from_buffers``, Arrow storage).

``OUT`` becomes a Minari datasets root: the dataset is ``OUT/<dataset_id>/`` and is loaded with

    os.environ["MINARI_DATASETS_PATH"] = "OUT"
    dataset = minari.load_dataset("mimicrete/TileSuction/demos-v0")

Each episode holds T + 1 observations: the T recorded ones (the observation each action was chosen
from) and the observation after the last step, which the demo file does not store and which comes
from replaying the episode (:func:`mimicrete.export.source.read_demo_dir`). Rewards,
terminations and truncations are the recorded ones; actions too, except the effector command,
which is a level (+1 / -1 held until the next command, not the demo's one-step switch:
:mod:`mimicrete.export.levels`, docs/formats.md section 4; the dataset's metadata names the
columns, ``mimicrete_action_names``, and the layout, ``mimicrete_action_layout`` = ``level``);
``infos`` hold the simulator's ``picked`` / ``held`` / ``installed`` / ``fell`` flags (row 0: the
reset, all false; row k + 1: after step k).

The dataset records the gymnasium env spec (``mimicrete/TileSuction-v0``...), so
``dataset.recover_environment()`` makes our env. An episode's metadata holds
``options = {"episode_seed": SEED}`` (a generated demo's also holds its recorded start:
``object_pose``, ``target_offset``, TilePlace's ``pad_yaw``): ``env.reset(options=...)`` starts
that very episode, and stepping the dataset's actions gives back the recorded observations. The
episode's ``seed`` (the gymnasium reset seed) is left out: the demos were not started from one.
The metadata also holds ``success``, ``source_demo``, ``source_handlog`` and
``source_handlog_sha256``.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete.export import levels
from mimicrete.export.source import ACTION_NAMES, INFO_KEYS, DemoSet, check_new_output


def default_dataset_id(ds: DemoSet) -> str:
    """``mimicrete/<TileSuction|BlockGrip|Screw|TileRow>/demos-v0``."""
    return f"mimicrete/{ds.sim}/demos-v0"


@contextlib.contextmanager
def _datasets_root(root: Path) -> Iterator[None]:
    """Minari finds its datasets through ``MINARI_DATASETS_PATH``; point it at ``root``, made
    absolute (Minari joins a relative root onto paths it already joined it to)."""
    old = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = os.path.abspath(root)
    try:
        yield
    finally:
        if old is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = old


def buffers(ds: DemoSet) -> list[Any]:
    """One ``minari.EpisodeBuffer`` per episode (T + 1 observations, see the module doc)."""
    from minari.data_collector import EpisodeBuffer

    out = []
    for ep in ds.episodes:
        n = len(ep)
        infos = {}
        for key in INFO_KEYS:
            flags = np.zeros(n + 1, dtype=bool)
            flags[1:] = ep.info[key]
            # A list, not a 1-D array: Minari 0.5.4's Arrow storage writes a 1-D info array with an
            # empty shape its own reader cannot parse back; a list is stored as a plain column.
            infos[key] = flags.tolist()
        out.append(
            EpisodeBuffer(
                id=ep.index,
                seed=None,
                options={"episode_seed": ep.seed, **(ep.start or {})},
                observations=np.concatenate([ep.obs, ep.final_obs[None, :]]).astype(np.float32),
                actions=ep.actions.astype(np.float32),
                rewards=ep.rewards.astype(np.float64),
                terminations=ep.terminated.copy(),
                truncations=ep.truncated.copy(),
                infos=infos,
            )
        )
    return out


def write(
    ds: DemoSet,
    out: str | os.PathLike[str],
    dataset_id: str | None = None,
    author: str | None = None,
) -> tuple[Path, str]:
    """Write ``ds`` as the Minari dataset ``dataset_id`` in the new datasets root ``out``
    (built in a temporary directory beside it, then renamed). Returns (out, dataset_id)."""
    import gymnasium as gym
    import minari

    import mimicrete.envs  # noqa: F401  (registers the env ids)
    from mimicrete.envs import _spaces
    from mimicrete.export.lerobot import _version

    out = check_new_output(out)
    dataset_id = dataset_id or default_dataset_id(ds)
    obs_space, act_space = _spaces(ds.sim)
    version = _version()
    requirements = [] if "source" in version else [f"mimicrete=={version}"]
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=out.parent))
    try:
        with _datasets_root(tmp), warnings.catch_warnings():
            # Minari warns about every optional field left empty (code_permalink, author, ...).
            warnings.simplefilter("ignore", UserWarning)
            dataset = minari.create_dataset_from_buffers(
                dataset_id=dataset_id,
                buffer=buffers(ds),
                env=gym.spec(ds.env_id),
                algorithm_name="human teleoperation (mimicrete hand demonstrations)",
                author=author,
                observation_space=obs_space,
                action_space=act_space,
                description=f"{ds.instruction} {len(ds.episodes)} demonstrations recorded "
                f"with mimicrete ({ds.env_id}, {ds.fps} Hz control).",
                requirements=requirements,
                data_format="arrow",
            )
            dataset.storage.update_episode_metadata(
                [
                    {
                        "success": ep.success,
                        "source_demo": Path(ep.file).name,
                        "source_handlog": ep.meta.get("source_handlog", ""),
                        "source_handlog_sha256": ep.meta.get("source_handlog_sha256", ""),
                    }
                    for ep in ds.episodes
                ],
                [ep.index for ep in ds.episodes],
            )
            dataset.storage.update_metadata(
                {
                    "mimicrete_action_layout": levels.LEVEL_LAYOUT,
                    "mimicrete_action_names": ACTION_NAMES[ds.task],
                }
            )
        os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out, dataset_id
