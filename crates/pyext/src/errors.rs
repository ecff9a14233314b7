//! The exception tree (`MimicreteError` → `IkError`, `SimError`, `LogFormatError`, with the Rust
//! errors' fields; misuse raises `ValueError`) and the conversions Python ↔ JSON / serde / numpy.

use demo_log::NdArray;
use demo_log::serde_json::{Value, json};
use numpy::ndarray::ArrayD;
use numpy::{Element, IntoPyArray, PyArray1, PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::PyTypeInfo;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};

create_exception!(mimicrete._native, MimicreteError, PyException, "Base class of every mimicrete error.");
create_exception!(mimicrete._native, IkError, MimicreteError, "Inverse kinematics found no solution.");
create_exception!(mimicrete._native, SimError, MimicreteError, "The simulator refused an input or state.");
create_exception!(mimicrete._native, LogFormatError, MimicreteError, "A hand log or demo file is malformed.");

/// An exception of type `T` with message `msg` and the attributes of the JSON object `fields`.
fn raise<T: PyTypeInfo>(msg: String, fields: Value) -> PyErr {
    let e = PyErr::new::<T, _>(msg);
    let fields = fields.as_object().into_iter().flatten();
    let set =
        Python::attach(|py| fields.into_iter().try_for_each(|(k, v)| e.value(py).setattr(k, to_py(py, v)?)));
    set.err().unwrap_or(e)
}

/// ur3-kin errors: `Unreachable` / `NotConverged` → `IkError` with their fields, the rest `ValueError`.
pub(crate) fn kin_err(e: ur3_kin::KinError) -> PyErr {
    use ur3_kin::KinError as K;
    let msg = e.to_string();
    match e {
        K::Unreachable { reason } => raise::<IkError>(msg, json!({ "reason": reason })),
        K::NotConverged { iters, pos_residual_m: p, rot_residual_rad: r } => {
            let f = json!({"reason": "did not converge", "iters": iters,
                "pos_residual_m": p, "rot_residual_rad": r});
            raise::<IkError>(msg, f)
        }
        _ => PyValueError::new_err(msg),
    }
}

/// tile-sim errors: stepping a finished episode → `SimError`; the caller's mistakes → `ValueError`.
pub(crate) fn sim_err(e: tile_sim::SimError) -> PyErr {
    let msg = e.to_string();
    match e {
        tile_sim::SimError::EpisodeOver => raise::<SimError>(msg.clone(), json!({ "reason": msg })),
        _ => PyValueError::new_err(msg),
    }
}

/// `LogFormatError` with `str(e)` = `file:line: reason` (`file: reason` without a line).
pub(crate) fn log_format(file: &str, line: Option<usize>, reason: &str) -> PyErr {
    let msg = line.map_or(format!("{file}: {reason}"), |l| format!("{file}:{l}: {reason}"));
    raise::<LogFormatError>(msg, json!({"file": file, "line": line, "reason": reason}))
}

pub(crate) fn handlog_err(e: demo_log::HandLogError) -> PyErr {
    log_format(&e.file, Some(e.line), &e.reason)
}

/// demo-log errors: malformed files → `LogFormatError`, I/O → `OSError`, bad values → `ValueError`.
pub(crate) fn demo_err(e: demo_log::DemoError) -> PyErr {
    use demo_log::DemoError as D;
    match e {
        D::Io { .. } => PyOSError::new_err(e.to_string()),
        D::Invalid(m) => PyValueError::new_err(m),
        D::Format { path, reason } => log_format(&path.display().to_string(), None, &reason),
        D::Mcap { path, source } => {
            log_format(&path.display().to_string(), None, &format!("MCAP error: {source}"))
        }
        D::HandLog(h) => handlog_err(h),
    }
}

/// A `LogFormatError` for Python code, with the native ones' fields and message.
#[pyfunction]
#[pyo3(signature = (file, line, reason))]
fn log_format_error(py: Python<'_>, file: &str, line: Option<usize>, reason: &str) -> Py<PyAny> {
    log_format(file, line, reason).into_value(py).into_any()
}

/// A serde value as Python data: dicts, lists, tuples, bytes.
pub(crate) fn to_py<'py, T: serde::Serialize + ?Sized>(
    py: Python<'py>,
    v: &T,
) -> PyResult<Bound<'py, PyAny>> {
    pythonize::pythonize(py, v).map_err(PyErr::from)
}

/// Python data as JSON: dicts, lists, tuples, numpy (`tolist()`), path-likes, str, int, float, bool, None.
/// Containers are walked here (numpy values inside them too); the leaves are pythonize's.
pub(crate) fn from_py(o: &Bound<'_, PyAny>) -> PyResult<Value> {
    if let Ok(d) = o.cast::<PyDict>() {
        return d
            .iter()
            .map(|(k, v)| Ok((k.extract()?, from_py(&v)?)))
            .collect::<PyResult<_>>()
            .map(Value::Object);
    } else if o.is_instance_of::<PyList>() || o.is_instance_of::<PyTuple>() {
        return o.try_iter()?.map(|x| from_py(&x?)).collect::<PyResult<_>>().map(Value::Array);
    } else if let Some(m) = ["tolist", "__fspath__"].into_iter().find(|m| o.hasattr(*m).unwrap_or(false)) {
        return from_py(&o.call_method0(m)?);
    }
    match pythonize::depythonize::<Value>(o) {
        Ok(Value::Null) if !o.is_none() => {
            Err(PyValueError::new_err(format!("{o} is not a finite number (JSON)")))
        }
        Ok(v) => Ok(v),
        Err(_) => Err(PyValueError::new_err(format!("{} is not JSON data", o.get_type().name()?))),
    }
}

/// A numpy array of `a`'s shape and elements.
pub(crate) fn nd_to_py<T: Element>(py: Python<'_>, a: NdArray<T>) -> PyResult<Bound<'_, PyArrayDyn<T>>> {
    let a = ArrayD::from_shape_vec(a.shape, a.data).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(a.into_pyarray(py))
}

/// A 1-D numpy array of `v`.
pub(crate) fn vector<T: Element>(py: Python<'_>, v: Vec<T>) -> Bound<'_, PyArray1<T>> {
    v.into_pyarray(py)
}

/// A numpy array `(len / cols, cols)` from row-major `v`.
pub(crate) fn matrix<T: Element>(
    py: Python<'_>,
    v: Vec<T>,
    cols: usize,
) -> PyResult<Bound<'_, PyArrayDyn<T>>> {
    nd_to_py(py, NdArray::matrix(v, cols).map_err(demo_err)?)
}

/// A numpy array's shape and elements.
pub(crate) fn nd_from_py<T: Element + Copy>(a: &PyReadonlyArrayDyn<'_, T>) -> NdArray<T> {
    let a = a.as_array();
    NdArray { shape: a.shape().to_vec(), data: a.iter().copied().collect() }
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let types = [
        (py.get_type::<MimicreteError>(), &[][..]),
        (py.get_type::<IkError>(), &["reason", "iters", "pos_residual_m", "rot_residual_rad"][..]),
        (py.get_type::<SimError>(), &["reason"][..]),
        (py.get_type::<LogFormatError>(), &["file", "line", "reason"][..]),
    ];
    for (t, fields) in types {
        fields.iter().try_for_each(|f| t.setattr(*f, py.None()))?;
        m.add(t.name()?, t)?;
    }
    add_functions!(m => log_format_error);
    Ok(())
}
