//! The exception tree and the conversions Python ↔ JSON / serde / numpy.
//!
//! `MimicreteError` → `IkError`, `SimError` (→ `SimInputError`, also a `ValueError` →
//! `ActionShapeError`), `LogFormatError`, `IoError` (also an `OSError`, with `errno`, `strerror`
//! and `filename`; an errno Python maps to a subclass, `ENOENT` → `FileNotFoundError`, is raised as
//! a class that is both). Each carries the Rust error's fields as attributes; other misuse raises
//! `ValueError`.

use demo_log::NdArray;
use demo_log::serde_json::{Value, json};
use numpy::ndarray::ArrayD;
use numpy::{Element, IntoPyArray, PyArray1, PyArrayDyn, PyReadonlyArrayDyn};
use pyo3::PyTypeInfo;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyList, PyTuple, PyType};
use std::path::Path;

create_exception!(mimicrete._native, MimicreteError, PyException, "Base class of every mimicrete error.");
create_exception!(mimicrete._native, IkError, MimicreteError, "Inverse kinematics found no solution.");
create_exception!(mimicrete._native, SimError, MimicreteError, "The simulator refused an input or state.");
create_exception!(mimicrete._native, LogFormatError, MimicreteError, "A hand log or demo file is malformed.");

/// The classes with two bases (made by calling `type`, which `create_exception!` cannot).
struct Classes {
    sim_input: Py<PyType>,
    action_shape: Py<PyType>,
    io: Py<PyType>,
    /// OSError's errno subclass (`FileNotFoundError`, ...) → a subclass of it and of `IoError`.
    io_kinds: Py<PyDict>,
}

static CLASSES: PyOnceLock<Classes> = PyOnceLock::new();

/// `type(name, bases, {"__module__": "mimicrete._native", "__doc__": doc})`.
fn class<'py>(py: Python<'py>, name: &str, doc: &str, bases: &[Bound<'py, PyType>]) -> PyResult<Py<PyType>> {
    let ns = PyDict::new(py);
    ns.set_item("__module__", "mimicrete._native")?;
    ns.set_item("__doc__", doc)?;
    Ok(py.get_type::<PyType>().call1((name, PyTuple::new(py, bases)?, ns))?.cast_into::<PyType>()?.unbind())
}

fn classes(py: Python<'_>) -> PyResult<&Classes> {
    CLASSES.get_or_try_init(py, || {
        let sim_input = class(
            py,
            "SimInputError",
            "The simulator refused the caller's input (a SimError and a ValueError; `reason`: what).",
            &[py.get_type::<SimError>(), py.get_type::<PyValueError>()],
        )?;
        let action_shape = class(
            py,
            "ActionShapeError",
            "An action array of the wrong shape: `expected` and `got` are shapes (tuples of ints), \
             `task` the task whose act_dim it must match.",
            &[sim_input.bind(py).clone()],
        )?;
        let io = class(
            py,
            "IoError",
            "A file the Rust core could not read or write: an OSError with `errno`, `strerror` and \
             `filename` (an errno Python maps to an OSError subclass is raised as a class that is \
             both, so `except FileNotFoundError` catches a missing file).",
            &[py.get_type::<MimicreteError>(), py.get_type::<PyOSError>()],
        )?;
        Ok::<_, PyErr>(Classes { sim_input, action_shape, io, io_kinds: PyDict::new(py).unbind() })
    })
}

/// An exception of class `t` with message `msg` and the attributes of the JSON object `fields`.
fn raise_as(py: Python<'_>, t: &Bound<'_, PyType>, msg: String, fields: Value) -> PyErr {
    let e = PyErr::from_type(t.clone(), msg);
    let fields = fields.as_object().into_iter().flatten();
    let set = fields.into_iter().try_for_each(|(k, v)| e.value(py).setattr(k, to_py(py, v)?));
    set.err().unwrap_or(e)
}

/// An exception of type `T` with message `msg` and the attributes of the JSON object `fields`.
fn raise<T: PyTypeInfo>(msg: String, fields: Value) -> PyErr {
    Python::attach(|py| raise_as(py, &py.get_type::<T>(), msg, fields))
}

/// The first error of `r`, or `r`'s exception.
fn either(r: PyResult<PyErr>) -> PyErr {
    r.unwrap_or_else(|e| e)
}

/// `SimInputError` (or `ActionShapeError` if `shape` = `(expected, got, task)`) with `reason` = `msg`.
fn sim_input(msg: String, shape: Option<(&[usize], &[usize], &str)>) -> PyErr {
    Python::attach(|py| {
        either((|| {
            let c = classes(py)?;
            let Some((expected, got, task)) = shape else {
                return Ok(raise_as(py, c.sim_input.bind(py), msg.clone(), json!({ "reason": msg })));
            };
            let e = raise_as(py, c.action_shape.bind(py), msg.clone(), json!({"reason": msg, "task": task}));
            e.value(py).setattr("expected", PyTuple::new(py, expected)?)?;
            e.value(py).setattr("got", PyTuple::new(py, got)?)?;
            Ok(e)
        })())
    })
}

/// `NdArray::into_shape` for an action array (`what`) of `task`: another shape is an
/// `ActionShapeError` with the expected and the given shape.
pub(crate) fn action_shape<T>(a: NdArray<T>, shape: &[usize], what: &str, task: &str) -> PyResult<Vec<T>> {
    let got = a.shape.clone();
    a.into_shape(shape, what).map_err(|e| {
        let msg = match e {
            demo_log::DemoError::Invalid(m) => m,
            e => e.to_string(),
        };
        sim_input(msg, Some((shape, &got, task)))
    })
}

/// `IoError` for `path` and the OS error `e`: `errno`, `strerror` and `filename` set as
/// `OSError(errno, strerror, filename)` sets them, and of the errno's OSError subclass too.
pub(crate) fn io_err(path: &Path, e: &std::io::Error) -> PyErr {
    Python::attach(|py| {
        either((|| {
            let c = classes(py)?;
            let filename = path.display().to_string();
            let Some(errno) = e.raw_os_error() else {
                let v = c.io.bind(py).call1((format!("{filename}: {e}"),))?;
                v.setattr("strerror", e.to_string())?;
                v.setattr("filename", filename)?;
                return Ok(PyErr::from_value(v));
            };
            let strerror = py.import("os")?.call_method1("strerror", (errno,))?;
            let kind = py.get_type::<PyOSError>().call1((errno, &strerror))?.get_type();
            let kinds = c.io_kinds.bind(py);
            let t = if kind.is(py.get_type::<PyOSError>()) {
                c.io.bind(py).clone()
            } else if let Some(t) = kinds.get_item(&kind)? {
                t.cast_into::<PyType>()?
            } else {
                let doc = format!("An IoError that is also a {}.", kind.name()?);
                let t = class(py, &kind.name()?.to_string(), &doc, &[c.io.bind(py).clone(), kind.clone()])?;
                kinds.set_item(&kind, &t)?;
                t.into_bound(py)
            };
            Ok(PyErr::from_value(t.call1((errno, strerror, filename))?))
        })())
    })
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

/// tile-sim errors: stepping a finished episode → `SimError`; the caller's mistakes →
/// `SimInputError` (a `ValueError`), a wrong action length → `ActionShapeError`.
pub(crate) fn sim_err(e: tile_sim::SimError) -> PyErr {
    use tile_sim::SimError as S;
    let msg = e.to_string();
    match e {
        S::EpisodeOver => raise::<SimError>(msg.clone(), json!({ "reason": msg })),
        S::ActionShape { expected, got, task } => sim_input(msg, Some((&[expected], &[got], task))),
        _ => sim_input(msg, None),
    }
}

/// A task spec that cannot be used → `SimInputError` (a `ValueError`) with `reason` = the message
/// and, for a bad value, `field` (dotted path) and `value`; an unreadable file → `IoError`.
pub(crate) fn spec_err(e: tile_sim::SpecError) -> PyErr {
    use tile_sim::SpecError as E;
    let msg = e.to_string();
    Python::attach(|py| {
        either((|| {
            let c = classes(py)?;
            let fields = match &e {
                E::Invalid { field, value, reason } => {
                    json!({"reason": reason, "field": field, "value": value})
                }
                E::Parse { line, column, text, reason, .. } => json!({
                    "reason": reason, "field": null, "value": null,
                    "line": line, "column": column, "text": text,
                }),
                _ => json!({"reason": msg, "field": null, "value": null}),
            };
            Ok(raise_as(py, c.sim_input.bind(py), msg.clone(), fields))
        })())
    })
}

/// `LogFormatError` with `str(e)` = `file:line: reason` (`file: reason` without a line).
pub(crate) fn log_format(file: &str, line: Option<usize>, reason: &str) -> PyErr {
    let msg = line.map_or(format!("{file}: {reason}"), |l| format!("{file}:{l}: {reason}"));
    raise::<LogFormatError>(msg, json!({"file": file, "line": line, "reason": reason}))
}

pub(crate) fn handlog_err(e: demo_log::HandLogError) -> PyErr {
    log_format(&e.file, Some(e.line), &e.reason)
}

/// demo-log errors: malformed files → `LogFormatError`, I/O → `IoError` (an `OSError` with
/// `errno` and `filename`), bad values → `ValueError`.
pub(crate) fn demo_err(e: demo_log::DemoError) -> PyErr {
    use demo_log::DemoError as D;
    match e {
        D::Io { path, source } => io_err(&path, &source),
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
    let c = classes(py)?;
    let two_bases = [
        (c.sim_input.bind(py).clone(), &[][..]),
        (c.action_shape.bind(py).clone(), &["expected", "got", "task"][..]),
        (c.io.bind(py).clone(), &[][..]),
    ];
    for (t, fields) in types.into_iter().chain(two_bases) {
        fields.iter().try_for_each(|f| t.setattr(*f, py.None()))?;
        m.add(t.name()?, t)?;
    }
    add_functions!(m => log_format_error);
    Ok(())
}
