//! Bindings for tile-sim: `SimEnv` (one world) and `SimVecEnv` (N worlds stepped across threads
//! with the interpreter lock released). Conversion and error mapping only; no simulation here.
//!
//! Shapes (f32 unless noted): single env obs `(obs_dim,)`, action `(act_dim,)`; vector env obs
//! `(num_envs, obs_dim)`, actions `(num_envs, act_dim)`, per-env scalars `(num_envs,)`.
//! Error mapping: wrong action/obs shapes, unknown task names, NaN actions and invalid states →
//! `ValueError` naming the expected shape; stepping a finished episode → `mimicrete.SimError`.

use crate::errors::SimError as PySimError;
use numpy::ndarray::{Array1, Array2};
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray2, PyArrayLikeDyn, PyReadonlyArrayDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use tile_sim::{Env, PoseRec, SceneFrame, Shape, SimError, StepBuffers, Task, VecEnv};

fn sim_err(e: SimError) -> PyErr {
    match e {
        SimError::EpisodeOver => PySimError::new_err(e.to_string()),
        other => PyValueError::new_err(other.to_string()),
    }
}

fn parse_task(name: &str) -> PyResult<Task> {
    Task::from_name(name).map_err(sim_err)
}

fn pose_dict<'py>(py: Python<'py>, p: &PoseRec) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("t", p.t.to_vec())?;
    d.set_item("q", p.q.to_vec())?;
    Ok(d)
}

fn snapshot_dict<'py>(py: Python<'py>, env: &Env) -> PyResult<Bound<'py, PyDict>> {
    let s = env.snapshot();
    let d = PyDict::new(py);
    d.set_item("task", s.task.name())?;
    d.set_item("q", s.q.to_vec())?;
    d.set_item("tool0", pose_dict(py, &s.tool0)?)?;
    d.set_item("tcp", pose_dict(py, &s.tcp)?)?;
    d.set_item("object", pose_dict(py, &s.object)?)?;
    d.set_item("target", pose_dict(py, &s.target)?)?;
    d.set_item("suction_on", s.suction_on)?;
    d.set_item("held", s.held)?;
    d.set_item("gripper_width", s.gripper_width)?;
    d.set_item("spin", s.spin)?;
    d.set_item("spin_angle", s.spin_angle)?;
    d.set_item("step", s.step)?;
    d.set_item("episode_seed", s.episode_seed)?;
    d.set_item("picked", s.picked)?;
    d.set_item("done", s.done)?;
    let links = PyList::empty(py);
    for p in env.link_poses().iter() {
        links.append(pose_dict(py, p)?)?;
    }
    d.set_item("links", links)?;
    Ok(d)
}

fn scene_list<'py>(py: Python<'py>, env: &Env) -> PyResult<Bound<'py, PyList>> {
    let l = PyList::empty(py);
    for it in env.scene().items {
        let d = PyDict::new(py);
        d.set_item("name", it.name)?;
        let frame = match it.frame {
            SceneFrame::World => "world".to_string(),
            SceneFrame::Link(i) => format!("link{i}"),
            SceneFrame::Object => "object".to_string(),
        };
        d.set_item("frame", frame)?;
        match it.shape {
            Shape::Box { half } => {
                d.set_item("kind", "box")?;
                d.set_item("half_extents", half.to_vec())?;
            }
            Shape::Cylinder { radius, half_height } => {
                d.set_item("kind", "cylinder")?;
                d.set_item("radius", radius)?;
                d.set_item("half_height", half_height)?;
            }
            Shape::Capsule { a, b, radius } => {
                d.set_item("kind", "capsule")?;
                d.set_item("a", a.to_vec())?;
                d.set_item("b", b.to_vec())?;
                d.set_item("radius", radius)?;
            }
        }
        d.set_item("translation", it.translation.to_vec())?;
        d.set_item("rotation", it.rotation.to_vec())?;
        d.set_item("rgba", it.rgba.to_vec())?;
        l.append(d)?;
    }
    Ok(l)
}

fn flat_f32(a: &PyArrayLikeDyn<'_, f32, AllowTypeChange>, shape: &[usize], what: &str) -> PyResult<Vec<f32>> {
    let v = a.as_array();
    if v.shape() != shape {
        let fmt = |s: &[usize]| match s {
            [a] => format!("({a},)"),
            _ => format!("({})", s.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(", ")),
        };
        return Err(PyValueError::new_err(format!(
            "{what} must have shape {}, got {}",
            fmt(shape),
            fmt(v.shape())
        )));
    }
    Ok(v.iter().copied().collect())
}

/// `(obs, reward, terminated, truncated, info)` of `SimEnv.step`.
type StepTuple<'py> = (Bound<'py, PyArray1<f32>>, f32, bool, bool, Bound<'py, PyDict>);

/// One simulated environment. `SimEnv(task, seed=0)`; task "TileSuction" | "BlockGrip" |
/// "Screw" (or "suction" | "grip" | "screw").
#[pyclass(module = "mimicrete._native")]
pub struct SimEnv {
    env: Env,
    obs: Vec<f32>,
}

#[pymethods]
impl SimEnv {
    #[new]
    #[pyo3(signature = (task, seed = 0))]
    fn new(task: &str, seed: u64) -> PyResult<Self> {
        let t = parse_task(task)?;
        Ok(SimEnv { env: Env::new(t, seed), obs: vec![0.0; t.obs_dim()] })
    }

    #[getter]
    fn task(&self) -> &'static str {
        self.env.task().name()
    }
    #[getter]
    fn obs_dim(&self) -> usize {
        self.env.task().obs_dim()
    }
    #[getter]
    fn obs_frame_dim(&self) -> usize {
        self.env.task().obs_frame_dim()
    }
    #[getter]
    fn act_dim(&self) -> usize {
        self.env.task().act_dim()
    }

    /// Start an episode (`seed=None`: next seed from the env's RNG) → obs `(obs_dim,)`.
    #[pyo3(signature = (seed = None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>) -> PyResult<Bound<'py, PyArray1<f32>>> {
        self.env.reset(seed, &mut self.obs).map_err(sim_err)?;
        Ok(Array1::from(self.obs.clone()).into_pyarray(py))
    }

    /// One step → `(obs, reward, terminated, truncated, info)`; info holds `picked`
    /// (ever this episode), `held`, `installed`, `fell`, `step`.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        action: PyArrayLikeDyn<'py, f32, AllowTypeChange>,
    ) -> PyResult<StepTuple<'py>> {
        let ad = self.env.task().act_dim();
        let a = flat_f32(&action, &[ad], "action")?;
        let out = self.env.step(&a, &mut self.obs).map_err(sim_err)?;
        let info = PyDict::new(py);
        info.set_item("picked", out.picked)?;
        info.set_item("held", out.held)?;
        info.set_item("installed", out.installed)?;
        info.set_item("fell", out.fell)?;
        info.set_item("step", self.env.snapshot().step)?;
        Ok((Array1::from(self.obs.clone()).into_pyarray(py), out.reward, out.terminated, out.truncated, info))
    }

    /// The current stacked observation `(obs_dim,)`.
    fn observation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        Array1::from(self.env.observation().to_vec()).into_pyarray(py)
    }

    /// State for demo recording (poses: `t` metres, `q` quaternion `[x, y, z, w]`, Base frame).
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        snapshot_dict(py, &self.env)
    }

    /// Scene items (dicts: name, frame "world"|"linkN"|"object", kind, sizes, translation,
    /// rotation `[x, y, z, w]`, rgba).
    fn scene<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        scene_list(py, &self.env)
    }

    /// Test/tool API: teleport the arm to joint angles `q` (6,) rad.
    fn set_joints(&mut self, q: PyReadonlyArrayDyn<'_, f64>) -> PyResult<()> {
        let v = q.as_array();
        if v.shape() != [6] {
            return Err(PyValueError::new_err(format!("q must have shape (6,), got {:?}", v.shape())));
        }
        self.env.set_joints(std::array::from_fn(|i| v[i])).map_err(sim_err)
    }

    /// Test/tool API: teleport the object to translation `t` (3,) and quaternion `q` (4,) [x,y,z,w].
    fn set_object_pose(&mut self, t: [f64; 3], q: [f64; 4]) -> PyResult<()> {
        self.env.set_object_pose(t, q).map_err(sim_err)
    }
}

/// N environments stepped in one call across `num_threads` threads (GIL released), same-step
/// auto-reset. `SimVecEnv(task, num_envs, seed=0, num_threads=2)`; env i is created with
/// seed `seed + i`.
#[pyclass(module = "mimicrete._native")]
pub struct SimVecEnv {
    venv: VecEnv,
    buf: StepBuffers,
    actions: Vec<f32>,
}

#[pymethods]
impl SimVecEnv {
    #[new]
    #[pyo3(signature = (task, num_envs, seed = 0, num_threads = 2))]
    fn new(task: &str, num_envs: usize, seed: u64, num_threads: usize) -> PyResult<Self> {
        let t = parse_task(task)?;
        let venv = VecEnv::new(t, num_envs, seed, num_threads).map_err(sim_err)?;
        Ok(SimVecEnv { venv, buf: StepBuffers::new(t, num_envs), actions: vec![0.0; num_envs * t.act_dim()] })
    }

    #[getter]
    fn task(&self) -> &'static str {
        self.venv.task().name()
    }
    #[getter]
    fn num_envs(&self) -> usize {
        self.venv.num_envs()
    }
    #[getter]
    fn num_threads(&self) -> usize {
        self.venv.num_threads()
    }
    #[getter]
    fn obs_dim(&self) -> usize {
        self.venv.task().obs_dim()
    }
    #[getter]
    fn act_dim(&self) -> usize {
        self.venv.task().act_dim()
    }

    /// Reset all envs (`seed`: env i gets `seed + i`; None: each env's own RNG) →
    /// obs `(num_envs, obs_dim)`.
    #[pyo3(signature = (seed = None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let (n, od) = (self.venv.num_envs(), self.venv.task().obs_dim());
        let mut obs = vec![0.0; n * od];
        self.venv.reset(seed, &mut obs).map_err(sim_err)?;
        to2(py, obs, n, od)
    }

    /// Reset the envs where `mask` (num_envs,) is true → obs `(num_envs, obs_dim)` (rows of
    /// the other envs hold their current observation).
    fn reset_mask<'py>(
        &mut self,
        py: Python<'py>,
        mask: PyArrayLikeDyn<'py, bool, AllowTypeChange>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let (n, od) = (self.venv.num_envs(), self.venv.task().obs_dim());
        let m = mask.as_array();
        if m.shape() != [n] {
            return Err(PyValueError::new_err(format!("mask must have shape ({n},), got {:?}", m.shape())));
        }
        let mv: Vec<bool> = m.iter().copied().collect();
        let mut obs = vec![0.0; n * od];
        self.venv.reset_mask(&mv, &mut obs).map_err(sim_err)?;
        to2(py, obs, n, od)
    }

    /// Reset env `i` to episode `seed` and replay `actions` (k, act_dim) in it (a recorded
    /// episode's first k steps); the other envs do not move → env `i`'s observation (obs_dim,).
    fn reset_replay<'py>(
        &mut self,
        py: Python<'py>,
        i: usize,
        seed: u64,
        actions: PyArrayLikeDyn<'py, f32, AllowTypeChange>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        let (ad, od) = (self.venv.task().act_dim(), self.venv.task().obs_dim());
        let k = actions.as_array().shape().first().copied().unwrap_or(0);
        let acts = flat_f32(&actions, &[k, ad], "actions")?;
        let mut obs = vec![0.0; od];
        self.venv.reset_replay(i, seed, &acts, &mut obs).map_err(sim_err)?;
        Ok(Array1::from_vec(obs).into_pyarray(py))
    }

    /// Step all envs with `actions` (num_envs, act_dim) → `(obs, reward, terminated,
    /// truncated, final_obs, has_final, picked, installed, fell)`; envs that ended are reset in
    /// the same call: `obs` holds their new first observation, `final_obs` rows (where
    /// `has_final`) the terminal one, other `final_obs` rows are zeros.
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: PyArrayLikeDyn<'py, f32, AllowTypeChange>,
    ) -> PyResult<(
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray1<f32>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray2<f32>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
        Bound<'py, PyArray1<bool>>,
    )> {
        let (n, ad, od) = (self.venv.num_envs(), self.venv.task().act_dim(), self.venv.task().obs_dim());
        {
            let v = actions.as_array();
            if v.shape() != [n, ad] {
                return Err(PyValueError::new_err(
                    format!("actions must have shape ({n}, {ad}), got {:?}", v.shape())
                        .replace('[', "(")
                        .replace(']', ")"),
                ));
            }
            for (dst, src) in self.actions.iter_mut().zip(v.iter()) {
                *dst = *src;
            }
        }
        let SimVecEnv { venv, buf, actions: acts } = self;
        py.detach(|| venv.step_buffers(acts, buf)).map_err(sim_err)?;
        for (i, hf) in buf.has_final.iter().enumerate() {
            if !hf {
                buf.final_obs[i * od..(i + 1) * od].iter_mut().for_each(|x| *x = 0.0);
            }
        }
        let b = &self.buf;
        Ok((
            to2(py, b.obs.clone(), n, od)?,
            Array1::from(b.reward.clone()).into_pyarray(py),
            Array1::from(b.terminated.clone()).into_pyarray(py),
            Array1::from(b.truncated.clone()).into_pyarray(py),
            to2(py, b.final_obs.clone(), n, od)?,
            Array1::from(b.has_final.clone()).into_pyarray(py),
            Array1::from(b.picked.clone()).into_pyarray(py),
            Array1::from(b.installed.clone()).into_pyarray(py),
            Array1::from(b.fell.clone()).into_pyarray(py),
        ))
    }

    /// Snapshot of env `i` (see `SimEnv.snapshot`).
    fn snapshot<'py>(&self, py: Python<'py>, i: usize) -> PyResult<Bound<'py, PyDict>> {
        let env = self.venv.env(i).ok_or_else(|| {
            PyValueError::new_err(format!("env index {i} out of range 0..{}", self.venv.num_envs()))
        })?;
        snapshot_dict(py, env)
    }
}

/// The decimal value an f32 constant was written as (0.04, not 0.03999999910593033).
fn f32_exact(x: f32) -> f64 {
    format!("{x}").parse().unwrap_or(x as f64)
}

fn to2(py: Python<'_>, v: Vec<f32>, n: usize, d: usize) -> PyResult<Bound<'_, PyArray2<f32>>> {
    let a = Array2::from_shape_vec((n, d), v).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(a.into_pyarray(py))
}

/// Simulator constants: frame stack, episode limit, control period (s), joint step (rad),
/// physics substeps, pick/install distances (m), and per-task dims.
#[pyfunction]
fn sim_constants(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let d = PyDict::new(py);
    d.set_item("FRAME_STACK", tile_sim::FRAME_STACK)?;
    d.set_item("MAX_EPISODE_STEPS", tile_sim::MAX_EPISODE_STEPS)?;
    d.set_item("CONTROL_DT", f32_exact(tile_sim::CONTROL_DT))?;
    d.set_item("MAX_JOINT_STEP", tile_sim::MAX_JOINT_STEP)?;
    d.set_item("PHYSICS_SUBSTEPS", tile_sim::PHYSICS_SUBSTEPS)?;
    d.set_item("PICK_DIST", f32_exact(tile_sim::PICK_DIST))?;
    d.set_item("INSTALL_DIST", f32_exact(tile_sim::INSTALL_DIST))?;
    d.set_item("HOME_Q", tile_sim::HOME_Q.to_vec())?;
    let tasks = PyDict::new(py);
    for t in Task::ALL {
        let td = PyDict::new(py);
        td.set_item("obs_frame_dim", t.obs_frame_dim())?;
        td.set_item("obs_dim", t.obs_dim())?;
        td.set_item("act_dim", t.act_dim())?;
        tasks.set_item(t.name(), td)?;
    }
    d.set_item("tasks", tasks)?;
    Ok(d)
}

/// The scripted expert's action for a `SimEnv`'s current state (stateful: one per env;
/// call `reset()` at each episode start).
#[pyclass(module = "mimicrete._native")]
pub struct SimExpert {
    ex: tile_sim::expert::Expert,
}

#[pymethods]
impl SimExpert {
    #[new]
    fn new(task: &str) -> PyResult<Self> {
        Ok(SimExpert { ex: tile_sim::expert::Expert::new(parse_task(task)?) })
    }
    fn reset(&mut self) {
        self.ex.reset();
    }
    /// Action `(act_dim,)` f32 for `env`'s current snapshot.
    fn act<'py>(&mut self, py: Python<'py>, env: &SimEnv) -> Bound<'py, PyArray1<f32>> {
        let mut a = vec![0.0; env.env.task().act_dim()];
        self.ex.act(&env.env.snapshot(), &mut a);
        Array1::from(a).into_pyarray(py)
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<SimEnv>()?;
    m.add_class::<SimVecEnv>()?;
    m.add_class::<SimExpert>()?;
    m.add_function(wrap_pyfunction!(sim_constants, m)?)?;
    Ok(())
}
