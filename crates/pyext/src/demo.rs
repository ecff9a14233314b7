//! Bindings for demo-log: hand logs ↔ numpy, the MCAP `DemoWriter`, demo reading and salvage.
//! No format logic lives here.
//!
//! Error mapping: malformed hand logs and demo files → `mimicrete.LogFormatError` (message
//! `file:line: reason` for hand logs, `file: reason` for demos); unreadable/unwritable files →
//! `OSError`; values the writer cannot record (NaN, decreasing time, bad shapes, unknown names) →
//! `ValueError`.

use crate::errors::LogFormatError;
use demo_log::{
    DemoError, DemoWriter as RsWriter, EpisodeMeta, EpisodeSummary, HandFrame, HandLog, HandLogError,
    HandLogHeader, ParseMode, ParseReport, Pose, SceneEntity, Shape, StepRecord, WriterOptions,
};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::exceptions::{PyOSError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use std::collections::BTreeMap;
use std::path::PathBuf;
use ur3_kin::{HandLayout, Handedness, Space};

fn handlog_err(e: HandLogError) -> PyErr {
    LogFormatError::new_err(e.to_string())
}

fn demo_err(e: DemoError) -> PyErr {
    match e {
        DemoError::Io { .. } => PyOSError::new_err(e.to_string()),
        DemoError::Invalid(_) => PyValueError::new_err(e.to_string()),
        DemoError::Format { .. } | DemoError::Mcap { .. } | DemoError::HandLog(_) => {
            LogFormatError::new_err(e.to_string())
        }
    }
}

fn mode(name: &str) -> PyResult<ParseMode> {
    ParseMode::from_name(name)
        .ok_or_else(|| PyValueError::new_err(format!("mode must be 'strict' or 'lenient', got {name:?}")))
}

fn header_dict<'py>(py: Python<'py>, h: &HandLogHeader) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("format", demo_log::HANDLOG_FORMAT)?;
    d.set_item("version", demo_log::HANDLOG_VERSION)?;
    d.set_item("layout", h.layout.name())?;
    d.set_item("space", h.space.name())?;
    d.set_item("handedness", h.handedness.name())?;
    d.set_item("units", "m")?;
    d.set_item("joint_count", h.layout.joint_count())?;
    d.set_item("task", h.task.clone())?;
    d.set_item("episode_seed", h.episode_seed)?;
    d.set_item("source", h.source.clone())?;
    let extra = match &h.extra {
        Some(m) => {
            let json = py.import("json")?;
            Some(json.call_method1("loads", (demo_log::serde_json::Value::Object(m.clone()).to_string(),))?)
        }
        None => None,
    };
    d.set_item("extra", extra)?;
    Ok(d)
}

fn report_dict<'py>(py: Python<'py>, r: &ParseReport) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("frame_lines", r.frame_lines)?;
    d.set_item("kept", r.kept)?;
    d.set_item("untracked_skipped", r.untracked_skipped)?;
    d.set_item("invalid_skipped", r.invalid_skipped)?;
    let skipped: Vec<(usize, String)> = r.skipped.iter().map(|s| (s.line, s.reason.clone())).collect();
    d.set_item("skipped", skipped)?;
    Ok(d)
}

fn handlog_to_py<'py>(py: Python<'py>, log: &HandLog, rep: &ParseReport) -> PyResult<Bound<'py, PyDict>> {
    let n = log.frames.len();
    let j = log.header.layout.joint_count();
    let t = Array1::from_iter(log.frames.iter().map(|f| f.t));
    let tracked = Array1::from_iter(log.frames.iter().map(|f| f.tracked));
    let joints = Array3::from_shape_fn((n, j, 3), |(i, k, c)| log.frames[i].joints[k][c]);
    let d = PyDict::new(py);
    d.set_item("header", header_dict(py, &log.header)?)?;
    d.set_item("t", t.into_pyarray(py))?;
    d.set_item("tracked", tracked.into_pyarray(py))?;
    d.set_item("joints", joints.into_pyarray(py))?;
    if n > 0 && log.frames.iter().all(|f| f.orientations.is_some()) {
        let o = Array3::from_shape_fn((n, j, 4), |(i, k, c)| {
            log.frames[i].orientations.as_ref().map(|o| o[k][c]).unwrap_or(f64::NAN)
        });
        d.set_item("orientations", o.into_pyarray(py))?;
    } else {
        d.set_item("orientations", py.None())?;
    }
    d.set_item("report", report_dict(py, rep)?)?;
    Ok(d)
}

/// Parse a hand-log file. Returns a dict: `header` (dict), `t` (T,) float64 s, `tracked` (T,)
/// bool, `joints` (T, J, 3) float64 m, `orientations` (T, J, 4) or None, `report` (dict:
/// frame_lines, kept, untracked_skipped, invalid_skipped, skipped [(line, reason)]).
/// Raises `LogFormatError("file:line: reason")`.
#[pyfunction]
#[pyo3(signature = (path, mode = "strict"))]
fn demo_parse_handlog<'py>(py: Python<'py>, path: PathBuf, mode: &str) -> PyResult<Bound<'py, PyDict>> {
    let m = self::mode(mode)?;
    let (log, rep) = py.detach(|| HandLog::from_path(&path, m)).map_err(handlog_err)?;
    handlog_to_py(py, &log, &rep)
}

/// Parse hand-log text; `name` is the file name used in error messages.
#[pyfunction]
#[pyo3(signature = (text, name = "<string>", mode = "strict"))]
fn demo_parse_handlog_str<'py>(
    py: Python<'py>,
    text: &str,
    name: &str,
    mode: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let m = self::mode(mode)?;
    let (log, rep) = HandLog::parse_str(text, name, m).map_err(handlog_err)?;
    handlog_to_py(py, &log, &rep)
}

fn header_from_dict(d: &Bound<'_, PyDict>) -> PyResult<HandLogHeader> {
    let get_str = |k: &str| -> PyResult<Option<String>> {
        match d.get_item(k)? {
            Some(v) if !v.is_none() => Ok(Some(v.extract()?)),
            _ => Ok(None),
        }
    };
    let need = |k: &str| -> PyResult<String> {
        get_str(k)?.ok_or_else(|| PyValueError::new_err(format!("hand header needs {k:?}")))
    };
    let layout = HandLayout::from_name(&need("layout")?).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let space = Space::from_name(&need("space")?).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let handedness =
        Handedness::from_name(&need("handedness")?).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let mut h = HandLogHeader::new(layout, space, handedness);
    h.task = get_str("task")?;
    h.source = get_str("source")?;
    h.episode_seed = match d.get_item("episode_seed")? {
        Some(v) if !v.is_none() => Some(v.extract()?),
        _ => None,
    };
    if let Some(v) = d.get_item("extra")?
        && !v.is_none()
    {
        let json = d.py().import("json")?;
        let text: String = json.call_method1("dumps", (v,))?.extract()?;
        match demo_log::serde_json::from_str(&text) {
            Ok(demo_log::serde_json::Value::Object(m)) => h.extra = Some(m),
            _ => return Err(PyValueError::new_err("hand header \"extra\" must be a JSON object (dict)")),
        }
    }
    Ok(h)
}

/// Write a hand log (atomically). `header` needs layout, space, handedness (task, episode_seed,
/// source, extra optional); `t` (T,), `tracked` (T,), `joints` (T, J, 3), `orientations`
/// (T, J, 4) or None. Raises `LogFormatError` for invalid content (nothing is written).
#[pyfunction]
#[pyo3(signature = (path, header, t, tracked, joints, orientations = None))]
fn demo_write_handlog(
    py: Python<'_>,
    path: PathBuf,
    header: &Bound<'_, PyDict>,
    t: PyReadonlyArray1<'_, f64>,
    tracked: PyReadonlyArray1<'_, bool>,
    joints: PyReadonlyArray3<'_, f64>,
    orientations: Option<PyReadonlyArray3<'_, f64>>,
) -> PyResult<()> {
    let header = header_from_dict(header)?;
    let (t, tracked, joints) = (t.as_array(), tracked.as_array(), joints.as_array());
    let n = t.len();
    let jc = header.layout.joint_count();
    if tracked.len() != n || joints.shape() != [n, jc, 3] {
        return Err(PyValueError::new_err(format!(
            "t (T,), tracked (T,), joints (T, {jc}, 3) expected for layout {}; got {:?}, {:?}, {:?}",
            header.layout.name(),
            t.shape(),
            tracked.shape(),
            joints.shape()
        )));
    }
    let o = orientations.as_ref().map(|o| o.as_array());
    if let Some(o) = &o
        && o.shape() != [n, jc, 4]
    {
        return Err(PyValueError::new_err(format!("orientations must be (T, {jc}, 4), got {:?}", o.shape())));
    }
    let frames = (0..n)
        .map(|i| HandFrame {
            t: t[i],
            tracked: tracked[i],
            joints: (0..jc).map(|k| [joints[[i, k, 0]], joints[[i, k, 1]], joints[[i, k, 2]]]).collect(),
            orientations: o
                .as_ref()
                .map(|o| (0..jc).map(|k| [o[[i, k, 0]], o[[i, k, 1]], o[[i, k, 2]], o[[i, k, 3]]]).collect()),
        })
        .collect();
    let log = HandLog { header, frames };
    py.detach(|| log.write_jsonl(&path)).map_err(handlog_err)
}

fn pose_from(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Pose> {
    if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f64>>() {
        let m = a.as_array();
        if m.shape() != [4, 4] {
            return Err(PyValueError::new_err(format!("{what} must be (7,) or (4, 4), got {:?}", m.shape())));
        }
        let mat = ur3_kin::nalgebra::Matrix4::from_fn(|r, c| m[[r, c]]);
        let p = ur3_kin::pose_from_matrix(&mat).map_err(|e| PyValueError::new_err(format!("{what}: {e}")))?;
        return Ok(Pose::from_isometry(&p));
    }
    let v: Vec<f64> = obj.extract().map_err(|_| {
        PyValueError::new_err(format!("{what} must be [x, y, z, qx, qy, qz, qw] or a (4, 4) matrix"))
    })?;
    if v.len() != 7 {
        return Err(PyValueError::new_err(format!(
            "{what} must be [x, y, z, qx, qy, qz, qw] (7 numbers), got {}",
            v.len()
        )));
    }
    Ok(Pose { position: [v[0], v[1], v[2]], orientation: [v[3], v[4], v[5], v[6]] })
}

fn entity_from(d: &Bound<'_, PyAny>) -> PyResult<SceneEntity> {
    let d = d.cast::<PyDict>().map_err(|_| PyValueError::new_err("a scene entity must be a dict"))?;
    let need = |k: &str| -> PyResult<Bound<'_, PyAny>> {
        d.get_item(k)?.ok_or_else(|| PyValueError::new_err(format!("scene entity needs {k:?}")))
    };
    let id: String = need("id")?.extract()?;
    let kind_name: String = need("kind")?.extract()?;
    let kind = Shape::from_name(&kind_name).ok_or_else(|| {
        PyValueError::new_err(format!("scene entity {id:?}: kind must be cube, cylinder or sphere"))
    })?;
    let size: [f64; 3] = need("size")?.extract()?;
    let pose = match d.get_item("pose")? {
        Some(p) => pose_from(&p, &format!("scene entity {id:?} pose"))?,
        None => Pose::IDENTITY,
    };
    let color: [f32; 4] = match d.get_item("color")? {
        Some(c) => c.extract()?,
        None => [0.7, 0.7, 0.7, 1.0],
    };
    let frame_id: String = match d.get_item("frame_id")? {
        Some(f) => f.extract()?,
        None => demo_log::BASE_FRAME.to_string(),
    };
    Ok(SceneEntity { id, frame_id, kind, size, pose, color })
}

fn str_map(d: Option<&Bound<'_, PyDict>>) -> PyResult<BTreeMap<String, String>> {
    let mut m = BTreeMap::new();
    if let Some(d) = d {
        for (k, v) in d.iter() {
            m.insert(k.extract::<String>()?, v.str()?.to_string());
        }
    }
    Ok(m)
}

fn meta_from(d: &Bound<'_, PyDict>) -> PyResult<EpisodeMeta> {
    let mut m = EpisodeMeta::default();
    for (k, v) in d.iter() {
        let key: String = k.extract()?;
        if v.is_none() {
            continue;
        }
        match key.as_str() {
            "episode" => m.episode = v.extract()?,
            "task" => m.task = v.extract()?,
            "seed" => m.seed = v.extract()?,
            "robot_model" => m.robot_model = v.extract()?,
            "source_handlog" => m.source_handlog = Some(v.extract()?),
            "gesture_model" => m.gesture_model = v.extract()?,
            "control_dt" => m.control_dt = v.extract()?,
            "hand" => {
                let hd =
                    v.cast::<PyDict>().map_err(|_| PyValueError::new_err("meta['hand'] must be a dict"))?;
                m.hand = Some(header_from_dict(hd)?);
            }
            "scene" => {
                for e in v.try_iter()? {
                    m.scene.push(entity_from(&e?)?);
                }
            }
            "extra" => {
                let ed =
                    v.cast::<PyDict>().map_err(|_| PyValueError::new_err("meta['extra'] must be a dict"))?;
                m.extra = str_map(Some(ed))?;
            }
            other => {
                return Err(PyValueError::new_err(format!(
                    "unknown episode meta key {other:?} (known: episode, task, seed, robot_model, \
                     source_handlog, gesture_model, control_dt, hand, scene, extra)"
                )));
            }
        }
    }
    Ok(m)
}

/// Records one episode into an MCAP demo (written as `path + ".partial"` until `finish`).
///
/// `DemoWriter(path, meta, chunk_size=65536, flush_every_steps=50)`; `meta` keys: episode,
/// task, seed, robot_model ("ur3"), source_handlog (path; hashed), gesture_model, control_dt,
/// hand (header dict: layout, space, handedness), scene (list of entity dicts: id, frame_id,
/// kind cube|cylinder|sphere, size [x,y,z] m, pose [x,y,z,qx,qy,qz,qw] or (4,4), color rgba),
/// extra (dict, values stringified). A context manager: leaving the block normally finishes
/// the episode with `success=False` if `finish` was not called; leaving it by an exception
/// abandons it (the `.partial` file stays, closed and salvageable).
#[pyclass(module = "mimicrete._native", name = "DemoWriter")]
pub struct PyDemoWriter {
    inner: Option<RsWriter>,
    path: PathBuf,
}

impl PyDemoWriter {
    fn w(&mut self) -> PyResult<&mut RsWriter> {
        self.inner
            .as_mut()
            .ok_or_else(|| PyRuntimeError::new_err(format!("{}: the writer is closed", self.path.display())))
    }
}

#[pymethods]
impl PyDemoWriter {
    #[new]
    #[pyo3(signature = (path, meta, chunk_size = 65536, flush_every_steps = 50))]
    fn new(
        path: PathBuf,
        meta: &Bound<'_, PyDict>,
        chunk_size: u64,
        flush_every_steps: u64,
    ) -> PyResult<Self> {
        let m = meta_from(meta)?;
        let opts = WriterOptions { chunk_size, flush_every_steps, ..Default::default() };
        let w = RsWriter::create_with_options(&path, &m, opts).map_err(demo_err)?;
        Ok(PyDemoWriter { inner: Some(w), path })
    }

    /// Record one step. `obs`, `action`: 1-D float32 arrays; `joints` (6,) rad; `ee_pose`,
    /// `tile_pose`: [x, y, z, qx, qy, qz, qw] or (4, 4); `events`: names ("pick", "install",
    /// "fall"); `scene`: entity dicts to add/replace.
    #[pyo3(signature = (step, t, obs, action, reward, terminated, truncated, gesture, joints, ee_pose, tile_pose, events = None, scene = None))]
    #[allow(clippy::too_many_arguments)]
    fn write_step(
        &mut self,
        step: u64,
        t: f64,
        obs: PyReadonlyArray1<'_, f32>,
        action: PyReadonlyArray1<'_, f32>,
        reward: f64,
        terminated: bool,
        truncated: bool,
        gesture: String,
        joints: [f64; 6],
        ee_pose: &Bound<'_, PyAny>,
        tile_pose: &Bound<'_, PyAny>,
        events: Option<Vec<String>>,
        scene: Option<&Bound<'_, PyList>>,
    ) -> PyResult<()> {
        let mut sc = Vec::new();
        if let Some(s) = scene {
            for e in s.iter() {
                sc.push(entity_from(&e)?);
            }
        }
        let rec = StepRecord {
            step,
            t,
            obs: obs.as_array().iter().copied().collect(),
            action: action.as_array().iter().copied().collect(),
            reward,
            terminated,
            truncated,
            gesture,
            joints,
            ee_pose: pose_from(ee_pose, "ee_pose")?,
            tile_pose: pose_from(tile_pose, "tile_pose")?,
            events: events.unwrap_or_default(),
            scene: sc,
        };
        self.w()?.write_step(&rec).map_err(demo_err)
    }

    /// Record a raw hand frame at episode time `t`: `joints` (J, 3) m; `hand_t` is the frame's
    /// own log time (defaults to `t`); `orientations` (J, 4) or None.
    #[pyo3(signature = (t, joints, tracked = true, hand_t = None, orientations = None))]
    fn write_hand_frame(
        &mut self,
        t: f64,
        joints: PyReadonlyArray2<'_, f64>,
        tracked: bool,
        hand_t: Option<f64>,
        orientations: Option<PyReadonlyArray2<'_, f64>>,
    ) -> PyResult<()> {
        let j = joints.as_array();
        if j.ndim() != 2 || j.shape()[1] != 3 {
            return Err(PyValueError::new_err(format!("joints must be (J, 3), got {:?}", j.shape())));
        }
        let o = match &orientations {
            Some(o) => {
                let o = o.as_array();
                if o.shape() != [j.shape()[0], 4] {
                    return Err(PyValueError::new_err(format!(
                        "orientations must be ({}, 4), got {:?}",
                        j.shape()[0],
                        o.shape()
                    )));
                }
                Some(o.rows().into_iter().map(|r| [r[0], r[1], r[2], r[3]]).collect())
            }
            None => None,
        };
        let f = HandFrame {
            t: hand_t.unwrap_or(t),
            tracked,
            joints: j.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect(),
            orientations: o,
        };
        self.w()?.write_hand_frame(&f, t).map_err(demo_err)
    }

    /// Record an event (`"pick"`, `"install"`, `"fall"`, ...) at episode time `t`.
    #[pyo3(signature = (t, name, properties = None))]
    fn write_event(&mut self, t: f64, name: &str, properties: Option<&Bound<'_, PyDict>>) -> PyResult<()> {
        let p = str_map(properties)?;
        self.w()?.write_event(t, name, &p).map_err(demo_err)
    }

    /// Steps written so far.
    #[getter]
    fn steps(&self) -> u64 {
        self.inner.as_ref().map(|w| w.steps()).unwrap_or(0)
    }

    /// The final path.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// End the episode (metadata record, summary) and rename the file into place. Returns a
    /// dict: path, steps, messages, chunks, bytes.
    #[pyo3(signature = (success, extra = None))]
    fn finish<'py>(
        &mut self,
        py: Python<'py>,
        success: bool,
        extra: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let summary = EpisodeSummary { success, extra: str_map(extra)? };
        self.w()?;
        let w = self.inner.take().expect("checked above");
        let s = py.detach(|| w.finish(&summary)).map_err(demo_err)?;
        let d = PyDict::new(py);
        d.set_item("path", s.path)?;
        d.set_item("steps", s.steps)?;
        d.set_item("messages", s.messages)?;
        d.set_item("chunks", s.chunks)?;
        d.set_item("bytes", s.bytes)?;
        Ok(d)
    }

    /// Close without finishing: the file stays as `path + ".partial"` (valid, salvageable).
    fn abandon(&mut self) {
        self.inner = None;
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    #[pyo3(signature = (exc_type, _exc, _tb))]
    fn __exit__(
        &mut self,
        py: Python<'_>,
        exc_type: Option<&Bound<'_, PyAny>>,
        _exc: Option<&Bound<'_, PyAny>>,
        _tb: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<bool> {
        if self.inner.is_some() {
            if exc_type.is_some_and(|e| !e.is_none()) {
                self.abandon();
            } else {
                self.finish(py, false, None)?;
            }
        }
        Ok(false)
    }
}

fn meta_dict<'py>(py: Python<'py>, m: &BTreeMap<String, String>) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    for (k, v) in m {
        d.set_item(k, v)?;
    }
    Ok(d)
}

/// Read one demo: dict obs (T, obs_dim) float32, actions (T, act_dim) float32, rewards (T,)
/// float32, terminated (T,) bool, truncated (T,) bool, t (T,) float64, meta (dict of str).
#[pyfunction]
fn demo_read<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let ep = py.detach(|| demo_log::read_demo(&path)).map_err(demo_err)?;
    let n = ep.len();
    let d = PyDict::new(py);
    let obs =
        Array2::from_shape_vec((n, ep.obs_dim), ep.obs).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let act = Array2::from_shape_vec((n, ep.act_dim), ep.actions)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    d.set_item("obs", obs.into_pyarray(py))?;
    d.set_item("actions", act.into_pyarray(py))?;
    d.set_item("rewards", Array1::from(ep.rewards).into_pyarray(py))?;
    d.set_item("terminated", Array1::from(ep.terminated).into_pyarray(py))?;
    d.set_item("truncated", Array1::from(ep.truncated).into_pyarray(py))?;
    d.set_item("t", Array1::from(ep.t).into_pyarray(py))?;
    d.set_item("meta", meta_dict(py, &ep.meta)?)?;
    Ok(d)
}

/// Read a demo file or every `*.mcap` of a directory (sorted by name), concatenated: dict obs
/// (N, obs_dim) float32, actions (N, act_dim) float32, rewards (N,) float32, terminated (N,)
/// bool, truncated (N,) bool, episode (N,) int64 (index into files), files (list of str),
/// metas (list of dict).
#[pyfunction]
fn demo_load<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let ds = py.detach(|| demo_log::load_dataset(&path)).map_err(demo_err)?;
    let n = ds.rewards.len();
    let d = PyDict::new(py);
    let obs =
        Array2::from_shape_vec((n, ds.obs_dim), ds.obs).map_err(|e| PyValueError::new_err(e.to_string()))?;
    let act = Array2::from_shape_vec((n, ds.act_dim), ds.actions)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    d.set_item("obs", obs.into_pyarray(py))?;
    d.set_item("actions", act.into_pyarray(py))?;
    d.set_item("rewards", Array1::from(ds.rewards).into_pyarray(py))?;
    d.set_item("terminated", Array1::from(ds.terminated).into_pyarray(py))?;
    d.set_item("truncated", Array1::from(ds.truncated).into_pyarray(py))?;
    d.set_item("episode", Array1::from_iter(ds.episode.iter().map(|&e| e as i64)).into_pyarray(py))?;
    let files: Vec<String> = ds.files.iter().map(|f| f.display().to_string()).collect();
    d.set_item("files", files)?;
    let metas = PyList::empty(py);
    for m in &ds.metas {
        metas.append(meta_dict(py, m)?)?;
    }
    d.set_item("metas", metas)?;
    Ok(d)
}

fn salvage_report<'py>(py: Python<'py>, r: &demo_log::SalvageReport) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("bytes_total", r.bytes_total)?;
    d.set_item("bytes_used", r.bytes_used)?;
    d.set_item("chunks_ok", r.chunks_ok)?;
    d.set_item("chunks_lost", r.chunks_lost)?;
    d.set_item("messages", r.messages)?;
    d.set_item("metadata", r.metadata)?;
    d.set_item("attachments", r.attachments)?;
    d.set_item("complete", r.complete)?;
    d.set_item("stopped_because", r.stopped_because.clone())?;
    d.set_item("lost_chunks", chunk_list(py, &r.lost_chunks)?)?;
    d.set_item("step_gaps", r.step_gaps.clone())?;
    d.set_item("messages_unattributed", r.messages_unattributed)?;
    d.set_item("layout_assumed", r.layout_assumed)?;
    Ok(d)
}

fn chunk_list<'py>(py: Python<'py>, chunks: &[demo_log::ChunkCheck]) -> PyResult<Bound<'py, PyList>> {
    let out = PyList::empty(py);
    for c in chunks {
        let d = PyDict::new(py);
        d.set_item("index", c.index)?;
        d.set_item("offset", c.offset)?;
        d.set_item("length", c.length)?;
        d.set_item("messages", c.messages)?;
        d.set_item("log_time_start", c.log_times.map(|t| t.0))?;
        d.set_item("log_time_end", c.log_times.map(|t| t.1))?;
        d.set_item("error", c.error.clone())?;
        d.set_item("recoverable", c.recoverable)?;
        out.append(d)?;
    }
    Ok(out)
}

/// Check a demo's integrity (every chunk's CRC, the data-section and summary CRCs, completeness):
/// dict ok, bytes, complete, chunks (list of dicts index, offset, length, messages,
/// log_time_start, log_time_end, error, recoverable), skipped (list of (start, end, reason)),
/// data_crc_ok, summary_problem, messages_ok, messages_lost, problems (list of str).
#[pyfunction]
fn demo_verify<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let r = py.detach(|| demo_log::verify(&path)).map_err(demo_err)?;
    let d = PyDict::new(py);
    d.set_item("ok", r.is_ok())?;
    d.set_item("bytes", r.bytes)?;
    d.set_item("complete", r.complete)?;
    d.set_item("chunks", chunk_list(py, &r.chunks)?)?;
    d.set_item("skipped", r.skipped.clone())?;
    d.set_item("data_crc_ok", r.data_crc_ok)?;
    d.set_item("summary_problem", r.summary_problem.clone())?;
    d.set_item("messages_ok", r.messages_ok)?;
    d.set_item("messages_lost", r.messages_lost)?;
    d.set_item("problems", r.problems.clone())?;
    Ok(d)
}

/// Every complete message of a (possibly cut) demo: (list of dicts topic, schema_name,
/// log_time ns, sequence, data bytes; report dict).
#[pyfunction]
fn demo_salvage<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Bound<'py, PyList>, Bound<'py, PyDict>)> {
    let (msgs, rep) = py.detach(|| demo_log::salvage(&path)).map_err(demo_err)?;
    let out = PyList::empty(py);
    for m in &msgs {
        let d = PyDict::new(py);
        d.set_item("topic", &m.topic)?;
        d.set_item("schema_name", &m.schema_name)?;
        d.set_item("log_time", m.log_time)?;
        d.set_item("sequence", m.sequence)?;
        d.set_item("data", PyBytes::new(py, &m.data))?;
        out.append(d)?;
    }
    Ok((out, salvage_report(py, &rep)?))
}

/// Rewrite what can be recovered from `path_in` as a valid MCAP file `path_out`; returns the
/// report dict.
#[pyfunction]
fn demo_salvage_to<'py>(
    py: Python<'py>,
    path_in: PathBuf,
    path_out: PathBuf,
) -> PyResult<Bound<'py, PyDict>> {
    let rep = py.detach(|| demo_log::salvage_to(&path_in, &path_out)).map_err(demo_err)?;
    salvage_report(py, &rep)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDemoWriter>()?;
    m.add_function(wrap_pyfunction!(demo_parse_handlog, m)?)?;
    m.add_function(wrap_pyfunction!(demo_parse_handlog_str, m)?)?;
    m.add_function(wrap_pyfunction!(demo_write_handlog, m)?)?;
    m.add_function(wrap_pyfunction!(demo_read, m)?)?;
    m.add_function(wrap_pyfunction!(demo_load, m)?)?;
    m.add_function(wrap_pyfunction!(demo_salvage, m)?)?;
    m.add_function(wrap_pyfunction!(demo_salvage_to, m)?)?;
    m.add_function(wrap_pyfunction!(demo_verify, m)?)?;
    m.add("DEMO_FORMAT_VERSION", demo_log::DEMO_FORMAT_VERSION)?;
    m.add("HANDLOG_VERSION", demo_log::HANDLOG_VERSION)?;
    Ok(())
}
