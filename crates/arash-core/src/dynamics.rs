//! Dynamics with a known parameter vector π: inverse dynamics, `M(q)`, `C(q, q̇)`, `g(q)`, forward
//! dynamics and the energies. Each evaluates the spatial inertias directly rather than forming the
//! regressor, and none allocates.
//!
//! `π` has the layout documented on [`Model`]; torques are N·m for revolute and N for prismatic
//! joints.

use crate::data::Data;
use crate::kinematics::{motion_sweep, placements_and_jacobians, subspace};
use crate::model::Model;
use crate::spatial::{apply_inertia, Force, Motion};

/// Why forward dynamics could not be solved.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum DynamicsError {
    #[error(
        "the mass matrix is not positive definite (pivot {pivot} is {value:.3e}); the parameters are not physical"
    )]
    MassNotPositiveDefinite { pivot: usize, value: f64 },
}

fn body_params(params: &[f64], b: usize) -> &[f64] {
    &params[crate::params::body(b)]
}

pub(crate) fn check_params(model: &Model, params: &[f64]) {
    assert_eq!(
        params.len(),
        model.num_params(),
        "π has {} entries, the model needs {}",
        params.len(),
        model.num_params()
    );
}

/// `τ_k = Σ_b J_b[:, k] · f_b` for per-body wrenches produced by `wrench(b)`.
fn project_wrenches<F: Fn(usize) -> Force>(model: &Model, data: &Data, tau: &mut [f64], wrench: F) {
    let n = model.dof();
    tau.fill(0.0);
    for b in 0..model.bodies.len() {
        let f = wrench(b);
        for (k, t) in tau.iter_mut().enumerate() {
            *t += data.jac[b * n + k].dot(&f);
        }
    }
}

/// Friction and elastic torques `fv·q̇ + fc·shape(q̇) + ke·q`, added to `tau`.
fn add_joint_torques(model: &Model, params: &[f64], q: &[f64], qd: &[f64], tau: &mut [f64]) {
    let at = model.layout();
    for k in 0..model.dof() {
        tau[k] += params[at.viscous(k)] * qd[k]
            + params[at.coulomb(k)] * model.coulomb_laws.eval(k, qd[k])
            + params[at.stiffness(k)] * q[k];
    }
}

/// Inverse dynamics `τ = M q̈ + C q̇ + g + friction + elastic = Y(q, q̇, q̈) π`.
pub fn inverse_dynamics(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    params: &[f64],
    tau: &mut [f64],
) {
    check_params(model, params);
    placements_and_jacobians(model, data, q);
    motion_sweep(model, data, qd, qd, qdd, true);
    project_wrenches(model, data, tau, |b| {
        let p = body_params(params, b);
        let (v, a) = (&data.vel[b], &data.acc[b]);
        let f = apply_inertia(p, a);
        let gyro = v.cross_force(&apply_inertia(p, v));
        Force { n: f.n + gyro.n, f: f.f + gyro.f }
    });
    add_joint_torques(model, params, q, qd, tau);
}

/// The joint-space mass matrix `M(q)`, row-major `dof × dof`. Friction and elastic entries of π are
/// not used.
pub fn mass_matrix(model: &Model, data: &mut Data, q: &[f64], params: &[f64], out: &mut [f64]) {
    check_params(model, params);
    placements_and_jacobians(model, data, q);
    fill_mass_matrix(model, data, params, out);
}

/// `M = Σ_b J_bᵀ I_b J_b`. Precondition: forward kinematics done.
fn fill_mass_matrix(model: &Model, data: &Data, params: &[f64], out: &mut [f64]) {
    let n = model.dof();
    assert_eq!(out.len(), n * n, "M output must hold {n} × {n} values");
    out.fill(0.0);
    for b in 0..model.bodies.len() {
        let p = body_params(params, b);
        let cols = &data.jac[b * n..(b + 1) * n];
        for l in 0..n {
            if cols[l] == Motion::ZERO {
                continue;
            }
            let f = apply_inertia(p, &cols[l]);
            for k in 0..=l {
                let m = cols[k].dot(&f);
                out[k * n + l] += m;
                if k != l {
                    out[l * n + k] += m;
                }
            }
        }
    }
}

/// The Coriolis/centrifugal matrix `C(q, q̇)` built from the Christoffel symbols of `M`, row-major
/// `dof × dof`, so that `Ṁ − 2C` is skew-symmetric and `C q̇` is the velocity-product torque.
pub fn coriolis_matrix(model: &Model, data: &mut Data, q: &[f64], qd: &[f64], params: &[f64], out: &mut [f64]) {
    check_params(model, params);
    let n = model.dof();
    assert_eq!(out.len(), n * n, "C output must hold {n} × {n} values");
    placements_and_jacobians(model, data, q);
    out.fill(0.0);
    // Column l is C e_l: the Slotine–Li wrench with q̇_r = e_l, q̈_r = 0 and no gravity.
    for l in 0..n {
        data.unit.fill(0.0);
        data.unit[l] = 1.0;
        let (unit, zeros) = (std::mem::take(&mut data.unit), std::mem::take(&mut data.zeros));
        motion_sweep(model, data, qd, &unit, &zeros, false);
        data.unit = unit;
        data.zeros = zeros;
        for b in 0..model.bodies.len() {
            let f = christoffel_wrench(body_params(params, b), &data.vel[b], &data.vel_ref[b], &data.acc[b]);
            for k in 0..n {
                out[k * n + l] += data.jac[b * n + k].dot(&f);
            }
        }
    }
}

/// `I a_r + ½[v ×* I v_r − I(v × v_r) + v_r ×* I v]`.
fn christoffel_wrench(p: &[f64], v: &Motion, v_r: &Motion, a_r: &Motion) -> Force {
    let base = apply_inertia(p, a_r);
    let t1 = v.cross_force(&apply_inertia(p, v_r));
    let t2 = apply_inertia(p, &v.cross(v_r));
    let t3 = v_r.cross_force(&apply_inertia(p, v));
    Force { n: base.n + (t1.n - t2.n + t3.n) * 0.5, f: base.f + (t1.f - t2.f + t3.f) * 0.5 }
}

/// The terms of the generalized momentum observer at `(q, q̇)` in one kinematic pass: the
/// momentum `M(q) q̇`, `Cᵀ(q, q̇) q̇` and the gravity torque `g(q)`, each `dof` long. Friction and
/// elastic entries of π are not used.
///
/// `Cᵀq̇` is `∂T/∂q`, the kinetic energy's gradient (the Christoffel `C` makes them equal), and a
/// tree's `∂T/∂θ` about one joint is `(v × s) · H`: the joint body's velocity crossed with its
/// axis, against the momentum `H` of everything the joint carries. That costs one sweep out and
/// one back instead of `C`'s `dof` sweeps; a coupled body adds its multiplier's share to the
/// coordinate that drives it.
pub fn momentum_terms(model: &Model, data: &mut Data, q: &[f64], qd: &[f64], params: &[f64], out: MomentumTerms<'_>) {
    check_params(model, params);
    let n = model.dof();
    let MomentumTerms { momentum, coriolis_t, gravity } = out;
    assert!(
        momentum.len() == n && coriolis_t.len() == n && gravity.len() == n,
        "the momentum terms must each hold {n} values"
    );
    placements_and_jacobians(model, data, q);
    // Velocities J q̇, and accelerations of gravity alone (no reference rate, no q̈).
    let zeros = std::mem::take(&mut data.zeros);
    motion_sweep(model, data, qd, &zeros, &zeros, true);
    data.zeros = zeros;
    momentum.fill(0.0);
    gravity.fill(0.0);
    for b in 0..model.bodies.len() {
        let p = body_params(params, b);
        let h = apply_inertia(p, &data.vel[b]);
        let w = apply_inertia(p, &data.acc[b]);
        for k in 0..n {
            let column = &data.jac[b * n + k];
            momentum[k] += column.dot(&h);
            gravity[k] += column.dot(&w);
        }
        data.subtree[b] = h;
    }
    coriolis_t.fill(0.0);
    for (b, body) in model.bodies.iter().enumerate().rev() {
        let carried = data.subtree[b];
        if let Some(c) = body.coupling {
            coriolis_t[c.index] += c.multiplier * data.vel[b].cross(&subspace(body)).dot(&carried);
        }
        if let Some(parent) = body.parent {
            data.subtree[parent] = data.subtree[parent].add(&carried.to_parent(&data.rot[b], &data.pos[b]));
        }
    }
}

/// Where [`momentum_terms`] writes: `M q̇`, `Cᵀq̇` and `g`, each `dof` long.
pub struct MomentumTerms<'a> {
    pub momentum: &'a mut [f64],
    pub coriolis_t: &'a mut [f64],
    pub gravity: &'a mut [f64],
}

/// The gravity torque `g(q)`.
pub fn gravity_torque(model: &Model, data: &mut Data, q: &[f64], params: &[f64], tau: &mut [f64]) {
    check_params(model, params);
    placements_and_jacobians(model, data, q);
    let zeros = std::mem::take(&mut data.zeros);
    motion_sweep(model, data, &zeros, &zeros, &zeros, true);
    data.zeros = zeros;
    project_wrenches(model, data, tau, |b| apply_inertia(body_params(params, b), &data.acc[b]));
}

/// Forward dynamics: `q̈ = M⁻¹ (τ − C q̇ − g − friction − elastic)`, by Cholesky of `M`.
pub fn forward_dynamics(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
    params: &[f64],
    qdd: &mut [f64],
) -> Result<(), DynamicsError> {
    forward_dynamics_with_armature(model, data, q, qd, tau, Parameters { params, armature: None }, qdd)
}

/// The parameters of a forward-dynamics call: π, and a reflected rotor inertia per joint (kg·m²
/// or kg) added to `M`'s diagonal, if any.
#[derive(Clone, Copy, Debug)]
pub struct Parameters<'a> {
    pub params: &'a [f64],
    pub armature: Option<&'a [f64]>,
}

/// Forward dynamics with the armature added to `M` at the state `(q, q̇)`:
/// `q̈ = (M + diag(armature))⁻¹ (τ − C q̇ − g − friction − elastic)`.
pub fn forward_dynamics_with_armature(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
    tau: &[f64],
    parameters: Parameters,
    qdd: &mut [f64],
) -> Result<(), DynamicsError> {
    let Parameters { params, armature } = parameters;
    let n = model.dof();
    assert!(tau.len() == n && qdd.len() == n, "τ and q̈ must have {n} entries");
    let zeros = std::mem::take(&mut data.zeros);
    let mut bias = std::mem::take(&mut data.rhs);
    inverse_dynamics(model, data, q, qd, &zeros, params, &mut bias);
    data.zeros = zeros;
    for k in 0..n {
        qdd[k] = tau[k] - bias[k];
    }
    data.rhs = bias;
    let mut mass = std::mem::take(&mut data.mass);
    fill_mass_matrix(model, data, params, &mut mass);
    if let Some(armature) = armature {
        for (k, j) in armature.iter().enumerate() {
            mass[k * n + k] += j;
        }
    }
    let result = cholesky_solve_in_place(&mut mass, n, qdd);
    data.mass = mass;
    result
}

/// Solve `A x = b` for symmetric positive definite `A` (row-major, overwritten by its factor);
/// `b` is overwritten by `x`. Small dense systems only: `dof` is a handful.
fn cholesky_solve_in_place(a: &mut [f64], n: usize, b: &mut [f64]) -> Result<(), DynamicsError> {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d.is_nan() || d <= 0.0 {
            return Err(DynamicsError::MassNotPositiveDefinite { pivot: j, value: d });
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[i * n + k] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[k * n + i] * b[k];
        }
        b[i] = s / a[i * n + i];
    }
    Ok(())
}

/// Kinetic energy `½ Σ vᵀ I v` (J). Precondition: none; runs its own kinematics.
pub fn kinetic_energy(model: &Model, data: &mut Data, q: &[f64], qd: &[f64], params: &[f64]) -> f64 {
    check_params(model, params);
    placements_and_jacobians(model, data, q);
    let n = model.dof();
    (0..model.bodies.len())
        .map(|b| {
            let mut v = Motion::ZERO;
            for (rate, column) in qd.iter().zip(&data.jac[b * n..(b + 1) * n]) {
                v.axpy(*rate, column);
            }
            0.5 * v.dot(&apply_inertia(body_params(params, b), &v))
        })
        .sum()
}

/// Gravitational potential energy `−Σ gᵀ(m p + R h)` (J), zero at the base origin.
pub fn potential_energy(model: &Model, data: &mut Data, q: &[f64], params: &[f64]) -> f64 {
    check_params(model, params);
    crate::kinematics::forward_kinematics(model, data, q);
    (0..model.bodies.len())
        .map(|b| {
            let p = body_params(params, b);
            let h = crate::spatial::Vec3::new(p[1], p[2], p[3]);
            -model.gravity.dot(&(data.world_pos[b] * p[0] + data.world_rot[b] * h))
        })
        .sum()
}
