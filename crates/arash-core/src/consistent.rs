//! Physically consistent identification: least squares over the full standard parameter vector π
//! with every body's pseudo-inertia positive semidefinite (Wensing, Kim and Slotine 2017),
//! non-negative friction and bounded cable stiffness, solved as a semidefinite program by Clarabel.
//!
//! Problem (π ∈ R^P):
//!
//!   minimise  (1/m)‖W π − τ‖² + (1/m)·λ Σᵢ ((πᵢ − π_CAD,ᵢ) / sᵢ)²
//!   subject to  J_b(π) ⪰ 0 for every body,  fv, fc ≥ 0,  ke_lo ≤ ke ≤ ke_hi
//!
//! W is the full stacked regressor (m rows). The second term is a weak pull toward CAD. Data fix
//! only the base parameters, so it picks one π among the many that fit equally well. Each
//! parameter is pulled in proportion to how strongly the data sees it on its own:
//!
//!   λᵢ = pull · (‖wᵢ‖² + 10⁻³ · c̄ / sᵢ²)
//!
//! So `pull = 1e-4` keeps CAD ten thousand times weaker than the data along every column. The floor
//! term, with c̄ the mean of ‖wᵢ‖²sᵢ², still pulls parameters the data never sees. `sᵢ` is the
//! parameter's natural scale: body mass m_b, m_b·ℓ for first moments, m_b·ℓ² for inertias, with
//! ℓ = 0.1 m; 1 for friction and stiffness.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT};
use faer::Mat;

use crate::model::Model;
use crate::physical::{min_pseudo_inertia_eigenvalues, onto_consistent, parameter_scales};
use crate::signal::options::{positive, SettingError};

/// Settings for [`identify_consistent`]: the physically consistent fit's semidefinite problem.
#[derive(Clone, Debug)]
pub struct ConsistentOptions {
    /// Strength of the pull toward CAD, relative to the data (0 disables it).
    pub pull: f64,
    /// Bounds on each joint's cable stiffness `ke` (N·m/rad or N/m).
    pub stiffness_bounds: (f64, f64),
    /// Length scale ℓ used to scale first moments and inertias (m).
    pub length_scale: f64,
}

impl Default for ConsistentOptions {
    fn default() -> Self {
        Self {
            pull: 1e-4,
            stiffness_bounds: (0.0, f64::INFINITY),
            length_scale: crate::physical::DEFAULT_LENGTH_SCALE_M,
        }
    }
}

impl ConsistentOptions {
    /// Check every setting before the problem is built.
    pub fn validate(&self) -> Result<(), SettingError> {
        if !(self.pull.is_finite() && self.pull >= 0.0) {
            return Err(SettingError::new("pull", self.pull, "a non-negative number (0 disables the pull toward CAD)"));
        }
        let (lo, hi) = self.stiffness_bounds;
        if !(lo.is_finite() && lo >= 0.0 && !hi.is_nan() && hi >= lo) {
            return Err(SettingError::new(
                "stiffness_bounds",
                format!("({lo}, {hi})"),
                "0 ≤ lower ≤ upper, the lower finite (the upper may be infinite)",
            ));
        }
        positive("length_scale", self.length_scale)
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConsistentError {
    #[error(transparent)]
    Setting(#[from] SettingError),
    #[error("the consistent problem has no solution: {0:?} (check the stiffness bounds)")]
    Infeasible(SolverStatus),
    #[error("Clarabel stopped with {0:?}; the consistent estimate is not reliable")]
    SolverFailed(SolverStatus),
    #[error("W has {cols} columns but the model has {params} parameters")]
    Shape { cols: usize, params: usize },
}

/// The physically consistent estimate.
#[derive(Clone, Debug)]
pub struct ConsistentFit {
    /// The full standard parameter vector, then the coefficients of any extra columns.
    pub params: Vec<f64>,
    /// Smallest eigenvalue of each body's pseudo-inertia (≥ 0 up to solver tolerance).
    pub min_pseudo_inertia_eigenvalue: Vec<f64>,
    pub status: SolverStatus,
    pub iterations: u32,
    pub solve_time_s: f64,
}

/// Solve the consistent problem for a stacked full regressor `w` (m × P) and torques `tau`.
///
/// `w` may carry columns beyond the P standard parameters (the effects a diagnosis found): their
/// coefficients are free, follow the P parameters in [`ConsistentFit::params`], and are pulled
/// toward zero as weakly as the others are pulled toward CAD.
pub fn identify_consistent(
    model: &Model,
    w: &Mat<f64>,
    tau: &[f64],
    options: &ConsistentOptions,
) -> Result<ConsistentFit, ConsistentError> {
    identify_consistent_bounded(model, w, tau, options, &[])
}

/// What an extra column's coefficient is held to in the consistent fit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ExtraBound {
    /// The sign it must have (`None`: either). A physical effect's sign is a constraint like a
    /// positive mass: a rotor inertia or a dissipative friction fitted negative is a model a
    /// controller cannot use (it feeds energy in).
    pub sign: Option<f64>,
    /// The largest magnitude it may take (`None`: any).
    pub magnitude: Option<f64>,
}

impl ExtraBound {
    /// The interval the coefficient lies in (infinite ends: unbounded): up to the magnitude on
    /// the sign's side, zero on the other.
    fn interval(&self) -> (f64, f64) {
        let c = self.magnitude.unwrap_or(f64::INFINITY);
        match self.sign {
            Some(sign) if sign > 0.0 => (0.0, c),
            Some(_) => (-c, 0.0),
            None => (-c, c),
        }
    }
}

/// [`identify_consistent`] with a bound on each extra column's coefficient (`extras[j]` for
/// column P + j; missing: free).
pub fn identify_consistent_bounded(
    model: &Model,
    w: &Mat<f64>,
    tau: &[f64],
    options: &ConsistentOptions,
    extras: &[ExtraBound],
) -> Result<ConsistentFit, ConsistentError> {
    options.validate()?;
    let (standard, p) = (model.num_params(), w.ncols());
    if p < standard {
        return Err(ConsistentError::Shape { cols: w.ncols(), params: standard });
    }
    let m = w.nrows() as f64;
    let gram = w.transpose() * w;
    let tau_mat = Mat::<f64>::from_fn(tau.len(), 1, |i, _| tau[i]);
    let wt_tau = w.transpose() * &tau_mat;
    let mut cad = model.cad_parameters();
    cad.resize(p, 0.0);
    let mut scales = parameter_scales(model, options.length_scale);
    // An extra column's scale: the size of a coefficient that moves the prediction by one
    // RMS torque, from its own curvature.
    scales.extend((standard..p).map(|i| (m / gram[(i, i)].max(f64::MIN_POSITIVE)).sqrt()));
    let mean_curvature = (0..p).map(|i| gram[(i, i)] * scales[i] * scales[i]).sum::<f64>() / p as f64;
    // ½ πᵀPπ + qᵀπ with P = 2(WᵀW + Λ)/m and q = −2(Wᵀτ + Λ π_CAD)/m.
    let reg = |i: usize| options.pull * (gram[(i, i)] + 1e-3 * mean_curvature / (scales[i] * scales[i]));
    let mut p_triplets = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..p {
        for i in 0..=j {
            let v = 2.0 * (gram[(i, j)] + if i == j { reg(i) } else { 0.0 }) / m;
            if v != 0.0 {
                p_triplets.0.push(i);
                p_triplets.1.push(j);
                p_triplets.2.push(v);
            }
        }
    }
    let p_mat = CscMatrix::new_from_triplets(p, p, p_triplets.0, p_triplets.1, p_triplets.2);
    let q: Vec<f64> = (0..p).map(|i| -2.0 * (wt_tau[(i, 0)] + reg(i) * cad[i]) / m).collect();
    let (a_mat, b, cones) = constraints(model, p, options.stiffness_bounds, extras);
    let settings = DefaultSettingsBuilder::default().verbose(false).max_iter(200).build().expect("valid settings");
    // The semidefinite cones call BLAS and LAPACK under their Fortran names: the binary links
    // them, arash's own (the arash-blas-lapack crate) or a system BLAS.
    let mut solver = DefaultSolver::new(&p_mat, &q, &a_mat, &b, &cones, settings).expect("well-formed problem");
    solver.solve();
    let status = solver.solution.status;
    match status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {}
        SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
            return Err(ConsistentError::Infeasible(status))
        }
        other => return Err(ConsistentError::SolverFailed(other)),
    }
    let mut params = solver.solution.x.clone();
    onto_consistent(model, &mut params[..standard]);
    Ok(ConsistentFit {
        min_pseudo_inertia_eigenvalue: min_pseudo_inertia_eigenvalues(model, &params[..standard]),
        params,
        status,
        iterations: solver.solution.iterations,
        solve_time_s: solver.solution.solve_time,
    })
}

/// `A π + s = b`, `s ∈ K`: non-negative friction, stiffness bounds, the intervals of the extra
/// columns that have one, then one 4×4 PSD cone per body. `p` counts the columns, extra ones
/// included.
fn constraints(
    model: &Model,
    p: usize,
    stiffness_bounds: (f64, f64),
    extras: &[ExtraBound],
) -> (CscMatrix<f64>, Vec<f64>, Vec<SupportedConeT<f64>>) {
    let (mut rows, mut cols, mut vals, mut b) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut push = |row: usize, col: usize, val: f64, rows: &mut Vec<usize>, cols: &mut Vec<usize>| {
        rows.push(row);
        cols.push(col);
        vals.push(val);
    };
    // Non-negative orthant: s = π_i − lo ≥ 0 (A = −e_i, b = −lo) and s = hi − π_i ≥ 0 (A = e_i),
    // each where its bound is finite.
    let mut row = 0;
    let mut within = |i: usize, (lo, hi): (f64, f64), rows: &mut Vec<usize>, cols: &mut Vec<usize>| {
        for (a, limit) in [(-1.0, -lo), (1.0, hi)] {
            if limit.is_finite() {
                push(row, i, a, rows, cols);
                b.push(limit);
                row += 1;
            }
        }
    };
    for i in model.layout().friction() {
        within(i, (0.0, f64::INFINITY), &mut rows, &mut cols);
    }
    for i in model.layout().stiffnesses() {
        within(i, stiffness_bounds, &mut rows, &mut cols);
    }
    let standard = model.num_params();
    for (j, bound) in extras.iter().enumerate().take(p.saturating_sub(standard)) {
        within(standard + j, bound.interval(), &mut rows, &mut cols);
    }
    let mut cones = vec![SupportedConeT::NonnegativeConeT(row)];
    // svec of J(π_b), upper triangle column by column, off-diagonals × √2; s = svec(J) = −Aπ.
    let r2 = std::f64::consts::SQRT_2;
    // (entry, [(body parameter index, coefficient)]) with indices m 0, mx 1, my 2, mz 3, Ixx 4,
    // Iyy 5, Izz 6, Ixy 7, Ixz 8, Iyz 9; Σ = ½ tr(I)·1 − I.
    let svec: [&[(usize, f64)]; 10] = [
        &[(4, -0.5), (5, 0.5), (6, 0.5)],
        &[(7, -r2)],
        &[(4, 0.5), (5, -0.5), (6, 0.5)],
        &[(8, -r2)],
        &[(9, -r2)],
        &[(4, 0.5), (5, 0.5), (6, -0.5)],
        &[(1, r2)],
        &[(2, r2)],
        &[(3, r2)],
        &[(0, 1.0)],
    ];
    for body in 0..model.bodies.len() {
        for entry in svec {
            for &(k, c) in entry {
                push(row, crate::params::body(body).start + k, -c, &mut rows, &mut cols);
            }
            b.push(0.0);
            row += 1;
        }
        cones.push(SupportedConeT::PSDTriangleConeT(4));
    }
    (CscMatrix::new_from_triplets(row, p, rows, cols, vals), b, cones)
}

#[cfg(test)]
mod options_tests {
    use super::*;

    #[test]
    fn the_defaults_are_valid() {
        assert_eq!(ConsistentOptions::default().validate(), Ok(()));
    }

    #[test]
    fn each_bad_setting_is_named() {
        let name = |e: Result<(), SettingError>| e.unwrap_err().name;
        let con = ConsistentOptions::default;
        assert_eq!(name(ConsistentOptions { pull: -1e-4, ..con() }.validate()), "pull");
        assert_eq!(name(ConsistentOptions { pull: f64::INFINITY, ..con() }.validate()), "pull");
        assert_eq!(name(ConsistentOptions { stiffness_bounds: (2.0, 1.0), ..con() }.validate()), "stiffness_bounds");
        assert_eq!(name(ConsistentOptions { length_scale: 0.0, ..con() }.validate()), "length_scale");
    }

    #[test]
    fn the_message_says_what_is_expected() {
        let e = ConsistentOptions { pull: -1.0, ..Default::default() }.validate().unwrap_err();
        assert_eq!(
            e.to_string(),
            "pull = -1 cannot be used: expected a non-negative number (0 disables the pull toward CAD)"
        );
    }
}
