//! `cogging`: torque ripple of the motor, `sin(nθ)` and `cos(nθ)` of the motor angle θ = q / r.
//! `scale` is n, the ripple periods per motor revolution; `transmission` is r, joint motion per
//! motor radian.

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct Cogging;

impl Effect for Cogging {
    fn id(&self) -> &'static str {
        "cogging"
    }
    fn width(&self) -> usize {
        2
    }
    fn column_names(&self) -> Vec<String> {
        vec!["sin(nθ)".into(), "cos(nθ)".into()]
    }
    fn filtered_like_torque(&self) -> bool {
        true
    }
    fn plotted_against(&self) -> &'static str {
        "q"
    }
    fn features(&self, term: &EffectTerm, x: Sample, _: &mut TermState, out: &mut [f64]) {
        let n = term.scale.unwrap_or(1.0);
        let theta = x.q / term.transmission.unwrap_or(1.0);
        let (sin, cos) = (n * theta).sin_cos();
        out[0] = sin;
        out[1] = cos;
    }
    fn detail(&self, term: &EffectTerm) -> String {
        format!(" ({} per motor revolution)", term.scale.unwrap_or(0.0))
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        let r = data.transmission.ok_or(NotSearched::TransmissionUnknown)?;
        let mut terms = data.with_scales(EffectKind::Cogging, data.cogging_periods.iter().copied());
        terms.iter_mut().for_each(|t| t.transmission = Some(r));
        Ok(terms)
    }
}
