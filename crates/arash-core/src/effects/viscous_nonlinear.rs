//! `viscous_nonlinear`: viscous friction that grows faster than linearly, `q̇·|q̇|`.

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct ViscousNonlinear;

impl Effect for ViscousNonlinear {
    fn id(&self) -> &'static str {
        "viscous_nonlinear"
    }
    fn column_names(&self) -> Vec<String> {
        vec!["q̇·|q̇|".into()]
    }
    /// `q̇·|q̇|` is smooth enough for the filtered velocity, and the friction velocity's
    /// quantisation noise would leak into it: not filtered like the torque.
    fn filtered_like_torque(&self) -> bool {
        false
    }
    /// Dissipative.
    fn physical_sign(&self) -> Option<f64> {
        Some(1.0)
    }
    fn plotted_against(&self) -> &'static str {
        "qd"
    }
    fn features(&self, _: &EffectTerm, x: Sample, _: &mut TermState, out: &mut [f64]) {
        out[0] = x.v * x.v.abs();
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![data.term(EffectKind::ViscousNonlinear)])
    }
}
