//! demo-log: hand logs in, MCAP demonstrations out.
//!
//! # Hand logs (input): JSON Lines, `mimicrete.handlog` version 1
//!
//! Line 1 is the header:
//!
//! ```json
//! {"format":"mimicrete.handlog","version":1,"layout":"openxr","space":"openxr","handedness":"right","units":"m",
//!  "task":"suction","episode_seed":7,"source":"synth","extra":{}}
//! ```
//!
//! `layout` ∈ `openxr` (26 joints), `webxr` (25), `meta_ovr` (24), `mediapipe` (21); `space` ∈
//! `openxr`, `webxr`, `unity`, `robot_base`; `handedness` ∈ `left`, `right`; `units` must be `m`.
//! `task`, `episode_seed` (u64), `source` (string) and `extra` (object) are optional; any other key
//! is an error. Every further line is one frame:
//!
//! ```json
//! {"t":0.0133,"tracked":true,"joints":[[x,y,z], ...],"orientations":[[x,y,z,w], ...]}
//! ```
//!
//! `t` in seconds, non-decreasing; `joints` has exactly `layout.joint_count()` entries, each
//! coordinate at most [`MAX_COORD_M`] (10 km) from the origin; `orientations` is optional. A key
//! may appear only once in an object (JSON leaves duplicates to the reader: here they are an
//! error, not "the last one wins"). Blank lines are ignored. Errors are [`HandLogError`], displayed
//! `file:line: reason` (1-based lines): missing/unknown header or header field, unknown layout,
//! space, handedness or units, wrong joint count, NaN/±Infinity (also Python's bare `NaN` tokens),
//! time going backwards, a truncated last line (no final newline and not valid JSON).
//! [`ParseMode::Strict`] stops at the first bad line and returns nothing; [`ParseMode::Lenient`]
//! skips bad and untracked frames and lists them in the [`ParseReport`].
//!
//! # Demonstrations (output): one MCAP file per episode
//!
//! zstd chunks (closed every 64 KiB or 50 steps), log times = episode seconds in ns, never
//! decreasing; no wall-clock anywhere, so the same input gives the same bytes. Channels, all
//! `json` encoded with `jsonschema` schemas:
//!
//! | topic | schema | content |
//! |---|---|---|
//! | `/demo/step` | `mimicrete.DemoStep.v1` | episode, step, t, obs (f32), action (f32), reward, terminated, truncated, gesture, joints (6, rad), ee_pose, tile_pose |
//! | `/hand/joints` | `mimicrete.HandFrame.v1` | the raw hand frame (its own `t`, tracked, joints, orientations); channel metadata: layout, space, handedness |
//! | `/tf` | `foxglove.FrameTransforms` | `base` → URDF links (`shoulder_link` … `wrist_3_link`, `flange`, `tool0`) from the step's joints, and `base` → `tile` |
//! | `/scene` | `foxglove.SceneUpdate` | on the first step: the scene the caller hands ([`EpisodeMeta::scene`]; the bindings hand the simulator's through teleop-core's `scene::demo_scene`: the UR3 as tile-sim's arm capsules locked to the URDF links, table, pad, target, end effector locked to `tool0`, object locked to `tile`), after the robot as cylinders between the links' origins ([`robot_link_entities`]) when the handed scene has no `robot/` entities; later: per-step entity updates |
//! | `/events` | `foxglove.Event` | `gesture_change`, caller events (`pick`, `install`, `fall`), and `success`/`failure` at the end |
//!
//! Metadata records: `episode_start` (written first: format, format_version, episode, task, seed,
//! robot_model, gesture_model, control_dt, source_handlog, source_handlog_sha256, hand layout)
//! and `episode` (written by [`DemoWriter::finish`]: the same plus success, length, total_reward,
//! obs_dim, act_dim, terminated). Attachment `<model>.urdf` (`ur3.urdf`): the robot description from
//! `ur3_kin::urdf::to_urdf_string`.
//!
//! The writer writes `PATH.partial` and renames it on finish. [`verify`] checks every chunk's CRC,
//! the data-section and summary CRCs and names the damaged chunks. [`salvage`] / [`salvage_to`]
//! give back every message of every intact chunk of a cut or damaged file, wherever the damage is;
//! [`salvage_to`] declares the lost steps so that the result loads. [`read_demo`] /
//! [`load_dataset`] turn demos into flat arrays.

mod arrays;
mod files;
mod frames;
mod handlog;
mod meta;
mod reader;
mod salvage;
mod scan;
pub mod schemas;
mod writer;

pub use arrays::{HandArrays, NdArray, shape_text};
pub use files::read_input;
pub use frames::{frame_numbers, frame_poses};
pub use handlog::{
    HANDLOG_FORMAT, HANDLOG_VERSION, HandFrame, HandLog, HandLogError, HandLogHeader, MAX_COORD_M, ParseMode,
    ParseReport, SkippedLine, frame_json,
};
pub use meta::{DEFAULT_ENTITY_COLOR, EPISODE_META_KEYS, check_episode_record, value_text};
pub use reader::{Dataset, Episode, demo_files, load_dataset, read_demo, read_demo_bytes};
pub use salvage::{
    ChunkCheck, RecoveredMessage, SalvageReport, Salvaged, VerifyReport, salvage, salvage_bytes, salvage_to,
    verify, verify_bytes,
};
/// The URDF links' parent-to-child transforms (ur3-kin's; `/tf` publishes them).
pub use ur3_kin::urdf::link_transforms;
pub use writer::{
    BASE_FRAME, DEMO_FORMAT, DEMO_FORMAT_VERSION, DemoWriter, DeployTick, EpisodeMeta, EpisodeSummary,
    LINK_FRAMES, Pose, Primitive, ROW_FRAMES, SceneEntity, Shape, StageTimes, StepRecord, TILE_FRAME,
    TOPIC_DEPLOY_TICK, TOPIC_EVENTS, TOPIC_HAND, TOPIC_SCENE, TOPIC_STAGE_TIMES, TOPIC_STEP, TOPIC_TF,
    WriteStats, WriterOptions, foxglove_entity, log_time_ns, robot_link_entities, sha256_hex,
};

/// Re-exported so that bindings can build the `extra` objects of hand-log headers.
pub use serde_json;

use std::path::{Path, PathBuf};

/// Errors of the demo writer, reader and salvage.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// A file could not be read or written.
    #[error("{path}: {source}", path = path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The MCAP library refused a write.
    #[error("{path}: MCAP error: {source}", path = path.display())]
    Mcap {
        /// The file.
        path: PathBuf,
        /// The library's error.
        source: mcap::McapError,
    },
    /// A demo file is malformed.
    #[error("{path}: {reason}", path = path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The caller passed something the writer cannot record.
    #[error("{0}")]
    Invalid(String),
    /// A hand log is malformed.
    #[error(transparent)]
    HandLog(#[from] HandLogError),
}

/// `PATH` + `.partial` (the name a file has while it is being written).
pub fn partial_path(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_os_string();
    s.push(".partial");
    PathBuf::from(s)
}
