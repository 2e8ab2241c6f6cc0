//! `drift`: a torque that grows over the log, `(t − t₀)/T`, as friction does while a drive warms
//! up. `span` holds the log's time origin t₀ and half-length T. A property of the log's own
//! clock, not of the robot: a controller does not compensate it.

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct Drift;

impl Effect for Drift {
    fn id(&self) -> &'static str {
        "drift"
    }
    fn column_names(&self) -> Vec<String> {
        vec!["(t − t₀)/T".into()]
    }
    fn plotted_against(&self) -> &'static str {
        "t"
    }
    fn at_run_time(&self) -> bool {
        false
    }
    fn features(&self, term: &EffectTerm, x: Sample, _: &mut TermState, out: &mut [f64]) {
        let (t0, span) = term.span.unwrap_or((0.0, 1.0));
        out[0] = (x.t - t0) / span;
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        let mut t = data.term(EffectKind::Drift);
        let (t0, t1) = data.time;
        t.span = Some((0.5 * (t0 + t1), 0.5 * (t1 - t0)));
        Ok(vec![t])
    }
}
