"""Converted demos for the export tests: real hand logs of the scripted person through the real
teleoperation path (``synth_hands`` + ``convert_log``)."""

from __future__ import annotations

from pathlib import Path

import pytest


def _demos(root: Path, task: str, episodes: int, seed: int) -> Path:
    from mimicrete import demonstrator as synth
    from mimicrete.teleop import convert

    hands = root / f"hands-{task}"
    out = root / f"demos-{task}"
    out.mkdir(parents=True)
    for i, p in enumerate(synth.synth_hands(task, episodes, seed, hands)):
        convert.convert_log(p, task, out, episode_index=i)
    return out


@pytest.fixture(scope="session")
def demos60(tmp_path_factory) -> Path:
    """60 suction demos (about 45 s to make on the shared 2-core machine)."""
    return _demos(tmp_path_factory.mktemp("export60"), "suction", 60, 0)


@pytest.fixture(scope="session")
def demos3(tmp_path_factory) -> Path:
    """3 suction demos."""
    return _demos(tmp_path_factory.mktemp("export3"), "suction", 3, 5)


@pytest.fixture(scope="session")
def grip_demo(tmp_path_factory) -> Path:
    """1 grip demo (for the mixed-task folder)."""
    return _demos(tmp_path_factory.mktemp("exportgrip"), "grip", 1, 1)
