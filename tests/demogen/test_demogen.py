"""Object-centric demo generation (``mimicrete demogen``): the segment transform, generation
through the real simulator from one recorded demo, and the CLI's bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs
from tests._cli_run import run_cli

from mimicrete import _native, demos, kin
from mimicrete import demogen as dg
from mimicrete.demogen import generator as gen
from mimicrete.demogen import segment as sg
from mimicrete.demogen.generator import GeneratedEpisode, _Runner


def _expert_demo(task: str, seed: int, path) -> None:
    """One real MCAP demo of ``task`` at a paper start: tile-sim's scripted expert driving the
    simulator, every step recorded through the project's demo writer."""
    spec = dg.task_frames(task)
    sim = _native.SimEnv(task, 0)
    expert = _native.SimExpert(task)
    obs = sim.reset(seed)
    expert.reset()
    ep = GeneratedEpisode("expert", {"object_pose": list(sim.start()["object_pose"])}, seed)
    ep.task = spec.sim
    run = _Runner(sim, ep, np.asarray(obs, np.float32))
    for _ in range(700):
        a = np.asarray(expert.act(sim), np.float64)
        target = kin.fk(run.q + a[:6] * sim.joint_step, model="ur3")
        try:
            run.step(target, a[6:])
        except gen._Abort:
            break
    assert ep.installed, f"the scripted expert should succeed at {task} from a paper start"
    dg.write_episode(ep, path, 0)


@pytest.fixture(scope="module")
def source_dir(tmp_path_factory):
    """One TileSuction source demo (:func:`_expert_demo`)."""
    out = tmp_path_factory.mktemp("src")
    _expert_demo("TileSuction", 11, out / "src_0000.mcap")
    return out


@pytest.fixture(scope="module", params=["BlockGrip", "Screw"])
def gripper_source(request, tmp_path_factory):
    """One source demo of each gripper task: ``(task, dir)``."""
    out = tmp_path_factory.mktemp(f"src_{request.param}")
    _expert_demo(request.param, 11, out / "src_0000.mcap")
    return request.param, out


def test_a_transformed_segment_lands_in_the_new_object_frame(source_dir):
    (src,) = dg.load_sources(source_dir)
    approach, place = src.segments
    assert approach.relative_to == "object" and place.relative_to == "target"
    dst = dg.frame(0.21, 0.35, 0.005, np.radians(25.0))
    moved = approach.moved_to(dst)
    # every pose keeps its pose relative to the frame: src⁻¹·P == dst⁻¹·P'
    rel_src = np.linalg.inv(approach.src) @ approach.poses
    rel_dst = np.linalg.inv(dst) @ moved
    np.testing.assert_allclose(rel_dst, rel_src, atol=1e-9)
    # the grasp pose (the segment's end) sits above the new tile as it sat above the old one
    tcp_above = approach.poses[-1][:3, 3] - approach.src[:3, 3]
    c, s = np.cos(np.radians(25.0)), np.sin(np.radians(25.0))
    want = dst[:3, 3] + np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]) @ tcp_above
    np.testing.assert_allclose(moved[-1][:3, 3], want, atol=1e-6)
    # the tool stays a rigid transform (pointing down, turned by the yaw)
    np.testing.assert_allclose(
        moved[:, :3, :3] @ moved[:, :3, :3].transpose(0, 2, 1),
        np.broadcast_to(np.eye(3), moved[:, :3, :3].shape),
        atol=1e-9,
    )


def test_generation_from_one_demo_installs_at_new_starts(source_dir, tmp_path):
    sources = dg.load_sources(source_dir, 1)
    starts = dg.draw_starts(6, seed=3, starts="wide")
    rep = dg.generate(sources, 6, tmp_path, starts=starts, seed=3, max_attempts=6)
    assert rep.attempts == 6 and rep.kept >= 5, rep.failures
    d = demos.load(tmp_path)
    assert d.num_episodes == rep.kept
    for meta, path in zip(d.metas, d.files, strict=True):
        assert meta["generated"] == "true" and meta["source_demo"] == "src_0000.mcap"
        assert meta["success"] == "true"
        pose = json.loads(meta["object_pose"])
        # the demo really starts there: its first observation holds the new tile
        first = demos.load(path).obs[0, -16:]
        np.testing.assert_allclose(first[13:15], pose[:2], atol=1e-5)
        # and its /scene draws the pad where that start moved it with the target
        from mcap.reader import make_reader

        with open(path, "rb") as f:
            msg = next(make_reader(f).iter_messages(topics=["/scene"]))[2]
        pad = {e["id"]: e for e in json.loads(msg.data)["entities"]}["pad"]["cubes"][0]
        offset = json.loads(meta["target_offset"])
        got = [pad["pose"]["position"][k] for k in ("x", "y")]
        np.testing.assert_allclose(got, np.array([-0.22, 0.28]) + offset, atol=1e-6)
    # the new starts lie outside the source's (paper) start
    src_x = sources[0].object[0]
    assert max(abs(json.loads(m["object_pose"])[0] - src_x) for m in d.metas) > 0.03
    # the installs are real: the last step of each generated demo is rewarded and terminal
    for sl in d.episode_slices():
        assert d.terminated[sl][-1] and d.rewards[sl].sum() >= 2.0 - 1e-6


def test_played_actions_are_in_units_of_the_specs_joint_step(tmp_path):
    """In a spec with ``robot.joint_step`` (here 0.02 rad, half the built-in step), an action
    demogen plays that does not saturate puts the arm on its IK answer in one step (it would
    reach only half way in units of ``MAX_JOINT_STEP``), and a source demo's poses are read
    with the step it ran at."""
    text = _native.task_spec("TileSuction", as_toml=True)
    path = tmp_path / "slow.toml"
    path.write_text(text.replace('model = "ur3"', 'model = "ur3"\njoint_step = 0.02', 1))
    sim = gen.sim_env("TileSuction", str(path))
    assert sim.joint_step == 0.02
    obs = sim.reset(0)
    ep = GeneratedEpisode("t", {"object_pose": list(sim.start()["object_pose"])}, 0)
    run = _Runner(sim, ep, np.asarray(obs, np.float32))
    pose = run.pose()
    for k in range(1, 6):  # 1 mm down a step: no joint needs a full step
        target = pose.copy()
        target[2, 3] -= 0.001 * k
        run.step(target, 0.0)
        a = ep.rows[-1]["action"][:6]
        assert np.max(np.abs(a)) < 1.0, a
        np.testing.assert_allclose(run.q, run.q_ik, atol=1e-6)
        np.testing.assert_allclose(run.pose()[:3, 3], target[:3, 3], atol=1e-6)
    # a source's last action is read with the step of the spec it ran in
    meta = {"task_spec": json.dumps(sim.spec())}
    q = np.asarray(sim.snapshot()["q"])
    full = np.array([1.0, 0, 0, 0, 0, 0, 0], np.float32)
    after = dg.segment.spec_of(meta, "suction"), dg.segment.spec_of({}, "suction")
    moved = [_native.joint_motion(s, q, full)[0] - q[0] for s in after]
    np.testing.assert_allclose(moved, [0.02, 0.04], atol=1e-12)


def test_cli_bad_input_exits_2_naming_the_problem(source_dir, tmp_path):
    r = run_cli(
        "demogen", "--demos", str(tmp_path / "nope"), "--count", "3", "--out", str(tmp_path / "o")
    )
    assert r.returncode == 2 and "--demos" in r.stderr and "no such file" in r.stderr, r.stderr
    r = run_cli("demogen", "--demos", str(source_dir), "--count", "0", "--out", str(tmp_path))
    assert r.returncode == 2 and "--count" in r.stderr, r.stderr
    r = run_cli(
        "demogen",
        "--demos",
        str(source_dir),
        "--count",
        "2",
        "--starts",
        "everywhere",
        "--out",
        str(tmp_path / "o2"),
    )
    assert r.returncode == 2 and "--starts everywhere" in r.stderr, r.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    r = run_cli("demogen", "--demos", str(empty), "--count", "2", "--out", str(tmp_path / "o3"))
    assert r.returncode == 2 and "no *.mcap" in r.stderr, r.stderr


def test_cli_writes_demos_with_a_summary(source_dir, tmp_path):
    out = tmp_path / "gen"
    r = run_cli(
        "demogen",
        "--demos",
        str(source_dir),
        "--count",
        "2",
        "--starts",
        "wide",
        "--out",
        str(out),
        "--seed",
        "1",
        "--no-progress",
    )
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "demogen.json").read_text())
    assert summary["kept"] == 2 and summary["attempts"] >= 2
    assert "yield" in r.stdout


def test_gripper_demos_split_after_the_grasp(gripper_source):
    """The gripper's switch (the first close command) starts the grasp, which stays in the
    object-relative segment until the source held the object; the rest is target-relative."""
    task, d = gripper_source
    (src,) = dg.load_sources(d)
    assert src.task == task
    grasp, rest = src.segments
    assert (grasp.relative_to, rest.relative_to) == ("object", "target")
    closing = np.flatnonzero(grasp.commands[:, 0] >= 0.5)
    # the fingers close at 0.1 m/s from 0.085 m: several close steps, all at the segment's end
    assert len(closing) >= 5 and closing[-1] == len(grasp) - 1
    assert np.all(np.diff(closing) == 1)
    assert np.all(grasp.commands[: closing[0], 0] <= -0.5)  # opened on the way there
    # the grasp ends at the object: the TCP (0.085 m along tool0 z) within 1 cm of its centre
    tcp = grasp.poses[-1][:3, 3] + 0.085 * grasp.poses[-1][:3, 2]
    assert np.linalg.norm(tcp - src.object) < 0.01
    if task == "Screw":  # the spin is a command column of its own, only after the grasp
        assert grasp.commands.shape[1] == 2 and np.all(grasp.commands[:, 1] == 0.0)
        assert np.sum(rest.commands[:, 1] >= 0.5) >= 50  # 3 turns at 1 turn/s, 25 steps/s
    else:
        assert grasp.commands.shape[1] == 1 and np.any(rest.commands[:, 0] <= -0.5)  # release


def test_gripper_generation_succeeds_at_the_requested_starts(gripper_source, tmp_path):
    task, d = gripper_source
    sources = dg.load_sources(d)
    starts = dg.draw_starts(6, seed=5, starts="wide", task=task)
    rep = dg.generate(sources, 6, tmp_path, starts=starts, seed=5, max_attempts=6)
    assert rep.attempts == 6 and rep.kept >= 5, rep.failures
    loaded = demos.load(tmp_path)
    assert loaded.num_episodes == rep.kept
    spec = dg.task_frames(task)
    lay = spec.lay
    requested = {json.dumps(s["object_pose"]) for s in starts}
    sim = _native.SimEnv(task, 0)
    for meta, path in zip(loaded.metas, loaded.files, strict=True):
        assert meta["task"] == task and meta["generated"] == "true" and meta["success"] == "true"
        assert meta["object_pose"] in requested
        pose, offset = json.loads(meta["object_pose"]), json.loads(meta["target_offset"])
        ep = demos.load(path)
        assert ep.actions.shape[1] == spec.act_dim
        first = ep.obs[0, -spec.frame_dim :]
        # the demo starts where it was asked to: the object, and the target the simulator puts
        # there for that start
        np.testing.assert_allclose(first[lay["object"]][:2], pose[:2], atol=1e-5)
        want = sim.reset(0, object_pose=pose, target_offset=offset)[-spec.frame_dim :]
        np.testing.assert_allclose(first[lay["target"]], want[lay["target"]], atol=1e-5)
    # the starts are wide: at least one 3 cm from the source's object in x or y
    spread = max(
        np.max(np.abs(np.asarray(json.loads(m["object_pose"])[:2]) - sources[0].object[:2]))
        for m in loaded.metas
    )
    assert spread > 0.03
    # the successes are real: the grasp (+1) and the place / screw (+1), the last step terminal
    for sl in loaded.episode_slices():
        assert loaded.terminated[sl][-1] and loaded.rewards[sl].sum() >= 2.0 - 1e-6


def test_cli_task_from_the_demos_and_mixed_tasks(source_dir, gripper_source, tmp_path):
    task, d = gripper_source
    out = tmp_path / "gen"
    r = run_cli("demogen", "--demos", str(d), "--count", "1", "--out", str(out), "--no-progress")
    assert r.returncode == 0, r.stderr
    summary = json.loads((out / "demogen.json").read_text())
    assert summary["task"] == task and summary["kept"] == 1
    assert json.loads((out / "demogen.json").read_text())["sources"] == ["src_0000.mcap"]
    r = run_cli(
        "demogen", "--demos", str(d), "--task", "suction", "--count", "1", "--out",
        str(tmp_path / "o1"),
    )  # fmt: skip
    assert r.returncode == 2 and "--task suction" in r.stderr and task in r.stderr, r.stderr
    assert "Traceback" not in r.stderr
    r = run_cli(
        "demogen", "--demos", str(d), "--task", "hammer", "--count", "1", "--out",
        str(tmp_path / "o2"),
    )  # fmt: skip
    assert r.returncode == 2 and "unknown task 'hammer'" in r.stderr, r.stderr
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    (mixed / "a.mcap").write_bytes((source_dir / "src_0000.mcap").read_bytes())
    (mixed / "b.mcap").write_bytes((d / "src_0000.mcap").read_bytes())
    r = run_cli("demogen", "--demos", str(mixed), "--count", "1", "--out", str(tmp_path / "o3"))
    assert r.returncode == 2 and "mixes tasks" in r.stderr and task in r.stderr, r.stderr
    assert "Traceback" not in r.stderr


def test_grasp_jitter_grasps_off_centre_and_places_the_block_not_the_tcp(tmp_path):
    """BlockGrip with ``grasp_jitter``: the block is held off the TCP by up to the jitter along
    the fingers, the place is shifted by that offset, and the block still lands on the target."""
    src_dir = tmp_path / "src"
    _expert_demo("BlockGrip", 11, src_dir / "src_0000.mcap")
    sources = dg.load_sources(src_dir)
    starts = dg.draw_starts(6, seed=5, starts="wide", task="BlockGrip")
    rep = dg.generate(
        sources, 6, tmp_path / "out", starts=starts, seed=5, max_attempts=6, grasp_jitter=0.02
    )
    assert rep.kept >= 5, rep.failures
    lay = dg.task_frames("BlockGrip").lay
    offsets = []
    for sl_obs in (demos.load(p).obs for p in rep.files):
        last = sl_obs[-1, -16:]
        offsets.append(np.linalg.norm((last[lay["object"]] - last[lay["tcp"]])[:2]))
        assert np.linalg.norm((last[lay["object"]] - last[lay["target"]])[:2]) < 0.005
    assert max(offsets) > 0.005 and max(offsets) < 0.025


def test_screw_demos_close_the_gripper_from_the_first_step_at_the_nut(tmp_path):
    """Screw (``TaskFrames.close_in_reach``): a person's demo holds the fingers open at the nut
    for many steps before closing; the generated demos command "close" from the first step whose
    state is within the simulator's grasp tolerance on, so a cloned policy's command at the nut
    is "close" (before, ~24 "open" steps per demo there against ~9 "close": its argmax never
    closed), and once it grips, it turns the nut at once (``screw_from_grasp``). The other tasks
    keep the source's commands."""
    from mimicrete import demonstrator as synth
    from mimicrete.teleop import convert

    assert dg.TASKS["Screw"].close_in_reach and dg.TASKS["Screw"].screw_from_grasp
    for other in ("TileSuction", "BlockGrip"):
        assert not dg.TASKS[other].close_in_reach and not dg.TASKS[other].screw_from_grasp
    src_dir = tmp_path / "src"
    src_dir.mkdir()
    (log,) = synth.synth_hands("screw", 1, 0, tmp_path / "hands")
    convert.convert_log(log, "screw", src_dir, episode_index=0)
    (src,) = dg.load_sources(src_dir)
    spec, lay = src.spec, src.spec.lay
    starts = dg.draw_starts(3, seed=5, starts="wide", task="Screw")
    sim = _native.SimEnv("Screw", 0)
    for k, st in enumerate(starts):
        ep = dg.generate_episode(sim, src, st, 40 + k)
        assert ep.installed, ep.why
        f = np.array([r["obs"][-spec.frame_dim :] for r in ep.rows], np.float64)
        a = np.array([r["action"] for r in ep.rows])
        pick = next(i for i, r in enumerate(ep.rows) if "pick" in r["events"])
        # well inside the tolerance (6 mm across, 2 cm along the tool; the flange points down):
        # the nut within 5 mm of the TCP horizontally and 1.5 cm vertically, before the step
        gap = f[:, lay["tcp"]] - f[:, lay["object"]]
        near = (np.linalg.norm(gap[:, :2], axis=1) < 0.005) & (np.abs(gap[:, 2]) < 0.015)
        first = int(np.flatnonzero(near)[0])
        assert first < pick - 10  # the source reached the nut well before it grasped
        assert np.all(a[first : pick + 1, 6] >= 0.5), np.flatnonzero(a[first : pick + 1, 6] < 0.5)
        assert not any(g.startswith("opening") for g in (r["gesture"] for r in ep.rows[first:]))
        # ``screw_from_grasp``: the nut turns from the step after the grip on, to the end
        assert np.all(a[pick + 1 :, 7] >= 0.5), np.flatnonzero(a[pick + 1 :, 7] < 0.5)


def test_cli_action_noise_perturbs_the_played_actions_by_sigma(source_dir, tmp_path):
    """``--action-noise SIGMA``: every played joint action carries Gaussian noise of standard
    deviation SIGMA (units of the joint step), recorded in the demos and the summary. Same seed,
    same starts and episode seeds with and without: the first action of each episode (the arm at
    the same reset, the IK at the same target) differs by the noise alone."""
    common = ["--demos", str(source_dir), "--count", "6", "--seed", "3", "--no-progress"]
    clean, noisy = tmp_path / "clean", tmp_path / "noisy"
    r = run_cli("demogen", *common, "--out", str(clean))
    assert r.returncode == 0, r.stderr
    r = run_cli("demogen", *common, "--out", str(noisy), "--action-noise", "0.05")
    assert r.returncode == 0, r.stderr
    assert json.loads((noisy / "demogen.json").read_text())["action_noise"] == 0.05
    first, metas = {}, {}
    for d in (clean, noisy):
        loaded = {p.name: demos.load(p) for p in sorted(d.glob("gen_*.mcap"))}
        first[d] = {  # keyed by the attempt (the start and episode seed it was drawn for)
            x.metas[0]["attempt"]: x.actions[0, :6].astype(np.float64) for x in loaded.values()
        }
        metas[d] = [x.metas[0] for x in loaded.values()]
    assert all(float(m["action_noise"]) == 0.05 for m in metas[noisy])
    assert not any("action_noise" in m for m in metas[clean])
    # the attempts that installed in both runs: first-step differences
    both = sorted(set(first[clean]) & set(first[noisy]))
    diffs = np.concatenate([first[noisy][n] - first[clean][n] for n in both])
    assert len(diffs) >= 24
    assert 0.025 < diffs.std() < 0.08, diffs
    assert abs(diffs.mean()) < 0.03
    bad = (("--action-noise", "-0.1"), ("--action-noise", "nan"), ("--grasp-jitter", "0.2"))
    for flag, value in bad:
        r = run_cli("demogen", *common, "--out", str(tmp_path / "bad"), flag, value)
        assert r.returncode == 2 and flag in r.stderr and "Traceback" not in r.stderr, r.stderr


@settings(max_examples=200, deadline=None)
@given(n=hs.integers(1, 600), speed=hs.floats(1.0, 10.0))
def test_retime_keeps_every_window_s_last_step_and_the_segment_s_end(n, speed):
    keep = sg.retime(n, speed)
    assert len(keep) == max(1, int(np.ceil(n / speed - 1e-9)))
    assert keep[-1] == n - 1 and keep[0] >= 0
    gaps = np.diff(np.concatenate([[-1], keep]))
    assert np.all(gaps >= 1) and np.all(gaps <= int(np.ceil(speed)))


def test_retime_at_speed_one_keeps_every_step_and_below_one_is_refused():
    np.testing.assert_array_equal(sg.retime(7, 1.0), np.arange(7))
    with pytest.raises(dg.DemoGenError, match="speed"):
        sg.retime(7, 0.5)


def test_a_latched_switch_inside_a_skipped_window_is_kept():
    commands = np.zeros((9, 1))
    commands[4, 0] = 1.0  # the suction's switch, on one step
    commands[7, 0] = -1.0  # the release
    keep = sg.retime(9, 3.0)  # steps 2, 5, 8
    out = sg.window_commands(commands, keep, latched=True)
    np.testing.assert_array_equal(out[:, 0], [0.0, 1.0, -1.0])
    # a level (the gripper) is its window's last value
    levels = np.repeat([[-1.0], [1.0], [1.0]], 3, axis=0)
    levels[3] = -1.0
    np.testing.assert_array_equal(sg.window_commands(levels, keep, False)[:, 0], [-1, 1, 1])


def test_cli_speed_out_of_range_exits_2(source_dir, tmp_path):
    for bad in ("0.5", "11", "nan"):
        r = run_cli("demogen", "--demos", str(source_dir), "--count", "2", "--speed", bad,
                    "--out", str(tmp_path / "o"))  # fmt: skip
        assert r.returncode == 2 and f"--speed must be in [1, 10], got {bad}" in r.stderr, r.stderr
