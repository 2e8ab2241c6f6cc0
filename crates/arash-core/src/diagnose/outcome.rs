//! The updated model and the signals behind the plots, once the search is over.

use super::findings::Series;
use super::options::DiagnoseError;
use super::prepare::Prepared;
use super::regression::{self, Fitted};
use super::weighted_fit::{Candidate, Problem};
use crate::base_parameters::BaseParameters;
use crate::model::Model;
use crate::model_file::{IdentifyMethod, ModelFile};
use crate::signal::log::Log;

/// What a written model records of the log it was fitted on.
pub(super) struct Source {
    pub(super) samples_in: usize,
    pub(super) fingerprint: String,
    /// Whether the given model was fitted on this log (its file's fingerprint is this log's).
    pub(super) fitted_the_given: bool,
}

impl Source {
    /// `given`: the given model file's fingerprint, if it has one.
    pub(super) fn of(log: &Log, given: Option<&str>) -> Self {
        let fingerprint = log.fingerprint();
        let fitted_the_given = given.is_some_and(|stored| log.has_fingerprint(stored, &fingerprint));
        Self { samples_in: log.t.len(), fingerprint, fitted_the_given }
    }
}

/// The model file for a refitted declared model: OLS on the samples the diagnosis used, with the
/// effects found taken out of the torque first (their coefficients are set after). σ%, the fit
/// and the condition number come from that fit, as `arash identify` reports them; σ over runs of
/// `block_s` (the held-out blocks' length).
pub(super) fn declared_model(
    model: &Model,
    base: &BaseParameters,
    urdf: &str,
    data: &Prepared,
    series: &Series,
    block_s: f64,
    source: &Source,
) -> Result<ModelFile, DiagnoseError> {
    use crate::model_file::{DataSummary, Fitted, Settings};
    use crate::physical::nearest_standard_parameters;
    use crate::signal::estimate::{fit_stacked, Method};
    let dof = data.dof;
    let rows = data.samples() * dof;
    let w = faer::Mat::<f64>::from_fn(rows, data.declared.len(), |i, j| data.declared[j].at(i / dof, i % dof, dof));
    let mut tau = series.tau.clone();
    for contribution in &series.contributions {
        tau.iter_mut().zip(contribution).for_each(|(t, c)| *t -= c);
    }
    let stride = data.stride();
    let block = ((block_s * data.fs / stride as f64).round() as usize).max(1);
    let fit = fit_stacked(&w, &tau, dof, base, Method::Ols, block).map_err(DiagnoseError::Estimate)?;
    let nearest = nearest_standard_parameters(model, base, &fit.beta);
    let fitted = Fitted {
        beta: fit.beta.clone(),
        sigma_percent: fit.sigma_percent.clone(),
        beta_covariance: crate::dense::square_row_major(fit.covariance.as_ref(), base.rank),
        params: None,
        training: fit.metrics.clone().into(),
        training_ols: fit.metrics.clone().into(),
        min_pseudo_inertia_eigenvalue: crate::physical::min_pseudo_inertia_eigenvalues(model, &nearest),
        condition_number: fit.condition_number,
        determination: fit.determination.clone(),
    };
    Ok(ModelFile::new(
        model,
        base,
        urdf,
        fitted,
        Settings {
            method: IdentifyMethod::Ols,
            periods: None,
            period_s: None,
            cutoff_hz: data.pre.cutoff_hz,
            friction_cutoff_hz: Some(data.pre.friction_cutoff_hz),
            coulomb_epsilon: Settings::law_fields(&model.coulomb_laws).0,
            friction_velocities: Settings::law_fields(&model.coulomb_laws).1,
            order: data.pre.order,
            decimate: stride,
            pull: 0.0,
            stiffness_bounds: (None, None),
            reasons: data.pre.choices.reasons.clone(),
            warnings: data.pre.choices.warnings.clone(),
        },
        DataSummary {
            sources: vec![],
            samples_in: source.samples_in,
            samples_used: data.samples(),
            sample_rate_hz: data.fs,
            periods_averaged: 1,
            fingerprint: Some(source.fingerprint.clone()),
        },
    ))
}

/// The signals behind the plots: the training samples as used, the residual of the declared
/// model (`before`: its columns and coefficients) and of the final one (`after`), and each
/// accepted effect's contribution.
pub(super) fn series(
    data: &Prepared,
    problem: &Problem,
    before: Fitted,
    after: Fitted,
    pool: &[Candidate],
    chosen: &[usize],
) -> Series {
    let dof = data.dof;
    let mut contributions = Vec::new();
    let (after_cols, x_after) = (after.columns, after.coefficients);
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
        residual_before: problem.residual(before.columns, before.coefficients),
        residual_after: problem.residual(after_cols, x_after),
        contributions,
    }
}
