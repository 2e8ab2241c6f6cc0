//! `compliance`: friction seen through a cable, with the encoder on the motor. `scale` is the
//! travel x₀ = F/k (rad or m), the cable's stretch under the joint's friction F.

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct Compliance;

/// The travels tried, as fractions of the joint's range: tens of µm on a 4000 N/m insertion
/// cable holding 0.2 N, far below the hysteresis bank's travels.
const TRAVEL_FRACTIONS: [f64; 3] = [0.0015, 0.003, 0.006];

impl Effect for Compliance {
    fn id(&self) -> &'static str {
        "compliance"
    }
    fn column_names(&self) -> Vec<String> {
        vec!["z (cable stretch)".into()]
    }
    fn filtered_like_torque(&self) -> bool {
        true
    }
    /// Friction through a stretched cable opposes motion.
    fn physical_sign(&self) -> Option<f64> {
        Some(1.0)
    }
    fn scale_is_continuous(&self) -> bool {
        true
    }
    fn plotted_against(&self) -> &'static str {
        "q"
    }
    /// After a reversal the joint holds while the cable re-stretches, so the motor's torque
    /// follows its position linearly over 2x₀ = 2F/k and then saturates at the friction F
    /// (elastoplastic: a spring until it slips). Unlike the Dahl state, the ramp is straight and
    /// ends at a definite travel.
    fn features(&self, term: &EffectTerm, x: Sample, state: &mut TermState, out: &mut [f64]) {
        let x0 = term.scale.unwrap_or(1.0);
        state.z = (state.z + state.travel_to(x.q) / x0).clamp(-1.0, 1.0);
        out[0] = state.z;
    }
    fn detail(&self, term: &EffectTerm) -> String {
        format!(" (x₀ = {:.2e})", term.scale.unwrap_or(0.0))
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(data.with_scales(EffectKind::Compliance, TRAVEL_FRACTIONS.map(|f| f * data.range())))
    }
}

#[cfg(test)]
mod tests {
    use crate::effects::{EffectKind, EffectTerm, Sample, TermState};

    /// The cable's stretch after a reversal is a straight ramp in position, 2x₀ long, then flat:
    /// the elastoplastic law, not the Dahl state's exponential.
    #[test]
    fn the_cable_stretch_ramps_straight_over_two_x0_then_holds() {
        let mut term = EffectTerm::new(EffectKind::Compliance, Some(0));
        let x0 = 50e-6;
        term.scale = Some(x0);
        let mut state = TermState::default();
        let mut out = [0.0];
        let step = 1e-6;
        for i in 0..=300 {
            term.features(Sample { q: -(i as f64) * step, ..Sample::default() }, &mut state, &mut out);
        }
        assert_eq!(out[0], -1.0, "held after a travel beyond 2x₀ backward");
        let bottom = -300.0 * step;
        for i in 1..=150 {
            term.features(Sample { q: bottom + i as f64 * step, ..Sample::default() }, &mut state, &mut out);
            let travel = i as f64 * step;
            let expected = (-1.0 + travel / x0).min(1.0);
            assert!((out[0] - expected).abs() < 1e-9, "after {travel:e} m: {} against {expected}", out[0]);
        }
        assert_eq!(out[0], 1.0);
    }
}
