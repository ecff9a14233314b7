//! Bindings for demo-log: hand logs ↔ numpy, the MCAP `DemoWriter`, demo reading and salvage.
//! Dicts cross as JSON values (`errors::{from_py, to_py}`); their keys, defaults and checks are
//! demo-log's (`EpisodeMeta::from_json`, `HandLogHeader::from_fields`, `Pose::from_numbers`).
//! Errors: `errors::{handlog_err, demo_err}`.

use crate::errors::{demo_err, from_py, handlog_err, to_py};
use demo_log::{
    DemoWriter as RsWriter, EpisodeMeta, EpisodeSummary, HandFrame, HandLog, HandLogHeader, ParseMode,
    ParseReport, Pose, StepRecord, WriterOptions,
};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use std::collections::BTreeMap;
use std::path::PathBuf;

fn mode(name: &str) -> PyResult<ParseMode> {
    ParseMode::from_name(name)
        .ok_or_else(|| PyValueError::new_err(format!("mode must be 'strict' or 'lenient', got {name:?}")))
}

fn handlog_to_py<'py>(py: Python<'py>, log: &HandLog, rep: &ParseReport) -> PyResult<Bound<'py, PyDict>> {
    let (n, j) = (log.frames.len(), log.header.layout.joint_count());
    let d = PyDict::new(py);
    let h = to_py(py, &log.header.to_json())?;
    for k in ["task", "episode_seed", "source", "extra"] {
        if !h.contains(k)? {
            h.set_item(k, py.None())?;
        }
    }
    h.set_item("joint_count", j)?;
    d.set_item("header", h)?;
    d.set_item("t", Array1::from_iter(log.frames.iter().map(|f| f.t)).into_pyarray(py))?;
    d.set_item("tracked", Array1::from_iter(log.frames.iter().map(|f| f.tracked)).into_pyarray(py))?;
    d.set_item(
        "joints",
        Array3::from_shape_fn((n, j, 3), |(i, k, c)| log.frames[i].joints[k][c]).into_pyarray(py),
    )?;
    let o = log.frames.iter().map(|f| f.orientations.as_ref()).collect::<Option<Vec<_>>>().filter(|_| n > 0);
    match o {
        Some(o) => d.set_item(
            "orientations",
            Array3::from_shape_fn((n, j, 4), |(i, k, c)| o[i][k][c]).into_pyarray(py),
        )?,
        None => d.set_item("orientations", py.None())?,
    }
    d.set_item("report", to_py(py, rep)?)?;
    Ok(d)
}

/// Parse a hand-log file → dict header, t, tracked, joints, orientations, report.
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
    let (log, rep) = HandLog::parse_str(text, name, self::mode(mode)?).map_err(handlog_err)?;
    handlog_to_py(py, &log, &rep)
}

/// Write a hand log atomically; invalid content raises `LogFormatError` and writes nothing.
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
    let header = HandLogHeader::from_fields(&from_py(header)?).map_err(demo_err)?;
    let (t, tracked, joints) = (t.as_array(), tracked.as_array(), joints.as_array());
    let (n, jc) = (t.len(), header.layout.joint_count());
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
            joints: (0..jc).map(|k| std::array::from_fn(|c| joints[[i, k, c]])).collect(),
            orientations: o
                .as_ref()
                .map(|o| (0..jc).map(|k| std::array::from_fn(|c| o[[i, k, c]])).collect()),
        })
        .collect();
    let log = HandLog { header, frames };
    py.detach(|| log.write_jsonl(&path)).map_err(handlog_err)
}

/// A pose from `[x, y, z, qx, qy, qz, qw]` or a (4, 4) matrix (`demo_log::Pose::from_numbers`).
fn pose_from(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Pose> {
    let flat: Vec<f64> = match obj.extract::<PyReadonlyArray2<'_, f64>>() {
        Ok(a) => a.as_array().iter().copied().collect(),
        Err(_) => obj.extract().map_err(|_| {
            PyValueError::new_err(format!("{what} must be [x, y, z, qx, qy, qz, qw] or a (4, 4) matrix"))
        })?,
    };
    Pose::from_numbers(&flat, what).map_err(demo_err)
}

fn str_map(d: Option<&Bound<'_, PyDict>>) -> PyResult<BTreeMap<String, String>> {
    d.map_or(Ok(BTreeMap::new()), |d| {
        d.iter().map(|(k, v)| Ok((k.extract()?, v.str()?.to_string()))).collect()
    })
}

/// Records one episode into an MCAP demo (`path + ".partial"` until `finish`); a context manager.
#[pyclass(module = "mimicrete._native", name = "DemoWriter")]
pub struct PyDemoWriter {
    inner: Option<RsWriter>,
    path: PathBuf,
}

impl PyDemoWriter {
    fn w(&mut self) -> PyResult<&mut RsWriter> {
        let p = &self.path;
        self.inner
            .as_mut()
            .ok_or_else(|| PyRuntimeError::new_err(format!("{}: the writer is closed", p.display())))
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
        let m = EpisodeMeta::from_json(&from_py(meta)?).map_err(demo_err)?;
        let opts = WriterOptions { chunk_size, flush_every_steps, ..Default::default() };
        let w = RsWriter::create_with_options(&path, &m, opts).map_err(demo_err)?;
        Ok(PyDemoWriter { inner: Some(w), path })
    }

    /// Record one step; poses are [x, y, z, qx, qy, qz, qw] or (4, 4); `scene`: entity dicts.
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
        let scene = scene.map_or(Ok(Vec::new()), |s| {
            s.iter().map(|e| demo_log::SceneEntity::from_json(&from_py(&e)?).map_err(demo_err)).collect()
        })?;
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
            scene,
        };
        self.w()?.write_step(&rec).map_err(demo_err)
    }

    /// Record a raw hand frame (J, 3) at episode time `t` (`hand_t`: the frame's own time).
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
        if j.shape()[1] != 3 {
            return Err(PyValueError::new_err(format!("joints must be (J, 3), got {:?}", j.shape())));
        }
        let o = orientations.as_ref().map(|o| o.as_array());
        if let Some(o) = &o
            && o.shape() != [j.shape()[0], 4]
        {
            let msg = format!("orientations must be ({}, 4), got {:?}", j.shape()[0], o.shape());
            return Err(PyValueError::new_err(msg));
        }
        let f = HandFrame {
            t: hand_t.unwrap_or(t),
            tracked,
            joints: j.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect(),
            orientations: o.map(|o| o.rows().into_iter().map(|r| [r[0], r[1], r[2], r[3]]).collect()),
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
        self.inner.as_ref().map_or(0, RsWriter::steps)
    }

    /// The final path.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// End the episode and rename the file into place → dict path, steps, messages, chunks, bytes.
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

fn f32_rows<'py>(
    py: Python<'py>,
    v: Vec<f32>,
    n: usize,
    d: usize,
) -> PyResult<Bound<'py, numpy::PyArray2<f32>>> {
    Ok(Array2::from_shape_vec((n, d), v).map_err(|e| PyValueError::new_err(e.to_string()))?.into_pyarray(py))
}

/// Read one demo → dict obs, actions, rewards, terminated, truncated, t, meta.
#[pyfunction]
fn demo_read<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let ep = py.detach(|| demo_log::read_demo(&path)).map_err(demo_err)?;
    let n = ep.len();
    let d = PyDict::new(py);
    d.set_item("obs", f32_rows(py, ep.obs, n, ep.obs_dim)?)?;
    d.set_item("actions", f32_rows(py, ep.actions, n, ep.act_dim)?)?;
    d.set_item("rewards", Array1::from(ep.rewards).into_pyarray(py))?;
    d.set_item("terminated", Array1::from(ep.terminated).into_pyarray(py))?;
    d.set_item("truncated", Array1::from(ep.truncated).into_pyarray(py))?;
    d.set_item("t", Array1::from(ep.t).into_pyarray(py))?;
    d.set_item("meta", ep.meta)?;
    Ok(d)
}

/// A demo file or every `*.mcap` of a directory (sorted), concatenated, with episode, files, metas.
#[pyfunction]
fn demo_load<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let ds = py.detach(|| demo_log::load_dataset(&path)).map_err(demo_err)?;
    let n = ds.rewards.len();
    let d = PyDict::new(py);
    d.set_item("obs", f32_rows(py, ds.obs, n, ds.obs_dim)?)?;
    d.set_item("actions", f32_rows(py, ds.actions, n, ds.act_dim)?)?;
    d.set_item("rewards", Array1::from(ds.rewards).into_pyarray(py))?;
    d.set_item("terminated", Array1::from(ds.terminated).into_pyarray(py))?;
    d.set_item("truncated", Array1::from(ds.truncated).into_pyarray(py))?;
    d.set_item("episode", Array1::from_iter(ds.episode.iter().map(|&e| e as i64)).into_pyarray(py))?;
    d.set_item("files", ds.files.iter().map(|f| f.display().to_string()).collect::<Vec<_>>())?;
    d.set_item("metas", ds.metas)?;
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

/// Rewrite what can be recovered from `path_in` as a valid MCAP file `path_out` → report dict.
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
