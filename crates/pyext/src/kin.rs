//! Bindings for ur3-kin: numpy ↔ the crate's types (batches, failures and checks are ur3-kin's),
//! the interpreter lock released around batches.

use crate::errors::kin_err;
use numpy::ndarray::{Array1, Array2, Array3, ArrayView1, ArrayView2};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use ur3_kin::nalgebra::Matrix4;
use ur3_kin::{Calibration, HandLayout, HandPoints, Handedness, IkOptions, Joints, KinError, Pose, UrModel};

type F1<'py> = PyReadonlyArray1<'py, f64>;
type F2<'py> = PyReadonlyArray2<'py, f64>;
type Arr1<'py> = Bound<'py, PyArray1<f64>>;
type Arr2<'py> = Bound<'py, PyArray2<f64>>;
type Arr3<'py> = Bound<'py, PyArray3<f64>>;
type Ok1<'py> = Bound<'py, PyArray1<bool>>;

fn model(name: &str) -> PyResult<&'static UrModel> {
    UrModel::by_name(name).map_err(kin_err)
}

fn shape_err(what: &str, expected: &str, got: &[usize]) -> PyErr {
    PyValueError::new_err(format!("{what} must have shape {expected}, got {got:?}"))
}

fn finite<'a>(it: impl IntoIterator<Item = &'a f64>, what: &str) -> PyResult<()> {
    let bad = || PyValueError::new_err(format!("{what} holds a NaN or an infinity"));
    it.into_iter().all(|x| x.is_finite()).then_some(()).ok_or_else(bad)
}

/// A `(K,)` array as `[f64; K]`.
fn vector<const K: usize>(v: ArrayView1<'_, f64>, what: &str) -> PyResult<[f64; K]> {
    let a = (v.len() == K).then(|| std::array::from_fn(|i| v[i]));
    a.ok_or_else(|| shape_err(what, &format!("({K},)"), v.shape()))
}

fn joints(v: &F1<'_>, what: &str) -> PyResult<Joints> {
    let q = vector::<6>(v.as_array(), what)?;
    finite(&q, what).map(|_| q)
}

/// Rows of an `(N, K)` array (`n`: the N required) as `[f64; K]`.
fn rows<const K: usize>(a: &F2<'_>, what: &str, n: Option<usize>) -> PyResult<Vec<[f64; K]>> {
    let a = a.as_array();
    if a.shape() != [n.unwrap_or(a.shape()[0]), K] {
        let n = n.map_or("N".to_string(), |n| n.to_string());
        return Err(shape_err(what, &format!("({n}, {K})"), a.shape()));
    }
    Ok(a.rows().into_iter().map(|r| std::array::from_fn(|k| r[k])).collect())
}

fn matrix(m: ArrayView2<'_, f64>) -> Matrix4<f64> {
    Matrix4::from_fn(|r, c| m[[r, c]])
}

fn pose_from(m: &F2<'_>, what: &str) -> PyResult<Pose> {
    let m = m.as_array();
    if m.shape() != [4, 4] {
        return Err(shape_err(what, "(4, 4)", m.shape()));
    }
    ur3_kin::pose_from_matrix(&matrix(m)).map_err(|e| PyValueError::new_err(format!("{what}: {e}")))
}

fn arr2(p: &Pose) -> Array2<f64> {
    let h = p.to_homogeneous();
    Array2::from_shape_fn((4, 4), |(r, c)| h[(r, c)])
}

fn stack(ps: &[Pose]) -> Array3<f64> {
    let hs: Vec<Matrix4<f64>> = ps.iter().map(Pose::to_homogeneous).collect();
    Array3::from_shape_fn((hs.len(), 4, 4), |(i, r, c)| hs[i][(r, c)])
}

fn table<const K: usize>(rows: &[[f64; K]]) -> Array2<f64> {
    Array2::from_shape_fn((rows.len(), K), |(r, c)| rows[r][c])
}

/// A calibration as Python passes it: `(base_from_space (4, 4) | None, scale, space name)`.
#[derive(FromPyObject)]
pub(crate) struct Calib<'py>(Option<F2<'py>>, f64, String);

impl Calib<'_> {
    pub(crate) fn get(&self) -> PyResult<Calibration> {
        let base = self.0.as_ref().map(|m| pose_from(m, "base_from_space")).transpose()?;
        Calibration::new(base, self.1, &self.2).map_err(kin_err)
    }
}

/// Names of the supported models.
#[pyfunction]
fn kin_models() -> Vec<&'static str> {
    ur3_kin::MODELS.iter().map(|m| m.name).collect()
}

/// DH parameters of a model: dict d1, a2, a3, d4, d5, d6 (metres) and reach.
#[pyfunction]
fn kin_dh(model_name: &str) -> PyResult<std::collections::BTreeMap<&'static str, f64>> {
    Ok(model(model_name)?.dh_table())
}

/// FK: q (6,) → tool0 in Base (4, 4).
#[pyfunction]
fn kin_fk<'py>(py: Python<'py>, q: F1<'py>, model_name: &str) -> PyResult<Arr2<'py>> {
    Ok(arr2(&ur3_kin::fk(model(model_name)?, &joints(&q, "q")?)).into_pyarray(py))
}

/// FK of many configurations: q (N, 6) → (N, 4, 4).
#[pyfunction]
fn kin_fk_batch<'py>(py: Python<'py>, q: F2<'py>, model_name: &str) -> PyResult<Arr3<'py>> {
    let (m, qs) = (model(model_name)?, rows::<6>(&q, "q", None)?);
    finite(qs.iter().flatten(), "q")?;
    Ok(stack(&ur3_kin::fk_batch(m, &qs)).into_pyarray(py))
}

/// Every DH frame (Base, after joint 1, …, tool0): (7, 4, 4).
#[pyfunction]
fn kin_fk_all<'py>(py: Python<'py>, q: F1<'py>, model_name: &str) -> PyResult<Arr3<'py>> {
    Ok(stack(&ur3_kin::fk_all(model(model_name)?, &joints(&q, "q")?)).into_pyarray(py))
}

/// Geometric Jacobian at tool0 in Base: (6, 6), rows linear then angular.
#[pyfunction]
fn kin_jacobian<'py>(py: Python<'py>, q: F1<'py>, model_name: &str) -> PyResult<Arr2<'py>> {
    let j = ur3_kin::jacobian(model(model_name)?, &joints(&q, "q")?);
    Ok(Array2::from_shape_fn((6, 6), |(r, c)| j[(r, c)]).into_pyarray(py))
}

/// IK nearest the seed: T (4, 4), seed (6,) or None → q (6,). Raises IkError / ValueError.
#[pyfunction]
#[pyo3(signature = (t, seed, model_name, tol=None))]
fn kin_ik<'py>(
    py: Python<'py>,
    t: F2<'py>,
    seed: Option<F1<'py>>,
    model_name: &str,
    tol: Option<f64>,
) -> PyResult<Arr1<'py>> {
    let (m, target) = (model(model_name)?, pose_from(&t, "T")?);
    let seed = seed.map(|s| joints(&s, "seed")).transpose()?;
    let q = ur3_kin::ik(m, &target, seed.as_ref(), &IkOptions::with_tol(tol).map_err(kin_err)?);
    Ok(Array1::from(q.map_err(kin_err)?.to_vec()).into_pyarray(py))
}

/// The paper's Gauss-Newton alone from a seed (no closed form): T (4, 4), seed (6,) → q (6,).
#[pyfunction]
#[pyo3(signature = (t, seed, model_name, tol=None, max_iters=100))]
fn kin_ik_gn<'py>(
    py: Python<'py>,
    t: F2<'py>,
    seed: F1<'py>,
    model_name: &str,
    tol: Option<f64>,
    max_iters: usize,
) -> PyResult<Arr1<'py>> {
    let (m, target, seed) = (model(model_name)?, pose_from(&t, "T")?, joints(&seed, "seed")?);
    let opts = IkOptions::gauss_newton(tol, max_iters).map_err(kin_err)?;
    Ok(Array1::from(ur3_kin::ik_gn(m, &target, &seed, &opts).map_err(kin_err)?.to_vec()).into_pyarray(py))
}

/// Every closed-form solution: T (4, 4) → (k, 6), k ≤ 8 (k = 0 when unreachable).
#[pyfunction]
#[pyo3(signature = (t, model_name, q6_ref=0.0))]
fn kin_ik_all<'py>(py: Python<'py>, t: F2<'py>, model_name: &str, q6_ref: f64) -> PyResult<Arr2<'py>> {
    let (m, target) = (model(model_name)?, pose_from(&t, "T")?);
    finite(&[q6_ref], "q6_ref")?;
    Ok(table(&ur3_kin::ik_all_with_q6(m, &target, q6_ref)).into_pyarray(py))
}

/// Batched IK, GIL released: Ts (N, 4, 4), seeds (N, 6) | None → (q (N, 6), ok (N,)); failed rows NaN.
#[pyfunction]
#[pyo3(signature = (ts, seeds, model_name, threads=0, tol=None))]
fn kin_ik_batch<'py>(
    py: Python<'py>,
    ts: PyReadonlyArray3<'py, f64>,
    seeds: Option<F2<'py>>,
    model_name: &str,
    threads: usize,
    tol: Option<f64>,
) -> PyResult<(Arr2<'py>, Ok1<'py>)> {
    let (m, a, opts) = (model(model_name)?, ts.as_array(), IkOptions::with_tol(tol).map_err(kin_err)?);
    if a.shape()[1..] != [4, 4] {
        return Err(shape_err("Ts", "(N, 4, 4)", a.shape()));
    }
    let seeds = seeds.map(|s| rows::<6>(&s, "seeds", Some(a.shape()[0]))).transpose()?;
    let mats: Vec<Matrix4<f64>> = a.outer_iter().map(matrix).collect();
    let res = py.detach(|| ur3_kin::ik_batch_matrices(m, &mats, seeds.as_deref(), &opts, threads));
    let res = res.map_err(|e| match e {
        KinError::NonFinite(_) => PyValueError::new_err("seeds hold a NaN or an infinity"),
        e => kin_err(e),
    })?;
    let (q, ok) = ur3_kin::split_failures(&res, [f64::NAN; 6]);
    Ok((table(&q).into_pyarray(py), Array1::from(ok).into_pyarray(py)))
}

/// Hand joints (3,) each, in the calibration's space → tool0 target (4, 4) in Base.
#[pyfunction]
fn kin_hand_to_target<'py>(
    py: Python<'py>,
    wrist: F1<'py>,
    index_proximal: F1<'py>,
    middle_proximal: F1<'py>,
    handedness: &str,
    calibration: Calib<'py>,
) -> PyResult<Arr2<'py>> {
    let v = |a: &F1<'py>, what| vector::<3>(a.as_array(), what);
    let (w, i, m) =
        (v(&wrist, "wrist")?, v(&index_proximal, "index_proximal")?, v(&middle_proximal, "middle_proximal")?);
    let hd = Handedness::from_name(handedness).map_err(kin_err)?;
    let t = ur3_kin::hand_to_target(&HandPoints::new(w, i, m), hd, &calibration.get()?).map_err(kin_err)?;
    Ok(arr2(&t).into_pyarray(py))
}

/// Many frames (N, 3) each → (T (N, 4, 4), ok (N,)); degenerate frames: ok False, identity T.
#[pyfunction]
fn kin_hand_to_target_batch<'py>(
    py: Python<'py>,
    wrist: F2<'py>,
    index_proximal: F2<'py>,
    middle_proximal: F2<'py>,
    handedness: &str,
    calibration: Calib<'py>,
) -> PyResult<(Arr3<'py>, Ok1<'py>)> {
    let n = Some(wrist.as_array().shape()[0]);
    let (w, i, m) = (
        rows(&wrist, "wrist", n)?,
        rows(&index_proximal, "index_proximal", n)?,
        rows(&middle_proximal, "middle_proximal", n)?,
    );
    let hands: Vec<HandPoints> = (0..w.len()).map(|k| HandPoints::new(w[k], i[k], m[k])).collect();
    let hd = Handedness::from_name(handedness).map_err(kin_err)?;
    let res = ur3_kin::hand_to_target_batch(&hands, hd, &calibration.get()?);
    let (ts, ok) = ur3_kin::split_failures(&res, Pose::identity());
    Ok((stack(&ts).into_pyarray(py), Array1::from(ok).into_pyarray(py)))
}

/// Points (N, 3) in the calibration's space → (N, 3) in the robot Base frame.
#[pyfunction]
fn kin_points_to_base<'py>(py: Python<'py>, points: F2<'py>, calibration: Calib<'py>) -> PyResult<Arr2<'py>> {
    let p: Vec<_> = rows::<3>(&points, "points", None)?.into_iter().map(Into::into).collect();
    let b: Vec<[f64; 3]> = calibration.get()?.points_to_base(&p).into_iter().map(Into::into).collect();
    Ok(table(&b).into_pyarray(py))
}

/// The default calibration's base_from_space (4, 4), scale and space name.
#[pyfunction]
fn kin_default_calibration<'py>(py: Python<'py>) -> (Arr2<'py>, f64, &'static str) {
    let c = Calibration::default();
    (arr2(&c.base_from_space).into_pyarray(py), c.scale, c.space.name())
}

/// Every hand layout (ur3-kin's `HandLayout` table): name → dict `joints` (the runtime's joint
/// names), `openxr` (each joint's OpenXR index, None where OpenXR has none), `wrist`,
/// `index_proximal`, `middle_proximal` (the indices the hand frame reads).
#[pyfunction]
fn kin_hand_layouts(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    for l in HandLayout::ALL {
        let d = dict!(py; "joints" => l.joint_names(), "openxr" => l.openxr_joints(), "wrist" => l.wrist(),
            "index_proximal" => l.index_proximal(), "middle_proximal" => l.middle_proximal());
        out.set_item(l.name(), d)?;
    }
    Ok(out)
}

/// The URDF (string) of a model, written from its DH table.
#[pyfunction]
fn kin_urdf(model_name: &str) -> PyResult<String> {
    Ok(ur3_kin::urdf::to_urdf_string(model(model_name)?))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    add_functions!(m => kin_models, kin_dh, kin_fk, kin_fk_batch, kin_fk_all, kin_jacobian, kin_ik, kin_ik_gn,
        kin_ik_all, kin_ik_batch, kin_hand_to_target, kin_hand_to_target_batch, kin_points_to_base,
        kin_default_calibration, kin_urdf, kin_hand_layouts);
    Ok(())
}
