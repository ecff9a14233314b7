//! Bindings for tile-sim (`SimEnv`, `SimVecEnv` stepped without the interpreter lock, the expert)
//! and the task scenes (demo-log's `episode_scene_json`, `frame_numbers`).

use crate::errors::{demo_err, matrix, nd_from_py, sim_err, to_py, vector};
use numpy::{AllowTypeChange, PyArray1, PyArrayDyn, PyArrayLikeDyn, PyReadonlyArrayDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::collections::BTreeMap;
use tile_sim::{Env, StepBuffers, Task, VecEnv, VecEnvState};

type Any<'py> = Bound<'py, PyAny>;

fn parse_task(name: &str) -> PyResult<Task> {
    Task::from_name(name).map_err(sim_err)
}

type Like<'py, T> = PyArrayLikeDyn<'py, T, AllowTypeChange>;
type Actions<'py> = Like<'py, f32>;

/// The rows of an `(n, cols)` array.
fn flat<T: numpy::Element + Copy>(a: &Like<'_, T>, cols: usize, what: &str) -> PyResult<Vec<T>> {
    nd_from_py(a).into_matrix(cols, what).map_err(demo_err)
}

/// The Foxglove `SceneEntity` list (JSON-ready dicts) of episode `seed` of `task`.
#[pyfunction]
#[pyo3(signature = (task, seed = 0, model = "ur3"))]
fn scene_entities<'py>(py: Python<'py>, task: &str, seed: u64, model: &str) -> PyResult<Any<'py>> {
    to_py(py, &demo_log::episode_scene_json(model, parse_task(task)?, seed).map_err(demo_err)?)
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
    demo_log::frame_numbers(model, &joints, &tile).map_err(demo_err)
}

/// `(obs, reward, terminated, truncated, info)` of `SimEnv.step`.
type StepTuple<'py> = (F32s<'py>, f32, bool, bool, Bound<'py, PyDict>);

/// One simulated environment: `SimEnv(task, seed=0)`, task "TileSuction" | "BlockGrip" | "Screw".
#[pyclass(module = "mimicrete._native")]
pub struct SimEnv {
    env: Env,
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
        Ok(SimEnv { env: Env::new(t, seed), task, obs_dim, obs_frame_dim, act_dim })
    }

    /// Start an episode (`seed=None`: next seed from the env's RNG) → obs `(obs_dim,)`.
    #[pyo3(signature = (seed = None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>) -> PyResult<F32s<'py>> {
        Ok(vector(py, self.env.reset_owned(seed).map_err(sim_err)?))
    }

    /// One step → `(obs, reward, terminated, truncated, info)`; info: picked, held, installed, fell, step.
    fn step<'py>(&mut self, py: Python<'py>, action: Actions<'py>) -> PyResult<StepTuple<'py>> {
        let a = nd_from_py(&action).into_shape(&[self.act_dim], "action").map_err(demo_err)?;
        let (obs, out, info) = self.env.step_owned(&a).map_err(sim_err)?;
        Ok((vector(py, obs), out.reward, out.terminated, out.truncated, to_py(py, &info)?.cast_into()?))
    }

    /// The current stacked observation `(obs_dim,)`.
    fn observation<'py>(&self, py: Python<'py>) -> F32s<'py> {
        vector(py, self.env.observation().to_vec())
    }

    /// State for demo recording (poses: `t` metres, `q` quaternion `[x, y, z, w]`, Base frame).
    fn snapshot<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        to_py(py, &self.env.record_state())
    }

    /// tile-sim's scene items as dicts (name, frame, kind, sizes, translation, rotation, rgba).
    fn scene<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        to_py(py, &self.env.scene().items)
    }

    /// `scene_entities(task, episode_seed)` of the current episode.
    fn scene_entities<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        scene_entities(py, self.task, self.env.snapshot().episode_seed, "ur3")
    }

    /// `scene_frames` of the current state: URDF links at the arm's joints, `tile` at the object.
    fn scene_frames(&self) -> PyResult<BTreeMap<&'static str, [f64; 7]>> {
        let s = self.env.snapshot();
        let tile = demo_log::Pose { position: s.object.t, orientation: s.object.q };
        demo_log::frame_numbers("ur3", &s.q, &tile).map_err(demo_err)
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
        let buf = StepBuffers::new(t, num_envs);
        Ok(SimVecEnv { venv, buf, task, num_envs, num_threads, obs_dim, act_dim })
    }

    /// Reset all envs, env i with seed `seed + i` (None: a base from the VecEnv's RNG) → obs.
    #[pyo3(signature = (seed = None))]
    fn reset<'py>(&mut self, py: Python<'py>, seed: Option<u64>) -> PyResult<Obs<'py>> {
        matrix(py, self.venv.reset_owned(seed).map_err(sim_err)?, self.obs_dim)
    }

    /// Reset the envs where `mask` (num_envs,) is true → obs (num_envs, obs_dim) of all envs.
    fn reset_mask<'py>(&mut self, py: Python<'py>, mask: Like<'py, bool>) -> PyResult<Obs<'py>> {
        let m = nd_from_py(&mask).into_shape(&[self.num_envs], "mask").map_err(demo_err)?;
        matrix(py, self.venv.reset_mask_owned(&m).map_err(sim_err)?, self.obs_dim)
    }

    /// How episodes start from the next reset (tile-sim's `Variation`; `robust`: `Variation::robust`).
    #[pyo3(signature = (object_x = None, target_jitter = 0.0, robust = false))]
    fn set_variation(
        &mut self,
        object_x: Option<[f32; 2]>,
        target_jitter: f32,
        robust: bool,
    ) -> PyResult<()> {
        let v = tile_sim::Variation::from_options(object_x, target_jitter, robust);
        self.venv.set_variation(v).map_err(sim_err)
    }

    /// Reset env `i` to episode `seed` and replay `actions` (k, act_dim) in it → its obs.
    fn reset_replay<'py>(
        &mut self,
        py: Python<'py>,
        i: usize,
        seed: u64,
        actions: Actions<'py>,
    ) -> PyResult<F32s<'py>> {
        let acts = flat(&actions, self.act_dim, "actions")?;
        Ok(vector(py, self.venv.reset_replay_owned(i, seed, &acts).map_err(sim_err)?))
    }

    /// Step all envs → (obs, reward, terminated, truncated, final_obs, has_final, picked, installed, fell).
    fn step<'py>(&mut self, py: Python<'py>, actions: Actions<'py>) -> PyResult<VecStep<'py>> {
        let (n, ad, od) = (self.num_envs, self.act_dim, self.obs_dim);
        let acts = nd_from_py(&actions).into_shape(&[n, ad], "actions").map_err(demo_err)?;
        let SimVecEnv { venv, buf, .. } = self;
        py.detach(|| venv.step_buffers(&acts, buf)).map_err(sim_err)?;
        let b = &self.buf;
        let flags = [&b.terminated, &b.truncated, &b.has_final, &b.picked, &b.installed, &b.fell];
        let [term, trunc, has_final, picked, installed, fell] = flags.map(|x| vector(py, x.clone()));
        let (obs, final_obs) = (matrix(py, b.obs.clone(), od)?, matrix(py, b.final_obs.clone(), od)?);
        Ok((obs, vector(py, b.reward.clone()), term, trunc, final_obs, has_final, picked, installed, fell))
    }

    /// tile-sim's `VecEnvState` as a dict: base_seed, episodes, seeds, actions (see the stub).
    fn state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let st = self.venv.state();
        let acts =
            st.actions.into_iter().map(|a| matrix(py, a, self.act_dim)).collect::<PyResult<Vec<_>>>()?;
        Ok(dict!(py; "base_seed" => st.base_seed, "episodes" => vector(py, st.episodes),
            "seeds" => vector(py, st.seeds), "actions" => PyList::new(py, acts)?))
    }

    /// Rebuild the envs from a `state()` dict's values (replaying each running episode) → obs.
    fn restore<'py>(
        &mut self,
        py: Python<'py>,
        base_seed: u64,
        episodes: Vec<u64>,
        seeds: Vec<u64>,
        actions: Vec<Actions<'py>>,
    ) -> PyResult<Obs<'py>> {
        let actions = actions.iter().enumerate();
        let actions =
            actions.map(|(i, a)| flat(a, self.act_dim, &format!("actions[{i}]"))).collect::<PyResult<_>>()?;
        let st = VecEnvState { base_seed, episodes, seeds, actions };
        let venv = &mut self.venv;
        matrix(py, py.detach(|| venv.restore_owned(&st)).map_err(sim_err)?, self.obs_dim)
    }

    /// Snapshot of env `i` (see `SimEnv.snapshot`).
    fn snapshot<'py>(&self, py: Python<'py>, i: usize) -> PyResult<Any<'py>> {
        let n = self.num_envs;
        let env = self
            .venv
            .env(i)
            .ok_or_else(|| PyValueError::new_err(format!("env index {i} out of range 0..{n}")))?;
        to_py(py, &env.record_state())
    }
}

/// The simulator's constants and per-task dims (`tile_sim::Constants`).
#[pyfunction]
fn sim_constants(py: Python<'_>) -> PyResult<Any<'_>> {
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
