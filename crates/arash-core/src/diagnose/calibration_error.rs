//! What the given model's own calibration error puts into the residual a diagnosis tests.
//!
//! Against a given model the inertial parameters are held at its β̂, fitted on another log with
//! its own noise. On a new trajectory that error shows in the residual as `Y_held (β − β̂)`, and
//! an effect whose columns correlate with it explains part of it: on a simulated six-axis arm
//! identified from 30 s of currents at 100 Hz, a drive gain of ±5 % (0.8 % σ from the noise
//! alone) was accepted on a wrist joint in three of ten seeds, on runs with and without a load,
//! where the gains were calibrated to 0.3 %; from a noise-free calibration, in none. The same
//! holds for the calibrated drive gains, whose errors scale each joint's torque
//! (`diagnose/gain_share.rs`).
//!
//! The model file records β̂'s covariance (`Fitted::beta_covariance`) and the gains' covariance.
//! Their error is `U z`, `z` standard normal, with `U` the directions below on the problem's
//! rows; a group's coefficients then move by `H⁻¹ C̃ᵀ U z`, and that covariance is added to the
//! batch sandwich of every test ([`super::regression::test_group`]). An effect is accepted where
//! it stands out of the noise *and* of what the calibration leaves uncertain.

use faer::{Mat, Side};

use super::gain_share::GainErrors;
use super::inputs::Context;
use super::outcome::Source;
use super::regression::{axpy, Column};
use super::weighted_fit::Problem;
use crate::choices::Choice;
use crate::dense;

/// Share of the calibration error's total variance the kept directions carry: the rest is spread
/// over directions each too small to move a test.
const KEPT_VARIANCE: f64 = 1.0 - 1e-6;

/// The directions of the calibration error on the problem's rows (weighted like its target),
/// whose covariance there is `Σ uᵢ uᵢᵀ`, and the reason that says what is counted; nothing
/// without a given model, or on the log it was fitted on (`train`'s fingerprint): there
/// its fit already left the residual orthogonal to its columns, and its error is not independent
/// of the log's noise.
pub(super) fn directions(
    ctx: &Context,
    problem: &Problem,
    gains: Option<&GainErrors>,
    train: &Source,
) -> (Vec<Vec<f64>>, Option<Choice>) {
    if ctx.given.is_none() {
        return (vec![], None);
    }
    if train.fitted_the_given {
        let reason = Choice::CalibrationError { parameters: false, gains: false, directions: 0, same_log: true };
        return (vec![], Some(reason));
    }
    let held = held_parameters(ctx, problem);
    let of_gains = gains.map(GainErrors::directions).unwrap_or_default();
    let (parameters, gains) = (!held.is_empty(), !of_gains.is_empty());
    let kept = principal(held.into_iter().chain(of_gains).collect());
    // Refitted, the parameters are this log's own: nothing to say unless the gains count.
    let silent = ctx.refit && !gains;
    let reason = Choice::CalibrationError { parameters, gains, directions: kept.len(), same_log: false };
    (kept, (!silent).then_some(reason))
}

/// `Y_held L`, `L Lᵀ` the covariance of the held β̂ (the sub-block of the file's: the marginal
/// covariance of the held parameters).
fn held_parameters(ctx: &Context, problem: &Problem) -> Vec<Vec<f64>> {
    let Some(g) = ctx.given.filter(|_| !ctx.refit) else {
        return vec![];
    };
    let n = problem.declared.len();
    if g.fitted.beta_covariance.len() != n * n {
        return vec![];
    }
    let held: Vec<usize> = (0..n).filter(|&i| !problem.free[i]).collect();
    let covariance = Mat::from_fn(held.len(), held.len(), |a, b| g.fitted.beta_covariance[held[a] * n + held[b]]);
    let columns: Vec<&Column> = held.iter().map(|&i| &problem.declared[i]).collect();
    dense::psd_factor(&covariance).into_iter().map(|l| combine(&columns, &l, problem)).collect()
}

/// `Σ wᵢ columnᵢ` on the problem's rows.
fn combine(columns: &[&Column], weights: &[f64], problem: &Problem) -> Vec<f64> {
    let mut v = vec![0.0; problem.y.len()];
    for (c, w) in columns.iter().zip(weights) {
        axpy(&mut v, *w, c, problem.dof);
    }
    v
}

/// Orthogonal directions with the same `Σ uᵢ uᵢᵀ` as `spanning`, the largest first, as many as
/// carry [`KEPT_VARIANCE`] of its trace: a test then costs a few products, not one per parameter.
fn principal(spanning: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
    if spanning.is_empty() {
        return spanning;
    }
    let gram = Mat::from_fn(spanning.len(), spanning.len(), |a, b| dense::dot(&spanning[a], &spanning[b]));
    let Ok(eigen) = gram.self_adjoint_eigen(Side::Lower) else {
        return spanning;
    };
    let (s, w) = (eigen.S().column_vector(), eigen.U());
    let total: f64 = (0..s.nrows()).map(|e| s[e].max(0.0)).sum();
    let mut kept = Vec::new();
    let mut carried = 0.0;
    // Eigenvalues come in nondecreasing order: take them from the largest.
    for e in (0..s.nrows()).rev().filter(|&e| s[e] > 0.0) {
        if carried >= KEPT_VARIANCE * total {
            break;
        }
        carried += s[e];
        let mut u = vec![0.0; spanning[0].len()];
        for (a, v) in spanning.iter().enumerate() {
            dense::axpy(&mut u, w[(a, e)], v);
        }
        kept.push(u);
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The kept directions reproduce the covariance they summarise.
    #[test]
    fn principal_directions_keep_the_covariance() {
        let spanning = vec![vec![1.0, 2.0, 0.0, -1.0], vec![0.5, -1.0, 3.0, 0.0], vec![1.5, 1.0, 3.0, -1.0]];
        let kept = principal(spanning.clone());
        assert_eq!(kept.len(), 2, "the third is the sum of the first two");
        let cov = |d: &[Vec<f64>], i: usize, j: usize| d.iter().map(|u| u[i] * u[j]).sum::<f64>();
        for i in 0..4 {
            for j in 0..4 {
                assert!((cov(&kept, i, j) - cov(&spanning, i, j)).abs() < 1e-9, "({i}, {j})");
            }
        }
    }
}
