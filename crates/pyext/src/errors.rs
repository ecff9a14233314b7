//! The exception tree every binding raises from, carrying the Rust errors' fields:
//! `MimicreteError(Exception)` → `IkError` (`reason`, `iters`, `pos_residual_m`,
//! `rot_residual_rad`), `SimError` (`reason`), `LogFormatError` (`file`, `line`, `reason`).
//! Fields a failure does not have are None (also the class-level defaults, so an instance raised
//! from Python code has them too). Misuse (bad shapes, unknown names) raises `ValueError`.
//! Also the conversion between Python values and JSON values (serde_json) the crates read and
//! write.

use demo_log::serde_json::{Map, Number, Value};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use pyo3::{IntoPyObjectExt, PyTypeInfo};

create_exception!(mimicrete._native, MimicreteError, PyException, "Base class of every mimicrete error.");
create_exception!(mimicrete._native, IkError, MimicreteError, "Inverse kinematics found no solution.");
create_exception!(mimicrete._native, SimError, MimicreteError, "The simulator refused an input or state.");
create_exception!(
    mimicrete._native,
    LogFormatError,
    MimicreteError,
    "A hand log or demo file is malformed (the message names file, line and reason)."
);

type Field<'a> = (&'a str, Option<Py<PyAny>>);

/// An exception of type `T` with message `msg` and attributes `fields`.
fn raise<T: PyTypeInfo>(msg: String, fields: Vec<Field<'_>>) -> PyErr {
    let e = PyErr::new::<T, _>(msg);
    Python::attach(|py| {
        for (k, v) in fields {
            if let Err(x) = e.value(py).setattr(k, v) {
                return x;
            }
        }
        e.clone_ref(py)
    })
}

fn obj<'py, T: IntoPyObjectExt<'py>>(py: Python<'py>, v: T) -> Option<Py<PyAny>> {
    v.into_py_any(py).ok()
}

/// ur3-kin errors: `Unreachable` / `NotConverged` → `IkError` with their fields; the others
/// (bad names, non-finite or non-rigid input, degenerate hands) → `ValueError`.
pub(crate) fn kin_err(e: ur3_kin::KinError) -> PyErr {
    use ur3_kin::KinError as K;
    let msg = e.to_string();
    Python::attach(|py| match e {
        K::Unreachable { reason } => raise::<IkError>(msg, vec![("reason", obj(py, reason))]),
        K::NotConverged { iters, pos_residual_m, rot_residual_rad } => raise::<IkError>(
            msg,
            vec![
                ("reason", obj(py, "did not converge")),
                ("iters", obj(py, iters)),
                ("pos_residual_m", obj(py, pos_residual_m)),
                ("rot_residual_rad", obj(py, rot_residual_rad)),
            ],
        ),
        _ => PyValueError::new_err(msg),
    })
}

/// tile-sim errors: stepping a finished episode → `SimError`; the caller's mistakes → `ValueError`.
pub(crate) fn sim_err(e: tile_sim::SimError) -> PyErr {
    match e {
        tile_sim::SimError::EpisodeOver => {
            let msg = e.to_string();
            Python::attach(|py| raise::<SimError>(msg.clone(), vec![("reason", obj(py, msg))]))
        }
        other => PyValueError::new_err(other.to_string()),
    }
}

/// `LogFormatError` with `str(e)` = `file:line: reason` (`file: reason` without a line).
pub(crate) fn log_format(file: &str, line: Option<usize>, reason: &str) -> PyErr {
    let msg = match line {
        Some(l) => format!("{file}:{l}: {reason}"),
        None => format!("{file}: {reason}"),
    };
    Python::attach(|py| {
        raise::<LogFormatError>(
            msg,
            vec![
                ("file", obj(py, file)),
                ("line", line.and_then(|l| obj(py, l))),
                ("reason", obj(py, reason)),
            ],
        )
    })
}

pub(crate) fn handlog_err(e: demo_log::HandLogError) -> PyErr {
    log_format(&e.file, Some(e.line), &e.reason)
}

/// demo-log errors: malformed files → `LogFormatError` (file, line when known, reason);
/// unreadable/unwritable files → `OSError`; values the writer cannot record → `ValueError`.
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

/// A `LogFormatError` raised from Python code with the same fields and message rule as the native
/// ones (`file:line: reason`, or `file: reason` when `line` is None).
#[pyfunction]
#[pyo3(signature = (file, line, reason))]
fn log_format_error(file: &str, line: Option<usize>, reason: &str) -> Py<PyAny> {
    Python::attach(|py| log_format(file, line, reason).into_value(py).into_any())
}

/// A Rust value (serde) as Python data: structs and maps as dicts, sequences as lists.
pub(crate) fn to_py<'py, T: serde::Serialize + ?Sized>(
    py: Python<'py>,
    v: &T,
) -> PyResult<Bound<'py, PyAny>> {
    pythonize::pythonize(py, v).map_err(PyErr::from)
}

/// Python data as a JSON value: dicts (str keys), lists, tuples, numpy arrays and scalars
/// (`tolist()`), path-likes (as str), str, int, finite float, bool, None.
pub(crate) fn from_py(o: &Bound<'_, PyAny>) -> PyResult<Value> {
    if o.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(b) = o.cast::<pyo3::types::PyBool>() {
        return Ok(Value::Bool(b.is_true()));
    }
    if let Ok(i) = o.cast::<pyo3::types::PyInt>() {
        return Ok(match i.extract::<i64>() {
            Ok(v) => Value::from(v),
            Err(_) => Value::from(i.extract::<u64>()?),
        });
    }
    if let Ok(f) = o.cast::<pyo3::types::PyFloat>() {
        let x = f.value();
        return Number::from_f64(x)
            .map(Value::Number)
            .ok_or_else(|| PyValueError::new_err(format!("{x} is not a finite number (JSON)")));
    }
    if let Ok(s) = o.extract::<String>() {
        return Ok(Value::String(s));
    }
    if let Ok(d) = o.cast::<PyDict>() {
        let mut m = Map::new();
        for (k, v) in d.iter() {
            m.insert(k.extract::<String>()?, from_py(&v)?);
        }
        return Ok(Value::Object(m));
    }
    if o.is_instance_of::<PyList>() || o.is_instance_of::<PyTuple>() {
        return o.try_iter()?.map(|x| from_py(&x?)).collect::<PyResult<Vec<_>>>().map(Value::Array);
    }
    if o.hasattr("tolist")? {
        return from_py(&o.call_method0("tolist")?);
    }
    if o.hasattr("__fspath__")? {
        return from_py(&o.call_method0("__fspath__")?);
    }
    Err(PyValueError::new_err(format!("{} is not JSON data", o.get_type().name()?)))
}

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let none = || py.None();
    let types = [
        (py.get_type::<MimicreteError>(), &[][..]),
        (py.get_type::<IkError>(), &["reason", "iters", "pos_residual_m", "rot_residual_rad"][..]),
        (py.get_type::<SimError>(), &["reason"][..]),
        (py.get_type::<LogFormatError>(), &["file", "line", "reason"][..]),
    ];
    for (t, fields) in types {
        for f in fields {
            t.setattr(*f, none())?;
        }
        m.add(t.name()?, t)?;
    }
    m.add_function(wrap_pyfunction!(log_format_error, m)?)?;
    Ok(())
}
