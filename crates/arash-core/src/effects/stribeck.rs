//! `stribeck`: static friction above Coulomb at low speed, `exp(−(q̇/v_s)²)·s(q̇)`. `scale` is the
//! Stribeck velocity v_s (rad/s or m/s).

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct Stribeck;

/// The Stribeck velocities tried, as fractions of the joint's RMS speed.
const VELOCITY_FRACTIONS: [f64; 5] = [SLOWEST_STRIBECK_FRACTION, 0.05, 0.1, 0.2, 0.4];

/// The slowest Stribeck velocity tried, as a fraction of the joint's RMS speed: the finest
/// velocity scale any friction column has, which the friction velocity must resolve
/// (`diagnose::options::MAX_VELOCITY_NOISE`).
pub const SLOWEST_STRIBECK_FRACTION: f64 = 0.025;

impl Effect for Stribeck {
    fn id(&self) -> &'static str {
        "stribeck"
    }
    fn column_names(&self) -> Vec<String> {
        vec!["exp(−(q̇/v_s)²)·s(q̇)".into()]
    }
    fn filtered_like_torque(&self) -> bool {
        true
    }
    /// Static friction is above Coulomb friction.
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
        let vs = term.scale.unwrap_or(1.0);
        out[0] = (-(x.v / vs).powi(2)).exp() * term.direction(x.v);
    }
    fn detail(&self, term: &EffectTerm) -> String {
        format!(" (v_s = {:.3})", term.scale.unwrap_or(0.0))
    }
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(data.with_scales(EffectKind::Stribeck, VELOCITY_FRACTIONS.map(|f| f * data.speed_rms)))
    }
}
