//! The three control laws. Each owns a copy of the model, a [`Data`] workspace and its scratch
//! buffers, so `step` never allocates.

use super::feedforward::EffectFeedforward;
use super::gains::{compensation_epsilon, IdcGains, PdGains, RobustGains};
use super::{Controller, ControllerKind, Desired};
use crate::data::Data;
use crate::dynamics::{gravity_torque, inverse_dynamics};
use crate::effects::EffectTerm;
use crate::model::Model;
use crate::regressor::slotine_li_regressor;

fn check_lengths(model: &Model, params: &[f64], gains: &[&[f64]]) {
    crate::dynamics::check_params(model, params);
    for g in gains {
        assert_eq!(g.len(), model.dof(), "a gain vector has {} entries, the robot has {} joints", g.len(), model.dof());
    }
}

/// PD with gravity compensation: `τ = g(q; π) − K_p (q − q_d) − K_d (q̇ − q̇_d)`.
pub struct PdGravity {
    model: Model,
    data: Data,
    params: Vec<f64>,
    gains: PdGains,
}

impl PdGravity {
    pub fn new(model: &Model, params: &[f64], gains: PdGains) -> Self {
        check_lengths(model, params, &[&gains.kp, &gains.kd]);
        Self { model: model.clone(), data: Data::new(model), params: params.to_vec(), gains }
    }
}

impl Controller for PdGravity {
    fn kind(&self) -> ControllerKind {
        ControllerKind::Pd
    }

    fn reset(&mut self) {}

    fn step(&mut self, _dt: f64, q: &[f64], qd: &[f64], desired: &Desired, tau: &mut [f64]) {
        gravity_torque(&self.model, &mut self.data, q, &self.params, tau);
        for k in 0..self.model.dof() {
            tau[k] -= self.gains.kp[k] * (q[k] - desired.q[k]) + self.gains.kd[k] * (qd[k] - desired.qd[k]);
        }
    }
}

/// Inverse dynamics (computed torque) control with a fixed parameter set — the paper's baseline
/// with the CAD values: `τ = ID(q, q̇, q̈_d − K_d ė − K_p e; π)`.
pub struct InverseDynamicsControl {
    model: Model,
    data: Data,
    params: Vec<f64>,
    gains: IdcGains,
    acc: Vec<f64>,
    effects: EffectFeedforward,
}

impl InverseDynamicsControl {
    pub fn new(model: &Model, params: &[f64], mut gains: IdcGains) -> Self {
        check_lengths(model, params, &[&gains.kp, &gains.kd, &gains.epsilon]);
        gains.epsilon = compensation_epsilon(model, &gains.epsilon);
        let acc = vec![0.0; model.dof()];
        let effects = EffectFeedforward::default();
        Self { model: model.clone(), data: Data::new(model), params: params.to_vec(), gains, acc, effects }
    }

    /// Compensate the effects a diagnosis added to the model, too (see [`EffectFeedforward`]).
    pub fn with_effects(mut self, effects: &[EffectTerm]) -> Self {
        self.effects = EffectFeedforward::new(&self.model, effects, &self.gains.epsilon, &mut self.params);
        self
    }
}

impl Controller for InverseDynamicsControl {
    fn kind(&self) -> ControllerKind {
        ControllerKind::Idc
    }

    fn reset(&mut self) {
        self.effects.reset();
    }

    fn step(&mut self, _dt: f64, q: &[f64], qd: &[f64], desired: &Desired, tau: &mut [f64]) {
        for k in 0..self.model.dof() {
            self.acc[k] =
                desired.qdd[k] - self.gains.kd[k] * (qd[k] - desired.qd[k]) - self.gains.kp[k] * (q[k] - desired.q[k]);
        }
        inverse_dynamics(&self.model, &mut self.data, q, qd, &self.acc, &self.params, tau);
        let layout = self.model.layout();
        for k in 0..self.model.dof() {
            let fc = self.params[layout.coulomb(k)];
            tau[k] += fc * ((qd[k] / self.gains.epsilon[k]).tanh() - self.model.coulomb_laws.eval(k, qd[k]));
        }
        self.effects.add(q, qd, &self.acc, tau);
    }
}

/// The paper's robust model-based controller (eq. 22):
///
/// `τ = Y_S(q, q̇, q̇_r, q̈_r) β̂ − K_d s`, with `e = q − q_d`, `s = ė + Λe`,
/// `q̇_r = q̇_d − Λe`, `q̈_r = q̈_d − Λė`, and `tanh(q̇/ε)` in place of `sign(q̇)` in the Coulomb
/// terms.
///
/// `β̂` enters as any full parameter vector whose product with the regressor equals `Y_S,b β̂`:
/// the identified `π̂`, or `β̂` placed on the independent columns
/// ([`crate::model_file::ModelFile::full_or_base_vector`]).
pub struct RobustController {
    model: Model,
    data: Data,
    params: Vec<f64>,
    gains: RobustGains,
    qd_r: Vec<f64>,
    qdd_r: Vec<f64>,
    s: Vec<f64>,
    y: Vec<f64>,
    effects: EffectFeedforward,
}

impl RobustController {
    pub fn new(model: &Model, params: &[f64], mut gains: RobustGains) -> Self {
        check_lengths(model, params, &[&gains.kd, &gains.lambda, &gains.epsilon]);
        gains.epsilon = compensation_epsilon(model, &gains.epsilon);
        let n = model.dof();
        Self {
            model: model.clone(),
            data: Data::new(model),
            params: params.to_vec(),
            gains,
            qd_r: vec![0.0; n],
            qdd_r: vec![0.0; n],
            s: vec![0.0; n],
            y: vec![0.0; n * model.num_params()],
            effects: EffectFeedforward::default(),
        }
    }

    /// Compensate the effects a diagnosis added to the model, too (see [`EffectFeedforward`]).
    /// Their accelerations are the reference's, `q̈_r`, as in the Slotine–Li regressor.
    pub fn with_effects(mut self, effects: &[EffectTerm]) -> Self {
        self.effects = EffectFeedforward::new(&self.model, effects, &self.gains.epsilon, &mut self.params);
        self
    }

    /// The sliding variable `s = ė + Λe` of the last step.
    pub fn sliding_variable(&self) -> &[f64] {
        &self.s
    }
}

impl Controller for RobustController {
    fn kind(&self) -> ControllerKind {
        ControllerKind::Robust
    }

    fn reset(&mut self) {
        self.effects.reset();
    }

    fn step(&mut self, _dt: f64, q: &[f64], qd: &[f64], desired: &Desired, tau: &mut [f64]) {
        let (n, big_p) = (self.model.dof(), self.model.num_params());
        let g = &self.gains;
        for k in 0..n {
            let (e, ed) = (q[k] - desired.q[k], qd[k] - desired.qd[k]);
            self.qd_r[k] = desired.qd[k] - g.lambda[k] * e;
            self.qdd_r[k] = desired.qdd[k] - g.lambda[k] * ed;
            self.s[k] = ed + g.lambda[k] * e;
        }
        slotine_li_regressor(&self.model, &mut self.data, q, qd, &self.qd_r, &self.qdd_r, &mut self.y);
        let layout = self.model.layout();
        for k in 0..n {
            let row = &mut self.y[k * big_p..(k + 1) * big_p];
            // Joint k's Coulomb column is non-zero in row k only; the per-joint ε goes here.
            row[layout.coulomb(k)] = (qd[k] / g.epsilon[k]).tanh();
            tau[k] = row.iter().zip(&self.params).map(|(y, p)| y * p).sum::<f64>() - g.kd[k] * self.s[k];
        }
        self.effects.add(desired.q, desired.qd, &self.qdd_r, tau);
    }
}
