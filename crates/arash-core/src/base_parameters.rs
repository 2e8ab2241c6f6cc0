//! Base parameters (paper section II-E): the combinations `β = B π` of the standard parameters that
//! joint torques can identify, with `Y(q, q̇, q̈) π = Y_r(q, q̇, q̈) β` for every `π`.
//!
//! Computed numerically (Gautier's method): stack the regressor at random states within the
//! limits, keep each column in turn if it is independent of the columns kept before it, and
//! express every other column in the kept ones. Keeping the earliest independent column makes each
//! base parameter read as "this standard parameter plus the ones regrouped into it".

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
}

impl Default for BaseParameterOptions {
    fn default() -> Self {
        Self { samples: 400, seed: 0x5eed, tolerance: 1e-8, zero_column: 1e-10, coefficient_floor: 1e-10 }
    }
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
        let (independent, rank_gap) = select_independent_columns(&w, options.tolerance, options.zero_column);
        let b = regrouping_matrix(&w, &independent, options.coefficient_floor);
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
        Ok(Self { rank, num_params: p, independent, b, names: short, expressions, rank_gap })
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
        let prismatic = joint.kind == JointKind::Prismatic;
        let (default_range, default_speed) = if prismatic { (0.1, 0.2) } else { (std::f64::consts::PI, 2.0) };
        let (lo, hi) = if joint.lower.is_finite() && joint.upper.is_finite() {
            (joint.lower, joint.upper)
        } else {
            (-default_range, default_range)
        };
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
/// `zero_column` times the largest column norm are round-off and never kept.
fn select_independent_columns(w: &Mat<f64>, tolerance: f64, zero_column: f64) -> (Vec<usize>, (f64, f64)) {
    let m = w.nrows();
    let column_norm = |j: usize| (0..m).map(|i| w[(i, j)] * w[(i, j)]).sum::<f64>().sqrt();
    let largest = (0..w.ncols()).map(column_norm).fold(0.0, f64::max);
    let mut basis: Vec<Vec<f64>> = Vec::new();
    let mut kept = Vec::new();
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
        if residual > tolerance {
            min_kept = min_kept.min(residual);
            let rn = residual * norm;
            basis.push(r.into_iter().map(|x| x / rn).collect());
            kept.push(j);
        } else {
            max_dropped = max_dropped.max(residual);
        }
    }
    (kept, (min_kept, max_dropped))
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
