//! `mimicrete._native`: the pyo3 layer over the crates (conversion, errors, the interpreter lock),
//! one file per crate (`kin.rs`, `sim.rs`, `demo.rs`, `teleop.rs`); `errors.rs`: exceptions and conversions.

use pyo3::prelude::*;

/// Add each `#[pyfunction]` to module `m`.
macro_rules! add_functions {
    ($m:expr => $($f:ident),+ $(,)?) => {
        $($m.add_function(wrap_pyfunction!($f, $m)?)?;)+
    };
}

/// A `PyDict` of `key => value` pairs (`set_item` converts each value); `?` on failure.
macro_rules! dict {
    ($py:expr; $($k:literal => $v:expr),+ $(,)?) => {{
        let d = pyo3::types::PyDict::new($py);
        $(d.set_item($k, $v)?;)+
        d
    }};
}

mod demo;
mod errors;
mod kin;
mod sim;
mod teleop;

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    kin::register(m)?;
    sim::register(m)?;
    demo::register(m)?;
    teleop::register(m)?;
    Ok(())
}
