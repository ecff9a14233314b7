//! Episode metadata, scene entities, poses and hand headers from JSON values: the one place that
//! knows their keys, defaults and messages (the Python binding converts a dict to JSON and calls
//! these).

use crate::DemoError;
use crate::handlog::HandLogHeader;
use crate::writer::{BASE_FRAME, EpisodeMeta, Pose, SceneEntity, Shape};
use serde_json::{Map, Value};
use ur3_kin::{HandLayout, Handedness, Space};

/// The keys of an episode-metadata object, in documentation order.
pub const EPISODE_META_KEYS: [&str; 11] = [
    "episode",
    "task",
    "seed",
    "robot_model",
    "source_handlog",
    "source_handlog_sha256",
    "gesture_model",
    "control_dt",
    "hand",
    "scene",
    "extra",
];

/// Colour of a scene entity that names none (light grey, opaque).
pub const DEFAULT_ENTITY_COLOR: [f32; 4] = [0.7, 0.7, 0.7, 1.0];

fn invalid(msg: impl Into<String>) -> DemoError {
    DemoError::Invalid(msg.into())
}

fn typed<T: serde::de::DeserializeOwned>(v: &Value, what: &str) -> Result<T, DemoError> {
    serde_json::from_value(v.clone()).map_err(|e| invalid(format!("{what}: {e}")))
}

fn object<'a>(v: &'a Value, what: &str) -> Result<&'a Map<String, Value>, DemoError> {
    v.as_object().ok_or_else(|| invalid(format!("{what} must be a dict")))
}

/// A JSON value as the text stored in a string map: strings as they are, anything else as JSON.
pub fn value_text(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

impl Pose {
    /// A pose from 7 numbers `[x, y, z, qx, qy, qz, qw]` or 16 (a 4×4 homogeneous matrix, row by
    /// row, checked to be a rigid transform); `what` names it in errors.
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for another count or a matrix that is not a rigid transform.
    pub fn from_numbers(v: &[f64], what: &str) -> Result<Pose, DemoError> {
        match v.len() {
            7 => Ok(Pose { position: [v[0], v[1], v[2]], orientation: [v[3], v[4], v[5], v[6]] }),
            16 => {
                let m = ur3_kin::nalgebra::Matrix4::from_fn(|r, c| v[r * 4 + c]);
                let p = ur3_kin::pose_from_matrix(&m).map_err(|e| invalid(format!("{what}: {e}")))?;
                Ok(Pose::from_isometry(&p))
            }
            n => Err(invalid(format!("{what} must be [x, y, z, qx, qy, qz, qw] (7 numbers), got {n}"))),
        }
    }

    /// `[x, y, z, qx, qy, qz, qw]`: the 7 numbers [`Pose::from_numbers`] reads.
    pub fn to_numbers(&self) -> [f64; 7] {
        std::array::from_fn(|i| if i < 3 { self.position[i] } else { self.orientation[i - 3] })
    }

    /// [`Pose::from_numbers`] of a JSON array of 7 numbers or of 4 rows of 4.
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for any other value.
    pub fn from_json(v: &Value, what: &str) -> Result<Pose, DemoError> {
        let bad = || invalid(format!("{what} must be [x, y, z, qx, qy, qz, qw] or a (4, 4) matrix"));
        let rows = v.as_array().ok_or_else(bad)?;
        let mut flat = Vec::with_capacity(16);
        for r in rows {
            match r {
                Value::Array(cols) if cols.len() == 4 && rows.len() == 4 => flat
                    .extend(cols.iter().map(|c| c.as_f64().ok_or_else(bad)).collect::<Result<Vec<_>, _>>()?),
                n => flat.push(n.as_f64().ok_or_else(bad)?),
            }
        }
        Pose::from_numbers(&flat, what)
    }
}

impl SceneEntity {
    /// An entity from a JSON object: `id`, `kind` (`cube` | `cylinder` | `sphere`) and `size`
    /// required; `frame_id` (default [`BASE_FRAME`]), `pose` (7 numbers or a 4×4 matrix, default
    /// identity) and `color` (default [`DEFAULT_ENTITY_COLOR`]) optional.
    ///
    /// # Errors
    /// [`DemoError::Invalid`] naming the entity and the field.
    pub fn from_json(v: &Value) -> Result<SceneEntity, DemoError> {
        let m = object(v, "a scene entity")?;
        let need = |k: &str| m.get(k).ok_or_else(|| invalid(format!("scene entity needs {k:?}")));
        let id: String = typed(need("id")?, "scene entity id")?;
        let kind_name: String = typed(need("kind")?, &format!("scene entity {id:?} kind"))?;
        let kind = Shape::from_name(&kind_name)
            .ok_or_else(|| invalid(format!("scene entity {id:?}: kind must be cube, cylinder or sphere")))?;
        let size: [f64; 3] = typed(need("size")?, &format!("scene entity {id:?} size"))?;
        let pose = match m.get("pose") {
            Some(p) if !p.is_null() => Pose::from_json(p, &format!("scene entity {id:?} pose"))?,
            _ => Pose::IDENTITY,
        };
        let color = match m.get("color") {
            Some(c) if !c.is_null() => typed(c, &format!("scene entity {id:?} color"))?,
            _ => DEFAULT_ENTITY_COLOR,
        };
        let frame_id = match m.get("frame_id") {
            Some(f) if !f.is_null() => typed(f, &format!("scene entity {id:?} frame_id"))?,
            _ => BASE_FRAME.to_string(),
        };
        Ok(SceneEntity { id, frame_id, kind, size, pose, color, extra: Vec::new() })
    }

    /// A list of entities ([`SceneEntity::from_json`] each); `what` names the list in errors.
    ///
    /// # Errors
    /// [`DemoError::Invalid`] when `v` is not a list or an entity is invalid.
    pub fn list_from_json(v: &Value, what: &str) -> Result<Vec<SceneEntity>, DemoError> {
        let items = v.as_array().ok_or_else(|| invalid(format!("{what} must be a list")))?;
        items.iter().map(SceneEntity::from_json).collect()
    }
}

impl HandLogHeader {
    /// A header from a JSON object with `layout`, `space`, `handedness` (required) and `task`,
    /// `episode_seed`, `source`, `extra` (optional; `null` = absent). Other keys (`format`,
    /// `version`, `units`, `joint_count`, as [`HandLogHeader::to_json`] writes them) are ignored.
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for a missing or unknown required field or a non-object `extra`.
    pub fn from_fields(v: &Value) -> Result<HandLogHeader, DemoError> {
        let m = object(v, "a hand header")?;
        let get = |k: &str| m.get(k).filter(|x| !x.is_null());
        let need = |k: &str| -> Result<String, DemoError> {
            get(k).ok_or_else(|| invalid(format!("hand header needs {k:?}"))).and_then(|x| typed(x, k))
        };
        let e = |e: ur3_kin::KinError| invalid(e.to_string());
        let mut h = HandLogHeader::new(
            HandLayout::from_name(&need("layout")?).map_err(e)?,
            Space::from_name(&need("space")?).map_err(e)?,
            Handedness::from_name(&need("handedness")?).map_err(e)?,
        );
        h.task = get("task").map(|x| typed(x, "task")).transpose()?;
        h.source = get("source").map(|x| typed(x, "source")).transpose()?;
        h.episode_seed = get("episode_seed").map(|x| typed(x, "episode_seed")).transpose()?;
        h.extra = match get("extra") {
            None => None,
            Some(Value::Object(o)) => Some(o.clone()),
            Some(_) => return Err(invalid("hand header \"extra\" must be a JSON object (dict)")),
        };
        Ok(h)
    }
}

impl EpisodeMeta {
    /// Metadata from a JSON object with any of [`EPISODE_META_KEYS`] (`null` = the default);
    /// absent keys keep [`EpisodeMeta::default`]. `extra` values are stored as text
    /// ([`value_text`]).
    ///
    /// # Errors
    /// [`DemoError::Invalid`] for an unknown key (named, with the known ones) or a value of the
    /// wrong type.
    pub fn from_json(v: &Value) -> Result<EpisodeMeta, DemoError> {
        let mut meta = EpisodeMeta::default();
        for (key, v) in object(v, "episode meta")? {
            if v.is_null() {
                continue;
            }
            let what = format!("meta[{key:?}]");
            match key.as_str() {
                "episode" => meta.episode = typed(v, &what)?,
                "task" => meta.task = typed(v, &what)?,
                "seed" => meta.seed = typed(v, &what)?,
                "robot_model" => meta.robot_model = typed(v, &what)?,
                "source_handlog" => meta.source_handlog = Some(typed(v, &what)?),
                "source_handlog_sha256" => meta.source_handlog_sha256 = Some(typed(v, &what)?),
                "gesture_model" => meta.gesture_model = typed(v, &what)?,
                "control_dt" => meta.control_dt = typed(v, &what)?,
                "hand" => meta.hand = Some(HandLogHeader::from_fields(v)?),
                "scene" => meta.scene = SceneEntity::list_from_json(v, &what)?,
                "extra" => {
                    meta.extra = object(v, &what)?.iter().map(|(k, x)| (k.clone(), value_text(x))).collect();
                }
                other => {
                    return Err(invalid(format!(
                        "unknown episode meta key {other:?} (known: {})",
                        EPISODE_META_KEYS.join(", ")
                    )));
                }
            }
        }
        Ok(meta)
    }
}

/// Check the values of a demo's `episode_start` / `episode` metadata record that readers rely on
/// (an exporter takes its frame rate from `control_dt` and its success flag from `success`):
/// `success` and `terminated` are `true` or `false`; `episode`, `seed`, `length`, `obs_dim`,
/// `act_dim` and `format_version` are non-negative integers; `control_dt` and `total_reward` are
/// finite numbers (`control_dt` ≥ 0); `format` is [`crate::DEMO_FORMAT`]. Absent keys are not
/// checked (an unfinished demo has no `success`). [`crate::read_demo`] refuses a record that
/// fails and [`crate::verify`] lists it as a problem, so loading and inspecting agree.
///
/// # Errors
/// The first bad value, in words: `success is "tpue", not true or false`.
pub fn check_episode_record(md: &std::collections::BTreeMap<String, String>) -> Result<(), String> {
    for key in ["success", "terminated"] {
        if let Some(v) = md.get(key)
            && v != "true"
            && v != "false"
        {
            return Err(format!("{key} is {v:?}, not true or false"));
        }
    }
    for key in ["episode", "seed", "length", "obs_dim", "act_dim", "format_version"] {
        if let Some(v) = md.get(key)
            && v.parse::<u64>().is_err()
        {
            return Err(format!("{key} is {v:?}, not a non-negative integer"));
        }
    }
    for key in ["control_dt", "total_reward"] {
        if let Some(v) = md.get(key) {
            let ok = v.parse::<f64>().is_ok_and(|x| x.is_finite() && (key != "control_dt" || x >= 0.0));
            if !ok {
                let want = if key == "control_dt" { "a finite number ≥ 0" } else { "a finite number" };
                return Err(format!("{key} is {v:?}, not {want}"));
            }
        }
    }
    if let Some(v) = md.get("format")
        && v != crate::DEMO_FORMAT
    {
        return Err(format!("format is {v:?}, not {:?}", crate::DEMO_FORMAT));
    }
    Ok(())
}

/// The metadata records whose values [`check_episode_record`] checks.
pub const CHECKED_RECORDS: [&str; 2] = ["episode_start", "episode"];
