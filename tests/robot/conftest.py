"""Fixtures of the deploy tests: a run directory holding the group 3 policy the learn tests keep
(``tests/learn/data/group3_policy.pt``: TileSuction on a UR3, trained here), the UR3's home pose
and its TCP, and a loopback RTDE controller serving them."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mimicrete import _native

from ._rtde_server import LoopbackRobot

POLICY = Path(__file__).parent.parent / "learn" / "data" / "group3_policy.pt"
#: where the tile lies in these tests (m, m, rad): one of the paper's starts
TILE = (0.1, 0.32, 0.0)


def home_q() -> np.ndarray:
    return np.asarray(_native.task_spec("TileSuction")["robot"]["home_q"], np.float64)


def tcp_of(q: np.ndarray) -> list[float]:
    """What a controller with the TCP set to the cups reports: x, y, z, rotation vector."""
    T = _native.kin_fk(np.asarray(q, np.float64), "ur3")
    p = T[:3, 3] + T[:3, 2] * 0.05
    return [*p, *Rotation.from_matrix(T[:3, :3]).as_rotvec()]


@pytest.fixture(scope="session")
def run_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("run")
    shutil.copy(POLICY, d / "policy.pt")
    return d


@pytest.fixture
def controller():
    """A CB3 controller (ur-rtde reads it at 125 Hz) standing at home_q, safety mode normal."""
    q = home_q()
    with LoopbackRobot(q, tcp=tcp_of(q)) as c:
        yield c
