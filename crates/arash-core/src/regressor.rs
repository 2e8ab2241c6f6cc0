//! The joint-torque regressors: `τ = Y(q, q̇, q̈) π` (paper eqs. 1–10) and the Slotine–Li regressor
//! `M q̈_r + C q̇_r + g + friction + elastic = Y_S(q, q̇, q̇_r, q̈_r) π` (eq. 22).
//!
//! Both are written into a caller-provided row-major `dof × P` slice (`P = model.num_params()`),
//! with the column layout documented on [`Model`]. Neither allocates.

use crate::data::Data;
use crate::kinematics::{
    motion_sweep, motion_sweep_of, placements_and_jacobians, placements_and_jacobians_of, skipped,
};
use crate::model::Model;
use crate::spatial::{inertia_coefficients, Motion, BODY_PARAMS};

/// `Y(q, q̇, q̈)`, row-major `dof × P`. Coulomb columns use each joint's law (`model.coulomb_laws`) of `q̇`.
pub fn regressor(model: &Model, data: &mut Data, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut [f64]) {
    regressor_of_bodies(model, data, q, qd, qdd, None, out);
}

/// [`regressor`] with the rigid-body columns computed only for the bodies flagged in `bodies` (one
/// flag per body; `None` means all), which must include each flagged body's parent, as
/// [`bodies_of_columns`] gives. The other bodies' columns are left zero, and their kinematics is
/// skipped. A base regressor needs the columns of a few bodies only (on ARASH:ASiST, 5 of 8).
pub fn regressor_of_bodies(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
    qdd: &[f64],
    bodies: Option<&[bool]>,
    out: &mut [f64],
) {
    if let Some(flags) = bodies {
        assert_eq!(flags.len(), model.bodies.len(), "one flag per body");
        let closed = model.bodies.iter().enumerate().all(|(b, body)| !flags[b] || body.parent.is_none_or(|p| flags[p]));
        assert!(closed, "every flagged body's parent must be flagged");
    }
    placements_and_jacobians_of(model, data, q, bodies);
    motion_sweep_of(model, data, qd, qd, qdd, true, bodies);
    // u · (I a + v ×* I v) = ρ(u, a) − ρ(v × u, v): the Newton–Euler wrench projected on u.
    fill_rigid_columns(model, data, bodies, out, |u, v, _, a| {
        let mut row = inertia_coefficients(u, a);
        let coriolis = inertia_coefficients(&v.cross(u), v);
        for (r, c) in row.iter_mut().zip(coriolis) {
            *r -= c;
        }
        row
    });
    fill_joint_columns(model, q, qd, qd, out);
}

/// The Slotine–Li regressor `Y_S(q, q̇, q̇_r, q̈_r)`, row-major `dof × P`.
///
/// The rigid-body part uses the Christoffel-consistent factorisation of Echeverri, Garofalo and
/// Wensing: per body, `f = I a_r + ½[v ×* I v_r − I(v × v_r) + v_r ×* I v]`, which makes
/// `Ṁ − 2C` skew-symmetric. Viscous friction acts on `q̇_r`, Coulomb friction on the measured
/// `q̇` (through `model.coulomb_laws`), elasticity on `q`. With `q̇_r = q̇` and `q̈_r = q̈` this is
/// exactly [`regressor`].
pub fn slotine_li_regressor(
    model: &Model,
    data: &mut Data,
    q: &[f64],
    qd: &[f64],
    qd_r: &[f64],
    qdd_r: &[f64],
    out: &mut [f64],
) {
    placements_and_jacobians(model, data, q);
    motion_sweep(model, data, qd, qd_r, qdd_r, true);
    // ρ is bilinear, so the −½ I(v × v_r) term folds into the acceleration once per body rather
    // than once per row: ρ(u, a_r) − ½ρ(u, v × v_r) = ρ(u, a_r − ½ v × v_r).
    for b in 0..model.bodies.len() {
        let fold = data.vel[b].cross(&data.vel_ref[b]);
        data.acc[b].axpy(-0.5, &fold);
    }
    fill_rigid_columns(model, data, None, out, slotine_li_row);
    fill_joint_columns(model, q, qd, qd_r, out);
}

/// `u · f` for the Christoffel-consistent wrench `f` above, as coefficients of π, given the folded
/// acceleration `a_folded = a_r − ½ v × v_r`.
#[inline]
fn slotine_li_row(u: &Motion, v: &Motion, v_r: &Motion, a_folded: &Motion) -> [f64; BODY_PARAMS] {
    let mut row = inertia_coefficients(u, a_folded);
    let t1 = inertia_coefficients(&v.cross(u), v_r);
    let t3 = inertia_coefficients(&v_r.cross(u), v);
    for i in 0..BODY_PARAMS {
        row[i] -= 0.5 * (t1[i] + t3[i]);
    }
    row
}

/// The flags for [`regressor_of_bodies`] that cover the regressor columns `columns`: a body is
/// needed when one of its ten inertial columns is listed, and so are its ancestors, whose motion
/// it inherits.
pub fn bodies_of_columns(model: &Model, columns: &[usize]) -> Vec<bool> {
    let mut bodies = vec![false; model.bodies.len()];
    for j in columns.iter().filter_map(|&j| model.layout().body_of(j)) {
        let mut body = Some(j);
        while let Some(b) = body {
            bodies[b] = true;
            body = model.bodies[b].parent;
        }
    }
    bodies
}

/// Write the 10 columns of every body (of every flagged body, given `bodies`): row `k` of body `b`
/// is `row(J_b[:, k], v_b, v_r,b, a_b)`.
fn fill_rigid_columns<F>(model: &Model, data: &Data, bodies: Option<&[bool]>, out: &mut [f64], row: F)
where
    F: Fn(&Motion, &Motion, &Motion, &Motion) -> [f64; BODY_PARAMS],
{
    let (n, p) = (model.dof(), model.num_params());
    assert_eq!(out.len(), n * p, "regressor output must hold dof × P = {n} × {p} values");
    out.fill(0.0);
    for b in 0..model.bodies.len() {
        if skipped(bodies, b) {
            continue;
        }
        let (v, v_r, a) = (&data.vel[b], &data.vel_ref[b], &data.acc[b]);
        for k in 0..n {
            let u = &data.jac[b * n + k];
            if *u == Motion::ZERO {
                continue; // joint k does not move body b
            }
            let start = k * p + crate::params::body(b).start;
            out[start..start + BODY_PARAMS].copy_from_slice(&row(u, v, v_r, a));
        }
    }
}

/// Friction and elastic columns: `fv·q̇_r`, `fc·shape(q̇)`, `ke·q` on each joint's own row.
fn fill_joint_columns(model: &Model, q: &[f64], qd: &[f64], qd_r: &[f64], out: &mut [f64]) {
    let (p, at) = (model.num_params(), model.layout());
    for k in 0..model.dof() {
        let row = &mut out[k * p..(k + 1) * p];
        row[at.viscous(k)] = qd_r[k];
        row[at.coulomb(k)] = model.coulomb_laws.eval(k, qd[k]);
        row[at.stiffness(k)] = q[k];
    }
}
