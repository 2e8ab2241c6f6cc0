//! `delay`: the torque recorded later (or earlier) than the position. `scale` is the shift in
//! samples, the coefficient the delay in seconds. A property of the log, not of the robot: it
//! has no columns, the diagnosis searches it first as a shift, and a controller ignores it. A
//! term with no joint shifts every joint's torque, one on a joint that joint's alone (the
//! diagnosis's guard takes the shift off a joint it harms, `diagnose/guard.rs`).

use super::{Effect, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct Delay;

impl Effect for Delay {
    fn id(&self) -> &'static str {
        "delay"
    }
    fn width(&self) -> usize {
        0
    }
    fn column_names(&self) -> Vec<String> {
        vec![]
    }
    fn plotted_against(&self) -> &'static str {
        "t"
    }
    fn at_run_time(&self) -> bool {
        false
    }
    fn features(&self, _: &EffectTerm, _: Sample, _: &mut TermState, _: &mut [f64]) {}
    fn detail(&self, term: &EffectTerm) -> String {
        format!(" ({} samples)", term.scale.unwrap_or(0.0))
    }
    /// Searched as a shift of the whole log, not per joint (the guard may take it off a joint).
    fn joint_candidates(&self, _: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![])
    }
}
