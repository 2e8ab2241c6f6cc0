//! Controller gains, in SI units (N·m·s/rad, N·s/m, 1/s, …), and the conversion of the paper's
//! gains.
//!
//! The paper gives `K_d = diag(0.4, 0.4, 10)` and `Λ = diag(10, 10, 220)` without units. `Λ` is a
//! rate (1/s) in any units, because `s = ė + Λe` adds `Λe` to `ė`. `K_d` maps `s` (joint velocity
//! units) to torque, so it scales with the unit of the joint: a gain per deg/s is 180/π times the
//! same gain per rad/s, and one per mm/s is 1000 times the gain per m/s. [`PaperUnits`] names the
//! three readings and [`RobustGains::from_paper`] converts. `docs/simulator.md` shows why only
//! [`PaperUnits::Si`] gives a stable 1 kHz loop on this robot: a velocity gain sampled every `Δt`
//! on inertia `M` is stable only while `K_d·Δt/M < 2`, and the degree or millimetre readings put
//! that number between 1.6 and 100.

use serde::{Deserialize, Serialize};

use crate::model::{JointKind, Model};

/// The units in which a published gain vector is stated: the velocity unit of `s`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PaperUnits {
    /// rad/s and m/s: the gain is already SI.
    Si,
    /// deg/s for revolute joints, mm/s for prismatic joints.
    DegMm,
    /// deg/s for revolute joints, cm/s for prismatic joints (the unit of the paper's trajectories).
    DegCm,
}

impl std::str::FromStr for PaperUnits {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, String> {
        match text {
            "si" => Ok(PaperUnits::Si),
            "deg-mm" => Ok(PaperUnits::DegMm),
            "deg-cm" => Ok(PaperUnits::DegCm),
            other => Err(format!("gain units must be si, deg-mm or deg-cm, not `{other}`")),
        }
    }
}

impl PaperUnits {
    /// SI gain per published gain: (velocity unit per rad/s or m/s).
    pub fn factor(self, kind: JointKind) -> f64 {
        let revolute = !matches!(kind, JointKind::Prismatic);
        match (self, revolute) {
            (PaperUnits::Si, _) => 1.0,
            (_, true) => 180.0 / std::f64::consts::PI,
            (PaperUnits::DegMm, false) => 1000.0,
            (PaperUnits::DegCm, false) => 100.0,
        }
    }
}

/// Gains of the robust controller (eq. 22): `τ = Y_S β̂ − K_d s`, `s = ė + Λe`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RobustGains {
    /// `K_d` per joint (N·m·s/rad or N·s/m).
    pub kd: Vec<f64>,
    /// `Λ` per joint (1/s).
    pub lambda: Vec<f64>,
    /// `ε` of `tanh(q̇/ε)`, which replaces `sign(q̇)` in the friction terms (rad/s or m/s).
    pub epsilon: Vec<f64>,
}

/// The paper's published `K_d` and `Λ` for [yaw, pitch, insertion].
pub const PAPER_KD: [f64; 3] = [0.4, 0.4, 10.0];
pub const PAPER_LAMBDA: [f64; 3] = [10.0, 10.0, 220.0];

/// The paper's gains do not fit the robot.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "the paper's gains K_d = diag(0.4, 0.4, 10), Λ = diag(10, 10, 220) are for the three joints of ARASH:ASiST \
     (yaw, pitch, insertion); robot `{robot}` has {dof}"
)]
pub struct GainsError {
    pub robot: String,
    pub dof: usize,
}

impl RobustGains {
    /// The paper's gains read in `units` and converted to SI for `model`'s joints; refused for a
    /// robot with another number of joints.
    pub fn from_paper(model: &Model, units: PaperUnits) -> Result<Self, GainsError> {
        if model.dof() != PAPER_KD.len() {
            return Err(GainsError { robot: model.name.clone(), dof: model.dof() });
        }
        let kinds = joint_kinds(model);
        Ok(Self {
            kd: PAPER_KD.iter().zip(&kinds).map(|(k, kind)| k * units.factor(*kind)).collect(),
            lambda: PAPER_LAMBDA.to_vec(),
            epsilon: default_epsilon(&kinds),
        })
    }

    /// The paper's gains in the SI reading (see the module documentation).
    pub fn paper(model: &Model) -> Result<Self, GainsError> {
        Self::from_paper(model, PaperUnits::Si)
    }
}

/// Gains of PD with gravity compensation: `τ = g(q) − K_p e − K_d ė`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PdGains {
    /// N·m/rad or N/m.
    pub kp: Vec<f64>,
    /// N·m·s/rad or N·s/m.
    pub kd: Vec<f64>,
}

/// Gains of inverse dynamics control, in acceleration units: `q̈_cmd = q̈_d − K_d ė − K_p e`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IdcGains {
    /// 1/s².
    pub kp: Vec<f64>,
    /// 1/s.
    pub kd: Vec<f64>,
    /// `ε` of `tanh(q̇/ε)` in the Coulomb terms, as for [`RobustGains::epsilon`].
    pub epsilon: Vec<f64>,
}

impl IdcGains {
    /// The error dynamics of the robust controller with an exact model, `M ṡ + K_d s = 0` and
    /// `ė + Λe = s`, have poles `−Λ` and `−K_d/M`. IDC with `K_p = Λ·K_d/M`, `K_d' = Λ + K_d/M`
    /// has the same poles, so the two controllers differ only in how they use the model. `M` is
    /// the diagonal of the mass matrix at `q_home` under `params`.
    pub fn matching(model: &Model, robust: &RobustGains, params: &[f64], q_home: &[f64]) -> Self {
        let n = model.dof();
        let mut data = crate::Data::new(model);
        let mut m = vec![0.0; n * n];
        crate::dynamics::mass_matrix(model, &mut data, q_home, params, &mut m);
        let second: Vec<f64> = (0..n).map(|k| robust.kd[k] / m[k * n + k]).collect();
        Self {
            kp: (0..n).map(|k| robust.lambda[k] * second[k]).collect(),
            kd: (0..n).map(|k| robust.lambda[k] + second[k]).collect(),
            epsilon: robust.epsilon.clone(),
        }
    }
}

impl PdGains {
    /// PD gains placing a critically damped pair of poles at `bandwidth_hz` on the diagonal of
    /// `M(q_home)`.
    pub fn critically_damped(model: &Model, params: &[f64], q_home: &[f64], bandwidth_hz: f64) -> Self {
        let n = model.dof();
        let mut data = crate::Data::new(model);
        let mut m = vec![0.0; n * n];
        crate::dynamics::mass_matrix(model, &mut data, q_home, params, &mut m);
        let w = 2.0 * std::f64::consts::PI * bandwidth_hz;
        Self {
            kp: (0..n).map(|k| m[k * n + k] * w * w).collect(),
            kd: (0..n).map(|k| m[k * n + k] * 2.0 * w).collect(),
        }
    }
}

fn joint_kinds(model: &Model) -> Vec<JointKind> {
    model.joints.iter().map(|j| j.kind).collect()
}

/// `ε` of 0.01 rad/s or 1 mm/s: below a twentieth of a degree per second the friction
/// compensation fades out instead of chattering on encoder noise.
pub fn default_epsilon(kinds: &[JointKind]) -> Vec<f64> {
    kinds.iter().map(|k| if matches!(k, JointKind::Prismatic) { 1e-3 } else { 1e-2 }).collect()
}

/// The width of each joint's Coulomb compensation `tanh(q̇/ε)`: the controller's own `epsilon`,
/// or the model's friction velocity where that is wider (an identified law that rises over a
/// speed of its own, `signal/friction_law.rs`, is compensated as it was fitted).
pub fn compensation_epsilon(model: &Model, epsilon: &[f64]) -> Vec<f64> {
    epsilon.iter().enumerate().map(|(k, e)| e.max(model.coulomb_laws.shape(k).epsilon().unwrap_or(0.0))).collect()
}

/// `ε` for every joint of `model` (see [`default_epsilon`]).
pub fn model_epsilon(model: &Model) -> Vec<f64> {
    default_epsilon(&joint_kinds(model))
}
