//! The mutable workspace paired with a [`Model`]: every buffer an evaluation needs, allocated once.

use crate::model::Model;
use crate::spatial::{Force, Mat3, Motion, Vec3};

/// Scratch and results for one [`Model`]. Create it once with [`Data::new`]; no algorithm in this
/// crate allocates after that. A `Data` must only be used with the model it was made for.
#[derive(Clone, Debug)]
pub struct Data {
    pub(crate) dof: usize,
    /// Orientation of each body frame in its parent frame.
    pub(crate) rot: Vec<Mat3>,
    /// Origin of each body frame in its parent frame (m).
    pub(crate) pos: Vec<Vec3>,
    /// Orientation of each body frame in the base frame.
    pub world_rot: Vec<Mat3>,
    /// Origin of each body frame in the base frame (m).
    pub world_pos: Vec<Vec3>,
    /// Body Jacobians in body coordinates; column `k` of body `b` at `b·dof + k`.
    pub(crate) jac: Vec<Motion>,
    /// Body velocities `J q̇`, body coordinates.
    pub(crate) vel: Vec<Motion>,
    /// Reference velocities `J q̇_r` (Slotine–Li), body coordinates.
    pub(crate) vel_ref: Vec<Motion>,
    /// Spatial accelerations (or reference accelerations), gravity included when asked for.
    pub(crate) acc: Vec<Motion>,
    /// Per-body forces summed over each body's subtree (the momentum observer's sweep).
    pub(crate) subtree: Vec<Force>,
    /// `(sin q_k, cos q_k)` of each actuated coordinate at the last forward kinematics.
    pub(crate) sin_cos: Vec<(f64, f64)>,
    /// dof × dof scratch for the mass matrix and its Cholesky factor.
    pub(crate) mass: Vec<f64>,
    pub(crate) rhs: Vec<f64>,
    pub(crate) unit: Vec<f64>,
    pub(crate) zeros: Vec<f64>,
}

impl Data {
    pub fn new(model: &Model) -> Self {
        let (nb, n) = (model.bodies.len(), model.dof());
        Self {
            dof: n,
            rot: vec![Mat3::identity(); nb],
            pos: vec![Vec3::zeros(); nb],
            world_rot: vec![Mat3::identity(); nb],
            world_pos: vec![Vec3::zeros(); nb],
            jac: vec![Motion::ZERO; nb * n],
            vel: vec![Motion::ZERO; nb],
            vel_ref: vec![Motion::ZERO; nb],
            acc: vec![Motion::ZERO; nb],
            subtree: vec![Force::ZERO; nb],
            sin_cos: vec![(0.0, 1.0); n],
            mass: vec![0.0; n * n],
            rhs: vec![0.0; n],
            unit: vec![0.0; n],
            zeros: vec![0.0; n],
        }
    }

    /// Column `k` of body `b`'s Jacobian (body coordinates), valid after forward kinematics.
    pub fn jacobian_column(&self, b: usize, k: usize) -> Motion {
        self.jac[b * self.dof + k]
    }
}
