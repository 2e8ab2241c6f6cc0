//! What a diagnosis reports: the effects accepted with their evidence, the candidates rejected
//! with a typed reason, the errors before and after, and the settings it ran with.

use serde::{Deserialize, Serialize};

use crate::choices::{Choice, Concern};
use crate::effects::{EffectKind, EffectTerm, NotSearched};
use crate::model::Model;
use crate::model_file::{Metrics, ModelFile};

/// An accepted effect and the evidence for it.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Finding {
    /// The catalogue identifier.
    pub name: String,
    /// Joints it acts on (0-based).
    pub joints: Vec<usize>,
    /// Readable: identifier, joint and variant.
    pub label: String,
    /// The term as written into the model (coefficients and their σ inside).
    pub term: EffectTerm,
    /// Hotelling-scaled batch Wald statistic, F(k, B − k).
    pub statistic: f64,
    /// B, the batches of its test, and their length (s).
    #[serde(default)]
    pub batches: usize,
    #[serde(default)]
    pub batch_s: f64,
    pub p_value: f64,
    /// The Holm threshold the p-value had to pass.
    pub threshold: f64,
    /// Relative cut of the held-out squared error, mean over `joints`.
    pub heldout_gain: f64,
    /// Per joint of the robot (0 where it does not act).
    pub heldout_gain_per_joint: Vec<f64>,
    /// Other candidates that explain the same thing on this data and cannot be told apart.
    pub aliases: Vec<String>,
    /// For a payload: the mass (kg), its σ (kg), the body, and the centre of mass in the body's
    /// frame (m), `None` along a direction the data cannot see.
    pub mass_kg: Option<f64>,
    #[serde(default)]
    pub mass_sigma_kg: Option<f64>,
    pub body: Option<String>,
    #[serde(default)]
    pub centre_of_mass_m: Option<[Option<f64>; 3]>,
    /// Per coefficient, the part of its σ the calibrated drive gains give (`diagnose::gain_share`;
    /// empty when the torque did not come from currents through them). `term.sigma` counts it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sigma_from_gains: Vec<f64>,
    /// Search round in which it was accepted (0: the delay search).
    pub round: usize,
    /// Where its scale (a Stribeck or friction velocity, a travel) was refined between the
    /// grid's points; `term.scale` is then the refined one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refined: Option<ScaleRefinement>,
}

/// A scale refined between the grid's points: the one the grid chose, the bracket its
/// neighbours on the grid set, and how much of the training residual's sum of squares (weighted)
/// the refined scale removes beyond the grid's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScaleRefinement {
    pub grid: f64,
    pub bracket: [f64; 2],
    pub residual_drop: f64,
}

impl Finding {
    /// Record the gains' part `from_gains` (per coefficient) of σ, which the test's σ already
    /// counts (`diagnose/calibration_error.rs`).
    pub(super) fn share_of_gains(&mut self, from_gains: &[f64]) {
        self.sigma_from_gains = from_gains.to_vec();
    }

    /// Read a payload's mass, its σ and its centre of mass off its term's coefficients
    /// (`m, m·cx, m·cy, m·cz`); nothing for any other effect. A first moment pinned at zero (its
    /// column is zero on this data, σ zero) leaves that coordinate unknown.
    pub(super) fn weigh(&mut self) {
        if self.term.kind != EffectKind::Payload {
            return;
        }
        let (c, sd) = (&self.term.coefficients, &self.term.sigma);
        let mass = c[0];
        self.mass_kg = Some(mass);
        self.mass_sigma_kg = sd.first().copied();
        self.body = self.term.body.clone();
        let seen = |i: usize| !(c[i] == 0.0 && sd.get(i).is_none_or(|s| *s == 0.0));
        self.centre_of_mass_m = (mass > 0.0).then(|| [1, 2, 3].map(|i| seen(i).then(|| c[i] / mass)));
    }
}

/// The data are lighter than the model: a payload with a clearly negative mass explained the
/// residual better than any effect could. A negative mass is never a payload, and every effect
/// accepted after it would only take up the missing weight (an offset along a joint that gravity
/// pulls, terms that vary with the pose), so the search stops there and says so.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TooHeavy {
    /// The body the missing mass was fitted on.
    pub body: String,
    /// The mass the data lack against the model (kg, positive), and its σ.
    pub mass_kg: f64,
    pub mass_sigma_kg: f64,
    /// The part of that σ the calibrated drive gains give, when the torque came from currents.
    #[serde(default)]
    pub mass_sigma_from_gains_kg: Option<f64>,
    pub p_value: f64,
    /// Held-out gain of the negative payload on the joint it helps most.
    pub heldout_gain: f64,
    /// The round of the search it stopped.
    pub round: usize,
}

/// A candidate that was not accepted, and why.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Rejection {
    pub name: String,
    pub joints: Vec<usize>,
    pub label: String,
    pub reason: RejectionReason,
    pub p_value: Option<f64>,
    pub heldout_gain: Option<f64>,
}

/// Why a candidate was not accepted. Figures are those of its test in the round it fell out.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "code", rename_all = "snake_case")]
pub enum RejectionReason {
    /// The effect was not searched on this joint.
    NotSearched { why: NotSearched },
    /// The current model already explains its columns (VIF above the limit).
    NotIdentifiable { vif: f64, max_vif: f64 },
    /// Its p-value is above Holm's threshold in this round.
    NotSignificant { p_value: f64, threshold: f64, round: usize },
    /// Significant, but its coefficient has the sign the physical effect cannot have.
    WrongSign { p_value: f64, coefficient: f64 },
    /// Significant, but its coefficient does not exceed the bound its effect must (`floor`, and
    /// `why`): a drive gain of −1 or less.
    BelowFloor { p_value: f64, coefficient: f64, floor: f64, why: String },
    /// Significant, but fitted with the accepted effects it gives `label` (an accepted effect or
    /// itself) the sign that effect cannot have (`coefficient`).
    FlipsSign { p_value: f64, label: String, coefficient: f64 },
    /// A payload whose mass is within `PAYLOAD_MASS_SIGMAS` σ of zero, or
    /// whose centre of mass is farther from its body's frame than the body extends
    /// ([`crate::model::Model::body_extent_m`]): not a mass on that body. `distance_m` is set for
    /// the second.
    NotAMass { p_value: f64, mass_kg: f64, mass_sigma_kg: f64, distance_m: Option<f64>, reach_m: f64 },
    /// A cable term where the joint's fitted Coulomb friction is not positive.
    NoFrictionForACable { p_value: f64, coulomb: f64 },
    /// A cable term that carries too little of the joint's Coulomb friction to be the cable.
    TooLittleFrictionForACable { p_value: f64, share: f64, coefficient: f64, coulomb: f64 },
    /// Significant, but it cuts the held-out error by less than `min_gain`.
    SmallGain { p_value: f64, gain: f64, min_gain: f64 },
    /// The accepted effect (`label`) explains it on this data.
    AliasOf { label: String },
    /// The search stopped at `max_effects` first.
    NotReached,
    /// The best shift of the torque is 0 samples.
    NoMisalignment,
    /// The best shift is within a zero-order-hold log's own misalignment; applied as alignment.
    Alignment { shift: isize },
    /// The best shift is at the edge of the search.
    AtSearchEdge { max_shift: isize },
    /// The predicted torque does not change, so a delay cannot be tested.
    Untestable,
    /// The log is too short for this candidate's test: its scores are correlated over so long
    /// that only `batches` independent batches fit, too few for `columns` coefficients.
    TooShort { batches: usize, columns: usize },
    /// The delay's p-value is above α.
    DelayNotSignificant { p_value: f64, alpha: f64 },
    /// A shift that cuts the held-out error by less than `min_gain`.
    DelaySmallGain { shift: isize, gain: f64, min_gain: f64 },
    /// Accepted in the search, but with it in the final fit `joint` predicts the held-out data
    /// worse than the model the diagnosis started from, by `sigmas` standard errors
    /// (`diagnose/guard.rs`).
    WorseThanStart { joint: String, sigmas: f64 },
}

impl RejectionReason {
    /// The reason's identifier, as in the JSON (`code`).
    pub fn code(&self) -> &'static str {
        match self {
            Self::NotSearched { .. } => "not_searched",
            Self::NotIdentifiable { .. } => "not_identifiable",
            Self::NotSignificant { .. } => "not_significant",
            Self::WrongSign { .. } => "wrong_sign",
            Self::BelowFloor { .. } => "below_floor",
            Self::FlipsSign { .. } => "flips_sign",
            Self::NotAMass { .. } => "not_a_mass",
            Self::NoFrictionForACable { .. } => "no_friction_for_a_cable",
            Self::TooLittleFrictionForACable { .. } => "too_little_friction_for_a_cable",
            Self::SmallGain { .. } => "small_gain",
            Self::AliasOf { .. } => "alias_of",
            Self::NotReached => "not_reached",
            Self::NoMisalignment => "no_misalignment",
            Self::Alignment { .. } => "alignment",
            Self::AtSearchEdge { .. } => "at_search_edge",
            Self::Untestable => "untestable",
            Self::TooShort { .. } => "too_short",
            Self::DelayNotSignificant { .. } => "delay_not_significant",
            Self::DelaySmallGain { .. } => "delay_small_gain",
            Self::WorseThanStart { .. } => "worse_than_start",
        }
    }
}

impl std::fmt::Display for RejectionReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotSearched { why } => write!(f, "{why}"),
            Self::NotIdentifiable { vif, max_vif } if vif > max_vif => {
                write!(f, "not identifiable on this data: the model already explains it (VIF {vif:.1e} > {max_vif})")
            }
            // The model leaves each column enough of its own, but together they are singular.
            Self::NotIdentifiable { vif, .. } => write!(
                f,
                "not identifiable on this data: its columns depend on one another once the model is taken out (VIF against the model {vif:.1e})"
            ),
            Self::NotSignificant { p_value, threshold, round } => {
                write!(f, "not significant: p = {p_value:.2e} above Holm's threshold {threshold:.2e} in round {round}")
            }
            Self::WrongSign { p_value, coefficient } => write!(
                f,
                "significant (p = {p_value:.2e}) but with the wrong sign for this effect (coefficient {coefficient:.3e}): some other error correlates with it"
            ),
            Self::BelowFloor { p_value, coefficient, floor, why } => write!(
                f,
                "significant (p = {p_value:.2e}) but its coefficient {coefficient:.3e} is not above {floor}: {why}; some other error correlates with it"
            ),
            Self::FlipsSign { p_value, label, coefficient } => write!(
                f,
                "significant (p = {p_value:.2e}) but fitted with the effects already found it gives {label} the wrong sign for that effect (coefficient {coefficient:.3e}): the two share some other error"
            ),
            Self::NotAMass { p_value, mass_kg, mass_sigma_kg, distance_m, reach_m } => match distance_m {
                None => write!(
                    f,
                    "significant (p = {p_value:.2e}) but its mass, {:.2} ± {:.2} g, is not told from nothing: a change of first moments, not a mass",
                    1e3 * mass_kg,
                    1e3 * mass_sigma_kg
                ),
                Some(d) => write!(
                    f,
                    "significant (p = {p_value:.2e}) but its centre of mass is {d:.3} m from the body's frame, beyond the body's extent ({reach_m:.3} m): not a mass on that body"
                ),
            },
            Self::NoFrictionForACable { p_value, coulomb } => write!(
                f,
                "significant (p = {p_value:.2e}) but the joint's fitted Coulomb friction ({coulomb:.3e}) is not positive: no friction for a cable to carry"
            ),
            Self::TooLittleFrictionForACable { p_value, share, coefficient, coulomb } => write!(
                f,
                "significant (p = {p_value:.2e}) but carries {:.0} % of the joint's Coulomb friction ({coefficient:.3e} against {coulomb:.3e}); a cable would carry most of it",
                100.0 * share
            ),
            Self::SmallGain { p_value, gain, min_gain } => write!(
                f,
                "significant (p = {p_value:.2e}) but cuts the held-out error by only {:.1} % (< {:.1} %)",
                100.0 * gain,
                100.0 * min_gain
            ),
            Self::AliasOf { label } => write!(f, "indistinguishable on this data from the accepted {label}"),
            Self::NotReached => f.write_str("not reached: the search stopped at max_effects"),
            Self::NoMisalignment => f.write_str("no misalignment: the best shift of the torque is 0 samples"),
            Self::Alignment { shift } => write!(
                f,
                "the best shift, {shift} sample(s), is within a zero-order-hold log's own misalignment; applied as alignment"
            ),
            Self::AtSearchEdge { max_shift } => {
                write!(f, "the best shift is at the edge of the search (±{max_shift} samples); widen max_delay_s")
            }
            Self::Untestable => f.write_str("the predicted torque does not change: a delay cannot be tested"),
            Self::TooShort { batches, columns } => write!(
                f,
                "cannot be tested on this log: its residual is correlated so long that only {batches} independent batches fit, too few for {columns} coefficient(s); a longer log, or a validation log, can tell"
            ),
            Self::DelayNotSignificant { p_value, alpha } => {
                write!(f, "not significant: p = {p_value:.2e} > α = {alpha}")
            }
            Self::DelaySmallGain { shift, gain, min_gain } => write!(
                f,
                "a shift of {shift} samples cuts the held-out error by only {:.1} % (< {:.1} %)",
                100.0 * gain,
                100.0 * min_gain
            ),
            Self::WorseThanStart { joint, sigmas } => write!(
                f,
                "accepted in the search, but with it {joint} predicts the held-out data worse than the model the diagnosis started from ({sigmas:.1} standard errors): dropped"
            ),
        }
    }
}

/// Fit quality per joint on the training data and on the held-out data.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ErrorSummary {
    pub training: Metrics,
    pub heldout: Metrics,
}

/// What the guard (`diagnose/guard.rs`) changed on one joint, and the joint's held-out RMS (N·m or N) around it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reverted {
    pub joint: usize,
    pub action: Reversion,
    /// The starting model's held-out RMS on the joint, and the diagnosis's before and after.
    pub start_rms: f64,
    pub rms_before: f64,
    pub rms_after: f64,
}

pub use crate::choices::Worse;

/// The model a diagnosis started from: its "before".
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StartedFrom {
    /// The declared model refitted on the log.
    #[default]
    Declared,
    /// The model the user gave.
    Given,
    /// The model identification made of the same log.
    Identified,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "code", rename_all = "snake_case")]
pub enum Reversion {
    /// The joint's refitted friction was put back at the given model's values.
    HoldFriction,
    /// The accepted effect `label` was dropped; it helped `helped` (joint indices) and harmed
    /// the joint by `sigmas` standard errors.
    DropEffect { label: String, helped: Vec<usize>, sigmas: f64 },
    /// The delay found (`samples`) was taken off the joint's torque: shifted, it predicted worse
    /// by `sigmas` standard errors; the shift helped `helped`.
    Unshifted { samples: isize, helped: Vec<usize>, sigmas: f64 },
}

/// Settings the diagnosis ran with.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DiagnoseSettings {
    pub cutoff_hz: f64,
    /// The cut-off of the velocity the Coulomb columns switch with (Hz).
    #[serde(default)]
    pub friction_cutoff_hz: Option<f64>,
    /// The Coulomb law of the declared model where every joint shares one: `tanh(q̇/ε)` with
    /// this ε, or `sign(q̇)` (`None`); `friction_velocities` gives each joint's.
    #[serde(default)]
    pub coulomb_epsilon: Option<f64>,
    /// Each joint's friction velocity in the declared model (`None`: `sign(q̇)`).
    #[serde(default)]
    pub friction_velocities: Vec<Option<f64>>,
    /// The preprocessing's choices and why (as in a model file).
    #[serde(default, with = "crate::choices::said")]
    pub reasons: Vec<Choice>,
    /// Choices the data support only weakly, or a setting the data disagree with.
    #[serde(default, with = "crate::choices::said")]
    pub warnings: Vec<Concern>,
    pub decimate: usize,
    /// The held-out split's blocks (s) and how many there were.
    pub block_s: f64,
    pub blocks: usize,
    /// The Wald test's batches as set (s); `None`: each test chose from its scores.
    #[serde(default)]
    pub batch_s: Option<f64>,
    pub alpha: f64,
    pub min_gain: f64,
    pub max_vif: f64,
    pub max_delay_s: f64,
    /// Whether the declared base parameters were refitted (no model given, or `refit`).
    pub refit: bool,
    /// The model the diagnosis started from.
    #[serde(default)]
    pub started_from: StartedFrom,
    /// What the held-out errors are measured on.
    pub heldout: String,
    pub candidates: usize,
}

/// Signals behind the residual plots: training samples as used (row-major samples × dof, SI).
#[derive(Clone, Debug, Default)]
pub struct Series {
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    pub tau: Vec<f64>,
    pub residual_before: Vec<f64>,
    pub residual_after: Vec<f64>,
    /// Each accepted effect's fitted contribution (same layout), in acceptance order.
    pub contributions: Vec<Vec<f64>>,
}

/// What [`super::diagnose`] found.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Diagnosis {
    /// `"arash-diagnosis/1"`.
    pub format: String,
    pub robot_name: String,
    pub joint_names: Vec<String>,
    /// Whether each joint is prismatic (units m, N) rather than revolute (rad, N·m).
    pub prismatic: Vec<bool>,
    pub accepted: Vec<Finding>,
    pub rejected: Vec<Rejection>,
    /// Set when the search stopped because the model is heavier than the data.
    #[serde(default)]
    pub too_heavy: Option<TooHeavy>,
    /// The model the diagnosis started from (the given or identified model as it is, or the
    /// declared model refitted), and the final one.
    pub before: ErrorSummary,
    pub after: ErrorSummary,
    /// What the guard put back so that no joint predicts the held-out data worse than `before`
    /// (`diagnose/guard.rs`), in order.
    #[serde(default)]
    pub reverted: Vec<Reverted>,
    /// Joints the final model predicts worse than `before` beyond the comparison's noise, after
    /// the guard (empty when the guard could keep every joint).
    #[serde(default)]
    pub still_worse: Vec<Worse>,
    /// The held-out error no model of the motion removes, RMS per joint (N·m or N): the torque's
    /// noise in the band, or what the band holds above the narrowest that predicts as well, if
    /// larger. Held-out gains are judged against the error above it, as far as that stands clear
    /// of it (`diagnose/noise.rs`).
    #[serde(default)]
    pub noise_floor: Vec<f64>,
    /// The torque's white noise in the band, RMS per joint (N·m or N): read from the torque above a
    /// quarter of the sample rate.
    #[serde(default)]
    pub sensor_noise: Vec<f64>,
    pub settings: DiagnoseSettings,
    /// The updated model: the declared parameters (refitted or as given) plus the effects.
    pub model: ModelFile,
    #[serde(skip)]
    pub series: Series,
}

pub(super) fn rejection(
    model: &Model,
    term: &EffectTerm,
    reason: RejectionReason,
    p_value: Option<f64>,
    gain: Option<f64>,
) -> Rejection {
    Rejection {
        name: term.kind.id().into(),
        joints: term.joints(model.dof()),
        label: term.describe(&model.joint_names()),
        reason,
        p_value,
        heldout_gain: gain,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `code()` is the JSON tag, so that Python and the JSON name a reason alike.
    #[test]
    fn a_reasons_code_is_its_json_tag() {
        let reasons = [
            RejectionReason::NotSearched { why: NotSearched::TransmissionUnknown },
            RejectionReason::NotSearched { why: NotSearched::NoCoupledMotor },
            RejectionReason::NotIdentifiable { vif: 2e3, max_vif: 1e3 },
            RejectionReason::NotIdentifiable { vif: 3e2, max_vif: 1e3 },
            RejectionReason::NotSignificant { p_value: 0.2, threshold: 0.01, round: 1 },
            RejectionReason::WrongSign { p_value: 1e-5, coefficient: -1.0 },
            RejectionReason::BelowFloor { p_value: 1e-5, coefficient: -1.04, floor: -1.0, why: "a reason".into() },
            RejectionReason::NotAMass {
                p_value: 1e-5,
                mass_kg: 1e-5,
                mass_sigma_kg: 1e-4,
                distance_m: None,
                reach_m: 1.0,
            },
            RejectionReason::NotAMass {
                p_value: 1e-5,
                mass_kg: 0.1,
                mass_sigma_kg: 1e-3,
                distance_m: Some(9.0),
                reach_m: 1.0,
            },
            RejectionReason::NoFrictionForACable { p_value: 1e-5, coulomb: -0.1 },
            RejectionReason::TooLittleFrictionForACable { p_value: 1e-5, share: 0.1, coefficient: 0.01, coulomb: 0.1 },
            RejectionReason::SmallGain { p_value: 1e-5, gain: 0.05, min_gain: 0.2 },
            RejectionReason::AliasOf { label: "offset on yaw".into() },
            RejectionReason::NotReached,
            RejectionReason::NoMisalignment,
            RejectionReason::Alignment { shift: 1 },
            RejectionReason::AtSearchEdge { max_shift: 20 },
            RejectionReason::Untestable,
            RejectionReason::TooShort { batches: 3, columns: 4 },
            RejectionReason::DelayNotSignificant { p_value: 0.5, alpha: 0.01 },
            RejectionReason::DelaySmallGain { shift: 3, gain: 0.01, min_gain: 0.2 },
            RejectionReason::WorseThanStart { joint: "yaw".into(), sigmas: 3.0 },
        ];
        for r in reasons {
            let json: serde_json::Value = serde_json::to_value(&r).unwrap();
            assert_eq!(json["code"], r.code(), "{json}");
            assert_eq!(serde_json::from_value::<RejectionReason>(json).unwrap(), r);
            assert!(!r.to_string().is_empty());
        }
    }
}
