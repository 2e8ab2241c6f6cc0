//! Excitation trajectory design (paper eqs. 18–20): a finite Fourier series per joint,
//!
//!   q(t) = q₀ + Σₗ [aₗ/(ω l) sin(ω l t) − bₗ/(ω l) cos(ω l t)],   ω = 2π/T,
//!
//! whose coefficients minimise the condition number of the normalised, stacked reduced regressor
//! over one period, within the position, speed and acceleration limits.
//!
//! **Normalisation.** `W` stacks `Y_r` at `samples` evenly spaced instants of one period. Each
//! column of `W` is divided by its Euclidean norm, and the condition number is that of the result,
//! σ_max/σ_min. This makes κ independent of the units of the base parameters (kg against kg·m²
//! against N·m·s/rad). Without the scaling, κ measures mostly those units.
//!
//! **Starting and ending at rest.** q̇(t) = Σ aₗ cos(ωlt) + bₗ sin(ωlt), so q̇(0) = Σ aₗ and
//! q̈(0) = ω Σ l·bₗ. Fixing a₁ = −Σₗ₍≥₂₎ aₗ and b₁ = −Σₗ₍≥₂₎ l·bₗ makes both zero. The series is
//! T-periodic, so it also ends at rest. The optimiser sees only the free coefficients.
//!
//! **Optimiser.** Nelder–Mead from the `argmin` crate on log κ plus a quadratic penalty on limit
//! violations. It runs several seeded restarts and keeps the best feasible result, so a given seed
//! always gives the same trajectory.

use argmin::core::{CostFunction, Error as ArgminError, Executor, State};
use argmin::solver::neldermead::NelderMead;
use faer::Mat;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::options::ExcitationOptions;
use crate::base_parameters::{BaseParameterOptions, BaseParameters, LimitsError, ReachableLimits};
use crate::control::fourier::Excitation;
use crate::data::Data;
use crate::dense;
use crate::model::Model;
use crate::regressor::regressor;
use crate::signal::options::SettingError;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExcitationError {
    #[error(transparent)]
    Setting(#[from] SettingError),
    #[error(transparent)]
    Limits(#[from] LimitsError),
    #[error("no restart found a trajectory within the limits that covers the least range and speed (best shortfall {0:.3e}); widen the limits, lower min_range_fraction or min_speed_fraction, or use more harmonics")]
    Infeasible(f64),
}

/// Sum of `excitation`'s limit violations (each relative to its limit) over a fine grid; 0 when
/// feasible.
pub fn limit_violation(excitation: &Excitation, limits: &Limits) -> f64 {
    sweep(excitation, limits).0
}

/// Instants per period on which limits and coverage are checked.
const GRID: usize = 400;

/// How far above the least range and speed (as shares) the optimiser aims; see
/// `Problem::violation_and_aim`.
const COVERAGE_AIM: f64 = 0.02;

/// How each joint moves over one period: the share of its usable range covered, its peak speed
/// against the fastest the series can reach over that range, and the share of the period it
/// moves faster than a tenth of its peak (where Coulomb friction is sliding, not switching).
#[derive(Clone, Debug, PartialEq)]
pub struct Coverage {
    pub range_fraction: Vec<f64>,
    pub speed_fraction: Vec<f64>,
    pub moving_fraction: Vec<f64>,
}

impl Coverage {
    pub fn of(excitation: &Excitation, limits: &Limits) -> Self {
        sweep(excitation, limits).1
    }

    /// How far short of `options`' least range and speed, raised by `aim`, the joints fall,
    /// summed (0 when none).
    fn shortfall(&self, options: &ExcitationOptions, aim: f64) -> f64 {
        // A least share of 0 asks for nothing, not for the aim above it.
        let short = |x: &[f64], least: f64| {
            if least > 0.0 {
                x.iter().map(|v| (least + aim - v).max(0.0)).sum::<f64>()
            } else {
                0.0
            }
        };
        short(&self.range_fraction, options.min_range_fraction)
            + short(&self.speed_fraction, options.min_speed_fraction)
    }
}

/// Each joint's extremes over the grid: positions, peak speed and peak acceleration.
struct Extremes {
    lo: Vec<f64>,
    hi: Vec<f64>,
    speed: Vec<f64>,
    acceleration: Vec<f64>,
}

/// One pass over the grid: the limit violation, the coverage and the extremes.
fn sweep(excitation: &Excitation, limits: &Limits) -> (f64, Coverage, Extremes) {
    let n = excitation.q0.len();
    let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let (mut lo, mut hi, mut peak) = (vec![f64::INFINITY; n], vec![f64::NEG_INFINITY; n], vec![0.0_f64; n]);
    let mut peak_acceleration = vec![0.0_f64; n];
    let mut speeds = Vec::with_capacity(GRID * n);
    let mut violation = 0.0;
    for i in 0..GRID {
        excitation.state_into(excitation.period_s * i as f64 / GRID as f64, &mut q, &mut qd, &mut qdd);
        for j in 0..n {
            let range = limits.upper[j] - limits.lower[j];
            violation += ((limits.lower[j] - q[j]).max(0.0) + (q[j] - limits.upper[j]).max(0.0)) / range;
            violation += (qd[j].abs() - limits.velocity[j]).max(0.0) / limits.velocity[j];
            violation += (qdd[j].abs() - limits.acceleration[j]).max(0.0) / limits.acceleration[j];
            (lo[j], hi[j], peak[j]) = (lo[j].min(q[j]), hi[j].max(q[j]), peak[j].max(qd[j].abs()));
            peak_acceleration[j] = peak_acceleration[j].max(qdd[j].abs());
        }
        speeds.extend_from_slice(&qd);
    }
    let fastest_harmonic = 2.0 * std::f64::consts::PI * excitation.harmonics as f64 / excitation.period_s;
    let range = |j: usize| limits.upper[j] - limits.lower[j];
    let coverage = Coverage {
        range_fraction: (0..n).map(|j| (hi[j] - lo[j]) / range(j)).collect(),
        speed_fraction: (0..n).map(|j| peak[j] / limits.velocity[j].min(0.5 * fastest_harmonic * range(j))).collect(),
        moving_fraction: (0..n)
            .map(|j| speeds.chunks(n).filter(|v| v[j].abs() > 0.1 * peak[j]).count() as f64 / GRID as f64)
            .collect(),
    };
    (violation, coverage, Extremes { lo, hi, speed: peak, acceleration: peak_acceleration })
}

/// The limits a trajectory must respect (margins already applied).
pub type Limits = ReachableLimits;

/// The limits of `options`: the model's, less the margin, with its acceleration limits.
pub fn limits(model: &Model, options: &ExcitationOptions) -> Result<Limits, ExcitationError> {
    ReachableLimits::new(model, options.acceleration_limits.as_deref(), options.margin).map_err(ExcitationError::Limits)
}

/// Progress of [`design_excitation`], for a progress display.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    pub restart: usize,
    pub restarts: usize,
    /// Best feasible κ so far (∞ before the first).
    pub best_condition_number: f64,
}

/// The normalised condition number of the stacked reduced regressor over one period.
pub fn normalised_condition_number(
    model: &Model,
    base: &BaseParameters,
    excitation: &Excitation,
    samples: usize,
) -> f64 {
    let w = stacked(model, base, excitation, samples);
    dense::condition_number(normalise_columns(w).as_ref())
}

/// Each base parameter's σ factor over one period: √[(WₙᵀWₙ)⁻¹]ᵢᵢ for the column-normalised
/// stacked regressor Wₙ. It is how much more the parameter's relative spread is than if its column
/// were orthogonal to all the others (1 at best); a parameter the trajectory barely separates has
/// a large factor. `None` when Wₙ has no full column rank.
pub fn sigma_factors(
    model: &Model,
    base: &BaseParameters,
    excitation: &Excitation,
    samples: usize,
) -> Option<Vec<f64>> {
    let w = normalise_columns(stacked(model, base, excitation, samples));
    let inverse = dense::spd_inverse((w.transpose() * &w).as_ref())?;
    Some((0..base.rank).map(|i| inverse[(i, i)].sqrt()).collect())
}

fn stacked(model: &Model, base: &BaseParameters, excitation: &Excitation, samples: usize) -> Mat<f64> {
    let (n, big_p, p) = (model.dof(), model.num_params(), base.rank);
    let mut data = Data::new(model);
    let (mut y, mut y_r) = (vec![0.0; n * big_p], vec![0.0; n * p]);
    let mut w = Mat::zeros(samples * n, p);
    for s in 0..samples {
        let (q, qd, qdd) = excitation.state(excitation.period_s * s as f64 / samples as f64);
        regressor(model, &mut data, &q, &qd, &qdd, &mut y);
        base.reduce(&y, &mut y_r);
        for k in 0..n {
            for c in 0..p {
                w[(s * n + k, c)] = y_r[k * p + c];
            }
        }
    }
    w
}

fn normalise_columns(mut w: Mat<f64>) -> Mat<f64> {
    for j in 0..w.ncols() {
        let norm = w.col(j).norm_l2();
        if norm > 0.0 {
            w.col_mut(j).iter_mut().for_each(|x| *x /= norm);
        }
    }
    w
}

/// The optimisation problem seen by Nelder–Mead.
#[derive(Clone, Copy)]
struct Problem<'a> {
    model: &'a Model,
    base: &'a BaseParameters,
    limits: &'a Limits,
    options: &'a ExcitationOptions,
}

impl Problem<'_> {
    /// Free coefficients → excitation (a₁, b₁ fixed by the rest-at-start conditions).
    fn excitation(&self, x: &[f64]) -> Excitation {
        let (n, l) = (self.model.dof(), self.options.harmonics);
        let per_joint = 1 + 2 * (l - 1);
        let (mut q0, mut a, mut b) = (Vec::new(), Vec::new(), Vec::new());
        for j in 0..n {
            let xj = &x[j * per_joint..(j + 1) * per_joint];
            q0.push(xj[0]);
            let mut aj = vec![0.0; l];
            let mut bj = vec![0.0; l];
            for h in 1..l {
                aj[h] = xj[h];
                bj[h] = xj[l - 1 + h];
            }
            aj[0] = -aj[1..].iter().sum::<f64>();
            bj[0] = -(1..l).map(|h| (h + 1) as f64 * bj[h]).sum::<f64>();
            a.push(aj);
            b.push(bj);
        }
        Excitation {
            harmonics: l,
            period_s: self.options.period_s,
            q0,
            a,
            b,
            condition_number: f64::NAN,
            condition_number_with_weak: f64::NAN,
        }
    }

    /// Limit violations plus the shortfall from the least range and speed: 0 when acceptable.
    fn violation(&self, excitation: &Excitation) -> f64 {
        self.violation_and_aim(excitation).0
    }

    /// [`Problem::violation`], and the shortfall from two points above the least range and
    /// speed. The optimiser aims there: a simplex that crawls up to the least range from below
    /// stalls at the kink of max(0, ·) a hair short of it, and the restart is lost.
    fn violation_and_aim(&self, excitation: &Excitation) -> (f64, f64) {
        let (violation, coverage, _) = sweep(excitation, self.limits);
        (violation + coverage.shortfall(self.options, 0.0), violation + coverage.shortfall(self.options, COVERAGE_AIM))
    }

    fn condition(&self, excitation: &Excitation) -> f64 {
        // Gram of the column-normalised W: κ = √(λmax/λmin). Cheaper than an SVD per evaluation.
        let w = normalise_columns(stacked(self.model, self.base, excitation, self.options.samples));
        let gram = w.transpose() * &w;
        let Ok(eig) = gram.self_adjoint_eigenvalues(faer::Side::Lower) else { return f64::INFINITY };
        let (min, max) = eig.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), e| (a.min(*e), b.max(*e)));
        (max / min.max(1e-300)).sqrt()
    }
}

impl CostFunction for Problem<'_> {
    type Param = Vec<f64>;
    type Output = f64;

    fn cost(&self, x: &Vec<f64>) -> Result<f64, ArgminError> {
        let excitation = self.excitation(x);
        let (violation, aim) = self.violation_and_aim(&excitation);
        if violation > 0.0 {
            // Outside the limits the condition number is irrelevant; steer back first.
            return Ok(100.0 + 1e3 * aim);
        }
        Ok(self.condition(&excitation).ln() + 1e3 * aim)
    }
}

/// Design an excitation trajectory for `model`. `progress` is called after every restart.
pub fn design_excitation(
    model: &Model,
    base: &BaseParameters,
    options: &ExcitationOptions,
    progress: &mut dyn FnMut(Progress),
) -> Result<Excitation, ExcitationError> {
    options.validate()?;
    if options.samples < 2 * base.rank {
        let least = format!("at least {} instants per period (twice the {} base parameters)", 2 * base.rank, base.rank);
        return Err(SettingError::new("samples", options.samples, least).into());
    }
    let limits = limits(model, options)?;
    let problem = Problem { model, base, limits: &limits, options };
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(options.restarts);
    let mut best: Option<(f64, Vec<f64>)> = None;
    let mut least_violation = f64::INFINITY;
    // Restarts run in parallel batches; each has its own seed, so results do not depend on the
    // number of threads, and progress is reported in restart order.
    for batch_start in (0..options.restarts).step_by(threads) {
        let batch: Vec<usize> = (batch_start..(batch_start + threads).min(options.restarts)).collect();
        let outcomes: Vec<(f64, Option<f64>, Vec<f64>)> = std::thread::scope(|scope| {
            let (problem, limits) = (&problem, &limits);
            let handles: Vec<_> = batch.iter().map(|&r| scope.spawn(move || run_restart(problem, limits, r))).collect();
            handles.into_iter().map(|h| h.join().expect("a restart never panics")).collect()
        });
        for (restart, (violation, kappa, x)) in batch.into_iter().zip(outcomes) {
            least_violation = least_violation.min(violation);
            if let Some(kappa) = kappa {
                if best.as_ref().is_none_or(|(k, _)| kappa < *k) {
                    best = Some((kappa, x));
                }
            }
            progress(Progress {
                restart: restart + 1,
                restarts: options.restarts,
                best_condition_number: best.as_ref().map_or(f64::INFINITY, |b| b.0),
            });
        }
    }
    let (_, x) = best.ok_or(ExcitationError::Infeasible(least_violation))?;
    let mut excitation = problem.excitation(&x);
    excitation.condition_number = normalised_condition_number(model, base, &excitation, options.samples);
    excitation.condition_number_with_weak = if base.weak.is_empty() {
        excitation.condition_number
    } else {
        let exact = BaseParameters::compute(model, &BaseParameterOptions::default().keep_weak())
            .expect("the default options are valid");
        normalised_condition_number(model, &exact, &excitation, options.samples)
    };
    Ok(excitation)
}

/// One Nelder–Mead run from a random start seeded by (seed, restart): returns the limit violation,
/// κ when feasible, and the free coefficients.
fn run_restart(problem: &Problem, limits: &Limits, restart: usize) -> (f64, Option<f64>, Vec<f64>) {
    let options = problem.options;
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    rng.set_stream(restart as u64);
    let x0 = feasible_start(problem, limits, &mut rng);
    let simplex = initial_simplex(&x0, limits, options.harmonics);
    let solver = NelderMead::new(simplex).with_sd_tolerance(1e-6).expect("valid tolerance");
    let result = Executor::new(*problem, solver)
        .configure(|state| state.max_iters(options.iterations))
        .run()
        .expect("the cost function cannot fail");
    let x = result.state().get_best_param().cloned().unwrap_or(x0);
    let excitation = problem.excitation(&x);
    let violation = problem.violation(&excitation);
    let kappa = (violation == 0.0).then(|| problem.condition(&excitation));
    (violation, kappa, x)
}

/// Draws of [`scaled_start`] tried per restart for joints that meet the least range and speed.
const START_DRAWS: usize = 256;

/// A scaled random start whose every joint aims above the least range and speed: each joint that
/// falls short is drawn again (joints are independent here), up to [`START_DRAWS`] times.
/// Nelder–Mead from an infeasible start spends its iterations crawling toward the constraints,
/// and often stalls short of them.
fn feasible_start(problem: &Problem, limits: &Limits, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let options = problem.options;
    if options.min_range_fraction <= 0.0 && options.min_speed_fraction <= 0.0 {
        return small_start(problem, limits, rng);
    }
    let per_joint = 1 + 2 * (options.harmonics - 1);
    let mut x = scaled_start(problem, limits, rng);
    for _ in 0..START_DRAWS {
        let (_, coverage, _) = sweep(&problem.excitation(&x), limits);
        let short: Vec<usize> = (0..problem.model.dof())
            .filter(|&j| {
                coverage.range_fraction[j] < options.min_range_fraction + COVERAGE_AIM
                    || coverage.speed_fraction[j] < options.min_speed_fraction + COVERAGE_AIM
            })
            .collect();
        if short.is_empty() {
            break;
        }
        let fresh = scaled_start(problem, limits, rng);
        for j in short {
            x[j * per_joint..(j + 1) * per_joint].copy_from_slice(&fresh[j * per_joint..(j + 1) * per_joint]);
        }
    }
    x
}

/// Without a least range and speed: small random coefficients around mid-range offsets, well
/// inside the limits (the design before the least range and speed existed).
fn small_start(problem: &Problem, limits: &Limits, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let l = problem.options.harmonics;
    let w = 2.0 * std::f64::consts::PI / problem.options.period_s;
    let mut x = Vec::new();
    for j in 0..problem.model.dof() {
        let mid = 0.5 * (limits.lower[j] + limits.upper[j]);
        let half = 0.5 * (limits.upper[j] - limits.lower[j]);
        // Coefficient scale such that 2(L−1) terms of this size stay within range, speed and
        // acceleration even with the dependent first harmonic.
        let scale = (half * w / (4.0 * l as f64))
            .min(limits.velocity[j] / (4.0 * l as f64))
            .min(limits.acceleration[j] / (4.0 * (l * l) as f64 * w));
        x.push(mid);
        for _ in 0..2 * (l - 1) {
            x.push(scale * rng.random_range(-1.0..1.0));
        }
    }
    x
}

/// A random start that reaches its limits: random coefficients on each joint, scaled until its
/// range, speed or acceleration reaches 95 % of its limit, and centred in the range. Small
/// coefficients would start far short of the least range and speed.
fn scaled_start(problem: &Problem, limits: &Limits, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let (n, l) = (problem.model.dof(), problem.options.harmonics);
    let per_joint = 1 + 2 * (l - 1);
    let mut x = Vec::with_capacity(n * per_joint);
    for j in 0..n {
        x.push(0.5 * (limits.lower[j] + limits.upper[j]));
        x.extend((0..2 * (l - 1)).map(|_| rng.random_range(-1.0..1.0)));
    }
    let extremes = sweep(&problem.excitation(&x), limits).2;
    for j in 0..n {
        let block = &mut x[j * per_joint..(j + 1) * per_joint];
        // The series is q₀ + h(t); fit h, whose extremes are the swept ones less q₀.
        let h = (extremes.lo[j] - block[0], extremes.hi[j] - block[0]);
        let (scale, centre) = limits.fit(j, h, extremes.speed[j], extremes.acceleration[j], 0.95);
        block[0] = centre;
        block[1..].iter_mut().for_each(|c| *c *= scale);
    }
    x
}

fn initial_simplex(x0: &[f64], limits: &Limits, harmonics: usize) -> Vec<Vec<f64>> {
    let per_joint = 1 + 2 * (harmonics - 1);
    let mut simplex = vec![x0.to_vec()];
    for i in 0..x0.len() {
        let j = i / per_joint;
        let step = if i % per_joint == 0 {
            0.05 * (limits.upper[j] - limits.lower[j])
        } else {
            0.05 * limits.velocity[j] / harmonics as f64
        };
        let mut x = x0.to_vec();
        x[i] += step;
        simplex.push(x);
    }
    simplex
}
