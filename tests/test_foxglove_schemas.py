"""Every ``/tf`` and ``/scene`` message of a converted demo, and the scene the native module hands
to a live viewer, validate against Foxglove's published JSON schemas (npm ``@foxglove/schemas``
2.1.0, ``dist/jsonschema/index.js``; installed by ``web/package.json``), not against a copy of
our own. The scene is complete: table, pad, target, cups locked to ``tool0``, tile locked to
``tile``."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from mimicrete import _native
from mimicrete import demonstrator as sy
from mimicrete.teleop import convert as cv

ROOT = Path(__file__).resolve().parent.parent
SCHEMAS = Path(
    os.environ.get(
        "MIMICRETE_FOXGLOVE_SCHEMAS", ROOT / "web" / "node_modules" / "@foxglove" / "schemas"
    )
)
INDEX = SCHEMAS / "dist" / "jsonschema" / "index.js"


def _foxglove_schemas() -> dict[str, dict]:
    """``exports.<Name> = {...};`` blocks of the package's generated module, as JSON."""
    if not INDEX.is_file():
        pytest.fail(f"{INDEX} missing: `make web` (npm ci in web/: @foxglove/schemas 2.1.0)")
    text = INDEX.read_text()
    out = {}
    for m in re.finditer(r"^exports\.(\w+) = (\{.*?^\});$", text, re.M | re.S):
        out[m.group(1)] = json.loads(m.group(2))
    assert {"FrameTransforms", "SceneUpdate", "SceneEntity"} <= out.keys()
    return out


def _validator(schema: dict):
    cls = jsonschema.validators.validator_for(schema)
    cls.check_schema(schema)
    return cls(schema)


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("fox")
    log = sy.synth_hands("suction", 1, 0, d / "logs")[0]
    res = cv.convert_log(log, "suction", d / "demos")
    assert res.out is not None
    return Path(res.out)


def test_every_tf_and_scene_message_validates(demo: Path):
    from mcap.reader import make_reader

    fox = _foxglove_schemas()
    tf, scene = _validator(fox["FrameTransforms"]), _validator(fox["SceneUpdate"])
    counts = {"/tf": 0, "/scene": 0}
    first_scene = None
    with demo.open("rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if channel.topic not in counts:
                continue
            msg = json.loads(message.data)
            (tf if channel.topic == "/tf" else scene).validate(msg)
            counts[channel.topic] += 1
            if channel.topic == "/scene" and first_scene is None:
                first_scene = msg
            assert (
                schema.name
                == {"/tf": "foxglove.FrameTransforms", "/scene": "foxglove.SceneUpdate"}[
                    channel.topic
                ]
            )
    steps = _native.demo_read(str(demo))["rewards"].shape[0]
    assert counts["/tf"] == steps and counts["/scene"] >= 1
    ents = {e["id"]: e for e in first_scene["entities"]}
    assert ents["table"]["frame_id"] == "base" and ents["target"]["frame_id"] == "base"
    assert ents["pad"]["frame_id"] == "base"
    assert ents["tile"]["frame_id"] == "tile" and ents["tile"]["frame_locked"] is True
    assert [ents[f"cup_{k}"]["frame_id"] for k in range(4)] == ["tool0"] * 4
    assert ents["suction_plate"]["frame_id"] == "tool0"
    assert ents["tile"]["cubes"][0]["size"] == {"x": 0.15, "y": 0.15, "z": 0.01}


def test_native_scene_entities_and_frames_for_a_live_viewer():
    fox = _foxglove_schemas()
    entity = _validator(fox["SceneEntity"])
    for task in ("TileSuction", "BlockGrip", "Screw"):
        ents = _native.scene_entities(task, 5)
        for e in ents:
            entity.validate(e)
        _validator(fox["SceneUpdate"]).validate({"deletions": [], "entities": ents})
    env = _native.SimEnv("TileSuction", 0)
    env.reset(5)
    assert env.scene_entities() == _native.scene_entities("TileSuction", 5)
    frames = env.scene_frames()
    locked = {e["frame_id"] for e in env.scene_entities()}
    assert locked - {"base"} <= frames.keys()
    snap = env.snapshot()
    np.testing.assert_allclose(frames["tile"], [*snap["object"]["t"], *snap["object"]["q"]])
    np.testing.assert_allclose(frames["tool0"][:3], snap["tool0"]["t"], atol=1e-9)
    same = _native.scene_frames(snap["q"], [*snap["object"]["t"], *snap["object"]["q"]])
    assert same == frames
