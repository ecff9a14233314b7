"""Live episodes: hand frames from the page drive a :class:`~.session.Session`; episodes are
started, stopped, discarded and saved (MCAP demo + raw hand log) here. No networking: the
server (:mod:`.server`) feeds this one frame at a time.

Between recordings a preview session (nothing recorded) lets the user see the robot follow. A
recording starts a fresh session on the next episode's seed (a new tile position) and ends by
itself on install, fall or the step limit, or when the user stops or discards it.

Episode control without controllers (:mod:`.left_hand`): a left-hand pinch (thumb tip to index
tip under 2 cm) held for 1 s starts a recording, or stops the one running; a left fist held for
1.5 s discards the one running.

The gesture side (:mod:`.gesture_desk`: the model that reads the hand, and the gesture mode that
makes the user's own, no recording meanwhile) is :attr:`Live.desk`; in the gesture mode the left
pinch records the next class (or pauses the one recording, or, once every class is full, leaves
the gesture mode). The model's file and held-out accuracy go into every demo's metadata.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import gestures as gest
from mimicrete import tasks
from mimicrete.kin import Calibration, parse_calibration

from .gesture_desk import GestureDesk
from .gesturemode import DEFAULT_PER_CLASS, GestureModeError
from .left_hand import LeftHandControl
from .protocol import FrameError, WireFrame
from .provenance import what_read
from .record import (
    LAYOUT,
    SPACE,
    DemoSink,
    Recording,
    episode_meta,
    source_keys,
    write_handlog,
)
from .session import Session, Step
from .view import HINTS, effector_state, follow_why, task_calibration, view_from_base


class Live:
    """The live state of one teleoperation server.

    Args:
        task: ``suction`` / ``grip`` / ``screw`` / ``row`` (a row's tiles each drawn in a frame
            of its own, ``tile_0`` …).
        out: folder for the demos (``TASK_NNNN.mcap``) and hand logs (``TASK_NNNN.handlog.jsonl``).
        calibration: tracking space → Base; None: ``out/calibration.json`` if saved by a
            recentre, else a standing user's scaled by the task spec's hand scale
            (:func:`.view.task_calibration`; scale 1 on the UR3).
        seed: simulator seed of the first episode (the next ones count up).
        model: gesture model (default: ``out/gesture_<task>_user.joblib`` if the gesture mode
            saved one, else the shipped one for the task).
        gestures: start in the gesture mode.
        gesture_samples: samples per class in the gesture mode.
        gesture_options: more keyword arguments of :class:`.gesturemode.GestureMode`
            (``settle_s``, ``min_interval_s``, ``grid``).
        mapping: ``clutch`` (the tool moves by the hand's motion since the clutch engaged) or
            ``absolute`` (the tool goes where the hand is, the paper's).
        task_file: a task spec file running ``task``'s logic: the episodes run in its env, the
            page draws its scene, the demos and hand logs name it (read once, here).
    """

    def __init__(
        self,
        task: str,
        out: str | Path,
        *,
        calibration: Calibration | None = None,
        seed: int = 0,
        model: gest.GestureModel | None = None,
        gestures: bool = False,
        gesture_samples: int = DEFAULT_PER_CLASS,
        gesture_options: dict[str, Any] | None = None,
        mapping: str = "clutch",
        task_file: str | None = None,
    ) -> None:
        self.task = tasks.get(task)
        #: (the spec file, the spec as read) the episodes run in; None: the built-in task
        self.spec: tuple[str, dict[str, Any]] | None = None
        if task_file is not None:
            spec_task, spec = tasks.load_task_file(task_file)
            if spec_task.name != self.task.name:
                raise ValueError(
                    f"{task_file} runs the {spec_task.name} task, not {self.task.name}"
                )
            self.spec = (str(task_file), spec)
        self.mapping = mapping  # how the hand drives the tool (teleop.session.Session)
        self.out = Path(out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.calib_path = self.out / "calibration.json"
        if calibration is None and self.calib_path.exists():
            calibration = parse_calibration(
                json.loads(self.calib_path.read_text()), str(self.calib_path), None, "calibration"
            )
        #: a standing user's, scaled by the spec's hand scale (view.task_calibration)
        self.calibration = calibration or task_calibration(task, task_file)
        self.events: list[dict[str, Any]] = []  # episode messages for the clients
        #: called from a worker thread when a save or a training has ended (the server wakes its
        #: loop to send the events and :meth:`GestureDesk.poll`); None: the next :meth:`push`
        self.notify: Callable[[], None] | None = None
        #: the gesture model in use and the gesture mode
        self.desk = GestureDesk(
            self.task,
            self.out,
            model,
            gesture_samples,
            gesture_options or {},
            self.events,
            on_model=self._model_changed,
            notify=lambda: self.notify,
        )
        self.next_index = self._first_free_index()
        self.seed = int(seed)
        self.episode: Recording | None = None
        self.last_result: str | None = None
        self._last_saved: dict[str, Any] | None = None
        # closing a demo and writing its hand log take tens of ms (more on a loaded machine): a
        # worker thread does it, so the frames of the next episode are not held up
        self._io = ThreadPoolExecutor(max_workers=1, thread_name_prefix="teleop-save")
        self._pending: list[Future[None]] = []
        #: the scene the clients were sent (a new session whose scene differs sends it again)
        self.scene: list[dict[str, Any]] | None = None
        self.preview = self._session(self.seed + self.next_index, None)
        self.left_hand = LeftHandControl()
        self._clutch: str | None = None  # engage / release, applied with the next frame
        self.last_right: np.ndarray | None = None
        #: the newest control step and the session it belongs to (:attr:`last_step`)
        self._last_step: tuple[Session, Step] | None = None
        if gestures:
            self.desk.enter()

    # ------------------------------------------------------------------ frames

    @property
    def session(self) -> Session:
        return self.episode.session if self.episode is not None else self.preview

    @property
    def recording(self) -> bool:
        return self.episode is not None

    @property
    def model(self) -> gest.GestureModel:
        """The gesture model the next session reads the hand with (:attr:`desk`'s)."""
        return self.desk.model

    def push(self, f: WireFrame, recv_ms: float | None = None) -> list[Step]:
        """One hand frame from the driving client, received at ``recv_ms`` (the server's clock;
        None: no stage times). Raises :class:`.protocol.FrameError` (``backwards``) for a frame
        whose ``t`` is before the previous one of the episode being recorded: it is not a frame
        of this episode (the hand log's times never decrease), so nothing of it is used, not even
        its left hand."""
        ep = self.episode
        if ep is not None and ep.t and f.t < ep.t[-1]:
            raise FrameError("backwards", f"frame time {f.t} before the previous {ep.t[-1]}")
        self.desk.poll()
        self._left_hand_control(f)
        if f.right_tracked:
            self.last_right = f.right
        ep = self.episode
        joints = f.right if f.right_tracked else np.zeros((25, 3))
        self.desk.push(f.t, f.right_tracked, joints)
        clutch, self._clutch = self._clutch, None
        if ep is not None:
            if clutch is not None:
                ep.clutch.append([len(ep.t), clutch])
            ep.t.append(f.t)
            ep.tracked.append(f.right_tracked)
            ep.joints.append(joints)
        s = self.session
        steps = s.push(f.t, f.right_tracked, joints, view=True, clutch=clutch)
        if steps:
            self._last_step = (s, steps[-1])
            if ep is not None and recv_ms is not None:
                idx = [st.index for st in steps]
                ep.stages.answered(f.seq, idx, f.t * 1000.0, f.sent_ms, recv_ms)
        if s.done:
            if ep is not None:
                self.stop()
            else:
                self.preview = self._session(self.seed + self.next_index, None)
        return steps

    def state_sent(self, seq: int, ms: float) -> None:
        """The state answering frame ``seq`` went out at ``ms`` (the server's clock)."""
        if self.episode is not None:
            self.episode.stages.state_sent(seq, ms)

    def acked(self, states: list[tuple[int, float]]) -> None:
        """The page's ``ack``: it received the states of frames ``seq`` at ``ms`` (its clock)."""
        if self.episode is not None:
            self.episode.stages.acked(states)

    def _left_hand_control(self, f: WireFrame) -> None:
        event = self.left_hand.update(f)
        if event == "fist" and self.recording:
            self.discard()
        elif event == "pinch":
            if self.desk.active:
                self.desk.pinch()
            elif self.recording:
                self.stop()
            else:
                self.start()

    # ------------------------------------------------------------------ episodes

    @property
    def success(self) -> str:
        """What a success is called (the spec's ``about.success``: ``installed``, ...)."""
        return str(self.spec[1]["about"]["success"]) if self.spec else self.task.success

    def start(self) -> None:
        """Begin recording the next episode (a running one is stopped and saved first); not in
        the gesture mode (:class:`GestureModeError`)."""
        if self.desk.active:
            raise GestureModeError("leave the gesture mode to record an episode")
        if self.episode is not None:
            self.stop()
        index = self.next_index
        seed = self.seed + index
        name = f"{self.task.name}_{index:04d}"
        meta = episode_meta(
            episode=index,
            task_sim=self.task.sim,
            seed=seed,
            source=None,  # the hand log is written at the end: named in the `episode` record
            model=self.model,
            layout=LAYOUT,
            space=SPACE,
            handedness="right",
            extra={
                "recorder": "mimicrete teleop",
                "calibration": self.calibration.to_dict(),
                **(tasks.task_file_meta(*self.spec) if self.spec else {}),
            },
        )
        task_file = None if self.spec is None else self.spec[0]
        sink = DemoSink(self.out / f"{name}.mcap", meta, task_file=task_file)
        hand = self.out / f"{name}.handlog.jsonl"
        read_by = what_read(self.model, self.desk.model_source, self.calibration, hand)
        self.episode = Recording(index, seed, self._session(seed, sink), sink, read_by=read_by)
        self.next_index += 1
        self.last_result = None
        self.events.append({"type": "episode", "event": "started", "index": index})

    def stop(self, result: str | None = None) -> dict[str, Any] | None:
        """End the recording and save it: the demo and the hand log (``result`` overrides the
        outcome's name, e.g. "disconnected")."""
        ep = self.episode
        if ep is None:
            return None
        self.episode = None
        s = ep.session
        s.finish()
        ep.stages.flush()
        o = s.outcome()
        if o.installed:
            res = self.success
        elif o.fell:
            res = "fell"
        elif o.truncated:
            res = "time limit"
        else:
            res = result or "stopped"
        self.last_result = res
        finished = s.done or result is None
        self._pending.append(self._io.submit(self._save, ep, res, finished))
        self.preview = self._session(self.seed + self.next_index, None)
        return {"index": ep.index, "result": res, "steps": o.steps, "finished": finished}

    def _save(self, ep: Recording, res: str, finished: bool) -> None:
        """Write the hand log and finish the demo (in the worker thread). The demo's ``episode``
        record names the hand log (:func:`.record.source_keys`) and says ``result`` and
        ``finished``. An episode cut short (a disconnect; Ctrl-C, SIGTERM or SIGHUP to the
        server) is finished all the same, so any MCAP reader opens it, and then renamed to
        ``TASK_NNNN.mcap.partial``: directory loaders leave it out of a data set."""
        s = ep.session
        name = f"{self.task.name}_{ep.index:04d}"
        demo = self.out / f"{name}.mcap"
        hand = self.out / f"{name}.handlog.jsonl"
        source = None
        if ep.t:
            write_handlog(hand, ep, self.task.name, self.mapping, self.spec)
            source = source_keys(hand, demo)
        ep.sink.close(s.installed, s.counts, {"result": res, "finished": finished}, source)
        if not finished:
            partial = Path(str(demo) + ".partial")
            os.replace(demo, partial)
            demo = partial
        saved = {
            "type": "episode",
            "event": "saved",
            "index": ep.index,
            "result": res,
            "demo": str(demo),
            "handlog": str(hand) if ep.t else None,
            "steps": s.step_index,
            "finished": finished,
        }
        self._last_saved = saved
        self.events.append(saved)
        notify = self.notify
        if notify is not None:  # the server sends it now, not with the next frame's answer
            try:
                notify()
            except RuntimeError:  # its loop has closed meanwhile
                pass

    def flush(self) -> None:
        """Wait until every stopped episode is on disk (errors of a save are raised here)."""
        pending, self._pending = self._pending, []
        for f in pending:
            f.result()

    @property
    def last_saved(self) -> dict[str, Any] | None:
        """The newest saved episode (waits for saves in progress)."""
        self.flush()
        return self._last_saved

    def discard(self) -> None:
        """End the recording without keeping anything."""
        ep = self.episode
        if ep is None:
            return
        self.episode = None
        ep.sink.discard()
        self.last_result = "discarded"
        self.events.append({"type": "episode", "event": "discarded", "index": ep.index})
        self.next_index -= 1  # the index is free again
        self.preview = self._session(self.seed + self.next_index, None)

    def clutch(self, engage: bool) -> None:
        """Engage the clutch (the hand's and the tool's poses are captured at the next frame)
        or release it (the tool stays while the hand repositions); recorded with that frame."""
        self._clutch = "engage" if engage else "release"

    def recentre(self) -> list[float] | None:
        """Shift the calibration so the right hand's current target is tool0's current position
        (the robot stays where it is); saved to ``out/calibration.json`` and used from now on.
        Not during a recording (its hand log has one calibration): returns None then, and when
        no hand has been seen yet."""
        s = self.session
        if s.target is None or self.recording:
            return None
        tool0 = np.asarray(s.snapshot()["tool0"]["t"], dtype=np.float64)
        delta = tool0 - s.target[:3, 3]
        c = self.calibration
        self.calibration = Calibration(c.rotation, c.translation + delta, c.scale, c.space)
        tmp = self.calib_path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(self.calibration.to_dict(), indent=1))
        os.replace(tmp, self.calib_path)
        s.set_calibration(self.calibration, shift=delta)
        return view_from_base(self.calibration)

    # ------------------------------------------------------------------ state out

    def state(self) -> dict[str, Any]:
        """What the page shows after a frame, from the session's view (the frames' poses from one
        FK, the simulator's snapshot, the target; taken by the frame's own call into Rust) and
        its newest control step (why the arm does not follow)."""
        s = self.session
        v = s.view if s.view is not None else s.core.view()
        snap = v["snapshot"]
        why = follow_why(s, self.last_step, self.recording)
        margin = None if s.margin is None else round(s.margin, 3)
        return {
            "type": "state",
            "frames": v["frames"],
            "ee": effector_state(self.task.name, snap),
            "gesture": s.gesture,
            "margin": margin,
            "following": why in (None, "not recording"),
            "why": why,
            "hint": HINTS.get(why),
            "engaged": s.engaged,
            "target": v["target"],
            "episode": self.episode.index if self.episode else self.next_index,
            "recording": self.recording,
            "step": s.step_index,
            "last_result": self.last_result,
            "mode": "gestures" if self.desk.active else "teleop",
        }

    @property
    def last_step(self) -> Step | None:
        """The newest control step of the current session (None before its first)."""
        if self._last_step is None or self._last_step[0] is not self.session:
            return None
        return self._last_step[1]

    def _model_changed(self) -> None:
        """Another gesture model drives: the preview takes it at once (an episode being recorded
        keeps the model its metadata names; the next one takes it)."""
        if self.episode is None:
            self.preview = self._session(self.seed + self.next_index, None)

    def close(self) -> None:
        """Wait for saves and a training in progress (their results are applied)."""
        self.flush()
        self.desk.close()

    # ------------------------------------------------------------------ internals

    def _session(self, seed: int, sink: DemoSink | None) -> Session:
        """A new session, which becomes the current one. Where its episode's scene differs from
        the one the clients have (the screw task's plate and bolt move with the seed), a
        ``scene`` message with the new entities goes out."""
        s = Session(
            self.task.name,
            LAYOUT,
            "right",
            self.calibration,
            seed,
            model=self.model,
            recorder=sink,
            mapping=self.mapping,
            task_file=None if self.spec is None else self.spec[0],
        )
        scene = s.scene_entities()
        if scene != self.scene:
            if self.scene is not None:  # the first one goes out in the hello
                self.events.append({"type": "scene", "scene": scene})
            self.scene = scene
        return s

    def _first_free_index(self) -> int:
        used = [
            int(p.name[len(self.task.name) + 1 :].split(".")[0])
            for p in self.out.glob(f"{self.task.name}_[0-9][0-9][0-9][0-9].*")
        ]
        return max(used) + 1 if used else 0
