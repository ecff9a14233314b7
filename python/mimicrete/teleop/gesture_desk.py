"""The gesture side of a live server: which model reads the hand, and the gesture mode that
makes the user's own (:class:`~.gesturemode.GestureMode` collects the samples and trains).

The model is, in this order: the one given, the user's own in ``out/gesture_<task>_user.joblib``,
the shipped one. A model the gesture mode trains drives from then on; :class:`~.live.Live` is told
through ``on_model`` so its next session reads the hand with it. Every change the page should see
goes into ``events`` as a ``gestures`` message (docs/formats.md §3).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from mimicrete import gestures as gest
from mimicrete.tasks import TaskSpec

from .gesturemode import (
    GestureMode,
    GestureModeError,
    check_per_class,
    task_classes,
    task_prompts,
    user_model_path,
)


class GestureDesk:
    """The gesture model in use and the gesture mode of one live server.

    Args:
        task: the task (its gesture classes).
        out: the server's output folder (the user's model is saved there).
        model: a model to use (None: the user's own if saved, else the shipped one).
        per_class: samples per class in the gesture mode.
        options: more keyword arguments of :class:`GestureMode`.
        events: where the ``gestures`` messages for the clients go (the server's list).
        on_model: called when another model drives (a training ended, or :meth:`set_model`).
        notify: returns the server's wake-up call (or None) when a training ends in its thread.
    """

    def __init__(
        self,
        task: TaskSpec,
        out: Path,
        model: gest.GestureModel | None,
        per_class: int,
        options: dict[str, Any],
        events: list[dict[str, Any]],
        on_model: Callable[[], None],
        notify: Callable[[], Callable[[], None] | None],
    ) -> None:
        self.task = task
        self.out = out
        self.model, self.model_source = self._pick_model(model)
        self.mode: GestureMode | None = None  # its samples stay while episodes record between
        self.active = False
        self._per_class = check_per_class(per_class)
        self._options = dict(options)
        self._events = events
        self._on_model = on_model
        self._notify = notify

    # ------------------------------------------------------------------ the model

    def _pick_model(self, given: gest.GestureModel | None) -> tuple[gest.GestureModel, str]:
        """The model in use and where it comes from (``given`` / ``user`` / ``shipped``); its
        ``info["path"]`` names its file (the demos' metadata quote it)."""
        if given is not None:
            return given, "given"
        path = user_model_path(self.out, self.task.name)
        if path.exists():
            want = set(task_classes(self.task.name))
            try:
                m = gest.load_model(path)
                if set(m.classes) != want:
                    raise ValueError(f"classes {m.classes}, the task needs {sorted(want)}")
            except (OSError, ValueError, KeyError, EOFError) as e:
                warnings.warn(
                    f"{path}: not used ({e}); the shipped gesture model drives. Record your "
                    "gestures again with `mimicrete teleop --gestures`",
                    RuntimeWarning,
                    stacklevel=4,
                )
            else:
                m.info["path"] = str(path)
                return m, "user"
        m = gest.load_default(self.task.name)
        m.info.setdefault("path", str(gest.default_model_path(self.task.name)))
        return m, "shipped"

    def model_status(self) -> dict[str, Any]:
        """The gesture model in use, for the page: ``file``, ``source`` (``given`` / ``user`` /
        ``shipped``), ``kind``, ``classes``, ``test_accuracy``, ``cv_accuracy``."""
        i = self.model.info
        return {
            "file": i.get("path"),
            "source": self.model_source,
            "kind": self.model.kind,
            "classes": list(self.model.classes),
            "test_accuracy": i.get("test_accuracy"),
            "cv_accuracy": i.get("cv_accuracy"),
        }

    def set_model(self, model: gest.GestureModel, source: str) -> None:
        """Read the hand with ``model`` from the next session on (an episode being recorded keeps
        the model its metadata names)."""
        self.model, self.model_source = model, source
        self._on_model()

    # ------------------------------------------------------------------ the gesture mode

    def enter(self, per_class: int | None = None, recording: bool = False) -> None:
        """Switch to the gesture mode (not while an episode records)."""
        if recording:
            raise GestureModeError("stop the episode before the gesture mode")
        if self.mode is None:
            opts = {"per_class": per_class or self._per_class, **self._options}
            self.mode = GestureMode(self.task.name, self.out, **opts)
        elif per_class is not None:
            self.mode.per_class = check_per_class(per_class)
        self.active = True
        self._event("entered")

    def exit(self) -> None:
        """Back to recording demonstrations (the samples stay; a training goes on)."""
        if self.mode is not None:
            self.mode.pause()
        self.active = False
        self._event("exited")

    def record(self, label: str | None = None) -> str:
        """Record (or redo) a class, default the next one that is not full."""
        label = self._mode().record(label)
        self._event("recording")
        return label

    def pause(self) -> None:
        self._mode().pause()
        self._event("paused")

    def train(self) -> None:
        """Train on the samples in the worker thread; :meth:`poll` applies the result."""
        future = self._mode().train()
        notify = self._notify()
        if notify is not None:
            future.add_done_callback(lambda _: notify())
        self._event("training")

    def poll(self) -> None:
        """Apply a training that has ended (on the caller's thread): the new model drives, and a
        ``trained`` (or ``train_failed``) event goes to the clients."""
        gm = self.mode
        if gm is None or not gm.training:
            return
        model, error = gm.finished()
        if model is not None:
            self.set_model(model, "user")
            self._event("trained")
        elif error is not None:
            self._event("train_failed")

    def push(self, t: float, tracked: bool, joints: np.ndarray) -> None:
        """One right-hand frame in the gesture mode: a sample of the class recording; once every
        class is full, the training starts (the page shows it)."""
        gm = self.mode
        if not self.active or gm is None:
            return
        took = gm.push(t, tracked, joints)
        if took == "class_done" and gm.next_class() is None:
            try:
                self.train()
            except GestureModeError as e:  # one is running (a class was redone meanwhile)
                self._event(took)
                self._events.append({"type": "error", "message": f"gestures: {e}"})
        elif took is not None:
            self._event("progress" if took == "sample" else took)

    def pinch(self) -> None:
        """Left pinch held in the gesture mode: pause the class recording, else record the next
        class, else (every class full, trained or training) leave the gesture mode."""
        gm = self._mode()
        if gm.current is not None:
            self.pause()
        elif gm.next_class() is not None:
            self.record()
        else:
            self.exit()

    def status(self, event: str = "status") -> dict[str, Any]:
        """The ``gestures`` message: the mode's state (empty counts before it was entered)."""
        if self.mode is not None:
            body = self.mode.status()
        else:
            classes = task_classes(self.task.name)
            body = {
                "task": self.task.name,
                "classes": list(classes),
                "prompts": {
                    c: {"meaning": m, "try": t}
                    for c, (m, t) in task_prompts(self.task.name).items()
                },
                "target": self._per_class,
                "counts": {c: 0 for c in classes},
                "current": None,
                "next": classes[0],
                "training": False,
                "report": None,
                "error": None,
            }
        return {
            "type": "gestures",
            "event": event,
            "active": self.active,
            **body,
            "model": self.model_status(),
        }

    def close(self) -> None:
        """Wait for a training in progress (its result is applied)."""
        if self.mode is not None:
            self.mode.close()
            self.poll()

    def _mode(self) -> GestureMode:
        if not self.active or self.mode is None:
            raise GestureModeError("not in the gesture mode")
        return self.mode

    def _event(self, event: str) -> None:
        self._events.append(self.status(event))
