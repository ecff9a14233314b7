//! Bindings for tile-sim (`SimEnv`, `SimVecEnv` stepped without the interpreter lock, the expert)
//! and the task scenes (teleop-core's `scene::scene_json`, demo-log's `frame_numbers`).

use crate::errors::{action_shape, demo_err, io_err, matrix, nd_from_py, sim_err, spec_err, to_py, vector};
use numpy::{AllowTypeChange, PyArray1, PyArrayDyn, PyArrayLikeDyn, PyReadonlyArrayDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;
use tile_sim::{Env, Start, StepBuffers, Task, TaskSpec, Variation, VecEnv, VecEnvState};

type Any<'py> = Bound<'py, PyAny>;

pub(crate) fn parse_task(name: &str) -> PyResult<Task> {
    Task::from_name(name).map_err(sim_err)
}

/// Read and check the task spec file at `path` (I/O errors → `IoError`, a bad spec →
/// `SimInputError` with `field`, `value`, `reason`).
pub(crate) fn read_spec(path: &str) -> PyResult<TaskSpec> {
    let text = std::fs::read_to_string(path).map_err(|e| io_err(Path::new(path), &e))?;
    TaskSpec::from_toml(&text, path).map_err(spec_err)
}

/// A task spec file, read and checked → the spec as a dict (the file's tables and fields).
#[pyfunction]
fn load_task_spec<'py>(py: Python<'py>, path: &str) -> PyResult<Any<'py>> {
    to_py(py, &read_spec(path)?)
}

/// The joint angles (6,) one step of `action` (its first six numbers, clipped to [-1, 1]) takes
/// the arm to from `q` (6,), under the task spec `spec` (a dict as `load_task_spec`, `task_spec`
/// or `SimEnv.spec` give it; checked: a bad one raises `SimInputError`).
#[pyfunction]
fn joint_motion<'py>(
    py: Python<'py>,
    spec: &Bound<'py, PyAny>,
    q: [f64; 6],
    action: Vec<f32>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let spec: TaskSpec =
        pythonize::depythonize(spec).map_err(|e| PyValueError::new_err(format!("spec: {e}")))?;
    spec.check().map_err(spec_err)?;
    if action.len() < 6 || action.iter().any(|x| !x.is_finite()) || q.iter().any(|x| !x.is_finite()) {
        return Err(PyValueError::new_err("q (6,) and action (at least 6) must be finite"));
    }
    Ok(vector(py, tile_sim::action::joint_motion(&spec, &q, &action).to_vec()))
}

/// The built-in spec of `task` as a dict (`as_toml=True`: the spec file's text).
#[pyfunction]
#[pyo3(signature = (task, as_toml = false))]
fn task_spec<'py>(py: Python<'py>, task: &str, as_toml: bool) -> PyResult<Any<'py>> {
    let t = parse_task(task)?;
    if as_toml {
        return Ok(pyo3::types::PyString::new(py, TaskSpec::builtin_toml(t)).into_any());
    }
    to_py(py, &*TaskSpec::builtin(t))
}

/// The hand → robot scale of live teleoperation in the spec file `task_file` (None: `task`'s
/// built-in spec, 1): its `robot.hand_scale`, else its arm's workspace scale
/// (`TaskSpec::hand_scale`); raises as `load_task_spec`.
#[pyfunction]
#[pyo3(signature = (task = "suction", task_file = None))]
fn hand_scale(task: &str, task_file: Option<&str>) -> PyResult<f32> {
    Ok(match task_file {
        Some(path) => read_spec(path)?.hand_scale(),
        None => TaskSpec::builtin(parse_task(task)?).hand_scale(),
    })
}

type Like<'py, T> = PyArrayLikeDyn<'py, T, AllowTypeChange>;
type Actions<'py> = Like<'py, f32>;

/// The rows of an `(n, cols)` array.
fn flat<T: numpy::Element + Copy>(a: &Like<'_, T>, cols: usize, what: &str) -> PyResult<Vec<T>> {
    nd_from_py(a).into_matrix(cols, what).map_err(demo_err)
}

/// The explicit start the keyword arguments name, if `object_pose` is given.
fn start_of(
    object_pose: Option<[f32; 3]>,
    target_offset: Option<[f32; 2]>,
    pad_offset: Option<[f32; 2]>,
    pad_yaw: Option<f32>,
) -> PyResult<Option<Start>> {
    match object_pose {
        Some(o) => Ok(Some(Start {
            pad_yaw: pad_yaw.unwrap_or(0.0),
            ..Start::from_options(o, target_offset.unwrap_or([0.0; 2]), pad_offset)
        })),
        None if target_offset.is_some() || pad_offset.is_some() || pad_yaw.is_some() => {
            Err(PyValueError::new_err("target_offset / pad_offset / pad_yaw need an object_pose"))
        }
        None => Ok(None),
    }
}

/// The variation `set_variation`'s arguments name (`starts`: "training" | "robust" | "wide";
/// `towards_wide`: that far from the paper's starts to the wide ones).
/// Named against the env's own `spec` (its paper and wide starts).
fn variation_of(
    spec: &TaskSpec,
    starts: Option<&str>,
    towards_wide: Option<f32>,
    object_x: Option<[f32; 2]>,
    target_jitter: f32,
    robust: bool,
) -> PyResult<Variation> {
    match (starts, towards_wide) {
        (Some(_), Some(_)) => Err(PyValueError::new_err("give starts or towards_wide, not both")),
        (Some(name), None) => Variation::named_in(name, spec).ok_or_else(|| {
            PyValueError::new_err(format!("starts: expected training, robust or wide, got {name:?}"))
        }),
        (None, Some(s)) => Ok(Variation::towards_wide_in(s, spec)),
        (None, None) => Ok(Variation::from_options_in(object_x, target_jitter, robust, spec)),
    }
}

/// The Foxglove `SceneEntity` list (JSON-ready dicts) of episode `seed` of `task`.
#[pyfunction]
#[pyo3(signature = (task, seed = 0, model = "ur3"))]
fn scene_entities<'py>(py: Python<'py>, task: &str, seed: u64, model: &str) -> PyResult<Any<'py>> {
    let scene = tile_sim::episode_scene(parse_task(task)?, seed);
    to_py(py, &teleop_core::scene::scene_json(model, &scene).map_err(demo_err)?)
}

/// `{frame_id: [x, y, z, qx, qy, qz, qw]}` in Base: URDF links at `joints`, `tile` at `tile_pose`,
/// a row's `tile_0` … at `row` (in row order).
#[pyfunction]
#[pyo3(signature = (joints, tile_pose, model = "ur3", row = None))]
fn scene_frames(
    joints: [f64; 6],
    tile_pose: Vec<f64>,
    model: &str,
    row: Option<Vec<Vec<f64>>>,
) -> PyResult<BTreeMap<&'static str, [f64; 7]>> {
    let tile = demo_log::Pose::from_numbers(&tile_pose, "tile_pose").map_err(demo_err)?;
    let row = row
        .unwrap_or_default()
        .iter()
        .enumerate()
        .map(|(i, p)| demo_log::Pose::from_numbers(p, &format!("row[{i}]")))
        .collect::<Result<Vec<_>, _>>()
        .map_err(demo_err)?;
    demo_log::frame_numbers(model, &joints, &tile, &row).map_err(demo_err)
}

/// `(obs, reward, terminated, truncated, info)` of `SimEnv.step`.
type StepTuple<'py> = (F32s<'py>, f32, bool, bool, Bound<'py, PyDict>);

/// One simulated environment: `SimEnv(task, seed=0)`, task "TileSuction" | "BlockGrip" | "Screw" |
/// "TileRow" (any name `tile_sim::Task::from_name` accepts; `sim_constants()["tasks"]` lists them
/// with their sizes). A TileRow snapshot has a `row` list (each tile's pose, target, picked,
/// installed).
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

impl SimEnv {
    /// The static scene of the current episode (its start, its spec).
    pub(crate) fn env_scene(&self) -> tile_sim::Scene {
        self.env.scene()
    }
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

    /// An env of the task the spec file at `path` describes (its logic, and so `task`, follows
    /// from the effector); raises as `load_task_spec`.
    #[staticmethod]
    #[pyo3(signature = (path, seed = 0))]
    fn from_spec_file(path: &str, seed: u64) -> PyResult<Self> {
        let spec = Arc::new(read_spec(path)?);
        let t = spec.task();
        let (task, obs_dim, obs_frame_dim, act_dim) = (t.name(), t.obs_dim(), t.obs_frame_dim(), t.act_dim());
        Ok(SimEnv { env: Env::from_spec(spec, seed), task, obs_dim, obs_frame_dim, act_dim })
    }

    /// The spec this env runs, as a dict.
    fn spec<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        to_py(py, &**self.env.spec())
    }

    /// Joint motion (rad) per step at full action: the spec's `robot.joint_step`, else
    /// `MAX_JOINT_STEP` (0.04).
    #[getter]
    fn joint_step(&self) -> f64 {
        self.env.joint_step()
    }

    /// Start an episode (`seed=None`: next seed from the env's RNG) → obs `(obs_dim,)`; at
    /// `object_pose` `[x, y, yaw]` with the target (and pad) moved by `target_offset` when given,
    /// the pad turned by `pad_yaw` (rad).
    #[pyo3(signature = (seed = None, object_pose = None, target_offset = None, pad_offset = None, pad_yaw = None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seed: Option<u64>,
        object_pose: Option<[f32; 3]>,
        target_offset: Option<[f32; 2]>,
        pad_offset: Option<[f32; 2]>,
        pad_yaw: Option<f32>,
    ) -> PyResult<F32s<'py>> {
        match start_of(object_pose, target_offset, pad_offset, pad_yaw)? {
            None => Ok(vector(py, self.env.reset_owned(seed).map_err(sim_err)?)),
            Some(st) => {
                let s = seed.unwrap_or_else(|| self.env.episode_seed().wrapping_add(1));
                let mut obs = vec![0.0; self.obs_dim];
                self.env.reset_start(st, s, &mut obs).map_err(sim_err)?;
                Ok(vector(py, obs))
            }
        }
    }

    /// Where the running episode started: `{"object_pose": [x, y, yaw], "target_offset": [dx, dy],
    /// "pad_offset": [dx, dy]}`.
    fn start<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        to_py(py, &self.env.start())
    }

    /// How episodes start from the next reset (see `SimVecEnv.set_variation`).
    #[pyo3(signature = (starts = None, towards_wide = None, object_x = None, target_jitter = 0.0, robust = false))]
    fn set_variation(
        &mut self,
        starts: Option<&str>,
        towards_wide: Option<f32>,
        object_x: Option<[f32; 2]>,
        target_jitter: f32,
        robust: bool,
    ) -> PyResult<()> {
        let v = variation_of(self.env.spec(), starts, towards_wide, object_x, target_jitter, robust)?;
        self.env.set_variation(v).map_err(sim_err)
    }

    /// One step → `(obs, reward, terminated, truncated, info)`; info: picked, held, installed, fell, step.
    fn step<'py>(&mut self, py: Python<'py>, action: Actions<'py>) -> PyResult<StepTuple<'py>> {
        let a = action_shape(nd_from_py(&action), &[self.act_dim], "action", self.task)?;
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

    /// The Foxglove `SceneEntity` list of the current episode (its start's pad, target, plate).
    fn scene_entities<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        to_py(py, &teleop_core::scene::scene_json(self.env.arm().name, &self.env.scene()).map_err(demo_err)?)
    }

    /// `scene_frames` of the current state: URDF links at the arm's joints, `tile` at the object,
    /// a row's `tile_0` … at its tiles.
    fn scene_frames(&self) -> PyResult<BTreeMap<&'static str, [f64; 7]>> {
        let s = self.env.snapshot();
        let tile = demo_log::Pose { position: s.object.t, orientation: s.object.q };
        let row: Vec<_> =
            s.row.iter().map(|r| demo_log::Pose { position: r.object.t, orientation: r.object.q }).collect();
        demo_log::frame_numbers(self.env.arm().name, &s.q, &tile, &row).map_err(demo_err)
    }

    /// Where the object is now, as a tiler would check it (`tile_sim::Placement`: `held`,
    /// `height_above_rest`, `xy_error` m, `yaw_error_deg`, `hold_gaps` m), or `None` (Screw).
    fn placement<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        to_py(py, &self.env.placement())
    }

    /// `placement()` at the end of the last finished episode, or `None` before one finished.
    fn last_placement<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        to_py(py, &self.env.last_placement())
    }

    /// The action's first six numbers (6,) that move the arm from where it is towards joint
    /// angles `q_goal` (6,) in one step, in the spec's action space (`robot.action`: joint
    /// motions, or the TCP's motion and turn): what the expert, teleop and demogen record.
    fn action_toward<'py>(
        &self,
        py: Python<'py>,
        q_goal: PyReadonlyArrayDyn<'_, f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let v = nd_from_py(&q_goal).into_shape(&[6], "q_goal").map_err(demo_err)?;
        if v.iter().any(|x| !x.is_finite()) {
            return Err(PyValueError::new_err("q_goal must be finite"));
        }
        Ok(vector(py, self.env.action_toward(&std::array::from_fn(|i| v[i])).to_vec()))
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

impl SimVecEnv {
    /// Env `i`, or a ValueError naming the index and the range.
    fn env_at(&self, i: usize) -> PyResult<&Env> {
        let n = self.num_envs;
        self.venv.env(i).ok_or_else(|| PyValueError::new_err(format!("env index {i} out of range 0..{n}")))
    }
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

    /// `num_envs` envs of the task the spec file at `path` describes (as `SimEnv.from_spec_file`;
    /// raises as `load_task_spec`).
    #[staticmethod]
    #[pyo3(signature = (path, num_envs, seed = 0, num_threads = 2))]
    fn from_spec_file(path: &str, num_envs: usize, seed: u64, num_threads: usize) -> PyResult<Self> {
        let spec = Arc::new(read_spec(path)?);
        let t = spec.task();
        let venv = VecEnv::from_spec(spec, num_envs, seed, num_threads).map_err(sim_err)?;
        let (task, num_threads, obs_dim, act_dim) = (t.name(), venv.num_threads(), t.obs_dim(), t.act_dim());
        let buf = StepBuffers::new(t, num_envs);
        Ok(SimVecEnv { venv, buf, task, num_envs, num_threads, obs_dim, act_dim })
    }

    /// The spec these envs run, as a dict.
    fn spec<'py>(&self, py: Python<'py>) -> PyResult<Any<'py>> {
        to_py(py, &**self.venv.spec())
    }

    /// Joint motion (rad) per step at full action: the spec's `robot.joint_step`, else
    /// `MAX_JOINT_STEP` (0.04).
    #[getter]
    fn joint_step(&self) -> f64 {
        self.venv.spec().joint_step()
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

    /// How episodes start from the next reset (tile-sim's `Variation`): `starts` names one
    /// ("training", "robust", "wide"), `towards_wide` in [0, 1] is that far from the paper's
    /// starts to the wide ones; else `robust`, or the paper's with `object_x` / `target_jitter`.
    #[pyo3(signature = (starts = None, towards_wide = None, object_x = None, target_jitter = 0.0, robust = false))]
    fn set_variation(
        &mut self,
        starts: Option<&str>,
        towards_wide: Option<f32>,
        object_x: Option<[f32; 2]>,
        target_jitter: f32,
        robust: bool,
    ) -> PyResult<()> {
        let v = variation_of(self.venv.spec(), starts, towards_wide, object_x, target_jitter, robust)?;
        self.venv.set_variation(v).map_err(sim_err)
    }

    /// Reset every env with base seed `seed`, env i at `object_poses[i]` `[x, y, yaw]` with its
    /// target (and pad) moved by `target_offsets[i]` → obs (num_envs, obs_dim).
    #[pyo3(signature = (seed, object_poses, target_offsets = None, pad_offsets = None, pad_yaws = None))]
    fn reset_starts<'py>(
        &mut self,
        py: Python<'py>,
        seed: u64,
        object_poses: Vec<[f32; 3]>,
        target_offsets: Option<Vec<[f32; 2]>>,
        pad_offsets: Option<Vec<[f32; 2]>>,
        pad_yaws: Option<Vec<f32>>,
    ) -> PyResult<Obs<'py>> {
        let n = self.num_envs;
        let count = |what: &str, len: usize| {
            if len == n {
                Ok(())
            } else {
                Err(PyValueError::new_err(format!("{what}: {len} entries for {n} envs")))
            }
        };
        count("object_pose", object_poses.len())?;
        let t = target_offsets.unwrap_or_else(|| vec![[0.0; 2]; n]);
        count("target_offset", t.len())?;
        if let Some(p) = &pad_offsets {
            count("pad_offset", p.len())?;
        }
        if let Some(p) = &pad_yaws {
            count("pad_yaw", p.len())?;
        }
        let starts: Vec<Start> = (0..n)
            .map(|i| Start {
                pad_yaw: pad_yaws.as_ref().map_or(0.0, |p| p[i]),
                ..Start::from_options(object_poses[i], t[i], pad_offsets.as_ref().map(|p| p[i]))
            })
            .collect();
        matrix(py, self.venv.reset_starts_owned(seed, &starts).map_err(sim_err)?, self.obs_dim)
    }

    /// Reset env `i` to episode `seed` (at `object_pose` / `target_offset` when given, else the
    /// paper's start of `seed`, where demos are recorded) and replay `actions` (k, act_dim) → its obs.
    #[pyo3(signature = (i, seed, actions, object_pose = None, target_offset = None, pad_offset = None, pad_yaw = None))]
    #[allow(clippy::too_many_arguments)]
    fn reset_replay<'py>(
        &mut self,
        py: Python<'py>,
        i: usize,
        seed: u64,
        actions: Actions<'py>,
        object_pose: Option<[f32; 3]>,
        target_offset: Option<[f32; 2]>,
        pad_offset: Option<[f32; 2]>,
        pad_yaw: Option<f32>,
    ) -> PyResult<F32s<'py>> {
        let acts = flat(&actions, self.act_dim, "actions")?;
        let st = start_of(object_pose, target_offset, pad_offset, pad_yaw)?;
        Ok(vector(py, self.venv.reset_replay_owned(i, seed, st, &acts).map_err(sim_err)?))
    }

    /// Where env `i`'s running episode started (see `SimEnv.start`).
    fn start<'py>(&self, py: Python<'py>, i: usize) -> PyResult<Any<'py>> {
        let env = self.env_at(i)?;
        to_py(py, &env.start())
    }

    /// Step all envs → (obs, reward, terminated, truncated, final_obs, has_final, picked, installed, fell).
    fn step<'py>(&mut self, py: Python<'py>, actions: Actions<'py>) -> PyResult<VecStep<'py>> {
        let (n, ad, od) = (self.num_envs, self.act_dim, self.obs_dim);
        let acts = action_shape(nd_from_py(&actions), &[n, ad], "actions", self.task)?;
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
        let starts: Vec<f32> = st.starts.iter().flat_map(|s| s.to_row()).collect();
        Ok(dict!(py; "base_seed" => st.base_seed, "episodes" => vector(py, st.episodes),
            "seeds" => vector(py, st.seeds), "starts" => matrix(py, starts, 8)?,
            "actions" => PyList::new(py, acts)?))
    }

    /// Rebuild the envs from a `state()` dict's values (replaying each running episode) → obs.
    #[pyo3(signature = (base_seed, episodes, seeds, actions, starts = None))]
    fn restore<'py>(
        &mut self,
        py: Python<'py>,
        base_seed: u64,
        episodes: Vec<u64>,
        seeds: Vec<u64>,
        actions: Vec<Actions<'py>>,
        starts: Option<Vec<Vec<f32>>>,
    ) -> PyResult<Obs<'py>> {
        let actions = actions.iter().enumerate();
        let actions =
            actions.map(|(i, a)| flat(a, self.act_dim, &format!("actions[{i}]"))).collect::<PyResult<_>>()?;
        // A state saved before starts were recorded: every episode then began at the paper's start of its seed.
        let task = self.venv.task();
        let starts = match starts {
            Some(rows) => rows.iter().map(|r| Start::from_row(r)).collect(),
            None => seeds.iter().map(|&s| Variation::default().start(task, s)).collect(),
        };
        let st = VecEnvState { base_seed, episodes, seeds, starts, actions };
        let venv = &mut self.venv;
        matrix(py, py.detach(|| venv.restore_owned(&st)).map_err(sim_err)?, self.obs_dim)
    }

    /// `SimEnv.last_placement` of env `i`: the placement its last finished episode ended with
    /// (an env that ended in a step has been reset already; this is kept through the reset).
    fn last_placement<'py>(&self, py: Python<'py>, i: usize) -> PyResult<Any<'py>> {
        let env = self.env_at(i)?;
        to_py(py, &env.last_placement())
    }

    /// Snapshot of env `i` (see `SimEnv.snapshot`).
    fn snapshot<'py>(&self, py: Python<'py>, i: usize) -> PyResult<Any<'py>> {
        let env = self.env_at(i)?;
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
    add_functions!(m => sim_constants, scene_entities, scene_frames, load_task_spec, task_spec, hand_scale, joint_motion);
    Ok(())
}
