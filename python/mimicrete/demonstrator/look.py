"""What the person sees during an episode: the one look the scripted person takes after the start.

A tile set down to a tiler's few millimetres and 2° is set down by eye: before the last
centimetre the person looks at the held tile over its pad and, while setting it down, moves the
hand by the tile's offset from its target and turns it by the tile's turn from square to the pad
(TilePlace, :data:`BY_EYE`). Everything before that look is planned open loop from the start's
scene (:mod:`.scene`), and so is everything after it but that correction.

What the person sees is handed in (``see``, :data:`Seer`): the commands pass
:func:`mimicrete.teleop.look.offset_seen`, the hand frames up to the look run through the
teleoperation session exactly as ``mimicrete convert`` will run them. Without it (``see=None``)
the person sets the object down without looking. Why the look was added: in tile-sim as first
written a tile sealed 1 mm off the cups' centre drifted to about 6 mm off in ten seconds held
still (the lips now stick and slip: it stays at 1 mm), and without the look 30 of 40 scripted
placements (``synth-hands --task place --seed 0``, converted) were placed, the other 10 let go
5-12 mm off the target's centre; with it 179 of 180 (seeds 0-2, 60 each), and 59 of 60 with the
physics of 1aed13b (``make demos-place``). A person setting a tile down looks at it anyway.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: The tasks whose person sets the object down by eye, and the phase it is set down in
#: (:meth:`.motion.Motion.set_down`; the look is taken as it starts).
BY_EYE: dict[str, str] = {"place": "set_down"}
#: How well the person judges the object's offset from its target by eye: the standard deviation
#: of the error on each horizontal axis (mm) and of its turn (degrees), the edges of a tile
#: against a pad's seen from a step away.
EYE_MM = 1.0
EYE_DEG = 0.3

#: What the person sees: ``see(task, seed, t, tracked, joints, layout, handedness, calib,
#: task_file)`` → the target's centre minus the object's (x, y, m) and the turn that squares the
#: object (rad) after the hand frames so far (:func:`mimicrete.teleop.look.offset_seen`).
Seer = Callable[..., np.ndarray]
