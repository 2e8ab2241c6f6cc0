//! The drive gains' share of an effect's σ, when the torque was computed from motor currents with
//! gains calibrated by a known load (`arash identify --load`, the drive-gain fit).
//!
//! A gain k̂ⱼ that is off by εⱼ = dkⱼ/kⱼ scales joint j's measured torque by 1 + εⱼ. The given
//! model was fitted on torque computed with the same gains, so its held parameters moved with them
//! by `∂β/∂ln kⱼ` ([`crate::model_file::DriveGains::beta_per_gain`]). What the diagnosis's fit
//! sees of εⱼ is the rest: the target changes by `εⱼ (τ⁽ʲ⁾ − Y_held ∂β_held/∂ln kⱼ)`, with `τ⁽ʲ⁾`
//! joint j's torque alone. Each fitted coefficient moves by its least squares on that, and its
//! variance from the gains is `D Σ_ε Dᵀ`, Σ_ε the gains' relative covariance. A payload found in
//! kilograms is then as uncertain as the gains that weighed it, and a common error of every gain
//! moves its mass by the same share.

use faer::Mat;

use super::inputs::Context;
use super::regression::{axpy, gram, rhs, solve_scaled, Column, Rows};
use super::weighted_fit::Problem;
use crate::dense;

/// Per joint, the change of the weighted target per unit relative error of its gain, and the
/// gains' relative covariance.
pub(super) struct GainErrors {
    targets: Vec<Vec<f64>>,
    covariance: Mat<f64>,
}

impl GainErrors {
    /// The gains' errors on `problem`, when its torque was computed from currents with a given
    /// model's calibrated gains; `None` otherwise.
    pub(super) fn of(ctx: &Context, problem: &Problem) -> Option<Self> {
        if !ctx.options.torque_from_currents {
            return None;
        }
        let g = ctx.given?.drive_gains.as_ref()?;
        let dof = problem.dof;
        let relative = |i: usize, j: usize| {
            let c = match g.covariance.is_empty() {
                true if i == j => g.sigma[i] * g.sigma[i],
                true => 0.0,
                false => g.covariance[i * dof + j],
            };
            c / (g.gains[i] * g.gains[j])
        };
        let covariance = Mat::from_fn(dof, dof, relative);
        let targets = (0..dof)
            .map(|j| {
                let mut v = vec![0.0; problem.tau.len()];
                for (i, t) in problem.tau.iter().enumerate().skip(j).step_by(dof) {
                    v[i] = t * problem.weights[j];
                }
                // The held columns are the model's; a refitted model takes up the scale itself.
                if let (false, Some(per)) = (ctx.refit, g.beta_per_gain.get(j)) {
                    let held = problem.declared.iter().zip(&problem.free).zip(per).filter(|((_, f), _)| !**f);
                    for ((column, _), d) in held {
                        axpy(&mut v, -d, column, dof);
                    }
                }
                v
            })
            .collect();
        Some(Self { targets, covariance })
    }

    /// The gains' errors as directions of the target, `Σⱼ Lⱼₑ targetⱼ` for each column `e` of
    /// `L Lᵀ = Σ_ε` (`diagnose/calibration_error.rs`).
    pub(super) fn directions(&self) -> Vec<Vec<f64>> {
        let rows = self.targets.first().map_or(0, Vec::len);
        let combine = |l: Vec<f64>| {
            let mut v = vec![0.0; rows];
            self.targets.iter().zip(&l).for_each(|(t, w)| dense::axpy(&mut v, *w, t));
            v
        };
        dense::psd_factor(&self.covariance).into_iter().map(combine).collect()
    }

    /// The σ the gains' errors give each coefficient of the least squares on `columns`.
    pub(super) fn sigma(&self, columns: &[&Column], dof: usize) -> Option<Vec<f64>> {
        if columns.is_empty() {
            return Some(vec![]);
        }
        let g = gram(columns, dof, Rows::All);
        let moves: Vec<Vec<f64>> =
            self.targets.iter().map(|v| solve_scaled(&g, &rhs(columns, v, dof, Rows::All))).collect::<Option<_>>()?;
        let d = Mat::from_fn(columns.len(), moves.len(), |c, j| moves[j][c]);
        let variance = &d * &self.covariance * d.transpose();
        Some(dense::standard_deviations(variance.as_ref()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One joint, the target `y = k̂ i = (1 + ε) m g` fitted on the column `g`: the mass comes
    /// out `(1 + ε) m`, so its σ from the gain is `m σ_ε` exactly.
    #[test]
    fn a_mass_fitted_on_one_joint_is_as_uncertain_as_its_gain() {
        let (m, sigma_rel) = (2.0, 0.03);
        let g: Vec<f64> = (0..50).map(|s| (0.1 * s as f64).sin() + 0.2).collect();
        let tau: Vec<f64> = g.iter().map(|x| m * x).collect();
        let errors = GainErrors { targets: vec![tau], covariance: Mat::from_fn(1, 1, |_, _| sigma_rel * sigma_rel) };
        let column = Column::dense(g, 1);
        let sigma = errors.sigma(&[&column], 1).unwrap();
        assert!((sigma[0] - m * sigma_rel).abs() < 1e-12, "{sigma:?}");
    }
}
