//! Base parameters (paper section II-E): the combinations `β = B π` of the standard parameters that
//! joint torques can identify, with `Y(q, q̇, q̈) π = Y_r(q, q̇, q̈) β` for every `π`.
//!
//! Computed numerically (Gautier's method): stack the regressor at random states within the
//! limits, keep each column in turn if it is independent of the columns kept before it, and
//! express every other column in the kept ones. Keeping the earliest independent column makes each
//! base parameter read as "this standard parameter plus the ones regrouped into it".
//!
//! **Identifiable in practice.** An exact rank test over random states accepts a combination that
//! only states no trajectory reaches can separate. ARASH:ASiST's `rocker_a.my` and
//! `instrument_holder.my` are first moments along y in frames that both rotate with ψ; their
//! columns differ through small yaw-coupling terms. Over random states in the limits the second
//! keeps 4·10⁻³ of its norm outside the span of the others; over smooth trajectories within the
//! position, speed and acceleration limits, 10⁻⁴ at best, where every other base parameter keeps
//! more than 3·10⁻². Such a parameter is *weak*: it is found by the same column test as above,
//! repeated on the reduced regressor stacked over random band-limited trajectories within the
//! limits (their union is a richer design than any one trajectory, so what it cannot separate no
//! single trajectory can), with the tolerance [`BaseParameterOptions::weak_tolerance`]. A weak
//! parameter is regrouped into the others by least squares over those trajectories, so that κ,
//! σ% and the excitation design measure what can be identified
//! ([`BaseParameterOptions::identifiable`]). The default keeps them: identification and
//! diagnosis still fit the exact base parameters (docs/identification.md says why).

use faer::prelude::*;
use faer::Mat;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::data::Data;
use crate::model::{JointKind, Model};
use crate::regressor::regressor;

/// Settings for [`BaseParameters::compute`].
#[derive(Clone, Debug)]
pub struct BaseParameterOptions {
    /// Random states stacked; each adds `dof` rows.
    pub samples: usize,
    /// Seed of the state sampler, so the result is reproducible.
    pub seed: u64,
    /// A column is dependent when its part outside the span of earlier kept columns is below
    /// `tolerance` times its norm.
    pub tolerance: f64,
    /// A column whose norm is below this fraction of the largest column norm is round-off: the
    /// parameter does not act (an exactly zero column computed in floating point).
    pub zero_column: f64,
    /// Regrouping coefficients smaller than this in magnitude are round-off, and set to zero.
    pub coefficient_floor: f64,
    /// A base parameter whose column keeps less than this fraction of its norm outside the span
    /// of the others over [`BaseParameterOptions::reach_trajectories`] trajectories within the
    /// limits is weak (not identifiable in practice) and regrouped; 0 (the default) keeps every
    /// one. [`WEAK_TOLERANCE`] is the one [`BaseParameterOptions::identifiable`] sets; the KUKA
    /// LWR4+ and Stäubli TX40 models have no base parameter below 0.2.
    pub weak_tolerance: f64,
    /// Random trajectories stacked for the weak-parameter test.
    pub reach_trajectories: usize,
}

impl Default for BaseParameterOptions {
    fn default() -> Self {
        Self {
            samples: 400,
            seed: 0x5eed,
            tolerance: 1e-8,
            zero_column: 1e-10,
            coefficient_floor: 1e-10,
            weak_tolerance: 0.0,
            reach_trajectories: 64,
        }
    }
}

/// The weak tolerance of [`BaseParameterOptions::identifiable`]: 10⁻³ sits in the two-decade gap
/// measured on ARASH:ASiST (1.9·10⁻⁴ against 4·10⁻²).
pub const WEAK_TOLERANCE: f64 = 1e-3;

impl BaseParameterOptions {
    /// The exact base parameters only: every combination any state separates is kept (`Y π = Y_r β`
    /// holds to round-off). The default.
    pub fn keep_weak(self) -> Self {
        Self { weak_tolerance: 0.0, ..self }
    }

    /// The base parameters a trajectory within the limits can identify: the weak ones regrouped
    /// (what the excitation design optimises by default).
    pub fn identifiable(self) -> Self {
        Self { weak_tolerance: WEAK_TOLERANCE, ..self }
    }

    /// The base parameters identification fits and the excitation design measures: the
    /// identifiable ones, or with `keep_weak` every exact one. Regrouping is the default because
    /// a weak parameter's estimate is its regrouping's noise: on ARASH:ASiST it sets κ and
    /// inflates the σ of every parameter it leans on (docs/identification.md, "Identifiable in
    /// practice").
    pub fn fitted(keep_weak: bool) -> Self {
        if keep_weak {
            Self::default().keep_weak()
        } else {
            Self::default().identifiable()
        }
    }

    /// The base parameters the diagnosis fits when it is given no model: every exact one. The
    /// regrouping reproduces the torque only to its residual (< 2·10⁻³ of it), a bias of arash's
    /// own that an effect could take up: on the independent null it made `configuration_disturbance`
    /// on yaw pass in 2 of 600 logs (docs/diagnosis.md). The diagnosis's inertial parameters are
    /// nuisance, so the weak one's noise costs it nothing it reports.
    pub fn diagnosed() -> Self {
        Self::default().keep_weak()
    }
}

/// Default acceleration limit of a trajectory, per unit of the joint's speed limit (1/s).
pub const DEFAULT_ACCELERATION_PER_SPEED: f64 = 5.0;
/// Default fraction of each position range a trajectory keeps clear at both ends.
pub const DEFAULT_POSITION_MARGIN: f64 = 0.05;

/// The states a trajectory may visit: positions (margins applied), speeds and accelerations.
#[derive(Clone, Debug)]
pub struct ReachableLimits {
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub velocity: Vec<f64>,
    pub acceleration: Vec<f64>,
}

impl ReachableLimits {
    /// The model's limits less `margin` of each range at both ends; unbounded joints get ±π rad or
    /// ±0.1 m and 2 rad/s or 2 m/s. `acceleration` per joint, or `None` for
    /// [`DEFAULT_ACCELERATION_PER_SPEED`] × the speed limit.
    pub fn new(model: &Model, acceleration: Option<&[f64]>, margin: f64) -> Result<Self, LimitsError> {
        let n = model.dof();
        let (mut lower, mut upper, mut velocity) = (vec![], vec![], vec![]);
        for joint in &model.joints {
            let (lo, hi) = position_range(joint);
            let m = margin * (hi - lo);
            lower.push(lo + m);
            upper.push(hi - m);
            velocity.push(if joint.velocity.is_finite() { joint.velocity } else { 2.0 });
        }
        let acceleration = match acceleration {
            Some(a) if a.len() != n => return Err(LimitsError::Count { got: a.len(), dof: n }),
            Some(a) => {
                if let Some(&bad) = a.iter().find(|x| !(x.is_finite() && **x > 0.0)) {
                    return Err(LimitsError::NotPositive(bad));
                }
                a.to_vec()
            }
            None => velocity.iter().map(|v| DEFAULT_ACCELERATION_PER_SPEED * v).collect(),
        };
        Ok(Self { lower, upper, velocity, acceleration })
    }
}

impl ReachableLimits {
    /// How joint `j`'s motion `x(t)` (extremes `lo`, `hi`; peak speed and acceleration) fits
    /// these limits: the `(scale, centre)` for which `centre + scale·x` reaches `fill` of the
    /// binding limit (range, speed or acceleration) and sits in the middle of the range.
    pub fn fit(&self, j: usize, (lo, hi): (f64, f64), speed: f64, acceleration: f64, fill: f64) -> (f64, f64) {
        let scale = fill
            * ((self.upper[j] - self.lower[j]) / (hi - lo))
                .min(self.velocity[j] / speed)
                .min(self.acceleration[j] / acceleration);
        (scale, 0.5 * (self.upper[j] + self.lower[j]) - scale * 0.5 * (hi + lo))
    }
}

/// A joint's position limits, or ±π rad (revolute) and ±0.1 m (prismatic) when unbounded.
fn position_range(joint: &crate::model::ActuatedJoint) -> (f64, f64) {
    if joint.lower.is_finite() && joint.upper.is_finite() {
        (joint.lower, joint.upper)
    } else if joint.kind == JointKind::Prismatic {
        (-0.1, 0.1)
    } else {
        (-std::f64::consts::PI, std::f64::consts::PI)
    }
}

/// Acceleration limits that [`ReachableLimits::new`] cannot use.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LimitsError {
    #[error("acceleration_limits has {got} entries, the robot {dof} joints")]
    Count { got: usize, dof: usize },
    #[error("acceleration_limits = {0} cannot be used: expected a positive number")]
    NotPositive(f64),
}

#[derive(Debug, thiserror::Error)]
pub enum BaseParameterError {
    #[error("need at least {needed} samples to see all {params} parameters, got {got}")]
    TooFewSamples { needed: usize, params: usize, got: usize },
    #[error("tolerance {0} must be in (0, 1)")]
    BadTolerance(f64),
}

/// The identifiable parameter combinations of a model.
#[derive(Clone, Debug)]
pub struct BaseParameters {
    /// Number of base parameters `p`.
    pub rank: usize,
    /// Number of standard parameters `P`.
    pub num_params: usize,
    /// Standard-parameter indices whose regressor columns form `Y_r`, in order.
    pub independent: Vec<usize>,
    /// `B`, row-major `p × P`: `β = B π`.
    pub b: Vec<f64>,
    /// A short name per base parameter: the leading standard parameter, with `_R` when others are
    /// regrouped into it.
    pub names: Vec<String>,
    /// Readable definitions, e.g. `β3 = yaw_yoke.Izz + 0.0196·rocker_a.m`.
    pub expressions: Vec<String>,
    /// Smallest relative residual among kept columns and largest among dropped ones: the gap that
    /// separates them (a wide gap means a clear rank decision).
    pub rank_gap: (f64, f64),
    /// The weak base parameters regrouped because no trajectory within the limits separates them
    /// (empty with [`BaseParameterOptions::keep_weak`]).
    pub weak: Vec<WeakParameter>,
    /// Over the trajectories within the limits: the smallest relative residual among the base
    /// parameters kept and the largest among the weak ones (0 when none is weak); `None` when the
    /// weak-parameter test was not run.
    pub reach_gap: Option<(f64, f64)>,
}

/// A combination of the exact base parameters that no trajectory within the limits separates.
#[derive(Clone, Debug)]
pub struct WeakParameter {
    /// The exact base parameter's short name, e.g. `instrument_holder.my`.
    pub name: String,
    /// Its column's relative residual over the trajectories: the sine of its angle to the others.
    pub residual: f64,
    /// How it was regrouped, e.g. `instrument_holder.my ≈ −1.02·rocker_a.my_R + …` (columns).
    pub expression: String,
}

impl BaseParameters {
    /// Compute the base parameters of `model` from random states within its limits.
    pub fn compute(model: &Model, options: &BaseParameterOptions) -> Result<Self, BaseParameterError> {
        let (n, p) = (model.dof(), model.num_params());
        if !(options.tolerance > 0.0 && options.tolerance < 1.0) {
            return Err(BaseParameterError::BadTolerance(options.tolerance));
        }
        let needed = p.div_ceil(n) * 2;
        if options.samples < needed {
            return Err(BaseParameterError::TooFewSamples { needed, params: p, got: options.samples });
        }
        let w = stacked_regressor(model, options.samples, options.seed);
        let (independent, rank_gap, _) = select_independent_columns(&w, options.tolerance, options.zero_column);
        let b = regrouping_matrix(&w, &independent, options.coefficient_floor);
        let exact = Self::from_b(model, independent, b, rank_gap);
        if options.weak_tolerance > 0.0 {
            Ok(exact.regroup_weak(model, options))
        } else {
            Ok(exact)
        }
    }

    /// These exact base parameters with the weak ones regrouped, as [`BaseParameters::compute`]
    /// gives them for `options` with a positive weak tolerance ([`WEAK_TOLERANCE`] when 0).
    pub fn identifiable(&self, model: &Model, options: &BaseParameterOptions) -> Self {
        let tolerance = if options.weak_tolerance > 0.0 { options.weak_tolerance } else { WEAK_TOLERANCE };
        self.clone().regroup_weak(model, &BaseParameterOptions { weak_tolerance: tolerance, ..options.clone() })
    }

    fn from_b(model: &Model, independent: Vec<usize>, b: Vec<f64>, rank_gap: (f64, f64)) -> Self {
        let p = model.num_params();
        let names = model.parameter_names();
        let rank = independent.len();
        let mut short = Vec::with_capacity(rank);
        let mut expressions = Vec::with_capacity(rank);
        for (i, &lead) in independent.iter().enumerate() {
            let row = &b[i * p..(i + 1) * p];
            let regrouped = row.iter().enumerate().any(|(j, &c)| j != lead && c != 0.0);
            short.push(if regrouped { format!("{}_R", names[lead]) } else { names[lead].clone() });
            expressions.push(format!("β{} = {}", i + 1, linear_combination(row, &names)));
        }
        Self { rank, num_params: p, independent, b, names: short, expressions, rank_gap, weak: vec![], reach_gap: None }
    }

    /// Repeat the column test on `Y_r` stacked over random trajectories within the limits, with
    /// the weak tolerance, and regroup the weak columns into the kept ones by least squares over
    /// those trajectories: `β' = T β` with `T` identity on the kept and the coefficients on the
    /// weak, so `B' = T B`.
    fn regroup_weak(self, model: &Model, options: &BaseParameterOptions) -> Self {
        let limits = ReachableLimits::new(model, None, DEFAULT_POSITION_MARGIN).expect("default limits are valid");
        let w = stacked_over_trajectories(model, &self, &limits, options);
        let (kept, (min_kept, max_weak), residuals) =
            select_independent_columns(&w, options.weak_tolerance, options.zero_column);
        if kept.len() == self.rank {
            return Self { reach_gap: Some((min_kept, 0.0)), ..self };
        }
        let t = weak_regrouping(&w, &kept, options.weak_tolerance);
        let (p, big_p) = (self.rank, self.num_params);
        let mut b = vec![0.0; kept.len() * big_p];
        for (i, row) in b.chunks_mut(big_p).enumerate() {
            for (k, &tik) in t[i * p..(i + 1) * p].iter().enumerate().filter(|(_, c)| **c != 0.0) {
                row.iter_mut().zip(&self.b[k * big_p..(k + 1) * big_p]).for_each(|(r, bk)| *r += tik * bk);
            }
        }
        let independent = kept.iter().map(|&i| self.independent[i]).collect();
        let mut regrouped = Self::from_b(model, independent, b, self.rank_gap);
        let column_names: Vec<String> = kept.iter().map(|&i| self.names[i].clone()).collect();
        regrouped.weak = (0..p)
            .filter(|k| !kept.contains(k))
            .map(|k| {
                let coefficients: Vec<f64> = (0..kept.len()).map(|i| t[i * p + k]).collect();
                WeakParameter {
                    name: self.names[k].clone(),
                    residual: residuals[k],
                    expression: format!(
                        "column of {} ≈ {}",
                        self.names[k],
                        linear_combination(&coefficients, &column_names)
                    ),
                }
            })
            .collect();
        regrouped.reach_gap = Some((min_kept, max_weak));
        regrouped
    }

    /// The exact base parameters of `model`, or its identifiable ones, whichever has `independent`
    /// as its columns (a model file made with or without the weak ones); `None` when neither has.
    pub fn with_independent(model: &Model, independent: &[usize]) -> Result<Option<Self>, BaseParameterError> {
        let options = BaseParameterOptions::default();
        let exact = Self::compute(model, &options)?;
        if exact.independent == independent {
            return Ok(Some(exact));
        }
        let regrouped = exact.identifiable(model, &options);
        Ok((regrouped.independent == independent).then_some(regrouped))
    }

    /// What the weak-parameter test found, in a few lines: the gap it decided across, and each
    /// weak parameter with its residual and how it was regrouped.
    pub fn weak_report(&self) -> String {
        let Some((kept, weak)) = self.reach_gap else {
            return "weak base parameters: kept (the test was not run)\n".into();
        };
        if self.weak.is_empty() {
            return format!(
                "weak base parameters: none (over trajectories within the limits every column keeps ≥ {kept:.1e} of its norm outside the others)\n"
            );
        }
        let mut s = format!(
            "weak base parameters: {}, which no trajectory within the limits separates (residual ≤ {:.1e}, every other ≥ {:.1e}); the excitation design and identification regroup them unless --keep-weak:\n",
            self.weak.len(),
            weak,
            kept
        );
        for w in &self.weak {
            s += &format!("  {} (residual {:.1e}): {}\n", w.name, w.residual, w.expression);
        }
        s
    }

    /// `β = B π`.
    pub fn project(&self, params: &[f64], beta: &mut [f64]) {
        assert!(params.len() == self.num_params && beta.len() == self.rank, "π must have P entries and β p entries");
        for (i, out) in beta.iter_mut().enumerate() {
            let row = &self.b[i * self.num_params..(i + 1) * self.num_params];
            *out = row.iter().zip(params).map(|(a, b)| a * b).sum();
        }
    }

    /// Gather `Y_r` (row-major `rows × p`) from a full regressor (row-major `rows × P`).
    pub fn reduce(&self, y: &[f64], y_r: &mut [f64]) {
        let rows = y.len() / self.num_params;
        assert!(
            y.len() == rows * self.num_params && y_r.len() == rows * self.rank,
            "Y must be rows × P and Y_r rows × p"
        );
        for r in 0..rows {
            for (i, &j) in self.independent.iter().enumerate() {
                y_r[r * self.rank + i] = y[r * self.num_params + j];
            }
        }
    }
}

/// A uniformly random state within the limits: position limits (±π, or ±0.1 m, when unbounded),
/// speed limits (or 2 rad/s, 0.2 m/s), and accelerations up to ten times the speed limit per second.
pub fn random_state(model: &Model, rng: &mut ChaCha8Rng, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
    for (k, joint) in model.joints.iter().enumerate() {
        let (lo, hi) = position_range(joint);
        let default_speed = if joint.kind == JointKind::Prismatic { 0.2 } else { 2.0 };
        let speed = if joint.velocity.is_finite() { joint.velocity } else { default_speed };
        q[k] = rng.random_range(lo..=hi);
        qd[k] = rng.random_range(-speed..=speed);
        qdd[k] = rng.random_range(-10.0 * speed..=10.0 * speed);
    }
}

/// `W`: the regressor at `samples` random states, stacked (`samples·dof × P`).
fn stacked_regressor(model: &Model, samples: usize, seed: u64) -> Mat<f64> {
    let (n, p) = (model.dof(), model.num_params());
    let mut data = Data::new(model);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut y = vec![0.0; n * p];
    let mut w = Mat::<f64>::zeros(samples * n, p);
    for s in 0..samples {
        random_state(model, &mut rng, &mut q, &mut qd, &mut qdd);
        regressor(model, &mut data, &q, &qd, &qdd, &mut y);
        for k in 0..n {
            for j in 0..p {
                w[(s * n + k, j)] = y[k * p + j];
            }
        }
    }
    w
}

/// Keep column `j` when its component outside the span of the columns kept so far exceeds
/// `tolerance · ‖w_j‖` (Gram–Schmidt, orthogonalised twice for accuracy). Columns below
/// `zero_column` times the largest column norm are round-off and never kept. Returns the kept
/// columns, the gap (smallest kept residual, largest dropped) and every column's residual.
fn select_independent_columns(w: &Mat<f64>, tolerance: f64, zero_column: f64) -> (Vec<usize>, (f64, f64), Vec<f64>) {
    let m = w.nrows();
    let column_norm = |j: usize| (0..m).map(|i| w[(i, j)] * w[(i, j)]).sum::<f64>().sqrt();
    let largest = (0..w.ncols()).map(column_norm).fold(0.0, f64::max);
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let mut kept = Vec::new();
    let mut residuals = vec![0.0; w.ncols()];
    let (mut min_kept, mut max_dropped) = (f64::INFINITY, 0.0_f64);
    for j in 0..w.ncols() {
        let column: Vec<f64> = (0..m).map(|i| w[(i, j)]).collect();
        let norm = column_norm(j);
        if norm <= zero_column * largest {
            continue; // the parameter never acts on any joint
        }
        let mut r = column;
        for _ in 0..2 {
            for e in &basis {
                let c: f64 = e.iter().zip(&r).map(|(a, b)| a * b).sum();
                r.iter_mut().zip(e).for_each(|(x, ei)| *x -= c * ei);
            }
        }
        let residual = r.iter().map(|x| x * x).sum::<f64>().sqrt() / norm;
        residuals[j] = residual;
        if residual > tolerance {
            min_kept = min_kept.min(residual);
            let rn = residual * norm;
            basis.push(r.into_iter().map(|x| x / rn).collect());
            kept.push(j);
        } else {
            max_dropped = max_dropped.max(residual);
        }
    }
    (kept, (min_kept, max_dropped), residuals)
}

/// `Y_r` stacked over `reach_trajectories` random trajectories within `limits`: on each joint a
/// Fourier series of 5 harmonics with random coefficients and a random period of 5–30 s, scaled
/// until its range, speed or acceleration reaches its limit and centred in the range, sampled at
/// 100 instants of one period.
fn stacked_over_trajectories(
    model: &Model,
    base: &BaseParameters,
    limits: &ReachableLimits,
    options: &BaseParameterOptions,
) -> Mat<f64> {
    const HARMONICS: usize = 5;
    const SAMPLES: usize = 100;
    let (n, big_p, p) = (model.dof(), model.num_params(), base.rank);
    let mut data = Data::new(model);
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let (mut y, mut y_r) = (vec![0.0; n * big_p], vec![0.0; n * p]);
    let mut w = Mat::<f64>::zeros(options.reach_trajectories * SAMPLES * n, p);
    let mut period_samples = PeriodSamples::new(SAMPLES, n);
    for trajectory in 0..options.reach_trajectories {
        let period = rng.random_range(5.0..30.0);
        for j in 0..n {
            let coefficients: Vec<(f64, f64)> =
                (0..HARMONICS).map(|_| (rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))).collect();
            period_samples.fill_scaled_fourier(j, &coefficients, period, limits);
        }
        let PeriodSamples { q, qd, qdd, .. } = &period_samples;
        for s in 0..SAMPLES {
            let at = s * n..(s + 1) * n;
            regressor(model, &mut data, &q[at.clone()], &qd[at.clone()], &qdd[at], &mut y);
            base.reduce(&y, &mut y_r);
            let row0 = (trajectory * SAMPLES + s) * n;
            for k in 0..n {
                for c in 0..p {
                    w[(row0 + k, c)] = y_r[k * p + c];
                }
            }
        }
    }
    w
}

/// Positions, speeds and accelerations at evenly spaced instants of one period, row-major
/// `samples × n`.
struct PeriodSamples {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    samples: usize,
    n: usize,
}

impl PeriodSamples {
    fn new(samples: usize, n: usize) -> Self {
        let zeros = || vec![0.0; samples * n];
        Self { q: zeros(), qd: zeros(), qdd: zeros(), samples, n }
    }

    /// Joint `j`: Σₗ aₗ/(ωl) sin(ωlt) − bₗ/(ωl) cos(ωlt) scaled by the largest factor that keeps
    /// range, speed and acceleration within `limits`, and centred in the position range.
    fn fill_scaled_fourier(&mut self, j: usize, coefficients: &[(f64, f64)], period: f64, limits: &ReachableLimits) {
        let (samples, n) = (self.samples, self.n);
        let w = 2.0 * std::f64::consts::PI / period;
        let (mut x, mut v, mut a) = (vec![0.0; samples], vec![0.0; samples], vec![0.0; samples]);
        for s in 0..samples {
            let t = period * s as f64 / samples as f64;
            for (l, &(al, bl)) in coefficients.iter().enumerate() {
                let wl = w * (l + 1) as f64;
                let (sin, cos) = (wl * t).sin_cos();
                x[s] += (al * sin - bl * cos) / wl;
                v[s] += al * cos + bl * sin;
                a[s] += wl * (bl * cos - al * sin);
            }
        }
        let (lo, hi) =
            (x.iter().copied().fold(f64::INFINITY, f64::min), x.iter().copied().fold(f64::NEG_INFINITY, f64::max));
        let peak = |y: &[f64]| y.iter().fold(0.0_f64, |m, z| m.max(z.abs()));
        let (scale, centre) = limits.fit(j, (lo, hi), peak(&v), peak(&a), 1.0);
        for s in 0..samples {
            self.q[s * n + j] = centre + scale * x[s];
            self.qd[s * n + j] = scale * v[s];
            self.qdd[s * n + j] = scale * a[s];
        }
    }
}

/// `T` (row-major `kept × p`): identity on the kept columns, and each weak column `k` regrouped by
/// least squares on the kept ones. A term whose share of the fit, |cᵢ|·‖wᵢ‖, is below `tolerance`
/// · ‖w_k‖ fits only the residual that makes the column weak; it is dropped and the fit repeated on
/// the rest, so the regrouping reads as the dependency it is.
fn weak_regrouping(w: &Mat<f64>, kept: &[usize], tolerance: f64) -> Vec<f64> {
    let (m, p) = (w.nrows(), w.ncols());
    let norm = |j: usize| (0..m).map(|i| w[(i, j)] * w[(i, j)]).sum::<f64>().sqrt();
    let mut t = vec![0.0; kept.len() * p];
    for (i, &k) in kept.iter().enumerate() {
        t[i * p + k] = 1.0;
    }
    for k in (0..p).filter(|k| !kept.contains(k)) {
        let rhs = Mat::<f64>::from_fn(m, 1, |i, _| w[(i, k)]);
        let mut support: Vec<usize> = (0..kept.len()).collect();
        let mut coefficients = vec![];
        for _ in 0..2 {
            let columns = Mat::<f64>::from_fn(m, support.len(), |i, c| w[(i, kept[support[c]])]);
            let c = columns.qr().solve_lstsq(&rhs);
            coefficients = (0..support.len()).map(|s| c[(s, 0)]).collect();
            let large: Vec<usize> = (0..support.len())
                .filter(|&s| coefficients[s].abs() * norm(kept[support[s]]) >= tolerance * norm(k))
                .collect();
            if large.len() == support.len() {
                break;
            }
            support = large.iter().map(|&s| support[s]).collect();
        }
        for (s, &i) in support.iter().enumerate() {
            t[i * p + k] = coefficients[s];
        }
    }
    t
}

/// `B` (row-major `p × P`): identity on the kept columns, and each dropped column `d` regrouped
/// by the least-squares (exact) solution of `W_kept k = w_d`.
fn regrouping_matrix(w: &Mat<f64>, kept: &[usize], floor: f64) -> Vec<f64> {
    let (m, big_p, p) = (w.nrows(), w.ncols(), kept.len());
    let w_kept = Mat::<f64>::from_fn(m, p, |i, c| w[(i, kept[c])]);
    let rhs = Mat::<f64>::from_fn(m, big_p, |i, j| w[(i, j)]);
    let coeffs = w_kept.qr().solve_lstsq(&rhs);
    let mut b = vec![0.0; p * big_p];
    for i in 0..p {
        for j in 0..big_p {
            let c = coeffs[(i, j)];
            b[i * big_p + j] = if kept[i] == j {
                1.0
            } else if kept.contains(&j) || c.abs() < floor {
                0.0
            } else {
                c
            };
        }
    }
    b
}

fn linear_combination(row: &[f64], names: &[String]) -> String {
    let mut text = String::new();
    for (j, &c) in row.iter().enumerate().filter(|(_, c)| **c != 0.0) {
        let magnitude = c.abs();
        let sign = if c < 0.0 { "−" } else { "+" };
        if text.is_empty() {
            if c < 0.0 {
                text.push('−');
            }
        } else {
            text.push_str(&format!(" {sign} "));
        }
        if (magnitude - 1.0).abs() < 1e-12 {
            text.push_str(&names[j]);
        } else {
            text.push_str(&format!("{}·{}", format_coefficient(magnitude), names[j]));
        }
    }
    text
}

/// Four significant figures, in plain notation where that stays short.
fn format_coefficient(x: f64) -> String {
    if (1e-3..1e4).contains(&x) {
        let digits = (3 - x.log10().floor() as i32).max(0) as usize;
        let s = format!("{x:.digits$}");
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    } else {
        format!("{x:.3e}")
    }
}
