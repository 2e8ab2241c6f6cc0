//! Physical consistency of a standard parameter vector: each body's 4×4 pseudo-inertia must be
//! positive semidefinite (Wensing, Kim and Slotine 2018). Also the scales that make parameters
//! of different units comparable, and the standard parameters nearest CAD behind a β.

use crate::base_parameters::BaseParameters;
use crate::model::Model;
use crate::spatial::pseudo_inertia;

/// How far below zero a pseudo-inertia eigenvalue may be and still count as physical: the
/// consistent solve's own tolerance.
pub const CONSISTENCY_TOLERANCE: f64 = 1e-9;

/// The length ℓ that makes first moments and inertias comparable with masses (m): a tenth of a
/// metre, the size of ARASH:ASiST's links.
pub const DEFAULT_LENGTH_SCALE_M: f64 = 0.1;

/// Per-parameter scales `s`: a body's mass m for its mass, m·ℓ for its first moments, m·ℓ² for its
/// inertias; 1 for friction and stiffness.
pub fn parameter_scales(model: &Model, length_scale: f64) -> Vec<f64> {
    let mut s = Vec::with_capacity(model.num_params());
    for body in &model.bodies {
        let m = body.inertial[0];
        let l = length_scale;
        s.extend_from_slice(&[
            m,
            m * l,
            m * l,
            m * l,
            m * l * l,
            m * l * l,
            m * l * l,
            m * l * l,
            m * l * l,
            m * l * l,
        ]);
    }
    s.extend(std::iter::repeat_n(1.0, 3 * model.dof()));
    s
}

/// Smallest eigenvalue of each body's 4×4 pseudo-inertia for parameters `params`.
pub fn min_pseudo_inertia_eigenvalues(model: &Model, params: &[f64]) -> Vec<f64> {
    (0..model.bodies.len())
        .map(|b| pseudo_inertia(&params[crate::params::body(b)]).symmetric_eigenvalues().min())
        .collect()
}

/// The standard parameters closest to CAD (in the scaled norm of [`parameter_scales`])
/// whose base parameters are exactly `beta`: `π = π_CAD + S²Bᵀ(B S² Bᵀ)⁻¹(β − B π_CAD)`.
pub fn nearest_standard_parameters(model: &Model, base: &BaseParameters, beta: &[f64]) -> Vec<f64> {
    let (p, big_p) = (base.rank, base.num_params);
    let cad = model.cad_parameters();
    let s2: Vec<f64> = parameter_scales(model, DEFAULT_LENGTH_SCALE_M).iter().map(|s| s * s).collect();
    let b = nalgebra::DMatrix::from_row_slice(p, big_p, &base.b);
    let b_s2 = nalgebra::DMatrix::from_fn(p, big_p, |i, j| b[(i, j)] * s2[j]);
    let gram = &b_s2 * b.transpose();
    let mut beta_cad = vec![0.0; p];
    base.project(&cad, &mut beta_cad);
    let gap = nalgebra::DVector::from_iterator(p, beta.iter().zip(&beta_cad).map(|(a, c)| a - c));
    let y = gram.lu().solve(&gap).expect("B has full row rank");
    let correction = b_s2.transpose() * y;
    cad.iter().zip(correction.iter()).map(|(c, d)| c + d).collect()
}
