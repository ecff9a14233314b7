//! The MCAP demonstration writer: one file per episode.

use crate::handlog::{HandFrame, HandLogHeader};
use crate::schemas;
use crate::{DemoError, partial_path};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};
use ur3_kin::nalgebra::{UnitQuaternion, Vector3};
use ur3_kin::{UrModel, urdf};

/// Format name written in the `episode` metadata record.
pub const DEMO_FORMAT: &str = "mimicrete.demo";
/// Demo format version (bumped with any incompatible change of a channel or record).
pub const DEMO_FORMAT_VERSION: u32 = 1;

/// Topic of the step records.
pub const TOPIC_STEP: &str = "/demo/step";
/// Topic of the raw hand frames.
pub const TOPIC_HAND: &str = "/hand/joints";
/// Topic of the transforms.
pub const TOPIC_TF: &str = "/tf";
/// Topic of the 3D scene.
pub const TOPIC_SCENE: &str = "/scene";
/// Topic of the events.
pub const TOPIC_EVENTS: &str = "/events";
/// Topic of a live session's per-step stage times (only live demos carry it).
pub const TOPIC_STAGE_TIMES: &str = "/teleop/stage_times";
/// Topic of a robot deployment's per-tick record (only `mimicrete deploy` logs carry it).
pub const TOPIC_DEPLOY_TICK: &str = "/deploy/tick";

/// Name of the root frame (the UR controller's Base frame, Z up, metres).
pub const BASE_FRAME: &str = urdf::LINKS[0];
/// Frames of the robot links published on `/tf`: the links of the URDF attached to the file after
/// its root ([`ur3_kin::urdf::LINKS`], ROS-Industrial `ur_description` layout); each is the child
/// of the one before, the first is the child of [`BASE_FRAME`].
pub const LINK_FRAMES: [&str; 8] = match urdf::LINKS.last_chunk::<8>() {
    Some(l) => *l,
    None => unreachable!(),
};
/// Frame of the tile (child of [`BASE_FRAME`]).
pub const TILE_FRAME: &str = "tile";
/// Frames of a row's objects (TileRow: one per tile, children of [`BASE_FRAME`]): object `i`
/// of a step's [`StepRecord::row_poses`] drives `ROW_FRAMES[i]`; [`TILE_FRAME`] stays the
/// current object (the held one, else the next to install). At most this many objects.
pub const ROW_FRAMES: [&str; 8] =
    ["tile_0", "tile_1", "tile_2", "tile_3", "tile_4", "tile_5", "tile_6", "tile_7"];

/// A pose: position (m) and orientation quaternion `[x, y, z, w]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Metres.
    pub position: [f64; 3],
    /// Unit quaternion, `[x, y, z, w]`.
    pub orientation: [f64; 4],
}

impl Pose {
    /// The identity pose.
    pub const IDENTITY: Pose = Pose { position: [0.0; 3], orientation: [0.0, 0.0, 0.0, 1.0] };

    /// From an `Isometry3`.
    pub fn from_isometry(p: &ur3_kin::Pose) -> Pose {
        let q = p.rotation.quaternion();
        Pose {
            position: [p.translation.x, p.translation.y, p.translation.z],
            orientation: [q.i, q.j, q.k, q.w],
        }
    }

    fn is_finite(&self) -> bool {
        self.position.iter().chain(self.orientation.iter()).all(|x| x.is_finite())
    }
}

impl Default for Pose {
    fn default() -> Self {
        Pose::IDENTITY
    }
}

/// Primitive shape of a [`SceneEntity`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// A box, `size` = full extents x, y, z.
    Cube,
    /// A cylinder along its local Z, `size` = (diameter x, diameter y, height).
    Cylinder,
    /// An ellipsoid, `size` = diameters.
    Sphere,
}

impl Shape {
    /// `"cube"`, `"cylinder"` or `"sphere"`.
    pub fn from_name(name: &str) -> Option<Shape> {
        match name.to_ascii_lowercase().as_str() {
            "cube" | "box" => Some(Shape::Cube),
            "cylinder" => Some(Shape::Cylinder),
            "sphere" => Some(Shape::Sphere),
            _ => None,
        }
    }
}

/// A visual primitive for `/scene` (table, tile, target, suction cups, ...). Published frame-locked:
/// an entity in frame [`TILE_FRAME`] moves with the tile.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneEntity {
    /// Unique id; a later entity with the same id replaces it.
    pub id: String,
    /// Frame the pose is expressed in (`"base"`, `"tile"`, `"tool0"`, ...).
    pub frame_id: String,
    /// Shape.
    pub kind: Shape,
    /// Size in metres (see [`Shape`]).
    pub size: [f64; 3],
    /// Pose of the primitive's centre in `frame_id`.
    pub pose: Pose,
    /// Colour, RGBA in 0..1.
    pub color: [f32; 4],
    /// Further primitives drawn as part of this entity (a capsule: its cylinder, then the
    /// spheres capping it), in `frame_id`.
    pub extra: Vec<Primitive>,
}

/// One more primitive of a [`SceneEntity`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Primitive {
    /// Shape.
    pub kind: Shape,
    /// Size in metres (see [`Shape`]).
    pub size: [f64; 3],
    /// Pose of the primitive's centre in the entity's frame.
    pub pose: Pose,
    /// Colour, RGBA in 0..1.
    pub color: [f32; 4],
}

impl SceneEntity {
    /// The entity's primitives: its own, then [`SceneEntity::extra`].
    pub fn primitives(&self) -> impl Iterator<Item = Primitive> + '_ {
        let first = Primitive { kind: self.kind, size: self.size, pose: self.pose, color: self.color };
        std::iter::once(first).chain(self.extra.iter().copied())
    }
}

/// Facts about an episode, known when recording starts.
#[derive(Debug, Clone, PartialEq)]
pub struct EpisodeMeta {
    /// Episode index within its data set.
    pub episode: u64,
    /// Task name (`"TileSuction"` / `"suction"`, `"BlockGrip"`, `"Screw"`, ...), recorded as given.
    pub task: String,
    /// Simulator seed of the episode.
    pub seed: u64,
    /// Robot model name known to `ur3_kin::UrModel::by_name` (`"ur3"`).
    pub robot_model: String,
    /// Source hand log, if any; its SHA-256 is computed when recording starts unless
    /// `source_handlog_sha256` gives it.
    pub source_handlog: Option<PathBuf>,
    /// SHA-256 (64 lower-case hex digits) of the source hand log's bytes as they were parsed
    /// ([`crate::ParseReport::sha256`]). A converter passes it so that the hash covers exactly
    /// the bytes converted, even when the file grows (or is replaced) after it was read.
    pub source_handlog_sha256: Option<String>,
    /// The hand log's header (layout, space, handedness), if hand frames are recorded.
    pub hand: Option<HandLogHeader>,
    /// Name/version of the gesture model used (`"svm-suction-v1"`), free text.
    pub gesture_model: String,
    /// Seconds per environment step, if fixed (0 = unknown).
    pub control_dt: f64,
    /// The static scene, published on `/scene` with the first step (the task's table, pad,
    /// target, effector and object: the caller hands the simulator's, teleop-core's
    /// `scene::demo_scene`). The robot is drawn as link cylinders before it unless it has
    /// entities `robot/...` of its own.
    pub scene: Vec<SceneEntity>,
    /// Any further facts, written into the metadata records.
    pub extra: BTreeMap<String, String>,
}

impl Default for EpisodeMeta {
    fn default() -> Self {
        EpisodeMeta {
            episode: 0,
            task: "suction".into(),
            seed: 0,
            robot_model: "ur3".into(),
            source_handlog: None,
            source_handlog_sha256: None,
            hand: None,
            gesture_model: String::new(),
            control_dt: 0.0,
            scene: Vec::new(),
            extra: BTreeMap::new(),
        }
    }
}

/// One environment step to record.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StepRecord {
    /// Step index: 0, 1, 2, ... (consecutive).
    pub step: u64,
    /// Seconds since the episode start (the message log time), non-decreasing.
    pub t: f64,
    /// Observation frame (the env's observation at this step, before the action).
    pub obs: Vec<f32>,
    /// Action taken.
    pub action: Vec<f32>,
    /// Reward received for the action.
    pub reward: f64,
    /// The episode ended by the task (install, fall).
    pub terminated: bool,
    /// The episode was cut (time limit).
    pub truncated: bool,
    /// Gesture read from the hand (`"suction"`, `"drop"`, `"hold"`, ...). A change is logged on
    /// `/events` as `gesture_change`.
    pub gesture: String,
    /// Robot joint angles, rad, base to wrist 3. Drives `/tf`.
    pub joints: [f64; 6],
    /// tool0 pose in Base.
    pub ee_pose: Pose,
    /// Tile pose in Base; drives the `tile` frame.
    pub tile_pose: Pose,
    /// A row's objects' poses in Base, in row order (TileRow; empty for one object): object `i`
    /// drives frame [`ROW_FRAMES`]`[i]`.
    pub row_poses: Vec<Pose>,
    /// Named events at this step (`"pick"`, `"install"`, `"fall"`), logged on `/events`.
    pub events: Vec<String>,
    /// Scene entities to add or replace at this step (e.g. a cup changing colour).
    pub scene: Vec<SceneEntity>,
}

/// Facts known when the episode ends.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EpisodeSummary {
    /// The task succeeded (tile installed).
    pub success: bool,
    /// Any further facts (`"picked": "true"`, ...).
    pub extra: BTreeMap<String, String>,
}

/// Writer tuning. The defaults keep at most ~64 KiB (uncompressed) of messages at risk on a crash.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WriterOptions {
    /// Uncompressed bytes after which a chunk is closed.
    pub chunk_size: u64,
    /// Close the chunk and flush to the OS every this many steps (0 = only by size).
    pub flush_every_steps: u64,
    /// zstd level (0 = zstd's default, 3).
    pub compression_level: u32,
}

impl Default for WriterOptions {
    fn default() -> Self {
        WriterOptions { chunk_size: 64 * 1024, flush_every_steps: 50, compression_level: 0 }
    }
}

/// What [`DemoWriter::finish`] wrote.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct WriteStats {
    /// Final path of the file (serialized as text, bytes that are not UTF-8 replaced: serde
    /// refuses such a path, and the demo is already in place when the stats are made).
    #[serde(serialize_with = "path_as_text")]
    pub path: PathBuf,
    /// Steps written.
    pub steps: u64,
    /// Messages written over all channels.
    pub messages: u64,
    /// Chunks in the file.
    pub chunks: u64,
    /// File size, bytes.
    pub bytes: u64,
}

// ---- message bodies (field order is fixed by the structs: the bytes are deterministic) ----

#[derive(Serialize, Clone, Copy)]
struct V3 {
    x: f64,
    y: f64,
    z: f64,
}
#[derive(Serialize, Clone, Copy)]
struct Q4 {
    x: f64,
    y: f64,
    z: f64,
    w: f64,
}
#[derive(Serialize, Clone, Copy)]
struct PoseMsg {
    position: V3,
    orientation: Q4,
}
impl From<&Pose> for PoseMsg {
    fn from(p: &Pose) -> Self {
        let [x, y, z] = p.position;
        let [qx, qy, qz, qw] = p.orientation;
        PoseMsg { position: V3 { x, y, z }, orientation: Q4 { x: qx, y: qy, z: qz, w: qw } }
    }
}
#[derive(Serialize, Clone, Copy)]
struct Time {
    sec: u64,
    nsec: u32,
}
impl Time {
    fn from_ns(ns: u64) -> Time {
        Time { sec: ns / 1_000_000_000, nsec: (ns % 1_000_000_000) as u32 }
    }
}
#[derive(Serialize)]
struct Rgba {
    r: f32,
    g: f32,
    b: f32,
    a: f32,
}

#[derive(Serialize)]
struct StepMsg<'a> {
    episode: u64,
    step: u64,
    t: f64,
    obs: &'a [f32],
    action: &'a [f32],
    reward: f64,
    terminated: bool,
    truncated: bool,
    gesture: &'a str,
    joints: &'a [f64; 6],
    ee_pose: PoseMsg,
    tile_pose: PoseMsg,
}

#[derive(Serialize)]
struct HandMsg<'a> {
    t: f64,
    tracked: bool,
    joints: &'a [[f64; 3]],
    #[serde(skip_serializing_if = "Option::is_none")]
    orientations: Option<&'a [[f64; 4]]>,
}

#[derive(Serialize)]
struct Tf<'a> {
    timestamp: Time,
    parent_frame_id: &'a str,
    child_frame_id: &'a str,
    translation: V3,
    rotation: Q4,
}
#[derive(Serialize)]
struct TfMsg<'a> {
    transforms: Vec<Tf<'a>>,
}

#[derive(Serialize)]
struct Prim {
    pose: PoseMsg,
    size: V3,
    color: Rgba,
}
#[derive(Serialize)]
struct CylPrim {
    pose: PoseMsg,
    size: V3,
    bottom_scale: f64,
    top_scale: f64,
    color: Rgba,
}
#[derive(Serialize)]
struct Kv<'a> {
    key: &'a str,
    value: &'a str,
}
#[derive(Serialize)]
struct Empty {}
#[derive(Serialize)]
struct Entity<'a> {
    timestamp: Time,
    frame_id: &'a str,
    id: &'a str,
    lifetime: Time,
    frame_locked: bool,
    metadata: Vec<Kv<'a>>,
    arrows: [Empty; 0],
    cubes: Vec<Prim>,
    spheres: Vec<Prim>,
    cylinders: Vec<CylPrim>,
    lines: [Empty; 0],
    triangles: [Empty; 0],
    texts: [Empty; 0],
    models: [Empty; 0],
}
#[derive(Serialize)]
struct SceneMsg<'a> {
    deletions: [Empty; 0],
    entities: Vec<Entity<'a>>,
}

#[derive(Serialize)]
struct EventType<'a> {
    name: &'a str,
    color: &'a str,
}
#[derive(Serialize)]
struct EventProp {
    key: String,
    #[serde(rename = "type")]
    kind: u8,
    value: String,
}
#[derive(Serialize)]
struct EventMsg<'a> {
    timestamp: Time,
    duration: Time,
    event_type: EventType<'a>,
    event_properties: Vec<EventProp>,
    id: String,
    device_id: &'a str,
}

fn event_color(name: &str) -> &'static str {
    match name {
        "gesture_change" => "#4A90D9",
        "pick" => "#F5A623",
        "install" | "success" => "#2EAD4B",
        "fall" | "failure" => "#D0021B",
        _ => "#9B9B9B",
    }
}

fn rgba(c: [f32; 4]) -> Rgba {
    Rgba { r: c[0], g: c[1], b: c[2], a: c[3] }
}

/// One entity as the Foxglove `SceneEntity` JSON object written on `/scene` (frame-locked, no
/// lifetime), stamped `t_ns`.
pub fn foxglove_entity(e: &SceneEntity, t_ns: u64) -> serde_json::Value {
    serde_json::to_value(entity_msg(e, Time::from_ns(t_ns))).unwrap_or(serde_json::Value::Null)
}

fn entity_msg<'a>(e: &'a SceneEntity, stamp: Time) -> Entity<'a> {
    let (mut cubes, mut spheres, mut cylinders) = (Vec::new(), Vec::new(), Vec::new());
    for p in e.primitives() {
        let size = V3 { x: p.size[0], y: p.size[1], z: p.size[2] };
        let (pose, color) = (PoseMsg::from(&p.pose), rgba(p.color));
        match p.kind {
            Shape::Cube => cubes.push(Prim { pose, size, color }),
            Shape::Sphere => spheres.push(Prim { pose, size, color }),
            Shape::Cylinder => {
                cylinders.push(CylPrim { pose, size, bottom_scale: 1.0, top_scale: 1.0, color })
            }
        }
    }
    Entity {
        timestamp: stamp,
        frame_id: &e.frame_id,
        id: &e.id,
        lifetime: Time { sec: 0, nsec: 0 },
        frame_locked: true,
        metadata: Vec::new(),
        arrows: [],
        cubes,
        spheres,
        cylinders,
        lines: [],
        triangles: [],
        texts: [],
        models: [],
    }
}

/// Cylinders drawing the robot as a stick figure, each frame-locked to a URDF link so it moves with
/// `/tf`: link L gets a cylinder from its origin to the origin of the next joint (a constant point
/// in L's frame).
pub fn robot_link_entities(model: &UrModel) -> Vec<SceneEntity> {
    let mut out = Vec::new();
    for (k, (parent, _child, xyz, _rpy, _)) in urdf::chain(model).into_iter().enumerate() {
        let d = Vector3::new(xyz[0], xyz[1], xyz[2]);
        let len = d.norm();
        if len < 1e-9 {
            continue;
        }
        let mid = d / 2.0;
        let rot = UnitQuaternion::rotation_between(&Vector3::z(), &d)
            .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
        let q = rot.quaternion();
        let radius = if k <= 3 { 0.045 } else { 0.035 };
        out.push(SceneEntity {
            id: format!("robot/{parent}"),
            frame_id: parent.to_string(),
            kind: Shape::Cylinder,
            size: [2.0 * radius, 2.0 * radius, len],
            pose: Pose { position: [mid.x, mid.y, mid.z], orientation: [q.i, q.j, q.k, q.w] },
            color: [0.55, 0.62, 0.70, 1.0],
            extra: Vec::new(),
        });
    }
    out
}

/// Seconds → nanoseconds log time.
///
/// # Errors
/// [`DemoError::Invalid`] for a negative or non-finite time.
pub fn log_time_ns(t: f64) -> Result<u64, DemoError> {
    if !t.is_finite() || !(0.0..=1.8e10).contains(&t) {
        return Err(DemoError::Invalid(format!(
            "time {t} s is not a finite, non-negative number of seconds"
        )));
    }
    Ok((t * 1e9).round() as u64)
}

fn path_as_text<S: serde::Serializer>(p: &Path, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&p.to_string_lossy())
}

/// Lower-case hex of a SHA-256 digest.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

struct Channels {
    step: u16,
    hand: u16,
    tf: u16,
    scene: u16,
    events: u16,
    /// Added by the first [`DemoWriter::write_stage_times`], so other demos keep five channels.
    stage_times: Option<u16>,
    /// Added by the first [`DemoWriter::write_deploy_tick`].
    deploy_tick: Option<u16>,
}

/// When one control step's hand frame passed each stage of a live session
/// (`mimicrete.StageTimes.v1`, topic [`TOPIC_STAGE_TIMES`]). `capture_ms` (the frame's own time),
/// `sent_ms` and `page_recv_ms` are on the client's clock; `server_recv_ms` and `state_sent_ms` on
/// the server's. `page_recv_ms` is `None` when the client did not acknowledge the state.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StageTimes {
    /// The control step (its `/demo/step` number).
    pub step: u64,
    /// The hand frame's sequence number.
    pub seq: u64,
    /// The frame's capture time, ms.
    pub capture_ms: f64,
    /// When the client sent the frame, ms.
    pub sent_ms: f64,
    /// When the server received it, ms.
    pub server_recv_ms: f64,
    /// When the server handed the state answering it to the socket, ms (`None`: the episode
    /// ended on this frame, before its state went out).
    pub state_sent_ms: Option<f64>,
    /// When the client received that state, ms.
    pub page_recv_ms: Option<f64>,
}

/// One control tick of a robot deployment (`mimicrete.DeployTick.v1`, topic
/// [`TOPIC_DEPLOY_TICK`]): what was read from the robot, where the tile was and from which source,
/// the policy's raw action, the joint command after the gates, which gates fired, whether the
/// command was sent, and the time from the read to the command. Joint angles in rad, poses in the
/// Base frame (m; the TCP as the controller reports it: x, y, z and a rotation vector).
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeployTick {
    /// The control tick (its `/demo/step` number).
    pub step: u64,
    /// Seconds since the deployment started (host clock).
    pub t: f64,
    /// The robot's timestamp of the state read (s; the controller's clock).
    pub robot_time: f64,
    /// Joint angles read.
    pub q_read: Vec<f64>,
    /// TCP pose read: x, y, z, rx, ry, rz.
    pub tcp_read: Vec<f64>,
    /// The controller's safety mode (1 = normal).
    pub safety_mode: i64,
    /// The standard digital outputs read, as bits.
    pub digital_out: u64,
    /// The tile pose put into the observation: x, y, yaw.
    pub tile_pose: Vec<f64>,
    /// Where that pose came from (`fixed`, `file:PATH`, `held`: carried with the suction cups).
    pub tile_source: String,
    /// The policy's action as it came out of the policy (`None` where it was not finite).
    pub raw_action: Vec<Option<f64>>,
    /// The joint target after the gates (the read angles when a gate held the arm).
    pub command_q: Vec<f64>,
    /// The suction output commanded after this tick.
    pub suction: bool,
    /// The gates that fired on this tick (empty: none).
    pub gates: Vec<String>,
    /// The command went to the robot (false in shadow mode and on a stop).
    pub sent: bool,
    /// From the state read to the command handed on (ms).
    pub latency_ms: f64,
}

/// Records one episode into an MCAP file.
///
/// Writes go to `PATH.partial`; [`DemoWriter::finish`] writes the summary and renames the file to
/// `PATH`. A crash leaves `PATH.partial`, from which [`crate::salvage_to`] recovers every message
/// of every complete chunk (chunks are closed at least every
/// [`WriterOptions::flush_every_steps`] steps). Dropping the writer without `finish` closes the
/// partial file validly (no `episode` record) and leaves it as `PATH.partial`.
pub struct DemoWriter {
    w: mcap::Writer<BufWriter<File>>,
    final_path: PathBuf,
    partial: PathBuf,
    meta: EpisodeMeta,
    model: &'static UrModel,
    ch: Channels,
    seq: [u32; 7],
    last_log_time: u64,
    steps: u64,
    messages: u64,
    events: u64,
    last_gesture: Option<String>,
    obs_dim: Option<usize>,
    act_dim: Option<usize>,
    total_reward: f64,
    steps_since_flush: u64,
    opts: WriterOptions,
    scene_written: bool,
    /// The entities of the first `/scene` message: robot, task scene, the caller's static scene.
    first_scene: Vec<SceneEntity>,
    last_t: f64,
    ended: bool,
    handlog_sha256: Option<String>,
}

const DEVICE_ID: &str = "mimicrete";

fn mcap_err(path: &Path) -> impl Fn(mcap::McapError) -> DemoError + '_ {
    move |e| DemoError::Mcap { path: path.to_path_buf(), source: e }
}

impl DemoWriter {
    /// Start recording an episode to `path` (written as `path.partial` until [`finish`](Self::finish)).
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for an unknown robot model, [`DemoError::Io`] when the file cannot be
    /// created or the source hand log cannot be read (for its hash).
    pub fn create(path: impl AsRef<Path>, meta: &EpisodeMeta) -> Result<DemoWriter, DemoError> {
        DemoWriter::create_with_options(path, meta, WriterOptions::default())
    }

    /// [`create`](Self::create) with explicit [`WriterOptions`].
    ///
    /// # Errors
    /// As [`create`](Self::create).
    pub fn create_with_options(
        path: impl AsRef<Path>,
        meta: &EpisodeMeta,
        opts: WriterOptions,
    ) -> Result<DemoWriter, DemoError> {
        let final_path = path.as_ref().to_path_buf();
        let model = UrModel::by_name(&meta.robot_model)
            .map_err(|_| DemoError::Invalid(format!("unknown robot model \"{}\"", meta.robot_model)))?;
        for e in &meta.scene {
            check_entity(e)?;
        }
        let handlog_sha256 = match (&meta.source_handlog_sha256, &meta.source_handlog) {
            (Some(h), _) => {
                if h.len() != 64 || !h.bytes().all(|b| b.is_ascii_digit() || (b'a'..=b'f').contains(&b)) {
                    return Err(DemoError::Invalid(format!(
                        "source_handlog_sha256 must be 64 lower-case hex digits, got {h:?}"
                    )));
                }
                Some(h.clone())
            }
            (None, Some(p)) => {
                let bytes = crate::read_input(p)?;
                Some(sha256_hex(&bytes))
            }
            (None, None) => None,
        };
        let partial = partial_path(&final_path);
        let file = File::create(&partial).map_err(|e| DemoError::Io { path: partial.clone(), source: e })?;
        let me = mcap_err(&partial);
        let mut w = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .compression_level(opts.compression_level)
            .compression_threads(0)
            .chunk_size(Some(opts.chunk_size.max(1024)))
            .profile("")
            .library(format!("mimicrete-demo-log/{}", env!("CARGO_PKG_VERSION")))
            .create(BufWriter::with_capacity(256 * 1024, file))
            .map_err(&me)?;
        // Static facts and the robot description first (outside chunks), so that a salvaged file
        // still says what it is and the first chunk starts with the schemas and channels.
        w.write_metadata(&mcap::records::Metadata {
            name: "episode_start".into(),
            metadata: metadata_map(meta, model, handlog_sha256.as_deref(), None),
        })
        .map_err(&me)?;
        w.attach(&mcap::Attachment {
            log_time: 0,
            create_time: 0,
            name: format!("{}.urdf", model.name),
            media_type: "application/xml".into(),
            data: std::borrow::Cow::Owned(urdf::to_urdf_string(model).into_bytes()),
        })
        .map_err(&me)?;
        let js = "jsonschema";
        let s_step =
            w.add_schema(schemas::STEP_SCHEMA_NAME, js, schemas::step_schema().as_bytes()).map_err(&me)?;
        let s_hand =
            w.add_schema(schemas::HAND_SCHEMA_NAME, js, schemas::hand_schema().as_bytes()).map_err(&me)?;
        let s_tf = w.add_schema(schemas::TF_SCHEMA_NAME, js, schemas::tf_schema().as_bytes()).map_err(&me)?;
        let s_scene =
            w.add_schema(schemas::SCENE_SCHEMA_NAME, js, schemas::scene_schema().as_bytes()).map_err(&me)?;
        let s_ev =
            w.add_schema(schemas::EVENT_SCHEMA_NAME, js, schemas::event_schema().as_bytes()).map_err(&me)?;
        let none = BTreeMap::new();
        let mut hand_md = BTreeMap::new();
        if let Some(h) = &meta.hand {
            hand_md.insert("layout".to_string(), h.layout.name().to_string());
            hand_md.insert("space".to_string(), h.space.name().to_string());
            hand_md.insert("handedness".to_string(), h.handedness.name().to_string());
            hand_md.insert("joint_count".to_string(), h.layout.joint_count().to_string());
            hand_md.insert("units".to_string(), "m".to_string());
        }
        let ch = Channels {
            step: w.add_channel(s_step, TOPIC_STEP, "json", &none).map_err(&me)?,
            hand: w.add_channel(s_hand, TOPIC_HAND, "json", &hand_md).map_err(&me)?,
            tf: w.add_channel(s_tf, TOPIC_TF, "json", &none).map_err(&me)?,
            scene: w.add_channel(s_scene, TOPIC_SCENE, "json", &none).map_err(&me)?,
            events: w.add_channel(s_ev, TOPIC_EVENTS, "json", &none).map_err(&me)?,
            stage_times: None,
            deploy_tick: None,
        };
        Ok(DemoWriter {
            w,
            final_path,
            partial: partial.clone(),
            meta: meta.clone(),
            model,
            ch,
            seq: [0; 7],
            last_log_time: 0,
            steps: 0,
            messages: 0,
            events: 0,
            last_gesture: None,
            obs_dim: None,
            act_dim: None,
            total_reward: 0.0,
            steps_since_flush: 0,
            opts,
            scene_written: false,
            first_scene: first_scene(model, meta),
            last_t: 0.0,
            ended: false,
            handlog_sha256,
        })
    }

    /// The final path (`.partial` is dropped from it on finish).
    pub fn path(&self) -> &Path {
        &self.final_path
    }

    /// Steps written so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    fn metadata_map(&self, summary: Option<&EpisodeSummary>) -> BTreeMap<String, String> {
        let mut md = metadata_map(&self.meta, self.model, self.handlog_sha256.as_deref(), summary);
        if summary.is_some() {
            md.insert("length".into(), self.steps.to_string());
            md.insert("total_reward".into(), format!("{}", self.total_reward));
            md.insert("obs_dim".into(), self.obs_dim.unwrap_or(0).to_string());
            md.insert("act_dim".into(), self.act_dim.unwrap_or(0).to_string());
            md.insert("terminated".into(), self.ended.to_string());
        }
        md
    }

    fn put(&mut self, which: usize, log_time: u64, data: &[u8]) -> Result<(), DemoError> {
        let stage = self.ch.stage_times.unwrap_or(0);
        let tick = self.ch.deploy_tick.unwrap_or(0);
        let channel_id =
            [self.ch.step, self.ch.hand, self.ch.tf, self.ch.scene, self.ch.events, stage, tick][which];
        let sequence = self.seq[which];
        self.seq[which] = sequence.wrapping_add(1);
        self.w
            .write_to_known_channel(
                &mcap::records::MessageHeader { channel_id, sequence, log_time, publish_time: log_time },
                data,
            )
            .map_err(mcap_err(&self.partial))?;
        self.last_log_time = log_time;
        self.messages += 1;
        Ok(())
    }

    fn check_time(&self, t: f64, what: &str) -> Result<u64, DemoError> {
        let ns = log_time_ns(t)?;
        if ns < self.last_log_time {
            return Err(DemoError::Invalid(format!(
                "{what}: time {t} s is before the last message written ({} s); log times must not decrease",
                self.last_log_time as f64 / 1e9
            )));
        }
        Ok(ns)
    }

    /// Record one step: `/demo/step`, `/tf` (every robot link from FK of `joints`, and the tile),
    /// `/scene` (the static scene and robot on the first step, then `rec.scene` updates) and
    /// `/events` (gesture changes and `rec.events`).
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for non-consecutive step numbers, decreasing time, non-finite values,
    /// or obs/action lengths that differ from the first step's; [`DemoError::Mcap`] on write failure.
    pub fn write_step(&mut self, rec: &StepRecord) -> Result<(), DemoError> {
        let links = urdf::link_transforms(self.model, &rec.joints);
        self.write_step_with_links(rec, &links)
    }

    /// [`DemoWriter::write_step`] with the arm's parent-to-child link transforms at `rec.joints`
    /// given (`ur3_kin::urdf::link_transforms` of the demo's robot model): a caller that needs
    /// them too (the live page's frames) runs the arm's chain once per step.
    ///
    /// # Errors
    /// As [`DemoError::Invalid`] of [`DemoError::write_step`], and a `links` of another length
    /// than the chain's.
    pub fn write_step_with_links(
        &mut self,
        rec: &StepRecord,
        links: &[(&'static str, &'static str, ur3_kin::Pose)],
    ) -> Result<(), DemoError> {
        if links.len() != LINK_FRAMES.len() {
            return Err(DemoError::Invalid(format!(
                "step {}: {} link transforms, the arm's chain has {}",
                rec.step,
                links.len(),
                LINK_FRAMES.len()
            )));
        }
        if self.ended {
            return Err(DemoError::Invalid(format!(
                "step {}: the episode already ended (terminated or truncated at step {})",
                rec.step,
                self.steps.saturating_sub(1)
            )));
        }
        if rec.step != self.steps {
            return Err(DemoError::Invalid(format!(
                "step number {} but {} steps were written",
                rec.step, self.steps
            )));
        }
        let ns = self.check_time(rec.t, &format!("step {}", rec.step))?;
        let dims = (rec.obs.len(), rec.action.len());
        if dims.0 == 0 || dims.1 == 0 {
            return Err(DemoError::Invalid(format!("step {}: empty obs or action", rec.step)));
        }
        if let (Some(o), Some(a)) = (self.obs_dim, self.act_dim)
            && (o, a) != dims
        {
            return Err(DemoError::Invalid(format!(
                "step {}: obs/action lengths {}/{} differ from the first step's {o}/{a}",
                rec.step, dims.0, dims.1
            )));
        }
        if let Some(i) = rec.obs.iter().position(|x| !x.is_finite()) {
            return Err(DemoError::Invalid(format!("step {}: obs[{i}] is {}", rec.step, rec.obs[i])));
        }
        if let Some(i) = rec.action.iter().position(|x| !x.is_finite()) {
            return Err(DemoError::Invalid(format!("step {}: action[{i}] is {}", rec.step, rec.action[i])));
        }
        if !rec.reward.is_finite()
            || rec.joints.iter().any(|x| !x.is_finite())
            || !rec.ee_pose.is_finite()
            || !rec.tile_pose.is_finite()
            || rec.row_poses.iter().any(|p| !p.is_finite())
        {
            return Err(DemoError::Invalid(format!("step {}: non-finite reward, joints or pose", rec.step)));
        }
        if rec.row_poses.len() > ROW_FRAMES.len() {
            return Err(DemoError::Invalid(format!(
                "step {}: {} row objects, a demo has frames for at most {}",
                rec.step,
                rec.row_poses.len(),
                ROW_FRAMES.len()
            )));
        }
        for e in &rec.scene {
            check_entity(e)?;
        }
        self.obs_dim = Some(dims.0);
        self.act_dim = Some(dims.1);

        let msg = StepMsg {
            episode: self.meta.episode,
            step: rec.step,
            t: rec.t,
            obs: &rec.obs,
            action: &rec.action,
            reward: rec.reward,
            terminated: rec.terminated,
            truncated: rec.truncated,
            gesture: &rec.gesture,
            joints: &rec.joints,
            ee_pose: PoseMsg::from(&rec.ee_pose),
            tile_pose: PoseMsg::from(&rec.tile_pose),
        };
        let bytes = serde_json::to_vec(&msg).map_err(|e| DemoError::Invalid(e.to_string()))?;
        self.put(0, ns, &bytes)?;

        // /tf: the link chain, then the tile, then a row's objects.
        let stamp = Time::from_ns(ns);
        let mut tfs = Vec::with_capacity(LINK_FRAMES.len() + 1 + rec.row_poses.len());
        for &(parent, child, rel) in links {
            let pm = PoseMsg::from(&Pose::from_isometry(&rel));
            tfs.push(Tf {
                timestamp: stamp,
                parent_frame_id: parent,
                child_frame_id: child,
                translation: pm.position,
                rotation: pm.orientation,
            });
        }
        for (child, pose) in
            std::iter::once((TILE_FRAME, &rec.tile_pose)).chain(ROW_FRAMES.into_iter().zip(&rec.row_poses))
        {
            let pm = PoseMsg::from(pose);
            tfs.push(Tf {
                timestamp: stamp,
                parent_frame_id: BASE_FRAME,
                child_frame_id: child,
                translation: pm.position,
                rotation: pm.orientation,
            });
        }
        let bytes =
            serde_json::to_vec(&TfMsg { transforms: tfs }).map_err(|e| DemoError::Invalid(e.to_string()))?;
        self.put(2, ns, &bytes)?;

        // /scene
        let mut entities: Vec<SceneEntity> = Vec::new();
        if !self.scene_written {
            entities.append(&mut self.first_scene);
            self.scene_written = true;
        }
        entities.extend(rec.scene.iter().cloned());
        if !entities.is_empty() {
            let msg =
                SceneMsg { deletions: [], entities: entities.iter().map(|e| entity_msg(e, stamp)).collect() };
            let bytes = serde_json::to_vec(&msg).map_err(|e| DemoError::Invalid(e.to_string()))?;
            self.put(3, ns, &bytes)?;
        }

        // /events
        if self.last_gesture.as_deref() != Some(rec.gesture.as_str()) {
            let mut props = vec![("to", rec.gesture.clone(), 0u8)];
            if let Some(prev) = &self.last_gesture {
                props.push(("from", prev.clone(), 0));
            }
            props.push(("step", rec.step.to_string(), 3));
            self.event_at(ns, "gesture_change", props)?;
            self.last_gesture = Some(rec.gesture.clone());
        }
        for name in &rec.events {
            self.event_at(ns, name, vec![("step", rec.step.to_string(), 3)])?;
        }

        self.total_reward += rec.reward;
        self.steps += 1;
        self.last_t = rec.t;
        self.ended = rec.terminated || rec.truncated;
        self.steps_since_flush += 1;
        if self.opts.flush_every_steps > 0 && self.steps_since_flush >= self.opts.flush_every_steps {
            self.w.flush().map_err(mcap_err(&self.partial))?;
            self.steps_since_flush = 0;
        }
        Ok(())
    }

    fn event_at(&mut self, ns: u64, name: &str, props: Vec<(&str, String, u8)>) -> Result<(), DemoError> {
        let msg = EventMsg {
            timestamp: Time::from_ns(ns),
            duration: Time { sec: 0, nsec: 0 },
            event_type: EventType { name, color: event_color(name) },
            event_properties: props
                .into_iter()
                .map(|(k, v, kind)| EventProp { key: k.to_string(), kind, value: v })
                .collect(),
            id: format!("episode-{}/event-{}", self.meta.episode, self.events),
            device_id: DEVICE_ID,
        };
        let bytes = serde_json::to_vec(&msg).map_err(|e| DemoError::Invalid(e.to_string()))?;
        self.put(4, ns, &bytes)?;
        self.events += 1;
        Ok(())
    }

    /// Record an event (`"pick"`, `"install"`, `"fall"`, ...) at time `t` with string properties.
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for a time before the last message.
    pub fn write_event(
        &mut self,
        t: f64,
        name: &str,
        properties: &BTreeMap<String, String>,
    ) -> Result<(), DemoError> {
        let ns = self.check_time(t, &format!("event {name}"))?;
        let props = properties.iter().map(|(k, v)| (k.as_str(), v.clone(), 0u8)).collect();
        self.event_at(ns, name, props)
    }

    /// Record when a live control step's hand frame passed each stage, on
    /// [`TOPIC_STAGE_TIMES`] at the log time of the latest message (a step's times are complete
    /// only after its state reached the client, so they are written after the step).
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for a step not yet written or a non-finite time.
    pub fn write_stage_times(&mut self, st: &StageTimes) -> Result<(), DemoError> {
        if st.step >= self.steps {
            return Err(DemoError::Invalid(format!(
                "stage times of step {}: only {} steps written",
                st.step, self.steps
            )));
        }
        let times = [st.capture_ms, st.sent_ms, st.server_recv_ms];
        if times.iter().chain(st.state_sent_ms.iter()).chain(st.page_recv_ms.iter()).any(|x| !x.is_finite()) {
            return Err(DemoError::Invalid(format!("stage times of step {}: a non-finite time", st.step)));
        }
        if self.ch.stage_times.is_none() {
            let me = mcap_err(&self.partial);
            let schema = schemas::stage_times_schema();
            let sid = self
                .w
                .add_schema(schemas::STAGE_TIMES_SCHEMA_NAME, "jsonschema", schema.as_bytes())
                .map_err(&me)?;
            self.ch.stage_times =
                Some(self.w.add_channel(sid, TOPIC_STAGE_TIMES, "json", &BTreeMap::new()).map_err(&me)?);
        }
        let bytes = serde_json::to_vec(st).map_err(|e| DemoError::Invalid(e.to_string()))?;
        self.put(5, self.last_log_time, &bytes)
    }

    /// Record one deployment tick on [`TOPIC_DEPLOY_TICK`] at the log time of the latest message
    /// (written after the tick's step).
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for a tick whose step is not yet written, a non-finite number or a
    /// vector of the wrong length.
    pub fn write_deploy_tick(&mut self, tick: &DeployTick) -> Result<(), DemoError> {
        if tick.step >= self.steps {
            return Err(DemoError::Invalid(format!(
                "deploy tick {}: only {} steps written",
                tick.step, self.steps
            )));
        }
        let lens = [
            ("q_read", tick.q_read.len(), 6),
            ("tcp_read", tick.tcp_read.len(), 6),
            ("tile_pose", tick.tile_pose.len(), 3),
            ("command_q", tick.command_q.len(), 6),
        ];
        if let Some((name, got, want)) = lens.iter().find(|(_, got, want)| got != want) {
            return Err(DemoError::Invalid(format!(
                "deploy tick {}: {name} has {got} numbers, expected {want}",
                tick.step
            )));
        }
        let numbers = [tick.t, tick.robot_time, tick.latency_ms];
        let all = numbers
            .iter()
            .chain(&tick.q_read)
            .chain(&tick.tcp_read)
            .chain(&tick.tile_pose)
            .chain(&tick.command_q);
        if all.clone().any(|x| !x.is_finite()) {
            return Err(DemoError::Invalid(format!("deploy tick {}: a non-finite number", tick.step)));
        }
        if self.ch.deploy_tick.is_none() {
            let me = mcap_err(&self.partial);
            let schema = schemas::deploy_tick_schema();
            let sid = self
                .w
                .add_schema(schemas::DEPLOY_TICK_SCHEMA_NAME, "jsonschema", schema.as_bytes())
                .map_err(&me)?;
            self.ch.deploy_tick =
                Some(self.w.add_channel(sid, TOPIC_DEPLOY_TICK, "json", &BTreeMap::new()).map_err(&me)?);
        }
        let bytes = serde_json::to_vec(tick).map_err(|e| DemoError::Invalid(e.to_string()))?;
        self.put(6, self.last_log_time, &bytes)
    }

    /// Record a raw hand frame on `/hand/joints` at log time `t` (episode seconds; the frame keeps
    /// its own `t` in the message).
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for a time before the last message, non-finite values, or a joint
    /// count that does not match `meta.hand`'s layout.
    pub fn write_hand_frame(&mut self, frame: &HandFrame, t: f64) -> Result<(), DemoError> {
        let ns = self.check_time(t, "hand frame")?;
        if let Some(h) = &self.meta.hand
            && frame.joints.len() != h.layout.joint_count()
        {
            return Err(DemoError::Invalid(format!(
                "hand frame has {} joints, layout {} has {}",
                frame.joints.len(),
                h.layout.name(),
                h.layout.joint_count()
            )));
        }
        if !frame.t.is_finite()
            || frame.joints.iter().flatten().any(|x| !x.is_finite())
            || frame.orientations.iter().flatten().flatten().any(|x| !x.is_finite())
        {
            return Err(DemoError::Invalid("hand frame has a non-finite value".into()));
        }
        let msg = HandMsg {
            t: frame.t,
            tracked: frame.tracked,
            joints: &frame.joints,
            orientations: frame.orientations.as_deref(),
        };
        let bytes = serde_json::to_vec(&msg).map_err(|e| DemoError::Invalid(e.to_string()))?;
        self.put(1, ns, &bytes)
    }

    /// Close the episode: an `episode_end` event, the `episode` metadata record (task, seed, robot,
    /// success, length, source hand log and its SHA-256, gesture model, format version, ...), the
    /// summary; then rename `PATH.partial` to `PATH`.
    ///
    /// # Errors
    /// [`DemoError::Mcap`] / [`DemoError::Io`] on write or rename failure.
    pub fn finish(mut self, summary: &EpisodeSummary) -> Result<WriteStats, DemoError> {
        let ns = log_time_ns(self.last_t)?.max(self.last_log_time);
        let name = if summary.success { "success" } else { "failure" };
        self.event_at(
            ns,
            name,
            vec![
                ("length", self.steps.to_string(), 3),
                ("total_reward", format!("{}", self.total_reward), 3),
            ],
        )?;
        let md = self.metadata_map(Some(summary));
        self.w
            .write_metadata(&mcap::records::Metadata { name: "episode".into(), metadata: md })
            .map_err(mcap_err(&self.partial))?;
        let s = self.w.finish().map_err(mcap_err(&self.partial))?;
        let DemoWriter { w, partial, final_path, steps, messages, .. } = self;
        // Flush the buffer and sync before the rename, so the final name never points at a short file.
        let file = w
            .into_inner()
            .into_inner()
            .map_err(|e| DemoError::Io { path: partial.clone(), source: e.into_error() })?;
        file.sync_all().map_err(|e| DemoError::Io { path: partial.clone(), source: e })?;
        let bytes = file.metadata().map(|m| m.len()).unwrap_or(0);
        drop(file);
        std::fs::rename(&partial, &final_path)
            .map_err(|e| DemoError::Io { path: final_path.clone(), source: e })?;
        let chunks = s.stats.as_ref().map(|st| st.chunk_count as u64).unwrap_or(0);
        Ok(WriteStats { path: final_path, steps, messages, chunks, bytes })
    }
}

fn metadata_map(
    m: &EpisodeMeta,
    model: &UrModel,
    handlog_sha256: Option<&str>,
    summary: Option<&EpisodeSummary>,
) -> BTreeMap<String, String> {
    let mut md = BTreeMap::new();
    for (k, v) in &m.extra {
        md.insert(k.clone(), v.clone());
    }
    md.insert("format".into(), DEMO_FORMAT.into());
    md.insert("format_version".into(), DEMO_FORMAT_VERSION.to_string());
    md.insert("step_schema".into(), schemas::STEP_SCHEMA_NAME.into());
    md.insert("episode".into(), m.episode.to_string());
    md.insert("task".into(), m.task.clone());
    md.insert("seed".into(), m.seed.to_string());
    md.insert("robot_model".into(), model.name.into());
    md.insert("gesture_model".into(), m.gesture_model.clone());
    md.insert("control_dt".into(), format!("{}", m.control_dt));
    md.insert(
        "source_handlog".into(),
        m.source_handlog.as_ref().map(|p| p.display().to_string()).unwrap_or_default(),
    );
    md.insert("source_handlog_sha256".into(), handlog_sha256.unwrap_or_default().to_string());
    if let Some(h) = &m.hand {
        md.insert("hand_layout".into(), h.layout.name().into());
        md.insert("hand_space".into(), h.space.name().into());
        md.insert("handedness".into(), h.handedness.name().into());
    }
    if let Some(s) = summary {
        for (k, v) in &s.extra {
            md.insert(k.clone(), v.clone());
        }
        md.insert("success".into(), s.success.to_string());
    }
    md
}

/// The first `/scene` message of a demo: `meta.scene` as handed, after the robot as
/// [`robot_link_entities`] unless the handed scene draws it (an entity id starting `robot/`).
fn first_scene(model: &UrModel, meta: &EpisodeMeta) -> Vec<SceneEntity> {
    let draws_robot = meta.scene.iter().any(|e| e.id.starts_with("robot/"));
    let mut v = if draws_robot { Vec::new() } else { robot_link_entities(model) };
    v.extend(meta.scene.iter().cloned());
    v
}

fn check_entity(e: &SceneEntity) -> Result<(), DemoError> {
    if e.primitives().any(|p| {
        !p.pose.is_finite()
            || p.size.iter().any(|x| !x.is_finite() || *x < 0.0)
            || p.color.iter().any(|c| !c.is_finite())
    }) {
        return Err(DemoError::Invalid(format!(
            "scene entity \"{}\": non-finite or negative pose/size/colour",
            e.id
        )));
    }
    Ok(())
}
