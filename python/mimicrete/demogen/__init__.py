"""Object-centric demo generation (MimicGen, Mandlekar et al. 2023): a few recorded TileSuction
demos → many installing demos at new starts (``mimicrete demogen``).

:mod:`.segment` splits a demo at its effector switch into an approach + grasp segment relative
to the tile and a transport + place segment relative to the target, and carries a segment into a
new frame; :mod:`.generator` runs the transformed segments in the simulator through the project's
IK and writes the episodes that install as MCAP demos.
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
    DemoGenError,
    Segment,
    SourceDemo,
    frame,
    load_sources,
    segment_episode,
    transform_poses,
)

__all__ = [
    "DemoGenError",
    "GeneratedEpisode",
    "Report",
    "Segment",
    "SourceDemo",
    "draw_starts",
    "frame",
    "generate",
    "generate_episode",
    "load_sources",
    "segment_episode",
    "transform_poses",
    "write_episode",
]
