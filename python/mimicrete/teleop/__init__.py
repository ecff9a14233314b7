"""Teleoperation: a tracked hand drives the UR3 and every step is recorded as a demonstration.

One per-frame path, :class:`~mimicrete.teleop.session.Session` (hand frame → gesture → smoothing →
filtered hand frame → tool0 target; control step → IK → joint action → sim step → record), run by
``convert`` over a hand-log file, by the scripted demonstrator's logs through ``convert``, and by
the live server (``mimicrete teleop``) over a WebSocket."""
