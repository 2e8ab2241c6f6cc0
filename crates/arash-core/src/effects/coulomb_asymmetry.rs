//! `coulomb_asymmetry`: Coulomb friction of a different size in each direction, `|s(q̇)|`, which
//! with the declared `fc·s(q̇)` makes `fc⁺` and `fc⁻`.

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct CoulombAsymmetry;

impl Effect for CoulombAsymmetry {
    fn id(&self) -> &'static str {
        "coulomb_asymmetry"
    }
    fn column_names(&self) -> Vec<String> {
        vec!["|s(q̇)|".into()]
    }
    fn filtered_like_torque(&self) -> bool {
        true
    }
    fn plotted_against(&self) -> &'static str {
        "qd"
    }
    fn features(&self, term: &EffectTerm, x: Sample, _: &mut TermState, out: &mut [f64]) {
        out[0] = term.direction(x.v).abs();
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![data.term(EffectKind::CoulombAsymmetry)])
    }
}
