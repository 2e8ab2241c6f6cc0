//! The effects a declared model may lack, one file per effect: what it adds to the torque (its
//! columns), the state it carries between samples, the candidates the diagnosis tries for it, and
//! whether a controller can compensate it. `docs/diagnosis.md` gives the table; these files are
//! the definition. Depends only on the model.
//!
//! A term is evaluated one sample at a time by [`EffectTerm::features`], so that the diagnosis
//! (in bulk) and a controller (per cycle) compute the same thing. Terms that switch with the
//! direction of motion or ripple with position change faster than the torque's low-pass filter;
//! the diagnosis filters those columns exactly like the torque ("parallel filtering", as the
//! declared Coulomb columns are).
//!
//! To add an effect: a file here implementing [`Effect`], a variant of [`EffectKind`] and its
//! line in [`EffectKind::law`], and its row in `docs/diagnosis.md` (a test checks the row).

mod armature;
mod cogging;
mod compliance;
mod configuration;
mod coulomb_asymmetry;
mod coupled_rotor;
mod delay;
mod drift;
mod drive_gain;
mod friction_velocity;
mod hysteresis;
mod offset;
mod payload;
mod position_friction;
mod stribeck;
mod viscous_nonlinear;

use serde::{Deserialize, Serialize};

pub use armature::every_joint as armature_on_every_joint;
pub use configuration::CONFIGURATION_HARMONICS;
pub use friction_velocity::FRICTION_VELOCITY_SHARES;
pub use payload::on_body as payload_on;
pub use payload::{has_inertia as payload_has_inertia, with_inertia as payload_with_inertia};
pub use stribeck::SLOWEST_STRIBECK_FRACTION;

/// The stable identifiers of the effects.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    Offset,
    CoulombAsymmetry,
    Stribeck,
    FrictionVelocity,
    ViscousNonlinear,
    Armature,
    CoupledRotor,
    DriveGain,
    ConfigurationDisturbance,
    PositionFriction,
    Hysteresis,
    Compliance,
    Drift,
    Cogging,
    Delay,
    Payload,
}

impl EffectKind {
    /// Every effect, in the order the diagnosis tries a joint's candidates: the plainer explanation
    /// first, which is also how the search chooses between terms the data cannot tell apart.
    pub const ALL: [EffectKind; 16] = [
        Self::Offset,
        Self::CoulombAsymmetry,
        Self::Stribeck,
        Self::FrictionVelocity,
        Self::ViscousNonlinear,
        Self::Armature,
        Self::CoupledRotor,
        Self::DriveGain,
        Self::ConfigurationDisturbance,
        Self::PositionFriction,
        Self::Hysteresis,
        Self::Compliance,
        Self::Drift,
        Self::Cogging,
        Self::Delay,
        Self::Payload,
    ];

    /// The file that defines this effect.
    pub fn law(self) -> &'static dyn Effect {
        match self {
            Self::Offset => &offset::Offset,
            Self::CoulombAsymmetry => &coulomb_asymmetry::CoulombAsymmetry,
            Self::Stribeck => &stribeck::Stribeck,
            Self::FrictionVelocity => &friction_velocity::FrictionVelocity,
            Self::ViscousNonlinear => &viscous_nonlinear::ViscousNonlinear,
            Self::Armature => &armature::Armature,
            Self::CoupledRotor => &coupled_rotor::CoupledRotor,
            Self::DriveGain => &drive_gain::DriveGain,
            Self::ConfigurationDisturbance => &configuration::ConfigurationDisturbance,
            Self::PositionFriction => &position_friction::PositionFriction,
            Self::Hysteresis => &hysteresis::Hysteresis,
            Self::Compliance => &compliance::Compliance,
            Self::Drift => &drift::Drift,
            Self::Cogging => &cogging::Cogging,
            Self::Delay => &delay::Delay,
            Self::Payload => &payload::Payload,
        }
    }

    /// The effects the diagnosis searches unless told otherwise: all but `drive_gain`, which
    /// against a given model a mass change on a joint held mostly by gravity mimics (both scale
    /// its torque), and which a refit largely absorbs. It is searched when the torque comes from
    /// motor currents ([`crate::diagnose::DiagnoseOptions::torque_from_currents`]).
    pub fn searched_by_default() -> Vec<EffectKind> {
        Self::ALL.into_iter().filter(|k| *k != Self::DriveGain).collect()
    }

    /// The identifier used in reports, JSON and on the command line.
    pub fn id(self) -> &'static str {
        self.law().id()
    }

    pub fn from_id(id: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.id() == id)
    }

    /// The effects named by `ids` (surrounding spaces ignored), or the first unknown name.
    pub fn parse_list(ids: &[String]) -> Result<Vec<Self>, UnknownEffect> {
        ids.iter().map(|id| Self::from_id(id.trim()).ok_or_else(|| UnknownEffect(id.clone()))).collect()
    }

    /// Whether the columns change faster than the torque filter passes, and so must be computed
    /// from the friction velocity and filtered like the torque.
    pub fn filtered_like_torque(self) -> bool {
        self.law().filtered_like_torque()
    }

    /// Whether its `scale` is a continuous constant (a velocity or a travel) that the diagnosis
    /// refines between the grid's points, rather than a count such as cogging's periods.
    pub fn scale_is_continuous(self) -> bool {
        self.law().scale_is_continuous()
    }

    /// The sign its first coefficient (a payload's mass) must have to be the physical effect
    /// (`None`: either).
    /// A fit with the other sign is some other error that happens to correlate.
    pub fn physical_sign(self) -> Option<f64> {
        self.law().physical_sign()
    }

    /// The variable a residual plot shows this effect against: `t`, `q`, `qd`, `qdd` or `tau`.
    pub fn plotted_against(self) -> &'static str {
        self.law().plotted_against()
    }

    /// Whether a controller compensates it at run time. Effects that are properties of a log,
    /// not of the robot (a delay, a drift on the log's own clock), are not.
    pub fn at_run_time(self) -> bool {
        self.law().at_run_time()
    }
}

/// An effect identifier that is not one of [`EffectKind::ALL`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown effect `{0}` (known: {known})", known = EffectKind::ALL.map(EffectKind::id).join(", "))]
pub struct UnknownEffect(pub String);

/// One sample of a joint, as an effect's columns see it.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sample {
    /// Position (rad or m).
    pub q: f64,
    /// The friction velocity (rad/s or m/s).
    pub v: f64,
    /// Acceleration (rad/s² or m/s²).
    pub qdd: f64,
    /// Time (s).
    pub t: f64,
    /// The model's torque on the joint (N·m or N): the declared model's prediction in the
    /// diagnosis, the controller's command before the term at run time.
    pub tau: f64,
}

/// What the candidate bank of one joint is built from: the training data's range of motion.
#[derive(Clone, Debug)]
pub struct JointData<'a> {
    pub joint: usize,
    /// Position range (lo, hi) over the training data (rad or m).
    pub span: (f64, f64),
    /// RMS velocity (rad/s or m/s).
    pub speed_rms: f64,
    /// Largest |velocity| and |acceleration| (rad/s, rad/s² or m/s, m/s²).
    pub peak_speed: f64,
    pub peak_acceleration: f64,
    /// The `tanh(q̇/ε)` width of the joint's friction direction (`None`: `sign(q̇)`).
    pub epsilon: Option<f64>,
    /// First and last time of the training data (s).
    pub time: (f64, f64),
    /// Joint motion per motor radian, when known.
    pub transmission: Option<f64>,
    /// Ripple periods per motor revolution to try for cogging.
    pub cogging_periods: &'a [f64],
}

impl JointData<'_> {
    /// Joint `k`'s term of `kind` with the data's shaping constants and no coefficients.
    pub fn term(&self, kind: EffectKind) -> EffectTerm {
        let mut t = EffectTerm::new(kind, Some(self.joint));
        t.epsilon = self.epsilon;
        t.span = Some(self.span);
        t.fitted_on =
            Some(FittedRange { position: self.span, speed: self.peak_speed, acceleration: self.peak_acceleration });
        t
    }

    /// The position range, never zero.
    pub fn range(&self) -> f64 {
        (self.span.1 - self.span.0).max(1e-9)
    }

    fn with_scales(&self, kind: EffectKind, scales: impl IntoIterator<Item = f64>) -> Vec<EffectTerm> {
        scales
            .into_iter()
            .map(|s| {
                let mut t = self.term(kind);
                t.scale = Some(s);
                t
            })
            .collect()
    }
}

/// Why an effect was not searched on a joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NotSearched {
    /// Cogging needs the motor transmission, which was not given.
    TransmissionUnknown,
    /// A coupled rotor needs a declared transmission in which a motor turns with more than one
    /// joint.
    NoCoupledMotor,
    /// The joint's Coulomb law was chosen from these data, the best of every friction velocity.
    LawChosenFromData,
}

impl std::fmt::Display for NotSearched {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::TransmissionUnknown => {
                f.write_str("not searched: the motor transmission is unknown (give it with --transmission)")
            }
            Self::NoCoupledMotor => f.write_str(
                "not searched: no declared motor turns with more than one joint (declare one with --coupling)",
            ),
            Self::LawChosenFromData => f.write_str(
                "not searched: the joint's Coulomb law was chosen from these data, the best fit of every friction velocity",
            ),
        }
    }
}

/// One effect's definition. Implemented once per file of this module.
pub trait Effect: Sync {
    /// The stable identifier.
    fn id(&self) -> &'static str;

    /// Number of sample-wise columns.
    fn width(&self) -> usize {
        1
    }

    /// Column names, for reports.
    fn column_names(&self) -> Vec<String>;

    /// See [`EffectKind::filtered_like_torque`].
    fn filtered_like_torque(&self) -> bool {
        false
    }

    /// Whether column `column` is filtered like the torque; by default all are or none is.
    fn column_filtered(&self, _column: usize) -> bool {
        self.filtered_like_torque()
    }

    /// See [`EffectKind::physical_sign`].
    fn physical_sign(&self) -> Option<f64> {
        None
    }

    /// The value the first coefficient must exceed, whatever its σ, to be the physical effect,
    /// and why (`None`: no such bound). A drive's gain factor `1 + g` must be positive: at or
    /// below zero the drive would cancel or reverse every torque through it, and a controller
    /// would feed back with the wrong sign.
    fn floor(&self) -> Option<(f64, &'static str)> {
        None
    }

    /// See [`EffectKind::scale_is_continuous`].
    fn scale_is_continuous(&self) -> bool {
        false
    }

    /// Whether every coefficient, not only the first, must have [`Self::physical_sign`].
    fn every_coefficient_signed(&self) -> bool {
        false
    }

    /// See [`EffectKind::plotted_against`].
    fn plotted_against(&self) -> &'static str;

    /// See [`EffectKind::at_run_time`].
    fn at_run_time(&self) -> bool {
        true
    }

    /// The term's columns at one sample of its joint, into `out` (`width()` long); `state`
    /// carries what the effect remembers from sample to sample.
    fn features(&self, term: &EffectTerm, x: Sample, state: &mut TermState, out: &mut [f64]);

    /// The constants of the term in a report, after its name and joint: `" (v_s = 0.010)"`.
    fn detail(&self, _term: &EffectTerm) -> String {
        String::new()
    }

    /// The candidates the diagnosis tries on one joint.
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched>;
}

/// One effect as it is stored in a model file: its kind, where it acts, the constants that shape
/// its columns, and the fitted coefficients.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EffectTerm {
    pub kind: EffectKind,
    /// The joint it acts on (`None`: every joint, as for a payload or a delay).
    pub joint: Option<usize>,
    /// The body a payload sits on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body: Option<String>,
    /// The effect's one shape constant; its file says what it is (a Stribeck velocity, a travel
    /// x₀, cogging periods per motor revolution, a delay in samples).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<f64>,
    /// Position range (lo, hi) that normalises configuration and position-friction terms, or
    /// the time origin and span (s) of a drift.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub span: Option<(f64, f64)>,
    /// Joint motion per motor radian, for cogging.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transmission: Option<f64>,
    /// For a motor that turns with several joints, its motion per radian (or metre) of each
    /// joint, on the scale of its own joint `joint` (whose entry is 1): the term's sample is
    /// `g·q` and its torque acts on joint j times `g[j]`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coupling: Option<Vec<f64>>,
    /// ε of the `tanh(q̇/ε)` direction in friction terms; `None` is `sign(q̇)`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub epsilon: Option<f64>,
    /// The joint's motion in the data the term was fitted on; a controller evaluates the term
    /// inside it (`None`: everywhere).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fitted_on: Option<FittedRange>,
    /// Names of the columns, in coefficient order.
    pub columns: Vec<String>,
    pub coefficients: Vec<f64>,
    /// Standard deviations of the coefficients (block sandwich).
    pub sigma: Vec<f64>,
}

/// How far below zero (in the coefficient's SI unit) a coefficient bound to be non-negative may
/// sit and still be read as zero: far below any effect's size on a robot (10⁻⁹ kg·m² of rotor
/// inertia, 10⁻⁹ N·m of Stribeck excess), far above a solver's round-off.
pub const SIGN_ROUND_OFF: f64 = 1e-9;

/// A run-time effect a model file carries that nothing may compensate or read torque through
/// ([`EffectTerm::unphysical_coefficient`]): its label, the coefficient and what is wrong with it.
#[derive(Clone, Debug, PartialEq)]
pub struct Unphysical {
    pub label: String,
    pub index: usize,
    pub value: f64,
    pub why: &'static str,
}

/// The first of `effects` acting at run time that has an unphysical coefficient: the one rule
/// the controllers and the force observer refuse a model file by.
pub fn first_unphysical(effects: &[EffectTerm], joint_names: &[String]) -> Option<Unphysical> {
    effects.iter().filter(|t| t.kind.at_run_time()).find_map(|term| {
        let (index, value, why) = term.unphysical_coefficient()?;
        Some(Unphysical { label: term.describe(joint_names), index, value, why })
    })
}

/// The motion of a joint over the data a term was fitted on. A fit says nothing about motion
/// it never saw: `q̇·|q̇|` fitted below 3 mm/s and evaluated at 9 mm/s is a guess nine times the
/// size of anything the data checked. So a controller clamps the joint's sample into this range
/// before it evaluates the term ([`EffectTerm::within_fitted`]), which bounds every term's torque
/// by what its fit covered.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FittedRange {
    /// Position (lo, hi) (rad or m).
    pub position: (f64, f64),
    /// Largest |velocity| (rad/s or m/s).
    pub speed: f64,
    /// Largest |acceleration| (rad/s² or m/s²).
    pub acceleration: f64,
}

/// The state a term needs between samples: `z`, the hysteresis term's Dahl state or the
/// compliance term's cable stretch, in [−1, 1], and the position it was last updated at.
#[derive(Clone, Copy, Debug, Default)]
pub struct TermState {
    pub z: f64,
    pub last_q: Option<f64>,
}

impl TermState {
    /// The travel from the last position to `q` (zero at the first sample), which becomes the
    /// last position.
    fn travel_to(&mut self, q: f64) -> f64 {
        let dq = self.last_q.map_or(0.0, |last| q - last);
        self.last_q = Some(q);
        dq
    }
}

impl EffectTerm {
    /// A term with no coefficients yet.
    pub fn new(kind: EffectKind, joint: Option<usize>) -> Self {
        Self {
            kind,
            joint,
            body: None,
            scale: None,
            span: None,
            transmission: None,
            coupling: None,
            epsilon: None,
            fitted_on: None,
            columns: vec![],
            coefficients: vec![],
            sigma: vec![],
        }
    }

    /// Number of columns of the sample-wise features.
    pub fn width(&self) -> usize {
        self.kind.law().width()
    }

    /// Column names, for reports.
    pub fn column_names(&self) -> Vec<String> {
        self.kind.law().column_names()
    }

    /// Rotor inertia fitted on every joint at once: one coefficient per joint, each with the
    /// physical sign, and one of which may be nil.
    pub fn is_armature_on_every_joint(&self) -> bool {
        self.kind == EffectKind::Armature && self.joint.is_none()
    }

    /// Whether every coefficient is held to the effect's sign, each judged within its σ (one
    /// may be nil, none clearly of the wrong sign): rotor inertia on every joint, a coupled
    /// rotor's inertia and frictions.
    pub fn signs_every_coefficient(&self) -> bool {
        self.is_armature_on_every_joint() || self.kind.law().every_coefficient_signed()
    }

    /// The sign coefficient `i` must have for the term to be its physical effect (`None`:
    /// either): the first coefficient ([`EffectKind::physical_sign`]), or every one where
    /// [`Self::signs_every_coefficient`].
    pub fn coefficient_sign(&self, i: usize) -> Option<f64> {
        (i == 0 || self.signs_every_coefficient()).then(|| self.kind.physical_sign()).flatten()
    }

    /// Whether column `column` is filtered like the torque ([`EffectKind::filtered_like_torque`]).
    pub fn column_filtered(&self, column: usize) -> bool {
        self.kind.law().column_filtered(column)
    }

    /// The term's sample from every joint's: its joint's, or for a coupled rotor the motor's
    /// own motion `g·x` ([`Self::coupling`]). `None` for a term on no one joint.
    pub fn sample_of(&self, q: &[f64], v: &[f64], qdd: &[f64], t: f64, tau: &[f64]) -> Option<Sample> {
        let k = self.joint?;
        Some(match &self.coupling {
            None => Sample { q: q[k], v: v[k], qdd: qdd[k], t, tau: tau[k] },
            Some(g) => {
                let dot = |x: &[f64]| g.iter().zip(x).map(|(a, b)| a * b).sum::<f64>();
                Sample { q: dot(q), v: dot(v), qdd: dot(qdd), t, tau: tau[k] }
            }
        })
    }

    /// How much of the term's torque acts on joint `j`: `g[j]` for a coupled rotor, 1 on its
    /// own joint otherwise, 0 elsewhere.
    pub fn weight_on(&self, j: usize) -> f64 {
        match (&self.coupling, self.joint) {
            (Some(g), _) => g.get(j).copied().unwrap_or(0.0),
            (None, Some(k)) => f64::from(j == k),
            (None, None) => 1.0,
        }
    }

    /// The joints the term acts on (every joint for a payload, a delay or rotor inertia on
    /// every joint).
    pub fn joints(&self, dof: usize) -> Vec<usize> {
        (0..dof).filter(|&j| self.weight_on(j) != 0.0).collect()
    }

    /// Whether `c`, as coefficient `i` of this term (from any fit), has the sign its effect cannot
    /// have ([`Self::coefficient_sign`]) by more than `slack`. The one sign rule of the diagnosis's
    /// checks, the consistent refit's constraints and the controllers' refusal.
    pub fn wrong_sign_at(&self, i: usize, c: f64, slack: f64) -> bool {
        self.coefficient_sign(i).is_some_and(|sign| c * sign < -slack)
    }

    /// The bound `c`, as coefficient `i` of this term, fails to exceed, and why, if it does
    /// (a drive gain at or below −1). No slack: the bound is what the effect is, not a fit's
    /// noise about it.
    pub fn below_floor_at(&self, i: usize, c: f64) -> Option<(f64, &'static str)> {
        self.kind.law().floor().filter(|&(floor, _)| i == 0 && c <= floor)
    }

    /// The first coefficient (index, value) a controller must not use: one that is not finite,
    /// or has the sign its effect cannot have by more than two of its σ, or by more than
    /// [`SIGN_ROUND_OFF`] where it has no σ (a consistent refit's, whose solver may leave a
    /// bound's zero at −10⁻¹⁵), or does not exceed its effect's floor ([`Self::below_floor_at`]).
    /// With the index and value, what is wrong with it, as a clause: "is not a number".
    pub fn unphysical_coefficient(&self) -> Option<(usize, f64, &'static str)> {
        self.coefficients.iter().enumerate().find_map(|(i, &c)| {
            let slack = self.sigma.get(i).filter(|s| **s > 0.0).map_or(SIGN_ROUND_OFF, |s| 2.0 * s);
            let why = match self.below_floor_at(i, c) {
                _ if !c.is_finite() => "is not a number",
                Some((_, why)) => why,
                None if self.wrong_sign_at(i, c, slack) => "has the sign this effect cannot have",
                None => return None,
            };
            Some((i, c, why))
        })
    }

    /// `x` with its position, velocity and acceleration clamped into [`Self::fitted_on`].
    pub fn within_fitted(&self, x: Sample) -> Sample {
        let Some(r) = self.fitted_on else { return x };
        let clamp = |v: f64, lo: f64, hi: f64| if lo <= hi { v.clamp(lo, hi) } else { v };
        Sample {
            q: clamp(x.q, r.position.0, r.position.1),
            v: clamp(x.v, -r.speed, r.speed),
            qdd: clamp(x.qdd, -r.acceleration, r.acceleration),
            ..x
        }
    }

    /// The direction of motion as the term's friction sees it: `tanh(v/ε)`, or `sign(v)`.
    fn direction(&self, v: f64) -> f64 {
        match self.epsilon {
            Some(eps) => (v / eps).tanh(),
            None => v.signum() * f64::from(v != 0.0),
        }
    }

    /// `q` scaled to [0, 1] over the term's span.
    fn unit(&self, q: f64) -> f64 {
        let (lo, hi) = self.span.unwrap_or((0.0, 1.0));
        (q - lo) / (hi - lo)
    }

    /// The term's columns at one sample of its joint. `state` carries the hysteresis and
    /// compliance states from sample to sample. Payload and delay have no joint-wise features and
    /// write nothing.
    pub fn features(&self, x: Sample, state: &mut TermState, out: &mut [f64]) {
        self.kind.law().features(self, x, state, out);
    }

    /// A one-line description with units, for reports.
    pub fn describe(&self, joint_names: &[String]) -> String {
        let joint = self.joint.map(|k| joint_names.get(k).cloned().unwrap_or_else(|| format!("joint {}", k + 1)));
        let on = match (joint, self.kind) {
            (Some(j), _) => format!(" on {j}"),
            (None, EffectKind::Armature) => " on every joint".into(),
            (None, _) => String::new(),
        };
        format!("{}{on}{}", self.kind.id(), self.kind.law().detail(self))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identifiers_round_trip_and_are_the_documented_ones() {
        let doc = include_str!("../../../../docs/diagnosis.md");
        for k in EffectKind::ALL {
            assert_eq!(EffectKind::from_id(k.id()), Some(k));
            assert!(doc.contains(&format!("`{}`", k.id())), "{} is not documented", k.id());
            let term = EffectTerm::new(k, Some(0));
            assert_eq!(term.column_names().len(), term.width(), "{}", k.id());
        }
    }
}
