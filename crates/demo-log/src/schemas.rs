//! The JSON Schemas (draft 2020-12 compatible) of every channel a demo carries.
//!
//! Our own records carry their version in the schema name (`mimicrete.DemoStep.v1`); the visual
//! channels use the Foxglove well-known schema names so the Foxglove app decodes them (it matches on
//! the name; the schema text here lists the fields this crate writes). The text is built from
//! fixed strings, so the bytes are the same on every build.

/// Schema name of `/demo/step`.
pub const STEP_SCHEMA_NAME: &str = "mimicrete.DemoStep.v1";
/// Schema name of `/hand/joints`.
pub const HAND_SCHEMA_NAME: &str = "mimicrete.HandFrame.v1";
/// Schema name of `/teleop/stage_times`.
pub const STAGE_TIMES_SCHEMA_NAME: &str = "mimicrete.StageTimes.v1";
/// Schema name of `/deploy/tick`.
pub const DEPLOY_TICK_SCHEMA_NAME: &str = "mimicrete.DeployTick.v1";
/// Schema name of `/tf`.
pub const TF_SCHEMA_NAME: &str = "foxglove.FrameTransforms";
/// Schema name of `/scene`.
pub const SCENE_SCHEMA_NAME: &str = "foxglove.SceneUpdate";
/// Schema name of `/events`.
pub const EVENT_SCHEMA_NAME: &str = "foxglove.Event";

const NUM: &str = r#"{"type":"number"}"#;
const BOOL: &str = r#"{"type":"boolean"}"#;
const STR: &str = r#"{"type":"string"}"#;
const UINT: &str = r#"{"type":"integer","minimum":0}"#;

fn object(title: Option<&str>, props: &[(&str, String)], required: &[&str]) -> String {
    let mut s = String::from("{");
    if let Some(t) = title {
        s.push_str(&format!(r#""title":"{t}","#));
    }
    s.push_str(r#""type":"object","properties":{"#);
    for (i, (k, v)) in props.iter().enumerate() {
        if i > 0 {
            s.push(',');
        }
        s.push_str(&format!(r#""{k}":{v}"#));
    }
    s.push_str(r#"},"required":["#);
    s.push_str(&required.iter().map(|r| format!(r#""{r}""#)).collect::<Vec<_>>().join(","));
    s.push_str("]}");
    s
}

fn array_of(items: &str) -> String {
    format!(r#"{{"type":"array","items":{items}}}"#)
}

fn fixed_array(items: &str, n: usize) -> String {
    format!(r#"{{"type":"array","items":{items},"minItems":{n},"maxItems":{n}}}"#)
}

fn vec3() -> String {
    object(
        Some("foxglove.Vector3"),
        &[("x", NUM.into()), ("y", NUM.into()), ("z", NUM.into())],
        &["x", "y", "z"],
    )
}

fn quat() -> String {
    object(
        Some("foxglove.Quaternion"),
        &[("x", NUM.into()), ("y", NUM.into()), ("z", NUM.into()), ("w", NUM.into())],
        &["x", "y", "z", "w"],
    )
}

fn pose() -> String {
    object(
        Some("foxglove.Pose"),
        &[("position", vec3()), ("orientation", quat())],
        &["position", "orientation"],
    )
}

fn color() -> String {
    object(
        Some("foxglove.Color"),
        &[("r", NUM.into()), ("g", NUM.into()), ("b", NUM.into()), ("a", NUM.into())],
        &["r", "g", "b", "a"],
    )
}

fn time() -> String {
    object(
        Some("time"),
        &[("sec", UINT.into()), ("nsec", r#"{"type":"integer","minimum":0,"maximum":999999999}"#.into())],
        &["sec", "nsec"],
    )
}

fn duration() -> String {
    object(
        Some("duration"),
        &[
            ("sec", r#"{"type":"integer"}"#.into()),
            ("nsec", r#"{"type":"integer","minimum":0,"maximum":999999999}"#.into()),
        ],
        &["sec", "nsec"],
    )
}

fn with_schema_header(body: String, description: &str) -> String {
    // Insert `$schema` and `description` right after the opening brace.
    format!(
        r#"{{"$schema":"https://json-schema.org/draft/2020-12/schema","description":"{description}",{}"#,
        &body[1..]
    )
}

/// `mimicrete.DemoStep.v1`: one environment step of a demonstration.
pub fn step_schema() -> String {
    let body = object(
        Some(STEP_SCHEMA_NAME),
        &[
            ("episode", UINT.into()),
            ("step", UINT.into()),
            ("t", NUM.into()),
            ("obs", array_of(NUM)),
            ("action", array_of(NUM)),
            ("reward", NUM.into()),
            ("terminated", BOOL.into()),
            ("truncated", BOOL.into()),
            ("gesture", STR.into()),
            ("joints", fixed_array(NUM, 6)),
            ("ee_pose", pose()),
            ("tile_pose", pose()),
        ],
        &[
            "episode",
            "step",
            "t",
            "obs",
            "action",
            "reward",
            "terminated",
            "truncated",
            "gesture",
            "joints",
            "ee_pose",
            "tile_pose",
        ],
    );
    with_schema_header(
        body,
        "One environment step: observation frame (float32 list), action (float32 list: joint motions then \
         end-effector command), reward, episode end flags, the gesture read from the hand, the robot joint \
         angles (rad, base to wrist 3), tool0 pose and tile pose in the robot Base frame (m, quaternion xyzw). \
         t is seconds since the episode start and equals the message log time.",
    )
}

/// `mimicrete.HandFrame.v1`: one raw hand-log frame, as read from the log.
pub fn hand_schema() -> String {
    let body = object(
        Some(HAND_SCHEMA_NAME),
        &[
            ("t", NUM.into()),
            ("tracked", BOOL.into()),
            ("joints", array_of(&fixed_array(NUM, 3))),
            ("orientations", array_of(&fixed_array(NUM, 4))),
        ],
        &["t", "tracked", "joints"],
    );
    with_schema_header(
        body,
        "A raw tracked-hand frame: t is the hand log's own time (s), joints are metres in the hand log's \
         space and layout (see the channel metadata), orientations are quaternions xyzw.",
    )
}

/// `mimicrete.StageTimes.v1`: when one control step's hand frame passed each stage of a live
/// session. Page times (`capture_ms`, `sent_ms`, `page_recv_ms`) are on the client's clock, server
/// times on the server's; only differences within one clock mean anything.
pub fn stage_times_schema() -> String {
    let opt_num = r#"{"type":["number","null"]}"#;
    let body = object(
        Some(STAGE_TIMES_SCHEMA_NAME),
        &[
            ("step", UINT.into()),
            ("seq", UINT.into()),
            ("capture_ms", NUM.into()),
            ("sent_ms", NUM.into()),
            ("server_recv_ms", NUM.into()),
            ("state_sent_ms", opt_num.into()),
            ("page_recv_ms", opt_num.into()),
        ],
        &["step", "seq", "capture_ms", "sent_ms", "server_recv_ms", "state_sent_ms", "page_recv_ms"],
    );
    with_schema_header(
        body,
        "The stages of one live control step's hand frame: capture_ms (the frame's t) and sent_ms on \
         the client's clock; server_recv_ms and state_sent_ms (the state answering the frame handed \
         to the socket; null when the episode ended on that frame) on the server's; page_recv_ms \
         (the client's clock) when the client acknowledged the state, else null. Written after the step, at the log time of the latest \
         message.",
    )
}

/// `mimicrete.DeployTick.v1`: one control tick of `mimicrete deploy`.
pub fn deploy_tick_schema() -> String {
    let vec = |n: usize| format!(r#"{{"type":"array","items":{NUM},"minItems":{n},"maxItems":{n}}}"#);
    let raw = r#"{"type":"array","items":{"type":["number","null"]}}"#;
    let strs = format!(r#"{{"type":"array","items":{STR}}}"#);
    let props: Vec<(&str, String)> = vec![
        ("step", UINT.into()),
        ("t", NUM.into()),
        ("robot_time", NUM.into()),
        ("q_read", vec(6)),
        ("tcp_read", vec(6)),
        ("safety_mode", r#"{"type":"integer"}"#.into()),
        ("digital_out", UINT.into()),
        ("tile_pose", vec(3)),
        ("tile_source", STR.into()),
        ("raw_action", raw.into()),
        ("command_q", vec(6)),
        ("suction", BOOL.into()),
        ("gates", strs),
        ("sent", BOOL.into()),
        ("latency_ms", NUM.into()),
    ];
    let names: Vec<&str> = props.iter().map(|(k, _)| *k).collect();
    let body = object(Some(DEPLOY_TICK_SCHEMA_NAME), &props, &names);
    with_schema_header(
        body,
        "One control tick of a robot deployment: the joints (rad) and TCP (x, y, z, rotation vector) \
         read, the safety mode and digital outputs read, the tile pose (x, y, yaw) put into the \
         observation and its source, the policy's raw action (null where not finite), the joint \
         target after the gates, the suction commanded, the gates that fired, whether the command \
         was sent, and the time from the read to the command (ms).",
    )
}

/// `foxglove.FrameTransforms`.
pub fn tf_schema() -> String {
    let tf = object(
        Some("foxglove.FrameTransform"),
        &[
            ("timestamp", time()),
            ("parent_frame_id", STR.into()),
            ("child_frame_id", STR.into()),
            ("translation", vec3()),
            ("rotation", quat()),
        ],
        &["timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"],
    );
    with_schema_header(
        object(Some(TF_SCHEMA_NAME), &[("transforms", array_of(&tf))], &["transforms"]),
        "An array of FrameTransform messages",
    )
}

/// `foxglove.SceneUpdate` (cubes, cylinders and spheres; the other primitive arrays are written
/// empty).
pub fn scene_schema() -> String {
    let kv = object(
        Some("foxglove.KeyValuePair"),
        &[("key", STR.into()), ("value", STR.into())],
        &["key", "value"],
    );
    let cube = object(
        Some("foxglove.CubePrimitive"),
        &[("pose", pose()), ("size", vec3()), ("color", color())],
        &["pose", "size", "color"],
    );
    let sphere = object(
        Some("foxglove.SpherePrimitive"),
        &[("pose", pose()), ("size", vec3()), ("color", color())],
        &["pose", "size", "color"],
    );
    let cylinder = object(
        Some("foxglove.CylinderPrimitive"),
        &[
            ("pose", pose()),
            ("size", vec3()),
            ("bottom_scale", NUM.into()),
            ("top_scale", NUM.into()),
            ("color", color()),
        ],
        &["pose", "size", "bottom_scale", "top_scale", "color"],
    );
    let any_obj = r#"{"type":"object"}"#;
    let entity = object(
        Some("foxglove.SceneEntity"),
        &[
            ("timestamp", time()),
            ("frame_id", STR.into()),
            ("id", STR.into()),
            ("lifetime", duration()),
            ("frame_locked", BOOL.into()),
            ("metadata", array_of(&kv)),
            ("arrows", array_of(any_obj)),
            ("cubes", array_of(&cube)),
            ("spheres", array_of(&sphere)),
            ("cylinders", array_of(&cylinder)),
            ("lines", array_of(any_obj)),
            ("triangles", array_of(any_obj)),
            ("texts", array_of(any_obj)),
            ("models", array_of(any_obj)),
        ],
        &[
            "timestamp",
            "frame_id",
            "id",
            "lifetime",
            "frame_locked",
            "metadata",
            "cubes",
            "spheres",
            "cylinders",
        ],
    );
    let deletion = object(
        Some("foxglove.SceneEntityDeletion"),
        &[("timestamp", time()), ("type", r#"{"type":"integer","enum":[0,1]}"#.into()), ("id", STR.into())],
        &["timestamp", "type", "id"],
    );
    with_schema_header(
        object(
            Some(SCENE_SCHEMA_NAME),
            &[("deletions", array_of(&deletion)), ("entities", array_of(&entity))],
            &["deletions", "entities"],
        ),
        "An update to the entities displayed in a 3D scene",
    )
}

/// `foxglove.Event`.
pub fn event_schema() -> String {
    let etype = object(Some("foxglove.EventType"), &[("name", STR.into()), ("color", STR.into())], &["name"]);
    let prop = object(
        Some("foxglove.EventProperty"),
        &[
            ("key", STR.into()),
            ("type", r#"{"type":"integer","enum":[0,1,2,3,4,5]}"#.into()),
            ("value", STR.into()),
        ],
        &["key", "type", "value"],
    );
    with_schema_header(
        object(
            Some(EVENT_SCHEMA_NAME),
            &[
                ("timestamp", time()),
                ("duration", duration()),
                ("event_type", etype),
                ("event_properties", array_of(&prop)),
                ("id", STR.into()),
                ("device_id", STR.into()),
            ],
            &["timestamp", "id", "device_id"],
        ),
        "A discrete event: gesture changes, pick, install, fall, episode end",
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_schema_is_valid_json_with_its_title() {
        for (name, s) in [
            (STEP_SCHEMA_NAME, step_schema()),
            (HAND_SCHEMA_NAME, hand_schema()),
            (TF_SCHEMA_NAME, tf_schema()),
            (SCENE_SCHEMA_NAME, scene_schema()),
            (EVENT_SCHEMA_NAME, event_schema()),
        ] {
            let v: serde_json::Value = serde_json::from_str(&s).unwrap();
            assert_eq!(v["title"], name);
            assert_eq!(v["type"], "object");
        }
    }
}
