"""The clutch (issue "a real hand works the first time", part 2) through the live server's state:
any hand orientation drives the tool from where it is, no jump at engagement, a released hand
repositions, and a live hand log with clutch commands converts back to its live demo exactly."""

from __future__ import annotations

import numpy as np
import pytest

from mimicrete import demos
from mimicrete.teleop import convert as cv
from mimicrete.teleop.live import Live
from mimicrete.teleop.view import standing_calibration
from mimicrete.testing.hand_poses import TURNS, Driver, hand_for_tool


def _hand(tool0: np.ndarray, turn) -> np.ndarray:
    return hand_for_tool(tool0, turn, standing_calibration())


@pytest.mark.parametrize("turn", TURNS, ids=[str(np.round(t.as_rotvec(), 2)) for t in TURNS])
def test_any_hand_orientation_drives_the_tool_by_the_hands_motion(tmp_path, turn):
    live = Live("suction", tmp_path / "out", calibration=standing_calibration(), seed=2)
    drive = Driver(live)
    start = drive.tool()
    here = _hand(start + np.array([0.0, 0.0, 0.15]), turn)  # 15 cm above the tool, turned
    drive.hold(here, 0.5)
    assert live.state()["engaged"]
    assert np.linalg.norm(drive.tool() - start) < 1e-3, "the arm moved at engagement"
    d = np.array([0.05, -0.03, -0.04])  # Base
    there = _hand(start + np.array([0.0, 0.0, 0.15]) + d, turn)
    drive.move(here, there, 0.6)
    drive.hold(there, 1.0)
    assert all(w is None for w in drive.why), set(drive.why)
    np.testing.assert_allclose(drive.tool() - start, d, atol=3e-3)
    live.close()


def test_a_released_hand_repositions_and_the_live_log_converts_to_its_demo(tmp_path):
    live = Live("suction", tmp_path / "out", calibration=standing_calibration(), seed=4)
    drive = Driver(live)
    live.start()
    start = drive.tool()
    a = _hand(start, TURNS[2])
    drive.hold(a, 0.4)
    b = _hand(start + np.array([0.04, 0.0, -0.05]), TURNS[2])
    drive.move(a, b, 0.5)
    drive.hold(b, 0.4)
    moved = drive.tool()
    live.clutch(False)  # release, then move the hand 20 cm away and turn it
    c = _hand(start + np.array([-0.2, 0.1, 0.1]), TURNS[5])
    drive.move(b, c, 0.6)
    drive.hold(c, 0.4)
    assert live.state()["why"] == "not engaged" and not live.state()["engaged"]
    assert live.state()["hint"].startswith("the clutch is released")
    np.testing.assert_allclose(drive.tool(), moved, atol=1e-3)
    live.clutch(True)
    drive.hold(c, 0.4)
    np.testing.assert_allclose(drive.tool(), moved, atol=1e-3)  # no jump at re-engagement
    e = _hand(start + np.array([-0.2, 0.1, 0.07]), TURNS[5])
    drive.move(c, e, 0.3)
    drive.hold(e, 0.6)
    np.testing.assert_allclose(drive.tool() - moved, [0.0, 0.0, -0.03], atol=3e-3)
    live.stop()
    saved = live.last_saved
    log = cv.load_log(saved["handlog"])
    assert log.header["extra"]["mapping"] == "clutch"
    assert [c for _, c in log.header["extra"]["clutch"]] == ["release", "engage"]
    d = demos.load(saved["demo"])
    again = cv.convert_log(saved["handlog"], "suction", tmp_path / "again")
    np.testing.assert_array_equal(again.actions, d.actions)
    np.testing.assert_array_equal(demos.load(again.out).obs, d.obs)
    # without its clutch commands the same frames make another demo: they are what made it
    del log.header["extra"]["clutch"]
    log.header["extra"]["mapping"] = "absolute"
    other = cv.convert_log(log, "suction", None, source=saved["handlog"])
    assert not np.array_equal(other.actions, d.actions)
    live.close()


def test_a_malformed_clutch_entry_is_refused_by_name(tmp_path):
    from mimicrete import LogFormatError
    from mimicrete.teleop.provenance import DrivingError, driving_of

    for extra, field in [
        ({"mapping": "teleport"}, "extra.mapping"),
        ({"mapping": "clutch", "clutch": [[5, "grab"]]}, "extra.clutch[0]"),
        ({"mapping": "clutch", "clutch": [[99, "engage"]]}, "extra.clutch[0]"),
        ({"mapping": "clutch", "clutch": {"0": "engage"}}, "extra.clutch"),
        ({"clutch": [[1, "release"]]}, "extra.clutch"),
    ]:
        with pytest.raises(
            DrivingError, match=rf"^log\.jsonl:1: {field.replace('[', '.').replace(']', '.')}"
        ) as e:
            driving_of({"extra": extra}, 10, "log.jsonl")
        assert isinstance(e.value, LogFormatError)  # bad input: `convert` exits 2
        assert (e.value.file, e.value.line, e.value.reason.split(" ")[0]) == ("log.jsonl", 1, field)
    assert driving_of({}, 10, "x") == ("absolute", {})
