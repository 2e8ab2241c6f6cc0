//! What the pipeline chose from a log, and what it is unsure of, as data.
//!
//! Identification and the diagnosis make their choices from the data (the period, the cut-off,
//! the friction velocity, each joint's Coulomb law, the drive gains, a log's repair) and say why.
//! Each reason is a [`Choice`] and each doubt a [`Concern`]: an enum that carries the figures the
//! choice was made from, with a `Display` that gives the sentence a user reads. A program asks the
//! variant ("was the cut-off set or chosen?"); a person reads the text. Clarabel's `SolverStatus`
//! and the diagnosis's [`RejectionReason`](crate::diagnose) are the pattern.
//!
//! In a model file each is stored as its fields, tagged by `code`, with its `text` beside them
//! ([`said`]). A line from a file written before reasons were data reads as `Recorded`.

use serde::{Deserialize, Serialize};
use std::fmt::{self, Display, Formatter};

use crate::model::{CoulombLaws, CoulombShape};

/// A choice made while preparing or fitting a log, with the figures it was made from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "code", rename_all = "snake_case")]
pub enum Choice {
    /// The user gave the period; `count` whole periods of it fit the log.
    PeriodGiven { count: usize, period_s: f64 },
    /// The user gave the number of periods.
    PeriodsGiven { count: usize, period_s: f64 },
    /// `periods = 1` was given: no averaging.
    NotAveraged,
    /// Not periodic: no joint moves.
    NoJointMoves,
    /// Not periodic: the motion never moves away from itself within half the log.
    NeverMovesAway { half_log_s: f64 },
    /// Not periodic: the closest repeat differs by more than the limit.
    DoesNotRepeat { after_s: f64, mismatch: f64, limit: f64 },
    /// Periodic: `count` periods found.
    PeriodsFound { count: usize, period_s: f64, mismatch: f64 },
    /// The user gave the cut-off.
    CutoffGiven { cutoff_hz: f64 },
    /// No motion stands above the noise: the lowest cut-off.
    CutoffNoMotion { cutoff_hz: f64 },
    /// The cut-off from the motion's spectrum: `factor` × the bandwidth `signal_hz` (the highest
    /// harmonic that repeats where `periodic`, else where the motion stands above the position
    /// noise), or the lowest the log allows (`lowest_hz`) where that is higher.
    CutoffFromSpectrum { cutoff_hz: f64, signal_hz: f64, factor: f64, periodic: bool, lowest_hz: Option<f64> },
    /// The cut-off whose fitted model predicts held-out torque as well as the best and fits its
    /// own filtered torque best. `trials` are `[cut-off Hz, mean FP% predicted]`; `spectral` is
    /// what the spectrum suggested.
    CutoffSearched {
        cutoff_hz: f64,
        trials: Vec<[f64; 2]>,
        periodic: bool,
        most_accurate_hz: f64,
        training_fp: f64,
        predicted_fp: f64,
        most_accurate_fp: f64,
        sigmas: f64,
        points: f64,
        spectral: Option<Box<Choice>>,
    },
    /// The diagnosis's band: the widest cut-off that predicts held-out torque as well as the best.
    /// `trials` are `[cut-off Hz, mean FP%]`; `equal_hz` those as good as the best.
    BandSearched {
        cutoff_hz: f64,
        trials: Vec<[f64; 2]>,
        validation_runs: bool,
        most_accurate_hz: f64,
        most_accurate_fp: f64,
        sigmas: f64,
        equal_hz: Vec<f64>,
    },
    /// The time stamps jitter: the samples are taken as a uniform stream at the mean rate.
    Jitter { share: f64, rate_hz: f64 },
    /// Not periodic: each end left out of the fit, where the zero-phase filter starts up.
    EdgesLeftOut { edge_s: f64, cutoff_periods: f64 },
    /// The velocity that switches Coulomb friction: the user's (`given`), else the main cut-off.
    FrictionCutoff { cutoff_hz: f64, given: bool, at_most_quarter: bool },
    /// The friction velocity whose fit is best at the chosen cut-off; `trials` are `[Hz, mean FP%]`.
    FrictionCutoffSearched { cutoff_hz: f64, band_hz: f64, trials: Vec<[f64; 2]> },
    /// The diagnosis's friction velocity: the band's, where no joint's positions sit on an
    /// encoder's grid.
    FrictionAtBandNoGrid { cutoff_hz: f64 },
    /// The diagnosis's friction velocity at the band, where the quantisation's share of joint
    /// `joint`'s RMS speed is `share` (at most `limit`).
    FrictionAtBand { cutoff_hz: f64, joint: usize, share: f64, limit: f64 },
    /// Narrower than the band, so that quantisation makes up at most `limit` of the speed.
    FrictionNarrowed {
        cutoff_hz: f64,
        band_hz: f64,
        band_joint: usize,
        band_share: f64,
        joint: usize,
        share: f64,
        limit: f64,
    },
    /// The lowest the motion allows, quantisation still over the limit.
    FrictionLowest { cutoff_hz: f64, joint: usize, share: f64, limit: f64 },
    /// Resting samples left out of the fit: each joint's share.
    Resting { shares: Vec<f64>, hold_samples: usize, hold_s: f64 },
    /// The Coulomb laws kept as they were: the log holds too few stretches to choose one.
    /// `velocities` are each joint's friction velocity (`None`: sign(q̇)).
    LawsKept {
        velocities: Vec<Option<f64>>,
        samples: usize,
        folds: usize,
        guards_per_fold: usize,
        guard: usize,
        min_folds: usize,
    },
    /// Each joint's Coulomb law chosen from the data.
    LawsChosen {
        joints: Vec<JointLaw>,
        shares: [f64; 2],
        folds: usize,
        standard_errors: f64,
        t: f64,
        unresolved: Vec<UnresolvedLaw>,
    },
    /// Base parameters no trajectory within the limits separates, regrouped.
    Regrouped { rank: usize, names: Vec<String>, weak: f64, kept: f64 },
    /// An instrumental-variable estimate (`estimator`) from the closed loop simulated with it.
    ClosedLoop { estimator: String, iterations: usize, last_change_sigma: f64 },
    /// Some of its iterations simulated the nearest physically consistent model instead; `first`
    /// is the first such iteration, with its time and why.
    ClosedLoopDetours { estimator: String, detours: usize, iterations: usize, first: String },
    /// A held-out log validated at the lowest cut-off it allows, not training's.
    ValidatedAtLowest { lowest_hz: f64, cutoff_hz: f64 },
    /// Drive gains fitted with the base parameters from runs with and without a known load.
    DriveGainsFitted { mass_kg: f64, body: String, estimated: Vec<String>, joints: Vec<JointGain> },
    /// The known load makes under `floor` of these joints' torque.
    LoadBarelyLoads { floor: f64, joints: Vec<String> },
    /// A datasheet's gain agrees with the load's.
    DatasheetAgrees { joint: String, datasheet: [f64; 2], load: [f64; 2], z: f64 },
    /// The load does not fix this gain: the datasheet's is used.
    DatasheetUsed { joint: String, datasheet: [f64; 2], load: [f64; 2] },
    /// Rows trimmed from an end of a log (`log` names the log where there are several).
    Trimmed { log: String, end: LogEnd, first: usize, last: usize, why: RunBreak },
    /// A log resampled onto a uniform grid.
    Resampled {
        log: String,
        first: usize,
        last: usize,
        rate_hz: f64,
        samples: usize,
        blended: usize,
        off_steps: f64,
        shortest_s: f64,
        longest_s: f64,
        median_s: f64,
    },
    /// The simulated rig's own parameters, written as a model file to compare with: not estimated.
    SimulatedRigsOwn,
    /// A diagnosis without a given model started from the model identified on the same log:
    /// `periods` averaged (1: none), its cut-off, each joint's friction velocity (`None`:
    /// sign(q̇)). `refitted`: the declared parameters were refitted with the effects; otherwise
    /// held at the identified values, because refitted they predicted the joints `worse` worse.
    DiagnosisFromIdentified {
        periods: usize,
        cutoff_hz: f64,
        velocities: Vec<Option<f64>>,
        refitted: bool,
        worse: Vec<Worse>,
    },
    /// Identification refused the log (`why`): the diagnosis started from the declared model
    /// refitted.
    DiagnosisFromDeclared { why: String },
    /// Against a given model, whether each test counts that model's own calibration error
    /// (`diagnose/calibration_error.rs`): its held parameters' covariance (`parameters`), its
    /// drive gains' (`gains`), as `directions` directions on the training log; none where the
    /// log is the one the model was fitted on (`same_log`).
    CalibrationError { parameters: bool, gains: bool, directions: usize, same_log: bool },
    /// A line from a file written before reasons were data.
    Recorded { text: String },
}

/// A joint the final model still predicts worse than the model the diagnosis started from, beyond
/// the comparison's noise, after the guard (`diagnose/guard.rs`): with the declared parameters
/// refitted, the refit itself can lose where no effect acts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Worse {
    pub joint: usize,
    /// The starting model's held-out RMS on the joint and the final model's (N·m or N).
    pub start_rms: f64,
    pub rms: f64,
    /// The excess of the mean squared error in standard errors of the difference.
    pub sigmas: f64,
    /// The band the loss was judged in, where it is the starting model's own cut-off (Hz), both
    /// RMS filtered there; `None`: the diagnosis's band.
    #[serde(default)]
    pub band_hz: Option<f64>,
}

impl Worse {
    /// Where the RMS were measured, after them: `" in the starting model's band, 4.00 Hz"`, or
    /// nothing at the diagnosis's band.
    pub fn in_band(&self) -> String {
        self.band_hz.map(|hz| format!(" in the starting model's band, {hz:.2} Hz")).unwrap_or_default()
    }
}

/// A choice the data support only weakly, with its figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "code", rename_all = "snake_case")]
pub enum Concern {
    /// The periods given do not repeat.
    PeriodsDoNotRepeat { count: usize, mismatch: f64 },
    /// The motion repeats, but the log holds under two periods.
    UnderTwoPeriods { period_s: f64, periods: f64 },
    /// Few periods to average.
    FewPeriods { count: usize },
    /// The motion's bandwidth times `factor` is beyond a quarter of the sample rate.
    CutoffCapped { signal_hz: f64, factor: f64, sample_rate_hz: f64, cap_hz: f64 },
    /// The model predicts best at the lowest cut-off the log's length allows.
    BestAtLowestCutoff { cutoff_hz: f64 },
    /// The best cut-off is the highest tried, a quarter of the sample rate.
    BestAtHighestCutoff { cutoff_hz: f64 },
    /// The laws and cut-offs had not settled after `rounds` rounds.
    LawsNotSettled { rounds: usize, unsettled: Vec<usize> },
    /// An instrumental-variable estimate did not settle.
    ClosedLoopNotSettled { estimator: String, iterations: usize, last_change_sigma: f64 },
    /// A datasheet's gain and the load's differ.
    DatasheetDisagrees { joint: String, datasheet: [f64; 2], load: [f64; 2], z: f64 },
    /// Gains the load does not fix.
    GainsNotFixed { joints: Vec<LooseGain>, max_sigma: f64, min_over: f64 },
    /// The diagnosis's band cannot go lower on a log this short.
    BandFloorFromLength { floor_hz: f64, duration_s: f64, blocks: usize, memories: f64 },
    /// The user's cut-off predicts held-out torque worse than the data's choice.
    CutoffGivenPredictsWorse { cutoff_hz: f64, chosen_hz: f64, sigmas: f64, fp: f64, chosen_fp: f64 },
    /// A line from a file written before warnings were data.
    Recorded { text: String },
}

/// A choice the hand's force estimate was made with: its bandwidth, σ, thresholds and velocity.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "code", rename_all = "snake_case")]
pub enum ForceChoice {
    /// The observer's bandwidth per joint from its hand-free run on held-out data: the widest of
    /// `grid_hz` at which its RMS on `runs` is within `allowance` × its value at the first.
    ObserverRun { grid_hz: Vec<f64>, hand_bandwidth_hz: f64, hand_band_hz: f64, runs: Vec<String>, allowance: f64 },
    /// The bandwidth per joint is the model file's observer run's (`run`).
    BandwidthFromRun { bandwidth_hz: Vec<f64>, run: Box<ForceChoice> },
    /// A quarter (`1 / per_band`) of the band the model's σ was measured in.
    BandwidthFromBand { bandwidth_hz: f64, band_hz: f64 },
    /// `per_hand_band` × a hand's band, at most a tenth of the sample rate.
    BandwidthFromHand { bandwidth_hz: f64, per_hand_band: f64, hand_band_hz: f64 },
    /// σ is the observer's hand-free RMS on the model's held-out data (`source`).
    SigmaFromObserver { source: String },
    /// σ is the model's held-out residual RMS.
    SigmaFromResidual { source: String, samples: usize },
    /// The collision threshold is at least `margin` × the largest hand-free estimate held out.
    CollisionFloor { margin: f64, peak: Vec<f64> },
    /// Coulomb friction switches as the controllers' tanh where the model's law is sign.
    TanhForSign,
    /// Zero-phase: the observer's lag undone backward, then band-limited.
    ZeroPhase { band_hz: f64, per_hand_band: f64, hand_band_hz: f64, order: usize },
    /// q̇ from q filtered zero-phase at `cutoffs_hz` (per joint): `per_band` × the zero-phase
    /// band where `zero_phase`, else the model's band or `per_band` × the joint's bandwidth.
    Velocity { cutoffs_hz: Vec<f64>, order: usize, zero_phase: bool, per_band: f64, model_band_hz: f64 },
    /// Contact and collision thresholds set by hand in the configuration.
    ThresholdsByHand,
    /// Contact at `contact` σ and collision at `collision` σ of the held-out σ.
    ThresholdsFromSigma { contact: f64, collision: f64 },
    /// No contact or collision told: the file's σ is its residual's, not the observer's.
    NoThresholdsResidualSigma,
    /// No contact or collision told: no held-out σ and no thresholds.
    NoThresholdsNoSigma,
    /// A line from a file written before reasons were data.
    Recorded { text: String },
}

impl Display for ForceChoice {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            Self::ObserverRun { grid_hz, hand_bandwidth_hz, hand_band_hz, runs, allowance } => write!(
                f,
                "the widest of {grid_hz:?} Hz (from {hand_bandwidth_hz:.0} Hz, ten times a hand's {hand_band_hz} Hz \
                 band) at which the observer's hand-free RMS on the held-out runs ({}) is within {allowance} times its \
                 value at {:.0} Hz: wider, what the band lets through (noise grows √2 per octave) outgrows the error \
                 already there",
                runs.join(", "),
                grid_hz.first().copied().unwrap_or_default()
            ),
            Self::BandwidthFromRun { bandwidth_hz, run } => {
                write!(f, "the observer's bandwidth per joint is {:?} Hz: {run}", round3(bandwidth_hz))
            }
            Self::BandwidthFromBand { bandwidth_hz, band_hz } => write!(
                f,
                "the observer's bandwidth is {bandwidth_hz:.3} Hz, a quarter of the {band_hz:.3} Hz band the model's σ \
                 was measured in: the model file records no observer run on held-out data (identify with --validate) \
                 to set it from, and at a wider bandwidth the estimate would pass what that σ never saw"
            ),
            Self::BandwidthFromHand { bandwidth_hz, per_hand_band, hand_band_hz } => write!(
                f,
                "the observer's bandwidth is {bandwidth_hz:.3} Hz, {per_hand_band} times the {hand_band_hz} Hz band of \
                 a hand's force (at most a tenth of the sample rate)"
            ),
            Self::SigmaFromObserver { source } => {
                write!(f, "σ is the observer's hand-free RMS at its bandwidth on the model's held-out data ({source})")
            }
            Self::SigmaFromResidual { source, samples } => {
                write!(f, "σ is the model's held-out residual RMS ({source}, {samples} samples)")
            }
            Self::CollisionFloor { margin, peak } => write!(
                f,
                "the collision threshold is at least {margin} times the largest hand-free estimate on the held-out \
                 runs, {:?}",
                round3(peak)
            ),
            Self::TanhForSign => {
                f.write_str("Coulomb friction switches as the controllers' tanh(q̇/ε) where the model's law is sign(q̇)")
            }
            Self::ZeroPhase { band_hz, per_hand_band, hand_band_hz, order } => write!(
                f,
                "zero-phase: the observer's lag undone backward, then band-limited to {band_hz} Hz ({per_hand_band} \
                 times a hand's {hand_band_hz} Hz, order {order}); σ and the levels are the causal observer's"
            ),
            Self::Velocity { cutoffs_hz, order, zero_phase, per_band, model_band_hz } => {
                write!(
                    f,
                    "q̇ is the central difference of q filtered zero-phase at {:?} Hz per joint (order {order}): ",
                    round3(cutoffs_hz)
                )?;
                match zero_phase {
                    true => write!(f, "{per_band} times the zero-phase estimate's band"),
                    false => write!(
                        f,
                        "the model's band ({model_band_hz:.3} Hz) or {per_band} times the joint's bandwidth, whichever \
                         is wider"
                    ),
                }
            }
            Self::ThresholdsByHand => f.write_str("thresholds set by hand in the configuration"),
            Self::ThresholdsFromSigma { contact, collision } => {
                write!(f, "contact at {contact}σ and collision at {collision}σ of the model's held-out σ")
            }
            Self::NoThresholdsResidualSigma => f.write_str(
                "no contact or collision is told: the model file's held-out σ is its residual's, not the observer's \
                 (record the observer's run with `arash identify --validate`), and no thresholds are set \
                 (force.contact, force.collision)",
            ),
            Self::NoThresholdsNoSigma => f.write_str(
                "no contact or collision is told: the model file records no held-out σ and no thresholds are set \
                 (force.contact, force.collision)",
            ),
            Self::Recorded { text } => f.write_str(text),
        }
    }
}

impl FromText for ForceChoice {
    fn from_text(text: String) -> Self {
        Self::Recorded { text }
    }
}

/// Each value to a thousandth, as the force's reasons print vectors.
fn round3(v: &[f64]) -> Vec<f64> {
    v.iter().map(|x| (x * 1000.0).round() / 1000.0).collect()
}

/// One joint's Coulomb law as chosen: `velocity` is `None` for `sign(q̇)`; for `tanh(q̇/v)`
/// `per_rms_speed` is v over the joint's RMS speed, and `error_share` its held-out squared error
/// over sign(q̇)'s.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointLaw {
    pub joint: usize,
    pub velocity: Option<f64>,
    pub per_rms_speed: f64,
    pub error_share: f64,
}

/// A joint's fittest law not kept: its friction velocity strays from the velocity at the main
/// cut-off by `stray` RMS over `samples` samples, more than the law's `velocity`, or only
/// `transition` of those samples are clear of rests and stops, fewer than `needed`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UnresolvedLaw {
    pub joint: usize,
    pub velocity: f64,
    pub stray: f64,
    pub samples: usize,
    /// Samples in the law's transition clear of rests and stops, and the fewest that show it.
    pub transition: usize,
    pub needed: usize,
}

/// A drive gain from a calibration with a load: `gain ± sigma`, the load's share of the joint's
/// torque and the load's torque over what the model leaves.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointGain {
    pub joint: String,
    pub gain: f64,
    pub sigma: f64,
    pub load_share: f64,
    pub over_unexplained: f64,
}

/// A gain the load does not fix: its relative σ, the load over the unexplained, and the mass at
/// the same place that would fix it (where the load loads the joint at all).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LooseGain {
    pub joint: String,
    pub relative_sigma: f64,
    pub over_unexplained: f64,
    pub mass_that_fixes_kg: Option<f64>,
}

/// Which end of a log rows were trimmed from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LogEnd {
    Start,
    End,
}

/// Why a log's usable run starts or stops at `row`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "code", rename_all = "snake_case")]
pub enum RunBreak {
    /// Row `row` has `signal` not finite.
    NotFinite { row: usize, signal: String },
    /// `t` goes back at `row`.
    TimeGoesBack { row: usize, from_s: f64, to_s: f64 },
    /// A gap before `row` longer than interpolation fills.
    Gap { row: usize, steps: f64, seconds: f64, max_steps: f64 },
}

impl Choice {
    /// The variant's tag, as in the JSON (`code`), so that Python and the file name it alike.
    pub fn code(&self) -> String {
        tag_of(self)
    }

    /// A choice of the cut-off (which the diagnosis's band choice replaces).
    pub fn is_cutoff(&self) -> bool {
        matches!(
            self,
            Self::CutoffGiven { .. }
                | Self::CutoffNoMotion { .. }
                | Self::CutoffFromSpectrum { .. }
                | Self::CutoffSearched { .. }
                | Self::BandSearched { .. }
        )
    }

    /// A choice of the Coulomb columns: their velocity's cut-off or their laws.
    pub fn is_friction(&self) -> bool {
        matches!(
            self,
            Self::FrictionCutoff { .. }
                | Self::FrictionCutoffSearched { .. }
                | Self::FrictionAtBandNoGrid { .. }
                | Self::FrictionAtBand { .. }
                | Self::FrictionNarrowed { .. }
                | Self::FrictionLowest { .. }
                | Self::LawsKept { .. }
                | Self::LawsChosen { .. }
        )
    }

    /// A choice that follows from the cut-off: the friction's, and the samples left out of the
    /// fit (the filter's start-up at the ends, the resting samples).
    pub fn follows_cutoff(&self) -> bool {
        self.is_friction() || matches!(self, Self::EdgesLeftOut { .. } | Self::Resting { .. })
    }

    /// This choice said of the log `label` (a repair's, where several logs were repaired).
    pub fn of_log(mut self, label: &str) -> Self {
        if let Self::Trimmed { log, .. } | Self::Resampled { log, .. } = &mut self {
            *log = label.to_string();
        }
        self
    }

    /// The cut-off's why: the text after "cut-off X Hz: ".
    fn cutoff_why(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            Self::CutoffGiven { .. } => f.write_str("set by the user"),
            Self::CutoffNoMotion { .. } => f.write_str("no motion above the noise, the lowest cut-off"),
            Self::CutoffFromSpectrum { signal_hz, factor, periodic, lowest_hz, .. } => {
                let what = match periodic {
                    true => format!("highest harmonic that repeats from period to period {signal_hz:.3} Hz"),
                    false => format!("the motion stands above the position noise floor up to {signal_hz:.3} Hz"),
                };
                match lowest_hz {
                    Some(floor) => write!(f, "the lowest cut-off the log allows, {floor:.3} Hz ({what})"),
                    None => write!(f, "{factor} × the bandwidth ({what})"),
                }
            }
            _ => Ok(()),
        }
    }

    fn cutoff_hz(&self) -> Option<f64> {
        match self {
            Self::CutoffGiven { cutoff_hz }
            | Self::CutoffNoMotion { cutoff_hz }
            | Self::CutoffFromSpectrum { cutoff_hz, .. }
            | Self::CutoffSearched { cutoff_hz, .. }
            | Self::BandSearched { cutoff_hz, .. } => Some(*cutoff_hz),
            _ => None,
        }
    }
}

impl Concern {
    /// The variant's tag, as in the JSON (`code`).
    pub fn code(&self) -> String {
        tag_of(self)
    }
}

/// The `code` a tagged enum serialises with.
fn tag_of(value: &impl Serialize) -> String {
    serde_json::to_value(value)
        .ok()
        .and_then(|v| v.get("code").and_then(|c| c.as_str()).map(str::to_string))
        .unwrap_or_default()
}

/// `[x, y]` pairs as "x Hz y" with two decimals, joined by commas.
fn by_hz(trials: &[[f64; 2]]) -> String {
    trials.iter().map(|[hz, fp]| format!("{hz:.2} Hz {fp:.2}")).collect::<Vec<_>>().join(", ")
}

/// A log's label as a prefix.
fn prefix(log: &str) -> String {
    match log.is_empty() {
        true => String::new(),
        false => format!("{log}: "),
    }
}

impl Display for Choice {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            Self::PeriodGiven { count, period_s } => {
                write!(f, "{count} periods of {period_s:.4} s: period set by the user")
            }
            Self::PeriodsGiven { count, period_s } => write!(f, "{count} periods of {period_s:.4} s: set by the user"),
            Self::NotAveraged => f.write_str("not averaged over periods: periods = 1 was given"),
            Self::NoJointMoves => f.write_str("not periodic: no joint moves"),
            Self::NeverMovesAway { half_log_s } => write!(
                f,
                "not periodic: the motion never moves away from itself within half the log ({half_log_s:.1} s)"
            ),
            Self::DoesNotRepeat { after_s, mismatch, limit } => write!(
                f,
                "not periodic: the closest repeat (after {after_s:.3} s) differs by {:.1} % of the motion's variance \
                 (periodic is ≤ {:.0} %)",
                100.0 * mismatch,
                100.0 * limit
            ),
            Self::PeriodsFound { count, period_s, mismatch } => write!(
                f,
                "{count} periods of {period_s:.4} s detected (consecutive periods differ by {:.3} % of the motion's \
                 variance)",
                100.0 * mismatch
            ),
            Self::CutoffGiven { .. } | Self::CutoffNoMotion { .. } | Self::CutoffFromSpectrum { .. } => {
                write!(f, "cut-off {:.3} Hz: ", self.cutoff_hz().unwrap_or_default())?;
                self.cutoff_why(f)
            }
            Self::CutoffSearched {
                cutoff_hz,
                trials,
                periodic,
                most_accurate_hz,
                training_fp,
                predicted_fp,
                most_accurate_fp,
                sigmas,
                points,
                spectral,
            } => {
                let target = match periodic {
                    true => {
                        "unfiltered torque of the other half of the periods (even and odd periods predict each other)"
                    }
                    false => "unfiltered torque",
                };
                let (lo, hi) = (trials.first().map_or(0.0, |t| t[0]), trials.last().map_or(0.0, |t| t[0]));
                write!(
                    f,
                    "cut-off {cutoff_hz:.3} Hz: of {} cut-offs from {lo:.2} to {hi:.2} Hz whose fitted models predict \
                     the {target} as well as the best one ({most_accurate_hz:.2} Hz) within {sigmas} standard errors \
                     and {points} point, the one that fits its filtered torque best (mean FP% {training_fp:.2}; on \
                     the unfiltered torque {predicted_fp:.2} against {most_accurate_fp:.2}); the motion's spectrum \
                     suggests {:.2} Hz (",
                    trials.len(),
                    spectral.as_ref().and_then(|s| s.cutoff_hz()).unwrap_or_default(),
                )?;
                if let Some(s) = spectral {
                    s.cutoff_why(f)?;
                }
                write!(f, "); mean FP% on the unfiltered torque by cut-off: {}", by_hz(trials))
            }
            Self::BandSearched {
                cutoff_hz,
                trials,
                validation_runs,
                most_accurate_hz,
                most_accurate_fp,
                sigmas,
                equal_hz,
            } => {
                let held = match validation_runs {
                    true => "the validation runs",
                    false => "the odd-numbered held-out blocks (the model fitted on the even ones)",
                };
                let (lo, hi) = (trials.first().map_or(0.0, |t| t[0]), trials.last().map_or(0.0, |t| t[0]));
                let equal: Vec<String> = equal_hz.iter().map(|hz| format!("{hz:.2}")).collect();
                write!(
                    f,
                    "cut-off {cutoff_hz:.3} Hz: of {} cut-offs from {lo:.2} to {hi:.2} Hz, the widest of those whose \
                     declared model predicts the unfiltered torque of {held} as well as the best \
                     ({most_accurate_hz:.2} Hz, mean FP% {most_accurate_fp:.2}) within {sigmas} of the best's \
                     sampling errors ({} Hz): as much of the motion, in as many independent samples, as the data \
                     carry; mean FP% by cut-off: {}",
                    trials.len(),
                    equal.join(", "),
                    by_hz(trials)
                )
            }
            Self::Jitter { share, rate_hz } => write!(
                f,
                "time stamps jitter by up to {:.0} % of the step with no gap: the samples are taken as a uniform \
                 {rate_hz:.3} Hz stream (the mean rate)",
                100.0 * share
            ),
            Self::EdgesLeftOut { edge_s, cutoff_periods } => write!(
                f,
                "not periodic: {edge_s:.3} s ({cutoff_periods} cut-off periods) at each end left out of the fit, \
                 where the zero-phase filter starts up"
            ),
            Self::FrictionCutoff { cutoff_hz, given, at_most_quarter } => {
                let source = match (given, at_most_quarter) {
                    (true, true) => "set by the user, at most fs/4",
                    (true, false) => "set by the user",
                    (false, _) => "the main cut-off",
                };
                write!(f, "Coulomb columns switch with the velocity filtered at {cutoff_hz:.3} Hz ({source})")
            }
            Self::FrictionCutoffSearched { cutoff_hz, band_hz, trials } => write!(
                f,
                "Coulomb columns switch with the velocity filtered at {cutoff_hz:.3} Hz: the best fit at the \
                 {band_hz:.3} Hz cut-off of {} velocity cut-offs, an octave apart (mean FP% {})",
                trials.len(),
                by_hz(trials)
            ),
            Self::FrictionAtBandNoGrid { cutoff_hz } => write!(
                f,
                "Coulomb columns switch with the velocity filtered at {cutoff_hz:.3} Hz: the band's cut-off; no \
                 joint's positions sit on an encoder's grid, so what the velocity holds there is motion"
            ),
            Self::FrictionAtBand { cutoff_hz, joint, share, limit } => write!(
                f,
                "Coulomb columns switch with the velocity filtered at {cutoff_hz:.3} Hz: the band's cut-off; the \
                 encoders' quantisation makes up {} there (at most {:.3} %)",
                speed_share(*share, *joint),
                100.0 * limit
            ),
            Self::FrictionNarrowed { cutoff_hz, band_hz, band_joint, band_share, joint, share, limit } => write!(
                f,
                "Coulomb columns switch with the velocity filtered at {cutoff_hz:.3} Hz: the encoders' quantisation \
                 makes up {} at the band's {band_hz:.3} Hz and {} here (at most {:.3} %, a tenth of the slowest \
                 Stribeck velocity searched); wider, the friction columns would switch with the encoder's steps",
                speed_share(*band_share, *band_joint),
                speed_share(*share, *joint),
                100.0 * limit
            ),
            Self::FrictionLowest { cutoff_hz, joint, share, limit } => write!(
                f,
                "Coulomb columns switch with the velocity filtered at {cutoff_hz:.3} Hz, the lowest the motion \
                 allows: the encoders' quantisation makes up {} there (at most {:.3} % asked)",
                speed_share(*share, *joint),
                100.0 * limit
            ),
            Self::Resting { shares, hold_samples, hold_s } => {
                let each: Vec<String> =
                    shares.iter().enumerate().map(|(k, s)| format!("joint {k} {:.1} %", 100.0 * s)).collect();
                write!(
                    f,
                    "resting samples left out of the fit ({}): the reading held for {hold_samples} samples ({:.0} ms) \
                     or more, where dry friction holds the joint with a force that is no law of its velocity",
                    each.join(", "),
                    1e3 * hold_s
                )
            }
            Self::LawsKept { velocities, samples, folds, guards_per_fold, guard, min_folds } => write!(
                f,
                "Coulomb laws not chosen from the data, kept as {}: its {samples} samples hold {folds} stretches of \
                 {guards_per_fold} filter memories ({guard} samples each), fewer than the {min_folds} that choosing \
                 a law needs; a longer log or a wider cut-off would allow it",
                CoulombLaws::declared(
                    velocities
                        .iter()
                        .map(|v| v.map_or(CoulombShape::Sign, |epsilon| CoulombShape::Tanh { epsilon }))
                        .collect()
                )
            ),
            Self::LawsChosen { joints, shares, folds, standard_errors, t, unresolved } => {
                let each: Vec<String> = joints
                    .iter()
                    .map(|j| match j.velocity {
                        None => format!("joint {} sign(q̇)", j.joint),
                        Some(v) => format!(
                            "joint {} tanh(q̇/{v:.3e}) ({:.3} × its RMS speed; held-out squared error {:.1} % of \
                             sign(q̇)'s)",
                            j.joint,
                            j.per_rms_speed,
                            100.0 * j.error_share
                        ),
                    })
                    .collect();
                write!(
                    f,
                    "Coulomb laws chosen from the data, each joint's sign(q̇) unless the tanh(q̇/v), for v from {} to \
                     {} × its RMS speed, that best predicts {folds} stretches of the log, each fitted without, \
                     predicts them better by more than {standard_errors} standard error of the stretches' \
                     differences (as Student's t with {} degrees of freedom: {t:.2}): {}",
                    shares[0],
                    shares[1],
                    folds.saturating_sub(1),
                    each.join("; ")
                )?;
                for u in unresolved {
                    match u.stray > u.velocity {
                        true => write!(
                            f,
                            "; joint {}'s fittest tanh(q̇/{:.3e}) not kept: where it acts, its friction velocity \
                             strays from the velocity at the main cut-off by {:.3e} RMS ({} samples), more than the \
                             law's v, so it is a law of the filter, not of the motion",
                            u.joint, u.velocity, u.stray, u.samples
                        )?,
                        false => write!(
                            f,
                            "; joint {}'s fittest tanh(q̇/{:.3e}) not kept: only {} of the {} samples where it acts \
                             are clear of rests and of stops shorter than a rest (at least {} are needed, three of \
                             the torque filter's memories), so its transition is the stops' ramp through the \
                             filter, not the joint's friction",
                            u.joint, u.velocity, u.transition, u.samples, u.needed
                        )?,
                    }
                }
                Ok(())
            }
            Self::Regrouped { rank, names, weak, kept } => write!(
                f,
                "base parameters: {rank}; {} regrouped, since no trajectory within the limits separates {} from the \
                 others (residual ≤ {weak:.1e} against ≥ {kept:.1e} for every kept one); keep_weak=True / \
                 --keep-weak fits every exact one",
                names.join(", "),
                if names.len() == 1 { "it" } else { "them" },
            ),
            Self::ClosedLoop { estimator, iterations, last_change_sigma } => write!(
                f,
                "{estimator}: the closed loop simulated with the estimate, {iterations} iteration(s); the last moved \
                 no β by more than {last_change_sigma:.3} σ"
            ),
            Self::ClosedLoopDetours { estimator, detours, iterations, first } => write!(
                f,
                "{estimator}: the estimate of {detours} of the {iterations} iteration(s) did not simulate (first: \
                 iteration {first}); their simulation used the nearest physically consistent model"
            ),
            Self::ValidatedAtLowest { lowest_hz, cutoff_hz } => write!(
                f,
                "validated at {lowest_hz:.3} Hz, the lowest cut-off this log allows, not training's {cutoff_hz:.3} Hz"
            ),
            Self::DriveGainsFitted { mass_kg, body, estimated, joints } => {
                let each: Vec<String> = joints
                    .iter()
                    .map(|j| {
                        format!(
                            "{} {:.4} ± {:.4} (load {:.1} % of its torque, {:.1} × what the model leaves)",
                            j.joint,
                            j.gain,
                            j.sigma,
                            100.0 * j.load_share,
                            j.over_unexplained
                        )
                    })
                    .collect();
                let with = match estimated.is_empty() {
                    true => String::new(),
                    false => format!(", its {} estimated with them", estimated.join(", ")),
                };
                write!(
                    f,
                    "drive gains fitted with the base parameters from runs with and without a {mass_kg} kg load on \
                     {body} (Gautier and Briot 2014){with}: {}",
                    each.join("; ")
                )
            }
            Self::LoadBarelyLoads { floor, joints } => write!(
                f,
                "the known load makes under {:.0} % of the torque of {}: their gains are fixed only through \
                 parameters they share with the other joints, and their σ says how well; a load on a body these \
                 joints move, carried over motion that loads them, fixes them directly",
                100.0 * floor,
                joints.join(", ")
            ),
            Self::DatasheetAgrees { joint, datasheet: [k, s], load: [g, gs], z } => write!(
                f,
                "{joint}: the datasheet's gain {k:.4} ± {s:.4} agrees with the load's {g:.4} ± {gs:.4} ({z:+.1} σ)"
            ),
            Self::DatasheetUsed { joint, datasheet: [k, s], load: [g, gs] } => write!(
                f,
                "{joint}: the load does not fix its gain, so the datasheet's {k:.4} ± {s:.4} is used (the load's fit \
                 gave {g:.4} ± {gs:.4})"
            ),
            Self::Trimmed { log, end, first, last, why } => {
                let side = match end {
                    LogEnd::Start => "start",
                    LogEnd::End => "end",
                };
                write!(f, "{}rows {first}–{last} trimmed from the {side}: {why}", prefix(log))
            }
            Self::Resampled {
                log,
                first,
                last,
                rate_hz,
                samples,
                blended,
                off_steps,
                shortest_s,
                longest_s,
                median_s,
            } => {
                write!(
                    f,
                    "{}resampled rows {first}–{last} ({} rows) onto a uniform {rate_hz:.4} Hz grid of {samples} \
                     samples by linear interpolation ({blended} blended between two logged samples): the stamps \
                     leave one uniform line by up to {off_steps:.2} steps (half a step or more is a sample's own \
                     time, not stamping noise), steps from {shortest_s:.6} to {longest_s:.6} s against the median \
                     {median_s:.6} s",
                    prefix(log),
                    last + 1 - first
                )
            }
            Self::DiagnosisFromIdentified { periods, cutoff_hz, velocities, refitted, worse } => {
                let averaged = match periods {
                    1 => "not averaged over periods".to_string(),
                    n => format!("{n} periods averaged"),
                };
                let laws: Vec<String> = velocities
                    .iter()
                    .enumerate()
                    .map(|(k, v)| match v {
                        Some(v) => format!("joint {k} tanh(q̇/{v:.3})"),
                        None => format!("joint {k} sign(q̇)"),
                    })
                    .collect();
                write!(
                    f,
                    "the diagnosis starts from the model identified on this log (OLS, {averaged}, cut-off \
                     {cutoff_hz:.2} Hz; {}): its held-out error is the \"before\"; ",
                    laws.join(", ")
                )?;
                if *refitted {
                    return f.write_str(
                        "the declared parameters are refitted with the effects, each Coulomb law chosen at the \
                         diagnosis's band, and no joint predicts the held-out data worse than the identified model",
                    );
                }
                let lost: Vec<String> = worse
                    .iter()
                    .map(|w| {
                        format!(
                            "joint {} {:.4e} against {:.4e}{} ({:.1} standard errors)",
                            w.joint,
                            w.rms,
                            w.start_rms,
                            w.in_band(),
                            w.sigmas
                        )
                    })
                    .collect();
                write!(
                    f,
                    "the identified parameters are held and friction refitted where it predicts better, because \
                     refitted with the effects they predicted the held-out data worse on {}",
                    lost.join(", ")
                )
            }
            Self::DiagnosisFromDeclared { why } => write!(
                f,
                "the diagnosis starts from the declared model refitted on this log: identification refused it ({why})"
            ),
            Self::CalibrationError { same_log: true, .. } => f.write_str(
                "the given model's own calibration error is not counted in the tests: it was fitted on this very \
                 log (the same fingerprint), whose residual its fit already leaves orthogonal to its parameters' columns",
            ),
            Self::CalibrationError { parameters, gains, directions, .. } => {
                let parts = [parameters.then_some("its held parameters' covariance"), gains.then_some("its drive gains'")];
                let counted: Vec<&str> = parts.into_iter().flatten().collect();
                match counted.is_empty() {
                    true => f.write_str(
                        "the given model's own calibration error is not counted in the tests: its file records no \
                         covariance of its parameters (written before it was kept)",
                    ),
                    false => write!(
                        f,
                        "every test counts the given model's own calibration error ({}; {directions} directions on \
                         this log): an effect must stand out of the noise and of what the calibration leaves uncertain",
                        counted.join(" and ")
                    ),
                }
            }
            Self::SimulatedRigsOwn => f.write_str(
                "the simulated rig's own parameters of the declared model (its scenario and seed): not estimated",
            ),
            Self::Recorded { text } => f.write_str(text),
        }
    }
}

/// "x % of joint k's RMS speed".
fn speed_share(share: f64, joint: usize) -> String {
    format!("{:.2} % of joint {joint}'s RMS speed", 100.0 * share)
}

impl Display for RunBreak {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            Self::NotFinite { row, signal } => write!(f, "row {row} has {signal} not finite"),
            Self::TimeGoesBack { row, from_s, to_s } => {
                write!(f, "t goes back from {from_s} s to {to_s} s at row {row}")
            }
            Self::Gap { row, steps, seconds, max_steps } => write!(
                f,
                "a gap of {steps:.1} median steps ({seconds:.6} s) before row {row}, longer than the {max_steps} \
                 interpolation fills"
            ),
        }
    }
}

impl Display for Concern {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        match self {
            Self::PeriodsDoNotRepeat { count, mismatch } => write!(
                f,
                "the {count} periods given do not repeat: consecutive ones differ by {:.1} % of the motion's variance",
                100.0 * mismatch
            ),
            Self::UnderTwoPeriods { period_s, periods } => write!(
                f,
                "the motion repeats after {period_s:.4} s, but the log holds {periods:.2} such periods: not averaged"
            ),
            Self::FewPeriods { count } => write!(
                f,
                "only {count} periods to average: the noise falls by √{count} only, and a period found from {count} \
                 repeats is uncertain"
            ),
            Self::CutoffCapped { signal_hz, factor, sample_rate_hz, cap_hz } => write!(
                f,
                "the motion reaches {signal_hz:.1} Hz, so {factor} × it is beyond a quarter of the {sample_rate_hz:.1} \
                 Hz sample rate: the cut-off is capped at {cap_hz:.1} Hz and the filter bends the highest harmonics"
            ),
            Self::BestAtLowestCutoff { cutoff_hz } => write!(
                f,
                "the model predicts best at the lowest cut-off the log's length allows ({cutoff_hz:.2} Hz): a lower \
                 one may predict better still; a longer log would allow it"
            ),
            Self::BestAtHighestCutoff { cutoff_hz } => write!(
                f,
                "the best cut-off is the highest tried, a quarter of the sample rate ({cutoff_hz:.1} Hz): the torque \
                 the model explains reaches the sampling limit (sample faster, or the model lacks a fast effect)"
            ),
            Self::LawsNotSettled { rounds, unsettled } => write!(
                f,
                "the Coulomb laws and the cut-offs had not settled after {rounds} rounds of choosing each with the \
                 other: {} keep sign(q̇), the simpler law, since the last round moved them between sign(q̇) and a \
                 smooth law; the other joints keep the last chosen; the cut-offs are those chosen for the laws \
                 kept",
                match unsettled.as_slice() {
                    [] => "no joint".to_string(),
                    [k] => format!("joint {k}"),
                    ks => format!("joints {}", ks.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(", ")),
                }
            ),
            Self::ClosedLoopNotSettled { estimator, iterations, last_change_sigma } => write!(
                f,
                "{estimator} did not settle in {iterations} iterations (the last moved a β by {last_change_sigma:.2} \
                 σ): the estimate is the last one"
            ),
            Self::DatasheetDisagrees { joint, datasheet: [k, s], load: [g, gs], z } => write!(
                f,
                "{joint}: the datasheet's gain {k:.4} ± {s:.4} and the load's {g:.4} ± {gs:.4} differ by {z:.1} σ; \
                 the load's is kept (check the datasheet, the current sensor's scale and the load)"
            ),
            Self::GainsNotFixed { joints, max_sigma, min_over } => {
                let each: Vec<String> = joints
                    .iter()
                    .map(|j| {
                        let least = j
                            .mass_that_fixes_kg
                            .map_or(String::new(), |m| format!("; about {m:.3} kg at the same place would fix it"));
                        format!(
                            "{} (σ {:.0} %, load {:.1} × the unexplained{least})",
                            j.joint,
                            100.0 * j.relative_sigma,
                            j.over_unexplained
                        )
                    })
                    .collect();
                write!(
                    f,
                    "not fixed by this load: the gains of {}. A gain is fixed when its σ is under {:.0} % (a \
                     datasheet's ±10 % at 2σ) and, on a joint the load loads, the load's torque is at least {:.0} × \
                     what the model leaves unexplained there (what the model misses biases the gain by up to their \
                     ratio). Keep a datasheet's value for them, or calibrate again with a load these joints carry \
                     more of",
                    each.join(", "),
                    100.0 * max_sigma,
                    min_over
                )
            }
            Self::BandFloorFromLength { floor_hz, duration_s, blocks, memories } => write!(
                f,
                "the diagnosis's band cannot go below {floor_hz:.2} Hz on a {duration_s:.1} s log: its {blocks} \
                 held-out blocks must each span {memories} filter memories; a longer log or a validation log would \
                 allow a narrower one"
            ),
            Self::CutoffGivenPredictsWorse { cutoff_hz, chosen_hz, sigmas, fp, chosen_fp } => write!(
                f,
                "the cut-off set ({cutoff_hz:.3} Hz) predicts held-out torque worse than the data's choice would \
                 ({chosen_hz:.3} Hz), by more than {sigmas} of its sampling errors: mean FP% {fp:.2} against \
                 {chosen_fp:.2}; leave the cut-off to the data, or read the effects found with that in mind"
            ),
            Self::Recorded { text } => f.write_str(text),
        }
    }
}

/// Stored as text in files written before it was data.
pub trait FromText {
    fn from_text(text: String) -> Self;
}

impl FromText for Choice {
    fn from_text(text: String) -> Self {
        Self::Recorded { text }
    }
}

impl FromText for Concern {
    fn from_text(text: String) -> Self {
        Self::Recorded { text }
    }
}

/// The JSON of a list of choices or concerns: each its tagged fields with its `text` beside
/// them (`#[serde(with = "said")]`). A plain string, or an entry whose code this version does
/// not know, reads as `Recorded` with its text.
pub mod said {
    use super::FromText;
    use serde::de::{DeserializeOwned, Deserializer};
    use serde::ser::{Error, Serializer};
    use serde::{Deserialize, Serialize};
    use serde_json::Value;
    use std::fmt::Display;

    pub fn serialize<S: Serializer, T: Serialize + Display>(items: &[T], s: S) -> Result<S::Ok, S::Error> {
        let values = items.iter().map(with_text).collect::<Result<Vec<Value>, _>>().map_err(S::Error::custom)?;
        values.serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>, T: DeserializeOwned + FromText>(d: D) -> Result<Vec<T>, D::Error> {
        Ok(Vec::<Value>::deserialize(d)?.into_iter().map(read).collect())
    }

    /// One entry, as [`serialize`] and [`deserialize`] do a list's (`#[serde(with = "said::one")]`).
    pub mod one {
        use super::*;

        pub fn serialize<S: Serializer, T: Serialize + Display>(item: &T, s: S) -> Result<S::Ok, S::Error> {
            with_text(item).map_err(S::Error::custom)?.serialize(s)
        }

        pub fn deserialize<'de, D: Deserializer<'de>, T: DeserializeOwned + FromText>(d: D) -> Result<T, D::Error> {
            Ok(read(Value::deserialize(d)?))
        }
    }

    /// Every entry as JSON, as a file holds them.
    pub fn values<T: Serialize + Display>(items: &[T]) -> Vec<Value> {
        items.iter().map(|item| with_text(item).expect("a choice's fields are JSON")).collect()
    }

    /// One entry as JSON: its fields, tagged, and its text.
    pub fn with_text<T: Serialize + Display>(item: &T) -> Result<Value, serde_json::Error> {
        let mut value = serde_json::to_value(item)?;
        if let Value::Object(map) = &mut value {
            map.insert("text".into(), Value::String(item.to_string()));
        }
        Ok(value)
    }

    /// One entry read back: by its code, or as its text.
    pub fn read<T: DeserializeOwned + FromText>(value: Value) -> T {
        match value {
            Value::String(text) => T::from_text(text),
            value => {
                let text = value.get("text").and_then(Value::as_str).unwrap_or_default().to_string();
                serde_json::from_value(value).unwrap_or_else(|_| T::from_text(text))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A choice goes through its JSON unchanged, with its text beside its fields; a plain string
    /// (a file before choices were data) and an unknown code read as their text.
    #[test]
    fn a_choice_round_trips_and_old_lines_read_as_text() {
        let choice = Choice::CutoffFromSpectrum {
            cutoff_hz: 12.5,
            signal_hz: 2.5,
            factor: 5.0,
            periodic: true,
            lowest_hz: None,
        };
        let value = said::with_text(&choice).unwrap();
        assert_eq!(value["code"], "cutoff_from_spectrum");
        assert_eq!(value["cutoff_hz"], 12.5);
        assert_eq!(
            value["text"],
            "cut-off 12.500 Hz: 5 × the bandwidth (highest harmonic that repeats from period to period 2.500 Hz)"
        );
        assert_eq!(said::read::<Choice>(value), choice);
        let old = said::read::<Choice>(Value::String("cut-off 3 Hz: set by the user".into()));
        assert_eq!(old, Choice::Recorded { text: "cut-off 3 Hz: set by the user".into() });
        let unknown = serde_json::json!({"code": "from_the_future", "text": "later"});
        assert_eq!(said::read::<Concern>(unknown), Concern::Recorded { text: "later".into() });
        assert_eq!(choice.code(), "cutoff_from_spectrum");
    }

    use serde_json::Value;

    /// A searched cut-off names the spectrum's suggestion by its own why, as the line did.
    #[test]
    fn a_searched_cutoff_quotes_the_spectrums_reason() {
        let spectral = Choice::CutoffFromSpectrum {
            cutoff_hz: 4.0,
            signal_hz: 0.5,
            factor: 5.0,
            periodic: false,
            lowest_hz: Some(4.0),
        };
        let searched = Choice::CutoffSearched {
            cutoff_hz: 8.0,
            trials: vec![[4.0, 90.0], [8.0, 91.0]],
            periodic: false,
            most_accurate_hz: 8.0,
            training_fp: 92.0,
            predicted_fp: 91.0,
            most_accurate_fp: 91.0,
            sigmas: 2.0,
            points: 1.0,
            spectral: Some(Box::new(spectral)),
        };
        let text = searched.to_string();
        assert!(
            text.contains("the motion's spectrum suggests 4.00 Hz (the lowest cut-off the log allows, 4.000 Hz"),
            "{text}"
        );
        assert!(text.ends_with("by cut-off: 4.00 Hz 90.00, 8.00 Hz 91.00"), "{text}");
        assert!(searched.is_cutoff() && !searched.follows_cutoff());
    }
}
