//! Physical consistency of a standard parameter vector: each body's 4×4 pseudo-inertia must be
//! positive semidefinite (Wensing, Kim and Slotine 2018). Also the scales that make parameters
//! of different units comparable, and the standard parameters nearest CAD behind a β.

use faer::Mat;

use crate::base_parameters::BaseParameters;
use crate::dense;
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

/// Each body's pseudo-inertia in `params` moved onto the positive semidefinite cone, in place: an
/// eigenvalue below a 10⁻¹²th of the body's largest is raised to that. An interior-point solve
/// meets the cone only to its tolerance, and left a body of a closed-loop fit at −2.6·10⁻⁸ kg·m²
/// (body scale 10⁻⁴), which [`CONSISTENCY_TOLERANCE`] refuses; raised, its eigenvalue stays
/// non-negative through the round trip to ten parameters and back.
pub fn onto_consistent(model: &Model, params: &mut [f64]) {
    for b in 0..model.bodies.len() {
        let p = &mut params[crate::params::body(b)];
        let eigen = pseudo_inertia(p).symmetric_eigen();
        let floor = 1e-12 * eigen.eigenvalues.max().max(0.0);
        if eigen.eigenvalues.min() >= floor {
            continue;
        }
        let raised = eigen.eigenvalues.map(|l| l.max(floor));
        let j = eigen.eigenvectors * nalgebra::Matrix4::from_diagonal(&raised) * eigen.eigenvectors.transpose();
        // J = [[Σ, h], [hᵀ, m]] with Σ = ½ tr(I)·1 − I, so I = tr(Σ)·1 − Σ.
        let trace = j[(0, 0)] + j[(1, 1)] + j[(2, 2)];
        p[0] = j[(3, 3)];
        (0..3).for_each(|k| p[1 + k] = 0.5 * (j[(k, 3)] + j[(3, k)]));
        (p[4], p[5], p[6]) = (trace - j[(0, 0)], trace - j[(1, 1)], trace - j[(2, 2)]);
        (p[7], p[8], p[9]) = (-j[(0, 1)], -j[(0, 2)], -j[(1, 2)]);
    }
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
    let b = Mat::from_fn(p, big_p, |i, j| base.b[i * big_p + j]);
    let b_s2 = Mat::from_fn(p, big_p, |i, j| b[(i, j)] * s2[j]);
    let gram = &b_s2 * b.transpose();
    let mut beta_cad = vec![0.0; p];
    base.project(&cad, &mut beta_cad);
    let gap = Mat::from_fn(p, 1, |i, _| beta[i] - beta_cad[i]);
    let y = dense::solve(gram.as_ref(), gap.as_ref()).expect("B has full row rank");
    let correction = b_s2.transpose() * y;
    cad.iter().enumerate().map(|(j, c)| c + correction[(j, 0)]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A body a hair outside the cone (a point mass with its inertia lowered by 10⁻⁸ kg·m², the
    /// pseudo-inertia's eigenvalues 0, 0, 0 and m·(1 + |c|²) before) is moved just inside, by about
    /// that much; the CAD bodies, inside already, are left exactly as they are.
    #[test]
    fn a_body_just_outside_the_cone_is_moved_just_inside_and_the_others_are_kept() {
        let model = crate::arash_asist();
        let mut params = model.cad_parameters();
        let before = params.clone();
        let (m, c) = (0.07, [0.01, -0.02, 0.03]);
        let point =
            crate::spatial::params_from_com(m, &crate::spatial::Vec3::new(c[0], c[1], c[2]), &Default::default());
        let mut outside = point;
        outside[4] -= 1e-8;
        params[crate::params::body(1)].copy_from_slice(&outside);
        assert!(min_pseudo_inertia_eigenvalues(&model, &params)[1] < -1e-9);
        onto_consistent(&model, &mut params);
        assert!(min_pseudo_inertia_eigenvalues(&model, &params).iter().all(|e| *e >= 0.0));
        let moved = params[crate::params::body(1)].iter().zip(&outside).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(moved > 1e-10 && moved < 2e-8, "moved by {moved}");
        for b in (0..model.bodies.len()).filter(|&b| b != 1) {
            assert_eq!(params[crate::params::body(b)], before[crate::params::body(b)]);
        }
    }
}
