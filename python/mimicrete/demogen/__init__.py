"""Object-centric demo generation (MimicGen, Mandlekar et al. 2023): a few recorded demos of
TileSuction, BlockGrip, Screw or TilePlace → many successful demos at new starts (``mimicrete
demogen``).

:mod:`.segment` splits a demo at its effector switch (the suction on, the gripper closing) into an
approach + grasp segment relative to the object and the rest relative to the target (one table,
``TASKS``, says per task which switch and frames apply), and carries a segment into a new frame;
:mod:`.generator` runs the transformed segments in the simulator through the project's IK and
writes the episodes that succeed as MCAP demos.
"""

from .generator import (
    GeneratedEpisode,
    Report,
    draw_starts,
    generate,
    generate_episode,
    write_episode,
)
from .segment import (
    TASKS,
    DemoGenError,
    Segment,
    SourceDemo,
    TaskFrames,
    frame,
    load_sources,
    segment_episode,
    task_frames,
    transform_poses,
)

__all__ = [
    "DemoGenError",
    "GeneratedEpisode",
    "Report",
    "Segment",
    "SourceDemo",
    "TASKS",
    "TaskFrames",
    "draw_starts",
    "frame",
    "generate",
    "generate_episode",
    "load_sources",
    "segment_episode",
    "task_frames",
    "transform_poses",
    "write_episode",
]
