//! The physically consistent model and the effects a diagnosis found, fitted together.
//!
//! The diagnosis estimates each effect by least squares beside the declared model. A controller
//! that compensates the effects needs a consistent model too (it inverts `M(q)`), and fitting the
//! two separately lets each absorb the other's error: the inertia soaks up part of a wiring
//! torque, or a "payload" soaks up the inertia's error. Here the SDP of
//! [`crate::consistent`] gets the effects' columns as extra columns, so that both
//! come from one fit on the same data. Each coefficient keeps its effect's sign and at most the
//! magnitude the diagnosis measured, within [`REFIT_SIGMAS`] of its σ: the diagnosis estimated
//! it at its own band, where the term is resolved; at a calibration's narrow cut-off it is
//! nearly collinear with the declared friction, and unbounded the two traded freely.

use faer::Mat;

use super::band::Band;
use super::options::{DiagnoseError, DiagnoseOptions, REFIT_SIGMAS};
use super::prepare::{full_columns, prepare, term_columns};
use crate::base_parameters::BaseParameters;
use crate::consistent::{identify_consistent_bounded, ConsistentOptions, ExtraBound};
use crate::effects::{EffectKind, EffectTerm};
use crate::model::Model;
use crate::model_file::{IdentifyMethod, ModelFile};
use crate::signal::estimate::joint_metrics;
use crate::signal::log::Log;

/// Refit `found` (a diagnosis's updated model) as a physically consistent model with its
/// effects, on the training log the diagnosis used. The effects that act at run time are kept
/// (not `delay` or `drift`, whose log-specific meaning a controller cannot use;
/// a delay the diagnosis found still aligns the data); a `payload` is a change of inertial
/// parameters, which the consistent fit estimates anyway. The effects' standard deviations are
/// not re-estimated and are left empty.
pub fn consistent_with_effects(
    model: &Model,
    base: &BaseParameters,
    train: Log,
    found: &ModelFile,
    options: &DiagnoseOptions,
    consistent: &ConsistentOptions,
) -> Result<ModelFile, DiagnoseError> {
    let model = &*found.with_its_law(model);
    let (dof, standard) = (model.dof(), model.num_params());
    // The found model's band, or the one asked for (a calibration's). The friction velocity is
    // the one the effects were found with unless one is set: their friction terms (Stribeck's
    // exp(−(q̇/v_s)²)) are functions of it, their v_s and bounds were estimated on it, and on a
    // velocity filtered at a calibration's slow cut-off (2 Hz at a 4 Hz cut-off, on the demo's
    // rig) the refit kept a tenth of the yaw's Stribeck excess and half the insertion's
    // (docs/diagnosis.md, "The consistent refit's friction velocity").
    let cutoff_hz = options.preprocess.cutoff_hz.unwrap_or(found.settings.cutoff_hz);
    let friction_hz = options.preprocess.friction_cutoff_hz.or(found.settings.friction_cutoff_hz).unwrap_or(cutoff_hz);
    let band = Band { cutoff_hz, friction_hz };
    let mut data =
        prepare(model, base, train.into(), options, band, options.max_delay_s).map_err(DiagnoseError::Training)?;
    // What a drive gain scales: the found model's declared torque.
    let mut predicted = vec![0.0; data.samples() * dof];
    for (column, b) in data.declared.iter().zip(&found.fitted.beta) {
        super::regression::axpy(&mut predicted, *b, column, dof);
    }
    data.predicted = predicted;
    // Each joint's shift: a delay term on one joint shifts that joint's torque, one on none all.
    let mut shifts = vec![0isize; dof];
    for term in found.effects.iter().filter(|t| t.kind == EffectKind::Delay) {
        let shift = term.scale.map_or(0, |s| s.round() as isize);
        match term.joint {
            Some(k) if k < dof => shifts[k] = shift,
            Some(_) => {}
            None => shifts.fill(shift),
        }
    }
    let mut terms: Vec<_> =
        found.effects.iter().filter(|t| t.kind.at_run_time() && t.kind != EffectKind::Payload).cloned().collect();
    let mut columns = full_columns(model, &data.pre, &data.kept);
    let mut widths = Vec::with_capacity(terms.len());
    let mut bounds = Vec::new();
    for term in &terms {
        let term_columns = term_columns(model, term, &data);
        widths.push(term_columns.len());
        bounds.extend((0..term_columns.len()).map(|i| bound(term, i)));
        for column in term_columns {
            let rows = data.samples() * dof;
            columns.push((0..rows).map(|r| column.at(r / dof, r % dof, dof)).collect());
        }
    }
    let tau = data.tau_shifted(&shifts);
    let w = Mat::<f64>::from_fn(tau.len(), columns.len(), |i, j| columns[j][i]);
    let fit = identify_consistent_bounded(model, &w, &tau, consistent, &bounds)?;
    let predicted = crate::signal::estimate::apply(&w, &fit.params);

    let mut extra = fit.params[standard..].iter().copied();
    for (term, width) in terms.iter_mut().zip(widths) {
        term.coefficients = extra.by_ref().take(width).collect();
        term.sigma = vec![];
    }
    let params = fit.params[..standard].to_vec();
    let mut beta = vec![0.0; base.rank];
    base.project(&params, &mut beta);
    let mut model_out = found.clone();
    model_out.fitted.beta = beta;
    model_out.fitted.params = Some(params);
    model_out.fitted.min_pseudo_inertia_eigenvalue = fit.min_pseudo_inertia_eigenvalue;
    model_out.fitted.training = joint_metrics(&tau, &predicted, dof).into();
    model_out.settings.method = IdentifyMethod::Consistent;
    model_out.settings.pull = consistent.pull;
    terms.extend(found.effects.iter().filter(|t| t.kind == EffectKind::Delay).cloned());
    model_out.effects = terms;
    Ok(model_out)
}

/// Coefficient `i` of `term` in the refit: its effect's sign, and at most the diagnosis's
/// estimate's magnitude plus [`REFIT_SIGMAS`] of its σ (none where the term has no σ).
fn bound(term: &EffectTerm, i: usize) -> ExtraBound {
    let estimate = term.coefficients.get(i).zip(term.sigma.get(i));
    let magnitude = estimate.map(|(c, s)| c.abs() + REFIT_SIGMAS * s).filter(|m| m.is_finite());
    ExtraBound { sign: term.coefficient_sign(i), magnitude }
}
