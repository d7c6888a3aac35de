//! `tensorscout._native`: the Python bindings of tensorscout. The Python package (`tensorscout/`)
//! wraps these classes: `Simulation` (one run, step by step), the environment cores behind the
//! Gymnasium environments, the planning context a Python planner reads, and the benchmark.
//!
//! Every entry point runs inside [`errors::guard`], so that a Rust panic becomes a Python exception
//! and never aborts the interpreter; library errors become the exceptions of `tensorscout._errors`
//! with the command line's one-line message.

mod bench;
mod config;
mod env;
mod episode;
mod errors;
mod planner;
mod simulation;

use pyo3::prelude::*;

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", tensorscout::VERSION)?;
    m.add_class::<simulation::PySimulation>()?;
    m.add_class::<simulation::PyGridSpec>()?;
    m.add_class::<env::PyEnvCore>()?;
    m.add_class::<env::PyVecEnvCore>()?;
    m.add_class::<planner::PyPlanContext>()?;
    m.add_function(wrap_pyfunction!(bench::bench, m)?)?;
    m.add_function(wrap_pyfunction!(panic_inside_guard, m)?)?;
    Ok(())
}

/// Panics inside [`errors::guard`], as a bug in any entry point would: the tests check that it
/// arrives as `tensorscout.InternalError`, with the interpreter alive.
#[pyfunction]
#[pyo3(name = "_panic_inside_guard")]
fn panic_inside_guard(py: Python<'_>, message: String) -> PyResult<()> {
    errors::guard(py, || panic!("{message}"))
}
