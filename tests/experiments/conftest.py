"""Fixtures the experiment harness tests share."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="module")
def one_demo(tmp_path_factory) -> Path:
    """One scripted TileSuction hand demonstration converted into an MCAP demo (a folder)."""
    from mimicrete import demonstrator as synth
    from mimicrete.teleop import convert

    root = tmp_path_factory.mktemp("one-demo")
    out = root / "demos"
    out.mkdir()
    for i, p in enumerate(synth.synth_hands("suction", 1, 7, root / "hands")):
        convert.convert_log(p, "suction", out, episode_index=i)
    return out
