//! `arash.SimulatedMotors`: the simulated rig's motor side (plant, amplifiers, encoders, current
//! sensing; `arash_core::sim::Drive`) one control cycle at a time, for a drive simulator written
//! in Python to put behind its process data. `arash mock-motor` serves the same `Drive` over
//! arash's own protocol, so a run through either link sees the same rig.

use arash_core::sim::{Drive, Scenario};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::convert::value_error;
use crate::robot::Robot;

#[pyclass(name = "SimulatedMotors", module = "arash")]
pub struct SimulatedMotors {
    drive: Drive,
    dof: usize,
}

#[pymethods]
impl SimulatedMotors {
    /// `scenario` is a scenario's TOML ("" for the nominal rig); `counts_per_rev` and
    /// `transmission` the encoders as the daemon's `[drive]` states them, which replace the
    /// scenario's as `arash mock-motor` replaces them; `seed` overrides the scenario's.
    #[new]
    #[pyo3(signature = (robot, scenario, counts_per_rev, transmission, seed=None))]
    fn new(
        robot: &Robot,
        scenario: &str,
        counts_per_rev: Vec<f64>,
        transmission: Vec<f64>,
        seed: Option<u64>,
    ) -> PyResult<Self> {
        let model = &robot.model;
        let dof = model.dof();
        let mut scenario = Scenario::from_toml(scenario).map_err(value_error)?;
        if let Some(seed) = seed {
            scenario.seed = seed;
        }
        for (name, values) in [("counts_per_rev", &counts_per_rev), ("transmission", &transmission)] {
            if values.len() != dof || values.iter().any(|v| !v.is_finite() || *v <= 0.0) {
                return Err(PyValueError::new_err(format!(
                    "{name} takes {dof} positive finite values, one per joint; got {values:?}"
                )));
            }
        }
        scenario.sensors.counts_per_rev = counts_per_rev;
        scenario.sensors.transmission = transmission;
        scenario.validate(dof).map_err(value_error)?;
        Ok(Self { drive: Drive::new(model, &scenario).map_err(value_error)?, dof })
    }

    /// One cycle of `dt` seconds with the joint torques `tau` (N·m or N) held.
    fn apply(&mut self, dt: f64, tau: Vec<f64>) -> PyResult<()> {
        if tau.len() != self.dof || tau.iter().any(|t| !t.is_finite()) || !(dt > 0.0 && dt.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "apply takes dt > 0 and {} finite torques; got dt {dt}, tau {tau:?}",
                self.dof
            )));
        }
        self.drive.apply(dt, &tau).map_err(value_error)
    }

    /// Each encoder's reading in whole counts (the encoders sit on the motors).
    fn encoder_counts(&self) -> Vec<i64> {
        (0..self.dof).map(|k| self.drive.encoder_counts(k)).collect()
    }

    /// The joint torque the current sensors measured during the last `apply` (N·m or N).
    fn measured_torque(&self) -> Vec<f64> {
        self.drive.measured_torque().to_vec()
    }

    /// The true joint positions (rad or m).
    fn q(&self) -> Vec<f64> {
        self.drive.plant().q().to_vec()
    }

    /// The header of `truth_row`'s CSV table (the columns `arash mock-motor --truth` writes).
    fn truth_header(&self) -> String {
        self.drive.truth_csv_header()
    }

    /// The last cycle's truth as a CSV row: t, q, q̇, the motors' and the hand's joint torques,
    /// and the hand's force (SI, base frame).
    fn truth_row(&self) -> String {
        let mut row = String::new();
        self.drive.truth_csv_row(&mut row);
        row
    }

    /// Simulated time (s).
    fn time(&self) -> f64 {
        self.drive.plant().time()
    }
}
