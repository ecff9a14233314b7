"""A live hand log says what read it (issue 23, part 3): its header names the gesture model (file
relative to the log's folder, SHA-256, classes) and the calibration; ``mimicrete convert`` of it
uses both by default and gives the live demo back step for step; a missing or changed model is
refused by name (exit 2, no traceback); explicit options override and the demo says which was
used; a hand log without them (older, offline) converts as before."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from mimicrete import demonstrator as sy
from mimicrete import demos
from mimicrete import gestures as g
from mimicrete.cli import main as cli_main
from mimicrete.hands import log as handlog
from mimicrete.kin import Calibration
from mimicrete.teleop import convert as cv
from mimicrete.teleop import provenance as pv
from mimicrete.teleop.gesturemode import user_model_path
from mimicrete.teleop.live import Live
from mimicrete.teleop.protocol import WireFrame

SHIPPED = g.default_model_path("suction")


def _frames(log: handlog.HandLogData) -> list[WireFrame]:
    """The log's right hand as the page sends it (no left hand)."""
    none = np.zeros((25, 3))
    return [
        WireFrame(k, float(log.t[k]), 0.0, bool(log.tracked[k]), False, log.joints[k], none)
        for k in range(len(log))
    ]


def _live_episode(folder: Path, model_file: Path | None, seed: int = 3) -> tuple[Live, dict]:
    """One synthetic suction episode recorded live into ``folder/out``, read by the model saved
    as the user's (a copy of ``model_file``; None: the shipped one)."""
    log = cv.load_log(sy.synth_hands("suction", 1, seed, folder / "hands", layout="webxr")[0])
    out = folder / "out"
    if model_file is not None:
        user = user_model_path(out, "suction")
        user.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(model_file, user)
        shutil.copy(str(model_file) + ".json", str(user) + ".json")
    cal = cv.calibration_of(log)
    live = Live("suction", out, calibration=cal, seed=int(log.header["episode_seed"]))
    live.start()
    for f in _frames(log):
        live.push(f)
        if not live.recording:
            break
    live.stop()
    live.close()
    saved = live.last_saved
    assert saved is not None and saved["handlog"], saved
    return live, saved


def _same_demo(a: str | Path, b: str | Path) -> None:
    x, y = demos.load(a), demos.load(b)
    assert len(x.actions) == len(y.actions) > 0
    np.testing.assert_array_equal(x.actions, y.actions)
    np.testing.assert_array_equal(x.rewards, y.rewards)
    np.testing.assert_array_equal(x.obs, y.obs)


@pytest.fixture(scope="module")
def user_live(tmp_path_factory) -> tuple[Live, dict]:
    """A live episode read by a personal model (the grip model saved as the user's: another file
    than the shipped one, beside the demos)."""
    return _live_episode(tmp_path_factory.mktemp("user"), SHIPPED)


def test_live_hand_log_names_its_model_and_calibration(user_live):
    live, saved = user_live
    hand = Path(saved["handlog"])
    header = cv.load_log(hand).header
    entry = header["extra"]["gesture_model"]
    user = user_model_path(live.out, "suction")
    assert entry == {
        "file": user.name,  # relative to the hand log's folder
        "shipped": False,
        "sha256": pv.file_sha256(user),
        "classes": list(live.model.classes),
        "kind": "per-frame",
        "origin": "user",
    }
    assert Calibration.from_dict(header["extra"]["calibration"]).to_dict() == (
        live.calibration.to_dict()
    )


def test_convert_uses_the_logged_model_and_gives_the_live_demo_back(user_live, tmp_path):
    live, saved = user_live
    # the folder moves: the model is found beside the hand log
    moved = tmp_path / "moved"
    shutil.copytree(live.out, moved)
    hand = moved / Path(saved["handlog"]).name
    res = cv.convert_log(hand, "suction", tmp_path / "again")
    _same_demo(saved["demo"], res.out)
    meta = demos.read(res.out)["meta"]
    assert meta["gesture_model_from"] == "handlog" and meta["calibration_from"] == "handlog"
    assert meta["gesture_model_file"] == str(user_model_path(moved, "suction").resolve())
    assert meta["gesture_model_sha256"] == pv.file_sha256(user_model_path(moved, "suction"))
    # explicit options override, and the demo says so
    cal = Calibration.from_dict(json.loads(json.dumps(live.calibration.to_dict())))
    over = cv.convert_log(
        hand, "suction", tmp_path / "over", model=g.load_model(SHIPPED), calibration=cal
    )
    meta = demos.read(over.out)["meta"]
    assert meta["gesture_model_from"] == "given" and meta["calibration_from"] == "given"


def test_the_model_that_read_the_hand_is_the_one_used(tmp_path):
    """A personal model that reads the hand otherwise than the shipped one (here the shipped
    model with closing and opening exchanged): the live episode never picks, its hand log
    converts to exactly that demo, and the shipped model would have made another one."""
    m = g.load_model(SHIPPED)
    svc = m.pipeline[-1]
    swap = {"closing": "opening", "opening": "closing"}
    svc.classes_ = np.array([swap.get(str(c), str(c)) for c in svc.classes_], dtype=object)
    m._fast = None
    swapped = m.save(tmp_path / "model" / "swapped.joblib")
    live, saved = _live_episode(tmp_path, swapped)
    assert saved["result"] != "installed"
    res = cv.convert_log(saved["handlog"], "suction", tmp_path / "again")
    _same_demo(saved["demo"], res.out)
    other = cv.convert_log(saved["handlog"], "suction", None, model=g.load_model(SHIPPED))
    assert other.installed and not res.installed


def test_shipped_model_is_named_by_its_shipped_file(tmp_path):
    _, saved = _live_episode(tmp_path, None)
    entry = cv.load_log(saved["handlog"]).header["extra"]["gesture_model"]
    assert entry["file"] == SHIPPED.name and entry["shipped"] and entry["origin"] == "shipped"
    assert entry["sha256"] == pv.file_sha256(SHIPPED)
    res = cv.convert_log(saved["handlog"], "suction", tmp_path / "again")
    _same_demo(saved["demo"], res.out)
    assert demos.read(res.out)["meta"]["gesture_model_from"] == "handlog"


def test_older_hand_logs_keep_the_shipped_model(tmp_path):
    path = sy.synth_hands("suction", 1, 3, tmp_path / "hands", layout="webxr")[0]
    assert "gesture_model" not in (cv.load_log(path).header.get("extra") or {})
    res = cv.convert_log(path, "suction", tmp_path / "demos")
    meta = demos.read(res.out)["meta"]
    assert meta["gesture_model_from"] == "default"
    assert meta["gesture_model_file"] == str(SHIPPED)
    assert meta["calibration_from"] == "handlog"  # the synthetic demonstrator writes one


def _convert_cli(hand: Path, out: Path, *more: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "mimicrete", "convert", str(hand), "--task", "suction"]
        + ["--out", str(out), "--no-progress", *more],
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_cli_refuses_a_missing_model_by_name(user_live, tmp_path):
    live, saved = user_live
    folder = tmp_path / "copy"
    shutil.copytree(live.out, folder)
    hand = folder / Path(saved["handlog"]).name
    model = user_model_path(folder, "suction")
    model.unlink()
    r = _convert_cli(hand, tmp_path / "demos")
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith(f"mimicrete convert: error: {hand}: its gesture model {model}")
    assert "is missing" in line and "--gesture-model" in line, line
    assert not list((tmp_path / "demos").glob("*.mcap"))
    # --gesture-model reads it with another model
    r = _convert_cli(hand, tmp_path / "demos", "--gesture-model", str(SHIPPED))
    assert r.returncode == 0, r.stderr
    meta = demos.read(tmp_path / "demos" / "suction_0000.mcap")["meta"]
    assert meta["gesture_model_from"] == "given"


def test_cli_refuses_a_changed_model(user_live, tmp_path):
    live, saved = user_live
    folder = tmp_path / "copy"
    shutil.copytree(live.out, folder)
    hand = folder / Path(saved["handlog"]).name
    model = user_model_path(folder, "suction")
    want = pv.file_sha256(model)
    shutil.copy(g.default_model_path("screw"), model)  # a new training replaced it
    r = _convert_cli(hand, tmp_path / "demos")
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    line = r.stderr.strip().splitlines()[-1]
    assert line.startswith(f"mimicrete convert: error: {hand}: its gesture model {model} is not")
    assert f"SHA-256 {pv.file_sha256(model)}, the hand log says {want}" in line, line
    assert not list((tmp_path / "demos").glob("*.mcap"))


@pytest.mark.parametrize(
    ("entry", "match"),
    [
        ("x", r"extra.gesture_model must be an object"),
        ({"file": None, "sha256": None, "classes": ["a"]}, r"was no file"),
        ({"file": "m.joblib", "sha256": "abc", "classes": ["a"]}, r"64 lower-case hex"),
        ({"file": "m.joblib", "sha256": "0" * 64, "classes": []}, r"classes must be a list"),
    ],
)
def test_malformed_entries_are_refused(tmp_path, entry, match):
    with pytest.raises(pv.ModelFileError, match=match):
        pv.model_of({"extra": {"gesture_model": entry}}, tmp_path / "h.jsonl")


def test_other_classes_are_refused(tmp_path):
    entry = {"file": SHIPPED.name, "shipped": True, "sha256": pv.file_sha256(SHIPPED)}
    entry["classes"] = ["a", "b", "c"]
    with pytest.raises(pv.ModelFileError, match=r"has classes \['closing'"):
        pv.model_of({"extra": {"gesture_model": entry}}, tmp_path / "h.jsonl")


def test_cli_calibration_option_overrides(user_live, tmp_path, capsys):
    live, saved = user_live
    cal = tmp_path / "cal.json"
    c = live.calibration
    moved = Calibration(c.rotation, c.translation + [0.0, 0.0, 0.05], c.scale, c.space)
    cal.write_text(json.dumps(moved.to_dict()))
    argv = ["convert", saved["handlog"], "--task", "suction", "--no-progress"]
    assert cli_main([*argv, "--out", str(tmp_path / "a"), "--calibration", str(cal)]) == 0
    meta = demos.read(tmp_path / "a" / Path(saved["demo"]).name)["meta"]
    assert meta["calibration_from"] == "given"
    logged = meta["calibration"]  # nested extra values are stored as JSON text
    logged = json.loads(logged) if isinstance(logged, str) else logged
    np.testing.assert_allclose(logged["translation"], moved.translation)
    bad = tmp_path / "bad.json"
    bad.write_text('{"rotation": 1}')
    assert cli_main([*argv, "--out", str(tmp_path / "b"), "--calibration", str(bad)]) == 2
    assert f"--calibration {bad}: " in capsys.readouterr().err


def test_docs_list_every_field_written(user_live):
    """docs/formats.md §1 documents each field of ``extra.gesture_model`` a live log has."""
    _, saved = user_live
    docs = (Path(__file__).resolve().parents[2] / "docs" / "formats.md").read_text()
    entry = cv.load_log(saved["handlog"]).header["extra"]
    assert "| `extra.calibration` |" in docs
    for key in entry["gesture_model"]:
        assert f"| `extra.gesture_model.{key}` |" in docs, key
