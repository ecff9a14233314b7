//! The exception tree every binding raises from:
//! `MimicreteError(Exception)` → `IkError`, `SimError`, `LogFormatError`.
//! Misuse (bad shapes, unknown names) raises `ValueError` with the expected shape or the known names.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

create_exception!(mimicrete._native, MimicreteError, PyException, "Base class of every mimicrete error.");
create_exception!(mimicrete._native, IkError, MimicreteError, "Inverse kinematics found no solution.");
create_exception!(mimicrete._native, SimError, MimicreteError, "The simulator refused an input or state.");
create_exception!(
    mimicrete._native,
    LogFormatError,
    MimicreteError,
    "A hand log or demo file is malformed (the message names file, line and reason)."
);

pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("MimicreteError", py.get_type::<MimicreteError>())?;
    m.add("IkError", py.get_type::<IkError>())?;
    m.add("SimError", py.get_type::<SimError>())?;
    m.add("LogFormatError", py.get_type::<LogFormatError>())?;
    Ok(())
}
