import numpy as np
import pytest


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", default=False, help="run tests marked slow")


def pytest_collection_modifyitems(config, items):
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="slow: pass --runslow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


#: task → (TCP, tool0-to-TCP distance, object centre z, target; a target x of None sits under
#: the object) as tile-sim lays the scene out (object y 0.32, x uniform in [0, 0.15]).
_SIM_LIKE = {
    "suction": ((0.0, 0.25, 0.2), 0.05, 0.005, (-0.22, 0.28, 0.045)),
    "grip": ((0.0, 0.25, 0.17), 0.085, 0.02, (-0.22, 0.28, 0.06)),
    "screw": ((0.0, 0.25, 0.17), 0.085, 0.073, (None, 0.32, 0.06775)),
}


def _sim_like_scene(task: str, seed: int):
    from mimicrete.teleop import synth as sy

    x = float(np.random.default_rng(seed).uniform(0.0, 0.15))
    tcp, tcp_z, obj_z, (tx, ty, tz) = _SIM_LIKE[task]
    return sy.Scene(
        task,
        seed,
        np.array(tcp),
        tcp_z,
        np.array([x, 0.32, obj_z]),
        np.array([x if tx is None else tx, ty, tz]),
    )


@pytest.fixture(scope="session")
def sim_like_scene():
    """``(task, seed) -> mimicrete.synth.Scene`` laid out as tile-sim lays it out, without the
    simulator (for tests that do not need its bindings)."""
    return _sim_like_scene


@pytest.fixture(scope="session")
def scene_fn(sim_like_scene):
    """The simulator's own scene (``synth.scene_from_env``) when its bindings are built, else
    :func:`sim_like_scene`."""
    from mimicrete.teleop import synth as sy

    return sy.scene_from_env if sy.have_simulator() else sim_like_scene
