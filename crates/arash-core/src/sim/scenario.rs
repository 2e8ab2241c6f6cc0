//! Scenario files (TOML): what the simulated rig is like. `docs/simulator.md` gives every
//! equation and default; `scenarios/` holds one file per effect.
//!
//! Every section and field is optional; omitted values take the documented defaults, which
//! describe ARASH:ASiST. An `[effects.NAME]` table switches that undeclared effect on, with its
//! own fields defaulting to the documented size. Unknown keys are errors, so a misspelt effect is
//! not silently ignored.

use serde::{Deserialize, Serialize};

/// Why a scenario was refused.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("cannot read scenario {path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("scenario is not valid: {0}")]
    Toml(#[from] toml::de::Error),
    #[error("scenario field `{field}` {problem}")]
    Field { field: String, problem: String },
}

fn field_error(field: &str, problem: impl Into<String>) -> ScenarioError {
    ScenarioError::Field { field: field.into(), problem: problem.into() }
}

/// The fixed-step integrator of the plant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Integrator {
    /// Velocity first, then position with the new velocity: one dynamics evaluation per step,
    /// bounded energy error (no secular drift) on conservative motion. The default: it keeps
    /// 10 kHz affordable at > 50× real time.
    SemiImplicitEuler,
    /// Classical Runge–Kutta 4: four evaluations per step, for reference runs.
    Rk4,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Physics {
    /// Integration steps per control cycle.
    pub substeps: usize,
    pub integrator: Integrator,
    /// Control and sampling rate (Hz).
    pub rate_hz: f64,
}

impl Default for Physics {
    fn default() -> Self {
        Self { substeps: 10, integrator: Integrator::SemiImplicitEuler, rate_hz: 1000.0 }
    }
}

/// How the true robot differs from its CAD model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Truth {
    /// Scale of the seeded perturbation of the inertial parameters (1 = the documented size,
    /// 0 = CAD values).
    pub perturbation: f64,
    /// Viscous friction per joint (N·m·s/rad or N·s/m).
    pub viscous: Vec<f64>,
    /// Coulomb friction per joint (N·m or N).
    pub coulomb: Vec<f64>,
    /// Cable stiffness per joint, torque `ke·q` (N·m/rad or N/m).
    pub stiffness: Vec<f64>,
    /// ε of the plant's `tanh(q̇/ε)` Coulomb law (rad/s or m/s): smooth enough for the explicit
    /// integrator, sharp against the motion.
    pub coulomb_epsilon: f64,
}

impl Default for Truth {
    fn default() -> Self {
        Self {
            perturbation: 1.0,
            viscous: vec![0.006, 0.004, 2.6],
            coulomb: vec![0.012, 0.009, 0.22],
            stiffness: vec![0.01, 0.015, 2.0],
            coulomb_epsilon: 1e-3,
        }
    }
}

/// Encoders and current sensing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Sensors {
    /// Encoder counts per motor revolution (after quadrature).
    pub counts_per_rev: Vec<f64>,
    /// Joint motion per motor radian (rad/rad, or m/rad for the insertion capstan).
    pub transmission: Vec<f64>,
    /// Standard deviation of the torque derived from motor current (N·m or N).
    pub torque_noise: Vec<f64>,
    /// Cut-off of the velocity estimator (Hz).
    pub velocity_cutoff_hz: f64,
}

impl Default for Sensors {
    fn default() -> Self {
        Self {
            counts_per_rev: crate::ARASH_ASIST_COUNTS_PER_REV.to_vec(),
            transmission: crate::ARASH_ASIST_TRANSMISSION.to_vec(),
            torque_noise: vec![0.002, 0.002, 0.03],
            velocity_cutoff_hz: 50.0,
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Actuators {
    /// Saturation per joint (N·m or N); empty = the URDF effort limits.
    pub torque_limit: Vec<f64>,
}

/// Extra static friction decaying with speed: `(f_s − f_c)·exp(−(q̇/v_s)²)·tanh(q̇/ε)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Stribeck {
    /// `f_s − f_c` per joint (N·m or N).
    pub static_excess: Vec<f64>,
    /// `v_s` per joint (rad/s or m/s).
    pub velocity_scale: Vec<f64>,
}

impl Default for Stribeck {
    fn default() -> Self {
        Self { static_excess: vec![0.01, 0.008, 0.15], velocity_scale: vec![0.05, 0.05, 0.002] }
    }
}

/// Coulomb friction stronger in one direction: `δ·|tanh(q̇/ε)|` on top of `f_c·tanh(q̇/ε)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CoulombAsymmetry {
    /// δ per joint (N·m or N): friction is `f_c + δ` moving forward, `f_c − δ` moving back.
    pub delta: Vec<f64>,
}

impl Default for CoulombAsymmetry {
    fn default() -> Self {
        Self { delta: vec![0.005, 0.004, 0.08] }
    }
}

/// A constant offset in the torque measured from motor current.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TorqueOffset {
    /// Offset per joint (N·m or N).
    pub offset: Vec<f64>,
}

impl Default for TorqueOffset {
    fn default() -> Self {
        Self { offset: vec![0.01, -0.008, 0.12] }
    }
}

/// Reflected rotor inertia added to the diagonal of `M` (the motor pays for it, the rigid-body
/// model does not know it).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Armature {
    /// Per joint (kg·m² or kg).
    pub inertia: Vec<f64>,
}

impl Default for Armature {
    fn default() -> Self {
        Self { inertia: vec![0.003, 0.003, 0.06] }
    }
}

/// A smooth position-dependent torque from cables or wiring: `A·sin(2π q/P + φ)` per joint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ConfigurationDisturbance {
    /// A per joint (N·m or N).
    pub amplitude: Vec<f64>,
    /// P per joint (rad or m).
    pub period: Vec<f64>,
    /// φ per joint (rad).
    pub phase: Vec<f64>,
}

impl Default for ConfigurationDisturbance {
    fn default() -> Self {
        Self { amplitude: vec![0.012, 0.015, 0.12], period: vec![1.2, 1.0, 0.03], phase: vec![0.4, 1.1, 0.0] }
    }
}

/// Cable compliance: the motor and the joint are two masses joined by a spring and damper; the
/// encoder sits on the motor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Compliance {
    /// k per joint (N·m/rad or N/m), in joint units.
    pub stiffness: Vec<f64>,
    /// c per joint (N·m·s/rad or N·s/m).
    pub damping: Vec<f64>,
    /// Motor-side inertia reflected to the joint (kg·m² or kg).
    pub motor_inertia: Vec<f64>,
}

impl Default for Compliance {
    fn default() -> Self {
        Self {
            stiffness: vec![300.0, 300.0, 4000.0],
            damping: vec![0.08, 0.08, 2.0],
            motor_inertia: vec![0.003, 0.003, 0.06],
        }
    }
}

/// Torque ripple periodic in motor angle: `A·sin(n·θ_motor + φ)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Cogging {
    /// A per joint (N·m or N, at the joint).
    pub amplitude: Vec<f64>,
    /// n: ripple periods per motor revolution.
    pub periods_per_rev: Vec<f64>,
    pub phase: Vec<f64>,
}

impl Default for Cogging {
    fn default() -> Self {
        Self { amplitude: vec![0.006, 0.006, 0.08], periods_per_rev: vec![6.0; 3], phase: vec![0.0, 0.5, 1.0] }
    }
}

/// The measured torque lags the position by a whole number of samples.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Delay {
    pub samples: usize,
}

impl Default for Delay {
    fn default() -> Self {
        Self { samples: 4 }
    }
}

/// Friction changing as the drive warms up: viscous, Coulomb and Stribeck friction scale by
/// `1 + a·(1 − exp(−t/T))`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FrictionDrift {
    /// a: the final relative change (−0.3 = 30 % less friction when warm).
    pub amplitude: f64,
    /// T (s).
    pub time_constant_s: f64,
}

impl Default for FrictionDrift {
    fn default() -> Self {
        Self { amplitude: -0.3, time_constant_s: 120.0 }
    }
}

/// A point mass added to a body at `at_s` seconds into the run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Payload {
    pub body: String,
    /// kg.
    pub mass: f64,
    /// Position in the body frame (m).
    pub position: [f64; 3],
    /// When the mass is attached (s).
    pub at_s: f64,
}

impl Default for Payload {
    fn default() -> Self {
        Self { body: "insertion_carriage".into(), mass: 0.05, position: [0.0, 0.0, 0.01], at_s: 0.0 }
    }
}

/// Friction growing with the square of speed: `c·q̇·|q̇|`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ViscousNonlinear {
    /// c per joint (N·m·s²/rad² or N·s²/m²).
    pub coefficient: Vec<f64>,
}

impl Default for ViscousNonlinear {
    fn default() -> Self {
        Self { coefficient: vec![0.015, 0.015, 40.0] }
    }
}

/// Coulomb friction that changes along the joint's travel: `a·x·tanh(q̇/ε)`, with x running from
/// −1 at the lower URDF limit to 1 at the upper.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PositionFriction {
    /// a per joint (N·m or N).
    pub amplitude: Vec<f64>,
}

impl Default for PositionFriction {
    fn default() -> Self {
        Self { amplitude: vec![0.008, 0.006, 0.12] }
    }
}

/// Dahl friction (pre-sliding hysteresis): `h·z`, `dz/dq = (1 − z·sign(q̇))/x₀`, so the friction
/// force builds up over a travel of a few x₀ after each reversal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Hysteresis {
    /// h per joint (N·m or N).
    pub amplitude: Vec<f64>,
    /// x₀ per joint (rad or m).
    pub travel: Vec<f64>,
}

impl Default for Hysteresis {
    fn default() -> Self {
        Self { amplitude: vec![0.008, 0.006, 0.12], travel: vec![0.01, 0.01, 0.0005] }
    }
}

/// The current sensor's offset drifting linearly: `τ_meas += r·t`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TorqueDrift {
    /// r per joint (N·m/s or N/s).
    pub rate: Vec<f64>,
}

impl Default for TorqueDrift {
    fn default() -> Self {
        Self { rate: vec![2e-4, -2e-4, 3e-3] }
    }
}

/// The undeclared effects: each is off unless its table is present.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Effects {
    pub stribeck: Option<Stribeck>,
    pub coulomb_asymmetry: Option<CoulombAsymmetry>,
    pub torque_offset: Option<TorqueOffset>,
    pub armature: Option<Armature>,
    pub configuration_disturbance: Option<ConfigurationDisturbance>,
    pub compliance: Option<Compliance>,
    pub cogging: Option<Cogging>,
    pub delay: Option<Delay>,
    pub friction_drift: Option<FrictionDrift>,
    pub payload: Option<Payload>,
    pub viscous_nonlinear: Option<ViscousNonlinear>,
    pub position_friction: Option<PositionFriction>,
    pub hysteresis: Option<Hysteresis>,
    pub torque_drift: Option<TorqueDrift>,
}

impl Effects {
    /// Names of the effects switched on, in declaration order.
    pub fn enabled(&self) -> Vec<&'static str> {
        let flags = [
            ("stribeck", self.stribeck.is_some()),
            ("coulomb_asymmetry", self.coulomb_asymmetry.is_some()),
            ("torque_offset", self.torque_offset.is_some()),
            ("armature", self.armature.is_some()),
            ("configuration_disturbance", self.configuration_disturbance.is_some()),
            ("compliance", self.compliance.is_some()),
            ("cogging", self.cogging.is_some()),
            ("delay", self.delay.is_some()),
            ("friction_drift", self.friction_drift.is_some()),
            ("payload", self.payload.is_some()),
            ("viscous_nonlinear", self.viscous_nonlinear.is_some()),
            ("position_friction", self.position_friction.is_some()),
            ("hysteresis", self.hysteresis.is_some()),
            ("torque_drift", self.torque_drift.is_some()),
        ];
        flags.iter().filter(|(_, on)| *on).map(|(name, _)| *name).collect()
    }
}

/// Band-limited random force: on each base axis a sum of sinusoids of equal amplitude at
/// frequencies spread evenly up to `band_hz`, with seeded phases, scaled to `rms`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RandomForce {
    /// RMS per base axis x, y, z (N).
    pub rms: [f64; 3],
    /// Highest frequency (Hz).
    pub band_hz: f64,
    /// When the force starts and ends (s); no end = the whole run.
    pub start_s: f64,
    pub end_s: Option<f64>,
}

impl Default for RandomForce {
    fn default() -> Self {
        Self { rms: [0.5, 0.5, 0.5], band_hz: 2.0, start_s: 0.0, end_s: None }
    }
}

/// A press like tissue contact: the force rises and falls as `F·sin²(π (t − at)/duration)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Press {
    pub at_s: f64,
    pub duration_s: f64,
    /// Peak force, base frame (N).
    pub force: [f64; 3],
}

/// A force switched on at `at_s` and held until `end_s` (or the end of the run).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Step {
    pub at_s: f64,
    #[serde(default)]
    pub end_s: Option<f64>,
    /// Base frame (N).
    pub force: [f64; 3],
}

/// A trainee's grasp of the instrument: a spring and a damper from the frame's origin to where
/// the hand means it to be, a set-point that starts at the origin when the hand takes hold and
/// then follows a path (the trainee's intended motion, free of tremor). The force it exerts
/// depends on how the device answers, which is what transparency is measured by.
///
/// The defaults are one subject's fitted arm impedance in van Beek, Bergmann Tiest, Mugge and
/// Kappers, "Haptic perception of force magnitude and its relation to postural arm dynamics in
/// 3D", Scientific Reports 5, 18004 (2015), figure 3: K = 135 N/m, B = 6.45 N·s/m. Its mass
/// (0.55 kg there) is left out: the arm carries the hand's weight, and along a path of a few
/// millimetres a second its inertial force is well under a millinewton.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Grasp {
    /// N/m and N·s/m.
    pub stiffness: f64,
    pub damping: f64,
    /// When the hand takes hold (s).
    pub at_s: f64,
    /// The path, per axis of the frame as it is when the hand takes hold (for the instrument tip:
    /// across, across, along the instrument into the eye): `a·sin(2π t/T)` from `at_s`, its
    /// amplitude `a` (m) rising over one period so that it starts at rest, with period `T` (s).
    pub amplitude_m: [f64; 3],
    pub period_s: [f64; 3],
    /// Presses along the frame's z: the set-point goes `depth_m` deeper and back as
    /// `sin²(π (t − at)/duration)`.
    pub press: Vec<PathPress>,
}

impl Default for Grasp {
    fn default() -> Self {
        Self {
            stiffness: 135.0,
            damping: 6.45,
            at_s: 0.0,
            amplitude_m: [0.0; 3],
            period_s: [4.0; 3],
            press: Vec::new(),
        }
    }
}

/// A press of the grasp's set-point along the frame's z.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathPress {
    pub at_s: f64,
    pub duration_s: f64,
    /// How much deeper the set-point goes (m).
    pub depth_m: f64,
}

/// An operator's hand: a force at a frame of the robot that the plant feels and no log records
/// (the truth records it). The parts add up.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Hand {
    /// The frame whose origin the force acts at.
    pub frame: String,
    pub random: Option<RandomForce>,
    pub press: Vec<Press>,
    pub step: Vec<Step>,
    /// A grasp that moves the instrument along a path.
    pub grasp: Option<Grasp>,
}

impl Default for Hand {
    fn default() -> Self {
        Self { frame: "instrument_tip".into(), random: None, press: Vec::new(), step: Vec::new(), grasp: None }
    }
}

/// A whole scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Scenario {
    /// Defaults to the file's stem.
    pub name: String,
    pub description: String,
    /// Seeds the truth perturbation and the sensor noise: same seed, same run.
    pub seed: u64,
    pub physics: Physics,
    pub truth: Truth,
    pub sensors: Sensors,
    pub actuators: Actuators,
    pub effects: Effects,
    /// An operator's hand at the instrument, if any.
    pub hand: Option<Hand>,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            name: String::new(),
            description: String::new(),
            seed: 1,
            physics: Physics::default(),
            truth: Truth::default(),
            sensors: Sensors::default(),
            actuators: Actuators::default(),
            effects: Effects::default(),
            hand: None,
        }
    }
}

impl Scenario {
    pub fn from_toml(text: &str) -> Result<Self, ScenarioError> {
        Ok(toml::from_str(text)?)
    }

    pub fn load(path: &std::path::Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path)
            .map_err(|source| ScenarioError::Io { path: path.display().to_string(), source })?;
        let mut scenario = Self::from_toml(&text)?;
        if scenario.name.is_empty() {
            scenario.name = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        }
        Ok(scenario)
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("scenarios serialise")
    }

    /// Check every per-joint vector has `dof` entries and every size is in range; the error
    /// names the field.
    pub fn validate(&self, dof: usize) -> Result<(), ScenarioError> {
        let p = &self.physics;
        if p.substeps == 0 {
            return Err(field_error("physics.substeps", "must be at least 1"));
        }
        positive("physics.rate_hz", p.rate_hz)?;
        let t = &self.truth;
        if !(t.perturbation.is_finite() && t.perturbation >= 0.0) {
            return Err(field_error("truth.perturbation", format!("must be ≥ 0, not {}", t.perturbation)));
        }
        positive("truth.coulomb_epsilon", t.coulomb_epsilon)?;
        joints("truth.viscous", &t.viscous, dof, Sign::NonNegative)?;
        joints("truth.coulomb", &t.coulomb, dof, Sign::NonNegative)?;
        joints("truth.stiffness", &t.stiffness, dof, Sign::Any)?;
        let s = &self.sensors;
        joints("sensors.counts_per_rev", &s.counts_per_rev, dof, Sign::Positive)?;
        joints("sensors.transmission", &s.transmission, dof, Sign::Positive)?;
        joints("sensors.torque_noise", &s.torque_noise, dof, Sign::NonNegative)?;
        positive("sensors.velocity_cutoff_hz", s.velocity_cutoff_hz)?;
        if !self.actuators.torque_limit.is_empty() {
            joints("actuators.torque_limit", &self.actuators.torque_limit, dof, Sign::Positive)?;
        }
        self.validate_effects(dof)?;
        self.validate_hand()
    }

    fn validate_hand(&self) -> Result<(), ScenarioError> {
        let Some(h) = &self.hand else { return Ok(()) };
        let finite_force = |field: &str, f: &[f64; 3]| match f.iter().all(|v| v.is_finite()) {
            true => Ok(()),
            false => Err(field_error(field, format!("must be finite, not {f:?}"))),
        };
        let window = |field: &str, start: f64, end: Option<f64>| match (start.is_finite() && start >= 0.0, end) {
            (false, _) => Err(field_error(field, format!("starts at {start} s; it must be finite and ≥ 0"))),
            (true, Some(e)) if !(e.is_finite() && e > start) => {
                Err(field_error(field, format!("ends at {e} s; it must end after it starts ({start} s)")))
            }
            _ => Ok(()),
        };
        if let Some(r) = &h.random {
            finite_force("hand.random.rms", &r.rms)?;
            if r.rms.iter().any(|v| *v < 0.0) {
                return Err(field_error("hand.random.rms", format!("must be ≥ 0, not {:?}", r.rms)));
            }
            positive("hand.random.band_hz", r.band_hz)?;
            window("hand.random", r.start_s, r.end_s)?;
        }
        for (i, p) in h.press.iter().enumerate() {
            finite_force(&format!("hand.press[{i}].force"), &p.force)?;
            window(&format!("hand.press[{i}]"), p.at_s, None)?;
            positive(&format!("hand.press[{i}].duration_s"), p.duration_s)?;
        }
        for (i, s) in h.step.iter().enumerate() {
            finite_force(&format!("hand.step[{i}].force"), &s.force)?;
            window(&format!("hand.step[{i}]"), s.at_s, s.end_s)?;
        }
        if let Some(g) = &h.grasp {
            for (field, value) in [("hand.grasp.stiffness", g.stiffness), ("hand.grasp.damping", g.damping)] {
                if !(value.is_finite() && value >= 0.0) {
                    return Err(field_error(field, format!("must be finite and ≥ 0, not {value}")));
                }
            }
            window("hand.grasp", g.at_s, None)?;
            finite_force("hand.grasp.amplitude_m", &g.amplitude_m)?;
            for (axis, period) in g.period_s.iter().enumerate() {
                positive(&format!("hand.grasp.period_s[{axis}]"), *period)?;
            }
            for (i, p) in g.press.iter().enumerate() {
                window(&format!("hand.grasp.press[{i}]"), p.at_s, None)?;
                positive(&format!("hand.grasp.press[{i}].duration_s"), p.duration_s)?;
                if !p.depth_m.is_finite() {
                    return Err(field_error(&format!("hand.grasp.press[{i}].depth_m"), "must be finite"));
                }
            }
        }
        Ok(())
    }

    fn validate_effects(&self, dof: usize) -> Result<(), ScenarioError> {
        let e = &self.effects;
        if let Some(x) = &e.stribeck {
            joints("effects.stribeck.static_excess", &x.static_excess, dof, Sign::Any)?;
            joints("effects.stribeck.velocity_scale", &x.velocity_scale, dof, Sign::Positive)?;
        }
        if let Some(x) = &e.coulomb_asymmetry {
            joints("effects.coulomb_asymmetry.delta", &x.delta, dof, Sign::Any)?;
        }
        if let Some(x) = &e.torque_offset {
            joints("effects.torque_offset.offset", &x.offset, dof, Sign::Any)?;
        }
        if let Some(x) = &e.armature {
            joints("effects.armature.inertia", &x.inertia, dof, Sign::NonNegative)?;
            if e.compliance.is_some() {
                return Err(field_error(
                    "effects.armature",
                    "cannot be combined with effects.compliance, which carries its own motor_inertia",
                ));
            }
        }
        if let Some(x) = &e.configuration_disturbance {
            joints("effects.configuration_disturbance.amplitude", &x.amplitude, dof, Sign::Any)?;
            joints("effects.configuration_disturbance.period", &x.period, dof, Sign::Positive)?;
            joints("effects.configuration_disturbance.phase", &x.phase, dof, Sign::Any)?;
        }
        if let Some(x) = &e.compliance {
            joints("effects.compliance.stiffness", &x.stiffness, dof, Sign::Positive)?;
            joints("effects.compliance.damping", &x.damping, dof, Sign::NonNegative)?;
            joints("effects.compliance.motor_inertia", &x.motor_inertia, dof, Sign::Positive)?;
        }
        if let Some(x) = &e.cogging {
            joints("effects.cogging.amplitude", &x.amplitude, dof, Sign::Any)?;
            joints("effects.cogging.periods_per_rev", &x.periods_per_rev, dof, Sign::Positive)?;
            joints("effects.cogging.phase", &x.phase, dof, Sign::Any)?;
        }
        if let Some(x) = &e.friction_drift {
            if !(x.amplitude.is_finite() && x.amplitude > -1.0) {
                return Err(field_error("effects.friction_drift.amplitude", "must be finite and > −1"));
            }
            positive("effects.friction_drift.time_constant_s", x.time_constant_s)?;
        }
        if let Some(x) = &e.viscous_nonlinear {
            joints("effects.viscous_nonlinear.coefficient", &x.coefficient, dof, Sign::Any)?;
        }
        if let Some(x) = &e.position_friction {
            joints("effects.position_friction.amplitude", &x.amplitude, dof, Sign::Any)?;
        }
        if let Some(x) = &e.hysteresis {
            joints("effects.hysteresis.amplitude", &x.amplitude, dof, Sign::Any)?;
            joints("effects.hysteresis.travel", &x.travel, dof, Sign::Positive)?;
        }
        if let Some(x) = &e.torque_drift {
            joints("effects.torque_drift.rate", &x.rate, dof, Sign::Any)?;
        }
        if let Some(x) = &e.payload {
            positive("effects.payload.mass", x.mass)?;
            if x.position.iter().any(|v| !v.is_finite()) || !x.at_s.is_finite() || x.at_s < 0.0 {
                return Err(field_error("effects.payload", "position and at_s must be finite, at_s ≥ 0"));
            }
        }
        Ok(())
    }
}

#[derive(Clone, Copy)]
enum Sign {
    Any,
    NonNegative,
    Positive,
}

fn positive(field: &str, v: f64) -> Result<(), ScenarioError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(field_error(field, format!("must be positive and finite, not {v}")))
    }
}

fn joints(field: &str, v: &[f64], dof: usize, sign: Sign) -> Result<(), ScenarioError> {
    if v.len() != dof {
        return Err(field_error(field, format!("has {} entries; the robot has {dof} joints", v.len())));
    }
    for (k, &x) in v.iter().enumerate() {
        let ok = x.is_finite()
            && match sign {
                Sign::Any => true,
                Sign::NonNegative => x >= 0.0,
                Sign::Positive => x > 0.0,
            };
        if !ok {
            let need = match sign {
                Sign::Any => "finite",
                Sign::NonNegative => "finite and ≥ 0",
                Sign::Positive => "finite and > 0",
            };
            return Err(field_error(&format!("{field}[{k}]"), format!("must be {need}, not {x}")));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_file_is_the_nominal_scenario() {
        let s = Scenario::from_toml("").unwrap();
        assert_eq!(s, Scenario::default());
        assert!(s.effects.enabled().is_empty());
        s.validate(3).unwrap();
    }

    #[test]
    fn an_effect_table_switches_the_effect_on_with_defaults() {
        let s = Scenario::from_toml("[effects.stribeck]\n[effects.delay]\nsamples = 7\n").unwrap();
        assert_eq!(s.effects.enabled(), ["stribeck", "delay"]);
        assert_eq!(s.effects.stribeck, Some(Stribeck::default()));
        assert_eq!(s.effects.delay.as_ref().unwrap().samples, 7);
    }

    #[test]
    fn errors_name_the_bad_field() {
        let e = Scenario::from_toml("[effects.stribek]\n").unwrap_err().to_string();
        assert!(e.contains("stribek"), "{e}");
        let s = Scenario::from_toml("[sensors]\ntorque_noise = [0.1, 0.1]\n").unwrap();
        let e = s.validate(3).unwrap_err().to_string();
        assert!(e.contains("sensors.torque_noise") && e.contains("2 entries"), "{e}");
        let s = Scenario::from_toml("[effects.compliance]\nstiffness = [1.0, -1.0, 1.0]\n").unwrap();
        let e = s.validate(3).unwrap_err().to_string();
        assert!(e.contains("effects.compliance.stiffness[1]"), "{e}");
        let s = Scenario::from_toml("[effects.compliance]\n[effects.armature]\n").unwrap();
        assert!(s.validate(3).unwrap_err().to_string().contains("effects.armature"));
    }

    #[test]
    fn round_trips_through_toml() {
        let mut s = Scenario::default();
        s.effects.payload = Some(Payload::default());
        s.effects.cogging = Some(Cogging::default());
        assert_eq!(Scenario::from_toml(&s.to_toml()).unwrap(), s);
    }
}
