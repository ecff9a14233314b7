//! `mimicrete._native`: the thin pyo3 layer over the Rust crates. No logic lives here, only
//! conversion between numpy/Python values and the crates' types, error mapping, and releasing the
//! interpreter lock around heavy work. One file per wrapped crate:
//! `kin.rs` (ur3-kin), `sim.rs` (tile-sim and the task scenes), `demo.rs` (demo-log); `errors.rs`
//! holds the exception tree (with the Rust errors' fields) and the value conversions
//! (Python ↔ JSON, numpy ↔ `demo_log::NdArray`).

use pyo3::prelude::*;

/// Add each `#[pyfunction]` to module `m`.
macro_rules! add_functions {
    ($m:expr => $($f:ident),+ $(,)?) => {
        $($m.add_function(wrap_pyfunction!($f, $m)?)?;)+
    };
}

mod demo;
mod errors;
mod kin;
mod sim;

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    kin::register(m)?;
    sim::register(m)?;
    demo::register(m)?;
    Ok(())
}
