"""The effector command of an exported action: a **level**, and back to what the env takes.

A demo (MCAP) records the effector command as the env received it. The suction heads latch
(TileSuction, TileRow, TilePlace: ``action[6]`` >= 0.5 switches the suction on, <= -0.5 off,
anything between keeps it), so ``mimicrete convert`` and ``mimicrete demogen`` send a command only
on the step it switches and 0 ("keep") on every other step: 60 of the 18,653 frames of
``make demos`` are non-zero. A learner fitting that column with an L1 or diffusion loss on
mean/std-normalised actions sees a 0.3 % event and never switches the suction on.

An exported dataset (``mimicrete export``, docs/formats.md section 4) therefore carries the
effector command as a level, named ``suction_level`` / ``gripper_level`` (the layout before it
named the column ``suction_command`` / ``gripper_command`` and held the demo's command as sent):

* suction (suction, row, place): the commanded state, +1 on / -1 off, held from the step it was
  switched until the next switch, -1 before the first (the suction starts off);
* gripper (grip, screw): the fingers move only while commanded, so the demo's command is a level
  already (+1 closing, -1 opening, held as the hand showed it); the steps before the first command
  become -1 (the fingers start fully open: opening them does nothing), and a 0 later in a demo
  (the hand showed "fixed": the fingers stop where they are) stays 0;
* the screw's spin (``spin_command``, +1 / 0 / -1 while shown) is exported as recorded.

A level is itself an action the env takes: stepping the exported actions as they are gives back
the demo step for step (the export checks this on every episode). A policy's level is a float:
:func:`to_env` gives the suction its sign (> 0: +1 on, else -1 off), which in the latched
simulator is what the demo's one-step switch did; the gripper's level goes as it is (the env
closes at >= 0.5, opens at <= -0.5 and holds the fingers between).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: the action column of the effector command (every task: after the six joint motions)
EFFECTOR = 6
#: tasks whose effector is a latched suction switch; the others' is a gripper
SUCTION_TASKS = ("suction", "row", "place")
GRIPPER_TASKS = ("grip", "screw")
#: a level column's name ends with this; the layout before it named the column as below
LEVEL_SUFFIX = "_level"
SUCTION_LEVEL = "suction_level"
OLD_COMMAND_NAMES = ("suction_command", "gripper_command")
#: the two layouts, by name
LEVEL_LAYOUT = "level"
SWITCH_LAYOUT = "switch"


def to_levels(task: str, actions: np.ndarray) -> np.ndarray:
    """One demo's recorded actions (T, act_dim) with column :data:`EFFECTOR` as a level (see the
    module doc); the other columns copied. ``task``: a built-in task's short name."""
    a = np.array(actions, dtype=np.float32, copy=True)
    if a.ndim != 2 or a.shape[1] <= EFFECTOR:
        raise ValueError(f"actions of shape {a.shape}: no effector column {EFFECTOR}")
    c = a[:, EFFECTOR]
    cmd = np.where(c >= 0.5, 1.0, np.where(c <= -0.5, -1.0, 0.0)).astype(np.float32)
    steps = np.arange(len(cmd))
    last = np.maximum.accumulate(np.where(cmd != 0.0, steps, -1)) if len(cmd) else steps
    if task in SUCTION_TASKS:  # the last switch, held; off before the first
        a[:, EFFECTOR] = np.where(last >= 0, cmd[np.maximum(last, 0)], -1.0)
    elif task in GRIPPER_TASKS:  # as commanded; open before the first command
        a[:, EFFECTOR] = np.where(last >= 0, c, -1.0)
    else:
        raise ValueError(f"task {task!r}: no effector level known")
    return a


def layout_of(action_names: Sequence[str]) -> str:
    """:data:`LEVEL_LAYOUT` or :data:`SWITCH_LAYOUT` (the old one) from an exported action's
    names (LeRobot: ``info.json``'s ``features.action.names``); ValueError for neither."""
    names = list(action_names)
    if any(str(n).endswith(LEVEL_SUFFIX) for n in names):
        return LEVEL_LAYOUT
    if any(n in OLD_COMMAND_NAMES for n in names):
        return SWITCH_LAYOUT
    raise ValueError(f"action names {names}: no effector column (neither *_level nor *_command)")


def old_layout_message(where: str) -> str:
    """One line for a dataset exported in the old layout."""
    return (
        f"{where}: exported in the old action layout ('suction_command' / 'gripper_command': "
        "the effector command as a one-frame switch, 0 on every other frame); this version "
        "exports it as a level ('suction_level' / 'gripper_level', docs/formats.md section 4): "
        "export the demos again"
    )


def to_env(actions: np.ndarray, action_names: Sequence[str]) -> np.ndarray:
    """Exported-layout actions (…, act_dim), a policy's or the dataset's, as the env takes them:
    the suction's level (``suction_level``) by its sign, > 0 -> +1 and <= 0 -> -1; every other
    column unchanged (the gripper's level is what the env takes). An old-layout action has no
    ``suction_level`` and is returned unchanged: its switches are what the env took."""
    a = np.array(actions, dtype=np.float32, copy=True)
    names = list(action_names)
    if a.shape[-1] != len(names):
        raise ValueError(f"actions of width {a.shape[-1]}, {len(names)} names")
    cols = [i for i, n in enumerate(names) if n == SUCTION_LEVEL]
    if cols:
        a[..., cols] = np.where(a[..., cols] > 0.0, 1.0, -1.0)
    return a
