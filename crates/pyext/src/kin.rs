//! Bindings for ur3-kin: numpy arrays ↔ the crate's types, error mapping (`errors::kin_err`), the
//! interpreter lock released around batched work. The batch loops and their per-row failure
//! policy are ur3-kin's (`fk_batch`, `ik_batch_matrices`, `hand_to_target_batch`).

use crate::errors::kin_err;
use numpy::ndarray::{Array1, Array2, Array3, ArrayView1, ArrayView2};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use ur3_kin::nalgebra::{Matrix4, Vector3};
use ur3_kin::{Calibration, Handedness, IkOptions, Joints, KinError, Pose, Space, UrModel};

type Arr1<'py> = Bound<'py, PyArray1<f64>>;
type F1<'py> = PyReadonlyArray1<'py, f64>;
type F2<'py> = PyReadonlyArray2<'py, f64>;
type F3<'py> = PyReadonlyArray3<'py, f64>;
type Ok1<'py> = Bound<'py, PyArray1<bool>>;
type Arr2<'py> = Bound<'py, PyArray2<f64>>;
type Arr3<'py> = Bound<'py, PyArray3<f64>>;

fn model(name: &str) -> PyResult<&'static UrModel> {
    UrModel::by_name(name).map_err(kin_err)
}

fn shape_err(what: &str, expected: &str, got: &[usize]) -> PyErr {
    PyValueError::new_err(format!("{what} must have shape {expected}, got {got:?}"))
}

fn finite(it: impl IntoIterator<Item = f64>, what: &str) -> PyResult<()> {
    match it.into_iter().all(f64::is_finite) {
        true => Ok(()),
        false => Err(PyValueError::new_err(format!("{what} holds a NaN or an infinity"))),
    }
}

fn joints_from(v: ArrayView1<'_, f64>, what: &str) -> PyResult<Joints> {
    if v.len() != 6 {
        return Err(shape_err(what, "(6,)", v.shape()));
    }
    finite(v.iter().copied(), what)?;
    Ok(std::array::from_fn(|i| v[i]))
}

/// Rows of an `(N, k)` array as `[f64; K]`.
fn rows<const K: usize>(a: ArrayView2<'_, f64>, what: &str, n: Option<usize>) -> PyResult<Vec<[f64; K]>> {
    let want = n.unwrap_or(a.shape()[0]);
    if a.shape() != [want, K] {
        let n = n.map_or("N".to_string(), |n| n.to_string());
        return Err(shape_err(what, &format!("({n}, {K})"), a.shape()));
    }
    Ok(a.rows().into_iter().map(|r| std::array::from_fn(|k| r[k])).collect())
}

fn vec3_from(v: ArrayView1<'_, f64>, what: &str) -> PyResult<Vector3<f64>> {
    if v.len() != 3 {
        return Err(shape_err(what, "(3,)", v.shape()));
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

fn matrix(m: ArrayView2<'_, f64>) -> Matrix4<f64> {
    Matrix4::from_fn(|r, c| m[[r, c]])
}

fn pose_from(m: ArrayView2<'_, f64>, what: &str) -> PyResult<Pose> {
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

fn options(tol: Option<f64>) -> PyResult<IkOptions> {
    let mut o = IkOptions::default();
    if let Some(t) = tol {
        if !(t.is_finite() && t > 0.0) {
            return Err(PyValueError::new_err(format!("tol must be a positive finite number, got {t}")));
        }
        (o.tol_pos_m, o.tol_rot_rad) = (t, t);
    }
    Ok(o)
}

fn joints_arr<'py>(py: Python<'py>, q: Joints) -> Arr1<'py> {
    Array1::from(q.to_vec()).into_pyarray(py)
}

/// Names of the supported models.
#[pyfunction]
fn kin_models() -> Vec<&'static str> {
    ur3_kin::MODELS.iter().map(|m| m.name).collect()
}

/// DH parameters of a model: dict d1, a2, a3, d4, d5, d6 (metres) and reach.
#[pyfunction]
fn kin_dh(model_name: &str) -> PyResult<std::collections::BTreeMap<&'static str, f64>> {
    let m = model(model_name)?;
    let kv = [("d1", m.d1), ("a2", m.a2), ("a3", m.a3), ("d4", m.d4), ("d5", m.d5), ("d6", m.d6)];
    Ok(kv.into_iter().chain([("reach", m.reach())]).collect())
}

/// FK: q (6,) → tool0 in Base (4, 4).
#[pyfunction]
fn kin_fk<'py>(py: Python<'py>, q: F1<'py>, model_name: &str) -> PyResult<Arr2<'py>> {
    Ok(arr2(&ur3_kin::fk(model(model_name)?, &joints_from(q.as_array(), "q")?)).into_pyarray(py))
}

/// FK of many configurations: q (N, 6) → (N, 4, 4).
#[pyfunction]
fn kin_fk_batch<'py>(py: Python<'py>, q: F2<'py>, model_name: &str) -> PyResult<Arr3<'py>> {
    let m = model(model_name)?;
    let qs = rows::<6>(q.as_array(), "q", None)?;
    finite(qs.iter().flatten().copied(), "q")?;
    Ok(stack(&ur3_kin::fk_batch(m, &qs)).into_pyarray(py))
}

/// Every DH frame (Base, after joint 1, …, tool0): (7, 4, 4).
#[pyfunction]
fn kin_fk_all<'py>(py: Python<'py>, q: F1<'py>, model_name: &str) -> PyResult<Arr3<'py>> {
    Ok(stack(&ur3_kin::fk_all(model(model_name)?, &joints_from(q.as_array(), "q")?)).into_pyarray(py))
}

/// Geometric Jacobian at tool0 in Base: (6, 6), rows linear then angular.
#[pyfunction]
fn kin_jacobian<'py>(py: Python<'py>, q: F1<'py>, model_name: &str) -> PyResult<Arr2<'py>> {
    let j = ur3_kin::jacobian(model(model_name)?, &joints_from(q.as_array(), "q")?);
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
    let (m, target) = (model(model_name)?, pose_from(t.as_array(), "T")?);
    let seed = seed.map(|s| joints_from(s.as_array(), "seed")).transpose()?;
    Ok(joints_arr(py, ur3_kin::ik(m, &target, seed.as_ref(), &options(tol)?).map_err(kin_err)?))
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
    let (m, target) = (model(model_name)?, pose_from(t.as_array(), "T")?);
    let seed = joints_from(seed.as_array(), "seed")?;
    let opts = IkOptions { max_iters, use_analytic: false, max_step_rad: f64::INFINITY, ..options(tol)? };
    Ok(joints_arr(py, ur3_kin::ik_gn(m, &target, &seed, &opts).map_err(kin_err)?))
}

/// Every closed-form solution: T (4, 4) → (k, 6), k ≤ 8 (k = 0 when unreachable).
#[pyfunction]
#[pyo3(signature = (t, model_name, q6_ref=0.0))]
fn kin_ik_all<'py>(py: Python<'py>, t: F2<'py>, model_name: &str, q6_ref: f64) -> PyResult<Arr2<'py>> {
    let (m, target) = (model(model_name)?, pose_from(t.as_array(), "T")?);
    finite([q6_ref], "q6_ref")?;
    let sols = ur3_kin::ik_all_with_q6(m, &target, q6_ref);
    Ok(Array2::from_shape_fn((sols.len(), 6), |(r, c)| sols[r][c]).into_pyarray(py))
}

/// Batched IK, GIL released: Ts (N, 4, 4), seeds (N, 6) | None → (q (N, 6), ok (N,)); failed rows NaN.
#[pyfunction]
#[pyo3(signature = (ts, seeds, model_name, threads=0, tol=None))]
fn kin_ik_batch<'py>(
    py: Python<'py>,
    ts: F3<'py>,
    seeds: Option<F2<'py>>,
    model_name: &str,
    threads: usize,
    tol: Option<f64>,
) -> PyResult<(Arr2<'py>, Ok1<'py>)> {
    let (m, a) = (model(model_name)?, ts.as_array());
    if a.shape()[1..] != [4, 4] {
        return Err(shape_err("Ts", "(N, 4, 4)", a.shape()));
    }
    let n = a.shape()[0];
    let seeds = seeds.map(|s| rows::<6>(s.as_array(), "seeds", Some(n))).transpose()?;
    let mats: Vec<Matrix4<f64>> = a.outer_iter().map(matrix).collect();
    let opts = options(tol)?;
    let res = py.detach(|| ur3_kin::ik_batch_matrices(m, &mats, seeds.as_deref(), &opts, threads));
    let res = res.map_err(|e| match e {
        KinError::NonFinite(_) => PyValueError::new_err("seeds hold a NaN or an infinity"),
        e => kin_err(e),
    })?;
    let q = Array2::from_shape_fn((n, 6), |(i, k)| res[i].as_ref().map_or(f64::NAN, |s| s[k]));
    let ok = Array1::from_iter(res.iter().map(Result::is_ok));
    Ok((q.into_pyarray(py), ok.into_pyarray(py)))
}

fn calibration(base_from_space: Option<F2<'_>>, scale: f64, space: &str) -> PyResult<Calibration> {
    let space = Space::from_name(space).map_err(kin_err)?;
    let base_from_space = match base_from_space {
        Some(m) => pose_from(m.as_array(), "base_from_space")?,
        None => Calibration::default().base_from_space,
    };
    if !(scale.is_finite() && scale > 0.0) {
        return Err(PyValueError::new_err(format!("scale must be a positive finite number, got {scale}")));
    }
    Ok(Calibration { base_from_space, scale, space })
}

/// Hand joints (3,) each, in `space` → tool0 target (4, 4) in Base (`base_from_space` None: default).
#[pyfunction]
#[pyo3(signature = (wrist, index_proximal, middle_proximal, handedness, base_from_space, scale, space))]
#[allow(clippy::too_many_arguments)]
fn kin_hand_to_target<'py>(
    py: Python<'py>,
    wrist: F1<'py>,
    index_proximal: F1<'py>,
    middle_proximal: F1<'py>,
    handedness: &str,
    base_from_space: Option<F2<'py>>,
    scale: f64,
    space: &str,
) -> PyResult<Arr2<'py>> {
    let hd = Handedness::from_name(handedness).map_err(kin_err)?;
    let cal = calibration(base_from_space, scale, space)?;
    let w = vec3_from(wrist.as_array(), "wrist")?;
    let i = vec3_from(index_proximal.as_array(), "index_proximal")?;
    let mp = vec3_from(middle_proximal.as_array(), "middle_proximal")?;
    Ok(arr2(&ur3_kin::hand_to_target(&w, &i, &mp, hd, &cal).map_err(kin_err)?).into_pyarray(py))
}

/// Many frames (N, 3) each → (T (N, 4, 4), ok (N,)); degenerate frames: ok False, identity T.
#[pyfunction]
#[pyo3(signature = (wrist, index_proximal, middle_proximal, handedness, base_from_space, scale, space))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn kin_hand_to_target_batch<'py>(
    py: Python<'py>,
    wrist: F2<'py>,
    index_proximal: F2<'py>,
    middle_proximal: F2<'py>,
    handedness: &str,
    base_from_space: Option<F2<'py>>,
    scale: f64,
    space: &str,
) -> PyResult<(Arr3<'py>, Ok1<'py>)> {
    let hd = Handedness::from_name(handedness).map_err(kin_err)?;
    let cal = calibration(base_from_space, scale, space)?;
    let n = Some(wrist.as_array().shape()[0]);
    let v = |a: &F2<'py>, what| -> PyResult<Vec<Vector3<f64>>> {
        Ok(rows::<3>(a.as_array(), what, n)?.into_iter().map(Vector3::from).collect())
    };
    let (w, i, m) =
        (v(&wrist, "wrist")?, v(&index_proximal, "index_proximal")?, v(&middle_proximal, "middle_proximal")?);
    let res = ur3_kin::hand_to_target_batch(&w, &i, &m, hd, &cal).map_err(kin_err)?;
    let ts: Vec<Pose> = res.iter().map(|r| r.as_ref().map_or(Pose::identity(), |p| *p)).collect();
    let ok = Array1::from_iter(res.iter().map(Result::is_ok));
    Ok((stack(&ts).into_pyarray(py), ok.into_pyarray(py)))
}

/// Points (N, 3) from `space` into the robot Base frame.
#[pyfunction]
#[pyo3(signature = (points, base_from_space, scale, space))]
fn kin_points_to_base<'py>(
    py: Python<'py>,
    points: F2<'py>,
    base_from_space: Option<F2<'py>>,
    scale: f64,
    space: &str,
) -> PyResult<Arr2<'py>> {
    let cal = calibration(base_from_space, scale, space)?;
    let p: Vec<Vector3<f64>> =
        rows::<3>(points.as_array(), "points", None)?.into_iter().map(Vector3::from).collect();
    let b = cal.points_to_base(&p);
    Ok(Array2::from_shape_fn((b.len(), 3), |(k, c)| b[k][c]).into_pyarray(py))
}

/// The default calibration's base_from_space (4, 4), scale and space name.
#[pyfunction]
fn kin_default_calibration<'py>(py: Python<'py>) -> (Arr2<'py>, f64, &'static str) {
    let c = Calibration::default();
    (arr2(&c.base_from_space).into_pyarray(py), c.scale, c.space.name())
}

/// The URDF (string) of a model, written from its DH table.
#[pyfunction]
fn kin_urdf(model_name: &str) -> PyResult<String> {
    Ok(ur3_kin::urdf::to_urdf_string(model(model_name)?))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(kin_models, m)?)?;
    m.add_function(wrap_pyfunction!(kin_dh, m)?)?;
    m.add_function(wrap_pyfunction!(kin_fk, m)?)?;
    m.add_function(wrap_pyfunction!(kin_fk_batch, m)?)?;
    m.add_function(wrap_pyfunction!(kin_fk_all, m)?)?;
    m.add_function(wrap_pyfunction!(kin_jacobian, m)?)?;
    m.add_function(wrap_pyfunction!(kin_ik, m)?)?;
    m.add_function(wrap_pyfunction!(kin_ik_gn, m)?)?;
    m.add_function(wrap_pyfunction!(kin_ik_all, m)?)?;
    m.add_function(wrap_pyfunction!(kin_ik_batch, m)?)?;
    m.add_function(wrap_pyfunction!(kin_hand_to_target, m)?)?;
    m.add_function(wrap_pyfunction!(kin_hand_to_target_batch, m)?)?;
    m.add_function(wrap_pyfunction!(kin_points_to_base, m)?)?;
    m.add_function(wrap_pyfunction!(kin_default_calibration, m)?)?;
    m.add_function(wrap_pyfunction!(kin_urdf, m)?)?;
    Ok(())
}
