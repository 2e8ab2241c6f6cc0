//! `hysteresis`: friction that follows the direction of travel with memory (Dahl). `scale` is the
//! travel x₀ (rad or m) over which the state forgets the previous direction.

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct Hysteresis;

/// The travels tried, as fractions of the joint's range.
const TRAVEL_FRACTIONS: [f64; 3] = [0.03, 0.1, 0.3];

impl Effect for Hysteresis {
    fn id(&self) -> &'static str {
        "hysteresis"
    }
    fn column_names(&self) -> Vec<String> {
        vec!["z (Dahl)".into()]
    }
    fn filtered_like_torque(&self) -> bool {
        true
    }
    /// It opposes motion.
    fn physical_sign(&self) -> Option<f64> {
        Some(1.0)
    }
    fn scale_is_continuous(&self) -> bool {
        true
    }
    fn plotted_against(&self) -> &'static str {
        "q"
    }
    /// Dahl: dz/dq = (1 − z·sign(dq)) / x₀, so z follows the direction of travel and forgets the
    /// previous one over a travel of a few x₀. Integrated exactly over each step, so large steps
    /// cannot overshoot.
    fn features(&self, term: &EffectTerm, x: Sample, state: &mut TermState, out: &mut [f64]) {
        let x0 = term.scale.unwrap_or(1.0);
        let dq = state.travel_to(x.q);
        if dq != 0.0 {
            let target = dq.signum();
            state.z = target + (state.z - target) * (-dq.abs() / x0).exp();
        }
        out[0] = state.z;
    }
    fn detail(&self, term: &EffectTerm) -> String {
        format!(" (x₀ = {:.3})", term.scale.unwrap_or(0.0))
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(data.with_scales(EffectKind::Hysteresis, TRAVEL_FRACTIONS.map(|f| f * data.range())))
    }
}

#[cfg(test)]
mod tests {
    use crate::effects::{EffectKind, EffectTerm, Sample, TermState};

    #[test]
    fn the_dahl_state_follows_the_direction_of_travel() {
        let mut term = EffectTerm::new(EffectKind::Hysteresis, Some(0));
        term.scale = Some(0.01);
        let mut state = TermState::default();
        let mut out = [0.0];
        for i in 0..200 {
            term.features(Sample { q: i as f64 * 1e-3, ..Sample::default() }, &mut state, &mut out);
        }
        assert!(out[0] > 0.99, "saturates forward: {}", out[0]);
        let top = 0.199;
        for i in 1..=200 {
            term.features(Sample { q: top - i as f64 * 1e-3, ..Sample::default() }, &mut state, &mut out);
        }
        assert!(out[0] < -0.99, "and backward: {}", out[0]);
    }
}
