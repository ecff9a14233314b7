//! Bindings for demo-log (hand logs ↔ numpy, the MCAP `DemoWriter`, reading, salvage); keys,
//! defaults, shapes and checks are demo-log's.

use crate::errors::{demo_err, from_py, handlog_err, matrix, nd_from_py, nd_to_py, to_py, vector};
use demo_log::{
    DemoWriter as RsWriter, EpisodeMeta, EpisodeSummary, HandArrays, HandFrame, HandLog, HandLogHeader,
    ParseMode, ParseReport, Pose, SceneEntity, StepRecord, WriterOptions,
};
use numpy::{PyReadonlyArray1, PyReadonlyArrayDyn};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

type FDyn<'py> = PyReadonlyArrayDyn<'py, f64>;
type Dict<'py> = Bound<'py, PyDict>;
type Obj = Py<PyAny>;

fn handlog_to_py<'py>(py: Python<'py>, log: &HandLog, rep: &ParseReport) -> PyResult<Dict<'py>> {
    let (a, header) = (log.to_arrays(), to_py(py, &log.header_fields())?);
    let orientations = a.orientations.map(|o| nd_to_py(py, o)).transpose()?;
    Ok(dict!(py; "header" => header, "t" => nd_to_py(py, a.t)?, "tracked" => nd_to_py(py, a.tracked)?,
        "joints" => nd_to_py(py, a.joints)?, "orientations" => orientations, "report" => to_py(py, rep)?))
}

/// Parse a hand-log file → dict header, t, tracked, joints, orientations, report.
#[pyfunction]
#[pyo3(signature = (path, mode = "strict"))]
fn demo_parse_handlog<'py>(py: Python<'py>, path: PathBuf, mode: &str) -> PyResult<Dict<'py>> {
    let m = ParseMode::parse(mode).map_err(demo_err)?;
    let (log, rep) = py.detach(|| HandLog::from_path(&path, m)).map_err(handlog_err)?;
    handlog_to_py(py, &log, &rep)
}

/// Parse hand-log text; `name` is the file name used in error messages.
#[pyfunction]
#[pyo3(signature = (text, name = "<string>", mode = "strict"))]
fn demo_parse_handlog_str<'py>(py: Python<'py>, text: &str, name: &str, mode: &str) -> PyResult<Dict<'py>> {
    let (log, rep) =
        HandLog::parse_str(text, name, ParseMode::parse(mode).map_err(demo_err)?).map_err(handlog_err)?;
    handlog_to_py(py, &log, &rep)
}

/// Write a hand log atomically; invalid content raises `LogFormatError` and writes nothing.
#[pyfunction]
#[pyo3(signature = (path, header, t, tracked, joints, orientations = None))]
fn demo_write_handlog(
    py: Python<'_>,
    path: PathBuf,
    header: &Dict<'_>,
    t: PyReadonlyArrayDyn<'_, f64>,
    tracked: PyReadonlyArrayDyn<'_, bool>,
    joints: FDyn<'_>,
    orientations: Option<FDyn<'_>>,
) -> PyResult<()> {
    let header = HandLogHeader::from_fields(&from_py(header)?).map_err(demo_err)?;
    let (t, tracked, joints, orientations) =
        (nd_from_py(&t), nd_from_py(&tracked), nd_from_py(&joints), orientations.as_ref().map(nd_from_py));
    let a = HandArrays { t, tracked, joints, orientations };
    let log = HandLog::from_arrays(header, &a).map_err(demo_err)?;
    py.detach(|| log.write_jsonl(&path)).map_err(handlog_err)
}

/// A pose from `[x, y, z, qx, qy, qz, qw]` or a (4, 4) matrix (`demo_log::Pose::from_json`); a
/// value that is not numbers (NaN, infinity, a string, an object) is refused with its reason.
fn pose_from(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Pose> {
    let v = from_py(obj).map_err(|e| PyValueError::new_err(format!("{what}: {}", e.value(obj.py()))))?;
    Pose::from_json(&v, what).map_err(demo_err)
}

fn str_map(d: Option<&Dict<'_>>) -> PyResult<BTreeMap<String, String>> {
    d.map_or(Ok(BTreeMap::new()), |d| {
        d.iter().map(|(k, v)| Ok((k.extract()?, v.str()?.to_string()))).collect()
    })
}

/// The static scene of `env`'s episode (a `SimEnv`: its start, its spec).
fn scene_of(env: &Bound<'_, PyAny>) -> PyResult<tile_sim::Scene> {
    match env.cast::<crate::sim::SimEnv>() {
        Ok(e) => Ok(e.borrow().env_scene()),
        Err(_) => Err(PyTypeError::new_err(format!("env must be a SimEnv, not {}", env.get_type().name()?))),
    }
}

/// Records one episode into an MCAP demo (`path + ".partial"` until `finish`); a context manager.
#[pyclass(module = "mimicrete._native", name = "DemoWriter")]
pub struct PyDemoWriter {
    inner: Option<RsWriter>,
    /// The final path.
    #[pyo3(get)]
    path: PathBuf,
}

fn closed(path: &Path) -> PyErr {
    PyRuntimeError::new_err(format!("{}: the writer is closed", path.display()))
}

impl PyDemoWriter {
    pub(crate) fn open(&mut self) -> PyResult<&mut RsWriter> {
        self.inner.as_mut().ok_or_else(|| closed(&self.path))
    }
}

#[pymethods]
impl PyDemoWriter {
    #[new]
    #[pyo3(signature = (path, meta, chunk_size = 65536, flush_every_steps = 50, env = None))]
    fn new(
        path: PathBuf,
        meta: &Dict<'_>,
        chunk_size: u64,
        flush_every_steps: u64,
        env: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        let mut m = EpisodeMeta::from_json(&from_py(meta)?).map_err(demo_err)?;
        // demo-log records the scene it is handed: the robot and the task's (the env's own start
        // and spec when one is given, else the task's paper start for the seed), then meta's
        let env_scene = env.map(scene_of).transpose()?;
        if let Ok(model) = ur3_kin::UrModel::by_name(&m.robot_model) {
            m.scene = match &env_scene {
                Some(scene) => teleop_core::scene::env_demo_scene(model, scene, &m.scene),
                None => teleop_core::scene::demo_scene(model, &m.task, m.seed, &m.scene),
            };
        }
        let opts = WriterOptions { chunk_size, flush_every_steps, ..Default::default() };
        let w = RsWriter::create_with_options(&path, &m, opts).map_err(demo_err)?;
        Ok(PyDemoWriter { inner: Some(w), path })
    }

    /// Record one step; poses are [x, y, z, qx, qy, qz, qw] or (4, 4); `scene`: entity dicts;
    /// `row_poses`: a row's objects' poses (frames `tile_0` …), in row order.
    #[pyo3(signature = (step, t, obs, action, reward, terminated, truncated, gesture, joints, ee_pose, tile_pose, events = None, scene = None, row_poses = None))]
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
        row_poses: Option<Vec<Bound<'_, PyAny>>>,
    ) -> PyResult<()> {
        let scene = scene.map(|s| SceneEntity::list_from_json(&from_py(s)?, "scene").map_err(demo_err));
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
            row_poses: row_poses
                .unwrap_or_default()
                .iter()
                .enumerate()
                .map(|(i, p)| pose_from(p, &format!("row_poses[{i}]")))
                .collect::<PyResult<_>>()?,
            events: events.unwrap_or_default(),
            scene: scene.transpose()?.unwrap_or_default(),
        };
        self.open()?.write_step(&rec).map_err(demo_err)
    }

    /// Record a raw hand frame (J, 3) at episode time `t` (`hand_t`: the frame's own time).
    #[pyo3(signature = (t, joints, tracked = true, hand_t = None, orientations = None))]
    fn write_hand_frame(
        &mut self,
        t: f64,
        joints: FDyn<'_>,
        tracked: bool,
        hand_t: Option<f64>,
        orientations: Option<FDyn<'_>>,
    ) -> PyResult<()> {
        let o = orientations.as_ref().map(nd_from_py);
        let f = HandFrame::from_arrays(hand_t.unwrap_or(t), tracked, &nd_from_py(&joints), o.as_ref());
        self.open()?.write_hand_frame(&f.map_err(demo_err)?, t).map_err(demo_err)
    }

    /// Record an event (`"pick"`, `"install"`, `"fall"`, ...) at episode time `t`.
    #[pyo3(signature = (t, name, properties = None))]
    fn write_event(&mut self, t: f64, name: &str, properties: Option<&Dict<'_>>) -> PyResult<()> {
        let p = str_map(properties)?;
        self.open()?.write_event(t, name, &p).map_err(demo_err)
    }

    /// Record when a live control step's hand frame passed each stage (`/teleop/stage_times`):
    /// client times `capture_ms`, `sent_ms`, `page_recv_ms` (None: not acknowledged), server
    /// times `server_recv_ms`, `state_sent_ms` (None: the episode ended on the frame).
    #[pyo3(signature = (step, seq, capture_ms, sent_ms, server_recv_ms, state_sent_ms = None, page_recv_ms = None))]
    #[allow(clippy::too_many_arguments)]
    fn write_stage_times(
        &mut self,
        step: u64,
        seq: u64,
        capture_ms: f64,
        sent_ms: f64,
        server_recv_ms: f64,
        state_sent_ms: Option<f64>,
        page_recv_ms: Option<f64>,
    ) -> PyResult<()> {
        let st = demo_log::StageTimes {
            step,
            seq,
            capture_ms,
            sent_ms,
            server_recv_ms,
            state_sent_ms,
            page_recv_ms,
        };
        self.open()?.write_stage_times(&st).map_err(demo_err)
    }

    /// Record one deployment tick (`/deploy/tick`, ``mimicrete.DeployTick.v1``) from a dict of
    /// its fields (every field, no other; see the schema); written after the tick's step.
    fn write_deploy_tick(&mut self, tick: &Bound<'_, PyAny>) -> PyResult<()> {
        let v = from_py(tick)
            .map_err(|e| PyValueError::new_err(format!("deploy tick: {}", e.value(tick.py()))))?;
        let tick: demo_log::DeployTick = demo_log::serde_json::from_value(v)
            .map_err(|e| PyValueError::new_err(format!("deploy tick: {e}")))?;
        self.open()?.write_deploy_tick(&tick).map_err(demo_err)
    }

    /// Steps written so far.
    #[getter]
    fn steps(&self) -> u64 {
        self.inner.as_ref().map_or(0, RsWriter::steps)
    }

    /// End the episode and rename the file into place → dict path, steps, messages, chunks, bytes.
    #[pyo3(signature = (success, extra = None))]
    fn finish<'py>(
        &mut self,
        py: Python<'py>,
        success: bool,
        extra: Option<&Dict<'_>>,
    ) -> PyResult<Dict<'py>> {
        let summary = EpisodeSummary { success, extra: str_map(extra)? };
        let w = self.inner.take().ok_or_else(|| closed(&self.path))?;
        let s = py.detach(|| w.finish(&summary)).map_err(demo_err)?;
        let d = to_py(py, &s)?.cast_into::<PyDict>()?;
        d.set_item("path", &s.path)?;
        Ok(d)
    }

    /// Close without finishing: the file stays as `path + ".partial"` (valid, salvageable).
    fn abandon(&mut self) {
        self.inner = None;
    }

    fn __enter__(slf: Py<Self>) -> Py<Self> {
        slf
    }

    /// Finish (success False) when the block ends normally, abandon when it raises.
    #[pyo3(signature = (exc_type, _exc, _tb))]
    fn __exit__(&mut self, py: Python<'_>, exc_type: Obj, _exc: Obj, _tb: Obj) -> PyResult<bool> {
        match self.inner.is_some() && exc_type.is_none(py) {
            true => drop(self.finish(py, false, None)?),
            false => self.abandon(),
        }
        Ok(false)
    }
}

/// Read one demo → dict obs, actions, rewards, terminated, truncated, t, meta.
#[pyfunction]
fn demo_read<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Dict<'py>> {
    let e = py.detach(|| demo_log::read_demo(&path)).map_err(demo_err)?;
    let (obs, actions) = (matrix(py, e.obs, e.obs_dim)?, matrix(py, e.actions, e.act_dim)?);
    Ok(dict!(py; "obs" => obs, "actions" => actions, "rewards" => vector(py, e.rewards),
        "terminated" => vector(py, e.terminated), "truncated" => vector(py, e.truncated),
        "t" => vector(py, e.t), "meta" => e.meta))
}

/// A demo file or every `*.mcap` of a directory (sorted), concatenated, with episode, files, metas.
#[pyfunction]
fn demo_load<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Dict<'py>> {
    let d = py.detach(|| demo_log::load_dataset(&path)).map_err(demo_err)?;
    let (obs, actions) = (matrix(py, d.obs, d.obs_dim)?, matrix(py, d.actions, d.act_dim)?);
    let episode = vector(py, d.episode.iter().map(|&e| i64::from(e)).collect());
    // Paths, not text: a file name that is not UTF-8 must still name the file (Python: `str`
    // with surrogate escapes, via `os.fspath`).
    let files = d.files;
    Ok(dict!(py; "obs" => obs, "actions" => actions, "rewards" => vector(py, d.rewards),
        "terminated" => vector(py, d.terminated), "truncated" => vector(py, d.truncated),
        "episode" => episode, "files" => files, "metas" => d.metas))
}

/// Check a demo's integrity: `demo_log::VerifyReport` as a dict, plus ok.
#[pyfunction]
fn demo_verify<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyAny>> {
    let r = py.detach(|| demo_log::verify(&path)).map_err(demo_err)?;
    let d = to_py(py, &r)?;
    d.set_item("ok", r.is_ok())?;
    Ok(d)
}

/// Every complete message of a (possibly cut) demo (`RecoveredMessage` dicts) and the report.
#[pyfunction]
fn demo_salvage<'py>(py: Python<'py>, path: PathBuf) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let (msgs, rep) = py.detach(|| demo_log::salvage(&path)).map_err(demo_err)?;
    Ok((to_py(py, &msgs)?, to_py(py, &rep)?))
}

/// Rewrite what can be recovered from `path_in` as a valid MCAP file `path_out` → report dict.
#[pyfunction]
fn demo_salvage_to<'py>(py: Python<'py>, path_in: PathBuf, path_out: PathBuf) -> PyResult<Bound<'py, PyAny>> {
    let rep = py.detach(|| demo_log::salvage_to(&path_in, &path_out)).map_err(demo_err)?;
    to_py(py, &rep)
}

/// The `*.mcap` entries of a directory, sorted (`demo_log::demo_files`: whatever they are, so
/// that one that cannot be read is refused by name, not skipped).
#[pyfunction]
fn demo_files(path: PathBuf) -> PyResult<Vec<PathBuf>> {
    demo_log::demo_files(&path).map_err(demo_err)
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyDemoWriter>()?;
    add_functions!(m => demo_parse_handlog, demo_parse_handlog_str, demo_write_handlog, demo_read, demo_load,
        demo_salvage, demo_salvage_to, demo_verify, demo_files);
    m.add("DEMO_FORMAT_VERSION", demo_log::DEMO_FORMAT_VERSION)?;
    m.add("HANDLOG_VERSION", demo_log::HANDLOG_VERSION)?;
    Ok(())
}
