//! `friction_velocity`: the joint's declared Coulomb law rises too sharply through zero speed:
//! the friction rises over a speed of its own. Its column is `tanh(q̇/v) − s(q̇)`, the law with
//! friction velocity `v` (`scale`, rad/s or m/s) less the declared one `s`: with a coefficient
//! equal to the joint's Coulomb friction it replaces the declared law by the smoother one of
//! velocity `v`. A smooth rise the declared `sign(q̇)` lacks shows here, and not as a Stribeck
//! term of the wrong sign, hysteresis or a cable's compliance (issue 44).
//!
//! Only smoother laws than the declared one are candidates. A law that rises more sharply than
//! the declared one puts more friction near zero speed than the model has: that is a Stribeck
//! excess, whose column (`stribeck`) has the same shape there, and the two would otherwise split
//! one effect between two names (on the simulated rig's Stribeck scenario, a law sharper than its
//! declared tanh(q̇/10⁻³) took the place of the Stribeck term it injects).

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct FrictionVelocity;

/// The friction velocities tried, as shares of the joint's RMS speed: from a thousandth (a law
/// the encoders' resolution cannot tell from the sign) to the RMS speed itself, a factor of 2 to
/// 2.5 apart. A law slower still saturates on few of the samples: over most of the motion it is
/// viscous friction, which the declared model has, and the two columns trade against each other
/// and against whatever the model lacks (on the TX40's joint 5 a law at twice the RMS speed took
/// up the friction of the wrist motor the declared model has no term for, and the diagnosis then
/// named two Stribeck terms and a rotor inertia on that joint). A joint that barely moves can need
/// the top of the range: a closed loop whose insertion's friction rises over 2 mm/s moved it at
/// 2.4 mm/s RMS (0.8 × its RMS speed; docs/identification.md). Identification chooses a robot's
/// laws from the same grid (`signal/friction_law.rs`).
pub const FRICTION_VELOCITY_SHARES: [f64; 10] = [0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0];

impl Effect for FrictionVelocity {
    fn id(&self) -> &'static str {
        "friction_velocity"
    }
    fn column_names(&self) -> Vec<String> {
        vec!["tanh(q̇/v) − s(q̇)".into()]
    }
    fn filtered_like_torque(&self) -> bool {
        true
    }
    /// It carries the joint's dry friction, which opposes motion.
    fn physical_sign(&self) -> Option<f64> {
        Some(1.0)
    }
    fn scale_is_continuous(&self) -> bool {
        true
    }
    fn plotted_against(&self) -> &'static str {
        "qd"
    }
    fn features(&self, term: &EffectTerm, x: Sample, _: &mut TermState, out: &mut [f64]) {
        let v = term.scale.unwrap_or(1.0);
        out[0] = (x.v / v).tanh() - term.direction(x.v);
    }
    fn detail(&self, term: &EffectTerm) -> String {
        format!(" (v = {:.3e})", term.scale.unwrap_or(0.0))
    }
    /// Every velocity of the grid at least twice the declared law's own: one closer is nearly the
    /// same law, and its column, nearly nothing, would take a coefficient many times the joint's
    /// friction to fit any mismatch of the transition's shape.
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        let declared = data.epsilon.unwrap_or(0.0);
        let velocities = FRICTION_VELOCITY_SHARES.iter().map(|s| s * data.speed_rms).filter(|v| *v >= 2.0 * declared);
        Ok(data.with_scales(EffectKind::FrictionVelocity, velocities))
    }
}

#[cfg(test)]
mod tests {
    use crate::effects::{EffectKind, EffectTerm, Sample, TermState};

    /// With the declared sign law, the column is the smooth law's shortfall: zero far from zero
    /// speed, −1 + tanh(q̇/v) just above it; fitted with the Coulomb coefficient it makes the law
    /// tanh(q̇/v).
    #[test]
    fn the_column_is_the_smooth_law_less_the_declared_one() {
        let mut term = EffectTerm::new(EffectKind::FrictionVelocity, Some(0));
        term.scale = Some(0.01);
        let mut out = [0.0];
        let at = |v: f64, term: &EffectTerm, out: &mut [f64; 1]| {
            term.features(Sample { v, ..Sample::default() }, &mut TermState::default(), out);
            out[0]
        };
        assert!(at(1.0, &term, &mut out).abs() < 1e-12);
        assert!((at(0.005, &term, &mut out) - ((0.5f64).tanh() - 1.0)).abs() < 1e-12);
        let fc = 0.7;
        for v in [-0.03, -0.004, 0.002, 0.02] {
            let declared = fc * f64::signum(v);
            assert!((declared + fc * at(v, &term, &mut out) - fc * (v / 0.01).tanh()).abs() < 1e-12);
        }
        // Against a declared tanh law the column is the difference of the two widths.
        term.epsilon = Some(0.001);
        assert!((at(0.005, &term, &mut out) - ((0.5f64).tanh() - (5.0f64).tanh())).abs() < 1e-12);
    }
}
