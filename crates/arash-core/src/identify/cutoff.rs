//! The cut-off identification uses when the user sets none.
//!
//! The positions' spectrum bounds the motion ([`super::decide`]), but not everything that moves
//! is what the model explains: a closed-loop log repeats, period after period, a controller's
//! response at several hertz that the rigid-body model with friction does not reproduce, and that
//! costs the fit more than the noise a lower cut-off would let through. So the cut-off is chosen
//! by the fit itself: ordinary least squares at cut-offs from the lowest the log allows
//! ([`lowest_cutoff_hz`]) up to [`SEARCH_ABOVE_SPECTRAL`] times the spectral rule's value, the one
//! that explains the filtered torque best. A cut-off below the
//! motion's bandwidth bends the signal, which the fit shows at once, so the choice cannot run off
//! to the lowest value; between cut-offs that fit alike the highest is kept.
//! docs/identification.md ("Choices made from the data") gives the measurements.

use super::estimate::{fit, Method};
use super::preprocess::{
    friction_cutoff_hz, lowest_cutoff_hz, preprocess, Choices, PreprocessError, PreprocessOptions, Preprocessed,
};
use super::{Declared, IdentifyError, Log};

/// Cut-offs tried per doubling: a step of 19 %, which changes the fit by far less than a point.
pub const CUTOFFS_PER_OCTAVE: f64 = 4.0;

/// The search goes this far above the spectral rule's cut-off: the torque holds products and
/// harmonics of the motion (Coriolis terms, gravity's sine of the angle) above the motion's own
/// bandwidth, and on some logs they matter more than the noise a higher cut-off lets in.
pub const SEARCH_ABOVE_SPECTRAL: f64 = 4.0;

/// Cut-offs whose mean FP% is within this many points of the best count as equally good; the
/// highest of them is chosen, because it bends the signal least.
pub const EQUAL_FIT_POINTS: f64 = 0.1;

/// The candidate's samples are thinned to at least this many per period of the highest cut-off
/// in play (the friction velocity's), which leaves the fit's figures unchanged and the search
/// several times faster on long logs.
const SEARCH_SAMPLES_PER_CUTOFF: f64 = 20.0;

/// The log preprocessed at the cut-off that fits best, its choices saying why. A cut-off the user
/// set is kept.
///
/// The friction velocity's cut-off is not searched: on the demo's closed-loop log a search by the
/// same criterion picked 26.8 Hz for a fit within 0.1 point of 20 Hz's, and the robust controller
/// with that model lost the paper's halving of the insertion error (docs/identification.md).
pub fn preprocess_for_fit(
    declared: Declared,
    log: Log,
    options: &PreprocessOptions,
) -> Result<Preprocessed, IdentifyError> {
    let dof = declared.model.dof();
    let spectral = preprocess(log.t, log.q, log.tau, dof, options)?;
    // The period found once is kept for every candidate.
    let fixed = PreprocessOptions { period_s: spectral.period_s, periods: Some(1), ..options.clone() };
    let floor = lowest_cutoff_hz(log.t.len(), spectral.sample_rate_hz, spectral.periodic);
    let top = search_top(&spectral);
    let searched = match options.cutoff_hz {
        Some(_) => None,
        None => {
            let scored = score(declared, log, &fixed, spectral.sample_rate_hz, &candidate_cutoffs(floor, top))?;
            best_of(&scored).map(|chosen| (chosen, scored))
        }
    };
    let cutoff = searched.as_ref().map_or(spectral.cutoff_hz, |m| m.0);
    let mut pre = preprocess(log.t, log.q, log.tau, dof, &PreprocessOptions { cutoff_hz: Some(cutoff), ..fixed })?;
    pre.choices = explain(&spectral.choices, &pre.choices, (floor, spectral.cutoff_hz, top), &searched);
    Ok(pre)
}

/// The highest cut-off tried: [`SEARCH_ABOVE_SPECTRAL`] times the spectral rule's, within a
/// quarter of the sample rate.
fn search_top(spectral: &Preprocessed) -> f64 {
    (SEARCH_ABOVE_SPECTRAL * spectral.cutoff_hz).min(0.25 * spectral.sample_rate_hz)
}

/// Mean training FP% of an OLS fit at each candidate cut-off (`fs`: the rate `fixed` preprocesses
/// at); candidates that cannot be filtered or fitted are left out.
fn score(
    declared: Declared,
    log: Log,
    fixed: &PreprocessOptions,
    fs: f64,
    candidates: &[f64],
) -> Result<Vec<(f64, f64)>, IdentifyError> {
    let Declared { model, base, .. } = declared;
    let dof = model.dof();
    let mut scored = Vec::with_capacity(candidates.len());
    for &cutoff in candidates {
        // The Coulomb columns are shaped from the friction velocity after thinning, so the thinned
        // rate must carry that velocity too, not only the cut-off.
        let friction_hz = friction_cutoff_hz(fixed.friction_cutoff_hz, cutoff, fs);
        let thin = ((fs / (SEARCH_SAMPLES_PER_CUTOFF * friction_hz)).floor() as usize).max(1);
        let trial = PreprocessOptions { cutoff_hz: Some(cutoff), decimate: thin, ..fixed.clone() };
        let pre = match preprocess(log.t, log.q, log.tau, dof, &trial) {
            Ok(pre) => pre,
            Err(PreprocessError::DecimationAliases { .. } | PreprocessError::TooShortForCutoff { .. }) => continue,
            Err(e) => return Err(e.into()),
        };
        // A cut-off at which the parameters cannot be fitted is simply not a candidate.
        if let Ok(f) = fit(model, base, &pre, Method::Ols) {
            scored.push((cutoff, f.metrics.fp_percent.iter().sum::<f64>() / dof as f64));
        }
    }
    Ok(scored)
}

/// The highest candidate within [`EQUAL_FIT_POINTS`] of the best (it bends the signal least);
/// `None` when none fitted.
fn best_of(scored: &[(f64, f64)]) -> Option<f64> {
    let best = scored.iter().map(|s| s.1).reduce(f64::max)?;
    scored.iter().rev().find(|s| s.1 >= best - EQUAL_FIT_POINTS).map(|s| s.0)
}

/// Geometric steps from `floor` to `top` (both included).
fn candidate_cutoffs(floor: f64, top: f64) -> Vec<f64> {
    if top <= floor {
        return vec![top];
    }
    let steps = (CUTOFFS_PER_OCTAVE * (top / floor).log2()).ceil() as usize;
    (0..=steps).map(|i| floor * (top / floor).powf(i as f64 / steps as f64)).collect()
}

/// The spectral choices (period, bandwidth) with the cut-off line replaced by the search's, the
/// lines that depend on the cut-off from the final preprocessing, and a warning when the best fit
/// sits at the lowest cut-off tried.
fn explain(
    spectral: &Choices,
    last: &Choices,
    (floor, rule, top): (f64, f64, f64),
    searched: &Option<(f64, Vec<(f64, f64)>)>,
) -> Choices {
    // The lines that depend on the cut-off come from the final preprocessing.
    let from_last = |r: &String| r.starts_with("Coulomb") || r.contains("left out of the fit");
    let mut reasons: Vec<String> = spectral.reasons.iter().filter(|r| !from_last(r)).cloned().collect();
    let mut warnings = spectral.warnings.clone();
    if let Some((chosen, scored)) = searched {
        let at = reasons.iter().position(|r| r.starts_with("cut-off")).unwrap_or(reasons.len());
        let spectral_line = reasons.get(at).cloned().unwrap_or_default();
        let line = format!(
            "cut-off {chosen:.3} Hz: the best least-squares fit (mean FP% {:.2}) of {} cut-offs from {floor:.2} to {top:.2} Hz, \
             around the spectral rule's {rule:.2} Hz ({}); mean FP% by cut-off: {}",
            scored.iter().find(|s| s.0 == *chosen).map_or(f64::NAN, |s| s.1),
            scored.len(),
            spectral_line.trim_start_matches(&format!("cut-off {rule:.3} Hz: ")),
            scored.iter().map(|(c, fp)| format!("{c:.2} Hz {fp:.2}")).collect::<Vec<_>>().join(", "),
        );
        match at < reasons.len() {
            true => reasons[at] = line,
            false => reasons.push(line),
        }
        if scored.len() > 1 && *chosen == scored[0].0 && top > floor {
            warnings.push(format!(
                "the best fit is at the lowest cut-off tried ({chosen:.2} Hz): the data may be noisier than the motion \
                 is fast; consider a longer log or more periods"
            ));
        }
    }
    reasons.extend(last.reasons.iter().filter(|r| from_last(r)).cloned());
    Choices { reasons, warnings }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alike_fits_keep_the_highest_cutoff() {
        let scored = [(1.0, 90.0), (2.0, 99.0), (4.0, 99.05), (8.0, 98.0)];
        assert_eq!(best_of(&scored), Some(4.0));
        assert_eq!(best_of(&[]), None);
    }

    #[test]
    fn candidates_step_geometrically_from_the_floor_to_the_top() {
        let c = candidate_cutoffs(1.0, 8.0);
        assert_eq!(c.len(), 13, "{c:?}");
        assert!((c[0] - 1.0).abs() < 1e-12 && (c[12] - 8.0).abs() < 1e-12);
        assert!(c.windows(2).all(|w| (w[1] / w[0] - 2f64.powf(0.25)).abs() < 1e-12));
        assert_eq!(candidate_cutoffs(1.0, 0.5), vec![0.5]);
    }
}
