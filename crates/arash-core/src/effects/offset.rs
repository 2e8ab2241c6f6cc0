//! `offset`: a constant torque on a joint (a sensor bias, a cable's pretension, a spring).

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct Offset;

impl Effect for Offset {
    fn id(&self) -> &'static str {
        "offset"
    }
    fn column_names(&self) -> Vec<String> {
        vec!["1".into()]
    }
    fn plotted_against(&self) -> &'static str {
        "t"
    }
    fn features(&self, _: &EffectTerm, _: Sample, _: &mut TermState, out: &mut [f64]) {
        out[0] = 1.0;
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![data.term(EffectKind::Offset)])
    }
}
