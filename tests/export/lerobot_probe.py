"""Run by tests/export/test_lerobot.py in the lerobot venv (.venv-export): load a dataset with
lerobot's own LeRobotDataset and print what the test compares, as one JSON object.

    HF_HUB_OFFLINE=1 .venv-export/bin/python tests/export/lerobot_probe.py ROOT
"""

from __future__ import annotations

import json
import sys

import numpy as np
from lerobot.datasets.lerobot_dataset import CODEBASE_VERSION, LeRobotDataset


def main(root: str) -> None:
    ds = LeRobotDataset("local/mimicrete-export-test", root=root)
    # A policy's view: the current action and the next two (lerobot pads past the episode end).
    chunked = LeRobotDataset(
        "local/mimicrete-export-test", root=root, delta_timestamps={"action": [0.0, 0.04, 0.08]}
    )
    first, last = ds[0], ds[len(ds) - 1]
    ep0 = ds.meta.episodes[0]
    ends = [int(ds.meta.episodes[i]["dataset_to_index"]) - 1 for i in range(ds.num_episodes)]
    last_chunk = chunked[ends[0]]
    out = {
        "codebase_version": CODEBASE_VERSION,
        "num_frames": ds.num_frames,
        "num_episodes": ds.num_episodes,
        "fps": ds.fps,
        "features": sorted(ds.features),
        "first_action": first["action"].numpy().tolist(),
        "last_action": last["action"].numpy().tolist(),
        "first_state": first["observation.state"].numpy().tolist(),
        "first_task": first["task"],
        "last_timestamp": float(last["timestamp"]),
        "last_frame_index": int(last["frame_index"]),
        "done_at_ends": [bool(ds[i]["next.done"]) for i in ends],
        "success_at_ends": [bool(ds[i]["next.success"]) for i in ends],
        "episode_lengths": [int(ds.meta.episodes[i]["length"]) for i in range(ds.num_episodes)],
        "episode0_seed": int(ep0["mimicrete/seed"]),
        "episode0_source_demo": ep0["mimicrete/source_demo"],
        "chunk_at_end_pad": last_chunk["action_is_pad"].numpy().tolist(),
        "chunk_at_end_action0": last_chunk["action"][0].numpy().tolist(),
        "stats_action_mean": np.asarray(ds.meta.stats["action"]["mean"]).tolist(),
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1])
