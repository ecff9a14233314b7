"""The scripted human demonstrator: calibration inversion, hand logs, motion and gestures."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mimicrete import demonstrator as sy
from mimicrete import gestures as g
from mimicrete import kin
from mimicrete.hands import layouts
from mimicrete.hands import log as handlog
from mimicrete.hands import model as hm


def _rot_from(seed: int) -> np.ndarray:
    return hm.random_rotation(np.random.default_rng(seed))


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    hand=st.sampled_from(["left", "right"]),
    scale=st.floats(0.5, 2.0),
    space=st.sampled_from(["openxr", "robot_base"]),
    shape=st.sampled_from(list(hm.GESTURE_SHAPES)),
)
def test_hand_pose_inverts_hand_to_target(seed, hand, scale, space, shape):
    rng = np.random.default_rng(seed)
    calib = kin.Calibration(hm.random_rotation(rng), rng.normal(size=3), scale, space)
    tool0 = np.eye(4)
    tool0[:3, :3] = hm.random_rotation(rng)
    tool0[:3, 3] = rng.uniform(-0.4, 0.4, size=3)
    rot, wrist = sy.hand_pose_for_tool0(tool0, hand, calib)
    j = hm.hand_joints(hm.GESTURE_SHAPES[shape], rot, wrist, rng.uniform(0.8, 1.2), hand)
    back = kin.hand_to_target(j[1], j[7], j[12], hand, calib)
    np.testing.assert_allclose(back, tool0, atol=1e-9)
    np.testing.assert_allclose(
        kin.points_to_base(sy.points_from_base(tool0[:3, 3], calib), calib),
        tool0[:3, 3],
        atol=1e-12,
    )


def test_default_calibration_matches_ur3_kin_doc():
    # ur3-kin Calibration::default(): a hand 0.4 m in front of and 0.4 m below the head maps to
    # (0.3, 0, 0.2) in Base.
    np.testing.assert_allclose(
        kin.points_to_base([0.0, -0.4, -0.4], kin.Calibration()), [0.3, 0.0, 0.2]
    )


def test_header_calibration_keeps_its_format(scene_fn):
    # what hand logs have always stored under extra.calibration (readers of old logs rely on it)
    ep = sy.synth_episode(scene_fn("suction", 1), 0)
    stored = json.loads(json.dumps(ep.header["extra"]["calibration"]))
    assert stored == {
        "rotation": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        "translation": [-0.1, 0.0, 0.6],
        "scale": 1.0,
        "space": "openxr",
    }
    assert kin.Calibration.from_dict(stored).to_dict() == stored
    rng = np.random.default_rng(4)
    for hand in ("right", "left"):
        j = hm.hand_joints(
            hm.GESTURE_SHAPES["opening"], hm.random_rotation(rng), rng.normal(size=3), 1.0, hand
        )
        np.testing.assert_array_equal(
            kin.hand_to_target(j[1], j[7], j[12], hand, kin.Calibration.from_dict(stored)),
            kin.hand_to_target(j[1], j[7], j[12], hand),  # ur3-kin's own default
        )


def _read(path):
    lines = path.read_text().splitlines()
    return json.loads(lines[0]), [json.loads(x) for x in lines[1:]]


@pytest.mark.parametrize("layout", ["openxr", "webxr", "meta_ovr", "mediapipe"])
def test_handlog_format_and_layouts(tmp_path, layout, scene_fn):
    paths = sy.synth_hands("suction", 2, 7, tmp_path, layout=layout, scene_fn=scene_fn)
    assert [p.name for p in paths] == ["suction_0000.handlog.jsonl", "suction_0001.handlog.jsonl"]
    head, frames = _read(paths[0])
    assert head["format"] == "mimicrete.handlog" and head["version"] == 1
    assert (head["layout"], head["space"], head["handedness"], head["units"]) == (
        layout,
        "openxr",
        "right",
        "m",
    )
    assert head["task"] == "suction"
    assert head["episode_seed"] == sy.episode_seeds(7, 2)[0]
    # the project's one parser (Rust demo-log, strict: unknown header or frame fields are errors)
    # reads every file back with the same layout and frame count
    for p in paths:
        parsed = handlog.parse(p)
        assert parsed.header["layout"] == layout and len(parsed.t) == len(_read(p)[1])
    t = np.array([f["t"] for f in frames])
    np.testing.assert_allclose(np.diff(t), 1 / 90, atol=2e-6)
    assert 5.0 < t[-1] < 40.0
    n = layouts.LAYOUT_JOINTS[layout]
    assert all(len(f["joints"]) == n and all(len(p) == 3 for p in f["joints"]) for f in frames)
    # the frame joints are where the calibration says tool0 is
    fw, fi, fm = layouts.FRAME_JOINTS[layout]
    j0 = np.array(frames[0]["joints"])
    calib = kin.Calibration.from_dict(head["extra"]["calibration"])
    t0 = kin.hand_to_target(j0[fw], j0[fi], j0[fm], "right", calib)
    scene = head["extra"]["scene"]
    tcp0 = t0[:3, 3] + t0[:3, 2] * scene["tcp_z"]
    assert np.linalg.norm(tcp0 - np.array(scene["tcp"])) < 0.006
    assert t0[:3, 2] @ np.array([0, 0, -1.0]) > np.cos(np.radians(5))  # tool points down


def test_same_seed_same_files_other_seed_other_files(tmp_path, scene_fn):
    a = sy.synth_hands("grip", 2, 3, tmp_path / "a", scene_fn=scene_fn)
    b = sy.synth_hands("grip", 2, 3, tmp_path / "b", scene_fn=scene_fn)
    c = sy.synth_hands("grip", 2, 4, tmp_path / "c", scene_fn=scene_fn)
    for pa, pb, pc in zip(a, b, c, strict=True):
        assert pa.read_bytes() == pb.read_bytes()
        assert pa.read_bytes() != pc.read_bytes()


@pytest.mark.parametrize("task", sy.TASKS)
def test_motion_is_human_and_reaches_the_object(task, scene_fn):
    scene = scene_fn(task, 11)
    ep = sy.synth_episode(scene, 5)
    tcp = ep.tool0[:, :3, 3] + ep.tool0[:, :3, 2] * scene.tcp_z
    dt = 1 / 90
    speed = np.linalg.norm(np.diff(tcp, axis=0), axis=1) / dt
    assert 0.1 < speed.max() < 1.2  # a person's reach, not a teleport
    assert np.all(np.linalg.norm(np.diff(ep.tool0[:, :3, 3], axis=0), axis=1) < 0.02)
    # tremor: the hand is never perfectly still, even while holding (the first grasp: the row
    # grasps its three tiles one after another, the first one scene.object)
    holds = [i for i, p in enumerate(ep.phases) if p == "grasp"]
    holds = [i for k, i in enumerate(holds) if i - k == holds[0]]  # the first run of frames
    assert len(holds) > 20
    jitter = np.std(tcp[holds], axis=0)
    assert np.all(jitter > 1e-5) and np.all(jitter < 0.003)
    # at the grasp the TCP is over the object within a few millimetres
    grasp_tcp = tcp[holds].mean(axis=0)
    on_top = task in ("suction", "row")
    goal = scene.object + np.array([0, 0, scene.object[2]]) if on_top else scene.object
    assert np.linalg.norm(grasp_tcp[:2] - goal[:2]) < 0.004
    assert -0.005 < grasp_tcp[2] - goal[2] < 0.02
    # overshoot and correction phases happen somewhere in a set of episodes
    phases = set()
    for s in range(6):
        phases |= set(sy.synth_episode(scene, s).phases)
    assert any(p.endswith("_correct") for p in phases)


@pytest.mark.parametrize("task", sy.TASKS)
def test_gestures_follow_the_task_through_in_between_shapes(task, scene_fn):
    scene = scene_fn(task, 2)
    ep = sy.synth_episode(scene, 1)
    model = g.load_default("screw" if task == "screw" else "grip")
    raw = model.predict(ep.joints, "right")
    sm = g.GestureSmoother(initial=raw[0])
    smooth = [sm.update(x) for x in raw]
    runs = [smooth[0]] + [b for a, b in zip(smooth, smooth[1:], strict=False) if a != b]
    if task == "screw":
        assert runs[:2] == ["opening_stopped", "closing_fixed"]
        assert "closing_tightening" in runs
        assert "closing_loosening" not in runs
    else:
        assert runs[:3] == ["opening", "closing", "opening"]
    # during a gesture change the fingers pass through shapes that are neither end
    close = [i for i, p in enumerate(ep.phases) if p == "close"]
    mid = ep.joints[close[len(close) // 2]]
    ends = [ep.joints[close[0] - 1], ep.joints[close[-1] + 1]]
    f = g.features_3d(mid)
    assert all(np.linalg.norm(f - g.features_3d(e)) > 0.2 for e in ends)


def test_cli_writes_logs(tmp_path, monkeypatch, capsys, scene_fn):
    from mimicrete.cli import main as cli_main

    rc = cli_main(
        [
            "synth-hands",
            "--task",
            "screw",
            "--episodes",
            "2",
            "--seed",
            "1",
            "--out",
            str(tmp_path),
            "--layout",
            "meta_ovr",
        ]
    )
    assert rc == 0
    files = sorted(tmp_path.glob("*.jsonl"))
    assert len(files) == 2
    head, frames = _read(files[0])
    assert head["layout"] == "meta_ovr" and len(frames[0]["joints"]) == 24
    assert "wrote 2 hand logs" in capsys.readouterr().out


@pytest.mark.parametrize(("task", "tcp_z"), [("suction", 0.05), ("grip", 0.085), ("screw", 0.085)])
def test_scene_from_env_is_what_the_simulator_resets(task, tcp_z):
    from mimicrete import _native, tasks

    xs = []
    for seed in range(20):
        sc = sy.scene_from_env(task, seed)
        assert sc.episode_seed == seed and sc.task == task
        assert sc.tcp_z == pytest.approx(tcp_z, abs=1e-6)
        assert sc.object[1] == pytest.approx(0.32, abs=1e-6)  # tile-sim OBJECT_Y
        xs.append(sc.object[0])
        env = _native.SimEnv(tasks.get(task).sim)
        obs = env.reset(seed)
        frame = obs[-len(obs) // 5 :]
        np.testing.assert_allclose(frame[sy.obs_layout(task)["object"]], sc.object, atol=1e-6)
        np.testing.assert_allclose(frame[sy.obs_layout(task)["target"]], sc.target, atol=1e-6)
    assert 0.0 <= min(xs) < max(xs) <= 0.15  # paper: tile x randomised in [0, 0.15] m
