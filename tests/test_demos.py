"""MCAP demos written by the Rust writer, checked by independent readers: the official ``mcap``
package (CRCs validated), ``pymcap-cli doctor`` (small-mcap, an independent implementation) and
``jsonschema`` on every message."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import mimicrete as mc

OBS, ACT = 24, 7


def _scene():
    ident = [0, 0, 0, 0, 0, 0, 1]
    return [
        {
            "id": "table",
            "frame_id": "base",
            "kind": "cube",
            "size": [0.8, 0.6, 0.02],
            "pose": [-0.3, 0, -0.01, 0, 0, 0, 1],
            "color": [0.6, 0.5, 0.4, 1],
        },
        {"id": "tile", "frame_id": "tile", "kind": "cube", "size": [0.1, 0.1, 0.01], "pose": ident},
        {
            "id": "target",
            "frame_id": "base",
            "kind": "cube",
            "size": [0.1, 0.1, 0.001],
            "pose": np.eye(4),
            "color": [0.2, 0.8, 0.2, 0.5],
        },
        {
            "id": "cup0",
            "frame_id": "tool0",
            "kind": "cylinder",
            "size": [0.02, 0.02, 0.01],
            "pose": ident,
        },
        {"id": "marker", "kind": "sphere", "size": [0.01, 0.01, 0.01]},
    ]


def _step_values(i: int, n: int):
    rng = np.random.default_rng(i)
    obs = rng.standard_normal(OBS).astype(np.float32)
    act = rng.uniform(-1, 1, ACT).astype(np.float32)
    reward = 1.0 if i in (5, n - 1) else 0.0
    q = [0.1 * i, -1.2, 1.0, -0.5, -1.57, 0.0]
    return obs, act, reward, q


def write_episode(
    path: Path, episode: int = 0, n: int = 40, finish: bool = True, **kw
) -> dict | None:
    meta = {
        "episode": episode,
        "task": "suction",
        "seed": 100 + episode,
        "robot_model": "ur3",
        "gesture_model": "svm-test",
        "control_dt": 0.04,
        "hand": {"layout": "mediapipe", "space": "openxr", "handedness": "right"},
        "scene": _scene(),
        "extra": {"note": "pytest", "n": 3},
    }
    meta.update(kw)
    w = mc.demos.DemoWriter(str(path), meta, chunk_size=8192, flush_every_steps=8)
    for i in range(n):
        t = 0.04 * i
        obs, act, reward, q = _step_values(i, n)
        w.write_hand_frame(t, np.full((21, 3), 0.01 * i), True, 100.0 + t)
        w.write_step(
            i,
            t,
            obs,
            act,
            reward,
            i == n - 1,
            False,
            "suction" if i >= 10 else "hold",
            q,
            mc.kin.fk(np.array(q)) if hasattr(mc, "kin") else [0, 0, 0, 0, 0, 0, 1],
            [-0.3, 0.001 * i, 0.005, 0, 0, 0, 1],
            ["pick"] if i == 5 else [],
        )
        if i == 20:
            w.write_event(t, "install", {"where": "target"})
    if not finish:
        w.abandon()
        return None
    return w.finish(True, {"picked": True})


@pytest.fixture()
def demo(tmp_path: Path) -> Path:
    p = tmp_path / "ep0.mcap"
    write_episode(p)
    return p


def test_official_reader_with_crc_validation(demo: Path):
    from mcap.reader import make_reader

    counts: dict[str, int] = {}
    last = -1
    with demo.open("rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            assert message.log_time >= last
            last = message.log_time
            if channel.topic == "/demo/step":
                assert schema.name == "mimicrete.DemoStep.v1" and schema.encoding == "jsonschema"
        meta = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        atts = list(reader.iter_attachments())
    # events: gesture_change at steps 0 and 10, pick, install, success
    assert counts == {"/demo/step": 40, "/hand/joints": 40, "/tf": 40, "/scene": 1, "/events": 5}
    assert summary.statistics.message_count == sum(counts.values())
    assert last == round(0.04 * 39 * 1e9)
    assert meta["episode"]["success"] == "true"
    assert meta["episode"]["length"] == "40"
    assert meta["episode"]["note"] == "pytest"
    assert meta["episode"]["picked"] == "True"
    assert meta["episode_start"]["seed"] == "100"
    assert [a.name for a in atts] == ["ur3.urdf"]
    assert atts[0].media_type == "application/xml"
    assert b'<robot name="ur3">' in atts[0].data


def _pymcap_cli() -> str | None:
    exe = Path(sys.executable).parent / "pymcap-cli"
    return str(exe) if exe.exists() else shutil.which("pymcap-cli")


def test_independent_checker_doctor(demo: Path, tmp_path: Path):
    cli = _pymcap_cli()
    if cli is None:
        pytest.fail("pymcap-cli (requirements/dev.txt) is not installed: run `make setup`")
    r = subprocess.run([cli, "doctor", str(demo)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    # And it agrees that a cut file is broken.
    cut = tmp_path / "cut.mcap"
    data = demo.read_bytes()
    cut.write_bytes(data[: len(data) // 2])
    r = subprocess.run([cli, "doctor", str(cut)], capture_output=True, text=True)
    assert r.returncode != 0
    # The salvaged rewrite passes doctor.
    fixed = tmp_path / "fixed.mcap"
    mc.demos.salvage_to(cut, fixed)
    r = subprocess.run([cli, "doctor", str(fixed)], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_every_message_validates_against_its_jsonschema(demo: Path):
    import jsonschema
    from mcap.reader import make_reader

    validators = {}
    seen = set()
    with demo.open("rb") as f:
        for schema, _channel, message in make_reader(f, validate_crcs=True).iter_messages():
            if schema.id not in validators:
                s = json.loads(schema.data)
                jsonschema.Draft202012Validator.check_schema(s)
                assert s["title"] == schema.name
                validators[schema.id] = jsonschema.Draft202012Validator(s)
            validators[schema.id].validate(json.loads(message.data))
            seen.add(schema.name)
    assert seen == {
        "mimicrete.DemoStep.v1",
        "mimicrete.HandFrame.v1",
        "foxglove.FrameTransforms",
        "foxglove.SceneUpdate",
        "foxglove.Event",
    }


def test_tf_matches_forward_kinematics(demo: Path):
    from mcap.reader import make_reader

    with demo.open("rb") as f:
        for _s, _c, m in make_reader(f).iter_messages(topics=["/tf"]):
            tf = json.loads(m.data)["transforms"]
            step = m.log_time / 0.04e9
            i = round(step)
            T = np.eye(4)
            for x in tf[:-1]:  # the chain base -> ... -> tool0
                tr, r = x["translation"], x["rotation"]
                qx, qy, qz, qw = r["x"], r["y"], r["z"], r["w"]
                R = np.array(
                    [
                        [
                            1 - 2 * (qy * qy + qz * qz),
                            2 * (qx * qy - qz * qw),
                            2 * (qx * qz + qy * qw),
                        ],
                        [
                            2 * (qx * qy + qz * qw),
                            1 - 2 * (qx * qx + qz * qz),
                            2 * (qy * qz - qx * qw),
                        ],
                        [
                            2 * (qx * qz - qy * qw),
                            2 * (qy * qz + qx * qw),
                            1 - 2 * (qx * qx + qy * qy),
                        ],
                    ]
                )
                A = np.eye(4)
                A[:3, :3] = R
                A[:3, 3] = [tr["x"], tr["y"], tr["z"]]
                T = T @ A
            assert tf[-2]["child_frame_id"] == "tool0" and tf[-1]["child_frame_id"] == "tile"
            q = np.array(_step_values(i, 40)[3])
            np.testing.assert_allclose(T, mc.kin.fk(q), atol=1e-9)


def test_round_trip_arrays(tmp_path: Path):
    p = tmp_path / "ep.mcap"
    stats = write_episode(p, n=33)
    assert stats["steps"] == 33 and str(stats["path"]) == str(p)
    d = mc.demos.load(p)
    assert d.obs.shape == (33, OBS) and d.obs.dtype == np.float32
    assert d.actions.shape == (33, ACT) and d.actions.dtype == np.float32
    assert d.rewards.dtype == np.float32 and d.terminated.dtype == np.bool_
    for i in range(33):
        obs, act, reward, _q = _step_values(i, 33)
        np.testing.assert_array_equal(d.obs[i], obs)  # bit-exact float32
        np.testing.assert_array_equal(d.actions[i], act)
        assert d.rewards[i] == reward
    assert d.terminated.tolist() == [False] * 32 + [True]
    assert not d.truncated.any()
    assert (d.episode == 0).all()
    one = mc.demos.read(p)
    np.testing.assert_allclose(one["t"], 0.04 * np.arange(33), rtol=0, atol=1e-12)
    assert one["meta"]["success"] == "true"


def test_directory_load(tmp_path: Path):
    lens = [12, 30, 7]
    for e, n in enumerate(lens):
        write_episode(tmp_path / f"ep{e:02d}.mcap", episode=e, n=n)
    write_episode(tmp_path / "ep99.mcap", episode=99, n=5, finish=False)  # leaves ep99.mcap.partial
    assert (tmp_path / "ep99.mcap.partial").exists()
    d = mc.demos.load(tmp_path)
    assert len(d) == sum(lens) and d.num_episodes == 3
    assert d.episode.tolist() == sum(([e] * n for e, n in enumerate(lens)), [])
    assert [s.stop - s.start for s in d.episode_slices()] == lens
    assert [m["episode"] for m in d.metas] == ["0", "1", "2"]
    np.testing.assert_array_equal(d["obs"][12], _step_values(0, 30)[0])


def test_cut_file_errors_and_salvage(demo: Path, tmp_path: Path):
    from mcap.records import Message
    from mcap.stream_reader import StreamReader

    data = demo.read_bytes()
    for frac in (0.3, 0.6, 0.9):
        cut = tmp_path / f"cut{frac}.mcap"
        cut.write_bytes(data[: int(len(data) * frac)])
        with pytest.raises(mc.LogFormatError, match=r"salvage"):
            mc.demos.load(cut)
        # The official streaming reader yields every intact message before failing: an
        # independent count of what salvage must return.
        n_stream = 0
        with cut.open("rb") as f:
            try:
                for rec in StreamReader(f).records:
                    n_stream += isinstance(rec, Message)
            except Exception:
                pass
        msgs, report = mc.demos.salvage(cut)
        assert len(msgs) == n_stream == report["messages"]
        assert not report["complete"] and report["chunks_ok"] > 0
        fixed = tmp_path / f"fixed{frac}.mcap"
        mc.demos.salvage_to(cut, fixed)
        d = mc.demos.load(fixed)
        assert len(d) == sum(m["topic"] == "/demo/step" for m in msgs)
        np.testing.assert_array_equal(d.obs, mc.demos.load(demo).obs[: len(d)])


def _write_first_step(w, obs, act, reward, q):
    """Step 0 at t = 0, neither terminated nor truncated, identity poses."""
    ident = [0, 0, 0, 0, 0, 0, 1]
    w.write_step(0, 0.0, obs, act, reward, False, False, "hold", q, ident, ident)


def test_context_manager(tmp_path: Path):
    p = tmp_path / "cm.mcap"
    obs, act, reward, q = _step_values(0, 3)
    with mc.demos.DemoWriter(str(p), {"task": "suction"}) as w:
        _write_first_step(w, obs, act, reward, q)
        assert w.steps == 1
    assert p.exists() and mc.demos.read(p)["meta"]["success"] == "false"
    p2 = tmp_path / "boom.mcap"
    with pytest.raises(RuntimeError, match="boom"):
        with mc.demos.DemoWriter(str(p2), {}) as w:
            _write_first_step(w, obs, act, reward, q)
            raise RuntimeError("boom")
    assert not p2.exists()
    part = tmp_path / "boom.mcap.partial"
    assert len(mc.demos.read(part)["rewards"]) == 1  # closed validly, salvageable
    with pytest.raises(RuntimeError, match="closed"):
        w.write_event(0.0, "late")


def test_writer_errors(tmp_path: Path):
    obs, act, reward, q = _step_values(0, 3)
    pose = [0, 0, 0, 0, 0, 0, 1]
    w = mc.demos.DemoWriter(str(tmp_path / "e.mcap"), {})
    bad = obs.copy()
    bad[2] = np.nan
    with pytest.raises(ValueError, match=r"step 0: obs\[2\] is NaN"):
        w.write_step(0, 0.0, bad, act, reward, False, False, "hold", q, pose, pose)
    with pytest.raises(ValueError, match="7 numbers"):
        w.write_step(0, 0.0, obs, act, reward, False, False, "hold", q, [0, 0, 0], pose)
    w.write_step(0, 0.5, obs, act, reward, False, False, "hold", q, pose, pose)
    with pytest.raises(ValueError, match="log times must not decrease"):
        w.write_step(1, 0.1, obs, act, reward, False, False, "hold", q, pose, pose)
    with pytest.raises(ValueError, match='unknown episode meta key "colour"'):
        mc.demos.DemoWriter(str(tmp_path / "f.mcap"), {"colour": 1})
    with pytest.raises(ValueError, match='unknown robot model "ur4"'):
        mc.demos.DemoWriter(str(tmp_path / "g.mcap"), {"robot_model": "ur4"})
    with pytest.raises(OSError):
        mc.demos.DemoWriter(str(tmp_path / "no" / "such" / "dir.mcap"), {})
    with pytest.raises(OSError):
        mc.demos.DemoWriter(
            str(tmp_path / "h.mcap"), {"source_handlog": str(tmp_path / "missing.jsonl")}
        )
    w.abandon()


def test_source_handlog_hash(tmp_path: Path):
    import hashlib

    log = tmp_path / "hand.jsonl"
    mc.hands.write(
        log,
        {"layout": "mediapipe", "space": "openxr", "handedness": "left"},
        np.zeros(2),
        np.ones(2, bool),
        np.zeros((2, 21, 3)),
    )
    p = tmp_path / "ep.mcap"
    write_episode(p, n=3, source_handlog=str(log))
    meta = mc.demos.read(p)["meta"]
    assert meta["source_handlog_sha256"] == hashlib.sha256(log.read_bytes()).hexdigest()
    assert meta["source_handlog"] == str(log)


def test_inspect_cli(demo: Path, tmp_path: Path, capsys):
    from mimicrete import cli

    assert cli.main(["inspect", str(demo)]) == 0
    out = capsys.readouterr().out
    assert "/demo/step" in out and "mimicrete.DemoStep.v1" in out
    assert "success=True" in out and "ur3.urdf" in out and "steps=40" in out
    assert cli.main(["inspect", "--json", str(demo)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["steps"] == 40 and info["success"] is True and info["finished"] is True
    assert math.isclose(info["duration_s"], 0.04 * 39, abs_tol=1e-9)
    counts = {c["topic"]: c["messages"] for c in info["channels"]}
    assert counts["/tf"] == 40 and counts["/scene"] == 1
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(demo.read_bytes()[:3000])
    assert cli.main(["inspect", str(cut)]) == 1
    assert "salvage" in capsys.readouterr().out


def _first_scene(path: Path) -> dict[str, dict]:
    from mcap.reader import make_reader

    with path.open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            if channel.topic == "/scene":
                return {e["id"]: e for e in json.loads(message.data)["entities"]}
    raise AssertionError("no /scene")


def _one_step_demo(path: Path, meta: dict, **kw) -> Path:
    with mc.demos.DemoWriter(str(path), meta, **kw) as w:
        w.write_step(0, 0.0, np.zeros(16, np.float32), np.zeros(7, np.float32), 0.0, False, False,
                     "fixed", [0.0] * 6, [0, 0, 0, 0, 0, 0, 1], [0, 0, 0, 0, 0, 0, 1])
        w.finish(False)
    return path


def test_a_demo_records_its_envs_scene(tmp_path: Path):
    """DemoWriter(env=SimEnv) draws the env's own start (a wide one moves the pad with the
    target); without env, the task's paper start for the seed; entity for entity the same scene
    the live page gets from the env (``scene_entities``)."""
    from mimicrete import _native

    sim = _native.SimEnv("TileSuction", 0)
    sim.reset(7, object_pose=[0.25, 0.27, 0.3], target_offset=[0.03, -0.02])
    meta = {"task": "TileSuction", "seed": 7, "robot_model": "ur3"}
    own = _first_scene(_one_step_demo(tmp_path / "own.mcap", meta, env=sim))
    paper = _first_scene(_one_step_demo(tmp_path / "paper.mcap", meta))
    assert own.keys() == paper.keys() and "robot/upper_arm" in own
    pad = lambda s: s["pad"]["cubes"][0]["pose"]["position"]  # noqa: E731
    moved = {k: pad(own)[k] - pad(paper)[k] for k in ("x", "y")}
    assert moved == pytest.approx({"x": 0.03, "y": -0.02}, abs=1e-6)
    live = {e["id"]: e for e in sim.scene_entities()}
    assert pad(live) == pytest.approx(pad(own), abs=1e-9)
    with pytest.raises(TypeError, match="env must be a SimEnv, not str"):
        mc.demos.DemoWriter(str(tmp_path / "bad.mcap"), meta, env="TileSuction")
