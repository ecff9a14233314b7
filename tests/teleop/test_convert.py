"""Hand log → demo converter: parsing, filtering, the per-frame pipeline, and (with the
simulator bindings) the end-to-end acceptance."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mimicrete import LogFormatError, kin
from mimicrete import demonstrator as sy
from mimicrete.cli import main as cli_main
from mimicrete.hands import log as handlog
from mimicrete.teleop import convert as cv
from mimicrete.teleop import session as ss


def _log(tmp_path, scene_fn, task="suction", seed=0, layout="openxr", handedness="right"):
    paths = sy.synth_hands(
        task, 1, seed, tmp_path, layout=layout, handedness=handedness, scene_fn=scene_fn
    )
    return paths[0]


# ---------------------------------------------------------------- parsing


def test_load_log_roundtrip(tmp_path, scene_fn):
    path = _log(tmp_path, scene_fn, layout="webxr")
    log = cv.load_log(path)
    assert log.header["layout"] == "webxr" and log.header["handedness"] == "right"
    assert log.joints.shape[1:] == (25, 3)
    assert len(log.t) == len(log.tracked) == len(log.joints)
    assert np.all(np.diff(log.t) > 0)
    raw = json.loads(path.read_text().splitlines()[5])
    np.testing.assert_array_equal(log.joints[4], np.array(raw["joints"]))


HEADER = json.dumps(handlog.header("mediapipe", "openxr", "right"))
GOOD = json.dumps({"t": 0.0, "tracked": True, "joints": [[0.0, 0.0, 0.0]] * 21})


@pytest.mark.parametrize(
    ("lines", "match"),
    [
        ([], r":1: missing header: the file is empty"),
        (["{"], r":1: missing header: line 1 is not a JSON object"),
        ([json.dumps({"format": "x"})], r':1: unknown format "x" in header'),
        ([HEADER.replace("mediapipe", "kinect")], r':1: header: unknown layout "kinect"'),
        ([HEADER.replace('"m"', '"cm"')], r':1: header: unknown units "cm"'),
        ([HEADER], r":2: no frames"),
        ([HEADER, GOOD, GOOD.replace("0.0,", "-1.0,", 1)], r":3: time goes backwards"),
        (
            [HEADER, GOOD, json.dumps({"t": 1, "tracked": True, "joints": [[0, 0, 0]] * 20})],
            r":3: wrong joint count: 20 joints, layout mediapipe has 21",
        ),
        ([HEADER, '{"t": 1, "tracked": 1, "joints": []}'], r":2: \"tracked\" must be a bool"),
        (
            [
                HEADER,
                GOOD,
                '{"t": 2, "tracked": true, "joints": ' + str([[0, 0, 0]] * 20 + [[0, 0]]) + "}",
            ],
            r":3: joint 20 must be \[x, y, z\], got 2 numbers",
        ),
        (
            [HEADER, GOOD.replace("0.0]", "NaN]", 1)],
            r":2: non-finite value \(NaN\) in joint 0 coordinate z",
        ),
        ([HEADER, GOOD, '{"t": 3, "tracked": true'], r":3: invalid JSON"),
    ],
)
def test_convert_errors_name_file_and_line(tmp_path, lines, match):
    path = tmp_path / "bad.jsonl"
    path.write_text("\n".join(lines) + ("\n" if lines else ""))
    with pytest.raises(LogFormatError, match=match) as e:
        cv.convert_log(path, "suction", None)
    assert str(e.value).startswith(f"{path}:")


# ---------------------------------------------------------------- numerics


# The loop's numerics (the joint action, the wrap, the One Euro filter, the suction's switch
# commands) are teleop-core's and tested there: crates/teleop-core/tests/numerics.rs.


# ---------------------------------------------------------------- the per-frame pipeline


@pytest.mark.parametrize("task", ["suction", "grip", "screw"])
@pytest.mark.parametrize("handedness", ["right", "left"])
def test_teleop_targets_follow_the_plan_and_gestures_command(task, handedness, scene_fn):
    scene = scene_fn(task, 3)
    ep = sy.synth_episode(scene, 2, handedness=handedness)
    tele = ss.Session(task, "openxr", handedness, kin.Calibration(), seed=3)
    errs, ang, cmds = [], [], []
    for k in range(len(ep.t)):
        tele.observe(float(ep.t[k]), bool(ep.tracked[k]), ep.joints[k])
        cmds.append(tele.command())
        target = tele.target
        if target is not None and ep.tracked[k] and ep.phases[k] in ("grasp", "settle"):
            errs.append(np.linalg.norm(target[:3, 3] - ep.tool0[k][:3, 3]))
            r = target[:3, :3].T @ ep.tool0[k][:3, :3]
            ang.append(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1)))
    # while the hand is (nearly) still the filtered target sits on the plan
    assert np.median(errs) < 0.002 and max(errs) < 0.01
    assert np.median(ang) < np.radians(1.0)
    c = tele.counts
    assert c.frames == len(ep.t) and c.untracked == int((~ep.tracked).sum())
    ee = [x[0] for x in cmds]
    runs = [ee[0]] + [b for a, b in zip(ee, ee[1:], strict=False) if a != b]
    assert runs[:3] == [0.0, -1.0, 1.0]  # nothing yet, open, then close
    assert runs[-1] == -1.0  # released at the end
    if task == "screw":
        assert (1.0, 1.0) in cmds and (1.0, -1.0) not in cmds


def test_teleop_holds_target_through_untracked_frames(scene_fn):
    scene = scene_fn("suction", 1)
    ep = sy.synth_episode(scene, 0)
    tele = ss.Session("suction", "openxr", "right", kin.Calibration(), seed=1)
    for k in range(100):
        tele.observe(float(ep.t[k]), True, ep.joints[k])
    held = tele.target.copy()
    state = tele.gesture
    for k in range(100, 110):  # the runtime lost the hand; its joints are garbage
        tele.observe(float(ep.t[k]), False, np.zeros_like(ep.joints[k]))
        np.testing.assert_array_equal(tele.target, held)
        assert tele.gesture == state
    assert tele.counts.untracked == 10
    # a degenerate (collapsed) hand counts and keeps the target too
    tele.observe(float(ep.t[110]), True, np.zeros_like(ep.joints[0]))
    np.testing.assert_array_equal(tele.target, held)
    assert tele.counts.degenerate == 1


def test_task_names_and_logged_task_mismatch(tmp_path, scene_fn):
    from mimicrete import tasks

    assert tasks.get("TileSuction").name == "suction"
    assert tasks.get("block_grip").name == "grip"
    assert tasks.get("mimicrete/Screw-v0").name == "screw"
    with pytest.raises(ValueError, match="unknown task"):
        tasks.get("weld")
    path = _log(tmp_path, scene_fn, task="suction")
    with pytest.raises(ValueError, match="hand log is for task 'suction'"):
        cv.convert_log(path, "grip", None)


# ---------------------------------------------------------------- end to end (needs the bindings)


@pytest.mark.parametrize("task", ["suction", "grip", "screw"])
def test_convert_installs_and_replays_exactly(tmp_path, task):
    from mimicrete import _native, demos, tasks

    paths = sy.synth_hands(task, 3, 0, tmp_path / "logs")
    results = []
    for i, p in enumerate(paths):
        res = cv.convert_log(p, task, tmp_path / "demos", episode_index=i)
        assert res.installed and res.picked and not res.fell, (p, res.counts)
        assert res.counts.unreachable == 0
        assert res.counts.frames + res.counts.frames_after_end >= res.counts.frames
        results.append(res)
    # the demos on disk hold exactly what was stepped, and replaying their actions in a fresh
    # environment with the episode's seed gives back their rewards bit for bit
    d = demos.load(tmp_path / "demos")
    assert d.num_episodes == 3
    for res, sl, meta in zip(results, d.episode_slices(), d.metas, strict=True):
        assert int(meta["seed"]) == res.episode_seed and meta["success"] == "true"
        np.testing.assert_array_equal(d.actions[sl], res.actions)
        np.testing.assert_array_equal(d.rewards[sl], np.array(res.rewards, dtype=np.float32))
        replayed = cv.replay(task, res.episode_seed, d.actions[sl])
        np.testing.assert_array_equal(np.array(replayed, dtype=np.float32), d.rewards[sl])
        assert d.terminated[sl][-1] and sum(replayed) == 2.0  # pick/grip +1, install +1
        # each record pairs an action with the observation it was chosen from (obs_t, a_t):
        # BC and GAIL learn from these pairs, so a one-step shift would teach the wrong mapping
        env = _native.SimEnv(tasks.get(task).sim)
        obs = env.reset(res.episode_seed)
        for o_rec, a in zip(d.obs[sl], d.actions[sl], strict=True):
            np.testing.assert_array_equal(o_rec, np.asarray(obs, dtype=np.float32))
            before = np.asarray(obs)[-len(obs) // 5 :][6]
            obs = env.step(a)[0]
            if task == "suction":  # a suction command is recorded only where it switches
                after = np.asarray(obs)[-len(obs) // 5 :][6]
                assert (a[6] != 0) == (before != after), (a[6], before, after)
        if task == "suction":  # the demonstrator switches the suction on once and never drops
            assert d.actions[sl][:, 6].tolist().count(1.0) == 1
            assert -1.0 not in d.actions[sl][:, 6]


@pytest.mark.parametrize(
    ("task", "layout", "hand"),
    [("suction", "meta_ovr", "left"), ("grip", "mediapipe", "left"), ("screw", "webxr", "right")],
)
def test_other_layouts_and_the_left_hand_install(tmp_path, task, layout, hand):
    path = sy.synth_hands(task, 1, 7, tmp_path, layout=layout, handedness=hand)[0]
    log = cv.load_log(path)
    assert (log.header["layout"], log.header["handedness"]) == (layout, hand)
    res = cv.convert_log(log, task, None, source=path)
    assert res.installed, res.counts


def test_unreachable_targets_are_counted_not_followed(tmp_path):
    # the same demonstration with the calibration shifted 2 m away: every target is out of reach
    path = sy.synth_hands("suction", 1, 0, tmp_path / "logs")[0]
    log = cv.load_log(path)
    log.header["extra"]["calibration"]["translation"] = [2.5, 0.0, 0.6]
    res = cv.convert_log(log, "suction", None, source=path)
    assert res.counts.unreachable == res.steps > 0  # every step had a target, none reachable
    assert res.counts.frames_after_end == 0  # the log ran out, the episode did not end
    assert not res.installed
    assert np.all(res.actions[:, :6] == 0.0)  # no motion made up


def test_cli_convert_dir(tmp_path, capsys):
    sy.synth_hands("grip", 2, 1, tmp_path / "logs")
    (tmp_path / "logs" / "broken.jsonl").write_text('{"format": "nope"}\n')
    argv = ["convert", str(tmp_path / "logs"), "--task", "grip", "--out", str(tmp_path / "demos")]
    assert cli_main([*argv, "--no-progress"]) == 2  # one log refused (bad input)
    out = capsys.readouterr()
    assert 'broken.jsonl:1: unknown format "nope" in header' in out.err
    assert "2 demos in" in out.out and "2 installed (100.0 %), 1 logs failed" in out.out
    assert sorted(p.name for p in (tmp_path / "demos").iterdir()) == [
        "grip_0000.mcap",
        "grip_0001.mcap",
    ]


@pytest.mark.slow
@pytest.mark.parametrize("task", ["suction", "grip", "screw"])
def test_acceptance_60_episodes_install_rate(tmp_path, task):
    paths = sy.synth_hands(task, 60, 0, tmp_path / "logs")
    ok = sum(
        cv.convert_log(p, task, tmp_path / "demos", episode_index=i).installed
        for i, p in enumerate(paths)
    )
    assert ok >= 57  # ≥ 95 %


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), hand=st.sampled_from(["left", "right"]))
def test_session_target_is_the_public_hand_to_target(seed, hand):
    """The session calls ur3-kin's hand → tool0 map with the calibration converted once; on the
    first frame (the filter passes it through) that is exactly ``mc.kin.hand_to_target``."""
    from mimicrete.hands import model as hm

    rng = np.random.default_rng(seed)
    calib = kin.Calibration(hm.random_rotation(rng), rng.normal(size=3), rng.uniform(0.5, 2.0))
    j = hm.hand_joints(hm.GESTURE_SHAPES["fixed"], hm.random_rotation(rng), rng.normal(size=3))
    s = ss.Session("suction", "openxr", hand, calib, seed=0)
    s.observe(0.0, True, j)
    np.testing.assert_array_equal(s.target, kin.hand_to_target(j[1], j[7], j[12], hand, calib))
