//! The delay search: an integer shift of the torque against the position, searched before any
//! other effect because an unmodelled delay otherwise masquerades as velocity-dependent
//! friction.

use super::findings::{rejection, Finding, Rejection, RejectionReason};
use super::inputs::Context;
use super::prepare::Prepared;
use super::regression::{least_squares, residual, test_group, Column, NormalEquations, Rows, Untested};
use super::weighted_fit::{sse, Problem};
use crate::effects::{EffectKind, EffectTerm};
use crate::signal::conditioning::central_difference;

/// Search an integer shift of the torque against the position, and accept it only if it is
/// significant (a block Wald test of the linearised delay, the derivative of the predicted
/// torque) and cuts the held-out error by at least `min_gain`. Returns the shift to apply.
pub(super) fn search_delay(ctx: &Context) -> (isize, Result<Finding, Rejection>) {
    match delay_finding(ctx) {
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
fn delay_finding(ctx: &Context) -> Result<Finding, (isize, Rejection)> {
    let (model, train, validation, options) = (ctx.model, &ctx.train, ctx.validation.as_ref(), ctx.options);
    let (weights, free, split) = (&ctx.weights[..], &ctx.free[..], &ctx.split);
    let max_shift = ctx.max_shift();
    let fixed_prediction = |data: &Prepared| ctx.fixed_prediction(data, &ctx.free);
    let dof = train.dof;
    let mut term = EffectTerm::new(EffectKind::Delay, None);
    term.columns = vec!["shift".into()];
    let reject = |term: &EffectTerm, reason: RejectionReason, p: Option<f64>, gain: Option<f64>| {
        rejection(model, term, reason, p, gain)
    };
    let fixed = fixed_prediction(train);
    // One weighted problem; only its target moves with the shift.
    let zero = Problem::new(train, train.tau(0), fixed.clone(), weights, free);
    let target = |data: &Prepared, fixed: &[f64], d: isize| -> Vec<f64> {
        data.tau(d).iter().zip(fixed).enumerate().map(|(i, (t, f))| (t - f) * weights[i % dof]).collect()
    };
    let declared = NormalEquations::over(zero.free_columns().collect(), &zero.y, dof, Rows::All);
    let declared_refs = &declared.columns;
    let total_sse = |y: &[f64]| -> f64 {
        let x = declared.solve_for(y).unwrap_or_else(|| vec![0.0; declared_refs.len()]);
        sse(declared_refs, &x, y, dof, Rows::All).iter().sum()
    };
    let scores: Vec<f64> = (-max_shift..=max_shift).map(|d| total_sse(&target(train, &fixed, d))).collect();
    let best = (0..scores.len()).min_by(|&a, &b| scores[a].total_cmp(&scores[b])).unwrap_or(max_shift as usize);
    let shift = best as isize - max_shift;
    term.scale = Some(shift as f64);
    if shift == 0 {
        return Err((0, reject(&term, RejectionReason::NoMisalignment, None, None)));
    }
    if shift.abs() <= ALIGNMENT_SAMPLES {
        return Err((shift, reject(&term, RejectionReason::Alignment { shift }, None, None)));
    }
    if shift.abs() == max_shift {
        return Err((0, reject(&term, RejectionReason::AtSearchEdge { max_shift }, None, None)));
    }
    // The linearised test: τ(t − d) ≈ τ(t) − d·τ̇(t).
    let x0 = declared.solve().unwrap_or_else(|| vec![0.0; declared_refs.len()]);
    let e0 = residual(declared_refs, &x0, &zero.y, dof);
    let predicted: Vec<f64> = zero.y.iter().zip(&e0).map(|(y, e)| y - e).collect();
    let h = train.stride() as f64 / train.fs;
    let column = Column::dense(central_difference(&predicted, dof, h, false), dof);
    // A given model's calibration error is formed on the problem this search shifts; a delay is
    // judged against the declared fit on this log alone.
    let test = match test_group(&declared, &e0, &[&column], ctx.batching, &[]) {
        Ok(test) => test,
        Err(Untested::Dependent { .. }) => return Err((0, reject(&term, RejectionReason::Untestable, None, None))),
        Err(Untested::TooFewBatches { batches, columns }) => {
            return Err((0, reject(&term, RejectionReason::TooShort { batches, columns }, None, None)))
        }
    };
    let gains: Vec<f64> = match validation {
        Some(v) => {
            let vfixed = fixed_prediction(v);
            let vzero = Problem::new(v, v.tau(0), vfixed.clone(), weights, free);
            let vrefs: Vec<&Column> = vzero.free_columns().collect();
            let at = |d: isize| -> Vec<f64> {
                let x = declared.solve_for(&target(train, &fixed, d)).unwrap_or_else(|| vec![0.0; declared_refs.len()]);
                sse(&vrefs, &x, &target(v, &vfixed, d), dof, Rows::All)
            };
            ctx.floor.gains(&at(0), &at(shift))
        }
        None => {
            let (train_rows, test_rows) = (&split.train, &split.test);
            let at = |d: isize| -> Vec<f64> {
                let y = target(train, &fixed, d);
                let x = least_squares(declared_refs, &y, dof, Rows::Where(train_rows))
                    .unwrap_or_else(|| vec![0.0; declared_refs.len()]);
                sse(declared_refs, &x, &y, dof, Rows::Where(test_rows))
            };
            ctx.floor.gains(&at(0), &at(shift))
        }
    };
    // Judged, as every effect on several joints is, on the joint it helps most: a misalignment
    // shows where the torque changes fastest and costs a slow joint nothing.
    let gain = gains.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let p_value = Some(test.p_value);
    if test.p_value > options.alpha {
        let reason = RejectionReason::DelayNotSignificant { p_value: test.p_value, alpha: options.alpha };
        return Err((0, reject(&term, reason, p_value, Some(gain))));
    }
    if gain < options.min_gain {
        let reason = RejectionReason::DelaySmallGain { shift, gain, min_gain: options.min_gain };
        return Err((0, reject(&term, reason, p_value, Some(gain))));
    }
    term.coefficients = vec![shift as f64 / train.fs];
    term.sigma = vec![test.sigma[0]];
    Ok(Finding {
        name: "delay".into(),
        joints: (0..dof).collect(),
        label: term.describe(&model.joint_names()),
        term,
        statistic: test.f_statistic,
        batches: test.batches,
        batch_s: test.batch_samples as f64 / train.kept_rate(),
        p_value: test.p_value,
        threshold: options.alpha,
        heldout_gain: gain,
        heldout_gain_per_joint: gains,
        aliases: vec![],
        mass_kg: None,
        mass_sigma_kg: None,
        body: None,
        centre_of_mass_m: None,
        sigma_from_gains: vec![],
        round: 0,
        refined: None,
    })
}
