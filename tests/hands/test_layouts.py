"""The hand layouts Python reads from ur3-kin's table (``_native.kin_hand_layouts``) give the
published indices (OpenXR ``XrHandJointEXT``, WebXR ``XRHandJoint``, Meta OVR ``BoneId``,
MediaPipe ``HandLandmark``), and the modules that read joints by name get them."""

from __future__ import annotations

import pytest

from mimicrete.hands import layouts
from mimicrete.teleop import left_hand, protocol


def test_the_table_gives_the_published_indices():
    assert layouts.LAYOUT_JOINTS == {"openxr": 26, "webxr": 25, "meta_ovr": 24, "mediapipe": 21}
    assert layouts.FRAME_JOINTS == {
        "openxr": (1, 7, 12),
        "webxr": (0, 6, 11),
        "meta_ovr": (0, 6, 9),
        "mediapipe": (0, 5, 9),
    }
    assert layouts.WEBXR_FROM_OPENXR == tuple(range(1, 26))
    assert layouts.OVR_FROM_OPENXR[:6] == (1, -1, -1, 2, 3, 4)
    assert layouts.OVR_FROM_OPENXR[19:] == (5, 10, 15, 20, 25)  # the five tips last
    assert layouts.MEDIAPIPE_FROM_OPENXR[:9] == (1, 2, 3, 4, 5, 7, 8, 9, 10)
    assert layouts.CANONICAL21["mediapipe"] == tuple(range(21))
    assert layouts.CANONICAL21["meta_ovr"][:5] == (0, 3, 4, 5, 19)
    assert layouts.OPENXR_NAMES[:2] == ("palm", "wrist") and len(set(layouts.OPENXR_NAMES)) == 26
    assert layouts.WEBXR_JOINT_NAMES[4] == "thumb-tip"
    assert layouts.WEBXR_JOINT_NAMES[-1] == "pinky-finger-tip"
    assert layouts.JOINT_NAMES["mediapipe"][9] == "MIDDLE_FINGER_MCP"


def test_joint_index_by_name_and_its_errors():
    for layout, (w, i, m) in layouts.FRAME_JOINTS.items():
        got = [
            layouts.joint_index(layout, n) for n in ("wrist", "index_proximal", "middle_proximal")
        ]
        assert got == [w, i, m]
    assert layouts.joint_index("meta-ovr", "little_metacarpal") == 15  # Pinky0
    with pytest.raises(ValueError, match="has no palm joint"):
        layouts.joint_index("webxr", "palm")
    with pytest.raises(ValueError, match="unknown OpenXR joint 'elbow'"):
        layouts.joint_index("openxr", "elbow")
    with pytest.raises(ValueError, match="unknown hand layout"):
        layouts.joint_index("kinect", "wrist")


def test_the_left_hand_controls_and_the_wire_format_read_the_webxr_joints():
    assert (left_hand.THUMB_TIP, left_hand.INDEX_TIP) == (4, 9)
    assert left_hand.FINGERTIPS == (9, 14, 19, 24)
    assert (left_hand.WRIST, left_hand.MIDDLE_PROXIMAL) == (0, 11)
    assert protocol.JOINTS == 25 and protocol.FRAME_BYTES == 632
