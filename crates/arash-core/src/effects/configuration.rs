//! `configuration_disturbance`: a torque that depends on where the joint is (wiring, a cable's
//! spring, an unmodelled mass), as a cosine series over the joint's range.

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

/// Terms of the cosine series. The constant term is left out: a position-dependent torque with a
/// mean would also be an offset.
pub const CONFIGURATION_HARMONICS: usize = 4;

pub struct ConfigurationDisturbance;

impl Effect for ConfigurationDisturbance {
    fn id(&self) -> &'static str {
        "configuration_disturbance"
    }
    fn width(&self) -> usize {
        CONFIGURATION_HARMONICS
    }
    fn column_names(&self) -> Vec<String> {
        (1..=CONFIGURATION_HARMONICS).map(|m| format!("cos({m}πx)")).collect()
    }
    fn plotted_against(&self) -> &'static str {
        "q"
    }
    fn features(&self, term: &EffectTerm, x: Sample, _: &mut TermState, out: &mut [f64]) {
        let unit = term.unit(x.q);
        for (m, o) in out.iter_mut().enumerate().take(CONFIGURATION_HARMONICS) {
            *o = (std::f64::consts::PI * (m + 1) as f64 * unit).cos();
        }
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![data.term(EffectKind::ConfigurationDisturbance)])
    }
}
