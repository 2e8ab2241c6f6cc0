//! The cut-off identification uses when the user sets none.
//!
//! The positions' spectrum bounds the motion ([`super::decide`]), but not everything that moves
//! is what the model explains: a closed-loop log repeats, period after period, a controller's
//! response at several hertz that the rigid-body model with friction does not reproduce, and that
//! costs the fit more than the noise a lower cut-off would let through. So the cut-off is chosen
//! by the fit itself: ordinary least squares at cut-offs from [`MIN_CUTOFF_HZ`] up to the
//! spectral rule's value, the one that explains the filtered torque best. A cut-off below the
//! motion's bandwidth bends the signal, which the fit shows at once, so the choice cannot run off
//! to the lowest value; between cut-offs that fit alike the highest is kept.
//! docs/identification.md ("Choices made from the data") gives the measurements.

use super::estimate::{fit, Method};
use super::preprocess::{preprocess, Choices, PreprocessError, PreprocessOptions, Preprocessed, MIN_CUTOFF_HZ};
use super::{Declared, IdentifyError, Log};

/// Cut-offs tried per doubling: a step of 19 %, which changes the fit by far less than a point.
pub const CUTOFFS_PER_OCTAVE: f64 = 4.0;

/// Cut-offs whose mean FP% is within this many points of the best count as equally good; the
/// highest of them is chosen, because it bends the signal least.
pub const EQUAL_FIT_POINTS: f64 = 0.1;

/// The candidate's samples are thinned to at least this many per cut-off period for the search,
/// which leaves the fit's figures unchanged and the search several times faster on long logs.
const SEARCH_SAMPLES_PER_CUTOFF: f64 = 20.0;

/// The log preprocessed at the cut-off that fits best, its choices saying why.
pub fn preprocess_for_fit(
    declared: Declared,
    log: Log,
    options: &PreprocessOptions,
) -> Result<Preprocessed, IdentifyError> {
    let Declared { model, base, .. } = declared;
    let dof = model.dof();
    let spectral = preprocess(log.t, log.q, log.tau, dof, options)?;
    if options.cutoff_hz.is_some() {
        return Ok(spectral);
    }
    // The period found once is kept for every candidate.
    let fixed = PreprocessOptions { period_s: spectral.period_s, periods: Some(1), ..options.clone() };
    let candidates = candidate_cutoffs(spectral.cutoff_hz);
    let mut scored = Vec::with_capacity(candidates.len());
    for &cutoff in &candidates {
        let thin = ((spectral.sample_rate_hz / (SEARCH_SAMPLES_PER_CUTOFF * cutoff)).floor() as usize).max(1);
        let trial = PreprocessOptions { cutoff_hz: Some(cutoff), decimate: thin, ..fixed.clone() };
        let pre = match preprocess(log.t, log.q, log.tau, dof, &trial) {
            Ok(pre) => pre,
            Err(PreprocessError::DecimationAliases { .. }) => continue,
            Err(e) => return Err(e.into()),
        };
        // A cut-off at which the parameters cannot be fitted is simply not a candidate.
        if let Ok(f) = fit(model, base, &pre, Method::Ols) {
            let mean = f.metrics.fp_percent.iter().sum::<f64>() / dof as f64;
            scored.push((cutoff, mean));
        }
    }
    let Some(best) = scored.iter().map(|s| s.1).reduce(f64::max) else {
        return Ok(spectral);
    };
    let chosen = scored.iter().rev().find(|s| s.1 >= best - EQUAL_FIT_POINTS).expect("the best qualifies").0;
    let final_options = PreprocessOptions { cutoff_hz: Some(chosen), ..fixed };
    let mut pre = preprocess(log.t, log.q, log.tau, dof, &final_options)?;
    pre.choices = explain(&spectral.choices, &pre.choices, (chosen, spectral.cutoff_hz), &scored);
    Ok(pre)
}

/// Geometric steps from [`MIN_CUTOFF_HZ`] to `top` (both included).
fn candidate_cutoffs(top: f64) -> Vec<f64> {
    if top <= MIN_CUTOFF_HZ {
        return vec![top];
    }
    let steps = (CUTOFFS_PER_OCTAVE * (top / MIN_CUTOFF_HZ).log2()).ceil() as usize;
    (0..=steps).map(|i| MIN_CUTOFF_HZ * (top / MIN_CUTOFF_HZ).powf(i as f64 / steps as f64)).collect()
}

/// The spectral choices (period, bandwidth) with the cut-off line replaced by the search's, the
/// friction line of the final preprocessing, and a warning when the best fit sits at an end.
fn explain(spectral: &Choices, last: &Choices, (chosen, top): (f64, f64), scored: &[(f64, f64)]) -> Choices {
    let is_cutoff = |r: &&String| r.starts_with("cut-off");
    let mut reasons: Vec<String> = spectral.reasons.iter().filter(|r| !r.starts_with("Coulomb")).cloned().collect();
    let figures = scored.iter().map(|(c, fp)| format!("{c:.2} Hz {fp:.2}")).collect::<Vec<_>>().join(", ");
    let at = reasons.iter().position(|r| is_cutoff(&r)).unwrap_or(reasons.len());
    let spectral_line = reasons.get(at).cloned().unwrap_or_default();
    let best = scored.iter().find(|s| s.0 == chosen).map_or(f64::NAN, |s| s.1);
    let line = format!(
        "cut-off {chosen:.3} Hz: the best least-squares fit (mean FP% {best:.2}) of {} cut-offs from {MIN_CUTOFF_HZ:.2} to \
         {top:.2} Hz, the top one being the spectral rule's ({}); mean FP% by cut-off: {figures}",
        scored.len(),
        spectral_line.trim_start_matches(&format!("cut-off {top:.3} Hz: ")),
    );
    match at < reasons.len() {
        true => reasons[at] = line,
        false => reasons.push(line),
    }
    reasons.extend(last.reasons.iter().filter(|r| r.starts_with("Coulomb")).cloned());
    let mut warnings = spectral.warnings.clone();
    if scored.len() > 1 && chosen == scored[0].0 && top > MIN_CUTOFF_HZ {
        warnings.push(format!(
            "the best fit is at the lowest cut-off tried ({chosen:.2} Hz): the data may be noisier than the motion \
             is fast; consider a longer log or more periods"
        ));
    }
    Choices { reasons, warnings }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidates_step_geometrically_from_the_floor_to_the_top() {
        let c = candidate_cutoffs(8.0);
        assert_eq!(c.len(), 13, "{c:?}");
        assert!((c[0] - MIN_CUTOFF_HZ).abs() < 1e-12 && (c[12] - 8.0).abs() < 1e-12);
        assert!(c.windows(2).all(|w| (w[1] / w[0] - 2f64.powf(0.25)).abs() < 1e-12));
        assert_eq!(candidate_cutoffs(0.5), vec![0.5]);
    }
}
