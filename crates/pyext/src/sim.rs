//! Bindings for tile-sim: `SimEnv`, `SimVecEnv` (N worlds stepped across threads, interpreter lock
//! released), the scripted expert, the task scenes (demo-log's `episode_scene`, `frame_poses`).
//! Shapes (f32): obs `(obs_dim,)` / `(num_envs, obs_dim)`, actions `(act_dim,)` / `(num_envs, act_dim)`.

use crate::errors::{demo_err, matrix, nd_from_py, sim_err, to_py, vector};
use numpy::ndarray::Array1;
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArrayDyn, PyArrayLikeDyn, PyReadonlyArrayDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{IntoPyDict, PyDict, PyList};
use std::collections::BTreeMap;
use tile_sim::{Env, StepBuffers, Task, VecEnv, VecEnvState};

fn parse_task(name: &str) -> PyResult<Task> {
    Task::from_name(name).map_err(sim_err)
}

/// tile-sim's `Snapshot` as a dict (poses `{"t": [x, y, z], "q": [x, y, z, w]}`) plus `links`.
fn snapshot_dict<'py>(py: Python<'py>, env: &Env) -> PyResult<Bound<'py, PyAny>> {
    let d = to_py(py, &env.snapshot())?;
    d.set_item("links", to_py(py, &env.link_poses())?)?;
    Ok(d)
}

fn flat<T: numpy::Element + Copy>(
    a: &PyArrayLikeDyn<'_, T, AllowTypeChange>,
    shape: &[usize],
    what: &str,
) -> PyResult<Vec<T>> {
    nd_from_py(a).into_shape(shape, what).map_err(demo_err)
}

/// Length of the first axis (0 for a scalar).
fn rows<T: numpy::Element>(a: &PyArrayLikeDyn<'_, T, AllowTypeChange>) -> usize {
    a.as_array().shape().first().copied().unwrap_or(0)
}

/// The Foxglove `SceneEntity` objects a demo of episode `seed` of `task` carries on `/scene`.
fn entities<'py>(py: Python<'py>, task: Task, seed: u64, model: &str) -> PyResult<Bound<'py, PyList>> {
    let m = ur3_kin::UrModel::by_name(model).map_err(crate::errors::kin_err)?;
    let ents = demo_log::episode_scene(m, task, seed);
    PyList::new(
        py,
        ents.iter().map(|e| to_py(py, &demo_log::foxglove_entity(e, 0))).collect::<PyResult<Vec<_>>>()?,
    )
}

/// Pose in Base, `[x, y, z, qx, qy, qz, qw]`, of every frame the scene entities are locked to.
fn frames(joints: [f64; 6], tile: demo_log::Pose, model: &str) -> PyResult<BTreeMap<&'static str, [f64; 7]>> {
    let m = ur3_kin::UrModel::by_name(model).map_err(crate::errors::kin_err)?;
    Ok(demo_log::frame_poses(m, &joints, &tile).into_iter().map(|(k, p)| (k, p.to_numbers())).collect())
}

/// The Foxglove `SceneEntity` list (JSON-ready dicts) of episode `seed` of `task`.
#[pyfunction]
#[pyo3(signature = (task, seed = 0, model = "ur3"))]
fn scene_entities<'py>(py: Python<'py>, task: &str, seed: u64, model: &str) -> PyResult<Bound<'py, PyList>> {
    entities(py, parse_task(task)?, seed, model)
}

/// `{frame_id: [x, y, z, qx, qy, qz, qw]}` in Base: URDF links at `joints`, `tile` at `tile_pose`.
#[pyfunction]
#[pyo3(signature = (joints, tile_pose, model = "ur3"))]
fn scene_frames(
    joints: [f64; 6],
    tile_pose: Vec<f64>,
    model: &str,
) -> PyResult<BTreeMap<&'static str, [f64; 7]>> {
    let tile = demo_log::Pose::from_numbers(&tile_pose, "tile_pose").map_err(demo_err)?;
    frames(joints, tile, model)
}

/// `(obs, reward, terminated, truncated, info)` of `SimEnv.step`.
type StepTuple<'py> = (F32s<'py>, f32, bool, bool, Bound<'py, PyDict>);

/// One simulated environment: `SimEnv(task, seed=0)`, task "TileSuction" | "BlockGrip" | "Screw".
#[pyclass(module = "mimicrete._native")]
pub struct SimEnv {
    env: Env,
    obs: Vec<f32>,
    #[pyo3(get)]
    task: &'static str,
    #[pyo3(get)]
    obs_dim: usize,
    #[pyo3(get)]
    obs_frame_dim: usize,
    #[pyo3(get)]
    act_dim: usize,
}

#[pymethods]
impl SimEnv {
    #[new]
    #[pyo3(signature = (task, seed = 0))]
    fn new(task: &str, seed: u64) -> PyResult<Self> {
        let t = parse_task(task)?;
        let (task, obs_dim, obs_frame_dim, act_dim) = (t.name(), t.obs_dim(), t.obs_frame_dim(), t.act_dim());
        Ok(SimEnv { env: Env::new(t, seed), obs: vec![0.0; obs_dim], task, obs_dim, obs_frame_dim, act_dim })
    }

    /// Start an episode (`seed=None`: next seed from the env's RNG) → obs `(obs_dim,)`.
    #[pyo3(signature = (seed = None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>) -> PyResult<F32s<'py>> {
        self.env.reset(seed, &mut self.obs).map_err(sim_err)?;
        Ok(vector(py, self.obs.clone()))
    }

    /// One step → `(obs, reward, terminated, truncated, info)`; info: picked, held, installed, fell, step.
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        action: PyArrayLikeDyn<'py, f32, AllowTypeChange>,
    ) -> PyResult<StepTuple<'py>> {
        let a = flat(&action, &[self.env.task().act_dim()], "action")?;
        let out = self.env.step(&a, &mut self.obs).map_err(sim_err)?;
        let info =
            [("picked", out.picked), ("held", out.held), ("installed", out.installed), ("fell", out.fell)]
                .into_py_dict(py)?;
        info.set_item("step", self.env.snapshot().step)?;
        Ok((vector(py, self.obs.clone()), out.reward, out.terminated, out.truncated, info))
    }

    /// The current stacked observation `(obs_dim,)`.
    fn observation<'py>(&self, py: Python<'py>) -> F32s<'py> {
        Array1::from(self.env.observation().to_vec()).into_pyarray(py)
    }

    /// State for demo recording (poses: `t` metres, `q` quaternion `[x, y, z, w]`, Base frame).
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        snapshot_dict(py, &self.env)
    }

    /// tile-sim's scene items as dicts (name, frame, kind, sizes, translation, rotation, rgba).
    fn scene<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_py(py, &self.env.scene().items)
    }

    /// `scene_entities(task, episode_seed)` of the current episode.
    fn scene_entities<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        entities(py, self.env.task(), self.env.snapshot().episode_seed, "ur3")
    }

    /// `scene_frames` of the current state: URDF links at the arm's joints, `tile` at the object.
    fn scene_frames(&self) -> PyResult<BTreeMap<&'static str, [f64; 7]>> {
        let s = self.env.snapshot();
        frames(s.q, demo_log::Pose { position: s.object.t, orientation: s.object.q }, "ur3")
    }

    /// Test/tool API: teleport the arm to joint angles `q` (6,) rad.
    fn set_joints(&mut self, q: PyReadonlyArrayDyn<'_, f64>) -> PyResult<()> {
        let v = nd_from_py(&q).into_shape(&[6], "q").map_err(demo_err)?;
        self.env.set_joints(std::array::from_fn(|i| v[i])).map_err(sim_err)
    }

    /// Test/tool API: teleport the object to translation `t` (3,) and quaternion `q` (4,) [x,y,z,w].
    fn set_object_pose(&mut self, t: [f64; 3], q: [f64; 4]) -> PyResult<()> {
        self.env.set_object_pose(t, q).map_err(sim_err)
    }
}

/// N envs stepped across threads, same-step auto-reset, seeds `tile_sim::episode_seed(seed, i, episode)`.
#[pyclass(module = "mimicrete._native")]
pub struct SimVecEnv {
    venv: VecEnv,
    buf: StepBuffers,
    #[pyo3(get)]
    task: &'static str,
    #[pyo3(get)]
    num_envs: usize,
    #[pyo3(get)]
    num_threads: usize,
    #[pyo3(get)]
    obs_dim: usize,
    #[pyo3(get)]
    act_dim: usize,
}

type Obs<'py> = Bound<'py, PyArrayDyn<f32>>;
type F32s<'py> = Bound<'py, PyArray1<f32>>;
type Bools<'py> = Bound<'py, PyArray1<bool>>;
/// `SimVecEnv.step`: obs, reward, terminated, truncated, final_obs, has_final, picked, installed, fell.
type VecStep<'py> =
    (Obs<'py>, F32s<'py>, Bools<'py>, Bools<'py>, Obs<'py>, Bools<'py>, Bools<'py>, Bools<'py>, Bools<'py>);

#[pymethods]
impl SimVecEnv {
    #[new]
    #[pyo3(signature = (task, num_envs, seed = 0, num_threads = 2))]
    fn new(task: &str, num_envs: usize, seed: u64, num_threads: usize) -> PyResult<Self> {
        let t = parse_task(task)?;
        let venv = VecEnv::new(t, num_envs, seed, num_threads).map_err(sim_err)?;
        let (task, num_threads, obs_dim, act_dim) = (t.name(), venv.num_threads(), t.obs_dim(), t.act_dim());
        Ok(SimVecEnv {
            venv,
            buf: StepBuffers::new(t, num_envs),
            task,
            num_envs,
            num_threads,
            obs_dim,
            act_dim,
        })
    }

    /// Reset all envs with base seed `seed` (env i gets `seed + i`, episode counts restart; None:
    /// a base drawn from the VecEnv's RNG) → obs (num_envs, obs_dim).
    #[pyo3(signature = (seed = None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>) -> PyResult<Obs<'py>> {
        let (n, od) = (self.venv.num_envs(), self.venv.task().obs_dim());
        let mut obs = vec![0.0; n * od];
        self.venv.reset(seed, &mut obs).map_err(sim_err)?;
        matrix(py, obs, od)
    }

    /// Reset the envs where `mask` (num_envs,) is true → obs (num_envs, obs_dim) of all envs.
    fn reset_mask<'py>(
        &mut self,
        py: Python<'py>,
        mask: PyArrayLikeDyn<'py, bool, AllowTypeChange>,
    ) -> PyResult<Obs<'py>> {
        let (n, od) = (self.venv.num_envs(), self.venv.task().obs_dim());
        let m = flat(&mask, &[n], "mask")?;
        let mut obs = vec![0.0; n * od];
        self.venv.reset_mask(&m, &mut obs).map_err(sim_err)?;
        matrix(py, obs, od)
    }

    /// How episodes start from the next reset: the object's x range (m) and the target's jitter
    /// (m); `robust=True` gives tile-sim's robustness evaluation (`Variation::robust`).
    #[pyo3(signature = (object_x = None, target_jitter = 0.0, robust = false))]
    fn set_variation(
        &mut self,
        object_x: Option<[f32; 2]>,
        target_jitter: f32,
        robust: bool,
    ) -> PyResult<()> {
        let v = match (robust, object_x) {
            (true, _) => tile_sim::Variation::robust(),
            (false, Some(x)) => tile_sim::Variation { object_x: x, target_jitter },
            (false, None) => tile_sim::Variation { target_jitter, ..Default::default() },
        };
        self.venv.set_variation(v).map_err(sim_err)
    }

    /// Reset env `i` to episode `seed` and replay `actions` (k, act_dim) in it (a recorded
    /// episode's first k steps); the other envs do not move → env `i`'s observation (obs_dim,).
    fn reset_replay<'py>(
        &mut self,
        py: Python<'py>,
        i: usize,
        seed: u64,
        actions: PyArrayLikeDyn<'py, f32, AllowTypeChange>,
    ) -> PyResult<F32s<'py>> {
        let (ad, od) = (self.venv.task().act_dim(), self.venv.task().obs_dim());
        let acts = flat(&actions, &[rows(&actions), ad], "actions")?;
        let mut obs = vec![0.0; od];
        self.venv.reset_replay(i, seed, &acts, &mut obs).map_err(sim_err)?;
        Ok(vector(py, obs))
    }

    /// Step all envs → (obs, reward, terminated, truncated, final_obs, has_final, picked, installed, fell).
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        actions: PyArrayLikeDyn<'py, f32, AllowTypeChange>,
    ) -> PyResult<VecStep<'py>> {
        let (n, ad, od) = (self.venv.num_envs(), self.venv.task().act_dim(), self.venv.task().obs_dim());
        let acts = flat(&actions, &[n, ad], "actions")?;
        let SimVecEnv { venv, buf, .. } = self;
        py.detach(|| venv.step_buffers(&acts, buf)).map_err(sim_err)?;
        let b = &self.buf;
        let v = |x: &Vec<bool>| vector(py, x.clone());
        Ok((
            matrix(py, b.obs.clone(), od)?,
            vector(py, b.reward.clone()),
            v(&b.terminated),
            v(&b.truncated),
            matrix(py, b.final_obs.clone(), od)?,
            v(&b.has_final),
            v(&b.picked),
            v(&b.installed),
            v(&b.fell),
        ))
    }

    /// `{"base_seed": int, "episodes": uint64 (num_envs,), "seeds": uint64 (num_envs,),
    /// "actions": [float32 (k_i, act_dim)]}`:
    /// what `restore` needs to rebuild every env mid-episode (tile-sim's `VecEnvState`).
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let st = self.venv.state();
        let acts =
            st.actions.into_iter().map(|a| matrix(py, a, self.act_dim)).collect::<PyResult<Vec<_>>>()?;
        Ok(dict!(py; "base_seed" => st.base_seed, "episodes" => vector(py, st.episodes),
            "seeds" => vector(py, st.seeds), "actions" => PyList::new(py, acts)?))
    }

    /// Rebuild the envs from a `state()` dict (replaying each running episode) → obs (num_envs,
    /// obs_dim), equal to the observations when the state was taken.
    fn restore<'py>(
        &mut self,
        py: Python<'py>,
        base_seed: u64,
        episodes: Vec<u64>,
        seeds: Vec<u64>,
        actions: Vec<PyArrayLikeDyn<'py, f32, AllowTypeChange>>,
    ) -> PyResult<Obs<'py>> {
        let (n, od, ad) = (self.venv.num_envs(), self.obs_dim, self.act_dim);
        let actions = actions.iter().enumerate();
        let actions = actions
            .map(|(i, a)| flat(a, &[rows(a), ad], &format!("actions[{i}]")))
            .collect::<PyResult<_>>()?;
        let st = VecEnvState { base_seed, episodes, seeds, actions };
        let mut obs = vec![0.0; n * od];
        let venv = &mut self.venv;
        py.detach(|| venv.restore(&st, &mut obs)).map_err(sim_err)?;
        matrix(py, obs, od)
    }

    /// Snapshot of env `i` (see `SimEnv.snapshot`).
    fn snapshot<'py>(&self, py: Python<'py>, i: usize) -> PyResult<Bound<'py, PyAny>> {
        let env = self.venv.env(i).ok_or_else(|| {
            PyValueError::new_err(format!("env index {i} out of range 0..{}", self.venv.num_envs()))
        })?;
        snapshot_dict(py, env)
    }
}

/// The simulator's constants and per-task dims (`tile_sim::Constants`).
#[pyfunction]
fn sim_constants(py: Python<'_>) -> PyResult<Bound<'_, PyAny>> {
    to_py(py, &tile_sim::Constants::get())
}

/// The scripted expert (stateful, one per env; `reset()` at each episode start).
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
    fn act<'py>(&mut self, py: Python<'py>, env: &SimEnv) -> F32s<'py> {
        let mut a = vec![0.0; env.env.task().act_dim()];
        self.ex.act(&env.env.snapshot(), &mut a);
        vector(py, a)
    }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<SimEnv>()?;
    m.add_class::<SimVecEnv>()?;
    m.add_class::<SimExpert>()?;
    add_functions!(m => sim_constants, scene_entities, scene_frames);
    Ok(())
}
