//! `drive_gain`: a joint's torque scaled by a wrong constant, `g τ`. Torque logged as a motor
//! current times an assumed torque constant, a gear ratio or cable drum radius that is off, or a
//! current sensor's scale: the joint's measured torque is (1 + g) times what the model says.
//!
//! The column is the model's own torque on the joint: in the diagnosis the declared model's
//! prediction (fitted, or the given model's), at run time the controller's command before this
//! term. A command passes the same drive, so the compensation scales all of it, feedback too.
//!
//! One gain on every joint is a scale of all parameters, which a fit absorbs; a gain on one
//! joint is not, unless that joint's torque uses only parameters of its own (then the
//! diagnosis's VIF says the candidate is not identifiable).

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct DriveGain;

impl Effect for DriveGain {
    fn id(&self) -> &'static str {
        "drive_gain"
    }
    fn column_names(&self) -> Vec<String> {
        vec!["τ (model)".into()]
    }
    fn plotted_against(&self) -> &'static str {
        "tau"
    }
    fn floor(&self) -> Option<(f64, &'static str)> {
        Some((-1.0, "a drive's gain factor 1 + g must be positive"))
    }
    fn features(&self, _: &EffectTerm, x: Sample, _: &mut TermState, out: &mut [f64]) {
        out[0] = x.tau;
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![data.term(EffectKind::DriveGain)])
    }
}
