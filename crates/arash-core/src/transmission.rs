//! Motor-side logs in joint space.
//!
//! Drives measure motor angles θ and motor torques τ_m. A transmission turns the motors by
//! θ = R (q − q₀) for joint angles q: R holds the gear ratios on its diagonal (motor radians per
//! joint radian) and, where one joint's motion also turns another joint's motor (a coupled wrist),
//! that coupling off the diagonal; q₀ are the joint offsets. Power balance, τᵀq̇ = τ_mᵀθ̇, gives
//! the joint torques τ = Rᵀ τ_m. The Stäubli TX40 is the example (docs/real-data.md): N =
//! (32, 32, 45, −48, 45, 32), and joint 5's motion turns motor 6 by N₆ = 32, so R\[5\]\[4\] = 32.
//!
//! Not on a real-time path: a log is mapped once, before preprocessing.

use faer::Mat;

use crate::dense;

/// Why a transmission cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransmissionError {
    #[error("gear ratios: {got} given for a {dof}-joint robot")]
    Ratios { got: usize, dof: usize },
    #[error("gear ratio of joint {joint} is {value}: expected a finite, non-zero number")]
    Ratio { joint: usize, value: f64 },
    #[error(
        "coupling ({motor}, {joint}) = {value}: motor and joint must lie in 1..={dof}, differ, and the value be finite"
    )]
    Coupling { motor: usize, joint: usize, value: f64, dof: usize },
    #[error("joint offsets: {got} given for a {dof}-joint robot, or one is not finite")]
    Offsets { got: usize, dof: usize },
    #[error(
        "the transmission matrix is singular (its smallest singular value is {smallest:.3e} of the largest): \
         motor angles cannot be mapped back to joint angles"
    )]
    Singular { smallest: f64 },
    #[error("{name} has {got} values, expected {expected} (samples × {dof})")]
    Shape { name: &'static str, got: usize, expected: usize, dof: usize },
}

/// The map from a motor-side log to joint space (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Transmission {
    /// Motor radians per joint radian, `dof × dof`.
    r: Mat<f64>,
    r_inv: Mat<f64>,
    offsets: Vec<f64>,
}

/// A transmission whose smallest singular value is below this share of its largest cannot be
/// inverted to encoder precision.
const SINGULAR: f64 = 1e-12;

impl Transmission {
    /// `ratios[k]`: motor radians per radian of joint k (negative for a reversed motor).
    /// `coupling`: `(motor, joint, value)`, 1-based, the motor radians of `motor` per radian of
    /// another `joint`. `offsets`: q₀ (rad), zero when `None`.
    pub fn new(
        dof: usize,
        ratios: &[f64],
        coupling: &[(usize, usize, f64)],
        offsets: Option<&[f64]>,
    ) -> Result<Self, TransmissionError> {
        if ratios.len() != dof {
            return Err(TransmissionError::Ratios { got: ratios.len(), dof });
        }
        if let Some((k, &value)) = ratios.iter().enumerate().find(|(_, v)| !v.is_finite() || **v == 0.0) {
            return Err(TransmissionError::Ratio { joint: k + 1, value });
        }
        let mut r = Mat::from_fn(dof, dof, |i, j| if i == j { ratios[i] } else { 0.0 });
        for &(motor, joint, value) in coupling {
            let inside = |i: usize| (1..=dof).contains(&i);
            if !inside(motor) || !inside(joint) || motor == joint || !value.is_finite() {
                return Err(TransmissionError::Coupling { motor, joint, value, dof });
            }
            r[(motor - 1, joint - 1)] = value;
        }
        let offsets = offsets.map_or_else(|| vec![0.0; dof], <[f64]>::to_vec);
        if offsets.len() != dof || offsets.iter().any(|v| !v.is_finite()) {
            return Err(TransmissionError::Offsets { got: offsets.len(), dof });
        }
        Self::from_matrix(r, offsets)
    }

    /// A transmission from the whole matrix R (`dof × dof`, motor radians per joint radian).
    pub fn from_matrix(r: Mat<f64>, offsets: Vec<f64>) -> Result<Self, TransmissionError> {
        if (0..r.ncols()).any(|j| r.col(j).iter().any(|v| !v.is_finite())) {
            return Err(TransmissionError::Singular { smallest: f64::NAN });
        }
        let smallest = 1.0 / dense::condition_number(r.as_ref());
        if smallest.is_nan() || smallest < SINGULAR {
            return Err(TransmissionError::Singular { smallest });
        }
        let r_inv = dense::inverse(r.as_ref()).ok_or(TransmissionError::Singular { smallest })?;
        Ok(Self { r, r_inv, offsets })
    }

    pub fn dof(&self) -> usize {
        self.offsets.len()
    }

    /// R, motor radians per joint radian.
    pub fn matrix(&self) -> &Mat<f64> {
        &self.r
    }

    /// The motors that turn with more than one joint: `(m, g)`, motor m's motion per unit of
    /// each joint on its own joint's scale, `g = R[m, :] / R[m, m]` (the `coupled_rotor` effect's
    /// direction). A motor with no ratio to its own joint has no such scale and is left out.
    pub fn coupled_motors(&self) -> Vec<(usize, Vec<f64>)> {
        let dof = self.dof();
        (0..dof)
            .filter(|&m| self.r[(m, m)] != 0.0 && (0..dof).any(|j| j != m && self.r[(m, j)] != 0.0))
            .map(|m| (m, (0..dof).map(|j| self.r[(m, j)] / self.r[(m, m)]).collect()))
            .collect()
    }

    /// Joint angles and torques (row-major `samples × dof`) from motor angles and motor torques.
    pub fn to_joints(&self, theta: &[f64], tau_motor: &[f64]) -> Result<(Vec<f64>, Vec<f64>), TransmissionError> {
        let dof = self.dof();
        let samples = theta.len() / dof.max(1);
        for (name, x) in [("motor angles", theta), ("motor torques", tau_motor)] {
            if x.len() != samples * dof || !theta.len().is_multiple_of(dof) {
                return Err(TransmissionError::Shape { name, got: x.len(), expected: samples * dof, dof });
            }
        }
        let mut q = vec![0.0; theta.len()];
        let mut tau = vec![0.0; tau_motor.len()];
        for s in 0..samples {
            let row = s * dof..(s + 1) * dof;
            let (th, tm) = (&theta[row.clone()], &tau_motor[row.clone()]);
            for k in 0..dof {
                q[s * dof + k] = self.offsets[k] + (0..dof).map(|j| self.r_inv[(k, j)] * th[j]).sum::<f64>();
                tau[s * dof + k] = (0..dof).map(|j| self.r[(j, k)] * tm[j]).sum::<f64>();
            }
        }
        Ok((q, tau))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tx40() -> Transmission {
        Transmission::new(6, &[32.0, 32.0, 45.0, -48.0, 45.0, 32.0], &[(6, 5, 32.0)], None).unwrap()
    }

    #[test]
    fn power_in_joint_space_equals_power_at_the_motors() {
        let t = tx40();
        let qd = [0.3, -0.2, 0.5, 0.1, -0.4, 0.7];
        let tau_m = [0.2, -1.0, 0.4, 0.05, -0.3, 0.1];
        let theta_d: Vec<f64> = (0..6).map(|j| (0..6).map(|k| t.matrix()[(j, k)] * qd[k]).sum()).collect();
        let (q, tau) = t.to_joints(&theta_d, &tau_m).unwrap();
        let joint_power: f64 = tau.iter().zip(&qd).map(|(a, b)| a * b).sum();
        let motor_power: f64 = tau_m.iter().zip(&theta_d).map(|(a, b)| a * b).sum();
        assert!((joint_power - motor_power).abs() < 1e-12 * motor_power.abs().max(1.0));
        // θ = R q̇ maps back to q̇ exactly.
        assert!(q.iter().zip(&qd).all(|(a, b)| (a - b).abs() < 1e-14));
    }

    /// Only motor 6 turns with two joints, with g = (0, 0, 0, 0, 1, 1).
    #[test]
    fn the_tx40s_wrist_motor_is_the_one_coupled_motor() {
        assert_eq!(tx40().coupled_motors(), vec![(5, vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0])]);
    }

    #[test]
    fn the_coupled_wrist_follows_upstreams_convention() {
        // Upstream (FIGAROH's TX40 example): q = R⁻¹ θ, τ = T τ_m with T = diag(N), T[4][5] = N[5].
        let (q, tau) = tx40().to_joints(&[0.0, 0.0, 0.0, 0.0, 45.0, 32.0], &[0.0, 0.0, 0.0, 0.0, 1.0, 1.0]).unwrap();
        assert!((q[4] - 1.0).abs() < 1e-15 && q[5].abs() < 1e-15, "{q:?}");
        assert!((tau[4] - 77.0).abs() < 1e-12 && (tau[5] - 32.0).abs() < 1e-12, "{tau:?}");
    }

    #[test]
    fn bad_transmissions_are_refused_by_name() {
        let err = |r: Result<Transmission, TransmissionError>| r.unwrap_err().to_string();
        assert!(err(Transmission::new(2, &[1.0], &[], None)).contains("1 given for a 2-joint"));
        assert!(err(Transmission::new(2, &[1.0, 0.0], &[], None)).contains("gear ratio of joint 2 is 0"));
        assert!(err(Transmission::new(2, &[1.0, 1.0], &[(1, 1, 2.0)], None)).contains("coupling (1, 1)"));
        assert!(err(Transmission::new(2, &[1.0, 1.0], &[(3, 1, 2.0)], None)).contains("coupling (3, 1)"));
        // Joint 2 turns motor 1 exactly as joint 1 does, and motor 2 likewise: rank 1.
        assert!(err(Transmission::new(2, &[1.0, 1.0], &[(1, 2, 1.0), (2, 1, 1.0)], None)).contains("singular"));
        let nan = Mat::from_fn(2, 2, |_, _| f64::NAN);
        assert!(err(Transmission::from_matrix(nan, vec![0.0; 2])).contains("singular"));
        let t = tx40();
        assert!(t.to_joints(&[0.0; 7], &[0.0; 6]).unwrap_err().to_string().contains("motor angles"));
        assert!(t.to_joints(&[0.0; 6], &[0.0; 12]).unwrap_err().to_string().contains("motor torques"));
    }
}
