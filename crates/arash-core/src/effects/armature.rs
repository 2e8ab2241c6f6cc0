//! `armature`: rotor inertia reflected through the transmission, `q̈`. On one joint, or on every
//! joint at once (`joint: None`, one coefficient per joint): rotor inertia is a property of
//! every drive, and one candidate for all joints competes fairly with a payload, which also
//! changes the inertia of several joints.

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct Armature;

impl Effect for Armature {
    fn id(&self) -> &'static str {
        "armature"
    }
    fn column_names(&self) -> Vec<String> {
        vec!["q̈".into()]
    }
    /// Inertia is positive.
    fn physical_sign(&self) -> Option<f64> {
        Some(1.0)
    }
    fn plotted_against(&self) -> &'static str {
        "qdd"
    }
    fn features(&self, _: &EffectTerm, x: Sample, _: &mut TermState, out: &mut [f64]) {
        out[0] = x.qdd;
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![data.term(EffectKind::Armature)])
    }
}

/// The candidate on every joint at once, with one column per joint.
pub fn every_joint(joint_names: &[String]) -> EffectTerm {
    let mut t = EffectTerm::new(EffectKind::Armature, None);
    t.columns = joint_names.iter().map(|j| format!("q̈ of {j}")).collect();
    t
}
