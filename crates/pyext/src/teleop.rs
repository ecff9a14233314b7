//! Bindings for teleop-core: one call per hand frame (`TeleopSession.push`), the session's state
//! as plain values; the loop, its checks and its numbers are teleop-core's.

use crate::demo::PyDemoWriter;
use crate::errors::{demo_err, kin_err, sim_err, to_py};
use crate::kin::Calib;
use crate::sim::{parse_task, read_spec};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use teleop_core::{ClutchInput, Frame, Mapping, Recorder, Session, SessionConfig, Step, TeleopError};
use ur3_kin::{HandLayout, Handedness};

type Any<'py> = Bound<'py, PyAny>;
/// `(index, t, obs, action, reward, terminated, truncated, events, why)` of one control step.
type StepTuple<'py> = (
    u64,
    f64,
    Bound<'py, PyArray1<f32>>,
    Bound<'py, PyArray1<f32>>,
    f32,
    bool,
    bool,
    Vec<&'static str>,
    Option<&'static str>,
);

fn teleop_err(e: TeleopError) -> PyErr {
    match e {
        TeleopError::Sim(e) => sim_err(e),
        TeleopError::Demo(e) => demo_err(e),
        e => PyValueError::new_err(e.to_string()),
    }
}

fn points(joints: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<[f64; 3]>> {
    let a = joints.as_array();
    if a.shape()[1] != 3 {
        return Err(PyValueError::new_err(format!("joints must be (J, 3), got {:?}", a.shape())));
    }
    Ok(a.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

fn clutch_input(c: Option<&str>) -> PyResult<Option<ClutchInput>> {
    match c {
        None => Ok(None),
        Some("engage") => Ok(Some(ClutchInput::Engage)),
        Some("release") => Ok(Some(ClutchInput::Release)),
        Some(o) => Err(PyValueError::new_err(format!("clutch must be 'engage' or 'release', got {o:?}"))),
    }
}

fn step_tuple(py: Python<'_>, s: Step) -> StepTuple<'_> {
    let why = s.why.map(|w| w.text());
    (
        s.index,
        s.t,
        s.obs.into_pyarray(py),
        s.action.into_pyarray(py),
        s.reward,
        s.terminated,
        s.truncated,
        s.events,
        why,
    )
}

/// One teleoperation episode (teleop-core's `Session`): `TeleopSession(task, layout, handedness,
/// calibration, seed, writer=None)`; every step is recorded into `writer` (a `DemoWriter`).
#[pyclass(module = "mimicrete._native", name = "TeleopSession")]
pub struct PyTeleopSession {
    core: Session,
    writer: Option<Py<PyDemoWriter>>,
}

impl PyTeleopSession {
    /// Run `f` with the recorder (the writer, borrowed for the call) if there is one.
    fn with_recorder<T>(
        &mut self,
        py: Python<'_>,
        f: impl FnOnce(&mut Session, Option<&mut dyn Recorder>) -> Result<T, TeleopError>,
    ) -> PyResult<T> {
        match &self.writer {
            None => f(&mut self.core, None).map_err(teleop_err),
            Some(w) => {
                let mut w = w.borrow_mut(py);
                let rec = w.open()?;
                f(&mut self.core, Some(rec)).map_err(teleop_err)
            }
        }
    }
}

#[pymethods]
impl PyTeleopSession {
    #[new]
    #[pyo3(signature = (task, layout, handedness, calibration, seed, writer = None, mapping = "absolute", task_file = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        task: &str,
        layout: &str,
        handedness: &str,
        calibration: Calib<'_>,
        seed: u64,
        writer: Option<Py<PyDemoWriter>>,
        mapping: &str,
        task_file: Option<&str>,
    ) -> PyResult<Self> {
        let mapping = Mapping::from_name(mapping).ok_or_else(|| {
            PyValueError::new_err(format!("mapping must be 'absolute' or 'clutch', got {mapping:?}"))
        })?;
        let cfg = SessionConfig {
            task: parse_task(task)?,
            layout: HandLayout::from_name(layout).map_err(kin_err)?,
            handedness: Handedness::from_name(handedness).map_err(kin_err)?,
            calibration: calibration.get()?,
            seed,
            mapping,
            spec: task_file.map(read_spec).transpose()?.map(std::sync::Arc::new),
        };
        Ok(PyTeleopSession { core: Session::new(cfg).map_err(teleop_err)?, writer })
    }

    /// Feed one hand frame `joints` (J, 3) at time `t` with its gesture class `raw` and the
    /// smoothed `gesture` after it → (the control steps that fell due, the page's view or None).
    #[pyo3(signature = (t, tracked, joints, raw, gesture, view = false, clutch = None))]
    #[allow(clippy::too_many_arguments)]
    fn push<'py>(
        &mut self,
        py: Python<'py>,
        t: f64,
        tracked: bool,
        joints: PyReadonlyArray2<'py, f64>,
        raw: Option<&str>,
        gesture: Option<&str>,
        view: bool,
        clutch: Option<&str>,
    ) -> PyResult<(Vec<StepTuple<'py>>, Option<Any<'py>>)> {
        let pts = points(&joints)?;
        let frame = Frame { t, tracked, joints: &pts, raw, gesture, clutch: clutch_input(clutch)? };
        let steps = self.with_recorder(py, |s, rec| s.push(&frame, rec))?;
        let steps = steps.into_iter().map(|s| step_tuple(py, s)).collect();
        Ok((steps, if view { Some(self.view(py)?) } else { None }))
    }

    /// The hand half of `push` alone: the gesture and the target from one frame, no steps.
    #[pyo3(signature = (t, tracked, joints, raw, gesture, clutch = None))]
    #[allow(clippy::too_many_arguments)]
    fn observe(
        &mut self,
        py: Python<'_>,
        t: f64,
        tracked: bool,
        joints: PyReadonlyArray2<'_, f64>,
        raw: Option<&str>,
        gesture: Option<&str>,
        clutch: Option<&str>,
    ) -> PyResult<()> {
        let pts = points(&joints)?;
        let frame = Frame { t, tracked, joints: &pts, raw, gesture, clutch: clutch_input(clutch)? };
        self.with_recorder(py, |s, rec| s.observe_only(&frame, rec))
    }

    /// The hand stream has ended: the control steps up to one period past the last frame.
    fn finish<'py>(&mut self, py: Python<'py>) -> PyResult<Vec<StepTuple<'py>>> {
        let steps = self.with_recorder(py, |s, rec| s.finish(rec))?;
        Ok(steps.into_iter().map(|s| step_tuple(py, s)).collect())
    }

    /// What the page draws now: `frames` (`{frame_id: [x, y, z, qx, qy, qz, qw]}` in Base, one
    /// FK of the joints), the simulator's `snapshot` and the `target` (7 numbers, or None).
    fn view<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        let (snap, frames) = (self.core.snapshot(), self.core.frame_numbers());
        let d = dict!(py; "frames" => to_py(py, &frames)?, "snapshot" => to_py(py, &snap)?,
            "target" => self.core.target_pose().map(|p| p.to_numbers()));
        Ok(d.into_any())
    }

    /// Use `calibration` from the next frame on; `shift` (3,) moves the current target with it.
    #[pyo3(signature = (calibration, shift = None))]
    fn set_calibration(&mut self, calibration: Calib<'_>, shift: Option<[f64; 3]>) -> PyResult<()> {
        self.core.set_calibration(calibration.get()?, shift);
        Ok(())
    }

    /// The frames' counts (`frames`, `untracked`, ... , `gestures`: class → frames, first seen first).
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = self.core.counts();
        let g = PyDict::new(py);
        for (k, v) in &c.gestures {
            g.set_item(k, v)?;
        }
        Ok(dict!(py; "frames" => c.frames, "untracked" => c.untracked, "degenerate" => c.degenerate,
            "unreachable" => c.unreachable, "steps" => c.steps, "frames_after_end" => c.frames_after_end,
            "gesture_changes" => c.gesture_changes, "gestures" => g))
    }

    /// The tool0 target (4, 4) in Base of the newest usable frame, or None.
    #[getter]
    fn target<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.core.target().map(|m| Array2::from_shape_fn((4, 4), |(r, c)| m[(r, c)]).into_pyarray(py))
    }

    /// The clutch is engaged (always False under the absolute mapping).
    #[getter]
    fn engaged(&self) -> bool {
        self.core.engaged()
    }

    /// The smoothed gesture the end effector obeys (None before any).
    #[getter]
    fn gesture(&self) -> Option<String> {
        self.core.gesture().map(str::to_string)
    }

    /// The end-effector command and spin of the smoothed gesture.
    #[getter]
    fn command(&self) -> (f32, f32) {
        self.core.command()
    }

    #[getter]
    fn step_index(&self) -> u64 {
        self.core.step_index()
    }

    /// Why the newest step did not follow the hand (None: it did, or no step yet).
    #[getter]
    fn last_why(&self) -> Option<&'static str> {
        self.core.last_why().map(|w| w.text())
    }

    /// The newest frame's tracked flag (None before any).
    #[getter]
    fn last_tracked(&self) -> Option<bool> {
        self.core.last_tracked()
    }

    /// The newest observation.
    #[getter]
    fn observation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        self.core.observation().to_vec().into_pyarray(py)
    }

    /// `{steps, picked, installed, fell, terminated, truncated, total_reward}`.
    #[getter]
    fn outcome<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let o = self.core.outcome();
        Ok(dict!(py; "steps" => o.steps, "picked" => o.picked, "installed" => o.installed, "fell" => o.fell,
            "terminated" => o.terminated, "truncated" => o.truncated, "total_reward" => o.total_reward))
    }

    /// The simulator's state (`SimEnv.snapshot` without the links).
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        to_py(py, &self.core.snapshot())
    }

    /// Test/tool API: teleport the arm to joint angles `q` (6,) rad.
    fn set_joints(&mut self, q: [f64; 6]) -> PyResult<()> {
        self.core.set_joints(q).map_err(teleop_err)
    }

    /// `scene_frames` of the current state: URDF links at the arm's joints, `tile` at the object.
    fn scene_frames(&self) -> std::collections::BTreeMap<&'static str, [f64; 7]> {
        self.core.frame_numbers()
    }

    /// The Foxglove `SceneEntity` list of the episode (its start's pad, target, plate).
    fn scene_entities<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        to_py(
            py,
            &teleop_core::scene::scene_json(self.core.env().arm().name, &self.core.env().scene())
                .map_err(demo_err)?,
        )
    }
}

/// The gesture classes and their (command, spin), teleop-core's table.
#[pyfunction]
fn teleop_gesture_commands() -> Vec<(&'static str, f32, f32)> {
    teleop_core::GESTURE_COMMANDS.to_vec()
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyTeleopSession>()?;
    add_functions!(m => teleop_gesture_commands);
    m.add("TELEOP_BRANCH_JUMP", teleop_core::BRANCH_JUMP)?;
    Ok(())
}
