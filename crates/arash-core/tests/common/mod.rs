//! Shared helpers for the integration tests: fixtures, random states and random physical
//! parameters.
#![allow(dead_code)]

pub mod counting;

use arash_core::base_parameters::random_state;
use arash_core::spatial::{params_from_com, Mat3, Vec3};
use arash_core::{load_urdf, Model};
use rand::{RngExt, SeedableRng};
pub use rand_chacha::ChaCha8Rng;

pub fn fixture(name: &str) -> Model {
    let path = format!("{}/../../tests/fixtures/{name}", env!("CARGO_MANIFEST_DIR"));
    load_urdf(&path).unwrap_or_else(|e| panic!("fixture {path}: {e}"))
}

/// The bundled robot and every test fixture.
pub fn all_models() -> Vec<Model> {
    vec![arash_core::arash_asist(), fixture("planar_2link.urdf"), fixture("serial_3dof.urdf")]
}

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

pub struct State {
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
}

pub fn state(model: &Model, rng: &mut ChaCha8Rng) -> State {
    let n = model.dof();
    let mut s = State { q: vec![0.0; n], qd: vec![0.0; n], qdd: vec![0.0; n] };
    random_state(model, rng, &mut s.q, &mut s.qd, &mut s.qdd);
    s
}

/// A random physically consistent parameter vector: each body a solid box of random size, mass,
/// centre and orientation; positive friction and stiffness.
pub fn physical_params(model: &Model, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut p = Vec::with_capacity(model.num_params());
    for _ in &model.bodies {
        let m = rng.random_range(0.05..2.0);
        let c = Vec3::new(rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2), rng.random_range(-0.2..0.2));
        let (a, b, d) = (rng.random_range(0.01..0.3), rng.random_range(0.01..0.3), rng.random_range(0.01..0.3));
        let principal = Mat3::from_diagonal(&Vec3::new(b * b + d * d, a * a + d * d, a * a + b * b)) * (m / 12.0);
        let r = *nalgebra::Rotation3::from_euler_angles(
            rng.random_range(-3.0..3.0),
            rng.random_range(-1.5..1.5),
            rng.random_range(-3.0..3.0),
        )
        .matrix();
        p.extend_from_slice(&params_from_com(m, &c, &(r * principal * r.transpose())));
    }
    for _ in 0..3 * model.dof() {
        p.push(rng.random_range(0.0..1.0));
    }
    p
}

/// Parameters with friction and elasticity zeroed: the rigid-body part only.
pub fn rigid_only(model: &Model, mut p: Vec<f64>) -> Vec<f64> {
    p[model.layout().friction().start..].fill(0.0);
    p
}

pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `Y π` for a row-major `dof × P` regressor.
pub fn apply(y: &[f64], p: &[f64]) -> Vec<f64> {
    y.chunks(p.len()).map(|row| dot(row, p)).collect()
}

pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

pub fn max_abs(a: &[f64]) -> f64 {
    a.iter().map(|x| x.abs()).fold(0.0, f64::max)
}
