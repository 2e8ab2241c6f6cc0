//! Identification (paper sections III–IV): preprocessing, least squares, and physically consistent
//! estimation, tied together by [`identify`] into a [`ModelFile`] that can be saved, loaded,
//! printed as the paper's tables and used for prediction.

pub mod closed_loop;
pub mod drive_gains;
pub mod excitation;
pub mod options;

use crate::base_parameters::BaseParameters;
use crate::choices::{Choice, Concern};
use crate::consistent::{identify_consistent, ConsistentError};
use crate::model::Model;
use crate::model_file::{DataSummary, Fitted, HeldOut, IdentifyMethod, Metrics, ModelFile, ModelFileError, Settings};
use crate::physical::{min_pseudo_inertia_eigenvalues, nearest_standard_parameters};
use crate::signal::estimate::{fit, joint_metrics, stack_full, EstimateError, JointMetrics, Method};
use crate::signal::preprocess::{self, preprocess, PreprocessError};
use crate::signal::{cutoff, estimate, friction_law};
use closed_loop::{closed_loop_fit, ClosedLoopError, ClosedLoopSettings, ClosedLoopStart};

// The surface most callers need; the modules above stay public for the rest.
pub use crate::consistent::{ConsistentFit, ConsistentOptions};
pub use crate::signal::log::{Declared, Log};
pub use crate::signal::options::{PreprocessOptions, SettingError};
pub use crate::signal::preprocess::Preprocessed;
pub use closed_loop::{ClosedLoop, Estimator, IvOptions};
pub use excitation::{design_excitation, ExcitationError};
pub use options::ExcitationOptions;

/// Everything [`identify`] can be told.
#[derive(Clone, Debug, Default)]
pub struct IdentifyOptions {
    pub preprocess: PreprocessOptions,
    pub consistent: ConsistentOptions,
    /// The IDIM-IV and DIDIM iteration (closed-loop methods only).
    pub iv: IvOptions,
}

#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    #[error(transparent)]
    Preprocess(#[from] PreprocessError),
    #[error(transparent)]
    Estimate(#[from] EstimateError),
    #[error(transparent)]
    Consistent(#[from] ConsistentError),
    #[error(transparent)]
    Base(#[from] crate::base_parameters::BaseParameterError),
    #[error(transparent)]
    File(#[from] ModelFileError),
    #[error(transparent)]
    ClosedLoop(#[from] ClosedLoopError),
    #[error(transparent)]
    Gains(#[from] drive_gains::GainsError),
    #[error(
        "method {0} needs the closed loop's reference (q_des, qd_des, qdd_des at every sample) and the controller that \
         ran it, and none was given; ols, wls and consistent work on the log alone"
    )]
    NeedsClosedLoop(IdentifyMethod),
}

impl From<JointMetrics> for Metrics {
    fn from(m: JointMetrics) -> Self {
        Self { fp_percent: m.fp_percent, relative_error: m.relative_error, rms: m.rms }
    }
}

/// Identify the declared robot's parameters from `log`. The closed-loop methods (IDIM-IV,
/// DIDIM) need [`identify_in_closed_loop`].
pub fn identify(
    declared: Declared,
    log: Log,
    method: IdentifyMethod,
    options: &IdentifyOptions,
) -> Result<ModelFile, IdentifyError> {
    identify_with(declared, log, method, None, options)
}

/// Identify from a log recorded in closed loop, whose reference and controller are known: any
/// method, IDIM-IV and DIDIM among them ([`closed_loop`]).
pub fn identify_in_closed_loop(
    declared: Declared,
    log: Log,
    closed_loop: ClosedLoop,
    method: IdentifyMethod,
    options: &IdentifyOptions,
) -> Result<ModelFile, IdentifyError> {
    identify_with(declared, log, method, Some(closed_loop), options)
}

/// Identify from motor currents with drive gains ([`drive_gains`]): `runs` are logs whose `tau` holds
/// currents (A), each with or without the known `load`. The gains, the base parameters and the
/// load's unknowns are fitted together; the model file is then fitted as [`identify`] fits it, on
/// the first unloaded run's torque `k̂ᵢ iᵢ`, and records the gains. Coulomb laws the robot does not
/// declare are chosen on that run and used for all. A datasheet's gains, each `(k, σ)`, are
/// checked against the load's and used where the load does not fix a gain
/// ([`drive_gains::with_datasheet`]).
pub fn identify_with_known_load(
    declared: Declared,
    runs: &[(Log, bool)],
    calibration: drive_gains::Calibration,
    method: IdentifyMethod,
    options: &IdentifyOptions,
) -> Result<(ModelFile, drive_gains::GainFit), IdentifyError> {
    let drive_gains::Calibration { load, datasheet, estimator } = calibration;
    let body = load.validate(declared.model)?;
    if let Some(given) = datasheet {
        drive_gains::check_datasheet(given, &declared.model.joint_names())?;
    }
    let first = runs.iter().position(|(_, loaded)| !loaded).ok_or(drive_gains::GainsError::MissingRuns("unloaded"))?;
    if !runs.iter().any(|(_, loaded)| *loaded) {
        return Err(drive_gains::GainsError::MissingRuns("loaded").into());
    }
    let against = cutoff::Against::Regressor;
    let (pre_first, laws) = preprocess_with_laws(declared, runs[first].0, &options.preprocess, against)?;
    let with_laws;
    let model = match laws {
        Some(laws) => {
            with_laws = Model { coulomb_laws: laws, ..declared.model.clone() };
            &with_laws
        }
        None => declared.model,
    };
    let declared = Declared { model, ..declared };
    let mut preprocessed = Vec::with_capacity(runs.len());
    for (r, (log, _)) in runs.iter().enumerate() {
        preprocessed.push(match r == first {
            true => pre_first.clone(),
            false => cutoff::preprocess_for_fit(declared, *log, &options.preprocess, against)?,
        });
    }
    let gain_runs: Vec<drive_gains::GainRun> = preprocessed
        .iter()
        .zip(runs)
        .map(|(data, (_, loaded))| drive_gains::GainRun { data, loaded: *loaded })
        .collect();
    let ls = if method == IdentifyMethod::Wls { Method::Wls } else { Method::Ols };
    let fit = drive_gains::fit_gains(model, declared.base, &gain_runs, load, body, ls, estimator)?;
    let dof = model.dof();
    let (mut reasons, mut warnings) = (fit.reasons.clone(), fit.warnings.clone());
    let (used, sigma, covariance, from_datasheet) = match datasheet {
        Some(given) => {
            let checked = drive_gains::with_datasheet(&fit, given, &model.joint_names())?;
            reasons.extend(checked.reasons);
            warnings.extend(checked.warnings);
            (checked.gains, checked.sigma, checked.covariance, checked.from_datasheet)
        }
        None => (fit.gains.clone(), fit.gain_sigma.clone(), fit.gain_covariance.clone(), vec![false; dof]),
    };
    let beta_per_gain = drive_gains::beta_per_gain(model, declared.base, &preprocessed[first], &used, ls)?;
    let log = runs[first].0;
    let torque: Vec<f64> = log.tau.iter().enumerate().map(|(i, c)| c * used[i % dof]).collect();
    let mut file = identify(declared, Log { tau: &torque, ..log }, method, options)?;
    file.settings.reasons.splice(0..0, reasons);
    file.settings.warnings.extend(warnings);
    file.drive_gains = Some(crate::model_file::DriveGains {
        gains: used,
        sigma,
        estimator,
        covariance,
        beta_per_gain,
        from_datasheet,
        load_body: load.body.clone(),
        load_mass: load.mass,
        load_estimate: fit.load.clone(),
        condition_number: fit.fit.condition_number,
        load_share: fit.load_torque_share.clone(),
        load_over_unexplained: fit.load_over_unexplained.clone(),
        fixed: fit.fixed.clone(),
    });
    Ok((file, fit))
}

/// Why the base parameters are fewer than the exact rank: the weak ones, regrouped.
fn weak_reason(base: &BaseParameters) -> Choice {
    let (kept, weak) = base.reach_gap.unwrap_or_default(); // the test ran: there are weak ones
    Choice::Regrouped { rank: base.rank, names: base.weak.iter().map(|w| w.name.clone()).collect(), weak, kept }
}

/// The log preprocessed at the cut-offs the data choose, and, where the robot declares no Coulomb
/// law, each joint's law chosen from the data with them. Cut-offs and laws depend on each other
/// (a law the fit does not use mis-scores the cut-offs, and the laws are fitted at the cut-offs),
/// so they are chosen in turn, starting from `sign(q̇)`, until the laws settle or
/// [`LAW_ROUNDS`] rounds: on a closed loop whose insertion's friction rises over 2 mm/s, the
/// cut-offs chosen under sign(q̇) gave a law of 1.2 mm/s and a model that predicted the paper's
/// trajectories at 46 % on the insertion (docs/identification.md).
fn preprocess_with_laws(
    declared: Declared,
    log: Log,
    options: &PreprocessOptions,
    against: cutoff::Against,
) -> Result<(preprocess::Preprocessed, Option<crate::model::CoulombLaws>), IdentifyError> {
    let (model, base) = (declared.model, declared.base);
    // The log is read once; each round of laws searches the cut-offs again.
    let reading = cutoff::Reading::of(declared, log, options)?;
    let mut pre = reading.preprocess_for_fit(declared, against)?;
    if model.coulomb_laws.is_declared() {
        return Ok((pre, None));
    }
    // The laws `pre` was preprocessed with.
    let mut laws = model.coulomb_laws.clone();
    let raw = friction_law::RawPositions::of(log, model.dof())?;
    // The cut-offs `laws` were chosen at, and why. The choice reads only the log preprocessed at
    // its cut-offs, so at the same cut-offs it would choose the same laws: settled, without
    // choosing again (most logs settle so, in their second round).
    let mut last: Option<((f64, f64), Choice)> = None;
    for round in 1..=LAW_ROUNDS {
        let band = (pre.cutoff_hz, pre.friction_cutoff_hz);
        if let Some((_, reason)) = last.as_ref().filter(|(at, _)| *at == band) {
            pre.choices.reasons.push(reason.clone());
            return Ok((pre, Some(laws)));
        }
        let Some(chosen) = friction_law::laws_for_fit(model, base, &pre, raw)? else { return Ok((pre, None)) };
        if friction_law::settled(&laws, &chosen.laws) {
            pre.choices.reasons.push(chosen.reason);
            return Ok((pre, Some(chosen.laws)));
        }
        last = Some((band, chosen.reason.clone()));
        let unsettled = match round == LAW_ROUNDS {
            true => {
                let (steady, unsettled) = friction_law::steady(&laws, &chosen.laws);
                laws = steady;
                unsettled
            }
            false => {
                laws = chosen.laws;
                Vec::new()
            }
        };
        let with_laws = Model { coulomb_laws: laws.clone(), ..model.clone() };
        pre = reading.preprocess_for_fit(Declared { model: &with_laws, ..declared }, against)?;
        if round == LAW_ROUNDS {
            // The cut-offs are those of the laws kept, so that the fit is the one they were chosen for.
            pre.choices.reasons.push(chosen.reason);
            pre.choices.warnings.push(Concern::LawsNotSettled { rounds: LAW_ROUNDS, unsettled });
        }
    }
    Ok((pre, Some(laws)))
}

/// Rounds of choosing the cut-offs with the laws and the laws at the cut-offs.
const LAW_ROUNDS: usize = 4;

fn identify_with(
    declared: Declared,
    log: Log,
    method: IdentifyMethod,
    closed_loop: Option<ClosedLoop>,
    options: &IdentifyOptions,
) -> Result<ModelFile, IdentifyError> {
    if method.closed_loop() && closed_loop.is_none() {
        return Err(IdentifyError::NeedsClosedLoop(method));
    }
    options.iv.validate()?;
    let against = match (method.closed_loop(), &closed_loop) {
        (true, Some(_)) => cutoff::Against::SimulatedLoop,
        _ => cutoff::Against::Regressor,
    };
    // The log's hash (10⁷ bytes of a long log) beside its checks, which hold the other core idle.
    let (fingerprint, prepared) = std::thread::scope(|scope| {
        let fingerprint = scope.spawn(|| log.fingerprint());
        let prepared = preprocess_with_laws(declared, log, &options.preprocess, against);
        (fingerprint.join().expect("hashing does not panic"), prepared)
    });
    let (mut pre, laws) = prepared?;
    let Declared { model, base, urdf } = declared;
    // A robot that declares no Coulomb law gets each joint's from the data, which the fit, the
    // closed-loop simulation and the model file all use.
    let with_laws;
    let model = match laws {
        Some(laws) => {
            with_laws = Model { coulomb_laws: laws, ..model.clone() };
            &with_laws
        }
        None => model,
    };
    if !base.weak.is_empty() {
        pre.choices.reasons.push(weak_reason(base));
    }
    let samples_in = log.t.len();
    let ls_method = if method == IdentifyMethod::Wls { Method::Wls } else { Method::Ols };
    let ls = fit(model, base, &pre, ls_method)?;
    let ols_metrics: Metrics = if ls_method == Method::Ols {
        ls.metrics.clone().into()
    } else {
        fit(model, base, &pre, Method::Ols)?.metrics.into()
    };
    let (ls, instruments) = match closed_loop.filter(|_| method.closed_loop()) {
        Some(closed_loop) => {
            let estimator = Estimator::of(method).expect("a closed-loop method names its estimator");
            let start = ClosedLoopStart { t: log.t, pre: &pre, preprocess: &options.preprocess, fit: &ls };
            let settings = ClosedLoopSettings { estimator, iv: &options.iv, consistent: &options.consistent };
            let iv = closed_loop_fit(model, base, &closed_loop, start, settings)?;
            let name = estimator.name().to_string();
            let (iterations, last_change_sigma) = (iv.iterations, iv.last_change_sigma);
            pre.choices.reasons.push(Choice::ClosedLoop { estimator: name.clone(), iterations, last_change_sigma });
            if let Some(first) = iv.detours.first().cloned() {
                let detours = iv.detours.len();
                pre.choices.reasons.push(Choice::ClosedLoopDetours {
                    estimator: name.clone(),
                    detours,
                    iterations,
                    first,
                });
            }
            if !iv.converged {
                pre.choices.warnings.push(Concern::ClosedLoopNotSettled {
                    estimator: name,
                    iterations,
                    last_change_sigma,
                });
            }
            (iv.fit, Some((estimator, iv.instruments)))
        }
        None => (ls, None),
    };
    let (beta, params, training, min_eig) = if method.consistent() {
        let (mut w, mut tau_f) = stack_full(model, &pre);
        estimate::leave_out_rests(&pre, &mut w, &mut tau_f, pre.settled.clone());
        let projected = instruments.as_ref().map(|(estimator, z)| estimator.full(base, &w, z));
        let c = identify_consistent(model, projected.as_ref().unwrap_or(&w), &tau_f, &options.consistent)?;
        let predicted: Vec<f64> = estimate::apply(&w, &c.params);
        let mut beta = vec![0.0; base.rank];
        base.project(&c.params, &mut beta);
        let metrics = joint_metrics(&tau_f, &predicted, model.dof()).into();
        (beta, Some(c.params), metrics, c.min_pseudo_inertia_eigenvalue)
    } else {
        let nearest = nearest_standard_parameters(model, base, &ls.beta);
        let min_eig = min_pseudo_inertia_eigenvalues(model, &nearest);
        (ls.beta.clone(), None, ls.metrics.clone().into(), min_eig)
    };
    let fitted = Fitted {
        beta,
        sigma_percent: ls.sigma_percent.clone(),
        beta_covariance: crate::dense::square_row_major(ls.covariance.as_ref(), base.rank),
        params,
        training,
        training_ols: ols_metrics,
        min_pseudo_inertia_eigenvalue: min_eig,
        condition_number: ls.condition_number,
        determination: ls.determination.clone(),
    };
    Ok(ModelFile::new(
        model,
        base,
        urdf,
        fitted,
        Settings {
            method,
            periods: pre.periodic.then_some(pre.periods_averaged),
            period_s: pre.period_s,
            cutoff_hz: pre.cutoff_hz,
            friction_cutoff_hz: Some(pre.friction_cutoff_hz),
            coulomb_epsilon: Settings::law_fields(&model.coulomb_laws).0,
            friction_velocities: Settings::law_fields(&model.coulomb_laws).1,
            order: options.preprocess.order,
            decimate: options.preprocess.decimate,
            pull: options.consistent.pull,
            stiffness_bounds: {
                let finite = |x: f64| x.is_finite().then_some(x);
                (finite(options.consistent.stiffness_bounds.0), finite(options.consistent.stiffness_bounds.1))
            },
            reasons: pre.choices.reasons.clone(),
            warnings: pre.choices.warnings.clone(),
        },
        DataSummary {
            sources: vec![],
            samples_in,
            samples_used: pre.settled.len(),
            sample_rate_hz: pre.sample_rate_hz,
            periods_averaged: pre.periods_averaged,
            fingerprint: Some(fingerprint),
        },
    ))
}

/// Table II shape: FP% per joint (rows, named by `joints`) for each validation run (columns).
pub fn validation_table(joints: &[String], labels: &[String], fp_percent: &[Vec<f64>]) -> String {
    let dof = fp_percent.first().map_or(0, Vec::len);
    let width = labels.iter().map(|l| l.chars().count() + 2).max().unwrap_or(0).max(12);
    let mut s = format!("{:<12}", "FP%");
    for l in labels {
        s += &format!("{l:>width$}");
    }
    s.push('\n');
    for k in 0..dof {
        let name = joints.get(k).cloned().unwrap_or_else(|| format!("joint {}", k + 1));
        s += &format!("{name:<12}");
        for run in fp_percent {
            s += &format!("{:>width$.2}", run[k]);
        }
        s.push('\n');
    }
    s
}

/// What a validation log gives: FP% and the other figures per joint, with the cut-off it was
/// filtered at and why.
#[derive(Clone, Debug)]
pub struct Validation {
    pub metrics: Metrics,
    pub cutoff_hz: f64,
    /// The validation log's preprocessing choices (period, trimmed ends, and the cut-off when it
    /// had to differ from training's).
    pub reasons: Vec<Choice>,
}

/// FP% per joint of `identification` on one validation log (same preprocessing as training):
/// one column of the paper's Table II, the cross-validation.
pub fn cross_validate(
    model: &Model,
    identification: &ModelFile,
    t: &[f64],
    q: &[f64],
    tau: &[f64],
    preprocess_options: &PreprocessOptions,
) -> Result<Validation, IdentifyError> {
    let series = validation_series(model, identification, t, q, tau, preprocess_options)?;
    Ok(Validation {
        metrics: joint_metrics(&series.measured, &series.predicted, model.dof()).into(),
        cutoff_hz: series.cutoff_hz,
        reasons: series.reasons,
    })
}

/// A validation run preprocessed as for [`cross_validate`]: the time of each sample, the filtered
/// measured torque and the model's prediction (both N × dof, row-major).
#[derive(Clone, Debug)]
pub struct ValidationSeries {
    pub t: Vec<f64>,
    pub measured: Vec<f64>,
    pub predicted: Vec<f64>,
    pub cutoff_hz: f64,
    pub reasons: Vec<Choice>,
}

/// The series [`cross_validate`] scores, for plotting measured against predicted torque.
///
/// The run is filtered at the training cut-offs, unless the caller says otherwise. A run that
/// is not periodic and too short for that cut-off (the filter's start-up would fill more than
/// half of it: a single period of a validation trajectory, say) is filtered at the lowest cut-off
/// it allows, and the reasons say so.
pub fn validation_series(
    model: &Model,
    identification: &ModelFile,
    t: &[f64],
    q: &[f64],
    tau: &[f64],
    preprocess_options: &PreprocessOptions,
) -> Result<ValidationSeries, IdentifyError> {
    let options = PreprocessOptions {
        cutoff_hz: preprocess_options.cutoff_hz.or(Some(identification.settings.cutoff_hz)),
        friction_cutoff_hz: preprocess_options.friction_cutoff_hz.or(identification.settings.friction_cutoff_hz),
        ..preprocess_options.clone()
    };
    let model = &*identification.with_its_law(model);
    let pre = match preprocess(t, q, tau, model.dof(), &options) {
        Err(PreprocessError::TooShortForCutoff { cutoff_hz, lowest_hz, .. }) => {
            let mut pre =
                preprocess(t, q, tau, model.dof(), &PreprocessOptions { cutoff_hz: Some(lowest_hz), ..options })?;
            pre.choices.reasons.push(Choice::ValidatedAtLowest { lowest_hz, cutoff_hz });
            pre
        }
        other => other?,
    };
    // Through the stacked regressor, so that the Coulomb columns are filtered like the torque.
    let (w, measured) = stack_full(model, &pre);
    let full = identification.full_or_base_vector();
    let predicted: Vec<f64> = estimate::apply(&w, &full);
    Ok(ValidationSeries {
        t: pre.settled_rows(&pre.t, 1).to_vec(),
        measured,
        predicted,
        cutoff_hz: pre.cutoff_hz,
        reasons: pre.choices.reasons,
    })
}

/// The model's residual on held-out runs (`(name, log)` each), for [`ModelFile::held_out`]: per
/// joint, the RMS over every run's samples of the measured torque minus the prediction, each run
/// filtered in the model's band and no periods averaged, since a force estimate sees each sample
/// on its own. `order` is the filter's, as the identification's.
pub fn held_out_residual(
    model: &Model,
    identification: &ModelFile,
    runs: &[(&str, Log<'_>)],
    order: usize,
) -> Result<HeldOut, IdentifyError> {
    let n = model.dof();
    let mut squares = vec![0.0; n];
    let (mut samples, mut cutoff_hz) = (0, identification.settings.cutoff_hz);
    let options = PreprocessOptions { periods: Some(1), order, ..Default::default() };
    for (_, log) in runs {
        let series = validation_series(model, identification, log.t, log.q, log.tau, &options)?;
        for (k, (m, p)) in series.measured.iter().zip(&series.predicted).enumerate() {
            squares[k % n] += (m - p) * (m - p);
        }
        samples += series.measured.len() / n;
        cutoff_hz = cutoff_hz.min(series.cutoff_hz);
    }
    let names: Vec<&str> = runs.iter().map(|(name, _)| *name).collect();
    Ok(HeldOut {
        rms: squares.iter().map(|s| (s / samples.max(1) as f64).sqrt()).collect(),
        samples,
        cutoff_hz,
        source: format!("validation runs: {}", names.join(", ")),
        observer: None,
    })
}
