//! `coupled_rotor`: the rotor of a motor that turns with more than one joint, as the Stäubli
//! TX40's wrist motor 6 turns with joints 5 and 6 (θ₆ = N₆ (q₅ + q₆)).
//!
//! A declared transmission θ = R q gives the motor's motion in units of its own joint,
//! `q_m = g·q` with `g = R[m, :] / R[m, m]`. Its rotor inertia I, viscous friction f_v and dry
//! friction f_c (all as its own joint sees them, as upstream's `Iam6`, `fvm6`, `fsm6` are) act
//! on every joint the motor turns with, through the same ratio (power balance, τ = gᵀ τ_m):
//!
//! τ_j += g_j (I q̈_m + f_v q̇_m + f_c s(q̇_m)).
//!
//! A motor that only one joint turns is that joint's `armature` and friction; this term exists
//! only where the transmission couples joints. Its columns are the motor's own sample
//! ([`EffectTerm::sample_of`]) spread over the joints by `g` ([`EffectTerm::weight_on`]); the
//! transmission names the coupled motors (`Transmission::coupled_motors`). The dry-friction
//! column switches with the motion and is filtered like the torque; the other two are not
//! ([`Effect::column_filtered`]).

use super::{Effect, EffectKind, EffectTerm, JointData, NotSearched, Sample, TermState};

pub struct CoupledRotor;

impl Effect for CoupledRotor {
    fn id(&self) -> &'static str {
        "coupled_rotor"
    }
    fn width(&self) -> usize {
        3
    }
    fn column_names(&self) -> Vec<String> {
        vec!["q̈_m".into(), "q̇_m".into(), "s(q̇_m)".into()]
    }
    fn column_filtered(&self, column: usize) -> bool {
        column == 2
    }
    /// Inertia and both frictions are positive.
    fn physical_sign(&self) -> Option<f64> {
        Some(1.0)
    }
    fn every_coefficient_signed(&self) -> bool {
        true
    }
    fn plotted_against(&self) -> &'static str {
        "qdd"
    }
    fn features(&self, term: &EffectTerm, x: Sample, _: &mut TermState, out: &mut [f64]) {
        out[0] = x.qdd;
        out[1] = x.v;
        out[2] = term.direction(x.v);
    }
    fn detail(&self, term: &EffectTerm) -> String {
        let g = term.coupling.as_deref().unwrap_or_default();
        let with: Vec<String> = g
            .iter()
            .enumerate()
            .filter(|&(j, &w)| w != 0.0 && Some(j) != term.joint)
            .map(|(j, w)| format!("joint {} ×{w:.3}", j + 1))
            .collect();
        format!(" (motor turns with {})", with.join(", "))
    }
    /// Built from the transmission, not joint by joint (`diagnose/candidates.rs`): `data` is
    /// the motor's own motion.
    fn joint_candidates(&self, data: &JointData) -> Result<Vec<EffectTerm>, NotSearched> {
        Ok(vec![data.term(EffectKind::CoupledRotor)])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::feedforward::EffectFeedforward;

    /// The equation, against a motor's dynamics written out by hand: a rotor of inertia J_m and
    /// frictions b_m, c_m on a motor shaft turned at θ̇ = N (q̇₃ + c q̇₂) (R[2][2] = N,
    /// R[2][1] = N c) needs the motor torque τ_m = J_m θ̈ + b_m θ̇ + c_m sign(θ̇), and the joints
    /// feel Rᵀ τ_m: N c τ_m on joint 2 and N τ_m on joint 3. The term's coefficients are those on
    /// joint 3's scale, N² J_m, N² b_m and N c_m, and a controller adds exactly that.
    #[test]
    fn the_motor_acts_on_every_joint_it_turns_with_through_the_transmission() {
        let (n, c, jm, bm, cm) = (40.0, -0.6, 2.0e-5, 3.0e-4, 0.05);
        let rows = [[1.0, 0.0, 0.0], [0.0, 25.0, 0.0], [0.0, n * c, n]];
        let r = faer::Mat::from_fn(3, 3, |i, j| rows[i][j]);
        let r = crate::transmission::Transmission::from_matrix(r, vec![0.0; 3]).unwrap();
        let (m, g) = r.coupled_motors().pop().expect("motor 3 is coupled");
        let mut term = EffectTerm::new(EffectKind::CoupledRotor, Some(m));
        term.coupling = Some(g);
        term.coefficients = vec![n * n * jm, n * n * bm, n * cm];
        let model = crate::arash_asist();
        let mut params = model.cad_parameters();
        let mut ff = EffectFeedforward::new(&model, std::slice::from_ref(&term), &[], &mut params);
        let (q, qd, qdd) = ([0.1, 0.2, 0.03], [0.3, -0.2, 0.05], [1.0, 2.0, -1.5]);
        let mut tau = [0.0; 3];
        ff.add(&q, &qd, &qdd, &mut tau);
        let (theta_d, theta_dd) = (n * (qd[2] + c * qd[1]), n * (qdd[2] + c * qdd[1]));
        let tau_m = jm * theta_dd + bm * theta_d + cm * theta_d.signum();
        let expected = [0.0, n * c * tau_m, n * tau_m];
        for (j, (t, e)) in tau.iter().zip(expected).enumerate() {
            assert!((t - e).abs() < 1e-12 * e.abs().max(1.0), "joint {}: {t} against {e}", j + 1);
        }
    }
}
