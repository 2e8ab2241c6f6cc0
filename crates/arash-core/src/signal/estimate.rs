//! Least-squares estimation of the base parameters (paper eqs. 14–17, 21).
//!
//! The stacked reduced regressor `W` (one row per sample and joint) is solved by the corrected
//! semi-normal equations: a Cholesky factor `R` of the column-scaled `WᵀW`, and one step of
//! iterative refinement on the true residual.
//!
//! Plain normal equations lose accuracy in proportion to κ(W)², against κ(W) for Householder QR.
//! ARASH:ASiST data has κ ≈ 10⁵, where squaring costs 10 of 16 digits. The refinement step brings
//! the error back to QR's level while κ²·ε ≪ 1 (Björck 1987). The Gram matrix is one matrix
//! product, ten times faster than a QR of a 900,000 × 23 matrix. Above κ = 10⁷ the fit falls
//! back to Householder QR (faer). Either way, `R` gives `(WᵀW)⁻¹ = R⁻¹R⁻ᵀ` for the covariance.

use faer::prelude::*;
use faer::{Mat, Scale};

use super::preprocess::Preprocessed;
use crate::base_parameters::BaseParameters;
use crate::data::Data;
use crate::dense::{self, dot};
use crate::dynamics::inverse_dynamics;
use crate::model::Model;
use crate::model_file::Determination;
use crate::regressor::{bodies_of_columns, regressor_of_bodies};
use crate::signal::conditioning::filter_columns;
use crate::signal::filter::Butterworth;

/// Which least-squares problem to solve.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// Ordinary least squares: every row weighted equally.
    Ols,
    /// Weighted least squares: each joint's rows divided by that joint's OLS residual standard
    /// deviation, so that N·m and N residuals count in proportion to their noise.
    Wls,
}

/// Why the data cannot give a meaningful estimate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimateError {
    #[error("the data does not excite {0}: these base parameters cannot be identified from it")]
    NotExcited(String),
    #[error("the data barely excites some directions (scaled condition number {condition:.3e} > {limit:.1e}); the weakest combination is {direction}")]
    IllConditioned { condition: f64, limit: f64, direction: String },
    #[error("{rows} equations cannot determine {params} parameters with an error estimate; record more samples")]
    TooFewRows { rows: usize, params: usize },
}

/// Per-joint fit quality.
#[derive(Clone, Debug, PartialEq)]
pub struct JointMetrics {
    /// `100(1 − ‖τ − τ̂‖ / ‖τ − mean τ‖)` (eq. 21), per joint.
    pub fp_percent: Vec<f64>,
    /// `‖τ − τ̂‖ / ‖τ‖`, per joint.
    pub relative_error: Vec<f64>,
    /// Root-mean-square residual (N·m or N), per joint.
    pub rms: Vec<f64>,
}

/// A least-squares estimate of the base parameters.
#[derive(Clone, Debug)]
pub struct Fit {
    pub method: Method,
    /// β̂.
    pub beta: Vec<f64>,
    /// Standard deviation of each β̂ (eq. 16).
    pub sigma_beta: Vec<f64>,
    /// The covariance of β̂ whose diagonal `sigma_beta` is (the block sandwich).
    pub covariance: Mat<f64>,
    /// Relative standard deviation `100 σ_β / |β̂|` (eq. 15).
    pub sigma_percent: Vec<f64>,
    /// Residual variance of the (weighted) system (eq. 17).
    pub sigma_p2: f64,
    /// Row weight of each joint (1 for OLS).
    pub joint_weights: Vec<f64>,
    /// Condition number of `W` with unit-norm columns.
    pub condition_number: f64,
    /// Fit quality on the training data.
    pub metrics: JointMetrics,
    /// Per parameter, what sets its σ% besides the noise (of the weighted `W`).
    pub determination: Vec<Determination>,
}

/// Scaled condition numbers above this are refused: such directions are set by round-off and
/// noise. ARASH:ASiST itself sits near 10⁶ on good data, because `rocker_a.my_R` and
/// `instrument_holder.my_R` differ only through small yaw-coupling terms; their σ% reports it.
pub const CONDITION_LIMIT: f64 = 1e8;

/// `W` (rows = samples × dof, one column per base parameter) and `τ`, stacked in the same row
/// order.
///
/// Coulomb friction columns step where a velocity changes sign, but the measured torque has been
/// low-pass filtered, so its steps are smoothed. Left alone, that mismatch biases the whole fit
/// (docs/identification.md gives the size). Those columns are therefore built from the friction
/// velocity ([`Preprocessed::coulomb_columns`]) and filtered exactly like the torque ("parallel
/// filtering"). The other columns are smooth functions of signals already filtered far below the
/// cut-off, and the filter leaves them unchanged.
///
/// Only the [`Preprocessed::settled`] samples are stacked: near the ends of a log that is not
/// periodic the filter's start-up transient would be fitted as if it were dynamics.
pub fn stack(model: &Model, base: &BaseParameters, data: &Preprocessed) -> (Mat<f64>, Vec<f64>) {
    stack_directed(model, base, data, &data.friction.directions(&model.coulomb_laws))
}

/// [`stack`] with the Coulomb directions of `model`'s laws already taken.
fn stack_directed(
    model: &Model,
    base: &BaseParameters,
    data: &Preprocessed,
    directions: &[f64],
) -> (Mat<f64>, Vec<f64>) {
    let (mut w, mut tau) =
        (stack_columns(model, data, &base.independent, directions), data.settled_rows(&data.tau, data.dof).to_vec());
    leave_out_rests(data, &mut w, &mut tau, data.settled.clone());
    (w, tau)
}

/// Zero the rows of `w` and the entries of `tau` (stacked at the samples `samples`, `dof` rows
/// each) of every joint that rests there ([`Preprocessed::resting`]). A zero row adds nothing to
/// the fit, its residual or σ's middle, and [`fit_stacked`] counts only the others.
pub fn leave_out_rests(data: &Preprocessed, w: &mut Mat<f64>, tau: &mut [f64], samples: impl Iterator<Item = usize>) {
    let dof = data.dof;
    for (r, s) in samples.enumerate() {
        for k in (0..dof).filter(|&k| data.resting[s * dof + k]) {
            let row = r * dof + k;
            tau[row] = 0.0;
            (0..w.ncols()).for_each(|c| w[(row, c)] = 0.0);
        }
    }
}

/// The rows of `w` (and `tau`) that are equations: not left out as zero ([`leave_out_rests`]).
fn equations(w: &Mat<f64>, tau: &[f64]) -> usize {
    (0..w.nrows()).filter(|&r| tau[r] != 0.0 || (0..w.ncols()).any(|c| w[(r, c)] != 0.0)).count()
}

/// The full regressor (all P standard parameters) stacked like [`stack`].
pub fn stack_full(model: &Model, data: &Preprocessed) -> (Mat<f64>, Vec<f64>) {
    let all: Vec<usize> = (0..model.num_params()).collect();
    let directions = data.friction.directions(&model.coulomb_laws);
    (stack_columns(model, data, &all, &directions), data.settled_rows(&data.tau, data.dof).to_vec())
}

fn stack_columns(model: &Model, data: &Preprocessed, columns: &[usize], directions: &[f64]) -> Mat<f64> {
    let every: Vec<usize> = (0..data.samples()).collect();
    let mut w = regressor_rows(model, data, columns, &every);
    let positions = coulomb_positions(model, columns);
    put_coulomb(&mut w, data.dof, &positions, directions, &every);
    let filter = Butterworth::lowpass(data.order, data.cutoff_hz, data.rate_hz()).expect("the torque was filtered so");
    filter_each_column(&mut w, data.dof, &filter, data.periodic);
    let n = data.dof;
    match data.settled == (0..data.samples()) {
        true => w,
        false => w.subrows(data.settled.start * n, data.settled.len() * n).to_owned(),
    }
}

/// Filter every column of a stacked `w` (rows sample by sample, `dof` per sample) over time, as
/// [`filter_columns`] filters a signal: "parallel filtering". The torque's content above the
/// cut-off is gone after filtering; a column computed from filtered signals still holds the
/// products of the motion's harmonics there (Coriolis terms, gravity's sine), which at a cut-off
/// a few times the motion's bandwidth bias the fit; filtered alike, model and torque match.
pub fn filter_each_column(w: &mut Mat<f64>, dof: usize, filter: &Butterworth, periodic: bool) {
    // The columns are independent and filtering them is most of stacking: one run of them per
    // core. Each is filtered exactly as alone, so the result does not depend on the cores.
    let columns: Vec<&mut [f64]> = w
        .as_mut()
        .col_iter_mut()
        .map(|c| c.try_as_col_major_mut().expect("a Mat's columns are contiguous").as_slice_mut())
        .collect();
    crate::parallel::map(columns, |column| {
        // A column's rows, sample by sample and joint by joint, are a `samples × dof` signal.
        let filtered = filter_columns(filter, column, dof, periodic).expect("long enough: the torque was");
        column.copy_from_slice(&filtered);
    });
}

/// The regressor's `columns` (standard-parameter indices) at the samples `rows` of `data`, one
/// row per sample and joint, sample by sample. The Coulomb columns are left as the regressor
/// gives them, unfiltered: see [`put_coulomb`].
pub fn regressor_rows(model: &Model, data: &Preprocessed, columns: &[usize], rows: &[usize]) -> Mat<f64> {
    let n = model.dof();
    let mut w = Mat::<f64>::zeros(rows.len() * n, columns.len());
    // Each thread fills a band of consecutive rows.
    let threads = std::thread::available_parallelism().map_or(1, |t| t.get());
    let per_thread = rows.len().div_ceil(threads).max(1);
    let bodies = bodies_of_columns(model, columns);
    std::thread::scope(|scope| {
        let mut rest = w.as_mut();
        for samples in rows.chunks(per_thread) {
            let (band, tail) = rest.split_at_row_mut(samples.len() * n);
            rest = tail;
            let bodies = &bodies;
            scope.spawn(move || fill_band(model, data, columns, bodies, samples, band));
        }
    });
    w
}

/// Where each joint's Coulomb column sits among `columns` (standard-parameter indices): `(joint,
/// position)` for every joint that has one there.
pub fn coulomb_positions(model: &Model, columns: &[usize]) -> Vec<(usize, usize)> {
    (0..model.dof())
        .filter_map(|k| columns.iter().position(|&j| j == model.layout().coulomb(k)).map(|c| (k, c)))
        .collect()
}

/// Write `coulomb` (`samples × dof`: the Coulomb columns, filtered like the torque or not) at
/// the samples `rows` into the Coulomb `positions` of `w`, stacked at those rows.
pub fn put_coulomb(w: &mut Mat<f64>, dof: usize, positions: &[(usize, usize)], coulomb: &[f64], rows: &[usize]) {
    for &(k, c) in positions {
        for (r, &s) in rows.iter().enumerate() {
            w[(r * dof + k, c)] = coulomb[s * dof + k];
        }
    }
}

/// The regressor rows of the samples `samples` into `band` (one row per sample and joint);
/// `bodies` are the flags [`bodies_of_columns`] gives for `columns`.
fn fill_band(
    model: &Model,
    data: &Preprocessed,
    columns: &[usize],
    bodies: &[bool],
    samples: &[usize],
    mut band: faer::MatMut<'_, f64>,
) {
    let (n, big_p) = (model.dof(), model.num_params());
    let mut ws = Data::new(model);
    let mut y = vec![0.0; n * big_p];
    for (local, &sample) in samples.iter().enumerate() {
        let range = sample * n..(sample + 1) * n;
        let (q, qd, qdd) = (&data.q[range.clone()], &data.qd[range.clone()], &data.qdd[range]);
        regressor_of_bodies(model, &mut ws, q, qd, qdd, Some(bodies), &mut y);
        for k in 0..n {
            for (c, &j) in columns.iter().enumerate() {
                band[(local * n + k, c)] = y[k * big_p + j];
            }
        }
    }
}

/// Fit β by OLS or WLS on preprocessed data.
///
/// σ_β comes from the sandwich of [`fit_stacked`], its middle taken from the residual of the
/// *unfiltered* torque (blocks of `2·fs/cutoff` samples). The filtered residual is what is left
/// of the noise after the filter and the fit: at a low cut-off the noise has few degrees of
/// freedom left (about `2·cutoff·duration` per joint) and the fit absorbs a good share of them,
/// so the filtered residual under-states the noise that moved β̂ (by 30–65 % in σ on simulated
/// data, docs/identification.md). The unfiltered residual keeps it: the model's columns are
/// smooth within a block, so they weigh the noise exactly as the filtered fit did.
pub fn fit(model: &Model, base: &BaseParameters, data: &Preprocessed, method: Method) -> Result<Fit, EstimateError> {
    // The directions once for both: on a long log's periods they cost a tenth of the fit.
    let directions = data.friction.directions(&model.coulomb_laws);
    let (w, tau) = stack_directed(model, base, data, &directions);
    let block = ((2.0 * data.rate_hz() / data.cutoff_hz).ceil() as usize).max(1);
    let unfiltered =
        |beta: &[f64]| residual_of(data, &prediction_of(model, data, &base.independent, beta, &directions));
    fit_stacked_with(&w, &tau, model.dof(), base, method, block, Some(&unfiltered))
}

/// The unfiltered torque less [`unfiltered_prediction`] on the [`Preprocessed::settled`] samples,
/// zero where a joint rests (its row is left out of the fit): what σ's middle is taken from.
pub fn unfiltered_residual(model: &Model, data: &Preprocessed, columns: &[usize], beta: &[f64]) -> Vec<f64> {
    residual_of(data, &unfiltered_prediction(model, data, columns, beta))
}

/// The unfiltered torque less `predicted` on the settled samples, zero where a joint rests.
fn residual_of(data: &Preprocessed, predicted: &[f64]) -> Vec<f64> {
    let measured = data.settled_rows(&data.tau_unfiltered, data.dof).iter();
    let resting = data.settled_rows(&data.resting, data.dof);
    measured.zip(predicted).zip(resting).map(|((t, p), rests)| if *rests { 0.0 } else { t - p }).collect()
}

/// The model `beta` on the [`Preprocessed::settled`] samples with unfiltered columns: the
/// regressor of the filtered signals, Coulomb friction switching with the friction velocity
/// (not filtered like the torque), sample by sample and joint by joint.
pub fn unfiltered_prediction(model: &Model, data: &Preprocessed, columns: &[usize], beta: &[f64]) -> Vec<f64> {
    prediction_of(model, data, columns, beta, &data.friction.directions(&model.coulomb_laws))
}

/// Samples per band of the unfiltered prediction.
const BAND_SAMPLES: usize = 4096;

/// [`unfiltered_prediction`] with the Coulomb directions of `model`'s laws already taken.
fn prediction_of(model: &Model, data: &Preprocessed, columns: &[usize], beta: &[f64], directions: &[f64]) -> Vec<f64> {
    let dof = data.dof;
    // `W β` is `Y π` with β placed on its columns and zeros elsewhere: the inverse dynamics of
    // π, which costs a fraction of the regressor it replaces. The Coulomb columns switch with
    // the friction velocity, not the law of the filtered one, so they are added apart.
    let mut params = vec![0.0; model.num_params()];
    columns.iter().zip(beta).for_each(|(&j, &b)| params[j] = b);
    let coulomb: Vec<(usize, f64)> = coulomb_positions(model, columns).iter().map(|&(k, c)| (k, beta[c])).collect();
    coulomb.iter().for_each(|&(k, _)| params[model.layout().coulomb(k)] = 0.0);
    let rows: Vec<usize> = data.settled.clone().collect();
    let mut predicted = vec![0.0; rows.len() * dof];
    // Bands of samples, which `parallel::map` spreads over the cores.
    let bands: Vec<(&[usize], &mut [f64])> =
        rows.chunks(BAND_SAMPLES).zip(predicted.chunks_mut(BAND_SAMPLES * dof)).collect();
    crate::parallel::map(bands, |(samples, out)| {
        let mut ws = Data::new(model);
        for (&s, tau) in samples.iter().zip(out.chunks_mut(dof)) {
            let at = s * dof..(s + 1) * dof;
            inverse_dynamics(model, &mut ws, &data.q[at.clone()], &data.qd[at.clone()], &data.qdd[at], &params, tau);
            coulomb.iter().for_each(|&(k, fc)| tau[k] += fc * directions[s * dof + k]);
        }
    });
    predicted
}

/// Fit β from an already stacked `W` and `τ` (rows ordered sample by sample, joint by joint).
///
/// σ_β is a block sandwich estimate, `(WᵀW)⁻¹ (Σ_b g_b g_bᵀ) (WᵀW)⁻¹` with `g_b = W_bᵀ e_b` over
/// blocks of `block_samples` consecutive samples. The classical eq. 16, `σ²(WᵀW)⁻¹`, assumes
/// residuals that are independent and equally noisy in every row. Filtered robot data breaks both
/// assumptions: residuals are correlated over the filter's memory, and N·m and N noise differ. On
/// ARASH:ASiST data filtered at 1.7 Hz, eq. 16 under-states σ_β by an order of magnitude. With
/// white residuals (`block_samples = 1`) the block estimate reduces to the heteroscedasticity-robust
/// one, which equals eq. 16 when the noise is equal.
pub fn fit_stacked(
    w: &Mat<f64>,
    tau: &[f64],
    dof: usize,
    base: &BaseParameters,
    method: Method,
    block_samples: usize,
) -> Result<Fit, EstimateError> {
    fit_stacked_with(w, tau, dof, base, method, block_samples, None)
}

/// The residual of the unfiltered torque given β, row for row with the stacked `W`.
type UnfilteredResidual<'a> = dyn Fn(&[f64]) -> Vec<f64> + 'a;

/// The OLS solution of a stacked `W β = τ` (β, R, κ), refused where [`fit_stacked`] refuses it:
/// too few rows, a column the data do not excite, κ over [`CONDITION_LIMIT`].
fn checked_ols(
    w: &Mat<f64>,
    tau: &[f64],
    dof: usize,
    base: &BaseParameters,
) -> Result<(Vec<f64>, Mat<f64>, f64), EstimateError> {
    let (m, p) = (equations(w, tau), w.ncols());
    if m <= p {
        return Err(EstimateError::TooFewRows { rows: m, params: p });
    }
    check_excitation(w, base)?;
    let ols = solve(w, tau, &vec![1.0; dof], dof);
    // κ of the column-scaled W from its R factor, accurate far beyond what a Gram matrix resolves.
    if ols.2.is_nan() || ols.2 > CONDITION_LIMIT {
        return Err(EstimateError::IllConditioned {
            condition: ols.2,
            limit: CONDITION_LIMIT,
            direction: weakest_direction(&ols.1, base),
        });
    }
    Ok(ols)
}

/// `R⁻¹`, refused where R is exactly singular (a κ too large to have been measured).
fn r_inverse(r_factor: &Mat<f64>) -> Result<Mat<f64>, EstimateError> {
    dense::inverse(r_factor.as_ref()).ok_or_else(|| EstimateError::IllConditioned {
        condition: f64::INFINITY,
        limit: CONDITION_LIMIT,
        direction: "a combination the QR factor found exactly singular".into(),
    })
}

/// [`fit_stacked`]'s OLS β and per-joint metrics alone, the same to the bit, without its
/// covariance: what a search that compares many candidate fits reads of each (the block
/// sandwich is a second pass over `W` per block, most of a fit's cost on a long stack).
pub fn ols_beta_and_metrics(
    w: &Mat<f64>,
    tau: &[f64],
    dof: usize,
    base: &BaseParameters,
) -> Result<(Vec<f64>, JointMetrics), EstimateError> {
    let (beta, r_factor, _) = checked_ols(w, tau, dof, base)?;
    r_inverse(&r_factor)?;
    let metrics = joint_metrics(tau, &apply(w, &beta), dof);
    Ok((beta, metrics))
}

/// [`fit_stacked`], the sandwich's middle taken from `unfiltered(β̂)` (the residual of the
/// unfiltered torque, row for row with `w`) when given: see [`fit`].
fn fit_stacked_with(
    w: &Mat<f64>,
    tau: &[f64],
    dof: usize,
    base: &BaseParameters,
    method: Method,
    block_samples: usize,
    unfiltered: Option<&UnfilteredResidual>,
) -> Result<Fit, EstimateError> {
    let (m, p) = (equations(w, tau), w.ncols());
    let ols = checked_ols(w, tau, dof, base)?;
    let weights = match method {
        Method::Ols => vec![1.0; dof],
        Method::Wls => {
            let residual = residual(w, tau, &ols.0);
            let per_joint = rms_per_joint(&residual, dof);
            per_joint.iter().map(|r| if *r > 0.0 { 1.0 / r } else { 1.0 }).collect()
        }
    };
    let (beta, r_factor, condition_number) = if method == Method::Ols { ols } else { solve(w, tau, &weights, dof) };
    // W β is one pass over W, which at 300,000 samples is larger than the cache: once serves both
    // the residual and the metrics.
    let predicted = apply(w, &beta);
    let weighted_residual: Vec<f64> =
        tau.iter().zip(&predicted).enumerate().map(|(i, (t, p))| (t - p) * weights[i % dof]).collect();
    let sigma_p2 = weighted_residual.iter().map(|e| e * e).sum::<f64>() / (m - p) as f64;
    let r_inv = r_inverse(&r_factor)?;
    let meat_residual = match unfiltered {
        Some(unfiltered) => {
            unfiltered(&beta).iter().enumerate().map(|(i, e)| e * weights[i % dof]).collect::<Vec<f64>>()
        }
        None => weighted_residual,
    };
    let covariance = block_sandwich_covariance(w, &meat_residual, &weights, dof, block_samples.max(1), &r_inv);
    let sigma_beta = dense::standard_deviations(covariance.as_ref());
    let sigma_percent = sigma_beta.iter().zip(&beta).map(|(s, b)| 100.0 * s / b.abs()).collect();
    let metrics = joint_metrics(tau, &predicted, dof);
    let determination = determination(&r_factor, &r_inv, column_over_torque(w, tau, dof), &beta);
    Ok(Fit {
        method,
        beta,
        sigma_beta,
        covariance,
        sigma_percent,
        sigma_p2,
        joint_weights: weights,
        condition_number,
        metrics,
        determination,
    })
}

/// Each column's [`Determination`] from the triangular factor `R` of the stacked `W` (`RᵀR =
/// WᵀW`) and its inverse: the Gram matrix's diagonal is `‖wᵢ‖²`, its inverse `R⁻¹R⁻ᵀ`, and
/// `1/(‖wᵢ‖²·(WᵀW)⁻¹ᵢᵢ)` is the squared part of column i outside the others' span. Regressing
/// column i on the others gives column j the coefficient `−(WᵀW)⁻¹ᵢⱼ/(WᵀW)⁻¹ᵢᵢ`; scaled to
/// unit columns, the largest names what it leans on. The torque shares are `beta`'s.
fn determination(r: &Mat<f64>, r_inv: &Mat<f64>, column_over_torque: Vec<f64>, beta: &[f64]) -> Vec<Determination> {
    let p = r.ncols();
    let inverse = r_inv * r_inv.transpose();
    let norms: Vec<f64> = (0..p).map(|i| r.col(i).norm_l2()).collect();
    (0..p)
        .zip(column_over_torque)
        .map(|(i, column_over_torque)| {
            let on_unit = |j: usize| (inverse[(i, j)] * norms[j]).abs();
            Determination {
                apart: 1.0 / (norms[i] * inverse[(i, i)].sqrt()),
                leans_on: (0..p).filter(|&j| j != i).max_by(|&a, &b| on_unit(a).total_cmp(&on_unit(b))),
                column_over_torque,
                torque_share: beta[i].abs() * column_over_torque,
            }
        })
        .collect()
}

/// Each column's norm over the torque's on one joint (rows `k`, `k + dof`, …), on the joint where
/// that ratio is largest: a parameter's share of the torque is judged where it acts most, since
/// a yaw term is small against the insertion's newtons but not against the yaw's own torque.
fn column_over_torque(w: &Mat<f64>, tau: &[f64], dof: usize) -> Vec<f64> {
    // Sample by sample, a joint per row: a remainder per entry cost a twentieth of the fit.
    let per_joint = |x: &[f64]| {
        let mut sums = vec![0.0; dof];
        x.chunks(dof).for_each(|sample| sums.iter_mut().zip(sample).for_each(|(s, v)| *s += v * v));
        sums
    };
    let torque = per_joint(tau);
    (0..w.ncols())
        .map(|i| {
            let column = per_joint(w.col_as_slice(i));
            column.iter().zip(&torque).filter(|(_, t)| **t > 0.0).map(|(c, t)| (c / t).sqrt()).fold(0.0, f64::max)
        })
        .collect()
}

/// Solve the row-weighted problem; return β, the triangular factor `R` (p × p) of the weighted
/// `W`, and the condition number of `W` with unit-norm columns.
fn solve(w: &Mat<f64>, tau: &[f64], weights: &[f64], dof: usize) -> (Vec<f64>, Mat<f64>, f64) {
    let (m, p) = (w.nrows(), w.ncols());
    let weighted_owned;
    let w_t: &Mat<f64> = if weights.iter().all(|w| *w == 1.0) {
        w
    } else {
        weighted_owned = Mat::<f64>::from_fn(m, p, |i, j| w[(i, j)] * weights[i % dof]);
        &weighted_owned
    };
    let b = Mat::<f64>::from_fn(m, 1, |i, _| tau[i] * weights[i % dof]);
    match corrected_semi_normal(w_t, &b) {
        Some(solution) => solution,
        None => householder_qr(w_t, &b),
    }
}

/// Corrected semi-normal equations (Björck 1987): R from the Cholesky factor of the column-scaled
/// Gram matrix, `RᵀR x = Wᵀb`, then one step of iterative refinement on the true residual.
/// Forming `WᵀW` is one matrix product, several times cheaper than a Householder QR of a tall `W`.
/// Squaring costs accuracy (κ² instead of κ), but the refinement step recovers QR's accuracy while
/// κ²·ε stays well below 1; two steps are taken for margin. Returns `None` for κ > 10⁷
/// (κ²·ε ≈ 10⁻²); the caller then uses Householder QR.
fn corrected_semi_normal(w: &Mat<f64>, b: &Mat<f64>) -> Option<(Vec<f64>, Mat<f64>, f64)> {
    let p = w.ncols();
    let gram = w.transpose() * w;
    let norms: Vec<f64> = (0..p).map(|j| gram[(j, j)].sqrt()).collect();
    if norms.contains(&0.0) {
        return None;
    }
    let scaled_gram = Mat::from_fn(p, p, |i, j| gram[(i, j)] / (norms[i] * norms[j]));
    let l_scaled = dense::cholesky(scaled_gram.as_ref())?;
    let r_scaled = l_scaled.transpose();
    let condition = dense::condition_number(r_scaled);
    if condition.is_nan() || condition > 1e7 {
        return None;
    }
    // R for the unscaled W: RᵀR = WᵀW.
    let r_factor = Mat::from_fn(p, p, |i, j| r_scaled[(i, j)] * norms[j]);
    let solve_normal = |rhs: &Mat<f64>| -> Mat<f64> {
        let mut v = w.transpose() * rhs;
        r_factor.transpose().solve_lower_triangular_in_place(&mut v);
        r_factor.solve_upper_triangular_in_place(&mut v);
        v
    };
    let mut x = solve_normal(b);
    for _ in 0..2 {
        let residual = b - w * &x;
        x = &x + solve_normal(&residual);
    }
    Some(((0..p).map(|i| x[(i, 0)]).collect(), r_factor, condition))
}

/// Householder QR (faer): the robust path for ill-conditioned `W`.
fn householder_qr(w: &Mat<f64>, b: &Mat<f64>) -> (Vec<f64>, Mat<f64>, f64) {
    let p = w.ncols();
    let qr = w.qr();
    let beta_mat = qr.solve_lstsq(b);
    let r = qr.thin_R();
    let r_factor = Mat::from_fn(p, p, |i, j| if j >= i { r[(i, j)] } else { 0.0 });
    let norms: Vec<f64> = (0..p).map(|j| r_factor.col(j).norm_l2()).collect();
    let scaled = Mat::from_fn(p, p, |i, j| r_factor[(i, j)] / norms[j]);
    let condition = dense::condition_number(scaled.as_ref());
    ((0..p).map(|i| beta_mat[(i, 0)]).collect(), r_factor, condition)
}

/// The covariance of β̂ from the sandwich (see [`fit_stacked`]) on the weighted system.
fn block_sandwich_covariance(
    w: &Mat<f64>,
    weighted_residual: &[f64],
    weights: &[f64],
    dof: usize,
    block_samples: usize,
    r_inv: &Mat<f64>,
) -> Mat<f64> {
    // Row-weighted residuals once; each sample's score is then g_s = Σ_k W_(s,k)ᵀ e_(s,k).
    let e: Vec<f64> = weighted_residual.iter().enumerate().map(|(i, r)| r * weights[i % dof]).collect();
    // (W̃ᵀW̃)⁻¹ = R⁻¹R⁻ᵀ for the weighted W̃.
    let gram_inv = r_inv * r_inv.transpose();
    sandwich_covariance(w, &e, dof, block_samples, &gram_inv)
}

/// The covariance from the sandwich `bread · Ω · breadᵀ`, with the small-sample factor `m / (m − p)`. Ω is
/// the overlapping-batch-means estimate of the long-run covariance of the scores
/// `g_s = Σ_k X_(s,k)ᵀ e_(s,k)` of `x` (W for least squares, the instruments for IV) on the
/// residual `e`: every run of `block_samples` consecutive samples, not only disjoint blocks.
/// Disjoint blocks give an Ω of rank at most their number, which at a low cut-off (a few blocks
/// per period) is below the number of parameters and under-states σ by a large factor; the
/// overlapping runs keep its rank and the same bandwidth (Bartlett's kernel).
pub fn sandwich_covariance(x: &Mat<f64>, e: &[f64], dof: usize, block_samples: usize, bread: &Mat<f64>) -> Mat<f64> {
    let (m, p) = (x.nrows(), x.ncols());
    let samples = m / dof;
    let block = block_samples.clamp(1, samples.max(1));
    let mut scores = Mat::<f64>::zeros(samples, p);
    for a in 0..p {
        let column = x.col_as_slice(a);
        for s in 0..samples {
            scores[(s, a)] = dot(&column[s * dof..(s + 1) * dof], &e[s * dof..(s + 1) * dof]);
        }
    }
    // The sums over every run of `block` samples, from a running sum.
    let runs = samples - block + 1;
    let mut sums = Mat::<f64>::zeros(runs, p);
    for a in 0..p {
        let mut running: f64 = (0..block).map(|s| scores[(s, a)]).sum();
        sums[(0, a)] = running;
        for t in 1..runs {
            running += scores[(t + block - 1, a)] - scores[(t - 1, a)];
            sums[(t, a)] = running;
        }
    }
    let gram = sums.transpose() * &sums;
    let scale = samples as f64 / (block as f64 * runs as f64);
    let meat = Mat::from_fn(p, p, |i, j| gram[(i, j)] * scale);
    bread * &meat * bread.transpose() * Scale(degrees_of_freedom_factor(m, p, samples, block))
}

/// The small-sample factor of the sandwich: `m_eff / (m_eff − p)` for residuals that carry
/// `m_eff` independent values. The fit takes `p` of them, and what is left under-states the
/// noise by that share. Residuals summed over overlapping runs of `block` samples carry about
/// 1.5 values per run length (the equivalent degrees of freedom of Bartlett's kernel) per joint;
/// with runs of one sample this is the textbook `m / (m − p)`. On filtered, period-averaged logs
/// the runs are long and the difference matters: σ_β came out 22 % low on simulated data without
/// it (docs/identification.md).
fn degrees_of_freedom_factor(m: usize, p: usize, samples: usize, block: usize) -> f64 {
    let (m, p) = (m as f64, p as f64);
    let joints = m / samples.max(1) as f64;
    let effective = m.min(1.5 * samples as f64 / block.max(1) as f64 * joints);
    // With fewer than two values per parameter left, the estimate of the noise is itself too
    // uncertain to correct further: the factor is capped at 2.
    (effective / (effective - p).max(0.5 * effective)).max(m / (m - p))
}

/// Refuse data in which some base parameter never acts.
fn check_excitation(w: &Mat<f64>, base: &BaseParameters) -> Result<(), EstimateError> {
    let p = w.ncols();
    // Plain sums of squares: faer's overflow-safe norm scales every entry, which on a long log's
    // W took a tenth of the fit, and a regressor's entries are nowhere near 10¹⁵⁰.
    let norms: Vec<f64> = (0..p).map(|j| w.col(j).iter().map(|x| x * x).sum::<f64>().sqrt()).collect();
    let largest = norms.iter().copied().fold(0.0, f64::max);
    let dead: Vec<String> = norms
        .iter()
        .enumerate()
        .filter(|(_, n)| **n <= 1e-12 * largest)
        .map(|(j, _)| format!("β{} ({})", j + 1, base.names[j]))
        .collect();
    if !dead.is_empty() {
        return Err(EstimateError::NotExcited(dead.join(", ")));
    }
    Ok(())
}

/// The combination of base parameters that the data sees least: the right singular vector of the
/// column-scaled R for its smallest singular value, as readable terms.
fn weakest_direction(r_factor: &Mat<f64>, base: &BaseParameters) -> String {
    let p = r_factor.ncols();
    let scaled = Mat::from_fn(p, p, |i, j| r_factor[(i, j)] / r_factor.col(j).norm_l2().max(f64::MIN_POSITIVE));
    let Some(weakest) = dense::weakest_direction(scaled.as_ref()) else { return "unknown".into() };
    let mut terms: Vec<(usize, f64)> = weakest.into_iter().enumerate().filter(|(_, c)| c.abs() > 0.1).collect();
    terms.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    terms.iter().map(|(j, c)| format!("{c:+.2}·β{} ({})", j + 1, base.names[*j])).collect::<Vec<_>>().join(" ")
}

/// `W x` for a stacked regressor `W` (any number of columns matching `x`).
pub fn apply(w: &Mat<f64>, beta: &[f64]) -> Vec<f64> {
    let b = Mat::<f64>::from_fn(beta.len(), 1, |i, _| beta[i]);
    let product = w * &b;
    (0..w.nrows()).map(|i| product[(i, 0)]).collect()
}

fn residual(w: &Mat<f64>, tau: &[f64], beta: &[f64]) -> Vec<f64> {
    apply(w, beta).iter().zip(tau).map(|(p, t)| t - p).collect()
}

fn rms_per_joint(residual: &[f64], dof: usize) -> Vec<f64> {
    let samples = residual.len() / dof;
    (0..dof)
        .map(|k| (residual.iter().skip(k).step_by(dof).map(|e| e * e).sum::<f64>() / samples as f64).sqrt())
        .collect()
}

/// FP%, relative error and RMS per joint for measured `tau` and predicted `tau_hat` (row-major
/// samples × dof).
pub fn joint_metrics(tau: &[f64], tau_hat: &[f64], dof: usize) -> JointMetrics {
    let samples = tau.len() / dof;
    let mut metrics = JointMetrics { fp_percent: vec![], relative_error: vec![], rms: vec![] };
    for k in 0..dof {
        let column = |x: &[f64]| x.iter().skip(k).step_by(dof).copied().collect::<Vec<f64>>();
        let (t, h) = (column(tau), column(tau_hat));
        let mean = t.iter().sum::<f64>() / samples as f64;
        let err = t.iter().zip(&h).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
        let spread = t.iter().map(|a| (a - mean) * (a - mean)).sum::<f64>().sqrt();
        let norm = t.iter().map(|a| a * a).sum::<f64>().sqrt();
        metrics.fp_percent.push(100.0 * (1.0 - err / spread));
        metrics.relative_error.push(err / norm);
        metrics.rms.push(err / (samples as f64).sqrt());
    }
    metrics
}
