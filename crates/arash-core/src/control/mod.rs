//! Joint-space controllers of the paper's section V, the safety gate in front of the motors, the
//! velocity estimator and reference trajectories.
//!
//! Every controller is a struct built once (it owns its scratch buffers) whose [`Controller::step`]
//! computes one torque command without allocating, so that the daemon's 1 kHz cycle and the
//! simulator share the exact same code.

pub mod estimator;
pub mod feedforward;
pub mod fourier;
pub mod gains;
mod laws;
pub mod logged;
pub mod safety;
pub mod trajectory;

pub use estimator::VelocityEstimator;
pub use feedforward::EffectFeedforward;
pub use gains::{GainsError, IdcGains, PdGains, RobustGains};
pub use laws::{InverseDynamicsControl, PdGravity, RobustController};
pub use safety::{Faults, LimitsError, SafetyGate, SafetyLimits};
pub use trajectory::{PlanLimits, Trajectory, TrajectoryError};

/// Desired joint state at one instant (rad or m, and their rates).
#[derive(Clone, Copy, Debug)]
pub struct Desired<'a> {
    pub q: &'a [f64],
    pub qd: &'a [f64],
    pub qdd: &'a [f64],
}

/// Which control law produced a command; logged as a number in every cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[repr(u32)]
pub enum ControllerKind {
    /// No controller: zero torque (motors disabled).
    None = 0,
    /// PD with gravity compensation.
    Pd = 1,
    /// Inverse dynamics (computed torque) control.
    Idc = 2,
    /// The paper's robust model-based controller, eq. 22.
    Robust = 3,
    /// The haptic mode: the model's compensation and the virtual fixtures; the hand moves the
    /// arm (`haptics::HapticLaw`).
    Haptic = 4,
}

/// One control law: `step` turns the estimated state and the reference into a torque command.
pub trait Controller: Send {
    fn kind(&self) -> ControllerKind;
    /// Forget any internal state (integrators), e.g. when the motors are re-enabled.
    fn reset(&mut self);
    /// One cycle of `dt` seconds. `q`, `qd` are the estimated joint state; `tau` receives the
    /// command (N·m or N). Never allocates.
    fn step(&mut self, dt: f64, q: &[f64], qd: &[f64], desired: &Desired, tau: &mut [f64]);
}

/// Why no controller could be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ControllerError {
    #[error("controller kind `none` commands no torque; choose pd, idc or robust")]
    NoController,
    #[error("the haptic mode is entered with `arash ctl haptic`, not as a controller; choose pd, idc or robust")]
    Haptic,
    #[error(
        "the {kind:?} controller needs the robust gains K_d and Λ, and there are none for robot `{robot}` \
         ({dof} joints; the paper's are for ARASH:ASiST's three). PD with gravity compensation sizes its \
         own gains from the robot's mass matrix"
    )]
    NoGains { kind: ControllerKind, robot: String, dof: usize },
    #[error(
        "the model's effect {label} has coefficient {index} = {value:e}, which {why}: a controller that \
         compensates it would feed energy in or command a non-number. Refit it (arash diagnose --consistent \
         keeps each effect's physical sign) or remove it from the model file"
    )]
    UnphysicalEffect { label: String, index: usize, value: f64, why: &'static str },
}

/// The controllers with their standard gains for `model` with parameter vector `params`:
/// - PD with gravity compensation, critically damped at 5 Hz on `M(q_home)`;
/// - inverse dynamics control with the poles of the robust controller ([`IdcGains::matching`]);
/// - the robust controller with `robust` gains.
///
/// `q_home` is the middle of the joint ranges. The last two need `robust`
/// ([`RobustGains::from_paper`] gives none for a robot other than ARASH:ASiST).
pub fn standard_controller(
    kind: ControllerKind,
    model: &crate::Model,
    params: &[f64],
    robust: Option<&RobustGains>,
) -> Result<Box<dyn Controller>, ControllerError> {
    controller_with_effects(kind, model, params, &[], robust)
}

/// [`standard_controller`], with the model-based laws also compensating `effects` found by a
/// diagnosis ([`EffectFeedforward`]; PD with gravity compensation ignores them). An effect whose
/// coefficient is not finite or has the sign its effect cannot have is refused, by name.
pub fn controller_with_effects(
    kind: ControllerKind,
    model: &crate::Model,
    params: &[f64],
    effects: &[crate::effects::EffectTerm],
    robust: Option<&RobustGains>,
) -> Result<Box<dyn Controller>, ControllerError> {
    let q_home: Vec<f64> = model.joints.iter().map(|j| 0.5 * (j.lower + j.upper)).collect();
    let q_home: Vec<f64> = q_home.into_iter().map(|q| if q.is_finite() { q } else { 0.0 }).collect();
    let gains = || robust.ok_or_else(|| ControllerError::NoGains { kind, robot: model.name.clone(), dof: model.dof() });
    if kind != ControllerKind::Pd {
        check_effects(model, effects)?;
    }
    Ok(match kind {
        ControllerKind::None => return Err(ControllerError::NoController),
        ControllerKind::Haptic => return Err(ControllerError::Haptic),
        ControllerKind::Pd => {
            Box::new(PdGravity::new(model, params, PdGains::critically_damped(model, params, &q_home, 5.0)))
        }
        ControllerKind::Idc => Box::new(
            InverseDynamicsControl::new(model, params, IdcGains::matching(model, gains()?, params, &q_home))
                .with_effects(effects),
        ),
        ControllerKind::Robust => {
            Box::new(RobustController::new(model, params, gains()?.clone()).with_effects(effects))
        }
    })
}

/// Refuse the first effect a controller must not compensate ([`crate::effects::first_unphysical`]).
fn check_effects(model: &crate::Model, effects: &[crate::effects::EffectTerm]) -> Result<(), ControllerError> {
    match crate::effects::first_unphysical(effects, &model.joint_names()) {
        Some(crate::effects::Unphysical { label, index, value, why }) => {
            Err(ControllerError::UnphysicalEffect { label, index, value, why })
        }
        None => Ok(()),
    }
}
