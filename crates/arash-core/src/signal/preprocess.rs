//! From a logged run to the signals identification uses (paper section III-C): average the
//! periods of a periodic excitation, low-pass filter with a zero-phase Butterworth, and take
//! central differences for q̇ and q̈, filtered the same way. Torque is averaged and filtered alike.
//!
//! Signals are row-major `N × dof` slices in SI units. A periodic average is filtered and
//! differentiated circularly (three periods side by side, the middle kept): one period of a
//! periodic signal has no ends, so it gets no end effects.

use std::borrow::Cow;

use super::data_choices::{bandwidth, find_period, harmonic_bandwidth, PERIODIC_MISMATCH};
use super::friction::{FrictionVelocity, RawVelocity};
use super::options::{PreprocessOptions, SettingError};
use crate::choices::{Choice, Concern};
use crate::model::CoulombLaws;
use crate::signal::conditioning::{averaged, central_difference, every_nth_row, filter_columns, periods_of, Averaging};
use crate::signal::filter::{Butterworth, FilterError};

/// Why a log cannot be preprocessed. Each variant names the offending input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PreprocessError {
    #[error("{name} has {got} values, expected {expected} ({samples} samples × {width})")]
    Shape { name: &'static str, got: usize, expected: usize, samples: usize, width: usize },
    #[error(
        "{name} is not finite at sample {sample} (a corrupt block at either end of the log is trimmed by the opt-in repair: \
         repair=True in Python, --repair on the command line)"
    )]
    NotFinite { name: &'static str, sample: usize },
    #[error("need at least {needed} samples, got {got}")]
    TooFewSamples { needed: usize, got: usize },
    #[error(
        "t does not increase at sample {index}: {before} s is followed by {after} s (a corrupt block at either end of the \
         log is trimmed by the opt-in repair: repair=True in Python, --repair on the command line)"
    )]
    TimeNotIncreasing { index: usize, before: f64, after: f64 },
    #[error(
        "t is not uniformly sampled: step {index} is {step:.6} s where the median step is {median:.6} s (a gap or a \
         reordering; jitter under half a step is accepted; the opt-in repair, repair=True in Python or --repair on the \
         command line, resamples isolated irregular steps onto a uniform grid)"
    )]
    NonUniformTime { index: usize, step: f64, median: f64 },
    #[error(
        "joint {joint} never moves (its position spans {span:.3e}, {steps:.0} encoder steps): nothing about it can be identified"
    )]
    JointStill { joint: usize, span: f64, steps: f64 },
    #[error(
        "the log is {duration_s:.2} s long and holds no cycle of any joint's motion (joint {joint} turns back most, \
         {reversals} time(s)): a log must cover at least one back-and-forth of the motion"
    )]
    NoCycle { duration_s: f64, reversals: usize, joint: usize },
    #[error("the log holds {periods} period(s) of {period_s:.4} s: averaging needs at least 2 whole periods")]
    TooFewPeriods { periods: usize, period_s: f64 },
    #[error(
        "the log is {duration_s:.2} s long and not periodic: at a cut-off of {cutoff_hz:.3} Hz the filter's start-up \
         transients fill {edge_s:.2} s at each end, more than a quarter of it; use a cut-off of at least {lowest_hz:.3} Hz \
         or a longer log"
    )]
    TooShortForCutoff { duration_s: f64, cutoff_hz: f64, edge_s: f64, lowest_hz: f64 },
    #[error(transparent)]
    Setting(#[from] SettingError),
    #[error(
        "decimating by {factor} leaves a Nyquist frequency of {nyquist_hz} Hz, not above the {cutoff_hz} Hz cut-off"
    )]
    DecimationAliases { factor: usize, nyquist_hz: f64, cutoff_hz: f64 },
    #[error(transparent)]
    Filter(#[from] FilterError),
}

/// What preprocessing chose, each with its reason, and the choices it is unsure of.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Choices {
    /// Each choice: the value, and whether the user set it or what in the data set it.
    pub reasons: Vec<Choice>,
    /// Choices the data support only weakly (too few periods, bandwidth near the cap, ...).
    pub warnings: Vec<Concern>,
}

/// Preprocessed signals, row-major `samples × dof`, ready for the regressor.
#[derive(Clone, Debug)]
pub struct Preprocessed {
    pub dof: usize,
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
    /// The velocity that switches Coulomb friction, averaged over the periods.
    pub qd_friction: Vec<f64>,
    /// That velocity period by period, from which the Coulomb columns are built.
    pub friction: FrictionVelocity,
    pub tau: Vec<f64>,
    /// The torque averaged over the periods but not filtered: what the model is finally judged
    /// against when the cut-off is chosen ([`super::cutoff`]).
    pub tau_unfiltered: Vec<f64>,
    /// The cut-off actually used (Hz).
    pub cutoff_hz: f64,
    /// The motion's bandwidth read from the positions (Hz), when the cut-off was left to the
    /// data and there is motion above the noise ([`super::data_choices`]).
    pub bandwidth_hz: Option<f64>,
    /// The cut-off of the friction velocity actually used (Hz).
    pub friction_cutoff_hz: f64,
    /// Rate of the signals before decimation (Hz): the log's, or, for a period that is not a
    /// whole number of samples, that of the period resampled to a whole number.
    pub sample_rate_hz: f64,
    /// Periods averaged (1 when not periodic).
    pub periods_averaged: usize,
    /// The period averaged over (s), when periodic.
    pub period_s: Option<f64>,
    /// Butterworth order used.
    pub order: usize,
    /// Whether the signals are one period of a periodic average (filtered circularly).
    pub periodic: bool,
    /// Decimation factor applied after filtering.
    pub decimate: usize,
    /// Whether each joint rests at each sample (`samples × dof`, [`super::resting`]): those rows are
    /// left out of the fit.
    pub resting: Vec<bool>,
    /// The samples clear of the zero-phase filter's start-up transients (all of them for a
    /// periodic average, which is filtered circularly): what identification fits and scores.
    pub settled: std::ops::Range<usize>,
    /// What was chosen, and why.
    pub choices: Choices,
    /// How the log was averaged: how its raw samples map onto these ([`Self::averaging`]).
    averaging: Option<Averaging>,
}

impl Preprocessed {
    pub fn samples(&self) -> usize {
        self.t.len()
    }

    /// `x` (`samples × width`) restricted to the [`Self::settled`] samples.
    pub fn settled_rows<'a, T>(&self, x: &'a [T], width: usize) -> &'a [T] {
        &x[self.settled.start * width..self.settled.end * width]
    }

    /// How the log was averaged over its periods (`None`: not periodic).
    pub fn averaging(&self) -> Option<Averaging> {
        self.averaging
    }

    /// Rate of the preprocessed samples (Hz): the input rate over the decimation factor.
    pub fn rate_hz(&self) -> f64 {
        self.sample_rate_hz / self.decimate as f64
    }

    /// Filter an extra `samples × width` signal exactly as the torque was filtered (circularly for
    /// a periodic average). Decimated data cannot be filtered again at the original rate.
    pub fn filter_like_torque(&self, x: &[f64], width: usize) -> Result<Vec<f64>, FilterError> {
        let filter = Butterworth::lowpass(self.order, self.cutoff_hz, self.rate_hz())?;
        filter_columns(&filter, x, width, self.periodic)
    }

    /// The Coulomb columns (`samples × dof`, joint k's direction in column k), filtered exactly
    /// like the torque: each joint's law of each period's friction velocity, averaged over the periods
    /// ([`FrictionVelocity::directions`]). Identification and the diagnosis both build their
    /// Coulomb columns here.
    pub fn coulomb_columns(&self, laws: &CoulombLaws) -> Vec<f64> {
        self.filter_like_torque(&self.friction.directions(laws), self.dof)
            .expect("the torque was filtered with these settings")
    }
}

/// Check shapes, finiteness and uniform sampling; return the sample period.
pub fn validate_log(t: &[f64], q: &[f64], tau: &[f64], dof: usize) -> Result<f64, PreprocessError> {
    let n = t.len();
    for (name, values) in [("q", q), ("tau", tau)] {
        if values.len() != n * dof {
            return Err(PreprocessError::Shape { name, got: values.len(), expected: n * dof, samples: n, width: dof });
        }
    }
    for (name, values, width) in [("t", t, 1), ("q", q, dof), ("tau", tau, dof)] {
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(PreprocessError::NotFinite { name, sample: i / width });
        }
    }
    if n < 64 {
        return Err(PreprocessError::TooFewSamples { needed: 64, got: n });
    }
    if let Some(i) = t.windows(2).position(|w| w[1] <= w[0]) {
        return Err(PreprocessError::TimeNotIncreasing { index: i + 1, before: t[i], after: t[i + 1] });
    }
    let step = |w: &[f64]| w[1] - w[0];
    // The median of at most MEDIAN_SAMPLES steps spread over the log.
    let mut steps: Vec<f64> = t.windows(2).step_by((n / MEDIAN_SAMPLES).max(1)).map(step).collect();
    let middle = steps.len() / 2;
    let median = *steps.select_nth_unstable_by(middle, f64::total_cmp).1;
    // A fixed-rate stream stamped by its host jitters around the step (the KUKA LWR4+ logs of
    // ../shared/data: ±35 %); a step off by half the median or more is a gap or a reordering.
    // `steps` is reordered by the selection, so the first such step is found in `t` itself.
    let off = |s: f64| (s - median).abs() / median;
    if let Some((index, step)) = t.windows(2).map(step).enumerate().find(|(_, s)| off(*s) >= MAX_JITTER) {
        return Err(PreprocessError::NonUniformTime { index, step, median });
    }
    // The stream's step is the slope of a line through the stamps.
    Ok(super::repair::stamp_line(t).0)
}

/// Time stamps may jitter by less than this share of the step: more is a gap (refused).
pub const MAX_JITTER: f64 = 0.5;

/// Jitter beyond this share of the step is reported among the choices.
const REPORTED_JITTER: f64 = 0.01;

/// The largest deviation of a time step from `dt`, as a share of `dt`.
fn jitter(t: &[f64], dt: f64) -> f64 {
    t.windows(2).map(|w| ((w[1] - w[0]) - dt).abs() / dt).fold(0.0, f64::max)
}

/// A joint spanning fewer encoder steps than this has not moved: what it shows is noise.
pub const STILL_STEPS: f64 = 20.0;

/// Refuse a joint that never moves, and a log in which no joint goes back and forth.
///
/// A joint has not moved when its span is within [`STILL_STEPS`] of its typical second
/// difference (an encoder step, or the noise; a smooth motion's is far smaller). A log shorter than one cycle of every
/// joint's motion (no joint turns back at least [`CYCLE_REVERSALS`] times) holds no period of
/// anything: its Coulomb columns never change sign, and what is fitted is a fragment.
fn check_the_joints_move(q: &[f64], dof: usize, dt: f64) -> Result<(), PreprocessError> {
    let n = q.len() / dof;
    // Row by row, every joint at once: a long log is read twice in order, not twice per joint
    // with a stride.
    let (mut lo, mut hi) = (vec![f64::INFINITY; dof], vec![f64::NEG_INFINITY; dof]);
    for row in q.chunks_exact(dof) {
        for ((l, h), v) in lo.iter_mut().zip(hi.iter_mut()).zip(row) {
            *l = l.min(*v);
            *h = h.max(*v);
        }
    }
    let mut turns: Vec<Reversals> = Vec::with_capacity(dof);
    for joint in 0..dof {
        let at = |i: usize| q[i * dof + joint];
        // The typical change of the change, from at most MEDIAN_SAMPLES of them spread over the
        // log: an encoder step or the noise, whichever shows, but not the motion. (The change
        // itself holds the motion's speed: a pitch swinging ±0.2 rad at 2.6 Hz, logged at 100 Hz,
        // spans only 19 of its median changes and was refused as still.)
        let stride = (n / MEDIAN_SAMPLES).max(1);
        let mut changes: Vec<f64> =
            (2..n).step_by(stride).map(|i| (at(i) - 2.0 * at(i - 1) + at(i - 2)).abs()).filter(|d| *d > 0.0).collect();
        let step = match changes.len() {
            0 => f64::INFINITY,
            len => *changes.select_nth_unstable_by(len / 2, f64::total_cmp).1,
        };
        let span = hi[joint] - lo[joint];
        if span < STILL_STEPS * step || span == 0.0 {
            let steps = if step.is_finite() { span / step } else { 0.0 };
            return Err(PreprocessError::JointStill { joint: joint + 1, span, steps });
        }
        turns.push(Reversals::new(q[joint], (REVERSAL_SHARE * span).max(STILL_STEPS * step)));
    }
    for row in q.chunks_exact(dof).skip(1) {
        turns.iter_mut().zip(row).for_each(|(r, v)| r.push(*v));
    }
    // The joint that turns back most, the first of equals.
    let most =
        turns.iter().enumerate().fold((0, 1), |most, (k, r)| if r.count > most.0 { (r.count, k + 1) } else { most });
    if most.0 < CYCLE_REVERSALS {
        let (reversals, joint) = most;
        return Err(PreprocessError::NoCycle { duration_s: n as f64 * dt, reversals, joint });
    }
    Ok(())
}

/// A joint's typical sample-to-sample change is the median of at most this many.
const MEDIAN_SAMPLES: usize = 20_000;

/// A joint completes a cycle of its motion when it turns back this many times.
pub const CYCLE_REVERSALS: usize = 2;

/// A turn counts when the joint comes back by this share of its span (and by
/// [`STILL_STEPS`] encoder steps at least): less is noise or a hesitation.
const REVERSAL_SHARE: f64 = 0.05;

/// How many times a signal, fed sample by sample, turns back by more than `hysteresis`.
struct Reversals {
    count: usize,
    direction: f64,
    extreme: f64,
    hysteresis: f64,
}

impl Reversals {
    fn new(first: f64, hysteresis: f64) -> Self {
        Self { count: 0, direction: 0.0, extreme: first, hysteresis }
    }

    fn push(&mut self, v: f64) {
        let moved = v - self.extreme;
        if self.direction * moved < 0.0 && moved.abs() > self.hysteresis {
            self.count += 1;
            self.direction = moved.signum();
            self.extreme = v;
        } else if self.direction == 0.0 && moved.abs() > self.hysteresis {
            self.direction = moved.signum();
            self.extreme = v;
        } else if self.direction * moved > 0.0 {
            self.extreme = v;
        }
    }
}

/// Decide whether and over what to average, from the options or the data.
fn choose_periods(
    q: &[f64],
    dof: usize,
    fs: f64,
    periods: Option<usize>,
    period: Option<f64>,
    choices: &mut Choices,
) -> Result<Option<Averaging>, PreprocessError> {
    let n = q.len() / dof;
    if let Some(period_s) = period {
        let samples = period_s * fs;
        let whole = (samples - samples.round()).abs() < 1e-6;
        let samples = if whole { samples.round() } else { samples };
        let count = ((n + super::data_choices::SHORT_BY) as f64 / samples).floor() as usize;
        if count < 2 {
            return Err(PreprocessError::TooFewPeriods { periods: count, period_s });
        }
        choices.reasons.push(Choice::PeriodGiven { count, period_s });
        return Ok(Some(Averaging { count, samples }));
    }
    match periods {
        Some(1) => {
            choices.reasons.push(Choice::NotAveraged);
            Ok(None)
        }
        Some(count) => {
            let per = n / count;
            if per < 2 {
                return Err(PreprocessError::TooFewSamples { needed: 2 * count, got: n });
            }
            let period_s = per as f64 / fs;
            let mismatch = super::data_choices::mismatch_of_columns(q, dof, per);
            choices.reasons.push(Choice::PeriodsGiven { count, period_s });
            if mismatch > PERIODIC_MISMATCH {
                choices.warnings.push(Concern::PeriodsDoNotRepeat { count, mismatch });
            }
            Ok(Some(Averaging { count, samples: per as f64 }))
        }
        None => {
            let search = find_period(q, dof, fs);
            choices.reasons.push(search.reason);
            let Some(period) = search.period else { return Ok(None) };
            let count = period.count;
            if count < 2 {
                choices.warnings.push(Concern::UnderTwoPeriods {
                    period_s: period.samples / fs,
                    periods: n as f64 / period.samples,
                });
                return Ok(None);
            }
            if count < super::data_choices::FEW_PERIODS {
                choices.warnings.push(Concern::FewPeriods { count });
            }
            Ok(Some(Averaging { count, samples: period.samples }))
        }
    }
}

/// The cut-off: the user's, or [`CUTOFF_PER_BANDWIDTH`] times the motion's bandwidth; and that
/// bandwidth (Hz) when it was measured.
///
/// A periodic log's bandwidth is its highest harmonic that repeats from period to period
/// ([`harmonic_bandwidth`]); any other's, the highest frequency above the position noise floor
/// ([`bandwidth`]).
fn choose_cutoff(
    q: &[f64],
    periods: Option<&[Vec<f64>]>,
    dof: usize,
    fs: f64,
    user: Option<f64>,
    choices: &mut Choices,
) -> (f64, Option<f64>) {
    if let Some(cutoff) = user {
        choices.reasons.push(Choice::CutoffGiven { cutoff_hz: cutoff });
        return (cutoff, None);
    }
    let cap = fs / 4.0;
    let periodic = periods.is_some();
    let samples = match periods {
        Some(periods) => periods.first().map_or(0, Vec::len) / dof.max(1),
        None => q.len() / dof.max(1),
    };
    let floor = lowest_cutoff_hz(samples, fs, periodic);
    let found = match periods {
        Some(periods) => harmonic_bandwidth(periods, dof, fs),
        None => bandwidth(q, dof, fs, false),
    };
    let Some(signal) = found else {
        choices.reasons.push(Choice::CutoffNoMotion { cutoff_hz: floor });
        return (floor, None);
    };
    let wanted = CUTOFF_PER_BANDWIDTH * signal;
    let cutoff = wanted.max(floor).min(cap);
    choices.reasons.push(Choice::CutoffFromSpectrum {
        cutoff_hz: cutoff,
        signal_hz: signal,
        factor: CUTOFF_PER_BANDWIDTH,
        periodic,
        lowest_hz: (wanted < floor).then_some(floor),
    });
    if wanted > cap {
        choices.warnings.push(Concern::CutoffCapped {
            signal_hz: signal,
            factor: CUTOFF_PER_BANDWIDTH,
            sample_rate_hz: fs,
            cap_hz: cap,
        });
    }
    (cutoff, Some(signal))
}

/// Run the whole pipeline on a log (`t`: N; `q`, `tau`: N × dof, row-major).
pub fn preprocess(
    t: &[f64],
    q: &[f64],
    tau: &[f64],
    dof: usize,
    options: &PreprocessOptions,
) -> Result<Preprocessed, PreprocessError> {
    Conditioned::of(t, q, tau, dof, options)?.at_cutoff(options)
}

/// What preprocessing reads from a log before it filters anything, which no cut-off changes:
/// the checks, the periods and their means, the resting samples and the raw friction velocity.
/// A cut-off search preprocesses one log at a dozen cut-offs; on the 300 s bench log these were
/// most of each.
pub(super) struct Conditioned<'a> {
    t0: f64,
    dof: usize,
    /// The log's sample period, and the one after a period's resampling to whole samples.
    raw_dt: f64,
    dt: f64,
    averaging: Option<Averaging>,
    raw_q: &'a [f64],
    /// Positions and torque: the periods' means, or the log's own.
    q: Cow<'a, [f64]>,
    tau: Cow<'a, [f64]>,
    raw_velocity: RawVelocity,
    resting: Vec<bool>,
    /// The options it was read with, which [`Self::at_cutoff`] must share but for the cut-offs.
    periods: (Option<usize>, Option<f64>),
    decimate: usize,
    leave_out_rests: bool,
    choices: Choices,
}

impl<'a> Conditioned<'a> {
    /// Check the log and read what `options` ask of it, whatever the cut-offs.
    pub(super) fn of(
        t: &[f64],
        q: &'a [f64],
        tau: &'a [f64],
        dof: usize,
        options: &PreprocessOptions,
    ) -> Result<Self, PreprocessError> {
        let raw_dt = validate_log(t, q, tau, dof)?;
        options.validate()?;
        let mut choices = Choices::default();
        let shake = jitter(t, raw_dt);
        if shake > REPORTED_JITTER {
            choices.reasons.push(Choice::Jitter { share: shake, rate_hz: 1.0 / raw_dt });
        }
        // Both read the whole log and neither needs the other; a joint that does not move is still
        // the first thing said.
        let (moves, averaging) = std::thread::scope(|scope| {
            let moves = scope.spawn(|| check_the_joints_move(q, dof, raw_dt));
            let averaging = choose_periods(q, dof, 1.0 / raw_dt, options.periods, options.period_s, &mut choices);
            (moves.join().expect("the check does not panic"), averaging)
        });
        moves?;
        let averaging = averaging?;
        // A period that is not a whole number of samples is resampled to the nearest whole number.
        let dt = averaging.map_or(raw_dt, |a| raw_dt * a.samples / a.per() as f64);
        let positions = || {
            let q_avg = averaged(q, dof, averaging);
            let resting = match options.leave_out_rests {
                true => super::resting::resting(q, dof, averaging, raw_dt, options.decimate),
                false => vec![false; (q_avg.len() / dof).div_ceil(options.decimate) * dof],
            };
            (q_avg, resting)
        };
        let torque_and_velocity = || (averaged(tau, dof, averaging), RawVelocity::of_log(q, dof, averaging, dt));
        // Independent, and on two cores they take the time of the longer one.
        let ((q_avg, resting), (tau_avg, raw_velocity)) = std::thread::scope(|scope| {
            let other = scope.spawn(torque_and_velocity);
            (positions(), other.join().expect("averaging does not panic"))
        });
        Ok(Self {
            t0: t[0],
            dof,
            raw_dt,
            dt,
            averaging,
            raw_q: q,
            q: q_avg,
            tau: tau_avg,
            raw_velocity,
            resting,
            periods: (options.periods, options.period_s),
            decimate: options.decimate,
            leave_out_rests: options.leave_out_rests,
            choices,
        })
    }

    /// The central difference of the raw positions, arranged as the log was averaged: what a
    /// friction velocity at any cut-off is filtered from ([`RawVelocity::filtered`]).
    pub(super) fn raw_velocity(&self) -> &RawVelocity {
        &self.raw_velocity
    }

    /// The log filtered at the cut-offs of `options`, whose other settings must be those it was
    /// read with.
    pub(super) fn at_cutoff(&self, options: &PreprocessOptions) -> Result<Preprocessed, PreprocessError> {
        debug_assert!(
            (options.periods, options.period_s, options.decimate, options.leave_out_rests)
                == (self.periods.0, self.periods.1, self.decimate, self.leave_out_rests),
            "a log conditioned with other settings"
        );
        let (dof, dt, averaging) = (self.dof, self.dt, self.averaging);
        let mut choices = self.choices.clone();
        let periodic = averaging.is_some();
        let fs = 1.0 / dt;
        let cutoff = match averaging {
            // The periods one by one only where the spectral rule reads their scatter.
            Some(a) => match options.cutoff_hz {
                Some(_) => choose_cutoff(&[], None, dof, fs, options.cutoff_hz, &mut choices),
                None => choose_cutoff(&[], Some(&periods_of(self.raw_q, dof, a)), dof, fs, None, &mut choices),
            },
            None => choose_cutoff(&self.q, None, dof, fs, options.cutoff_hz, &mut choices),
        };
        let (cutoff_hz, bandwidth_hz) = cutoff;
        let q = &self.q;
        let n = q.len() / dof;
        let filter = Butterworth::lowpass(options.order, cutoff_hz, fs)?;
        let decimated_nyquist = 0.5 * fs / options.decimate as f64;
        if cutoff_hz >= decimated_nyquist {
            return Err(PreprocessError::DecimationAliases {
                factor: options.decimate,
                nyquist_hz: decimated_nyquist,
                cutoff_hz,
            });
        }
        let edge = match periodic {
            true => 0,
            false => (EDGE_CUTOFF_PERIODS * fs / cutoff_hz).ceil() as usize,
        };
        if 4 * edge > n {
            return Err(PreprocessError::TooShortForCutoff {
                duration_s: n as f64 * dt,
                cutoff_hz,
                edge_s: edge as f64 * dt,
                lowest_hz: edge_limited_cutoff_hz(n, fs, false),
            });
        }
        if edge > 0 {
            choices
                .reasons
                .push(Choice::EdgesLeftOut { edge_s: edge as f64 * dt, cutoff_periods: EDGE_CUTOFF_PERIODS });
        }
        // Decimated indices whose samples lie at least `edge` samples from either end.
        let settled = edge.div_ceil(options.decimate)..(n - edge).div_ceil(options.decimate);
        let friction_cutoff_hz = friction_cutoff_hz(options.friction_cutoff_hz, cutoff_hz, fs);
        choices.reasons.push(Choice::FrictionCutoff {
            cutoff_hz: friction_cutoff_hz,
            given: options.friction_cutoff_hz.is_some(),
            at_most_quarter: true,
        });
        let torque_and_friction = || -> Result<_, FilterError> {
            let tau_f = filter_columns(&filter, &self.tau, dof, periodic)?;
            let friction = self.raw_velocity.filtered(options.order, friction_cutoff_hz, options.decimate)?;
            Ok((tau_f, friction))
        };
        // The two chains are independent; on two cores they take the time of the longer one.
        let (motion, other) = std::thread::scope(|scope| {
            let other = scope.spawn(torque_and_friction);
            (
                filtered_motion(&filter, q, dof, dt, periodic, options.filter_derivatives),
                other.join().expect("filtering does not panic"),
            )
        });
        let ((q_f, qd, qdd), (tau_f, friction)) = (motion?, other?);
        let keep = |x: &[f64]| every_nth_row(x, dof, options.decimate);
        choices.reasons.extend(super::resting::explain(&self.resting, dof, settled.clone(), self.raw_dt));
        let t_out: Vec<f64> = (0..n).step_by(options.decimate).map(|i| self.t0 + i as f64 * dt).collect();
        Ok(Preprocessed {
            dof,
            t: t_out,
            q: keep(&q_f),
            qd: keep(&qd),
            qdd: keep(&qdd),
            qd_friction: friction.mean(),
            friction,
            tau: keep(&tau_f),
            tau_unfiltered: keep(&self.tau),
            cutoff_hz,
            bandwidth_hz,
            friction_cutoff_hz,
            sample_rate_hz: fs,
            periods_averaged: averaging.map_or(1, |a| a.count),
            period_s: averaging.map(|a| a.per() as f64 * dt),
            order: options.order,
            periodic,
            decimate: options.decimate,
            resting: self.resting.clone(),
            settled,
            choices,
            averaging,
        })
    }
}

/// Positions, velocities and accelerations, each `samples × dof`.
pub(super) type Motion = (Vec<f64>, Vec<f64>, Vec<f64>);

/// Positions filtered by `filter`, and their velocity and acceleration by central differences
/// of step `dt` (each filtered again when `filter_derivatives`, the paper's method).
pub(super) fn filtered_motion(
    filter: &Butterworth,
    q: &[f64],
    dof: usize,
    dt: f64,
    periodic: bool,
    filter_derivatives: bool,
) -> Result<Motion, FilterError> {
    let q_f = filter_columns(filter, q, dof, periodic)?;
    let derivative = |x: &[f64]| -> Result<Vec<f64>, FilterError> {
        let d = central_difference(x, dof, dt, periodic);
        match filter_derivatives {
            true => filter_columns(filter, &d, dof, periodic),
            false => Ok(d),
        }
    };
    let qd = derivative(&q_f)?;
    let qdd = derivative(&qd)?;
    Ok((q_f, qd, qdd))
}

/// The friction velocity's cut-off: the user's, at most a quarter of the sample rate, or the
/// main cut-off.
pub fn friction_cutoff_hz(user: Option<f64>, cutoff_hz: f64, fs: f64) -> f64 {
    user.map_or(cutoff_hz, |f| f.min(0.25 * fs))
}

/// The cut-off over the highest frequency of the motion: the filter then passes the motion's
/// harmonics, and the products of two of them that the dynamics make, with a phase-free
/// (forward–backward) gain near one.
pub const CUTOFF_PER_BANDWIDTH: f64 = 5.0;

/// The lowest cut-off chosen from the data (Hz).
pub const MIN_CUTOFF_HZ: f64 = 1.0;

/// Samples within this many cut-off periods of either end of a log that is not periodic are left
/// out: a zero-phase Butterworth started from an odd extension of the log rings there, and the
/// two differences amplify it. On a smooth motion filtered at 1–20 Hz the error of q̈ there falls
/// from about the motion's RMS at the end to under 1 % of it at 5 periods (docs/identification.md).
pub const EDGE_CUTOFF_PERIODS: f64 = 5.0;

/// The lowest cut-off the spectral rule chooses for a log of `samples` at `fs`:
/// [`MIN_CUTOFF_HZ`], or the [`edge_limited_cutoff_hz`] when higher.
pub fn lowest_cutoff_hz(samples: usize, fs: f64, periodic: bool) -> f64 {
    MIN_CUTOFF_HZ.max(edge_limited_cutoff_hz(samples, fs, periodic))
}

/// The lowest cut-off at which the filter's end transients ([`EDGE_CUTOFF_PERIODS`]) take at most
/// a quarter of a log that is not periodic at each end (Hz); 0 for a periodic one, which has no
/// ends.
pub fn edge_limited_cutoff_hz(samples: usize, fs: f64, periodic: bool) -> f64 {
    match periodic {
        true => 0.0,
        false => 4.0 * EDGE_CUTOFF_PERIODS * fs / samples.saturating_sub(4).max(1) as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three joints, sum of harmonics of a 15 s period, sampled at 1 kHz.
    fn periodic_log(periods: usize, noise: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let (fs, period) = (1000.0, 15.0);
        let n = (fs * period) as usize * periods;
        let w = 2.0 * std::f64::consts::PI / period;
        let mut state = 12345u64;
        let mut noise_sample = move || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * noise
        };
        let t: Vec<f64> = (0..n).map(|i| i as f64 / fs).collect();
        let mut q = Vec::with_capacity(3 * n);
        let mut tau = Vec::with_capacity(3 * n);
        for &ti in &t {
            for j in 0..3 {
                let a = 0.3 * (w * ti + j as f64).sin() + 0.1 * (3.0 * w * ti).cos();
                q.push(a + noise_sample());
                tau.push(2.0 * a + noise_sample());
            }
        }
        (t, q, tau)
    }

    /// Worst error of q̇ and q̈ after preprocessing, relative to their amplitudes.
    fn derivative_error(noise: f64) -> f64 {
        let (t, q, tau) = periodic_log(4, noise);
        let options = PreprocessOptions { periods: Some(4), ..Default::default() };
        let out = preprocess(&t, &q, &tau, 3, &options).unwrap();
        assert_eq!(out.samples(), 15_000);
        assert_eq!(out.periods_averaged, 4);
        let w = 2.0 * std::f64::consts::PI / 15.0;
        // Highest harmonic 3w/2π = 0.2 Hz, so the bandwidth rule gives 1 Hz (its floor).
        assert!((out.cutoff_hz - 1.0).abs() < 1e-12, "cut-off {}", out.cutoff_hz);
        let mut worst: f64 = 0.0;
        for (k, &ti) in out.t.iter().enumerate() {
            for j in 0..3 {
                let qd = 0.3 * w * (w * ti + j as f64).cos() - 0.3 * w * (3.0 * w * ti).sin();
                let qdd = -0.3 * w * w * (w * ti + j as f64).sin() - 0.9 * w * w * (3.0 * w * ti).cos();
                worst = worst.max((out.qd[k * 3 + j] - qd).abs() / 0.1).max((out.qdd[k * 3 + j] - qdd).abs() / 0.05);
            }
        }
        worst
    }

    /// A cut-off search filters one conditioned log at many cut-offs: each must be what
    /// preprocessing the log at that cut-off gives, whatever cut-offs the log was read with and
    /// whatever was filtered before it.
    #[test]
    fn a_log_conditioned_once_filters_at_each_cut_off_as_preprocessing_does() {
        let (t, q, tau) = periodic_log(4, 1e-4);
        let options = PreprocessOptions { period_s: Some(15.0), periods: Some(1), ..Default::default() };
        // Read with cut-offs of its own, which none of the filtered logs below may keep.
        let read_at = PreprocessOptions { cutoff_hz: Some(5.0), friction_cutoff_hz: Some(3.0), ..options.clone() };
        let conditioned = Conditioned::of(&t, &q, &tau, 3, &read_at).unwrap();
        for (cutoff_hz, friction_cutoff_hz) in [(2.0, None), (0.7, Some(9.0)), (2.0, None)] {
            let at = PreprocessOptions { cutoff_hz: Some(cutoff_hz), friction_cutoff_hz, ..options.clone() };
            let (once, each) = (conditioned.at_cutoff(&at).unwrap(), preprocess(&t, &q, &tau, 3, &at).unwrap());
            assert_eq!(
                (once.periods_averaged, once.cutoff_hz, once.friction_cutoff_hz),
                (4, cutoff_hz, each.friction_cutoff_hz)
            );
            for (a, b) in [(&once.q, &each.q), (&once.qd, &each.qd), (&once.qdd, &each.qdd), (&once.tau, &each.tau)] {
                assert_eq!(a, b, "at {cutoff_hz} Hz");
            }
            assert_eq!(
                (&once.qd_friction, &once.resting, &once.choices),
                (&each.qd_friction, &each.resting, &each.choices)
            );
        }
    }

    #[test]
    fn periodic_pipeline_recovers_derivatives_of_a_known_signal() {
        // Noise-free: only filter attenuation and the O(h²) difference error remain.
        let clean = derivative_error(0.0);
        assert!(clean < 1e-5, "relative derivative error {clean}");
        // Encoder-sized noise (±0.1 mrad) survives two differentiations only attenuated.
        let noisy = derivative_error(1e-4);
        assert!(noisy < 5e-3, "relative derivative error with noise {noisy}");
    }

    #[test]
    fn bad_logs_are_refused_by_name() {
        let (t, q, tau) = periodic_log(2, 0.0);
        let err = |r: Result<Preprocessed, PreprocessError>| r.unwrap_err().to_string();
        let opts = PreprocessOptions::default();
        assert!(err(preprocess(&t, &q[..q.len() - 3], &tau, 3, &opts)).contains("q has"));
        let mut bad = q.clone();
        bad[300] = f64::NAN;
        assert!(err(preprocess(&t, &bad, &tau, 3, &opts)).contains("q is not finite at sample 100"));
        let mut jumpy = t.clone();
        jumpy[500..].iter_mut().for_each(|x| *x += 0.01);
        assert!(err(preprocess(&jumpy, &q, &tau, 3, &opts)).contains("step 499"));
        // Host-stamped jitter of up to 40 % of the step, without a gap, is a uniform stream.
        let shaky: Vec<f64> =
            t.iter().enumerate().map(|(i, x)| x + 2e-4 * ((i * 7919 % 13) as f64 / 6.0 - 1.0)).collect();
        let out = preprocess(&shaky, &q, &tau, 3, &opts).unwrap();
        assert!(out.choices.reasons.iter().any(|r| matches!(r, Choice::Jitter { .. })), "{:?}", out.choices.reasons);
        assert!((out.sample_rate_hz - 1000.0).abs() < 1e-3, "{}", out.sample_rate_hz);
        let zero = PreprocessOptions { periods: Some(0), ..Default::default() };
        assert!(err(preprocess(&t, &q, &tau, 3, &zero)).contains("periods = 0 cannot be used"));
        let mut repeated = t.clone();
        repeated[700] = repeated[699];
        assert!(err(preprocess(&repeated, &q, &tau, 3, &opts)).contains("t does not increase at sample 700"));
        let mut still = q.clone();
        still.chunks_mut(3).for_each(|row| row[1] = 0.25);
        assert!(err(preprocess(&t, &still, &tau, 3, &opts)).contains("joint 2 never moves"));
        // A second of a 15 s motion: no joint goes back and forth.
        let refused = err(preprocess(&t[..1000], &q[..3000], &tau[..3000], 3, &opts));
        assert!(refused.contains("1.00 s long and holds no cycle"), "{refused}");
    }
}
