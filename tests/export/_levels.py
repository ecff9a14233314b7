"""What an exported action should hold, computed here step by step (not by the exporter's code):
the demo's actions with the effector command (column 6) as a level. Suction: the commanded state,
+1 / -1, held from its switch until the next one, -1 before the first. Gripper: the command as
recorded, -1 before the first one."""

from __future__ import annotations

import numpy as np


def expected_levels(actions: np.ndarray, task: str = "suction") -> np.ndarray:
    """One episode's recorded actions -> the exported ones."""
    out = np.array(actions, dtype=np.float32, copy=True)
    state = -1.0
    commanded = False
    for k in range(len(out)):
        cmd = float(actions[k][6])
        commanded = commanded or abs(cmd) >= 0.5
        if task in ("grip", "screw"):
            out[k, 6] = cmd if commanded else -1.0
            continue
        if cmd >= 0.5:
            state = 1.0
        elif cmd <= -0.5:
            state = -1.0
        out[k, 6] = state
    return out


def expected_actions(d, task: str = "suction") -> np.ndarray:
    """A :class:`mimicrete.demos.Demos`' actions as exported, episode by episode."""
    return np.concatenate([expected_levels(d.actions[s], task) for s in d.episode_slices()])
