//! An external joint torque mapped to the force at a frame: the force `F` at the frame's origin,
//! in the base frame, whose joint torque `J_vᵀ F` is the estimate.
//!
//! With three or more joints that move the origin in every direction, `F = (J_v J_vᵀ)⁻¹ J_v τ`,
//! the force that best explains the torque; with fewer, the smallest force that does. Where the
//! joints cannot tell a direction (`J_v` nearly loses rank, as at ARASH:ASiST's instrument tip
//! when the tip reaches the remote centre), the sample is marked singular instead of reporting
//! the large number the inverse would give. Each axis carries the σ the joints' σ gives it.

use nalgebra::{Matrix3, SymmetricEigen, Vector3};

use crate::data::Data;
use crate::kinematics::{forward_kinematics, frame_jacobian, frame_placement};
use crate::model::{Frame, Model, UnknownFrame};
use crate::spatial::Vec3;

/// The force at a frame at one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameForceSample {
    /// The force at the frame's origin, base frame (N).
    pub force: [f64; 3],
    /// The same force in the frame's own axes (N): for ARASH:ASiST's `instrument_tip`, `z` is
    /// along the instrument into the eye and `x`, `y` across it.
    pub local: [f64; 3],
    /// The moment of the force about the `about` frame's origin, base frame (N·m).
    pub moment: [f64; 3],
    /// One σ of each base-frame component, from the joints' σ (N).
    pub sigma: [f64; 3],
    /// The frame's origin, base frame (m).
    pub position: [f64; 3],
    /// Whether the joints cannot resolve some direction of force here: `J_v`'s smallest
    /// needed singular value is below the lever the map was built with.
    pub singular: bool,
}

/// The map from joint torque to the force at one named frame, built once; [`Self::map`] does not
/// allocate.
#[derive(Clone, Debug)]
pub struct FrameForce {
    model: Model,
    data: Data,
    frame: Frame,
    about: Frame,
    min_lever_m: f64,
    linear: Vec<f64>,
    angular: Vec<f64>,
}

impl FrameForce {
    /// The force at `frame`, its moment taken about `about` (a frame name too). `min_lever_m` is
    /// the smallest lever (m per rad of a revolute joint, or per m of a prismatic one) by which
    /// the joints must move the frame in every direction a force is resolved in.
    pub fn new(model: &Model, frame: &str, about: &str, min_lever_m: f64) -> Result<Self, UnknownFrame> {
        let n = model.dof();
        Ok(Self {
            model: model.clone(),
            data: Data::new(model),
            frame: model.frame(frame)?,
            about: model.frame(about)?,
            min_lever_m,
            linear: vec![0.0; 3 * n],
            angular: vec![0.0; 3 * n],
        })
    }

    /// The frame the force is at.
    pub fn frame(&self) -> &Frame {
        &self.frame
    }

    /// The force at the frame whose joint torque is `tau` at configuration `q`; `sigma` is each
    /// joint's σ of `tau` (independent joints).
    pub fn map(&mut self, q: &[f64], tau: &[f64], sigma: &[f64]) -> FrameForceSample {
        let n = self.model.dof();
        forward_kinematics(&self.model, &mut self.data, q);
        frame_jacobian(&self.model, &self.data, &self.frame, &mut self.linear, &mut self.angular);
        let (rot, position) = frame_placement(&self.data, &self.frame);
        let (_, centre) = frame_placement(&self.data, &self.about);
        let jac = |i: usize, k: usize| self.linear[i * n + k];
        let gram = Matrix3::from_fn(|i, j| (0..n).map(|k| jac(i, k) * jac(j, k)).sum::<f64>());
        let eigen = SymmetricEigen::new(gram);
        let needed = n.min(3);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
        let floor = self.min_lever_m * self.min_lever_m;
        let singular = eigen.eigenvalues[order[needed - 1]] < floor;
        // The pseudo-inverse of the Gram matrix over the directions the joints resolve.
        let mut inverse = Matrix3::zeros();
        for &i in order.iter().take(needed) {
            let lambda = eigen.eigenvalues[i];
            if lambda >= floor {
                let v = eigen.eigenvectors.column(i);
                inverse += v * v.transpose() / lambda;
            }
        }
        // F = G⁺ J_v τ: the force is P τ with P = G⁺ J_v (3 × n); its σ follows from P.
        let mut force = Vector3::zeros();
        let mut variance = Vector3::zeros();
        for k in 0..n {
            let column = inverse * Vector3::new(jac(0, k), jac(1, k), jac(2, k));
            force += column * tau[k];
            variance += column.component_mul(&column) * sigma[k] * sigma[k];
        }
        let local = rot.transpose() * force;
        let moment: Vec3 = (position - centre).cross(&force);
        FrameForceSample {
            force: force.into(),
            local: local.into(),
            moment: moment.into(),
            sigma: variance.map(f64::sqrt).into(),
            position: position.into(),
            singular,
        }
    }
}
