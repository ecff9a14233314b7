"""Task specs through the native module (issue 26 §1): the built-in specs as dicts and TOML,
an env from a spec file, and bad spec files refused with the field, the value and why."""

from __future__ import annotations

from pathlib import Path

import pytest

from mimicrete import _native


def _suction_text() -> str:
    text = _native.task_spec("TileSuction", as_toml=True)
    assert isinstance(text, str)
    return text


def test_builtin_specs_name_their_tasks() -> None:
    for task, kind in [("TileSuction", "suction"), ("BlockGrip", "gripper"), ("Screw", "gripper")]:
        spec = _native.task_spec(task)
        assert spec["version"] == 1 and spec["name"] == task
        assert spec["effector"]["kind"] == kind
        assert spec["episode"]["max_steps"] == _native.sim_constants()["MAX_EPISODE_STEPS"]
    # Numbers read back as the file wrote them (f32 0.04 is 0.04, not 0.03999999910593033).
    suction = _native.task_spec("TileSuction")
    assert suction["thresholds"]["pick_dist"] == 0.04
    assert suction["object"]["half_extents"] == [0.075, 0.075, 0.005]
    assert suction["thresholds"]["fall_tilt_cos"] == 0.70710677  # the f32 nearest cos 45°
    assert suction["effector"] == {
        "kind": "suction",
        "plate_half_extents": [0.05, 0.05, 0.01],
        "cup_offset": 0.045,
        "cup_radius": 0.015,
        "tcp_z": 0.05,
    }


def test_env_from_spec_file_runs_the_files_numbers(tmp_path: Path) -> None:
    path = tmp_path / "short.toml"
    path.write_text(_suction_text().replace("max_steps = 750", "max_steps = 5"))
    assert _native.load_task_spec(str(path))["episode"] == {"max_steps": 5}
    env = _native.SimEnv.from_spec_file(str(path), seed=0)
    assert env.task == "TileSuction" and env.spec()["episode"]["max_steps"] == 5
    env.reset(seed=1)
    truncated = [env.step([0.0] * env.act_dim)[3] for _ in range(5)]
    assert truncated == [False] * 4 + [True]


def test_the_builtin_file_gives_the_builtin_episode(tmp_path: Path) -> None:
    path = tmp_path / "tile_suction.toml"
    path.write_text(_suction_text())
    a, b = _native.SimEnv("TileSuction", 0), _native.SimEnv.from_spec_file(str(path), 0)
    assert (a.reset(seed=3) == b.reset(seed=3)).all()
    for k in range(40):
        action = [0.5, -0.3, 0.2, 0.1, -0.4, 0.3, 1.0 if k > 20 else 0.0]
        oa, ob = a.step(action), b.step(action)
        assert (oa[0] == ob[0]).all() and oa[1:4] == ob[1:4]


def test_bad_specs_name_the_field_the_value_and_why(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(_suction_text().replace("mass = 0.5 ", "mass = -2 "))
    with pytest.raises(_native.SimInputError) as e:
        _native.load_task_spec(str(path))
    assert (e.value.field, e.value.value) == ("object.mass", "-2.0")
    assert "> 0" in e.value.reason and isinstance(e.value, ValueError)
    path.write_text(_suction_text().replace("mass = 0.5 ", "masss = 0.5 "))
    with pytest.raises(_native.SimInputError, match="masss") as e:
        _native.SimEnv.from_spec_file(str(path))
    assert e.value.field is None
    with pytest.raises(FileNotFoundError):
        _native.load_task_spec(str(tmp_path / "missing.toml"))
