//! Closing the loop on measured data: find what the declared model leaves in the residual, name
//! the effect it comes from, add it, and report the error before and after (`docs/diagnosis.md`).
//!
//! The search is forward selection over the [`catalogue`] with a decision rule built for robot
//! residuals, which are correlated over seconds:
//!
//! 1. a time misalignment is searched first, as an integer shift of the torque, because an
//!    unmodelled delay otherwise masquerades as velocity-dependent friction;
//! 2. each candidate group is partialled against the current model and gated by a block Wald test
//!    whose unit is a block of time ([`regression::test_group`]);
//! 3. candidates the current model already explains (VIF above the limit) are not identifiable
//!    and are set aside with that reason;
//! 4. Holm's procedure corrects for the number of candidates tested in the round;
//! 5. the survivors are ranked by how much they cut the error on held-out data (a validation log,
//!    or the odd-numbered blocks when fitting on the even ones), and one that does not cut it by
//!    at least `min_gain` is not worth a term;
//! 6. the best is added, the model refitted, and the search repeated until nothing passes.

pub mod catalogue;
mod refit;
pub mod regression;
mod report;

use serde::{Deserialize, Serialize};

use crate::base_parameters::BaseParameters;
use crate::data::Data;
use crate::identify::estimate::joint_metrics;
use crate::identify::preprocess::{central_difference, preprocess, PreprocessError, PreprocessOptions, Preprocessed};
use crate::identify::{Identification, IdentifyError, IdentifyMethod, Metrics};
use crate::model::{CoulombShape, Model};
use crate::regressor::regressor;
pub use catalogue::{EffectKind, EffectTerm, TermState};
pub use refit::consistent_with_effects;
use regression::{gram, least_squares, residual, rhs, test_group, Column, Rows};

/// Settings of [`diagnose`]; `Default` gives the documented defaults.
#[derive(Clone, Debug)]
pub struct DiagnoseOptions {
    /// Low-pass cut-off of every signal (Hz). Higher than identification's, so that ripple and
    /// friction transitions survive; capped at a fifth of the sample rate.
    pub cutoff_hz: f64,
    /// Keep every n-th filtered sample (`None`: about five samples per cut-off period).
    pub decimate: Option<usize>,
    /// Length of the blocks of time that are the unit of the Wald test and of the held-out split
    /// (s).
    pub block_s: f64,
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
    /// Joint motion per motor radian, for the cogging search (`None`: cogging is not searched).
    pub transmission: Option<Vec<f64>>,
    /// Ripple periods per motor revolution tried by the cogging search.
    pub cogging_periods: Vec<f64>,
    /// The effects searched (default: all of them).
    pub effects: Vec<EffectKind>,
    /// Coulomb friction in the declared model switches as `tanh(q̇/ε)` with this ε (rad/s or
    /// m/s); `None` keeps the model's own shape. A sharp `sign(q̇)` of an estimated velocity
    /// flips at full amplitude on every noisy zero crossing, which the measured friction does
    /// not do, and leaves a residual that looks like Stribeck friction.
    pub coulomb_epsilon: Option<f64>,
    /// Cut-off of the velocity that switches friction (Hz); `None`: identification's default.
    pub friction_cutoff_hz: Option<f64>,
    /// With a given model: hold its friction too (default: refit friction, which drifts with
    /// temperature and depends on how its velocity was estimated).
    pub hold_friction: bool,
    /// With a given model: refit its base parameters together with the effects (default: keep
    /// them, so that a payload or other change against that model shows).
    pub refit: bool,
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            cutoff_hz: 20.0,
            decimate: None,
            block_s: 2.0,
            alpha: 0.01,
            min_gain: 0.2,
            max_vif: 1000.0,
            max_delay_s: 0.02,
            max_effects: 6,
            transmission: None,
            cogging_periods: (1..=8).map(f64::from).collect(),
            effects: EffectKind::ALL.to_vec(),
            hold_friction: false,
            coulomb_epsilon: Some(1e-3),
            friction_cutoff_hz: None,
            refit: false,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    #[error("training log: {0}")]
    Training(PreprocessError),
    #[error("validation log: {0}")]
    Validation(PreprocessError),
    #[error(transparent)]
    Identify(#[from] IdentifyError),
    #[error("{0}")]
    Input(String),
    #[error(
        "the declared model cannot be fitted to this log: its columns are linearly dependent here (too little motion?)"
    )]
    Singular,
}

/// One log: `t` (N), `q` and `tau` (N × dof, row-major, SI).
#[derive(Clone, Copy, Debug)]
pub struct Log<'a> {
    pub t: &'a [f64],
    pub q: &'a [f64],
    pub tau: &'a [f64],
}

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
    /// Hotelling-scaled block Wald statistic, F(k, B − k).
    pub statistic: f64,
    pub p_value: f64,
    /// The Holm threshold the p-value had to pass.
    pub threshold: f64,
    /// Relative cut of the held-out squared error, mean over `joints`.
    pub heldout_gain: f64,
    /// Per joint of the robot (0 where it does not act).
    pub heldout_gain_per_joint: Vec<f64>,
    /// Other candidates that explain the same thing on this data and cannot be told apart.
    pub aliases: Vec<String>,
    /// For a payload: the mass (kg) and the body.
    pub mass_kg: Option<f64>,
    pub body: Option<String>,
    /// Search round in which it was accepted (0: the delay search).
    pub round: usize,
}

/// A candidate that was not accepted, and why.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Rejection {
    pub name: String,
    pub joints: Vec<usize>,
    pub label: String,
    pub reason: String,
    pub p_value: Option<f64>,
    pub heldout_gain: Option<f64>,
}

/// Fit quality per joint on the training data and on the held-out data.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ErrorSummary {
    pub training: Metrics,
    pub heldout: Metrics,
}

/// Settings the diagnosis ran with.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DiagnoseSettings {
    pub cutoff_hz: f64,
    pub decimate: usize,
    pub block_s: f64,
    pub blocks: usize,
    pub alpha: f64,
    pub min_gain: f64,
    pub max_vif: f64,
    pub max_delay_s: f64,
    /// Whether the declared base parameters were refitted (no model given, or `refit`).
    pub refit: bool,
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

/// What [`diagnose`] found.
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
    pub before: ErrorSummary,
    pub after: ErrorSummary,
    pub settings: DiagnoseSettings,
    /// The updated model: the declared parameters (refitted or as given) plus the effects.
    pub model: Identification,
    #[serde(skip)]
    pub series: Series,
}

/// A log filtered and sampled for the diagnosis, with the declared model's columns.
struct Prepared {
    dof: usize,
    fs: f64,
    pre: Preprocessed,
    q_raw: Vec<f64>,
    /// Full-rate sample indices used, every `stride`-th inside the trimmed ends.
    kept: Vec<usize>,
    /// Base-parameter columns, unweighted.
    declared: Vec<Column>,
    /// Mass and first-moment columns of each body with mass: (body, columns).
    bodies: Vec<(usize, Vec<Column>)>,
}

impl Prepared {
    fn samples(&self) -> usize {
        self.kept.len()
    }

    /// The filtered torque at the kept samples, shifted by `delay` full-rate samples.
    fn tau(&self, delay: isize) -> Vec<f64> {
        let dof = self.dof;
        let mut out = Vec::with_capacity(self.kept.len() * dof);
        for &i in &self.kept {
            let j = (i as isize + delay) as usize;
            out.extend_from_slice(&self.pre.tau[j * dof..(j + 1) * dof]);
        }
        out
    }

    fn at_kept(&self, x: &[f64]) -> Vec<f64> {
        let dof = self.dof;
        self.kept.iter().flat_map(|&i| x[i * dof..(i + 1) * dof].iter().copied()).collect()
    }
}

fn prepare(
    model: &Model,
    base: &BaseParameters,
    log: Log,
    options: &DiagnoseOptions,
    margin_s: f64,
) -> Result<Prepared, PreprocessError> {
    let dof = model.dof();
    let dt = crate::identify::preprocess::validate_log(log.t, log.q, log.tau, dof)?;
    let fs = 1.0 / dt;
    let cutoff_hz = options.cutoff_hz.min(fs / 5.0);
    let pre_options = PreprocessOptions {
        cutoff_hz: Some(cutoff_hz),
        filter_derivatives: false,
        friction_cutoff_hz: options.friction_cutoff_hz,
        ..PreprocessOptions::default()
    };
    let pre = preprocess(log.t, log.q, log.tau, dof, &pre_options)?;
    let stride = options.decimate.unwrap_or(((fs / (5.0 * cutoff_hz)).floor() as usize).max(1)).max(1);
    let n = pre.samples();
    let margin = ((margin_s * fs).ceil() as usize).max((3.0 * fs / cutoff_hz).ceil() as usize);
    if n < 2 * margin + 64 * stride {
        return Err(PreprocessError::TooFewSamples { needed: 2 * margin + 64 * stride, got: n });
    }
    let kept: Vec<usize> = (margin..n - margin).step_by(stride).collect();
    let (declared, bodies) = declared_columns(model, base, &pre, &kept);
    Ok(Prepared { dof, fs, pre, q_raw: log.q.to_vec(), kept, declared, bodies })
}

/// Column `c` of a body's mass and first-moment columns, or exact zeros where it is round-off
/// beside the others (a first moment along an axis the body turns about): the regression pins
/// such a column's coefficient to zero instead of fitting noise with it.
fn visible(columns: &[Vec<f64>], c: usize) -> Vec<f64> {
    let size = |v: &[f64]| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let largest = columns.iter().map(|v| size(v)).fold(0.0, f64::max);
    if size(&columns[c]) <= 1e-9 * largest {
        vec![0.0; columns[c].len()]
    } else {
        columns[c].clone()
    }
}

/// The base-parameter columns at the kept samples, Coulomb columns filtered like the torque (as
/// identification does), and each body's mass and first-moment columns (payload candidates).
fn declared_columns(
    model: &Model,
    base: &BaseParameters,
    pre: &Preprocessed,
    kept: &[usize],
) -> (Vec<Column>, Vec<(usize, Vec<Column>)>) {
    let dof = model.dof();
    let mut columns = full_columns(model, pre, kept);
    let bodies = (0..model.bodies.len())
        .filter(|&b| columns[10 * b].iter().any(|v| *v != 0.0))
        .map(|b| (b, (0..4).map(|c| Column::dense(visible(&columns[10 * b..10 * b + 4], c), dof)).collect()))
        .collect();
    let declared = base.independent.iter().map(|&j| Column::dense(std::mem::take(&mut columns[j]), dof)).collect();
    (declared, bodies)
}

/// All P standard-parameter columns at the kept samples (`kept × dof` rows each), the Coulomb
/// columns filtered like the torque.
fn full_columns(model: &Model, pre: &Preprocessed, kept: &[usize]) -> Vec<Vec<f64>> {
    let (dof, big_p) = (model.dof(), model.num_params());
    let mut columns = vec![vec![0.0; kept.len() * dof]; big_p];
    let mut data = Data::new(model);
    let mut y = vec![0.0; dof * big_p];
    for (s, &i) in kept.iter().enumerate() {
        let range = i * dof..(i + 1) * dof;
        regressor(model, &mut data, &pre.q[range.clone()], &pre.qd[range.clone()], &pre.qdd[range], &mut y);
        for k in 0..dof {
            for (j, column) in columns.iter_mut().enumerate() {
                column[s * dof + k] = y[k * big_p + j];
            }
        }
    }
    for k in 0..dof {
        let j = model.friction_offset() + 2 * k + 1;
        let shape = friction_shape(model, pre, k);
        let full: Vec<f64> = (0..pre.samples()).map(|s| shape.eval(pre.qd_friction[s * dof + k])).collect();
        let filtered = pre.filter_like_torque(&full, 1).expect("the torque was filtered with these settings");
        for (s, &i) in kept.iter().enumerate() {
            columns[j][s * dof + k] = filtered[i];
        }
    }
    columns
}

/// The direction function of joint `k`'s friction terms: the model's `tanh(q̇/ε)`, widened to
/// the noise of the friction velocity (its RMS difference from the velocity at the main
/// cut-off). A sign taken of a velocity that noisy flips at full amplitude where the true
/// velocity is merely small; `tanh(q̇/σ)` is close to the expected sign given the noise, which
/// is what the filtered torque records.
fn friction_shape(model: &Model, pre: &Preprocessed, k: usize) -> CoulombShape {
    let dof = pre.dof;
    let n = pre.samples();
    let noise =
        ((0..n).map(|s| (pre.qd_friction[s * dof + k] - pre.qd[s * dof + k]).powi(2)).sum::<f64>() / n as f64).sqrt();
    match model.coulomb_shape {
        CoulombShape::Tanh { epsilon } => CoulombShape::Tanh { epsilon: epsilon.max(noise) },
        CoulombShape::Sign => CoulombShape::Sign,
    }
}

/// The candidate templates for this robot and training data, and the effects not searched (with
/// the reason).
fn candidates(model: &Model, train: &Prepared, options: &DiagnoseOptions) -> (Vec<EffectTerm>, Vec<Rejection>) {
    let dof = model.dof();
    let mut terms = Vec::new();
    let mut skipped = Vec::new();
    let q = train.at_kept(&train.pre.q);
    let qd = train.at_kept(&train.pre.qd);
    let t0 = train.pre.t[train.kept[0]];
    let t1 = train.pre.t[*train.kept.last().expect("prepared logs have samples")];
    let wanted = |k: EffectKind| options.effects.contains(&k);
    for k in 0..dof {
        let column = |x: &[f64]| x.iter().skip(k).step_by(dof).copied().collect::<Vec<f64>>();
        let (qk, vk) = (column(&q), column(&qd));
        let lo = qk.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = qk.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let vrms = (vk.iter().map(|v| v * v).sum::<f64>() / vk.len() as f64).sqrt();
        let range = (hi - lo).max(1e-9);
        let epsilon = match friction_shape(model, &train.pre, k) {
            CoulombShape::Tanh { epsilon } => Some(epsilon),
            CoulombShape::Sign => None,
        };
        let term = |kind: EffectKind| {
            let mut t = EffectTerm::new(kind, Some(k));
            t.epsilon = epsilon;
            t.span = Some((lo, hi));
            t
        };
        let mut add = |kind: EffectKind, scale: Option<f64>| {
            if wanted(kind) {
                let mut t = term(kind);
                t.scale = scale;
                if kind == EffectKind::Drift {
                    t.span = Some((0.5 * (t0 + t1), 0.5 * (t1 - t0)));
                }
                terms.push(t);
            }
        };
        add(EffectKind::Offset, None);
        add(EffectKind::CoulombAsymmetry, None);
        for f in [0.025, 0.05, 0.1, 0.2] {
            add(EffectKind::Stribeck, Some(f * vrms));
        }
        add(EffectKind::ViscousNonlinear, None);
        add(EffectKind::Armature, None);
        add(EffectKind::ConfigurationDisturbance, None);
        add(EffectKind::PositionFriction, None);
        for f in [0.03, 0.1, 0.3] {
            add(EffectKind::Hysteresis, Some(f * range));
        }
        // x₀ = F/k, the cable's stretch under the joint's friction: tens of µm on a 4000 N/m
        // insertion cable holding 0.2 N, far below the hysteresis bank's travels.
        for f in [0.0015, 0.003, 0.006] {
            add(EffectKind::Compliance, Some(f * range));
        }
        add(EffectKind::Drift, None);
        if wanted(EffectKind::Cogging) {
            match options.transmission.as_ref().and_then(|t| t.get(k)) {
                Some(&r) => {
                    for &n in &options.cogging_periods {
                        let mut t = term(EffectKind::Cogging);
                        t.scale = Some(n);
                        t.transmission = Some(r);
                        terms.push(t);
                    }
                }
                None => skipped.push(Rejection {
                    name: "cogging".into(),
                    joints: vec![k],
                    label: format!("cogging on {}", model.joints[k].name),
                    reason: "not searched: the motor transmission is unknown (give it with --transmission)".into(),
                    p_value: None,
                    heldout_gain: None,
                }),
            }
        }
    }
    // Rotor inertia is a property of every drive at once: one candidate for all joints competes
    // fairly with a payload, which also changes the inertia of several joints.
    if wanted(EffectKind::Armature) && dof > 1 {
        terms.push(EffectTerm::new(EffectKind::Armature, None));
    }
    if wanted(EffectKind::Payload) {
        for (b, _) in &train.bodies {
            let mut t = EffectTerm::new(EffectKind::Payload, None);
            t.body = Some(model.bodies[*b].name.clone());
            terms.push(t);
        }
    }
    for t in &mut terms {
        t.columns = match (t.kind, t.joint) {
            (EffectKind::Armature, None) => model.joints.iter().map(|j| format!("q̈ of {}", j.name)).collect(),
            _ => t.column_names(),
        };
    }
    (terms, skipped)
}

/// Why a `compliance` candidate is not a cable, if it is not. With the encoder on the motor, all
/// of a joint's Coulomb friction reaches the motor through the cable's stretch, so a cable's
/// term takes over most of the friction the declared `sign(q̇)` column carried; a small stretch
/// term beside an unchanged Coulomb term only reshapes the friction transition. On the simulated
/// rig (seeds 1–4 and 15) the stretch term's coefficient is 101–113 % of the Coulomb coefficient
/// fitted without it when the cable is compliant, and 5–8 % on the nominal rig, where it makes
/// up for the friction velocity's rounding of each reversal.
fn not_the_cable(
    model: &Model,
    base: &BaseParameters,
    free: &[bool],
    coef: &[f64],
    given: Option<&Identification>,
    term: &EffectTerm,
    test: &regression::GroupTest,
) -> Option<String> {
    let (EffectKind::Compliance, Some(k)) = (term.kind, term.joint) else { return None };
    let j = base.independent.iter().position(|&p| p == model.friction_offset() + 2 * k + 1)?;
    let coulomb = if free[j] { coef[free[..j].iter().filter(|f| **f).count()] } else { given?.beta[j] };
    if coulomb <= 0.0 {
        return Some(format!(
            "significant (p = {:.2e}) but the joint's fitted Coulomb friction ({coulomb:.3e}) is not positive: no friction for a cable to carry",
            test.p_value
        ));
    }
    let share = test.coefficients[0] / coulomb;
    (share < 0.5).then(|| {
        format!(
            "significant (p = {:.2e}) but carries {:.0} % of the joint's Coulomb friction ({:.3e} against {:.3e}); a cable would carry most of it",
            test.p_value,
            100.0 * share,
            test.coefficients[0],
            coulomb
        )
    })
}

/// The columns of `term` on a prepared log.
fn term_columns(model: &Model, term: &EffectTerm, data: &Prepared) -> Vec<Column> {
    let dof = data.dof;
    if term.kind == EffectKind::Payload {
        let body = model.bodies.iter().position(|b| Some(&b.name) == term.body.as_ref());
        return data.bodies.iter().find(|(b, _)| Some(*b) == body).map(|(_, c)| c.clone()).unwrap_or_default();
    }
    let Some(k) = term.joint else {
        if term.kind == EffectKind::Armature {
            return (0..dof)
                .map(|k| Column::Joint(k, data.kept.iter().map(|&i| data.pre.qdd[i * dof + k]).collect()))
                .collect();
        }
        return vec![];
    };
    let width = term.width();
    let pre = &data.pre;
    let mut state = TermState::default();
    let mut out = vec![0.0; width];
    let mut columns = vec![Vec::with_capacity(data.samples()); width];
    if term.kind.filtered_like_torque() {
        // Every sample, from the unfiltered position and the friction velocity; then filtered.
        let n = pre.samples();
        let mut full = vec![0.0; n * width];
        for s in 0..n {
            let (q, v) = (data.q_raw[s * dof + k], pre.qd_friction[s * dof + k]);
            term.features(q, v, 0.0, pre.t[s], &mut state, &mut out);
            full[s * width..(s + 1) * width].copy_from_slice(&out);
        }
        let filtered = pre.filter_like_torque(&full, width).expect("the torque was filtered with these settings");
        for &i in &data.kept {
            for (c, column) in columns.iter_mut().enumerate() {
                column.push(filtered[i * width + c]);
            }
        }
    } else {
        for &i in &data.kept {
            let x = i * dof + k;
            term.features(pre.q[x], pre.qd[x], pre.qdd[x], pre.t[i], &mut state, &mut out);
            for (c, column) in columns.iter_mut().enumerate() {
                column.push(out[c]);
            }
        }
    }
    columns.into_iter().map(|v| Column::Joint(k, v)).collect()
}

/// The held-out split of the training log: fit on the even blocks, judge on the odd ones.
fn block_split(block: &[usize]) -> (Vec<bool>, Vec<bool>) {
    let train: Vec<bool> = block.iter().map(|b| b % 2 == 0).collect();
    let test = train.iter().map(|t| !t).collect();
    (train, test)
}

/// Block index of each kept sample; the last partial block joins the one before it.
fn blocks(data: &Prepared, block_s: f64) -> (Vec<usize>, usize) {
    let per = (block_s * data.fs).max(1.0);
    let first = data.kept[0];
    let raw: Vec<usize> = data.kept.iter().map(|&i| ((i - first) as f64 / per) as usize).collect();
    let last = *raw.last().unwrap_or(&0);
    let count_last = raw.iter().filter(|&&b| b == last).count();
    let merge = last > 0 && (count_last as f64) < 0.5 * per / (data.kept.get(1).map_or(1, |k| k - first)) as f64;
    let block: Vec<usize> = raw.iter().map(|&b| if merge && b == last { last - 1 } else { b }).collect();
    let count = block.last().map_or(0, |b| b + 1);
    (block, count)
}

/// The weighted problem on one log: the target `y = w·(τ − τ_given)` and every column scaled by
/// the joint weights `w`.
struct Problem {
    dof: usize,
    weights: Vec<f64>,
    tau: Vec<f64>,
    y: Vec<f64>,
    declared: Vec<Column>,
    /// Which declared columns are fitted (the others are held at the given model's values).
    free: Vec<bool>,
}

impl Problem {
    fn new(data: &Prepared, tau: Vec<f64>, fixed: Vec<f64>, weights: &[f64], free: &[bool]) -> Self {
        let dof = data.dof;
        let y = tau.iter().zip(&fixed).enumerate().map(|(i, (t, f))| (t - f) * weights[i % dof]).collect();
        let declared = data
            .declared
            .iter()
            .map(|c| {
                let mut c = c.clone();
                c.scale_rows(weights);
                c
            })
            .collect();
        Self { dof, weights: weights.to_vec(), tau, y, declared, free: free.to_vec() }
    }

    fn weighted(&self, mut columns: Vec<Column>) -> Vec<Column> {
        columns.iter_mut().for_each(|c| c.scale_rows(&self.weights));
        columns
    }

    /// The declared columns that are fitted.
    fn free_columns(&self) -> impl Iterator<Item = &Column> {
        self.declared.iter().zip(&self.free).filter(|(_, f)| **f).map(|(c, _)| c)
    }

    /// Unweighted per-joint metrics of the fit `coefficients` on `columns` over `rows`.
    fn metrics(&self, columns: &[&Column], coefficients: &[f64], rows: Rows) -> Metrics {
        let e = residual(columns, coefficients, &self.y, self.dof);
        let (mut tau, mut pred) = (Vec::new(), Vec::new());
        for s in 0..self.tau.len() / self.dof {
            if let Rows::Where(m) = rows {
                if !m[s] {
                    continue;
                }
            }
            for k in 0..self.dof {
                let i = s * self.dof + k;
                tau.push(self.tau[i]);
                pred.push(self.tau[i] - e[i] / self.weights[k]);
            }
        }
        joint_metrics(&tau, &pred, self.dof).into()
    }

    /// Unweighted residual of a fit, on every row.
    fn residual(&self, columns: &[&Column], coefficients: &[f64]) -> Vec<f64> {
        let e = residual(columns, coefficients, &self.y, self.dof);
        e.iter().enumerate().map(|(i, e)| e / self.weights[i % self.dof]).collect()
    }
}

/// Where held-out errors are measured: a validation log, or the odd blocks of the training log
/// while fitting on the even ones.
enum HeldOut {
    Validation(Problem),
    Blocks { train: Vec<bool>, test: Vec<bool> },
}

/// A candidate in the search: its term and its weighted columns on each log.
struct Candidate {
    term: EffectTerm,
    columns: Vec<Column>,
    validation: Vec<Column>,
}

/// Diagnose `train` against `model`'s declared dynamics (refitted, or `given`), holding out
/// `validation` when it is given. `urdf` is embedded in the updated model.
#[allow(clippy::too_many_arguments)]
pub fn diagnose(
    model: &Model,
    base: &BaseParameters,
    urdf: &str,
    train: Log,
    validation: Option<Log>,
    given: Option<&Identification>,
    options: &DiagnoseOptions,
) -> Result<Diagnosis, DiagnoseError> {
    let dof = model.dof();
    let mut shaped;
    let model = match options.coulomb_epsilon {
        Some(epsilon) => {
            shaped = model.clone();
            shaped.coulomb_shape = CoulombShape::Tanh { epsilon };
            &shaped
        }
        None => model,
    };
    let train_data = prepare(model, base, train, options, options.max_delay_s).map_err(DiagnoseError::Training)?;
    let validation_data = validation
        .map(|v| prepare(model, base, v, options, options.max_delay_s))
        .transpose()
        .map_err(DiagnoseError::Validation)?;
    if let Some(g) = given {
        g.controller_parameters(model)?;
        if g.base_independent != base.independent {
            return Err(DiagnoseError::Input(
                "the given model's base parameters were chosen differently from this robot's; identify it again with this version".into(),
            ));
        }
    }
    let refit = given.is_none() || options.refit;
    // Against a given model, friction is refitted all the same: it drifts with temperature, and
    // its coefficients depend on how the velocity that switches it was estimated.
    let friction = model.friction_offset()..model.elastic_offset();
    let free: Vec<bool> =
        base.independent.iter().map(|j| refit || (friction.contains(j) && !options.hold_friction)).collect();
    let fixed_prediction = |data: &Prepared| -> Vec<f64> {
        let mut pred = vec![0.0; data.samples() * dof];
        if let (Some(g), false) = (given, refit) {
            for ((c, b), _) in data.declared.iter().zip(&g.beta).zip(&free).filter(|(_, f)| !**f) {
                regression::axpy(&mut pred, *b, c, dof);
            }
            for term in &g.effects {
                for (c, x) in term_columns(model, term, data).iter().zip(&term.coefficients) {
                    regression::axpy(&mut pred, *x, c, dof);
                }
            }
        }
        pred
    };

    // Joint weights from the declared model's residual: N·m and N do not mix.
    let weights = {
        let tau = train_data.tau(0);
        let fixed = fixed_prediction(&train_data);
        let unit = Problem::new(&train_data, tau, fixed, &vec![1.0; dof], &free);
        let cols: Vec<&Column> = unit.free_columns().collect();
        let x = least_squares(&cols, &unit.y, dof, Rows::All).ok_or(DiagnoseError::Singular)?;
        let e = residual(&cols, &x, &unit.y, dof);
        (0..dof)
            .map(|k| {
                let rms =
                    (e.iter().skip(k).step_by(dof).map(|v| v * v).sum::<f64>() / train_data.samples() as f64).sqrt();
                if rms > 0.0 {
                    1.0 / rms
                } else {
                    1.0
                }
            })
            .collect::<Vec<f64>>()
    };
    let (block, block_count) = blocks(&train_data, options.block_s);
    let split = || {
        let (train, test) = block_split(&block);
        HeldOut::Blocks { train, test }
    };

    // 1. Delay.
    let max_shift = (options.max_delay_s * train_data.fs).round() as isize;
    let mut delay = 0isize;
    let mut accepted: Vec<Finding> = Vec::new();
    let mut delay_rejection = None;
    if options.effects.contains(&EffectKind::Delay) && max_shift > 0 {
        let outcome = search_delay(&DelaySearch {
            model,
            train: &train_data,
            validation: validation_data.as_ref(),
            weights: &weights,
            free: &free,
            fixed_prediction: &fixed_prediction,
            max_shift,
            block: &block,
            block_count,
            options,
        });
        delay = outcome.0;
        match outcome.1 {
            Ok(finding) => accepted.push(finding),
            Err(rejection) => delay_rejection = Some(rejection),
        }
    }

    let problem = Problem::new(&train_data, train_data.tau(delay), fixed_prediction(&train_data), &weights, &free);
    let heldout = match &validation_data {
        Some(v) => HeldOut::Validation(Problem::new(v, v.tau(delay), fixed_prediction(v), &weights, &free)),
        None => split(),
    };
    let (templates, mut rejected) = candidates(model, &train_data, options);
    if let Some(r) = delay_rejection {
        rejected.insert(0, r);
    }
    let pool: Vec<Candidate> = parallel_map(templates, |term| {
        let columns = problem.weighted(term_columns(model, &term, &train_data));
        let validation = match (&heldout, &validation_data) {
            (HeldOut::Validation(p), Some(v)) => p.weighted(term_columns(model, &term, v)),
            _ => vec![],
        };
        Candidate { term, columns, validation }
    })
    .into_iter()
    .filter(|c| !c.columns.is_empty())
    .collect();
    let candidate_count = pool.len();
    // Why each candidate is out for now; a rejection without a p-value is final.
    let mut status: Vec<Option<Rejection>> = vec![None; pool.len()];
    let mut chosen: Vec<usize> = Vec::new();

    // 2. Forward selection.
    for round in 1.. {
        if accepted.len() >= options.max_effects {
            break;
        }
        let base_cols = model_columns(&problem, &pool, &chosen);
        let base_gram = gram(&base_cols, dof, Rows::All);
        let coef = regression::solve_scaled(&base_gram, &rhs(&base_cols, &problem.y, dof, Rows::All))
            .ok_or(DiagnoseError::Singular)?;
        let coef: Vec<f64> = coef.iter().copied().collect();
        let e0 = residual(&base_cols, &coef, &problem.y, dof);
        let mut tested: Vec<(usize, regression::GroupTest)> = Vec::new();
        let open: Vec<usize> = (0..pool.len())
            .filter(|i| !chosen.contains(i) && status[*i].as_ref().is_none_or(|r| r.p_value.is_some()))
            .collect();
        let tests = parallel_map(open, |i| {
            let group: Vec<&Column> = pool[i].columns.iter().collect();
            (i, test_group(&base_cols, &base_gram, &e0, &group, &block, block_count, dof))
        });
        for (i, outcome) in tests {
            let c = &pool[i];
            match outcome {
                Some(t) if t.unexplained * options.max_vif >= 1.0 => tested.push((i, t)),
                other => {
                    let vif = other.map_or(f64::INFINITY, |t| 1.0 / t.unexplained);
                    status[i] = Some(rejection(
                        model,
                        &c.term,
                        format!(
                            "not identifiable on this data: the model already explains it (VIF {vif:.1e} > {})",
                            options.max_vif
                        ),
                        None,
                        None,
                    ));
                }
            }
        }
        if tested.is_empty() {
            break;
        }
        let p_values: Vec<f64> = tested.iter().map(|(_, t)| t.p_value).collect();
        let pass = regression::holm(&p_values, options.alpha);
        let mut order: Vec<usize> = (0..tested.len()).collect();
        order.sort_by(|&a, &b| p_values[a].total_cmp(&p_values[b]));
        let mut passing: Vec<(usize, f64, Vec<f64>, f64, f64)> = Vec::new();
        let mut scoring: Option<HeldOutBase> = None;
        for (rank, &o) in order.iter().enumerate() {
            let (i, t) = &tested[o];
            let threshold = regression::holm_threshold(options.alpha, tested.len(), rank);
            if !pass[o] {
                status[*i] = Some(rejection(
                    model,
                    &pool[*i].term,
                    format!(
                        "not significant: p = {:.2e} above Holm's threshold {:.2e} in round {round}",
                        t.p_value, threshold
                    ),
                    Some(t.p_value),
                    None,
                ));
                continue;
            }
            if let Some(sign) = pool[*i].term.kind.physical_sign() {
                if t.coefficients[0] * sign < 0.0 {
                    status[*i] = Some(rejection(model, &pool[*i].term, format!(
                        "significant (p = {:.2e}) but with the wrong sign for this effect (coefficient {:.3e}): some other error correlates with it",
                        t.p_value, t.coefficients[0]
                    ), Some(t.p_value), None));
                    continue;
                }
            }
            if let Some(reason) = not_the_cable(model, base, &free, &coef, given, &pool[*i].term, t) {
                status[*i] = Some(rejection(model, &pool[*i].term, reason, Some(t.p_value), None));
                continue;
            }
            let scoring = scoring.get_or_insert_with(|| HeldOutBase::new(&problem, &heldout, &pool, &chosen));
            let (gains, total) = scoring.gain(&problem, &heldout, &pool, &chosen, *i);
            let joints = effect_joints(&pool[*i].term, dof);
            // Accepted on the joint it helps most, ranked by what it does for the whole robot,
            // so that an effect acting on several joints competes fairly with one-joint terms.
            let gain = joints.iter().map(|&k| gains[k]).fold(f64::NEG_INFINITY, f64::max);
            if gain < options.min_gain {
                status[*i] = Some(rejection(
                    model,
                    &pool[*i].term,
                    format!(
                        "significant (p = {:.2e}) but cuts the held-out error by only {:.1} % (< {:.1} %)",
                        t.p_value,
                        100.0 * gain,
                        100.0 * options.min_gain
                    ),
                    Some(t.p_value),
                    Some(gain),
                ));
                continue;
            }
            status[*i] = None;
            passing.push((o, gain, gains, threshold, total));
        }
        let Some((o, gain, gains, threshold, _)) = most_useful(passing, |o| pool[tested[o].0].columns.len()) else {
            break;
        };
        let (winner, test) = tested[o].clone();
        // Candidates that passed too but that the winner explains are its aliases.
        let mut with_winner = chosen.clone();
        with_winner.push(winner);
        let next_cols = model_columns(&problem, &pool, &with_winner);
        let next_gram = gram(&next_cols, dof, Rows::All);
        let mut aliases = Vec::new();
        for (j, t) in &tested {
            if *j == winner || status[*j].is_some() {
                continue;
            }
            let group: Vec<&Column> = pool[*j].columns.iter().collect();
            let after = test_group(&next_cols, &next_gram, &e0, &group, &block, block_count, dof);
            let left = after.map_or(0.0, |a| a.unexplained / t.unexplained);
            if left < 0.05 {
                aliases.push(pool[*j].term.describe(&model.joint_names()));
                let reason = format!(
                    "indistinguishable on this data from the accepted {}",
                    pool[winner].term.describe(&model.joint_names())
                );
                status[*j] = Some(rejection(model, &pool[*j].term, reason, Some(t.p_value), None));
            }
        }
        chosen.push(winner);
        let c = &pool[winner];
        let mut term = c.term.clone();
        term.coefficients = test.coefficients.iter().zip(c.columns.iter()).map(|(x, _)| *x).collect();
        term.sigma = test.sigma.clone();
        let joints = effect_joints(&term, dof);
        let (mass_kg, body) = if term.kind == EffectKind::Payload {
            (Some(term.coefficients[0]), term.body.clone())
        } else {
            (None, None)
        };
        accepted.push(Finding {
            name: term.kind.id().into(),
            joints,
            label: term.describe(&model.joint_names()),
            term,
            statistic: test.f_statistic,
            p_value: test.p_value,
            threshold,
            heldout_gain: gain,
            heldout_gain_per_joint: gains,
            aliases,
            mass_kg,
            body,
            round,
        });
    }

    // 3. Final joint fit, errors before and after, and the updated model.
    let declared_only = model_columns(&problem, &pool, &[]);
    let final_cols = model_columns(&problem, &pool, &chosen);
    let x_before = least_squares(&declared_only, &problem.y, dof, Rows::All).ok_or(DiagnoseError::Singular)?;
    let x_after = least_squares(&final_cols, &problem.y, dof, Rows::All).ok_or(DiagnoseError::Singular)?;
    let n_declared = declared_only.len();
    // Coefficients of the effects from the joint fit (they moved as later effects came in).
    let mut offset = n_declared;
    for (f, &i) in accepted.iter_mut().filter(|f| f.term.kind != EffectKind::Delay).zip(&chosen) {
        let width = pool[i].columns.len();
        f.term.coefficients = x_after[offset..offset + width].to_vec();
        if f.term.kind == EffectKind::Payload {
            f.mass_kg = Some(f.term.coefficients[0]);
        }
        offset += width;
    }
    // Before: the declared model on the data as logged, without any shift found (the problem
    // already built when no shift was).
    let before = if delay == 0 {
        error_summary(&problem, &heldout, &pool, &[])
    } else {
        let unshifted = Problem::new(&train_data, train_data.tau(0), fixed_prediction(&train_data), &weights, &free);
        let unshifted_heldout = match &validation_data {
            Some(v) => HeldOut::Validation(Problem::new(v, v.tau(0), fixed_prediction(v), &weights, &free)),
            None => split(),
        };
        error_summary(&unshifted, &unshifted_heldout, &pool, &[])
    };
    let after = error_summary(&problem, &heldout, &pool, &chosen);
    let series = series(&train_data, &problem, &declared_only, &x_before, &final_cols, &x_after, &pool, &chosen);

    let mut updated = match given {
        Some(g) => g.clone(),
        None => declared_model(model, base, urdf, &train_data, &series, options, train.t.len())?,
    };
    // Against a given model its freed (friction) coefficients take the joint fit's values; a
    // refitted model keeps the OLS of `declared_model`, made with the effects taken out.
    let mut fitted = x_after.iter();
    for ((b, j), _) in updated.beta.iter_mut().zip(&base.independent).zip(&free).filter(|(_, f)| **f && !refit) {
        *b = *fitted.next().expect("one coefficient per free column");
        // A refitted friction coefficient is a standard parameter of its own.
        if let Some(params) = updated.params.as_mut().filter(|_| !refit) {
            params[*j] = *b;
        }
    }
    if refit {
        updated.params = None;
    }
    updated.effects.extend(accepted.iter().map(|f| f.term.clone()));

    for (i, c) in pool.iter().enumerate().filter(|(i, _)| !chosen.contains(i)) {
        rejected.push(status[i].clone().unwrap_or_else(|| {
            rejection(model, &c.term, "not reached: the search stopped at max_effects".into(), None, None)
        }));
    }
    Ok(Diagnosis {
        format: "arash-diagnosis/1".into(),
        robot_name: model.name.clone(),
        joint_names: model.joint_names(),
        prismatic: model.joints.iter().map(|j| j.kind == crate::model::JointKind::Prismatic).collect(),
        accepted,
        rejected,
        before,
        after,
        settings: DiagnoseSettings {
            cutoff_hz: train_data.pre.cutoff_hz,
            decimate: train_data.kept.get(1).map_or(1, |k| k - train_data.kept[0]),
            block_s: options.block_s,
            blocks: block_count,
            alpha: options.alpha,
            min_gain: options.min_gain,
            max_vif: options.max_vif,
            max_delay_s: options.max_delay_s,
            refit,
            heldout: if validation.is_some() {
                "the validation log".into()
            } else {
                "the odd-numbered blocks, fitting on the even ones".into()
            },
            candidates: candidate_count + 1,
        },
        model: updated,
        series,
    })
}

/// Of the candidates that passed (test index, own-joint gain, per-joint gains, Holm threshold,
/// whole-robot gain), the one to add: the largest whole-robot gain, except that a candidate with
/// fewer columns within 10 % of it is preferred. A payload's four columns can mimic an offset
/// on one joint; the simpler explanation should win when the data cannot tell them apart.
fn most_useful(
    passing: Vec<(usize, f64, Vec<f64>, f64, f64)>,
    width: impl Fn(usize) -> usize,
) -> Option<(usize, f64, Vec<f64>, f64, f64)> {
    let best = passing.iter().map(|p| p.4).fold(f64::NEG_INFINITY, f64::max);
    passing
        .into_iter()
        .filter(|p| p.4 >= 0.9 * best)
        .min_by(|a, b| width(a.0).cmp(&width(b.0)).then(b.4.total_cmp(&a.4)))
}

/// `f` over `items` on every core, in order. Candidates are independent of each other, and their
/// columns and tests are most of a diagnosis's time.
fn parallel_map<T: Send, R: Send>(items: Vec<T>, f: impl Fn(T) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(items.len().max(1));
    let per = items.len().div_ceil(threads).max(1);
    let mut chunks: Vec<Vec<T>> = Vec::new();
    let mut items = items.into_iter().peekable();
    while items.peek().is_some() {
        chunks.push(items.by_ref().take(per).collect());
    }
    std::thread::scope(|scope| {
        let f = &f;
        let handles: Vec<_> =
            chunks.into_iter().map(|chunk| scope.spawn(move || chunk.into_iter().map(f).collect::<Vec<R>>())).collect();
        handles.into_iter().flat_map(|h| h.join().expect("a diagnosis worker panicked")).collect()
    })
}

/// The model file for a refitted declared model: OLS on the samples the diagnosis used, with the
/// effects found taken out of the torque first (their coefficients are set after). σ%, the fit
/// and the condition number come from that fit, as `arash identify` reports them.
fn declared_model(
    model: &Model,
    base: &BaseParameters,
    urdf: &str,
    data: &Prepared,
    series: &Series,
    options: &DiagnoseOptions,
    samples_in: usize,
) -> Result<Identification, DiagnoseError> {
    use crate::identify::estimate::{fit_stacked, Method};
    use crate::identify::{consistent, nearest_standard_parameters, DataSummary, Settings};
    let dof = data.dof;
    let rows = data.samples() * dof;
    let w = faer::Mat::<f64>::from_fn(rows, data.declared.len(), |i, j| data.declared[j].at(i / dof, i % dof, dof));
    let mut tau = series.tau.clone();
    for contribution in &series.contributions {
        tau.iter_mut().zip(contribution).for_each(|(t, c)| *t -= c);
    }
    let stride = data.kept.get(1).map_or(1, |k| k - data.kept[0]);
    let block = ((options.block_s * data.fs / stride as f64).round() as usize).max(1);
    let fit = fit_stacked(&w, &tau, dof, base, Method::Ols, block)
        .map_err(|e| DiagnoseError::Identify(IdentifyError::Estimate(e)))?;
    let nearest = nearest_standard_parameters(model, base, &fit.beta);
    Ok(Identification {
        format: "arash-model/1".into(),
        software_version: env!("CARGO_PKG_VERSION").into(),
        robot_name: model.name.clone(),
        urdf: urdf.to_string(),
        parameter_names: model.parameter_names(),
        base_names: base.names.clone(),
        base_expressions: base.expressions.clone(),
        base_independent: base.independent.clone(),
        beta: fit.beta.clone(),
        sigma_percent: fit.sigma_percent.clone(),
        params: None,
        training: fit.metrics.clone().into(),
        training_ols: fit.metrics.clone().into(),
        min_pseudo_inertia_eigenvalue: consistent::min_pseudo_inertia_eigenvalues(model, &nearest),
        condition_number: fit.condition_number,
        settings: Settings {
            method: IdentifyMethod::Ols,
            periods: None,
            cutoff_hz: data.pre.cutoff_hz,
            order: data.pre.order,
            decimate: stride,
            pull: 0.0,
            stiffness_bounds: (None, None),
        },
        data: DataSummary {
            sources: vec![],
            samples_in,
            samples_used: data.samples(),
            sample_rate_hz: data.fs,
            periods_averaged: 1,
        },
        effects: vec![],
    })
}

/// The model's columns: the declared ones that are fitted, then the chosen effects'.
fn model_columns<'a>(problem: &'a Problem, pool: &'a [Candidate], chosen: &[usize]) -> Vec<&'a Column> {
    problem.free_columns().chain(chosen.iter().flat_map(|&i| pool[i].columns.iter())).collect()
}

/// The same columns on the validation log.
fn validation_columns<'a>(validation: &'a Problem, pool: &'a [Candidate], chosen: &[usize]) -> Vec<&'a Column> {
    validation.free_columns().chain(chosen.iter().flat_map(|&i| pool[i].validation.iter())).collect()
}

/// Weighted squared error per joint of `y − X x` over `rows`.
fn sse(columns: &[&Column], x: &[f64], y: &[f64], dof: usize, rows: Rows) -> Vec<f64> {
    let e = residual(columns, x, y, dof);
    let mut out = vec![0.0; dof];
    for (i, v) in e.iter().enumerate() {
        if let Rows::Where(m) = rows {
            if !m[i / dof] {
                continue;
            }
        }
        out[i % dof] += v * v;
    }
    out
}

/// Held-out squared error per joint of the model `chosen` (+ `extra`), fitted on the training
/// rows.
fn heldout_sse(problem: &Problem, heldout: &HeldOut, pool: &[Candidate], chosen: &[usize]) -> Vec<f64> {
    let dof = problem.dof;
    let cols = model_columns(problem, pool, chosen);
    match heldout {
        HeldOut::Blocks { train, test } => {
            let x = least_squares(&cols, &problem.y, dof, Rows::Where(train)).unwrap_or_else(|| vec![0.0; cols.len()]);
            sse(&cols, &x, &problem.y, dof, Rows::Where(test))
        }
        HeldOut::Validation(v) => {
            let x = least_squares(&cols, &problem.y, dof, Rows::All).unwrap_or_else(|| vec![0.0; cols.len()]);
            sse(&validation_columns(v, pool, chosen), &x, &v.y, dof, Rows::All)
        }
    }
}

/// The current model's fit on the rows it is trained on for held-out scoring, computed once per
/// round so that each candidate costs only its own products with the model.
struct HeldOutBase<'a> {
    cols: Vec<&'a Column>,
    gram: nalgebra::DMatrix<f64>,
    rhs: nalgebra::DVector<f64>,
    sse: Vec<f64>,
}

impl<'a> HeldOutBase<'a> {
    fn new(problem: &'a Problem, heldout: &HeldOut, pool: &'a [Candidate], chosen: &[usize]) -> Self {
        let dof = problem.dof;
        let cols = model_columns(problem, pool, chosen);
        let rows = match heldout {
            HeldOut::Blocks { train, .. } => Rows::Where(train),
            HeldOut::Validation(_) => Rows::All,
        };
        let gram = gram(&cols, dof, rows);
        let rhs = rhs(&cols, &problem.y, dof, rows);
        let sse = heldout_sse(problem, heldout, pool, chosen);
        Self { cols, gram, rhs, sse }
    }

    /// Relative cut of the held-out squared error from adding candidate `i`: per joint, and over
    /// all joints together (in the weighted units, where every joint counts by its noise).
    fn gain(
        &self,
        problem: &Problem,
        heldout: &HeldOut,
        pool: &[Candidate],
        chosen: &[usize],
        i: usize,
    ) -> (Vec<f64>, f64) {
        let dof = problem.dof;
        let group: Vec<&Column> = pool[i].columns.iter().collect();
        let rows = match heldout {
            HeldOut::Blocks { train, .. } => Rows::Where(train),
            HeldOut::Validation(_) => Rows::All,
        };
        let after = match regression::fit_augmented(&self.cols, &self.gram, &self.rhs, &group, &problem.y, dof, rows) {
            None => self.sse.clone(),
            Some(x) => match heldout {
                HeldOut::Blocks { test, .. } => {
                    let all: Vec<&Column> = self.cols.iter().copied().chain(group.iter().copied()).collect();
                    sse(&all, &x, &problem.y, dof, Rows::Where(test))
                }
                HeldOut::Validation(v) => {
                    let all: Vec<&Column> =
                        validation_columns(v, pool, chosen).into_iter().chain(pool[i].validation.iter()).collect();
                    sse(&all, &x, &v.y, dof, Rows::All)
                }
            },
        };
        let before = &self.sse;
        let per_joint = before.iter().zip(&after).map(|(b, a)| if *b > 0.0 { 1.0 - a / b } else { 0.0 }).collect();
        let total = 1.0 - after.iter().sum::<f64>() / before.iter().sum::<f64>().max(f64::MIN_POSITIVE);
        (per_joint, total)
    }
}

fn error_summary(problem: &Problem, heldout: &HeldOut, pool: &[Candidate], chosen: &[usize]) -> ErrorSummary {
    let dof = problem.dof;
    let cols = model_columns(problem, pool, chosen);
    let x_all = least_squares(&cols, &problem.y, dof, Rows::All).unwrap_or_else(|| vec![0.0; cols.len()]);
    let training = problem.metrics(&cols, &x_all, Rows::All);
    let heldout = match heldout {
        HeldOut::Blocks { train, test } => {
            let x = least_squares(&cols, &problem.y, dof, Rows::Where(train)).unwrap_or_else(|| vec![0.0; cols.len()]);
            problem.metrics(&cols, &x, Rows::Where(test))
        }
        HeldOut::Validation(v) => v.metrics(&validation_columns(v, pool, chosen), &x_all, Rows::All),
    };
    ErrorSummary { training, heldout }
}

fn effect_joints(term: &EffectTerm, dof: usize) -> Vec<usize> {
    match term.joint {
        Some(k) => vec![k],
        None => (0..dof).collect(),
    }
}

fn rejection(model: &Model, term: &EffectTerm, reason: String, p_value: Option<f64>, gain: Option<f64>) -> Rejection {
    Rejection {
        name: term.kind.id().into(),
        joints: effect_joints(term, model.dof()),
        label: term.describe(&model.joint_names()),
        reason,
        p_value,
        heldout_gain: gain,
    }
}

#[allow(clippy::too_many_arguments)]
fn series(
    data: &Prepared,
    problem: &Problem,
    before_cols: &[&Column],
    x_before: &[f64],
    after_cols: &[&Column],
    x_after: &[f64],
    pool: &[Candidate],
    chosen: &[usize],
) -> Series {
    let dof = data.dof;
    let mut contributions = Vec::new();
    let mut offset = after_cols.len() - chosen.iter().map(|&i| pool[i].columns.len()).sum::<usize>();
    for &i in chosen {
        let mut v = vec![0.0; data.samples() * dof];
        for (c, x) in pool[i].columns.iter().zip(&x_after[offset..]) {
            regression::axpy(&mut v, *x, c, dof);
        }
        v.iter_mut().enumerate().for_each(|(r, x)| *x /= problem.weights[r % dof]);
        offset += pool[i].columns.len();
        contributions.push(v);
    }
    Series {
        t: data.kept.iter().map(|&i| data.pre.t[i]).collect(),
        q: data.at_kept(&data.pre.q),
        qd: data.at_kept(&data.pre.qd),
        qdd: data.at_kept(&data.pre.qdd),
        tau: problem.tau.clone(),
        residual_before: problem.residual(before_cols, x_before),
        residual_after: problem.residual(after_cols, x_after),
        contributions,
    }
}

/// What the delay search works on.
struct DelaySearch<'a> {
    model: &'a Model,
    train: &'a Prepared,
    validation: Option<&'a Prepared>,
    weights: &'a [f64],
    free: &'a [bool],
    fixed_prediction: &'a dyn Fn(&Prepared) -> Vec<f64>,
    max_shift: isize,
    block: &'a [usize],
    block_count: usize,
    options: &'a DiagnoseOptions,
}

/// Search an integer shift of the torque against the position, and accept it only if it is
/// significant (a block Wald test of the linearised delay, the derivative of the predicted
/// torque) and cuts the held-out error by at least `min_gain`. Returns the shift to apply.
fn search_delay(search: &DelaySearch) -> (isize, Result<Finding, Rejection>) {
    match delay_finding(search) {
        Ok(f) => (f.term.scale.unwrap_or(0.0) as isize, Ok(f)),
        Err((shift, r)) if shift.abs() <= ALIGNMENT_SAMPLES => (shift, Err(r)),
        Err((_, r)) => (0, Err(r)),
    }
}

/// Shifts up to this many samples are alignment, not an effect: a log whose torque was held over
/// the cycle after the position was read (zero-order hold, as both the simulator and the daemon
/// log) is misaligned by up to a sample by construction. They are applied silently.
pub const ALIGNMENT_SAMPLES: isize = 1;

// Called once per diagnosis, so the large error variant costs nothing worth boxing for.
#[allow(clippy::result_large_err)]
fn delay_finding(search: &DelaySearch) -> Result<Finding, (isize, Rejection)> {
    let DelaySearch {
        model,
        train,
        validation,
        weights,
        free,
        fixed_prediction,
        max_shift,
        block,
        block_count,
        options,
    } = *search;
    let dof = train.dof;
    let mut term = EffectTerm::new(EffectKind::Delay, None);
    term.columns = vec!["shift".into()];
    let reject =
        |term: &EffectTerm, reason: String, p: Option<f64>, gain: Option<f64>| rejection(model, term, reason, p, gain);
    let fixed = fixed_prediction(train);
    // One weighted problem; only its target moves with the shift.
    let zero = Problem::new(train, train.tau(0), fixed.clone(), weights, free);
    let target = |data: &Prepared, fixed: &[f64], d: isize| -> Vec<f64> {
        data.tau(d).iter().zip(fixed).enumerate().map(|(i, (t, f))| (t - f) * weights[i % dof]).collect()
    };
    let declared_refs: Vec<&Column> = zero.free_columns().collect();
    let g = gram(&declared_refs, dof, Rows::All);
    let total_sse = |y: &[f64]| -> f64 {
        let x = regression::solve_scaled(&g, &rhs(&declared_refs, y, dof, Rows::All))
            .map_or_else(|| vec![0.0; declared_refs.len()], |x| x.iter().copied().collect());
        sse(&declared_refs, &x, y, dof, Rows::All).iter().sum()
    };
    let scores: Vec<f64> = (-max_shift..=max_shift).map(|d| total_sse(&target(train, &fixed, d))).collect();
    let best = (0..scores.len()).min_by(|&a, &b| scores[a].total_cmp(&scores[b])).unwrap_or(max_shift as usize);
    let shift = best as isize - max_shift;
    term.scale = Some(shift as f64);
    if shift == 0 {
        return Err((
            0,
            reject(&term, "no misalignment: the best shift of the torque is 0 samples".into(), None, None),
        ));
    }
    if shift.abs() <= ALIGNMENT_SAMPLES {
        let reason = format!(
            "the best shift, {shift} sample(s), is within a zero-order-hold log's own misalignment; applied as alignment"
        );
        return Err((shift, reject(&term, reason, None, None)));
    }
    if shift.abs() == max_shift {
        return Err((
            0,
            reject(
                &term,
                format!("the best shift is at the edge of the search (±{max_shift} samples); widen max_delay_s"),
                None,
                None,
            ),
        ));
    }
    // The linearised test: τ(t − d) ≈ τ(t) − d·τ̇(t).
    let x0 = least_squares(&declared_refs, &zero.y, dof, Rows::All).unwrap_or_else(|| vec![0.0; declared_refs.len()]);
    let e0 = residual(&declared_refs, &x0, &zero.y, dof);
    let predicted: Vec<f64> = zero.y.iter().zip(&e0).map(|(y, e)| y - e).collect();
    let h = (train.kept[1] - train.kept[0]) as f64 / train.fs;
    let column = Column::dense(central_difference(&predicted, dof, h, false), dof);
    let test = test_group(&declared_refs, &g, &e0, &[&column], block, block_count, dof);
    let Some(test) = test else {
        return Err((
            0,
            reject(&term, "the predicted torque does not change: a delay cannot be tested".into(), None, None),
        ));
    };
    let gains: Vec<f64> = match validation {
        Some(v) => {
            let vfixed = fixed_prediction(v);
            let vzero = Problem::new(v, v.tau(0), vfixed.clone(), weights, free);
            let vrefs: Vec<&Column> = vzero.free_columns().collect();
            let at = |d: isize| -> Vec<f64> {
                let x = least_squares(&declared_refs, &target(train, &fixed, d), dof, Rows::All)
                    .unwrap_or_else(|| vec![0.0; declared_refs.len()]);
                sse(&vrefs, &x, &target(v, &vfixed, d), dof, Rows::All)
            };
            let (b, a) = (at(0), at(shift));
            b.iter().zip(&a).map(|(b, a)| 1.0 - a / b).collect()
        }
        None => {
            let (train_rows, test_rows) = block_split(block);
            let at = |d: isize| -> Vec<f64> {
                let y = target(train, &fixed, d);
                let x = least_squares(&declared_refs, &y, dof, Rows::Where(&train_rows))
                    .unwrap_or_else(|| vec![0.0; declared_refs.len()]);
                sse(&declared_refs, &x, &y, dof, Rows::Where(&test_rows))
            };
            let (b, a) = (at(0), at(shift));
            b.iter().zip(&a).map(|(b, a)| 1.0 - a / b).collect()
        }
    };
    let gain = gains.iter().sum::<f64>() / dof as f64;
    if test.p_value > options.alpha {
        let reason = format!("not significant: p = {:.2e} > α = {}", test.p_value, options.alpha);
        return Err((0, reject(&term, reason, Some(test.p_value), Some(gain))));
    }
    if gain < options.min_gain {
        return Err((
            0,
            reject(
                &term,
                format!(
                    "a shift of {shift} samples cuts the held-out error by only {:.1} % (< {:.1} %)",
                    100.0 * gain,
                    100.0 * options.min_gain
                ),
                Some(test.p_value),
                Some(gain),
            ),
        ));
    }
    term.coefficients = vec![shift as f64 / train.fs];
    term.sigma = vec![test.sigma[0]];
    Ok(Finding {
        name: "delay".into(),
        joints: (0..dof).collect(),
        label: term.describe(&model.joint_names()),
        term,
        statistic: test.f_statistic,
        p_value: test.p_value,
        threshold: options.alpha,
        heldout_gain: gain,
        heldout_gain_per_joint: gains,
        aliases: vec![],
        mass_kg: None,
        body: None,
        round: 0,
    })
}
