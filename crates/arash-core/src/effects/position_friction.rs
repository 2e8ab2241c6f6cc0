//! `position_friction`: Coulomb friction that changes over the joint's range (a cable's wrap
//! angle, a tight spot), `s(q̇)·x` and `s(q̇)·x²` with x in [−1, 1] over the range.

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct PositionFriction;

impl Effect for PositionFriction {
    fn id(&self) -> &'static str {
        "position_friction"
    }
    fn width(&self) -> usize {
        2
    }
    fn column_names(&self) -> Vec<String> {
        vec!["s(q̇)·x".into(), "s(q̇)·x²".into()]
    }
    fn filtered_like_torque(&self) -> bool {
        true
    }
    fn plotted_against(&self) -> &'static str {
        "q"
    }
    fn features(&self, term: &EffectTerm, x: Sample, _: &mut TermState, out: &mut [f64]) {
        let s = term.direction(x.v);
        let u = 2.0 * term.unit(x.q) - 1.0;
        out[0] = s * u;
        out[1] = s * u * u;
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![data.term(EffectKind::PositionFriction)])
    }
}
