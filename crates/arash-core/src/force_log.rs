//! The hand's force over a whole log, offline: what `arash force` and `arash.external_force`
//! return. The momentum observer runs over the samples, the estimate is mapped to a frame, each
//! sample carries the σ the model's held-out data gives it, and thresholds tell contact from
//! collision (`docs/force.md`).
//!
//! The choices it makes when not told are made here, each with its reason:
//! - the observer's bandwidth and σ per joint are those measured on the model's held-out runs
//!   ([`observer_held_out`]): at least ten times the hand's band so that it follows a hand
//!   ([`HAND_BAND_HZ`], [`BANDWIDTH_PER_HAND_BAND`]), wider while the estimate's hand-free RMS
//!   stays within [`NOISE_ALLOWANCE`] of its value there. A model file that records no observer
//!   run gets a quarter of the band its σ was measured in ([`BAND_PER_BANDWIDTH`]), so that the
//!   σ it carries still describes it; bare parameters get the hand's least bandwidth;
//! - without a measured velocity, `q̇` is the central difference of `q` filtered zero-phase
//!   with the model's filter, at the model's band or the observer's bandwidth
//!   ([`VELOCITY_BAND_PER_BANDWIDTH`]), whichever is wider;
//! - the Coulomb terms switch with the model's own law where it has one: offline the velocity is
//!   filtered without lag, so the law the model was fitted with holds, where the controllers
//!   widen it against a noisy velocity;
//! - currents become torques through the drive gains the model was calibrated with.

use crate::choices::ForceChoice;
use crate::control::gains::{compensation_epsilon, model_epsilon, RobustGains};
use crate::force::{
    episodes, Episode, FrameForce, Level, MomentumObserver, ObserverError, ThresholdError, Thresholds, TorqueTiming,
};
use crate::model::{Model, UnknownFrame};
use crate::model_file::{ModelFile, ObserverHeldOut};
use crate::signal::conditioning::{central_difference, filter_columns};
use crate::signal::filter::{Butterworth, FilterError};
use crate::signal::log::Log;

use crate::force::settings::HAND_BANDWIDTH;
pub use crate::force::settings::{
    bandwidth_grid, default_bandwidth, default_frame, held_out_sigma, sigma_thresholds, FrameChoice, BANDWIDTH_GRID,
    BANDWIDTH_PER_HAND_BAND, BAND_PER_BANDWIDTH, HAND_BAND_HZ, NOISE_ALLOWANCE, PEAK_MARGIN,
};

/// The velocity filter's band over the observer's bandwidth. The momentum path differentiates
/// `M q̇`, so the velocity's noise (an encoder's steps) reaches the estimate amplified by `K`
/// above the bandwidth; a zero-phase filter at the bandwidth itself removes it there without
/// lag, and a hand's force, ten times slower, passes unchanged. On the demo's held-out runs at
/// 20 Hz, a filter at 4× the bandwidth doubles the yaw's and pitch's hand-free RMS and cuts the
/// insertion's by a third (docs/force.md).
pub const VELOCITY_BAND_PER_BANDWIDTH: f64 = 1.0;

/// A zero-phase estimate's band over the hand's ([`HAND_BAND_HZ`]): 5 Hz. Offline nothing forces
/// the estimate to be causal, so its lag can go and its band can shrink to the force's: the
/// model's Butterworth at 2.5 times the hand's band passes a 2 Hz force unchanged (fourth order:
/// within 0.1 %) and a press's rise of 0.2 s, and stops what a hand does not make, the encoder's
/// steps through the momentum path and the friction laws above all (on the demo's yaw, 60 % of
/// the causal estimate's error lies above 3 Hz).
pub const ZERO_PHASE_BAND_PER_HAND_BAND: f64 = 2.5;

/// A zero-phase estimate's velocity band over its own band: twice it (10 Hz). The friction laws
/// and `Cᵀq̇` are nonlinear in `q̇`, so velocity noise above the estimate's band folds down into
/// it, through the Coulomb switch near reversals above all; the dynamics the estimate keeps need
/// `q̇` only up to its band, and an octave above keeps the filter's edge out of it.
pub const ZERO_PHASE_VELOCITY_PER_BAND: f64 = 2.0;

/// A zero-phase estimate's band (Hz).
pub const ZERO_PHASE_BAND_HZ: f64 = HAND_BAND_HZ * ZERO_PHASE_BAND_PER_HAND_BAND;

/// Why a log's force could not be estimated.
#[derive(Debug, thiserror::Error)]
pub enum ForceLogError {
    #[error(transparent)]
    Observer(#[from] ObserverError),
    #[error(transparent)]
    Frame(#[from] UnknownFrame),
    #[error(transparent)]
    Thresholds(#[from] ThresholdError),
    #[error("filtering q to differentiate it: {0}")]
    Filter(#[from] FilterError),
    #[error("{0}")]
    Input(String),
}

/// How the effort column of a log is read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Effort {
    /// Joint torques (N·m, N).
    Torque,
    /// Motor currents (A), turned into torques by the model's drive gains.
    Current,
}

/// Where the thresholds come from.
#[derive(Clone, Debug, PartialEq)]
pub enum ThresholdChoice {
    /// No detection.
    None,
    /// `contact` and `collision` times each joint's σ.
    Sigma { contact: f64, collision: f64 },
    /// Per joint, by hand (N·m, N).
    ByHand { contact: Vec<f64>, collision: Vec<f64> },
}

/// What an offline estimate is made with; `None` fields are chosen from the model.
#[derive(Clone, Debug)]
pub struct ForceLogOptions {
    /// The observer's bandwidth per joint (Hz).
    pub bandwidth_hz: Option<Vec<f64>>,
    /// The Coulomb terms' switching velocity per joint.
    pub epsilon: Option<Vec<f64>>,
    /// Each joint's σ of the estimate (N·m, N).
    pub sigma: Option<Vec<f64>>,
    /// The frame the force is mapped to, and the frame its moment is taken about.
    pub frame: Option<FrameChoice>,
    /// The smallest lever the joints must give the frame's origin in every direction (m).
    pub min_lever_m: f64,
    pub timing: TorqueTiming,
    pub effort: Effort,
    pub thresholds: ThresholdChoice,
    /// Offline only: the estimate without lag and in the hand's band ([`ZERO_PHASE_BAND_HZ`]):
    /// the observer's first-order lag undone by the same lag run backward over the log, then
    /// the model's Butterworth forward and backward. The levels, and so contacts and
    /// collisions, stay the causal observer's: what the rig would have flagged, and when.
    pub zero_phase: bool,
}

impl Default for ForceLogOptions {
    fn default() -> Self {
        Self {
            bandwidth_hz: None,
            epsilon: None,
            sigma: None,
            frame: None,
            min_lever_m: 1e-3,
            timing: TorqueTiming::Sampled,
            effort: Effort::Torque,
            thresholds: ThresholdChoice::None,
            zero_phase: false,
        }
    }
}

/// The estimate over a log, each series row-major (samples × width).
#[derive(Clone, Debug, Default)]
pub struct ForceLog {
    /// The external joint torque (N·m, N), samples × dof.
    pub tau_ext: Vec<f64>,
    /// Each joint's σ of it.
    pub sigma_joint: Vec<f64>,
    /// The observer's bandwidth per joint (Hz).
    pub bandwidth_hz: Vec<f64>,
    /// At the frame, samples × 3: the force (N) in the base frame and in the frame's axes, its
    /// moment about the `about` frame (N·m), and one σ per base-frame axis; empty without a frame.
    pub force: Vec<f64>,
    pub local: Vec<f64>,
    pub moment: Vec<f64>,
    pub sigma: Vec<f64>,
    /// Per sample, whether the joints cannot resolve the force at the frame.
    pub singular: Vec<bool>,
    /// The frame the force is at and the one its moment is about, as used.
    pub frame: Option<(String, String)>,
    /// With thresholds: each sample's level, the thresholds, and the episodes found.
    pub levels: Vec<Level>,
    pub thresholds: Option<Thresholds>,
    pub episodes: Vec<Episode>,
    /// What chose each value that was not given.
    pub reasons: Vec<ForceChoice>,
}

/// A log: times (s), positions, the applied effort and, if measured, velocities (row-major,
/// samples × dof).
#[derive(Clone, Copy, Debug)]
pub struct ForceInput<'a> {
    pub t: &'a [f64],
    pub q: &'a [f64],
    pub qd: Option<&'a [f64]>,
    pub effort: &'a [f64],
}

/// The parameters the observer runs on: a model file (its parameters, effects, band, σ and drive
/// gains), or bare parameters π (the CAD's, say) with nothing measured about them.
#[derive(Clone, Copy, Debug)]
pub enum Source<'a> {
    File(&'a ModelFile),
    Params(&'a [f64]),
}

/// The hand's force over the log `input` of `model` on `source`.
pub fn estimate_force(
    model: &Model,
    source: Source<'_>,
    input: ForceInput<'_>,
    options: &ForceLogOptions,
) -> Result<ForceLog, ForceLogError> {
    let n = model.dof();
    let samples = check_input(&input, n)?;
    let file = match source {
        Source::File(f) => Some(f),
        Source::Params(_) => None,
    };
    let model = match file {
        Some(f) => f.with_its_law(model),
        None => std::borrow::Cow::Borrowed(model),
    };
    let mut reasons = Vec::new();
    let rate = (samples - 1) as f64 / (input.t[samples - 1] - input.t[0]);
    let bandwidth = bandwidth_of(file, options, rate, n, &mut reasons)?;
    let sigma = sigma_of(file, options, n, &mut reasons)?;
    let thresholds =
        match &options.thresholds {
            ThresholdChoice::None => None,
            ThresholdChoice::Sigma { contact, collision } => match sigma.iter().all(|s| *s == 0.0) {
                true => return Err(ForceLogError::Input(
                    "thresholds at multiples of σ need a σ per joint: the model has no held-out residual statistics \
                     (identify with validation runs, or diagnose), and no σ was given; or set the thresholds by hand \
                     in N·m and N"
                        .into(),
                )),
                false => {
                    // The held-out peak belongs with the model's own σ, not with one given.
                    let held_out = file.and_then(|f| f.held_out.as_ref()).filter(|_| options.sigma.is_none());
                    let (t, why) = sigma_thresholds(&sigma, *contact, *collision, held_out)?;
                    reasons.extend(why);
                    Some(t)
                }
            },
            ThresholdChoice::ByHand { contact, collision } => Some(Thresholds::by_hand(contact, collision, n)?),
        };
    let tau = torques_of(file, &input, options.effort, n)?;
    let qd = match input.qd {
        Some(qd) => std::borrow::Cow::Borrowed(qd),
        None => std::borrow::Cow::Owned(velocity_of(file, &input, &bandwidth, options.zero_phase, &mut reasons)?),
    };
    let (pi, effects) = match source {
        Source::File(f) => (f.full_or_base_vector(), f.effects.clone()),
        Source::Params(p) => (p.to_vec(), Vec::new()),
    };
    let epsilon = match &options.epsilon {
        Some(e) => e.clone(),
        None => epsilon_of(&model, &mut reasons),
    };
    let mut observer = MomentumObserver::new(&model, &pi, &effects, &bandwidth, &epsilon, options.timing)?;
    let frame = options.frame.as_ref().map(|c| {
        let base = || model.frames[0].name.clone();
        (c.frame.clone(), c.about.clone().unwrap_or_else(base))
    });
    // Built before the observer runs, so that an unknown frame is refused at once.
    let mut map = match &frame {
        Some((frame, about)) => Some(FrameForce::new(&model, frame, about, options.min_lever_m)?),
        None => None,
    };
    let mut out = ForceLog { tau_ext: vec![0.0; samples * n], frame, ..Default::default() };
    for i in 0..samples {
        let rows = i * n..(i + 1) * n;
        // The first sample primes the observer; its step length is never used.
        let dt = if i == 0 { 1.0 } else { input.t[i] - input.t[i - 1] };
        let estimate = observer.step(dt, &input.q[rows.clone()], &qd[rows.clone()], &tau[rows.clone()])?;
        out.tau_ext[rows].copy_from_slice(estimate);
        if let Some(t) = &thresholds {
            out.levels.push(t.level(estimate));
        }
    }
    if options.zero_phase {
        out.tau_ext = zero_phase(&out.tau_ext, input.t, &bandwidth, file, &mut reasons)?;
    }
    if let Some(map) = map.as_mut() {
        for (q, estimate) in input.q.chunks(n).zip(out.tau_ext.chunks(n)) {
            let s = map.map(q, estimate, &sigma);
            out.force.extend_from_slice(&s.force);
            out.local.extend_from_slice(&s.local);
            out.moment.extend_from_slice(&s.moment);
            out.sigma.extend_from_slice(&s.sigma);
            out.singular.push(s.singular);
        }
    }
    out.episodes = episodes(&out.levels);
    out.thresholds = thresholds;
    out.sigma_joint = sigma;
    out.bandwidth_hz = bandwidth;
    out.reasons = reasons;
    Ok(out)
}

/// Each joint's Coulomb width: the model's own law where it has one (the velocity offline has no
/// noise a sign would chatter on), else the robust controller's ε (the paper's where it has gains
/// for the robot, the joint kinds' default elsewhere).
fn epsilon_of(model: &Model, reasons: &mut Vec<ForceChoice>) -> Vec<f64> {
    let paper = RobustGains::paper(model).map(|g| g.epsilon);
    let controller = compensation_epsilon(model, &paper.unwrap_or_else(|_| model_epsilon(model)));
    let own: Vec<Option<f64>> = (0..model.dof()).map(|k| model.coulomb_laws.shape(k).epsilon()).collect();
    if own.iter().any(Option::is_none) {
        reasons.push(ForceChoice::TanhForSign);
    }
    own.iter().zip(controller).map(|(o, c)| o.unwrap_or(c)).collect()
}

/// The sample count, once every array has the shape of `t` and is finite, and `t` increases.
fn check_input(input: &ForceInput<'_>, n: usize) -> Result<usize, ForceLogError> {
    let samples = input.t.len();
    let arrays = [("q", Some(input.q)), ("the velocity", input.qd), ("the effort", Some(input.effort))];
    for (name, values) in arrays.iter().filter_map(|(name, v)| v.map(|v| (name, v))) {
        if values.len() != samples * n {
            return Err(ForceLogError::Input(format!(
                "{name} has {} values; {samples} samples of {n} joints need {}",
                values.len(),
                samples * n
            )));
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(ForceLogError::Input(format!("{name} is not finite at sample {} (joint {})", i / n, i % n)));
        }
    }
    if let Some(i) = input.t.iter().position(|v| !v.is_finite()) {
        return Err(ForceLogError::Input(format!("t is not finite at sample {i}")));
    }
    if samples < 2 {
        return Err(ForceLogError::Input(format!("the log has {samples} samples; the observer needs two or more")));
    }
    if let Some(i) = input.t.windows(2).position(|w| w[1] <= w[0]) {
        return Err(ForceLogError::Input(format!("t does not increase at sample {}", i + 1)));
    }
    Ok(samples)
}

/// The bandwidth given, or the band the model's σ was measured in.
fn bandwidth_of(
    file: Option<&ModelFile>,
    options: &ForceLogOptions,
    rate: f64,
    n: usize,
    reasons: &mut Vec<ForceChoice>,
) -> Result<Vec<f64>, ForceLogError> {
    if let Some(b) = &options.bandwidth_hz {
        return Ok(b.clone());
    }
    let held_out = file.and_then(|f| f.held_out.as_ref());
    let (hz, why) = default_bandwidth(held_out, file.map(|f| f.settings.cutoff_hz), rate, n);
    reasons.push(why);
    Ok(hz)
}

/// The σ given, or the model's held-out residual RMS, or none.
fn sigma_of(
    file: Option<&ModelFile>,
    options: &ForceLogOptions,
    n: usize,
    reasons: &mut Vec<ForceChoice>,
) -> Result<Vec<f64>, ForceLogError> {
    match (&options.sigma, file.and_then(|f| f.held_out.as_ref())) {
        (Some(s), _) if s.len() != n => {
            Err(ForceLogError::Input(format!("σ has {} entries; the robot has {n} joints", s.len())))
        }
        (Some(s), _) => Ok(s.clone()),
        (None, Some(h)) => {
            let (sigma, why) = held_out_sigma(h);
            reasons.push(why);
            Ok(sigma)
        }
        (None, None) => Ok(vec![0.0; n]),
    }
}

/// The applied torque: the effort as given, or currents times the model's drive gains.
fn torques_of<'a>(
    file: Option<&ModelFile>,
    input: &ForceInput<'a>,
    effort: Effort,
    n: usize,
) -> Result<std::borrow::Cow<'a, [f64]>, ForceLogError> {
    if effort == Effort::Torque {
        return Ok(std::borrow::Cow::Borrowed(input.effort));
    }
    let Some(gains) = file.and_then(|f| f.drive_gains.as_ref()) else {
        return Err(ForceLogError::Input(
            "the log holds currents, and the model has no drive gains to turn them into torques: calibrate them \
             with a known load (`arash identify --load`)"
                .into(),
        ));
    };
    Ok(input.effort.iter().enumerate().map(|(i, c)| c * gains.gains[i % n]).collect())
}

/// The causal estimate `tau_ext` (samples × dof) made zero-phase ([`ForceLogOptions::zero_phase`]):
/// each joint's first-order lag at its `bandwidth_hz` run backward in time (the pair is the
/// lag's squared magnitude and no phase), then the model's Butterworth at [`ZERO_PHASE_BAND_HZ`]
/// forward and backward (order 4 with bare parameters).
fn zero_phase(
    tau_ext: &[f64],
    t: &[f64],
    bandwidth_hz: &[f64],
    file: Option<&ModelFile>,
    reasons: &mut Vec<ForceChoice>,
) -> Result<Vec<f64>, ForceLogError> {
    let n = bandwidth_hz.len();
    let mut back = tau_ext.to_vec();
    for i in (0..t.len() - 1).rev() {
        for k in 0..n {
            let alpha = -(-std::f64::consts::TAU * bandwidth_hz[k] * (t[i + 1] - t[i])).exp_m1();
            let later = back[(i + 1) * n + k];
            back[i * n + k] = later + alpha * (tau_ext[i * n + k] - later);
        }
    }
    let rate = (t.len() - 1) as f64 / (t[t.len() - 1] - t[0]);
    let order = file.map_or(4, |f| f.settings.order);
    let filter = Butterworth::lowpass(order, ZERO_PHASE_BAND_HZ.min(0.2 * rate), rate)?;
    reasons.push(ForceChoice::ZeroPhase {
        band_hz: ZERO_PHASE_BAND_HZ,
        per_hand_band: ZERO_PHASE_BAND_PER_HAND_BAND,
        hand_band_hz: HAND_BAND_HZ,
        order,
    });
    Ok(filter_columns(&filter, &back, n, false)?)
}

/// `q̇` as the identification made it, `q` filtered zero-phase with the model's filter then
/// central differences, in a band wide enough for the observer's bandwidth.
fn velocity_of(
    file: Option<&ModelFile>,
    input: &ForceInput<'_>,
    bandwidth_hz: &[f64],
    zero_phase: bool,
    reasons: &mut Vec<ForceChoice>,
) -> Result<Vec<f64>, ForceLogError> {
    let n = bandwidth_hz.len();
    let Some(file) = file else {
        return Err(ForceLogError::Input(
            "no velocity was given, and bare parameters have no band to differentiate q in; give the velocity".into(),
        ));
    };
    let samples = input.t.len();
    let h = (input.t[samples - 1] - input.t[0]) / (samples - 1) as f64;
    let cutoffs: Vec<f64> = match zero_phase {
        true => vec![(ZERO_PHASE_VELOCITY_PER_BAND * ZERO_PHASE_BAND_HZ).min(0.2 / h); n],
        false => bandwidth_hz.iter().map(|b| velocity_cutoff(file.settings.cutoff_hz, *b, 1.0 / h)).collect(),
    };
    // Each joint's velocity at its own cut-off: one filter per distinct cut-off.
    let mut qd = vec![0.0; input.q.len()];
    let mut done = vec![false; n];
    for k in 0..n {
        if done[k] {
            continue;
        }
        let filter = Butterworth::lowpass(file.settings.order, cutoffs[k], 1.0 / h)?;
        let rate = central_difference(&filter_columns(&filter, input.q, n, false)?, n, h, false);
        for j in (k..n).filter(|&j| cutoffs[j] == cutoffs[k]) {
            done[j] = true;
            qd.iter_mut().skip(j).step_by(n).zip(rate.iter().skip(j).step_by(n)).for_each(|(o, v)| *o = *v);
        }
    }
    reasons.push(ForceChoice::Velocity {
        cutoffs_hz: cutoffs,
        order: file.settings.order,
        zero_phase,
        per_band: match zero_phase {
            true => ZERO_PHASE_VELOCITY_PER_BAND,
            false => VELOCITY_BAND_PER_BANDWIDTH,
        },
        model_band_hz: file.settings.cutoff_hz,
    });
    Ok(qd)
}

/// A joint's velocity cut-off: the model's band, widened to the observer's bandwidth on that
/// joint times [`VELOCITY_BAND_PER_BANDWIDTH`], below a fifth of the sample rate.
fn velocity_cutoff(model_band_hz: f64, bandwidth_hz: f64, rate_hz: f64) -> f64 {
    model_band_hz.max(VELOCITY_BAND_PER_BANDWIDTH * bandwidth_hz).min(0.2 * rate_hz)
}

/// The span of a run whose estimate holds neither edge: the zero-phase velocity filter rings for
/// about three of its periods at either end (a run that stops moving mid-stroke reads there as
/// a hand of 0.25 N·m on the demo's yaw), and the observer settles over five time constants.
fn interior(t: &[f64], bandwidth_hz: f64, velocity_cutoff_hz: f64) -> (f64, f64) {
    let edge = 3.0 / velocity_cutoff_hz;
    (t[0] + edge + 5.0 / (std::f64::consts::TAU * bandwidth_hz), t[t.len() - 1] - edge)
}

/// The observer run with no hand on a model's held-out runs at each bandwidth of
/// [`bandwidth_grid`]: per joint, the estimate's RMS away from the runs' edges (three velocity-filter
/// periods at either end, five time constants at the start),
/// and the widest bandwidth whose RMS is within [`NOISE_ALLOWANCE`] of the RMS at the least. What
/// a force estimate on this model then uses as its bandwidth and σ.
pub fn observer_held_out(
    model: &Model,
    file: &ModelFile,
    runs: &[(&str, Log<'_>)],
    timing: TorqueTiming,
) -> Result<ObserverHeldOut, ForceLogError> {
    let n = model.dof();
    if runs.is_empty() {
        return Err(ForceLogError::Input("the observer's σ needs at least one held-out run".into()));
    }
    let rate = runs
        .iter()
        .map(|(_, l)| (l.t.len().saturating_sub(1)) as f64 / (l.t[l.t.len() - 1] - l.t[0]))
        .fold(f64::INFINITY, f64::min);
    let grid = bandwidth_grid(rate);
    let mut grid_sigma = vec![0.0; grid.len() * n];
    let mut grid_peak = vec![0.0f64; grid.len() * n];
    for (g, &b) in grid.iter().enumerate() {
        let (mut squares, mut count) = (vec![0.0; n], 0usize);
        let options = ForceLogOptions { bandwidth_hz: Some(vec![b; n]), timing, ..Default::default() };
        for (name, log) in runs {
            let input = ForceInput { t: log.t, q: log.q, qd: None, effort: log.tau };
            let estimate = estimate_force(model, Source::File(file), input, &options)
                .map_err(|e| ForceLogError::Input(format!("held-out run {name}: {e}")))?;
            let (from, to) = interior(log.t, b, velocity_cutoff(file.settings.cutoff_hz, b, rate));
            for (row, _) in estimate.tau_ext.chunks(n).zip(log.t).filter(|(_, t)| (from..to).contains(*t)) {
                squares.iter_mut().zip(row).for_each(|(s, r)| *s += r * r);
                for (k, r) in row.iter().enumerate() {
                    grid_peak[g * n + k] = grid_peak[g * n + k].max(r.abs());
                }
                count += 1;
            }
        }
        if count == 0 {
            return Err(ForceLogError::Input(format!(
                "the held-out runs are too short for the observer to settle at {b} Hz"
            )));
        }
        for k in 0..n {
            grid_sigma[g * n + k] = (squares[k] / count as f64).sqrt();
        }
    }
    let (mut bandwidth_hz, mut sigma, mut peak) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    for k in 0..n {
        let column: Vec<f64> = (0..grid.len()).map(|g| grid_sigma[g * n + k]).collect();
        let chosen = (0..grid.len()).rev().find(|&g| column[g] <= NOISE_ALLOWANCE * column[0]).unwrap_or(0);
        bandwidth_hz[k] = grid[chosen];
        sigma[k] = column[chosen];
        peak[k] = grid_peak[chosen * n + k];
    }
    let reason = ForceChoice::ObserverRun {
        grid_hz: grid.clone(),
        hand_bandwidth_hz: HAND_BANDWIDTH,
        hand_band_hz: HAND_BAND_HZ,
        runs: runs.iter().map(|(name, _)| name.to_string()).collect(),
        allowance: NOISE_ALLOWANCE,
    };
    Ok(ObserverHeldOut { bandwidth_hz, sigma, grid_hz: grid, grid_sigma, reason, peak })
}
