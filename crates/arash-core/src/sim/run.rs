//! A whole simulated run: scenario, trajectory, controller and its parameters, duration. Shared
//! by `arash simulate` and `arash.simulate` so both build the same rig and log the same header.

use serde::Serialize;

use super::plant::PlantError;
use super::rig::Rig;
use super::scenario::Scenario;
use super::truth::true_parameters;
use crate::control::{controller_with_effects, ControllerKind, PlanLimits, RobustGains, Trajectory};
use crate::model::Model;

/// A controller as `arash simulate` and `arash.simulate` name it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControllerChoice {
    /// PD with gravity compensation.
    Pd,
    /// Inverse dynamics control with the CAD parameters: the paper's baseline.
    IdcCad,
    /// Inverse dynamics control with parameters the caller names.
    Idc,
    /// The robust controller (eq. 22).
    Robust,
}

impl std::str::FromStr for ControllerChoice {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        match text {
            "pd" => Ok(Self::Pd),
            "idc-cad" => Ok(Self::IdcCad),
            "idc" => Ok(Self::Idc),
            "robust" => Ok(Self::Robust),
            other => Err(format!("controller must be pd, idc-cad, idc or robust, not `{other}`")),
        }
    }
}

impl ControllerChoice {
    pub fn kind(self) -> ControllerKind {
        match self {
            Self::Pd => ControllerKind::Pd,
            Self::IdcCad | Self::Idc => ControllerKind::Idc,
            Self::Robust => ControllerKind::Robust,
        }
    }

    /// The parameter source used when the caller names none: `cad` for PD and the baseline,
    /// `truth` for the robust controller; plain `idc` needs one named.
    pub fn default_params(self) -> Option<&'static str> {
        match self {
            Self::Pd | Self::IdcCad => Some("cad"),
            Self::Robust => Some("truth"),
            Self::Idc => None,
        }
    }

    /// Refuse a parameter source this choice cannot run with: `idc-cad` runs on CAD only.
    pub fn check_params(self, source: &str) -> Result<(), String> {
        if self == Self::IdcCad && source != "cad" {
            return Err(format!("idc-cad runs with the CAD parameters, not {source}; use idc for others"));
        }
        Ok(())
    }
}

/// The parameter vectors the simulator itself can name: `cad` and `truth` (the simulated robot's
/// own, for `scenario`). `None` for any other name.
pub fn named_parameters(model: &Model, scenario: &Scenario, name: &str) -> Option<Vec<f64>> {
    match name {
        "cad" => Some(model.cad_parameters()),
        "truth" => Some(true_parameters(model, scenario)),
        _ => None,
    }
}

/// Everything that defines a simulated run.
#[derive(Clone, Debug, Serialize)]
pub struct RunSpec {
    pub scenario: Scenario,
    pub trajectory: Trajectory,
    pub controller: ControllerKind,
    /// Where the controller's parameters came from: `cad`, `truth` or a model file.
    pub params_source: String,
    /// The controller's parameter vector (P entries).
    pub params: Vec<f64>,
    /// Effects a diagnosis added to the controller's model, compensated by the model-based laws.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<crate::effects::EffectTerm>,
    /// The robust gains (also behind inverse dynamics control's); `None` for a robot the paper's
    /// gains do not fit, which only PD can then run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gains: Option<RobustGains>,
    /// Seconds of rig time.
    pub duration_s: f64,
}

impl RunSpec {
    /// Number of control cycles in the run.
    pub fn cycles(&self) -> usize {
        (self.duration_s * self.scenario.physics.rate_hz).round() as usize
    }

    /// The rig for this run, on its trajectory at `t = 0`.
    pub fn rig(&self, model: &Model) -> Result<Rig, PlantError> {
        if self.params.len() != model.num_params() {
            return Err(PlantError::Parameters(format!(
                "the controller's parameter vector has {} entries, the robot needs {}",
                self.params.len(),
                model.num_params()
            )));
        }
        if !(self.duration_s.is_finite() && self.duration_s > 0.0) {
            return Err(PlantError::Parameters(format!("the duration must be positive, not {} s", self.duration_s)));
        }
        let dt = 1.0 / self.scenario.physics.rate_hz;
        self.trajectory.check_limits(&PlanLimits::from_model(model), self.duration_s, dt)?;
        let controller =
            controller_with_effects(self.controller, model, &self.params, &self.effects, self.gains.as_ref())
                .map_err(|e| PlantError::Parameters(e.to_string()))?;
        Rig::new(model, &self.scenario, self.trajectory.clone(), controller)
    }

    /// The run's configuration as JSON, for the log's `run.json` attachment.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("run specs serialise")
    }

    /// The flight-log header for this run of `model` described by `urdf`; `with_truth` adds the
    /// `/arash/truth` channel (about 40 % more bytes and writing time).
    #[cfg(feature = "flightlog")]
    pub fn log_header(&self, model: &Model, urdf: &str, with_truth: bool) -> crate::flightlog::LogHeader {
        let mut metadata = std::collections::BTreeMap::new();
        metadata.insert("source".into(), "simulator".into());
        metadata.insert("robot".into(), model.name.clone());
        metadata.insert("scenario".into(), self.scenario.name.clone());
        metadata.insert("effects".into(), self.scenario.effects.enabled().join(","));
        metadata.insert("seed".into(), self.scenario.seed.to_string());
        metadata.insert("controller".into(), serde_json::to_value(self.controller).unwrap().as_str().unwrap().into());
        metadata.insert("params".into(), self.params_source.clone());
        metadata.insert("rate_hz".into(), self.scenario.physics.rate_hz.to_string());
        crate::flightlog::LogHeader {
            urdf: urdf.into(),
            joint_names: model.joint_names(),
            metadata,
            attachments: vec![
                ("scenario.toml".into(), "application/toml".into(), self.scenario.to_toml().into_bytes()),
                ("run.json".into(), "application/json".into(), self.to_json().into_bytes()),
            ],
            with_truth,
            start_unix_ns: 0,
        }
    }
}
