//! The settings of a diagnosis: one home for its defaults, and their validation.

use crate::consistent::ConsistentError;
use crate::effects::EffectKind;
use crate::identify::IdentifyError;
use crate::model_file::ModelFileError;
use crate::signal::estimate::EstimateError;
use crate::signal::options::{PreprocessOptions, SettingError};
use crate::signal::preprocess::PreprocessError;
use crate::transmission::Transmission;

/// The band search reaches at least this cut-off (Hz), the diagnosis's former fixed band, so
/// that ripple, friction transitions and delays are in it to be chosen where the data carry them
/// (`diagnose/band_choice.rs`; the search otherwise stops a few times above the motion's
/// spectrum, as identification's does) ...
pub const DIAGNOSIS_CUTOFF_HZ: f64 = 20.0;

/// ... and at most this share of the sample rate, so that the residual keeps five samples per
/// cut-off period after thinning.
pub const DIAGNOSIS_CUTOFF_SHARE: f64 = 0.2;

/// The largest RMS the encoder's quantisation may give the friction velocity, as a share of the
/// joint's RMS speed: a tenth of the slowest Stribeck velocity searched. That column changes by
/// its whole size over v_s, so noise of v_s/10 moves it by about a tenth where |q̇| ≈ v_s, and
/// flips the sign of a Coulomb column only within v_s/10 of a reversal. A coarser encoder gets a
/// slower friction velocity than the band (`diagnose/band.rs`, `velocity_resolved_cutoff`).
/// Measured at the band (docs/diagnosis.md, "The friction velocity"): the simulated rig's
/// closed-loop logs 0.17 %, the independent generator's 16- to 20-bit logs 0.02–0.39 %, its
/// 12-bit ones 0.6–1.0 %.
pub const MAX_VELOCITY_NOISE: f64 = 0.1 * crate::effects::SLOWEST_STRIBECK_FRACTION;

/// A payload's mass must be this many of its σ from zero: a fit whose mass the data cannot tell
/// from nothing is a change of first moments (a centre of mass the model has wrong), and its
/// centre of mass, m·c over a mass near zero, lies anywhere. Two σ: the sign test every other
/// signed coefficient gets (`search.rs`, `wrong_sign`).
pub const PAYLOAD_MASS_SIGMAS: f64 = 2.0;

/// An accepted effect is dropped when, with it, a joint predicts the held-out data worse than the
/// model the diagnosis started from by this many standard errors of the difference (batch means
/// over the held-out blocks, `diagnose/guard.rs`): worse by the noise of the comparison alone is
/// not worse, and a payload that helps five joints should not fall to round-off on the sixth. Two,
/// as for a payload's mass. Against a given model, a refitted friction must win by as much to be
/// kept: the two have the same columns, and the given model's are the identification's.
pub const HARM_SIGMAS: f64 = 2.0;

/// The consistent refit with the effects found (`diagnose/refit.rs`) holds each coefficient's
/// magnitude to at most the diagnosis's estimate's plus this many of its σ. The refit is made at
/// a calibration's narrow cut-off, where a Stribeck excess is nearly collinear with the Coulomb
/// and viscous columns; unbounded, it traded them differently on every run of the same demo
/// rig (yaw's excess 0.010–0.029 N·m against the diagnosis's 0.0081 ± 0.0003, CI 2026-12-06)
/// and one run tracked the yaw no better than CAD. Less than the estimate stays allowed: the
/// narrow band may find that the consistent model explains part of a term. Three, the
/// diagnosis's own bound for an estimate's spread.
pub const REFIT_SIGMAS: f64 = 3.0;

/// Settings of [`super::diagnose`]; `Default` gives the documented defaults.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    /// Preprocessing, in the settings identification takes: `cutoff_hz` (`None`: the band in
    /// which the declared model predicts held-out torque best, `diagnose/band_choice.rs`; set, it
    /// must lie below half the sample rate), `friction_cutoff_hz` (`None`: the cut-off, slower
    /// where the encoder's steps would exceed `MAX_VELOCITY_NOISE` of the speed) and `order`.
    /// The diagnosis reads residuals in time, so it never averages periods, and it thins with
    /// `decimate` below.
    pub preprocess: PreprocessOptions,
    /// Keep every n-th filtered sample (`None`: about five samples per cut-off period).
    pub decimate: Option<usize>,
    /// Length of the blocks of time of the held-out split without a validation log (s); a log
    /// shorter than ten of them gets ten shorter ones.
    pub block_s: f64,
    /// Length of the batches the Wald test's covariance is summed over (s). `None`: each test
    /// chooses from its own scores by blocking ([`super::regression::Batching::FromScores`]).
    pub batch_s: Option<f64>,
    /// Family-wise error rate of each round (Holm).
    pub alpha: f64,
    /// Smallest relative cut of the held-out squared error (mean over the joints an effect acts
    /// on) worth a term.
    pub min_gain: f64,
    /// A candidate whose columns the current model explains beyond this VIF is not identifiable.
    pub max_vif: f64,
    /// Largest torque–position misalignment searched (s).
    pub max_delay_s: f64,
    /// Stop after this many accepted effects.
    pub max_effects: usize,
    /// Joint motion per motor radian, for the cogging search (`None`: taken from `motors`, and
    /// without them cogging is not searched).
    pub transmission: Option<Vec<f64>>,
    /// The declared transmission of a motor-side log (the log is already in joint space): it
    /// gives the cogging search its ratios and the `coupled_rotor` search its coupled motors.
    pub motors: Option<Transmission>,
    /// Ripple periods per motor revolution tried by the cogging search.
    pub cogging_periods: Vec<f64>,
    /// The effects searched (default: [`EffectKind::searched_by_default`]).
    pub effects: Vec<EffectKind>,
    /// The torque was computed from motor currents: search `drive_gain` too (a torque constant
    /// or current scale that is off).
    pub torque_from_currents: bool,
    /// With a given model: hold its friction too (default: refit friction, which drifts with
    /// temperature and depends on how its velocity was estimated).
    pub hold_friction: bool,
    /// With a given model: refit its base parameters together with the effects (default: keep
    /// them, so that a payload or other change against that model shows).
    pub refit: bool,
    /// Without a given model, what the diagnosis starts from (`diagnose/start.rs`).
    pub start: Start,
}

/// What a diagnosis without a given model starts from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Start {
    /// The model identification makes of the same log, with its choices: the diagnosis builds on
    /// it and ends no worse than it on any joint of any held-out run.
    #[default]
    Identified,
    /// The declared model refitted on the log at the diagnosis's band, each joint's Coulomb law
    /// chosen there.
    Declared,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            preprocess: PreprocessOptions::default(),
            decimate: None,
            block_s: 2.0,
            batch_s: None,
            alpha: 0.01,
            min_gain: 0.2,
            max_vif: 1000.0,
            max_delay_s: 0.02,
            max_effects: 6,
            transmission: None,
            motors: None,
            cogging_periods: (1..=8).map(f64::from).collect(),
            effects: EffectKind::searched_by_default(),
            torque_from_currents: false,
            hold_friction: false,
            refit: false,
            start: Start::default(),
        }
    }
}

impl DiagnoseOptions {
    /// Check every setting before any work starts; `dof` is the robot's.
    pub fn validate(&self, dof: usize) -> Result<(), OptionsError> {
        self.preprocess.validate()?;
        let positive = [("block_s", self.block_s), ("batch_s", self.batch_s.unwrap_or(1.0)), ("max_vif", self.max_vif)];
        if let Some((name, value)) = positive.into_iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
            return Err(OptionsError::NotPositive { name, value });
        }
        if !(self.max_delay_s.is_finite() && self.max_delay_s >= 0.0) {
            return Err(OptionsError::NotPositive { name: "max_delay_s", value: self.max_delay_s });
        }
        if !(self.alpha > 0.0 && self.alpha < 1.0) {
            return Err(OptionsError::OutOfRange { name: "alpha", value: self.alpha, range: "(0, 1)" });
        }
        if !(0.0..1.0).contains(&self.min_gain) {
            return Err(OptionsError::OutOfRange { name: "min_gain", value: self.min_gain, range: "[0, 1)" });
        }
        if self.decimate == Some(0) {
            return Err(OptionsError::OutOfRange { name: "decimate", value: 0.0, range: "≥ 1" });
        }
        if let Some(t) = &self.transmission {
            if t.len() != dof || t.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(OptionsError::Transmission { dof, got: t.clone() });
            }
        }
        if let Some(m) = self.motors.as_ref().filter(|m| m.dof() != dof) {
            return Err(OptionsError::Motors { dof, got: m.dof() });
        }
        if let Some(&n) = self.cogging_periods.iter().find(|n| !(n.is_finite() && **n > 0.0)) {
            return Err(OptionsError::NotPositive { name: "cogging_periods", value: n });
        }
        Ok(())
    }
}

/// A setting of [`DiagnoseOptions`] that cannot be used, named.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OptionsError {
    #[error("{name} must be positive, got {value}")]
    NotPositive { name: &'static str, value: f64 },
    #[error("{name} must lie in {range}, got {value}")]
    OutOfRange { name: &'static str, value: f64, range: &'static str },
    #[error("transmission needs {dof} positive values, one per joint; got {got:?}")]
    Transmission { dof: usize, got: Vec<f64> },
    #[error("the declared transmission is for {got} joints, the robot has {dof}")]
    Motors { dof: usize, got: usize },
    #[error(transparent)]
    Preprocess(#[from] SettingError),
}

impl DiagnoseOptions {
    /// Whether `kind` is searched.
    pub fn searches(&self, kind: EffectKind) -> bool {
        self.effects.contains(&kind) || (kind == EffectKind::DriveGain && self.torque_from_currents)
    }

    /// Joint motion per motor radian of each joint's own motor, for cogging: `transmission`, or
    /// `1 / |R[k][k]|` of the declared `motors`.
    pub fn joint_per_motor_radian(&self) -> Option<Vec<f64>> {
        self.transmission.clone().or_else(|| {
            let r = self.motors.as_ref()?.matrix();
            Some((0..r.nrows()).map(|k| 1.0 / r[(k, k)].abs()).collect())
        })
    }

    /// The cut-off a log at `fs` Hz gets when the user sets none (Hz).
    pub fn default_cutoff_hz(fs: f64) -> f64 {
        DIAGNOSIS_CUTOFF_HZ.min(DIAGNOSIS_CUTOFF_SHARE * fs)
    }

    /// The preprocessing a log gets at `cutoff_hz`: the user's other settings, no averaging,
    /// derivatives not filtered again (they pass the filter once, as the torque does), no
    /// thinning before the diagnosis's own, and every sample's rows, resting or not: the diagnosis
    /// builds and scores its own rows, and does not yet leave rests out (its law choice sees the
    /// rows it scores).
    pub fn preprocessing(&self, cutoff_hz: f64) -> PreprocessOptions {
        PreprocessOptions {
            periods: Some(1),
            period_s: None,
            cutoff_hz: Some(cutoff_hz),
            decimate: 1,
            filter_derivatives: false,
            leave_out_rests: false,
            ..self.preprocess.clone()
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    #[error("training log: {0}")]
    Training(PreprocessError),
    #[error("validation log: {0}")]
    Validation(PreprocessError),
    #[error(
        "validation log: the runs' starts must increase strictly and lie inside its {samples} samples, not {starts:?}"
    )]
    RunStarts { starts: Vec<usize>, samples: usize },
    #[error(transparent)]
    Identify(#[from] IdentifyError),
    #[error(transparent)]
    Estimate(#[from] EstimateError),
    #[error(transparent)]
    Consistent(#[from] ConsistentError),
    #[error(transparent)]
    File(#[from] ModelFileError),
    #[error(transparent)]
    Options(#[from] OptionsError),
    #[error("the given model's base parameters were chosen differently from this robot's; identify it again with this version")]
    BaseMismatch,
    #[error("cutoff_hz = {cutoff_hz} Hz is not below the log's Nyquist frequency ({nyquist_hz:.3} Hz): the band must lie in (0, fs/2)")]
    BandAboveNyquist { cutoff_hz: f64, nyquist_hz: f64 },
    #[error(
        "the log is {duration_s:.2} s long, too short to choose the diagnosis's band: the lowest band its motion and \
         its held-out blocks allow is {lowest_hz:.3} Hz, above the widest searched ({top_hz:.3} Hz); a log of at least \
         {needed_s:.1} s (or a validation log) is needed"
    )]
    TooShortForBand { duration_s: f64, needed_s: f64, top_hz: f64, lowest_hz: f64 },
    #[error(
        "the declared model cannot be fitted to this log: its columns are linearly dependent here (too little motion?)"
    )]
    Singular,
}
