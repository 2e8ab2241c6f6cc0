//! The safety gate between a controller and the motors.
//!
//! Every command passes [`SafetyGate::apply`], which guarantees that what reaches a motor is
//! finite and bounded:
//! - a non-finite state or command, a joint beyond its limit (plus margin) or faster than its
//!   velocity guard latches a fault, and the output is zero from then on;
//! - otherwise the command is clamped to the torque limit and its change per cycle to the torque
//!   rate limit.
//!
//! A latched fault stays until [`SafetyGate::clear`] is called explicitly — an operator decision.

use crate::model::Model;

/// Fault bits, logged with every cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Faults(pub u32);

impl Faults {
    pub const NONE: Faults = Faults(0);
    /// q or q̇ was NaN or infinite.
    pub const NON_FINITE_STATE: Faults = Faults(1 << 0);
    /// The controller produced a NaN or infinite torque.
    pub const NON_FINITE_COMMAND: Faults = Faults(1 << 1);
    /// A joint went beyond its position limit by more than the margin.
    pub const POSITION_LIMIT: Faults = Faults(1 << 2);
    /// A joint moved faster than its velocity guard.
    pub const VELOCITY_LIMIT: Faults = Faults(1 << 3);
    /// The motor link lost frames for longer than allowed (set by the daemon).
    pub const LINK_TIMEOUT: Faults = Faults(1 << 4);
    /// The motor side reported a fault (set by the daemon).
    pub const MOTOR: Faults = Faults(1 << 5);
    /// A joint strayed further from its reference than the following-error limit (set by the
    /// daemon; catches a stuck encoder or a blocked joint).
    pub const FOLLOWING_ERROR: Faults = Faults(1 << 6);
    /// The measured motor current disagreed with the command for too long (set by the daemon).
    pub const CURRENT_MISMATCH: Faults = Faults(1 << 7);
    /// The drive reported its power stage on for too long while the host commanded it off (set
    /// by the daemon; a drive that ignores DISABLE, or a stale enable from an earlier host).
    pub const DRIVE_STATE: Faults = Faults(1 << 8);
    /// The drive left its enabled state while the host had it enabled, without a fault of its
    /// own, or never confirmed the enable (set by the daemon; an e-stop on the drive's
    /// quick-stop input, safe torque off). Only the operator's reset and enable restart it.
    pub const DRIVE_STOPPED: Faults = Faults(1 << 9);
    /// The hand's force observer read a collision during a trajectory run (set by the daemon):
    /// the run is stopped and the joints float under the model's compensation until the
    /// operator's reset (docs/daemon.md, "Contact and collision").
    pub const COLLISION: Faults = Faults(1 << 10);

    pub fn contains(self, other: Faults) -> bool {
        self.0 & other.0 == other.0
    }

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Names of the bits set, for reports.
    pub fn names(self) -> Vec<&'static str> {
        const NAMES: [&str; 11] = [
            "non-finite state",
            "non-finite command",
            "position limit",
            "velocity limit",
            "link timeout",
            "motor",
            "following error",
            "current mismatch",
            "drive state",
            "drive stopped",
            "collision",
        ];
        NAMES.iter().enumerate().filter(|(i, _)| self.0 & (1 << i) != 0).map(|(_, n)| *n).collect()
    }
}

impl std::ops::BitOr for Faults {
    type Output = Faults;
    fn bitor(self, rhs: Faults) -> Faults {
        Faults(self.0 | rhs.0)
    }
}

impl std::ops::BitOrAssign for Faults {
    fn bitor_assign(&mut self, rhs: Faults) {
        self.0 |= rhs.0;
    }
}

/// Per-joint limits enforced by the gate (SI).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SafetyLimits {
    /// |τ| ≤ torque (N·m or N).
    pub torque: Vec<f64>,
    /// |Δτ| per second ≤ torque_rate (N·m/s or N/s).
    pub torque_rate: Vec<f64>,
    /// |q̇| ≤ velocity, else fault (rad/s or m/s).
    pub velocity: Vec<f64>,
    /// lower − margin ≤ q ≤ upper + margin, else fault (rad or m).
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub margin: Vec<f64>,
}

impl SafetyLimits {
    /// From the model: URDF effort limits, velocity guards at 1.5× the URDF speed limits, the URDF
    /// position limits with a margin of 2° or 2 mm, and a torque rate allowing the full torque
    /// range in 10 ms.
    pub fn from_model(model: &Model) -> Self {
        let torque: Vec<f64> = model.joints.iter().map(|j| j.effort).collect();
        Self {
            torque_rate: torque.iter().map(|t| 2.0 * t / 0.01).collect(),
            torque,
            velocity: model.joints.iter().map(|j| 1.5 * j.velocity).collect(),
            lower: model.joints.iter().map(|j| j.lower).collect(),
            upper: model.joints.iter().map(|j| j.upper).collect(),
            margin: model
                .joints
                .iter()
                .map(|j| if matches!(j.kind, crate::JointKind::Prismatic) { 0.002 } else { 2f64.to_radians() })
                .collect(),
        }
    }

    /// Checks that every vector has `dof` entries and every limit is positive (or ±∞ for
    /// positions); the error names the first bad entry.
    pub fn validate(&self, dof: usize) -> Result<(), LimitsError> {
        let named: [(&str, &Vec<f64>); 6] = [
            ("torque", &self.torque),
            ("torque_rate", &self.torque_rate),
            ("velocity", &self.velocity),
            ("lower", &self.lower),
            ("upper", &self.upper),
            ("margin", &self.margin),
        ];
        for (name, v) in named {
            if v.len() != dof {
                return Err(LimitsError::Length { name, got: v.len(), dof });
            }
        }
        for k in 0..dof {
            for (name, v) in
                [("torque", self.torque[k]), ("torque_rate", self.torque_rate[k]), ("velocity", self.velocity[k])]
            {
                if v.is_nan() || v <= 0.0 {
                    return Err(LimitsError::NotPositive { name, joint: k, value: v });
                }
            }
            if self.margin[k].is_nan()
                || self.margin[k] < 0.0
                || self.lower[k].is_nan()
                || self.upper[k].is_nan()
                || self.lower[k] >= self.upper[k]
            {
                let (lower, upper, margin) = (self.lower[k], self.upper[k], self.margin[k]);
                return Err(LimitsError::NotAnInterval { joint: k, lower, upper, margin });
            }
        }
        Ok(())
    }
}

/// Latching safety gate; holds the last output for the rate limit.
#[derive(Clone, Debug)]
pub struct SafetyGate {
    limits: SafetyLimits,
    last: Vec<f64>,
    latched: Faults,
}

impl SafetyGate {
    pub fn new(limits: SafetyLimits) -> Self {
        let n = limits.torque.len();
        limits.validate(n).unwrap_or_else(|e| panic!("{e}"));
        Self { limits, last: vec![0.0; n], latched: Faults::NONE }
    }

    pub fn limits(&self) -> &SafetyLimits {
        &self.limits
    }

    /// Faults latched so far.
    pub fn faults(&self) -> Faults {
        self.latched
    }

    /// Latch a fault detected elsewhere (link timeout, motor fault).
    pub fn latch(&mut self, fault: Faults) {
        self.latched |= fault;
    }

    /// Clear latched faults and restart the rate limit from zero torque.
    pub fn clear(&mut self) {
        self.latched = Faults::NONE;
        self.last.fill(0.0);
    }

    /// Check the state and command, write the torque that may reach the motors into `out`, and
    /// return the latched faults. `dt` is the cycle period (s).
    pub fn apply(&mut self, dt: f64, q: &[f64], qd: &[f64], command: &[f64], out: &mut [f64]) -> Faults {
        self.latched |= self.check(q, qd, command);
        if !self.latched.is_empty() {
            out.fill(0.0);
            self.last.fill(0.0);
            return self.latched;
        }
        let l = &self.limits;
        for k in 0..out.len() {
            let step = l.torque_rate[k] * dt;
            let clamped = command[k].clamp(-l.torque[k], l.torque[k]);
            out[k] = clamped.clamp(self.last[k] - step, self.last[k] + step);
            self.last[k] = out[k];
        }
        self.latched
    }

    fn check(&self, q: &[f64], qd: &[f64], command: &[f64]) -> Faults {
        let l = &self.limits;
        let mut faults = Faults::NONE;
        for k in 0..command.len() {
            if !q[k].is_finite() || !qd[k].is_finite() {
                faults |= Faults::NON_FINITE_STATE;
                continue;
            }
            if !command[k].is_finite() {
                faults |= Faults::NON_FINITE_COMMAND;
            }
            if q[k] < l.lower[k] - l.margin[k] || q[k] > l.upper[k] + l.margin[k] {
                faults |= Faults::POSITION_LIMIT;
            }
            if qd[k].abs() > l.velocity[k] {
                faults |= Faults::VELOCITY_LIMIT;
            }
        }
        faults
    }
}

/// A [`SafetyLimits`] that cannot guard a robot, named.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LimitsError {
    #[error("safety limit `{name}` has {got} entries, the robot has {dof} joints")]
    Length { name: &'static str, got: usize, dof: usize },
    #[error("safety limit `{name}` of joint {joint} must be positive, not {value}")]
    NotPositive { name: &'static str, joint: usize, value: f64 },
    #[error("joint {joint}: position limits [{lower}, {upper}] with margin {margin} are not an interval")]
    NotAnInterval { joint: usize, lower: f64, upper: f64, margin: f64 },
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gate() -> SafetyGate {
        SafetyGate::new(SafetyLimits {
            torque: vec![1.0, 2.0],
            torque_rate: vec![100.0, 100.0],
            velocity: vec![3.0, 0.1],
            lower: vec![-1.0, -0.01],
            upper: vec![1.0, 0.02],
            margin: vec![0.1, 0.001],
        })
    }

    #[test]
    fn clamps_torque_and_its_rate() {
        let mut g = gate();
        let mut out = [0.0; 2];
        g.apply(1e-3, &[0.0, 0.0], &[0.0, 0.0], &[5.0, -5.0], &mut out);
        assert_eq!(out, [0.1, -0.1], "rate limit: 100 N·m/s × 1 ms");
        for _ in 0..100 {
            g.apply(1e-3, &[0.0, 0.0], &[0.0, 0.0], &[5.0, -5.0], &mut out);
        }
        assert_eq!(out, [1.0, -2.0], "torque limit");
    }

    #[test]
    fn faults_at_the_exact_boundaries_and_latch() {
        let mut out = [0.0; 2];
        // On the boundary is allowed; the next representable value beyond is not.
        let mut g = gate();
        let (top, bottom) = (1.0 + 0.1, -0.01 - 0.001);
        let beyond = |x: f64| f64::from_bits(x.to_bits() + 1);
        assert!(g.apply(1e-3, &[top, 0.02 + 0.001], &[3.0, -0.1], &[0.0, 0.0], &mut out).is_empty());
        assert!(g.apply(1e-3, &[-top, bottom], &[-3.0, 0.1], &[0.0, 0.0], &mut out).is_empty());
        for (q, qd, fault) in [
            ([beyond(top), 0.0], [0.0, 0.0], Faults::POSITION_LIMIT),
            ([0.0, beyond(bottom)], [0.0, 0.0], Faults::POSITION_LIMIT),
            ([0.0, 0.0], [0.0, beyond(0.1)], Faults::VELOCITY_LIMIT),
            ([0.0, 0.0], [beyond(-3.0), 0.0], Faults::VELOCITY_LIMIT),
            ([f64::NAN, 0.0], [0.0, 0.0], Faults::NON_FINITE_STATE),
            ([0.0, 0.0], [f64::INFINITY, 0.0], Faults::NON_FINITE_STATE),
        ] {
            let mut g = gate();
            let faults = g.apply(1e-3, &q, &qd, &[0.5, 0.5], &mut out);
            assert!(faults.contains(fault), "{q:?} {qd:?}: {faults:?}");
            assert_eq!(out, [0.0, 0.0]);
            // Latched: a good cycle afterwards still gives zero.
            assert!(g.apply(1e-3, &[0.0, 0.0], &[0.0, 0.0], &[0.5, 0.5], &mut out).contains(fault));
            assert_eq!(out, [0.0, 0.0]);
            g.clear();
            assert!(g.apply(1e-3, &[0.0, 0.0], &[0.0, 0.0], &[0.5, 0.5], &mut out).is_empty());
            assert_eq!(out, [0.1, 0.1]);
        }
        let mut g = gate();
        assert!(g
            .apply(1e-3, &[0.0, 0.0], &[0.0, 0.0], &[f64::NAN, 0.0], &mut out)
            .contains(Faults::NON_FINITE_COMMAND));
        assert_eq!(out, [0.0, 0.0]);
    }
}
