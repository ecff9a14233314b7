"""``--tile-pose aruco:CAMERA``: where the tile is, from an ArUco marker on its top face seen by a
camera (OpenCV's objdetect ``ArucoDetector``, then ``solvePnPGeneric`` with IPPE_SQUARE; OpenCV is
imported here only, from the ``robot`` extra).

``CAMERA`` is what ``cv2.VideoCapture`` opens: a device index (``0``), a video file (played at its
own frame rate) or a stream URL. ``--camera-calibration FILE.json`` gives::

    {"camera_matrix": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]],
     "dist_coeffs": [k1, k2, p1, p2, k3],          # optional, zeros
     "base_from_camera": [[...4 x 4...]],           # camera frame -> the robot's Base frame (m)
     "marker": {"dictionary": "DICT_4X4_50", "id": 7, "size": 0.05}}   # black square's side, m

The marker lies centred on the tile's top face, its x axis along the tile's. A frame's pose is
refused (the last accepted one stays) when the marker is not seen, when it does not lie flat (its
normal more than :data:`MAX_TILT_DEG` from Base's z), or when the view is ambiguous: IPPE's two
solutions fit about as well (error ratio above :data:`AMBIGUITY_RATIO`) and put the tile in
different places (more than :data:`AMBIGUITY_XY` apart or :data:`AMBIGUITY_YAW_DEG` turned), both
lying flat. No accepted pose for :data:`MAX_AGE` s: the pose is stale and the run stops
(while the tile is held the source is not asked: the cups hide the marker).
"""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from .tile_pose import TilePoseError

MAX_TILT_DEG = 20.0
AMBIGUITY_RATIO = 0.6
AMBIGUITY_XY = 0.003
AMBIGUITY_YAW_DEG = 2.0
#: an accepted pose older than this (s) is stale
MAX_AGE = 0.5
#: how long the first pose may take to come after the camera opens (s)
FIRST_POSE_TIMEOUT = 3.0


def _cv2() -> Any:
    try:
        import cv2
    except ImportError as e:
        raise TilePoseError(
            f"--tile-pose aruco: OpenCV is missing: pip install 'mimicrete[robot]' ({e})"
        ) from None
    return cv2


class Calibration:
    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        where = f"--camera-calibration {self.path}"
        try:
            d = json.loads(self.path.read_text(encoding="utf-8"))
        except OSError as e:
            raise TilePoseError(f"{where}: {e.strerror or e}") from None
        except ValueError as e:
            raise TilePoseError(f"{where}: not JSON ({e})") from None
        if not isinstance(d, dict):
            raise TilePoseError(f"{where}: expected a JSON object")
        self.K = _matrix(d, "camera_matrix", (3, 3), where)
        dist = d.get("dist_coeffs", [0.0] * 5)
        self.dist = _matrix({"dist_coeffs": dist}, "dist_coeffs", None, where).reshape(-1)
        self.base_from_camera = _matrix(d, "base_from_camera", (4, 4), where)
        R = self.base_from_camera[:3, :3]
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-4) or np.linalg.det(R) < 0:
            raise TilePoseError(f"{where}: field 'base_from_camera' is not a rigid transform")
        m = d.get("marker")
        if not isinstance(m, dict):
            raise TilePoseError(f"{where}: field 'marker' must be an object")
        self.dictionary = str(m.get("dictionary", "DICT_4X4_50"))
        mid, size = m.get("id"), m.get("size")
        if isinstance(mid, bool) or not isinstance(mid, int) or mid < 0:
            raise TilePoseError(f"{where}: field 'marker.id' must be an integer >= 0")
        if isinstance(size, bool) or not isinstance(size, int | float) or not 0 < size < 1:
            raise TilePoseError(f"{where}: field 'marker.size' must be in (0, 1) m")
        self.marker_id, self.size = int(mid), float(size)


def _matrix(d: dict, key: str, shape: tuple[int, int] | None, where: str) -> np.ndarray:
    try:
        a = np.asarray(d[key], np.float64)
    except KeyError:
        raise TilePoseError(f"{where}: field {key!r} is missing") from None
    except (TypeError, ValueError):
        raise TilePoseError(f"{where}: field {key!r} must be numbers") from None
    if (shape is not None and a.shape != shape) or not np.all(np.isfinite(a)):
        want = "x".join(map(str, shape)) if shape else "finite"
        raise TilePoseError(f"{where}: field {key!r} must be {want} finite numbers")
    return a


class MarkerPose:
    """One frame's marker pose estimate, judged: x, y, yaw of the tile (Base) or why refused."""

    def __init__(self, cal: Calibration) -> None:
        cv2 = _cv2()
        self.cv2 = cv2
        self.cal = cal
        try:
            dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, cal.dictionary))
        except AttributeError:
            raise TilePoseError(
                f"--camera-calibration {cal.path}: unknown marker dictionary {cal.dictionary!r}"
            ) from None
        self.detector = cv2.aruco.ArucoDetector(dictionary, cv2.aruco.DetectorParameters())
        h = cal.size / 2
        self.object_points = np.array(
            [[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]], np.float64
        )

    def estimate(self, frame: np.ndarray) -> tuple[tuple[float, float, float] | None, str]:
        cv2 = self.cv2
        gray = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        corners, ids, _ = self.detector.detectMarkers(gray)
        if ids is None or self.cal.marker_id not in ids.reshape(-1).tolist():
            return None, "marker not seen"
        k = ids.reshape(-1).tolist().index(self.cal.marker_id)
        img = np.asarray(corners[k], np.float64).reshape(4, 2)
        n, rvecs, tvecs, errs = cv2.solvePnPGeneric(
            self.object_points, img, self.cal.K, self.cal.dist, flags=cv2.SOLVEPNP_IPPE_SQUARE
        )
        if n == 0:
            return None, "no pose fits the marker"
        errs = np.asarray(errs, np.float64).reshape(-1)
        cands = [self._tile_pose(r, t) for r, t in zip(rvecs, tvecs, strict=False)]
        return judge(cands, errs)

    def _tile_pose(self, rvec: np.ndarray, tvec: np.ndarray) -> tuple[float, float, float, float]:
        R, _ = self.cv2.Rodrigues(rvec)
        cam_from_marker = np.eye(4)
        cam_from_marker[:3, :3], cam_from_marker[:3, 3] = R, np.asarray(tvec).reshape(3)
        T = self.cal.base_from_camera @ cam_from_marker
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, T[2, 2]))))
        yaw = math.atan2(T[1, 0], T[0, 0])
        return float(T[0, 3]), float(T[1, 3]), yaw, tilt


def judge(
    cands: list[tuple[float, float, float, float]], errs: np.ndarray
) -> tuple[tuple[float, float, float] | None, str]:
    """Pick IPPE's solution (x, y, yaw, tilt_deg each; their reprojection errors ``errs``, best
    first) or say why the frame is refused."""
    flat = [i for i, c in enumerate(cands) if c[3] <= MAX_TILT_DEG]
    if not flat:
        return None, f"marker not lying flat (tilted {min(c[3] for c in cands):.0f} deg)"
    best = min(flat, key=lambda i: errs[i])
    others = [i for i in flat if i != best]
    for i in others:
        ratio = errs[best] / max(errs[i], 1e-12)
        a, b = cands[best], cands[i]
        dyaw = abs((a[2] - b[2] + math.pi) % (2 * math.pi) - math.pi)
        apart = math.hypot(a[0] - b[0], a[1] - b[1]) > AMBIGUITY_XY
        if ratio > AMBIGUITY_RATIO and (apart or math.degrees(dyaw) > AMBIGUITY_YAW_DEG):
            return None, f"ambiguous pose (two fits, error ratio {ratio:.2f})"
    x, y, yaw, _ = cands[best]
    return (x, y, yaw), "ok"


class ArucoTilePose:
    """The tile pose source: a thread reads the camera and keeps the newest accepted pose."""

    def __init__(self, camera: str, calibration: str | Path | None) -> None:
        if calibration is None:
            raise TilePoseError("--tile-pose aruco: needs --camera-calibration FILE.json")
        cv2 = _cv2()
        self.cal = Calibration(calibration)
        self.marker = MarkerPose(self.cal)
        self.label = f"aruco:{camera}"
        self.version = 0
        self.refused: dict[str, int] = {}
        src: Any = int(camera) if camera.isdigit() else camera
        self.cap = cv2.VideoCapture(src)
        if not self.cap.isOpened():
            raise TilePoseError(f"--tile-pose aruco:{camera}: the camera does not open")
        fps = self.cap.get(cv2.CAP_PROP_FPS) if isinstance(src, str) else 0.0
        self._frame_period = 1.0 / fps if fps and Path(camera).is_file() else 0.0
        self._lock = threading.Lock()
        self._pose: tuple[float, float, float] | None = None
        self._at = 0.0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name="aruco")
        self._thread.start()
        end = time.monotonic() + FIRST_POSE_TIMEOUT
        while self._pose is None and time.monotonic() < end and self._thread.is_alive():
            time.sleep(0.01)
        if self._pose is None:
            self.close()
            why = (
                max(self.refused.items(), key=lambda kv: kv[1])[0] if self.refused else "no frames"
            )
            raise TilePoseError(
                f"--tile-pose aruco:{camera}: no accepted marker pose within "
                f"{FIRST_POSE_TIMEOUT:.0f} s ({why})"
            )

    def _run(self) -> None:
        next_t = time.monotonic()
        while not self._stop.is_set():
            ok, frame = self.cap.read()
            at = time.monotonic()
            if not ok:
                return  # the stream ended: the pose goes stale
            pose, why = self.marker.estimate(frame)
            with self._lock:
                if pose is None:
                    self.refused[why] = self.refused.get(why, 0) + 1
                else:
                    self._pose, self._at = pose, at
                    self.version += 1
            if self._frame_period:
                next_t += self._frame_period
                delay = next_t - time.monotonic()
                if delay > 0:
                    time.sleep(delay)

    def pose(self) -> tuple[float, float, float]:
        with self._lock:
            pose, age = self._pose, time.monotonic() - self._at
        if pose is None or age > MAX_AGE:
            raise TilePoseError(
                f"{self.label}: stale: no accepted marker pose for {1000 * age:.0f} ms "
                f"(at most {1000 * MAX_AGE:.0f})"
            )
        return pose

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)
        self.cap.release()
