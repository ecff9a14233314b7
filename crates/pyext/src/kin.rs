//! Bindings for ur3-kin: conversion between numpy arrays and the crate's types, error mapping,
//! and releasing the interpreter lock around batched work. No kinematics lives here.
//!
//! Error mapping: `Unreachable` / `NotConverged` → `mimicrete.IkError`; bad shapes, unknown names,
//! non-finite numbers, non-rigid matrices and degenerate hands → `ValueError`.

use crate::errors::IkError;
use numpy::ndarray::{Array1, Array2, Array3, ArrayView1, ArrayView2};
use numpy::{
    IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use ur3_kin::nalgebra::{Matrix4, Vector3};
use ur3_kin::{Calibration, Handedness, IkOptions, Joints, KinError, Pose, Space, UrModel};

fn kin_err(e: KinError) -> PyErr {
    match e {
        KinError::Unreachable { .. } | KinError::NotConverged { .. } => IkError::new_err(e.to_string()),
        other => PyValueError::new_err(other.to_string()),
    }
}

fn model(name: &str) -> PyResult<&'static UrModel> {
    UrModel::by_name(name).map_err(kin_err)
}

fn shape_err(what: &str, expected: &str, got: &[usize]) -> PyErr {
    PyValueError::new_err(format!("{what} must have shape {expected}, got {got:?}"))
}

fn joints_from(v: ArrayView1<'_, f64>, what: &str) -> PyResult<Joints> {
    if v.len() != 6 {
        return Err(shape_err(what, "(6,)", v.shape()));
    }
    if v.iter().any(|x| !x.is_finite()) {
        return Err(PyValueError::new_err(format!("{what} holds a NaN or an infinity")));
    }
    Ok(std::array::from_fn(|i| v[i]))
}

/// The model and the joint vector `q` (6,) of a single-configuration call.
fn model_and_q(model_name: &str, q: &PyReadonlyArray1<'_, f64>) -> PyResult<(&'static UrModel, Joints)> {
    Ok((model(model_name)?, joints_from(q.as_array(), "q")?))
}

fn vec3_from(v: ArrayView1<'_, f64>, what: &str) -> PyResult<Vector3<f64>> {
    if v.len() != 3 {
        return Err(shape_err(what, "(3,)", v.shape()));
    }
    Ok(Vector3::new(v[0], v[1], v[2]))
}

fn pose_from(m: ArrayView2<'_, f64>, what: &str) -> PyResult<Pose> {
    if m.shape() != [4, 4] {
        return Err(shape_err(what, "(4, 4)", m.shape()));
    }
    let mat = Matrix4::from_fn(|r, c| m[[r, c]]);
    ur3_kin::pose_from_matrix(&mat).map_err(|e| PyValueError::new_err(format!("{what}: {e}")))
}

fn pose_to_array(p: &Pose) -> Array2<f64> {
    let h = p.to_homogeneous();
    Array2::from_shape_fn((4, 4), |(r, c)| h[(r, c)])
}

/// Homogeneous matrices → one `(N, 4, 4)` array.
fn stack_homogeneous(hs: &[Matrix4<f64>]) -> Array3<f64> {
    Array3::from_shape_fn((hs.len(), 4, 4), |(i, r, c)| hs[i][(r, c)])
}

fn options(tol: Option<f64>) -> PyResult<IkOptions> {
    let mut o = IkOptions::default();
    if let Some(t) = tol {
        if !(t.is_finite() && t > 0.0) {
            return Err(PyValueError::new_err(format!("tol must be a positive finite number, got {t}")));
        }
        o.tol_pos_m = t;
        o.tol_rot_rad = t;
    }
    Ok(o)
}

/// Names of the supported models.
#[pyfunction]
fn kin_models() -> Vec<&'static str> {
    ur3_kin::MODELS.iter().map(|m| m.name).collect()
}

/// DH parameters of a model: dict d1, a2, a3, d4, d5, d6 (metres) and reach.
#[pyfunction]
fn kin_dh(py: Python<'_>, model_name: &str) -> PyResult<Py<pyo3::types::PyDict>> {
    let m = model(model_name)?;
    let d = pyo3::types::PyDict::new(py);
    for (k, v) in [
        ("d1", m.d1),
        ("a2", m.a2),
        ("a3", m.a3),
        ("d4", m.d4),
        ("d5", m.d5),
        ("d6", m.d6),
        ("reach", m.reach()),
    ] {
        d.set_item(k, v)?;
    }
    Ok(d.unbind())
}

/// FK: q (6,) → tool0 in Base (4, 4).
#[pyfunction]
fn kin_fk<'py>(
    py: Python<'py>,
    q: PyReadonlyArray1<'py, f64>,
    model_name: &str,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (m, q) = model_and_q(model_name, &q)?;
    Ok(pose_to_array(&ur3_kin::fk(m, &q)).into_pyarray(py))
}

/// FK of many configurations: q (N, 6) → (N, 4, 4).
#[pyfunction]
fn kin_fk_batch<'py>(
    py: Python<'py>,
    q: PyReadonlyArray2<'py, f64>,
    model_name: &str,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let m = model(model_name)?;
    let a = q.as_array();
    if a.shape()[1] != 6 {
        return Err(shape_err("q", "(N, 6)", a.shape()));
    }
    if a.iter().any(|x| !x.is_finite()) {
        return Err(PyValueError::new_err("q holds a NaN or an infinity"));
    }
    let hs: Vec<Matrix4<f64>> = (0..a.shape()[0])
        .map(|i| {
            let qi: Joints = std::array::from_fn(|k| a[[i, k]]);
            ur3_kin::fk(m, &qi).to_homogeneous()
        })
        .collect();
    Ok(stack_homogeneous(&hs).into_pyarray(py))
}

/// Every DH frame (Base, after joint 1, …, tool0): (7, 4, 4).
#[pyfunction]
fn kin_fk_all<'py>(
    py: Python<'py>,
    q: PyReadonlyArray1<'py, f64>,
    model_name: &str,
) -> PyResult<Bound<'py, PyArray3<f64>>> {
    let (m, q) = model_and_q(model_name, &q)?;
    let hs: Vec<Matrix4<f64>> = ur3_kin::fk_all(m, &q).iter().map(Pose::to_homogeneous).collect();
    Ok(stack_homogeneous(&hs).into_pyarray(py))
}

/// Geometric Jacobian at tool0 in Base: (6, 6), rows linear then angular.
#[pyfunction]
fn kin_jacobian<'py>(
    py: Python<'py>,
    q: PyReadonlyArray1<'py, f64>,
    model_name: &str,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let (m, q) = model_and_q(model_name, &q)?;
    let j = ur3_kin::jacobian(m, &q);
    Ok(Array2::from_shape_fn((6, 6), |(r, c)| j[(r, c)]).into_pyarray(py))
}

/// IK nearest the seed: T (4, 4), seed (6,) or None → q (6,). Raises IkError / ValueError.
#[pyfunction]
#[pyo3(signature = (t, seed, model_name, tol=None))]
fn kin_ik<'py>(
    py: Python<'py>,
    t: PyReadonlyArray2<'py, f64>,
    seed: Option<PyReadonlyArray1<'py, f64>>,
    model_name: &str,
    tol: Option<f64>,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = model(model_name)?;
    let target = pose_from(t.as_array(), "T")?;
    let seed = seed.map(|s| joints_from(s.as_array(), "seed")).transpose()?;
    let opts = options(tol)?;
    let q = ur3_kin::ik(m, &target, seed.as_ref(), &opts).map_err(kin_err)?;
    Ok(Array1::from(q.to_vec()).into_pyarray(py))
}

/// The paper's Gauss-Newton alone from a seed (no closed form): T (4, 4), seed (6,) → q (6,).
#[pyfunction]
#[pyo3(signature = (t, seed, model_name, tol=None, max_iters=100))]
fn kin_ik_gn<'py>(
    py: Python<'py>,
    t: PyReadonlyArray2<'py, f64>,
    seed: PyReadonlyArray1<'py, f64>,
    model_name: &str,
    tol: Option<f64>,
    max_iters: usize,
) -> PyResult<Bound<'py, PyArray1<f64>>> {
    let m = model(model_name)?;
    let target = pose_from(t.as_array(), "T")?;
    let seed = joints_from(seed.as_array(), "seed")?;
    let opts = IkOptions { max_iters, use_analytic: false, max_step_rad: f64::INFINITY, ..options(tol)? };
    let q = ur3_kin::ik_gn(m, &target, &seed, &opts).map_err(kin_err)?;
    Ok(Array1::from(q.to_vec()).into_pyarray(py))
}

/// Every closed-form solution: T (4, 4) → (k, 6), k ≤ 8 (k = 0 when unreachable).
#[pyfunction]
#[pyo3(signature = (t, model_name, q6_ref=0.0))]
fn kin_ik_all<'py>(
    py: Python<'py>,
    t: PyReadonlyArray2<'py, f64>,
    model_name: &str,
    q6_ref: f64,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let m = model(model_name)?;
    let target = pose_from(t.as_array(), "T")?;
    if !q6_ref.is_finite() {
        return Err(PyValueError::new_err("q6_ref must be finite"));
    }
    let sols = ur3_kin::ik_all_with_q6(m, &target, q6_ref);
    Ok(Array2::from_shape_fn((sols.len(), 6), |(r, c)| sols[r][c]).into_pyarray(py))
}

/// Batched IK over threads (GIL released): Ts (N, 4, 4), seeds (N, 6) or None →
/// (q (N, 6), ok (N,) bool). Rows whose solve failed (or whose T is not a rigid transform) hold
/// NaN in q and False in ok.
#[pyfunction]
#[pyo3(signature = (ts, seeds, model_name, threads=0, tol=None))]
#[allow(clippy::type_complexity)]
fn kin_ik_batch<'py>(
    py: Python<'py>,
    ts: PyReadonlyArray3<'py, f64>,
    seeds: Option<PyReadonlyArray2<'py, f64>>,
    model_name: &str,
    threads: usize,
    tol: Option<f64>,
) -> PyResult<(Bound<'py, PyArray2<f64>>, Bound<'py, PyArray1<bool>>)> {
    let m = model(model_name)?;
    let a = ts.as_array();
    if a.shape()[1..] != [4, 4] {
        return Err(shape_err("Ts", "(N, 4, 4)", a.shape()));
    }
    let n = a.shape()[0];
    let seeds: Option<Vec<Joints>> = match seeds {
        None => None,
        Some(s) => {
            let s = s.as_array();
            if s.shape() != [n, 6] {
                return Err(shape_err("seeds", &format!("({n}, 6) to match Ts"), s.shape()));
            }
            if s.iter().any(|x| !x.is_finite()) {
                return Err(PyValueError::new_err("seeds hold a NaN or an infinity"));
            }
            Some((0..n).map(|i| std::array::from_fn(|k| s[[i, k]])).collect())
        }
    };
    let opts = options(tol)?;
    // Invalid matrices become per-row failures (like unreachable targets), not an exception.
    let mut valid = vec![true; n];
    let targets: Vec<Pose> = (0..n)
        .map(|i| {
            let mat = Matrix4::from_fn(|r, c| a[[i, r, c]]);
            ur3_kin::pose_from_matrix(&mat).unwrap_or_else(|_| {
                valid[i] = false;
                Pose::identity()
            })
        })
        .collect();
    let results = py.detach(|| ur3_kin::ik_batch(m, &targets, seeds.as_deref(), &opts, threads));
    let mut q = Array2::<f64>::from_elem((n, 6), f64::NAN);
    let mut ok = Array1::<bool>::from_elem(n, false);
    for (i, r) in results.into_iter().enumerate() {
        if let (true, Ok(s)) = (valid[i], r) {
            ok[i] = true;
            for k in 0..6 {
                q[[i, k]] = s[k];
            }
        }
    }
    Ok((q.into_pyarray(py), ok.into_pyarray(py)))
}

fn calibration(
    base_from_space: Option<PyReadonlyArray2<'_, f64>>,
    scale: f64,
    space: &str,
) -> PyResult<Calibration> {
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

/// Hand joints → tool0 target (4, 4) in Base. Points (3,) in `space`; `base_from_space` (4, 4)
/// or None for the default calibration's transform.
#[pyfunction]
#[pyo3(signature = (wrist, index_proximal, middle_proximal, handedness, base_from_space, scale, space))]
#[allow(clippy::too_many_arguments)]
fn kin_hand_to_target<'py>(
    py: Python<'py>,
    wrist: PyReadonlyArray1<'py, f64>,
    index_proximal: PyReadonlyArray1<'py, f64>,
    middle_proximal: PyReadonlyArray1<'py, f64>,
    handedness: &str,
    base_from_space: Option<PyReadonlyArray2<'py, f64>>,
    scale: f64,
    space: &str,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let hd = Handedness::from_name(handedness).map_err(kin_err)?;
    let cal = calibration(base_from_space, scale, space)?;
    let w = vec3_from(wrist.as_array(), "wrist")?;
    let i = vec3_from(index_proximal.as_array(), "index_proximal")?;
    let mp = vec3_from(middle_proximal.as_array(), "middle_proximal")?;
    let t = ur3_kin::hand_to_target(&w, &i, &mp, hd, &cal).map_err(kin_err)?;
    Ok(pose_to_array(&t).into_pyarray(py))
}

/// Many frames: wrist, index_proximal, middle_proximal (N, 3) → (T (N, 4, 4), ok (N,)).
/// Degenerate or non-finite frames give ok False and an identity T.
#[pyfunction]
#[pyo3(signature = (wrist, index_proximal, middle_proximal, handedness, base_from_space, scale, space))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
fn kin_hand_to_target_batch<'py>(
    py: Python<'py>,
    wrist: PyReadonlyArray2<'py, f64>,
    index_proximal: PyReadonlyArray2<'py, f64>,
    middle_proximal: PyReadonlyArray2<'py, f64>,
    handedness: &str,
    base_from_space: Option<PyReadonlyArray2<'py, f64>>,
    scale: f64,
    space: &str,
) -> PyResult<(Bound<'py, PyArray3<f64>>, Bound<'py, PyArray1<bool>>)> {
    let hd = Handedness::from_name(handedness).map_err(kin_err)?;
    let cal = calibration(base_from_space, scale, space)?;
    let (w, i, mp) = (wrist.as_array(), index_proximal.as_array(), middle_proximal.as_array());
    let n = w.shape()[0];
    for (name, a) in [("wrist", &w), ("index_proximal", &i), ("middle_proximal", &mp)] {
        if a.shape() != [n, 3] {
            return Err(shape_err(name, &format!("({n}, 3)"), a.shape()));
        }
    }
    let mut ok = Array1::<bool>::from_elem(n, false);
    let hs: Vec<Matrix4<f64>> = (0..n)
        .map(|k| {
            let v = |a: &ArrayView2<'_, f64>| Vector3::new(a[[k, 0]], a[[k, 1]], a[[k, 2]]);
            match ur3_kin::hand_to_target(&v(&w), &v(&i), &v(&mp), hd, &cal) {
                Ok(t) => {
                    ok[k] = true;
                    t.to_homogeneous()
                }
                Err(_) => Matrix4::identity(),
            }
        })
        .collect();
    Ok((stack_homogeneous(&hs).into_pyarray(py), ok.into_pyarray(py)))
}

/// A point (3,) or points (N, 3) from `space` into the robot Base frame.
#[pyfunction]
#[pyo3(signature = (points, base_from_space, scale, space))]
fn kin_points_to_base<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    base_from_space: Option<PyReadonlyArray2<'py, f64>>,
    scale: f64,
    space: &str,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let cal = calibration(base_from_space, scale, space)?;
    let p = points.as_array();
    if p.shape()[1] != 3 {
        return Err(shape_err("points", "(N, 3)", p.shape()));
    }
    let n = p.shape()[0];
    let mut out = Array2::<f64>::zeros((n, 3));
    for k in 0..n {
        let b = cal.point_to_base(&Vector3::new(p[[k, 0]], p[[k, 1]], p[[k, 2]]));
        for c in 0..3 {
            out[[k, c]] = b[c];
        }
    }
    Ok(out.into_pyarray(py))
}

/// The default calibration's base_from_space (4, 4), scale and space name.
#[pyfunction]
fn kin_default_calibration<'py>(py: Python<'py>) -> (Bound<'py, PyArray2<f64>>, f64, &'static str) {
    let c = Calibration::default();
    (pose_to_array(&c.base_from_space).into_pyarray(py), c.scale, c.space.name())
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
