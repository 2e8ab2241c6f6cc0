//! The controller a log ran, as its run specification names it (`run.json`, which `arash simulate`
//! attaches to its flight log and the daemon to each run's log): enough to build it again, for
//! closed-loop identification (`identify::closed_loop` simulates the loop with it) and for the
//! daemon, which records it.

use serde::{Deserialize, Serialize};

use super::{controller_with_effects, Controller, ControllerKind, PdGains, PdGravity, RobustGains};
use crate::effects::EffectTerm;
use crate::model::Model;

/// Why a logged controller cannot be read or built again.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the logged controller cannot be rebuilt: {0}")]
pub struct LoggedControllerError(pub String);

/// The controller a closed-loop log ran, as IDIM-IV simulates it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "law", rename_all = "kebab-case")]
pub enum LoggedController {
    /// PD with gravity compensation, `τ = g(q; π_c) − K_p (q − q_d) − K_d (q̇ − q̇_d)`, with the
    /// controller's own parameter vector `params` and these gains.
    Pd { params: Vec<f64>, kp: Vec<f64>, kd: Vec<f64> },
    /// One of arash's controllers as `arash simulate` and the daemon build it
    /// ([`crate::control::controller_with_effects`]): the law, its parameter vector, the effects it
    /// compensates and the robust gains (PD sizes its own).
    Standard {
        kind: ControllerKind,
        params: Vec<f64>,
        #[serde(default)]
        effects: Vec<EffectTerm>,
        #[serde(default)]
        gains: Option<RobustGains>,
    },
}

/// The controller part of a run specification (`run.json`, which `arash simulate` attaches to
/// its flight log and the daemon to each run's log).
#[derive(Deserialize)]
struct RunController {
    controller: ControllerKind,
    params: Vec<f64>,
    #[serde(default)]
    effects: Vec<EffectTerm>,
    #[serde(default)]
    gains: Option<RobustGains>,
}

impl LoggedController {
    /// The controller named by a run specification (`run.json`): its law, parameter vector,
    /// compensated effects and robust gains.
    pub fn from_run_json(text: &str) -> Result<Self, LoggedControllerError> {
        let run: RunController = serde_json::from_str(text)
            .map_err(|e| LoggedControllerError(format!("run.json does not name one: {e}")))?;
        Ok(Self::Standard { kind: run.controller, params: run.params, effects: run.effects, gains: run.gains })
    }

    /// Read from JSON (`{"law": "pd", "params": [...], "kp": [...], "kd": [...]}`, or
    /// `{"law": "standard", "kind": "robust", "params": [...], "gains": {...}}`).
    pub fn from_json(text: &str) -> Result<Self, LoggedControllerError> {
        serde_json::from_str(text).map_err(|e| LoggedControllerError(format!("not a controller: {e}")))
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string(self).expect("a controller serialises")
    }

    /// The controller, built for `model`; an error names what does not fit the robot.
    pub fn build(&self, model: &Model) -> Result<Box<dyn Controller>, LoggedControllerError> {
        let (n, big_p) = (model.dof(), model.num_params());
        let params = match self {
            Self::Pd { params, .. } | Self::Standard { params, .. } => params,
        };
        if params.len() != big_p {
            return Err(LoggedControllerError(format!(
                "its parameter vector has {} entries; the robot has {big_p} parameters",
                params.len()
            )));
        }
        if let Some(x) = params.iter().find(|x| !x.is_finite()) {
            return Err(LoggedControllerError(format!("its parameter vector holds {x}")));
        }
        match self {
            Self::Pd { params, kp, kd } => {
                for (name, gains) in [("kp", kp), ("kd", kd)] {
                    if gains.len() != n || gains.iter().any(|g| !(g.is_finite() && *g >= 0.0)) {
                        return Err(LoggedControllerError(format!(
                            "{name} must hold {n} non-negative numbers, one per joint, not {gains:?}"
                        )));
                    }
                }
                Ok(Box::new(PdGravity::new(model, params, PdGains { kp: kp.clone(), kd: kd.clone() })))
            }
            Self::Standard { kind, params, effects, gains } => {
                controller_with_effects(*kind, model, params, effects, gains.as_ref())
                    .map_err(|e| LoggedControllerError(e.to_string()))
            }
        }
    }
}
