//! The hand's force over a whole log, offline: what `arash force` and `arash.external_force`
//! return. The momentum observer runs over the samples, the estimate is mapped to a frame, each
//! sample carries the σ the model's held-out residual gives it, and thresholds tell contact from
//! collision (`docs/force.md`).
//!
//! The choices it makes when not told are made here, each with its reason:
//! - the observer's bandwidth is a quarter of the band the model's σ was measured in (its
//!   held-out cut-off), [`BAND_PER_BANDWIDTH`];
//! - without a measured velocity, `q̇` is the central difference of `q` filtered zero-phase in
//!   the model's band with the model's filter, as the identification differentiated it;
//! - the Coulomb terms switch with the model's own law where it has one: offline the velocity is
//!   filtered without lag, so the law the model was fitted with holds, where the controllers
//!   widen it against a noisy velocity;
//! - currents become torques through the drive gains the model was calibrated with.

use crate::control::gains::{compensation_epsilon, model_epsilon, RobustGains};
use crate::force::{
    episodes, Episode, FrameForce, Level, MomentumObserver, ObserverError, ThresholdError, Thresholds, TorqueTiming,
};
use crate::identify::filter::{Butterworth, FilterError};
use crate::identify::signals::{central_difference, filter_columns};
use crate::model::{Model, UnknownFrame};
use crate::model_file::ModelFile;

/// The model's band over the observer's default bandwidth. The σ is measured in the band, by a
/// zero-phase Butterworth that cuts steeply at its edge; the observer's first-order lag rolls off
/// at only 20 dB per decade, so at the full band it would pass the residual above the band (and
/// the differentiated velocity's noise) that σ never saw. At a quarter of the band its
/// noise-equivalent band, π/2 of its bandwidth, lies well inside it: on the demo's rig the
/// estimate's hand-free RMS is then 0.65–0.85 σ per joint, against 0.9–1.4 σ at the full band
/// (docs/force.md).
pub const BAND_PER_BANDWIDTH: f64 = 4.0;

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

/// A frame the force is wanted at, and the frame its moment is taken about (default: the base).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameChoice {
    pub frame: String,
    pub about: Option<String>,
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
    pub reasons: Vec<String>,
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
    let bandwidth = bandwidth_of(file, options, n, &mut reasons)?;
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
                false => Some(Thresholds::from_sigma(&sigma, *contact, *collision)?),
            },
            ThresholdChoice::ByHand { contact, collision } => Some(Thresholds::by_hand(contact, collision, n)?),
        };
    let tau = torques_of(file, &input, options.effort, n)?;
    let qd = match input.qd {
        Some(qd) => std::borrow::Cow::Borrowed(qd),
        None => std::borrow::Cow::Owned(velocity_of(file, &input, n, &mut reasons)?),
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
        out.tau_ext[rows.clone()].copy_from_slice(estimate);
        if let Some(t) = &thresholds {
            out.levels.push(t.level(estimate));
        }
        if let Some(map) = map.as_mut() {
            let s = map.map(&input.q[rows], estimate, &sigma);
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

/// The robot's instrument tip and the remote centre its moment is taken about, where its URDF
/// names them (ARASH:ASiST's do): the frame a force is wanted at when none is named.
pub fn default_frame(model: &Model) -> Option<FrameChoice> {
    let has = |name: &str| model.frame(name).is_ok();
    (has("instrument_tip") && has("remote_centre"))
        .then(|| FrameChoice { frame: "instrument_tip".into(), about: Some("remote_centre".into()) })
}

/// Each joint's Coulomb width: the model's own law where it has one (the velocity offline has no
/// noise a sign would chatter on), else the robust controller's ε (the paper's where it has gains
/// for the robot, the joint kinds' default elsewhere).
fn epsilon_of(model: &Model, reasons: &mut Vec<String>) -> Vec<f64> {
    let paper = RobustGains::paper(model).map(|g| g.epsilon);
    let controller = compensation_epsilon(model, &paper.unwrap_or_else(|_| model_epsilon(model)));
    let own: Vec<Option<f64>> = (0..model.dof()).map(|k| model.coulomb_laws.shape(k).epsilon()).collect();
    if own.iter().any(Option::is_none) {
        reasons.push("Coulomb friction switches as the controllers' tanh(q̇/ε) where the model's law is sign(q̇)".into());
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
    n: usize,
    reasons: &mut Vec<String>,
) -> Result<Vec<f64>, ForceLogError> {
    if let Some(b) = &options.bandwidth_hz {
        return Ok(b.clone());
    }
    let Some(file) = file else {
        return Err(ForceLogError::Input(
            "the observer's bandwidth follows from a model file's band; with bare parameters give it".into(),
        ));
    };
    let (band, from) = match &file.held_out {
        Some(h) => (h.cutoff_hz, "the band the model's held-out σ was measured in"),
        None => (file.settings.cutoff_hz, "the band the model was fitted in (it records no held-out σ)"),
    };
    let hz = band / BAND_PER_BANDWIDTH;
    reasons.push(format!(
        "the observer's bandwidth is {hz:.3} Hz, a quarter of {band:.3} Hz, {from}: its lag's slow roll-off then \
         passes little of what lies above that band"
    ));
    Ok(vec![hz; n])
}

/// The σ given, or the model's held-out residual RMS, or none.
fn sigma_of(
    file: Option<&ModelFile>,
    options: &ForceLogOptions,
    n: usize,
    reasons: &mut Vec<String>,
) -> Result<Vec<f64>, ForceLogError> {
    match (&options.sigma, file.and_then(|f| f.held_out.as_ref())) {
        (Some(s), _) if s.len() != n => {
            Err(ForceLogError::Input(format!("σ has {} entries; the robot has {n} joints", s.len())))
        }
        (Some(s), _) => Ok(s.clone()),
        (None, Some(h)) => {
            reasons.push(format!("σ is the model's held-out residual RMS ({}, {} samples)", h.source, h.samples));
            Ok(h.rms.clone())
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

/// `q̇` as the identification made it: `q` filtered zero-phase in the model's band, then central
/// differences.
fn velocity_of(
    file: Option<&ModelFile>,
    input: &ForceInput<'_>,
    n: usize,
    reasons: &mut Vec<String>,
) -> Result<Vec<f64>, ForceLogError> {
    let Some(file) = file else {
        return Err(ForceLogError::Input(
            "no velocity was given, and bare parameters have no band to differentiate q in; give the velocity".into(),
        ));
    };
    let samples = input.t.len();
    let h = (input.t[samples - 1] - input.t[0]) / (samples - 1) as f64;
    let cutoff = file.settings.cutoff_hz;
    let filter = Butterworth::lowpass(file.settings.order, cutoff, 1.0 / h)?;
    let q = filter_columns(&filter, input.q, n, false)?;
    reasons.push(format!(
        "q̇ is the central difference of q filtered zero-phase at {cutoff:.3} Hz (order {}), as the model was fitted",
        file.settings.order
    ));
    Ok(central_difference(&q, n, h, false))
}
