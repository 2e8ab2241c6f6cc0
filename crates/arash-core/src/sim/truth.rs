//! The simulated robot's true parameters: the CAD values with a seeded perturbation, the
//! scenario's friction and cable stiffness, and an optional payload.
//!
//! The perturbation (scaled by `truth.perturbation`, documented in `docs/simulator.md`), per body:
//! - mass × (1 + 0.15 z), z ~ N(0, 1) clipped to ±2.5;
//! - centre of mass moved by 3 mm × z per axis;
//! - inertia about the centre of mass × (1 + 0.25 z), a scalar factor so it stays physical.
//!
//! This is the size of gap between a CAD model and an identified one that the paper reports
//! (it halves the tracking error), and it keeps every body physically consistent.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::scenario::Scenario;
use crate::model::Model;
use crate::spatial::{params_from_com, rotational_inertia, Mat3, Vec3};

const MASS_SIGMA: f64 = 0.15;
const COM_SIGMA_M: f64 = 0.003;
const INERTIA_SIGMA: f64 = 0.25;

fn clipped_normal(rng: &mut ChaCha8Rng) -> f64 {
    let z: f64 = StandardNormal.sample(rng);
    z.clamp(-2.5, 2.5)
}

/// Mass, centre of mass and inertia about the centre of mass of one body's parameters.
pub fn body_com(p: &[f64]) -> (f64, Vec3, Mat3) {
    let m = p[0];
    let c = Vec3::new(p[1], p[2], p[3]) / m;
    let i_c = rotational_inertia(p) - (Mat3::identity() * c.dot(&c) - c * c.transpose()) * m;
    (m, c, i_c)
}

/// The true parameter vector for `scenario` (without the payload, which [`add_payload`] adds
/// when it is attached).
pub fn true_parameters(model: &Model, scenario: &Scenario) -> Vec<f64> {
    let mut params = model.cad_parameters();
    let scale = scenario.truth.perturbation;
    // The truth has its own stream so that sensor noise settings do not change it.
    let mut rng = ChaCha8Rng::seed_from_u64(scenario.seed);
    rng.set_stream(0x7275_7468);
    for b in 0..model.bodies.len() {
        let p = &mut params[crate::params::ParamLayout::new(b + 1, 0).body(b)];
        let (m, c, i_c) = body_com(p);
        let (zm, zc, zi) =
            (clipped_normal(&mut rng), Vec3::from_fn(|_, _| clipped_normal(&mut rng)), clipped_normal(&mut rng));
        let mass = m * (1.0 + scale * MASS_SIGMA * zm);
        let com = c + zc * (scale * COM_SIGMA_M);
        let inertia = i_c * (1.0 + scale * INERTIA_SIGMA * zi);
        p.copy_from_slice(&params_from_com(mass, &com, &inertia));
    }
    let at = model.layout();
    for k in 0..model.dof() {
        params[at.viscous(k)] = scenario.truth.viscous[k];
        params[at.coulomb(k)] = scenario.truth.coulomb[k];
        params[at.stiffness(k)] = scenario.truth.stiffness[k];
    }
    params
}

/// Add a point mass `mass` at `position` (body frame) to body `b`.
pub fn add_payload(params: &mut [f64], b: usize, mass: f64, position: &[f64; 3]) {
    let extra = params_from_com(mass, &Vec3::from(*position), &Mat3::zeros());
    for (p, e) in params[crate::params::body(b)].iter_mut().zip(extra) {
        *p += e;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spatial::pseudo_inertia;

    #[test]
    fn the_truth_is_seeded_physical_and_scaled() {
        let model = crate::arash_asist();
        let mut scenario = Scenario::default();
        let a = true_parameters(&model, &scenario);
        assert_eq!(a, true_parameters(&model, &scenario), "deterministic for a seed");
        scenario.seed = 2;
        assert_ne!(a, true_parameters(&model, &scenario));
        for b in 0..model.bodies.len() {
            let eig = pseudo_inertia(&a[b * 10..b * 10 + 10]).symmetric_eigenvalues().min();
            assert!(eig > 0.0, "body {b} is not physical: λ_min = {eig}");
        }
        scenario.truth.perturbation = 0.0;
        let cad = model.cad_parameters();
        let zero = true_parameters(&model, &scenario);
        for i in 0..model.bodies.len() * 10 {
            assert!((zero[i] - cad[i]).abs() < 1e-15 * (1.0 + cad[i].abs()), "parameter {i}");
        }
    }
}
