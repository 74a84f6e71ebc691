//! `armctl._armctl`, the native half of the `armctl` Python package: the project's crates bound
//! with PyO3, nothing of their own. The pure-Python half (`armctl/__init__.py`) turns numpy arrays
//! into the plain lists these functions take, and their answers (dicts and lists, converted from
//! the operations' typed reports) back.
//!
//! - [`model`]: an arm's kinematics (forward kinematics, Jacobian, IK) and trajectory sampling;
//! - [`tree_model`]: a tree's (a URDF with several leaves): every end effector at once;
//! - [`arm`]: an arm driven through the firmware core, as every drive command drives it;
//! - [`obstacles`]: obstacles as Python gives them (dicts, tuples), read as the view reads them;
//! - [`calibrate`]: LeRobot's calibration procedure, answered on standard input;
//! - [`errors`]: `ArmctlError`, carrying the command line's one-line messages, and Ctrl-C.

mod arm;
mod calibrate;
mod errors;
mod model;
mod obstacles;
mod tree_model;

use pyo3::prelude::*;

#[pymodule]
fn _armctl(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::keep_python_signal_handling();
    m.add("ArmctlError", m.py().get_type::<errors::ArmctlError>())?;
    m.add_class::<model::Model>()?;
    m.add_function(wrap_pyfunction!(model::sample, m)?)?;
    m.add_class::<tree_model::TreeModel>()?;
    m.add_function(wrap_pyfunction!(tree_model::model, m)?)?;
    m.add_class::<arm::Arm>()?;
    m.add_function(wrap_pyfunction!(calibrate::calibrate, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
