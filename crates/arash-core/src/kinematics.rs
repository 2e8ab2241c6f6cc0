//! Forward kinematics, body Jacobians and the velocity/acceleration sweep shared by every
//! dynamics algorithm.

use crate::data::Data;
use crate::model::{Body, Frame, JointKind, Model};
use crate::spatial::{axis_angle, axis_rotation, Mat3, Motion, Vec3};

/// Joint motion subspace `S` of a body, in its own frame.
#[inline]
pub(crate) fn subspace(body: &Body) -> Motion {
    match body.kind {
        JointKind::Revolute => Motion::new(body.axis, Vec3::zeros()),
        JointKind::Prismatic => Motion::new(Vec3::zeros(), body.axis),
        JointKind::Fixed => Motion::ZERO,
    }
}

/// Tree-joint value driven by actuated values `x`; `with_offset` is false for rates.
#[inline]
fn tree_value(body: &Body, x: &[f64], with_offset: bool) -> f64 {
    body.coupling.map_or(0.0, |c| c.multiplier * x[c.index] + if with_offset { c.offset } else { 0.0 })
}

/// Placements (relative and in the base frame) and body Jacobians at configuration `q`.
///
/// Postcondition: `data.world_rot/world_pos` and the Jacobians describe `q`.
pub fn forward_kinematics(model: &Model, data: &mut Data, q: &[f64]) {
    placements_and_jacobians(model, data, q);
    for (b, body) in model.bodies.iter().enumerate() {
        let (rot, pos) = (data.rot[b], data.pos[b]);
        (data.world_rot[b], data.world_pos[b]) = match body.parent {
            Some(p) => (data.world_rot[p] * rot, data.world_pos[p] + data.world_rot[p] * pos),
            None => (rot, pos),
        };
    }
}

/// The orientation and origin of `frame` in the base frame. Precondition: forward kinematics done.
pub fn frame_placement(data: &Data, frame: &Frame) -> (Mat3, Vec3) {
    match frame.body {
        Some(b) => (data.world_rot[b] * frame.rot, data.world_pos[b] + data.world_rot[b] * frame.pos),
        None => (frame.rot, frame.pos),
    }
}

/// The Jacobian of `frame`'s origin in the base frame: the origin's velocity is `linear · q̇`
/// and the frame's angular velocity `angular · q̇` (each 3 × dof, row-major). Precondition:
/// forward kinematics done.
pub fn frame_jacobian(model: &Model, data: &Data, frame: &Frame, linear: &mut [f64], angular: &mut [f64]) {
    let n = model.dof();
    let Some(b) = frame.body else {
        linear.fill(0.0);
        angular.fill(0.0);
        return;
    };
    let rot = data.world_rot[b];
    for k in 0..n {
        let column = data.jac[b * n + k];
        let v = rot * (column.v + column.w.cross(&frame.pos));
        let w = rot * column.w;
        for i in 0..3 {
            linear[i * n + k] = v[i];
            angular[i * n + k] = w[i];
        }
    }
}

/// Parent-relative placements and body Jacobians at `q`: all that the dynamics needs (gravity
/// enters through the base acceleration, so no placement in the base frame is required).
pub(crate) fn placements_and_jacobians(model: &Model, data: &mut Data, q: &[f64]) {
    placements_and_jacobians_of(model, data, q, None);
}

/// [`placements_and_jacobians`] for the flagged bodies only (all for `None`). The flags must
/// include every flagged body's parent; the other bodies' entries are left stale.
pub(crate) fn placements_and_jacobians_of(model: &Model, data: &mut Data, q: &[f64], bodies: Option<&[bool]>) {
    assert_eq!(q.len(), model.dof(), "q has {} entries, the model has {} dof", q.len(), model.dof());
    let n = model.dof();
    for (k, joint) in model.joints.iter().enumerate() {
        if joint.kind == JointKind::Revolute {
            data.sin_cos[k] = q[k].sin_cos();
        }
    }
    for (b, body) in model.bodies.iter().enumerate() {
        if skipped(bodies, b) {
            continue;
        }
        let theta = tree_value(body, q, true);
        let (rot, pos) = match body.kind {
            JointKind::Revolute => (body.origin_rot * revolute_rotation(model, data, body, theta), body.origin_pos),
            JointKind::Prismatic => (body.origin_rot, body.origin_pos + body.origin_rot * body.axis * theta),
            JointKind::Fixed => (body.origin_rot, body.origin_pos),
        };
        data.rot[b] = rot;
        data.pos[b] = pos;
        match body.parent {
            Some(p) => {
                for k in 0..n {
                    let parent_column = data.jac[p * n + k];
                    // Joints that do not move the parent leave a zero column: skip the transform.
                    data.jac[b * n + k] =
                        if parent_column == Motion::ZERO { Motion::ZERO } else { parent_column.to_child(&rot, &pos) };
                }
            }
            None => data.jac[b * n..(b + 1) * n].fill(Motion::ZERO),
        }
        if let Some(c) = body.coupling {
            data.jac[b * n + c.index].axpy(c.multiplier, &subspace(body));
        }
    }
}

/// Whether body `b` is left out under the flags `bodies` (`None` keeps every body).
#[inline]
pub(crate) fn skipped(bodies: Option<&[bool]>, b: usize) -> bool {
    bodies.is_some_and(|flags| !flags[b])
}

/// The rotation of a revolute body by its tree angle `theta`. Passive joints of a closed chain
/// usually mimic an actuated revolute joint with multiplier ±1 and no offset; their sine and cosine
/// are then those of the actuated angle, exactly, and one `sin_cos` per actuated joint serves them
/// all (on ARASH:ASiST, 2 evaluations instead of 7).
#[inline]
fn revolute_rotation(model: &Model, data: &Data, body: &Body, theta: f64) -> Mat3 {
    match body.coupling {
        Some(c)
            if c.offset == 0.0 && c.multiplier.abs() == 1.0 && model.joints[c.index].kind == JointKind::Revolute =>
        {
            let (s, cos) = data.sin_cos[c.index];
            axis_rotation(&body.axis, c.multiplier * s, cos)
        }
        _ => axis_angle(&body.axis, theta),
    }
}

/// Body velocities `v = J q̇`, reference velocities `v_r = J q̇_r`, and reference accelerations
/// `a_r = X a_r,parent + S q̈_r + v × S q̇_r` (the Slotine–Li recursion; with `q̇_r = q̇` it is the
/// ordinary spatial acceleration). With `gravity`, the base accelerates at `−g` so that `a_r`
/// carries the gravity load.
///
/// Precondition: [`forward_kinematics`] has been called for the same `q`.
pub fn motion_sweep(model: &Model, data: &mut Data, qd: &[f64], qd_r: &[f64], qdd_r: &[f64], gravity: bool) {
    motion_sweep_of(model, data, qd, qd_r, qdd_r, gravity, None);
}

/// [`motion_sweep`] for the flagged bodies only (all for `None`), with the flags as in
/// [`placements_and_jacobians_of`].
pub(crate) fn motion_sweep_of(
    model: &Model,
    data: &mut Data,
    qd: &[f64],
    qd_r: &[f64],
    qdd_r: &[f64],
    gravity: bool,
    bodies: Option<&[bool]>,
) {
    let n = model.dof();
    assert!(
        qd.len() == n && qd_r.len() == n && qdd_r.len() == n,
        "velocity and acceleration vectors must have {n} entries"
    );
    let base = if gravity { Motion::new(Vec3::zeros(), -model.gravity) } else { Motion::ZERO };
    for (b, body) in model.bodies.iter().enumerate() {
        if skipped(bodies, b) {
            continue;
        }
        let cols = &data.jac[b * n..(b + 1) * n];
        let mut v = Motion::ZERO;
        for k in 0..n {
            v.axpy(qd[k], &cols[k]);
        }
        // The plain regressor and the dynamics pass q̇ as q̇_r: one product is enough.
        let v_r = if std::ptr::eq(qd, qd_r) {
            v
        } else {
            let mut v_r = Motion::ZERO;
            for k in 0..n {
                v_r.axpy(qd_r[k], &cols[k]);
            }
            v_r
        };
        let parent_acc = body.parent.map_or(base, |p| data.acc[p]);
        let mut a = parent_acc.to_child(&data.rot[b], &data.pos[b]);
        let s = subspace(body);
        a.axpy(tree_value(body, qdd_r, false), &s);
        a = a.add(&v.cross(&s).scaled(tree_value(body, qd_r, false)));
        data.vel[b] = v;
        data.vel_ref[b] = v_r;
        data.acc[b] = a;
    }
}
