//! The library of candidate effects: what each one adds to the torque, as a group of regressor
//! columns with a stable identifier. `docs/diagnosis.md` gives the table; this file is the
//! definition.
//!
//! A term is evaluated one sample at a time by [`EffectTerm::features`], so that the diagnosis
//! (in bulk) and a controller (per cycle) compute the same thing. Terms that switch with the
//! direction of motion or ripple with position change faster than the torque's low-pass filter;
//! the diagnosis filters those columns exactly like the torque ("parallel filtering", as the
//! declared Coulomb columns are).

use serde::{Deserialize, Serialize};

/// The stable identifiers of the candidate effects.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    Offset,
    CoulombAsymmetry,
    Stribeck,
    ViscousNonlinear,
    Armature,
    ConfigurationDisturbance,
    PositionFriction,
    Hysteresis,
    Cogging,
    Compliance,
    Delay,
    Payload,
    Drift,
}

impl EffectKind {
    pub const ALL: [EffectKind; 13] = [
        Self::Offset,
        Self::CoulombAsymmetry,
        Self::Stribeck,
        Self::ViscousNonlinear,
        Self::Armature,
        Self::ConfigurationDisturbance,
        Self::PositionFriction,
        Self::Hysteresis,
        Self::Cogging,
        Self::Compliance,
        Self::Delay,
        Self::Payload,
        Self::Drift,
    ];

    /// The identifier used in reports, JSON and on the command line.
    pub fn id(self) -> &'static str {
        match self {
            Self::Offset => "offset",
            Self::CoulombAsymmetry => "coulomb_asymmetry",
            Self::Stribeck => "stribeck",
            Self::ViscousNonlinear => "viscous_nonlinear",
            Self::Armature => "armature",
            Self::ConfigurationDisturbance => "configuration_disturbance",
            Self::PositionFriction => "position_friction",
            Self::Hysteresis => "hysteresis",
            Self::Cogging => "cogging",
            Self::Compliance => "compliance",
            Self::Delay => "delay",
            Self::Payload => "payload",
            Self::Drift => "drift",
        }
    }

    pub fn from_id(id: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.id() == id)
    }

    /// Whether the columns change faster than the torque filter passes, and so must be computed
    /// from the friction velocity and filtered like the torque. `q̇·|q̇|` is smooth enough for
    /// the filtered velocity, and the friction velocity's quantisation noise would leak into it.
    pub fn filtered_like_torque(self) -> bool {
        matches!(
            self,
            Self::CoulombAsymmetry
                | Self::Stribeck
                | Self::PositionFriction
                | Self::Hysteresis
                | Self::Cogging
                | Self::Compliance
        )
    }

    /// The sign its (single) coefficient must have to be the physical effect: static friction
    /// above Coulomb, positive rotor inertia, dissipative viscous friction, and hysteresis and
    /// friction through a stretched cable that oppose motion. A fit with the other sign is some
    /// other error that happens to correlate, not this effect.
    pub fn physical_sign(self) -> Option<f64> {
        match self {
            Self::Stribeck | Self::Armature | Self::Compliance | Self::ViscousNonlinear | Self::Hysteresis => Some(1.0),
            _ => None,
        }
    }

    /// The variable a residual plot shows this effect against.
    pub fn plotted_against(self) -> &'static str {
        match self {
            Self::Offset | Self::Drift | Self::Delay => "t",
            Self::Armature => "qdd",
            Self::ConfigurationDisturbance
            | Self::PositionFriction
            | Self::Cogging
            | Self::Hysteresis
            | Self::Compliance => "q",
            Self::Payload => "q",
            Self::CoulombAsymmetry | Self::Stribeck | Self::ViscousNonlinear => "qd",
        }
    }
}

/// Terms of the configuration disturbance's cosine series over the joint's range. The constant
/// term is left out: a position-dependent torque with a mean would also be an offset.
pub const CONFIGURATION_HARMONICS: usize = 4;

/// One effect as it is stored in a model file: its kind, where it acts, the constants that shape
/// its columns, and the fitted coefficients.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EffectTerm {
    pub kind: EffectKind,
    /// The joint it acts on (`None`: every joint, as for a payload or a delay).
    pub joint: Option<usize>,
    /// The body a payload sits on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body: Option<String>,
    /// Stribeck velocity scale (rad/s or m/s), hysteresis or compliance travel x₀ (rad or m),
    /// cogging periods per motor revolution, or the delay in samples.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<f64>,
    /// Position range (lo, hi) that normalises configuration and position-friction terms, or
    /// the time origin and span (s) of a drift.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub span: Option<(f64, f64)>,
    /// Joint motion per motor radian, for cogging.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transmission: Option<f64>,
    /// ε of the `tanh(q̇/ε)` direction in friction terms; `None` is `sign(q̇)`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub epsilon: Option<f64>,
    /// Names of the columns, in coefficient order.
    pub columns: Vec<String>,
    pub coefficients: Vec<f64>,
    /// Standard deviations of the coefficients (block sandwich).
    pub sigma: Vec<f64>,
}

/// The state a term needs between samples: `z`, the hysteresis term's Dahl state or the
/// compliance term's cable stretch, in [−1, 1], and the position it was last updated at.
#[derive(Clone, Copy, Debug, Default)]
pub struct TermState {
    pub z: f64,
    pub last_q: Option<f64>,
}

impl TermState {
    /// The travel from the last position to `q` (zero at the first sample), which becomes the
    /// last position.
    fn travel_to(&mut self, q: f64) -> f64 {
        let dq = self.last_q.map_or(0.0, |last| q - last);
        self.last_q = Some(q);
        dq
    }
}

impl EffectTerm {
    /// A term with no coefficients yet.
    pub fn new(kind: EffectKind, joint: Option<usize>) -> Self {
        Self {
            kind,
            joint,
            body: None,
            scale: None,
            span: None,
            transmission: None,
            epsilon: None,
            columns: vec![],
            coefficients: vec![],
            sigma: vec![],
        }
    }

    /// Number of columns of the sample-wise features (a payload has its own).
    pub fn width(&self) -> usize {
        match self.kind {
            EffectKind::ConfigurationDisturbance => CONFIGURATION_HARMONICS,
            EffectKind::PositionFriction | EffectKind::Cogging => 2,
            EffectKind::Payload => 4,
            EffectKind::Delay => 0,
            _ => 1,
        }
    }

    /// Column names, for reports.
    pub fn column_names(&self) -> Vec<String> {
        match self.kind {
            EffectKind::Offset => vec!["1".into()],
            EffectKind::CoulombAsymmetry => vec!["|s(q̇)|".into()],
            EffectKind::Stribeck => vec!["exp(−(q̇/v_s)²)·s(q̇)".into()],
            EffectKind::ViscousNonlinear => vec!["q̇·|q̇|".into()],
            EffectKind::Armature => vec!["q̈".into()],
            EffectKind::ConfigurationDisturbance => {
                (1..=CONFIGURATION_HARMONICS).map(|m| format!("cos({m}πx)")).collect()
            }
            EffectKind::PositionFriction => vec!["s(q̇)·x".into(), "s(q̇)·x²".into()],
            EffectKind::Hysteresis => vec!["z (Dahl)".into()],
            EffectKind::Cogging => vec!["sin(nθ)".into(), "cos(nθ)".into()],
            EffectKind::Compliance => vec!["z (cable stretch)".into()],
            EffectKind::Drift => vec!["(t − t₀)/T".into()],
            EffectKind::Payload => vec!["m".into(), "m·cx".into(), "m·cy".into(), "m·cz".into()],
            EffectKind::Delay => vec![],
        }
    }

    fn direction(&self, v: f64) -> f64 {
        match self.epsilon {
            Some(eps) => (v / eps).tanh(),
            None => v.signum() * f64::from(v != 0.0),
        }
    }

    /// The term's columns at one sample of its joint: position `q`, friction velocity `v`,
    /// acceleration `qdd` and time `t`. `state` carries the hysteresis and compliance states
    /// from sample to sample. Payload and delay have no joint-wise features and write nothing.
    pub fn features(&self, q: f64, v: f64, qdd: f64, t: f64, state: &mut TermState, out: &mut [f64]) {
        let (lo, hi) = self.span.unwrap_or((0.0, 1.0));
        let unit = (q - lo) / (hi - lo);
        let s = self.direction(v);
        match self.kind {
            EffectKind::Offset => out[0] = 1.0,
            EffectKind::CoulombAsymmetry => out[0] = s.abs(),
            EffectKind::Stribeck => {
                let vs = self.scale.unwrap_or(1.0);
                out[0] = (-(v / vs).powi(2)).exp() * s;
            }
            EffectKind::ViscousNonlinear => out[0] = v * v.abs(),
            EffectKind::Armature => out[0] = qdd,
            EffectKind::ConfigurationDisturbance => {
                for (m, o) in out.iter_mut().enumerate().take(CONFIGURATION_HARMONICS) {
                    *o = (std::f64::consts::PI * (m + 1) as f64 * unit).cos();
                }
            }
            EffectKind::PositionFriction => {
                let x = 2.0 * unit - 1.0;
                out[0] = s * x;
                out[1] = s * x * x;
            }
            EffectKind::Hysteresis => {
                // Dahl: dz/dq = (1 − z·sign(dq)) / x₀, so z follows the direction of travel and
                // forgets the previous one over a travel of a few x₀. Integrated exactly over
                // each step, so large steps cannot overshoot.
                let x0 = self.scale.unwrap_or(1.0);
                let dq = state.travel_to(q);
                if dq != 0.0 {
                    let target = dq.signum();
                    state.z = target + (state.z - target) * (-dq.abs() / x0).exp();
                }
                out[0] = state.z;
            }
            EffectKind::Cogging => {
                let n = self.scale.unwrap_or(1.0);
                let theta = q / self.transmission.unwrap_or(1.0);
                let (sin, cos) = (n * theta).sin_cos();
                out[0] = sin;
                out[1] = cos;
            }
            EffectKind::Compliance => {
                // Friction seen through a cable, with the encoder on the motor: after a reversal
                // the joint holds while the cable re-stretches, so the motor's torque follows its
                // position linearly over 2x₀ = 2F/k and then saturates at the friction F
                // (elastoplastic: a spring until it slips). Unlike the Dahl state, the ramp is
                // straight and ends at a definite travel.
                let x0 = self.scale.unwrap_or(1.0);
                state.z = (state.z + state.travel_to(q) / x0).clamp(-1.0, 1.0);
                out[0] = state.z;
            }
            EffectKind::Drift => {
                let (t0, span) = self.span.unwrap_or((0.0, 1.0));
                out[0] = (t - t0) / span;
            }
            EffectKind::Payload | EffectKind::Delay => {}
        }
    }

    /// A one-line description with units, for reports.
    pub fn describe(&self, joint_names: &[String]) -> String {
        let joint = self.joint.map(|k| joint_names.get(k).cloned().unwrap_or_else(|| format!("joint {}", k + 1)));
        let on = match (joint, self.kind) {
            (Some(j), _) => format!(" on {j}"),
            (None, EffectKind::Armature) => " on every joint".into(),
            (None, _) => String::new(),
        };
        let detail = match self.kind {
            EffectKind::Stribeck => format!(" (v_s = {:.3})", self.scale.unwrap_or(0.0)),
            EffectKind::Hysteresis => format!(" (x₀ = {:.3})", self.scale.unwrap_or(0.0)),
            EffectKind::Compliance => format!(" (x₀ = {:.2e})", self.scale.unwrap_or(0.0)),
            EffectKind::Cogging => format!(" ({} per motor revolution)", self.scale.unwrap_or(0.0)),
            EffectKind::Delay => format!(" ({} samples)", self.scale.unwrap_or(0.0)),
            EffectKind::Payload => format!(" on {}", self.body.as_deref().unwrap_or("?")),
            _ => String::new(),
        };
        format!("{}{on}{detail}", self.kind.id())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identifiers_round_trip_and_are_the_documented_ones() {
        let doc = include_str!("../../../../docs/diagnosis.md");
        for k in EffectKind::ALL {
            assert_eq!(EffectKind::from_id(k.id()), Some(k));
            assert!(doc.contains(&format!("`{}`", k.id())), "{} is not documented", k.id());
        }
    }

    #[test]
    fn the_dahl_state_follows_the_direction_of_travel() {
        let mut term = EffectTerm::new(EffectKind::Hysteresis, Some(0));
        term.scale = Some(0.01);
        let mut state = TermState::default();
        let mut out = [0.0];
        for i in 0..200 {
            term.features(i as f64 * 1e-3, 0.0, 0.0, 0.0, &mut state, &mut out);
        }
        assert!(out[0] > 0.99, "saturates forward: {}", out[0]);
        let top = 0.199;
        for i in 1..=200 {
            term.features(top - i as f64 * 1e-3, 0.0, 0.0, 0.0, &mut state, &mut out);
        }
        assert!(out[0] < -0.99, "and backward: {}", out[0]);
    }

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
            term.features(-(i as f64) * step, 0.0, 0.0, 0.0, &mut state, &mut out);
        }
        assert_eq!(out[0], -1.0, "held after a travel beyond 2x₀ backward");
        let bottom = -300.0 * step;
        for i in 1..=150 {
            term.features(bottom + i as f64 * step, 0.0, 0.0, 0.0, &mut state, &mut out);
            let travel = i as f64 * step;
            let expected = (-1.0 + travel / x0).min(1.0);
            assert!((out[0] - expected).abs() < 1e-9, "after {travel:e} m: {} against {expected}", out[0]);
        }
        assert_eq!(out[0], 1.0);
    }
}
