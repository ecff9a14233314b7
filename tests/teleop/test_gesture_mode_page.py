"""The page's gesture mode end to end, as a user teaches the SVM their own hand: the real
``mimicrete teleop`` server in the gesture mode, the built page in Debian's Chromium (Playwright,
headless), IWER emulating a Quest 3 whose right hand shows IWER's Quest-captured poses while it
moves and turns about the workspace (``window.__mimicrete.device``).

pinch → ``closing``, relaxed (``default``) → ``opening``, point → ``fixed``: the page records each
class (one is first recorded with the wrong pose and redone), the server writes the labelled CSV,
trains in a worker thread while frames keep being answered, the page shows the held-out accuracy
and the confusion matrix; the model then reads the live hand and drives an episode whose demo
names it. The CSV round-trips through ``mimicrete gesture train`` / ``eval``, and the next
``mimicrete teleop --out DIR`` picks the model up and records more episodes in the page, whose
hand logs name the model (and the recentred calibration): ``mimicrete convert`` of each gives back
its live demo step for step."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mimicrete import demos
from mimicrete import gestures as g
from mimicrete.cli import main as cli_main
from mimicrete.teleop.gesturemode import user_csv_path, user_model_path
from mimicrete.teleop.left_hand import INDEX_TIP, THUMB_TIP  # WebXR joints
from mimicrete.teleop.live import Live
from mimicrete.teleop.server import STATIC, ServerThread, TeleopServer
from mimicrete.teleop.view import standing_calibration
from mimicrete.testing import page_driver as br

POSES = {"closing": "pinch", "opening": "default", "fixed": "point"}
#: the shipped suction/grip model's sidecar: its held-out accuracy is what teleop prints
SHIPPED_SIDECAR = Path(g.__file__).parent / "models" / "gesture_grip.joblib.json"
PER_CLASS = 100


class HandMover:
    """Moves and turns IWER's right hand along a smooth random path about where it started (up
    to ``reach_m`` away, ``turn_deg`` about each axis), one step per call."""

    def __init__(self, page: Any, seed: int, reach_m: float = 0.15, turn_deg: float = 45.0):
        self.page, self.rng = page, np.random.default_rng(seed)
        self.reach, self.turn = reach_m, np.radians(turn_deg)
        self.home = page.evaluate(
            "() => { const h = window.__mimicrete.device.hands.right;"
            " const p = h.position, q = h.quaternion; return [p.x, p.y, p.z, q.x, q.y, q.z, q.w]; }"
        )
        self.pose, self.goal = np.zeros(6), self._random()

    def _random(self) -> np.ndarray:
        return np.concatenate(
            [self.rng.uniform(-1, 1, 3) * self.reach, self.rng.uniform(-1, 1, 3) * self.turn]
        )

    def step(self) -> None:
        d = self.goal - self.pose
        if np.linalg.norm(d) < 1e-3:
            self.goal = self._random()
            d = self.goal - self.pose
        self.pose = self.pose + d * min(1.0, 0.15 / max(float(np.linalg.norm(d)), 1e-9))
        q = np.asarray(self.home[3:], dtype=np.float64)
        for axis in range(3):  # small turns about x, y, z after the start orientation
            r = np.zeros(4)
            r[axis], r[3] = np.sin(self.pose[3 + axis] / 2), np.cos(self.pose[3 + axis] / 2)
            q = br._quat_mul(q, r)
        self.page.evaluate(
            "([p, q]) => { const h = window.__mimicrete.device.hands.right;"
            " h.position.set(p[0], p[1], p[2]); h.quaternion.set(q[0], q[1], q[2], q[3]); }",
            [(np.asarray(self.home[:3]) + self.pose[:3]).tolist(), q.tolist()],
        )

    def home_pose(self) -> None:
        self.pose = np.zeros(6)
        self.goal = self._random()
        self.page.evaluate(
            "(h) => { const r = window.__mimicrete.device.hands.right;"
            " r.position.set(h[0], h[1], h[2]); r.quaternion.set(h[3], h[4], h[5], h[6]); }",
            self.home,
        )


def set_pose(page: Any, pose: str) -> None:
    page.evaluate("(id) => { window.__mimicrete.device.hands.right.poseId = id; }", pose)


def counts(page: Any) -> dict[str, int]:
    return page.evaluate("window.__mimicrete.gestures.counts")


def record_class(page: Any, mover: HandMover, cls: str, until: int, max_steps: int = 4000) -> None:
    """Press the class's Record/Redo button and move the hand until it has ``until`` samples."""
    page.click(f"#gest-record-{cls}")
    page.wait_for_function("(c) => window.__mimicrete.gestures.current === c", arg=cls)
    for _ in range(max_steps):  # a bound, not a timing: each step waits for frames
        if counts(page)[cls] >= until:
            return
        mover.step()
        page.wait_for_timeout(40)  # hand frames arrive while Playwright waits
    raise AssertionError(f"{cls}: {counts(page)[cls]}/{until} samples after {max_steps} steps")


@pytest.fixture(scope="module")
def taught(tmp_path_factory) -> Iterator[dict[str, Any]]:
    """The whole session in the browser; what the page and the server showed."""
    if not (STATIC / "index.html").exists():
        pytest.fail(f"{STATIC} has no built page: run `make web`")
    out = tmp_path_factory.mktemp("mine")
    live = Live("suction", out, gestures=True, gesture_samples=PER_CLASS, seed=4)
    shipped_file = live.desk.model_status()["file"]
    seen: dict[str, Any] = {"out": out, "shipped_file": shipped_file}
    server = TeleopServer(live)
    with br.launch() as chromium, ServerThread(server) as run:
        with br.vr_page(
            chromium,
            f"http://127.0.0.1:{run.port}/?emulate=quest3&devui=0",
            viewport=(640, 720),
        ) as page:
            page.wait_for_function(
                "() => window.__mimicrete.gestures && window.__mimicrete.gestures.active"
            )
            seen["panel_visible"] = page.is_visible("#gestures")
            mover = HandMover(page, seed=3)
            # closing first with the wrong pose, paused part way, then redone with the pinch
            set_pose(page, POSES["fixed"])
            record_class(page, mover, "closing", 30)
            page.click("#gest-pause")
            page.wait_for_function("() => window.__mimicrete.gestures.current === null")
            seen["before_redo"] = counts(page)["closing"]
            # an episode cannot start in the gesture mode: the server says why
            page.click("#btn-start")
            page.wait_for_function(
                "() => window.__mimicrete.events.some((e) => e.type === 'error')"
            )
            seen["start_refused"] = next(
                e["message"]
                for e in page.evaluate("window.__mimicrete.events")
                if e["type"] == "error"
            )
            for cls, pose in POSES.items():
                set_pose(page, pose)
                page.wait_for_timeout(200)
                record_class(page, mover, cls, PER_CLASS)
            # the last class filled: the server trains by itself
            page.wait_for_function(
                "() => { const g = window.__mimicrete.gestures;"
                " return g.event === 'trained' || g.event === 'train_failed'; }",
                timeout=300_000,
            )
            page.wait_for_timeout(300)  # a HUD redraw
            seen["gestures"] = page.evaluate("window.__mimicrete.gestures")
            seen["events"] = [
                e["event"]
                for e in page.evaluate("window.__mimicrete.events")
                if e["type"] == "gestures"
            ]
            seen["accuracy_text"] = page.inner_text("#gest-accuracy")
            seen["confusion_cells"] = page.evaluate(
                "() => [...document.querySelectorAll('#gest-confusion tr')].map("
                "(r) => [...r.querySelectorAll('td')].map((c) => Number(c.textContent)))"
                ".filter((r) => r.length)"
            )
            seen["hud"] = page.inner_text("#hud")
            seen["headset"] = {
                label: value
                for label, value, _ in page.evaluate("window.__mimicrete.headsetLines()")
            }
            page.screenshot(path=str(out / "gesture_mode.png"))
            seen["frames_while_training"] = run.call(lambda: live.desk.mode.frames_while_training)
            seen["server_model"] = run.call(live.desk.model_status)
            # leave the gesture mode; the user model reads the live hand
            page.click("#btn-gestures")
            page.wait_for_function("() => !window.__mimicrete.gestures.active")
            mover.home_pose()
            read: dict[str, list[Any]] = {}
            for pose, cls in (("pinch", "closing"), ("default", "opening"), ("point", "fixed")):
                set_pose(page, pose)
                page.wait_for_function(
                    "(c) => window.__mimicrete.state && window.__mimicrete.state.gesture === c",
                    arg=cls,
                    timeout=30_000,
                )
                read[pose] = [cls, page.evaluate("window.__mimicrete.state.margin")]
            seen["read"] = read
            # an episode: pinch switches the suction on, the relaxed hand drops
            set_pose(page, "default")
            page.wait_for_function("() => window.__mimicrete.state.gesture === 'opening'")
            page.click("#btn-start")
            page.wait_for_function("() => window.__mimicrete.state.recording")
            set_pose(page, "pinch")
            page.wait_for_function(
                "() => { const s = window.__mimicrete.state; return s.recording && s.ee.on; }",
                timeout=30_000,
            )
            seen["on_with_pinch"] = page.evaluate("window.__mimicrete.state.gesture")
            set_pose(page, "default")
            page.wait_for_function(
                "() => { const s = window.__mimicrete.state; return s.recording && !s.ee.on; }",
                timeout=30_000,
            )
            page.click("#btn-stop")
            page.wait_for_function(
                "() => window.__mimicrete.events.some((e) => e.type === 'episode'"
                " && e.event === 'saved')",
                timeout=60_000,
            )
            seen["errors"] = [e for e in page.mimicrete_errors if "pageerror" in e]
    seen["saved"] = live.last_saved
    yield seen


def test_page_records_iwer_poses_trains_and_shows_held_out_accuracy(taught, figures_dir):
    out = taught["out"]
    assert taught["errors"] == []
    assert taught["panel_visible"]
    assert "gesture mode" in taught["start_refused"]
    gs = taught["gestures"]
    assert gs["event"] == "trained", gs.get("error")
    assert gs["counts"] == {c: PER_CLASS for c in POSES}
    r = gs["report"]
    print("gesture mode report:", {k: r[k] for k in ("cv_accuracy", "test_accuracy", "n_test")})
    print("confusion:", r["confusion"], "training took", r["seconds"], "s")
    # what the page shows: the held-out accuracy and the confusion matrix
    shown = float(re.search(r"held-out accuracy ([\d.]+) %", taught["accuracy_text"]).group(1))
    assert shown >= 98.0, taught["accuracy_text"]
    assert shown == pytest.approx(100 * r["test_accuracy"], abs=0.05)
    assert r["cv_accuracy"] >= 0.98
    assert taught["confusion_cells"] == r["confusion"]
    assert np.sum(r["confusion"]) == r["n_test"] == 60
    assert "held-out" in taught["hud"] and "yours" in taught["hud"]
    # in the headset (no DOM panel there) the HUD says it too
    head = taught["headset"]
    assert head["samples"] == " · ".join(f"{c} {PER_CLASS}/{PER_CLASS}" for c in POSES)
    assert head["trained"].startswith(f"held-out accuracy {shown:.1f} %")
    assert head["model"] == f"yours · {shown:.1f} % held-out"
    # the order of events the page received; training ran beside the frame loop
    ev = taught["events"]
    assert ev[-2:] == ["training", "trained"], ev
    assert ev.count("recording") == 4 and ev.count("paused") == 1  # closing twice
    assert ev.count("class_done") == 2  # the third class's last sample starts the training
    assert taught["frames_while_training"] > 0
    # files beside the demos; the server uses the model it saved
    csv, model = user_csv_path(out, "suction"), user_model_path(out, "suction")
    assert csv.exists() and model.exists() and Path(str(model) + ".json").exists()
    assert taught["server_model"]["source"] == "user"
    assert taught["server_model"]["file"] == str(model)
    side = json.loads(Path(str(model) + ".json").read_text())
    assert side["info"]["data"] == str(csv) and side["classes"] == list(POSES)
    if figures_dir is not None:  # `make figures`: the README's picture of the panel
        shutil.copy(out / "gesture_mode.png", figures_dir / "teleop_gestures.png")


def test_redo_dropped_the_wrong_samples(taught):
    """closing was first recorded with the pointing hand (30 samples), then redone with the
    pinch: every closing row of the CSV is a pinch (thumb tip on index tip)."""
    assert taught["before_redo"] >= 30
    data = g.read_gesture_csv(user_csv_path(taught["out"], "suction"))
    assert data.layout == "webxr" and set(data.handedness) == {"right"}
    closing = data.joints[data.labels == "closing"]
    assert len(closing) == PER_CLASS
    gap = np.linalg.norm(closing[:, THUMB_TIP] - closing[:, INDEX_TIP], axis=1)
    fixed = data.joints[data.labels == "fixed"]
    gap_point = np.linalg.norm(fixed[:, THUMB_TIP] - fixed[:, INDEX_TIP], axis=1)
    print("thumb-index gap: pinch max", gap.max(), "point min", gap_point.min())
    assert gap.max() < gap_point.min()
    # the hand moved and turned while the samples were taken
    assert np.ptp(data.joints[:, 0], axis=0).max() > 0.15


def test_user_model_reads_the_live_hand_and_drives_an_episode(taught):
    read = taught["read"]
    assert read["pinch"][0] == "closing" and read["default"][0] == "opening"
    assert read["point"][0] == "fixed"
    assert all(np.isfinite(m) and m > 0 for _, m in read.values()), read
    assert taught["on_with_pinch"] == "closing"
    saved = taught["saved"]
    assert saved is not None and saved["finished"] and saved["result"] == "stopped"
    meta = demos.read(saved["demo"])["meta"]
    model = user_model_path(taught["out"], "suction")
    assert meta["gesture_model_file"] == str(model)
    acc = taught["gestures"]["report"]["test_accuracy"]
    assert float(meta["gesture_model_accuracy"]) == pytest.approx(acc)
    assert meta["gesture_model"] == "svm-custom (closing/opening/fixed)"
    assert int(meta["gesture_changes"]) >= 2  # opening → closing → opening


def test_csv_round_trips_through_the_cli(taught, tmp_path, capsys):
    csv = user_csv_path(taught["out"], "suction")
    out = tmp_path / "again.joblib"
    assert cli_main(["gesture", "train", "--data", str(csv), "--out", str(out)]) == 0
    trained = capsys.readouterr().out
    again = g.load_model(out)
    assert again.layout == "webxr" and set(again.classes) == set(POSES)
    # the server trained on this CSV with the same split and grid: the same model
    server = g.load_model(user_model_path(taught["out"], "suction"))
    assert again.info["best_params"] == server.info["best_params"]
    assert again.info["test_accuracy"] == server.info["test_accuracy"]
    data = g.read_gesture_csv(csv)
    np.testing.assert_array_equal(
        again.predict(data.joints, "right"), server.predict(data.joints, "right")
    )
    assert "held-out accuracy" in trained
    for model in (out, user_model_path(taught["out"], "suction")):
        assert cli_main(["gesture", "eval", "--model", str(model), "--data", str(csv)]) == 0
        text = capsys.readouterr().out
        acc = float(re.search(r"accuracy: ([\d.]+) % on (\d+) samples", text).group(1))
        assert acc >= 98.0, text
        assert f"on {3 * PER_CLASS} samples" in text


def _start_lines(args: list[str]) -> str:
    """What ``mimicrete teleop ARGS`` prints on start (the process is ended after it)."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    proc = subprocess.Popen(
        [sys.executable, "-m", "mimicrete", "teleop", *args, "--port", str(port)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines: list[str] = []
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            lines.append(line)
            if line.startswith("open the page") or len(lines) > 50:
                break
    finally:
        proc.terminate()
        proc.wait(30)
    return "".join(lines)


def test_next_run_picks_up_the_user_model(taught, tmp_path, capsys):
    """``mimicrete teleop --out DIR`` says on start that it uses the model in DIR; a folder
    without one uses the shipped model and says how to teach it."""
    model = user_model_path(taught["out"], "suction")
    text = _start_lines(["--task", "suction", "--out", str(taught["out"])])
    assert f"gesture model: yours, {model}" in text, text
    acc = taught["gestures"]["report"]["test_accuracy"]
    assert f"{100 * acc:.2f} % held-out" in text
    # and the library does the same
    live = Live("suction", taught["out"])
    assert live.desk.model_status()["source"] == "user" and live.model.info["path"] == str(model)
    assert taught["shipped_file"] != str(model)
    fresh = _start_lines(["--task", "grip", "--out", str(tmp_path), "--gestures"])
    shipped = json.loads(SHIPPED_SIDECAR.read_text())["info"]["test_accuracy"]
    held_out = f"{100 * shipped:.2f} % held-out"
    assert f"gesture model: the shipped one (synthetic hands, {held_out})" in fresh, fresh
    assert (
        "gesture mode: record closing / opening / fixed (150 samples each) in the page; the "
        f"model is saved as {user_model_path(tmp_path, 'grip')}" in fresh
    ), fresh
    bad = ["teleop", "--task", "grip", "--out", str(tmp_path), "--gesture-samples", "5"]
    assert cli_main(bad) == 2
    assert "--gesture-samples must be in 10..5000" in capsys.readouterr().err


# ------------------------------------------------------------ the hand log says what read it

EPISODES = 3  # recorded in the page with the personal model


def _record_episode(page: Any, mover: HandMover, n_saved: int, k: int) -> None:
    """One episode in the page: start relaxed, move, pinch (suction on), move, relax (off),
    move, stop; waits until the server has saved it (``n_saved`` saved before it)."""
    set_pose(page, "default")
    page.wait_for_function("() => window.__mimicrete.state.gesture === 'opening'")
    page.click("#btn-start")
    page.wait_for_function("() => window.__mimicrete.state.recording")
    for pose, on in (("default", None), ("pinch", True), ("default", False)):
        set_pose(page, pose)
        if on is not None:
            page.wait_for_function(
                "(on) => { const s = window.__mimicrete.state; return s.recording"
                " && s.ee.on === on; }",
                arg=on,
                timeout=30_000,
            )
        for _ in range(10 + 5 * k):  # episodes of different lengths
            mover.step()
            page.wait_for_timeout(40)
    page.click("#btn-stop")
    page.wait_for_function(
        "(n) => window.__mimicrete.events.filter((e) => e.type === 'episode'"
        " && e.event === 'saved').length > n",
        arg=n_saved,
        timeout=60_000,
    )


@pytest.fixture(scope="module")
def recorded(taught) -> dict[str, Any]:
    """The next run in the folder the gesture mode trained in (``mimicrete teleop --out DIR``
    picks the personal model up) records :data:`EPISODES` more episodes in the page, the hand
    moving and turning; the saved events."""
    out = taught["out"]
    # recentred and absolute, so that the calibration the logs carry decides where the tool goes
    # (under the clutch a recentre's translation changes nothing: test_clutch.py)
    live = Live("suction", out, seed=21, mapping="absolute")
    assert live.desk.model_status()["source"] == "user"
    saved: list[dict[str, Any]] = []
    with br.launch() as chromium, ServerThread(TeleopServer(live)) as run:
        with br.vr_page(
            chromium, f"http://127.0.0.1:{run.port}/?emulate=quest3&devui=0", viewport=(480, 270)
        ) as page:
            page.wait_for_function(
                "() => { const s = window.__mimicrete.state; return s && s.target; }"
            )
            # the hand onto the tool (IWER's hand is out of the arm's reach where it starts): the
            # robot follows, and the hand logs carry this calibration, not the default
            page.click("#btn-recentre")
            page.wait_for_function(
                "() => window.__mimicrete.events.some((e) => e.type === 'calibration')",
                timeout=30_000,
            )
            calibration = run.call(lambda: live.calibration.to_dict())
            mover = HandMover(page, seed=8, reach_m=0.08, turn_deg=20.0)
            for k in range(EPISODES):
                _record_episode(page, mover, k, k)
            errors = [e for e in page.mimicrete_errors if "pageerror" in e]
            saved = [
                e
                for e in page.evaluate("window.__mimicrete.events")
                if e["type"] == "episode" and e["event"] == "saved"
            ]
    live.close()
    return {"out": out, "saved": saved, "errors": errors, "calibration": calibration}


def test_live_hand_logs_convert_with_the_personal_model_to_the_live_demos(
    taught, recorded, tmp_path
):
    """Every episode recorded live with the personal model (the gesture-mode session's and the
    next run's) names it in its hand log, and ``mimicrete convert HANDLOG`` with no option gives
    back the live demo: the same observations, actions and rewards, step for step."""
    from mimicrete.teleop import provenance as pv

    assert recorded["errors"] == []
    model = user_model_path(taught["out"], "suction")
    sha = pv.file_sha256(model)
    saved = [taught["saved"], *recorded["saved"]]
    assert len(saved) == 1 + EPISODES and all(s["finished"] for s in saved), saved
    again = tmp_path / "again"
    shipped = tmp_path / "shipped"
    differ, max_delta = 0, 0.0
    for s in saved:
        hand = Path(s["handlog"])
        extra = json.loads(hand.read_text().splitlines()[0])["extra"]
        entry = extra["gesture_model"]
        assert entry["file"] == model.name and not entry["shipped"], entry
        assert entry["sha256"] == sha and entry["classes"] == list(POSES)
        assert entry["origin"] == "user"
        argv = ["convert", str(hand), "--task", "suction", "--no-progress"]
        assert cli_main([*argv, "--out", str(again)]) == 0
        live_demo, conv = demos.load(s["demo"]), demos.load(again / Path(s["demo"]).name)
        assert len(conv.actions) == len(live_demo.actions) == s["steps"] > 0
        np.testing.assert_array_equal(conv.actions, live_demo.actions)
        np.testing.assert_array_equal(conv.rewards, live_demo.rewards)
        np.testing.assert_array_equal(conv.obs, live_demo.obs)
        if s is not taught["saved"]:  # recorded after the recentre: the arm followed the hand
            assert extra["calibration"] == recorded["calibration"]
            assert np.abs(live_demo.actions[:, :6]).max() > 0.1
        meta = demos.read(again / Path(s["demo"]).name)["meta"]
        assert meta["gesture_model_from"] == "handlog" and meta["calibration_from"] == "handlog"
        assert meta["gesture_model_sha256"] == sha
        # what the shipped model would have made of the same hand (issue 23's finding)
        with_shipped = ["--gesture-model", str(g.default_model_path("suction"))]
        assert cli_main([*argv, "--out", str(shipped), *with_shipped]) == 0
        other = demos.load(shipped / Path(s["demo"]).name)
        n = min(len(other.actions), len(live_demo.actions))
        d = np.abs(other.actions[:n] - live_demo.actions[:n]).max(initial=0.0)
        differ += bool(len(other.actions) != len(live_demo.actions) or d > 0)
        max_delta = max(max_delta, float(d))
    # the calibration matters too: the default one (not the recentred one the logs carry)
    # makes another demo of the last episode
    default = tmp_path / "default.json"
    default.write_text(json.dumps(standing_calibration().to_dict()))
    argv = ["convert", saved[-1]["handlog"], "--task", "suction", "--no-progress"]
    assert cli_main([*argv, "--out", str(tmp_path / "cal"), "--calibration", str(default)]) == 0
    other = demos.load(tmp_path / "cal" / Path(saved[-1]["demo"]).name)
    assert not np.array_equal(other.obs, demos.load(saved[-1]["demo"]).obs)
    print(
        f"{len(saved)} live episodes with the personal model: convert identical in all; "
        f"with the shipped model {differ} differ (max |Δaction| {max_delta:g})"
    )
