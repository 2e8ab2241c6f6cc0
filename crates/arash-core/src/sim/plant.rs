//! The true robot as a continuous-time system, integrated with a fixed step.
//!
//! State `x = [q, q̇]`, or `[q, q̇, θ, θ̇]` with cable compliance (θ: motor position in joint
//! units). The torque the motors apply is held constant over a control cycle (zero-order hold).
//!
//! Rigid drive: `(M + J_a) q̈ = τ_m − h(q, q̇; π) − τ_x(q, q̇) − τ_cog(q)`.
//! Compliant drive: `M q̈ = τ_s − h − τ_x`, `J_m θ̈ = τ_m − τ_s − τ_cog(θ)`,
//! `τ_s = k (θ − q) + c (θ̇ − q̇)`.
//! `h` holds gravity, velocity products, the declared friction (with the drift factor) and the
//! cable stiffness; `τ_x` the undeclared joint-side effects (Stribeck, asymmetric Coulomb,
//! configuration disturbance). A scenario's hand adds `J_vᵀ F_hand` on the joint side, with the
//! force held over the cycle like the motor torque and the Jacobian at each step's `q`.

use super::hand::HandForce;
use super::scenario::{Integrator, Scenario};
use super::truth::{add_payload, true_parameters};
use crate::data::Data;
use crate::dynamics::{forward_dynamics_with_armature, kinetic_energy, potential_energy, DynamicsError, Parameters};
use crate::model::{CoulombLaws, CoulombShape, Model};

/// The simulated robot: true parameters, undeclared effects and the integrator state.
pub struct Plant {
    model: Model,
    data: Data,
    scenario: Scenario,
    /// True parameters now (drift and payload applied).
    params: Vec<f64>,
    /// Declared friction `[fv, fc]` per joint before drift.
    friction: Vec<f64>,
    drift_scale: f64,
    /// Dahl state per joint (hysteresis effect), in [−1, 1].
    dahl: Vec<f64>,
    q_before: Vec<f64>,
    payload_body: Option<usize>,
    payload_attached: bool,
    armature: Option<Vec<f64>>,
    hand: Option<HandForce>,
    /// The hand's scheduled force over the present cycle (base frame, N), the whole force
    /// (with a grasp's mean over the cycle) and its joint torque at the cycle's start.
    hand_scheduled: [f64; 3],
    hand_force: [f64; 3],
    hand_torque: Vec<f64>,
    time: f64,
    x: Vec<f64>,
    // Integrator scratch.
    k: [Vec<f64>; 4],
    tmp: Vec<f64>,
    tau_joint: Vec<f64>,
    acc: Vec<f64>,
    acc_at_cycle_start: Vec<f64>,
}

/// Why the plant cannot be built or stepped.
#[derive(Debug, thiserror::Error)]
pub enum PlantError {
    #[error(transparent)]
    Scenario(#[from] super::scenario::ScenarioError),
    #[error("payload body `{0}` is not a body of the robot (bodies: {1})")]
    PayloadBody(String, String),
    #[error("the simulation diverged at t = {time:.4} s: {source}")]
    Dynamics { time: f64, source: DynamicsError },
    #[error("the simulation diverged at t = {0:.4} s: the state is no longer finite")]
    NonFinite(f64),
    #[error("scenario field `hand.frame`: {0}")]
    HandFrame(#[from] crate::model::UnknownFrame),
    #[error("{0}")]
    Parameters(String),
    #[error(transparent)]
    Trajectory(#[from] crate::control::TrajectoryError),
}

impl Plant {
    /// The plant for `model` (the CAD description) under `scenario`, at rest at `q0`.
    pub fn new(model: &Model, scenario: &Scenario) -> Result<Self, PlantError> {
        scenario.validate(model.dof())?;
        let n = model.dof();
        let mut truth_model = model.clone();
        truth_model.coulomb_laws =
            CoulombLaws::uniform(CoulombShape::Tanh { epsilon: scenario.truth.coulomb_epsilon }, n);
        let params = true_parameters(model, scenario);
        let payload_body = match &scenario.effects.payload {
            Some(p) => Some(model.bodies.iter().position(|b| b.name == p.body).ok_or_else(|| {
                let names: Vec<&str> = model.bodies.iter().map(|b| b.name.as_str()).collect();
                PlantError::PayloadBody(p.body.clone(), names.join(", "))
            })?),
            None => None,
        };
        let states = if scenario.effects.compliance.is_some() { 4 * n } else { 2 * n };
        let hand = scenario.hand.as_ref().map(|h| HandForce::new(model, h, scenario.seed)).transpose()?;
        Ok(Self {
            data: Data::new(&truth_model),
            model: truth_model,
            friction: params[model.layout().friction()].to_vec(),
            params,
            scenario: scenario.clone(),
            drift_scale: 1.0,
            payload_body,
            payload_attached: false,
            armature: scenario.effects.armature.as_ref().map(|a| a.inertia.clone()),
            hand,
            hand_scheduled: [0.0; 3],
            hand_force: [0.0; 3],
            hand_torque: vec![0.0; n],
            time: 0.0,
            x: vec![0.0; states],
            k: std::array::from_fn(|_| vec![0.0; states]),
            tmp: vec![0.0; states],
            tau_joint: vec![0.0; n],
            acc: vec![0.0; n],
            acc_at_cycle_start: vec![0.0; n],
            dahl: vec![0.0; n],
            q_before: vec![0.0; n],
        })
    }

    /// The truth model (the CAD geometry with the plant's `tanh` Coulomb law).
    pub fn model(&self) -> &Model {
        &self.model
    }

    /// The true parameter vector at the current time.
    pub fn params(&self) -> &[f64] {
        &self.params
    }

    pub fn time(&self) -> f64 {
        self.time
    }

    pub fn q(&self) -> &[f64] {
        &self.x[..self.model.dof()]
    }

    pub fn qd(&self) -> &[f64] {
        let n = self.model.dof();
        &self.x[n..2 * n]
    }

    /// Joint acceleration at the start of the last control cycle, with that cycle's torque.
    pub fn qdd(&self) -> &[f64] {
        &self.acc_at_cycle_start
    }

    /// Motor position in joint units: θ with compliance, q otherwise.
    pub fn motor_position(&self) -> &[f64] {
        let n = self.model.dof();
        if self.compliant() {
            &self.x[2 * n..3 * n]
        } else {
            &self.x[..n]
        }
    }

    /// Motor velocity in joint units: θ̇ with compliance, q̇ otherwise.
    pub fn motor_velocity(&self) -> &[f64] {
        let n = self.model.dof();
        if self.compliant() {
            &self.x[3 * n..]
        } else {
            &self.x[n..2 * n]
        }
    }

    /// The hand's force over the last cycle (base frame, N; zero without a hand): its
    /// scheduled force, and a grasp's mean over the cycle.
    pub fn hand_force(&self) -> &[f64; 3] {
        &self.hand_force
    }

    /// The hand's joint torque at the start of the last cycle (N·m or N).
    pub fn hand_torque(&self) -> &[f64] {
        &self.hand_torque
    }

    fn compliant(&self) -> bool {
        self.scenario.effects.compliance.is_some()
    }

    /// Place the robot at `q` moving at `qd`. With compliance, the motor starts ahead of the
    /// joint by the cable stretch that holds `tau_hold` (e.g. the inverse dynamics at the start),
    /// so the run does not begin with a resonance.
    pub fn reset(&mut self, q: &[f64], qd: &[f64], tau_hold: &[f64]) {
        let n = self.model.dof();
        self.x[..n].copy_from_slice(q);
        self.x[n..2 * n].copy_from_slice(qd);
        if let Some(c) = &self.scenario.effects.compliance {
            for k in 0..n {
                self.x[2 * n + k] = q[k] + tau_hold[k] / c.stiffness[k];
                self.x[3 * n + k] = qd[k];
            }
        }
        self.time = 0.0;
        self.set_time(0.0);
    }

    /// Apply the slow, time-dependent effects (friction drift, payload) for time `t`.
    fn set_time(&mut self, t: f64) {
        if let Some(d) = &self.scenario.effects.friction_drift {
            self.drift_scale = 1.0 + d.amplitude * (1.0 - (-t / d.time_constant_s).exp());
            for (p, f) in self.params[self.model.layout().friction()].iter_mut().zip(&self.friction) {
                *p = f * self.drift_scale;
            }
        }
        if let (Some(p), Some(b)) = (&self.scenario.effects.payload, self.payload_body) {
            if !self.payload_attached && t >= p.at_s {
                add_payload(&mut self.params, b, p.mass, &p.position);
                self.payload_attached = true;
            }
        }
    }

    /// Advance one control cycle of `dt` seconds in `substeps` steps with the motor torque `tau`.
    pub fn advance(&mut self, dt: f64, tau: &[f64]) -> Result<(), PlantError> {
        self.set_time(self.time);
        self.set_hand();
        let substeps = self.scenario.physics.substeps;
        let h = dt / substeps as f64;
        for i in 0..substeps {
            let n = self.model.dof();
            self.q_before.copy_from_slice(&self.x[..n]);
            match self.scenario.physics.integrator {
                Integrator::SemiImplicitEuler => self.semi_implicit_euler(h, tau)?,
                Integrator::Rk4 => self.rk4(h, tau)?,
            }
            let before = std::mem::take(&mut self.q_before);
            self.update_dahl(&before);
            self.q_before = before;
            if i == 0 {
                self.acc_at_cycle_start.copy_from_slice(&self.k[0][n..2 * n]);
            }
        }
        self.time += dt;
        if let Some(hand) = &self.hand {
            let grasp = hand.grasp_force();
            self.hand_force = std::array::from_fn(|i| self.hand_scheduled[i] + grasp[i]);
        }
        if self.x.iter().any(|v| !v.is_finite()) {
            return Err(PlantError::NonFinite(self.time));
        }
        Ok(())
    }

    fn semi_implicit_euler(&mut self, h: f64, tau: &[f64]) -> Result<(), PlantError> {
        let mut k0 = std::mem::take(&mut self.k[0]);
        let x = std::mem::take(&mut self.x);
        let result = self.derivative(&x, tau, &mut k0);
        self.x = x;
        self.k[0] = k0;
        result?;
        let n = self.model.dof();
        // Velocities first (blocks 1 and 3), then positions with the new velocities.
        for block in (0..self.x.len() / n).step_by(2) {
            for j in 0..n {
                let (p, v) = (block * n + j, (block + 1) * n + j);
                self.x[v] += h * self.k[0][v];
                self.x[p] += h * self.x[v];
            }
        }
        Ok(())
    }

    fn rk4(&mut self, h: f64, tau: &[f64]) -> Result<(), PlantError> {
        let x0 = std::mem::take(&mut self.x);
        let mut tmp = std::mem::take(&mut self.tmp);
        let mut ks = std::mem::replace(&mut self.k, std::array::from_fn(|_| Vec::new()));
        let mut result = Ok(());
        for stage in 0..4 {
            let c = [0.0, 0.5, 0.5, 1.0][stage];
            for i in 0..x0.len() {
                tmp[i] = if stage == 0 { x0[i] } else { x0[i] + c * h * ks[stage - 1][i] };
            }
            if let Err(e) = self.derivative(&tmp, tau, &mut ks[stage]) {
                result = Err(e);
                break;
            }
        }
        self.x = x0;
        if result.is_ok() {
            for (i, x) in self.x.iter_mut().enumerate() {
                *x += h / 6.0 * (ks[0][i] + 2.0 * ks[1][i] + 2.0 * ks[2][i] + ks[3][i]);
            }
        }
        self.k = ks;
        self.tmp = tmp;
        result
    }

    /// The hand's force for the cycle starting now, and its torque at the present `q`.
    fn set_hand(&mut self) {
        let n = self.model.dof();
        self.hand_torque.fill(0.0);
        let Some(hand) = &mut self.hand else { return };
        hand.start_cycle(&self.model, self.time, &self.x[..n]);
        self.hand_scheduled = hand.force(self.time);
        let (q, qd) = self.x[..2 * n].split_at(n);
        hand.add_torque_moving(&self.model, q, qd, &self.hand_scheduled, &mut self.hand_torque);
    }

    /// `ẋ = f(x, τ_m)`.
    fn derivative(&mut self, x: &[f64], tau: &[f64], dx: &mut [f64]) -> Result<(), PlantError> {
        let n = self.model.dof();
        let (q, qd) = (&x[..n], &x[n..2 * n]);
        for k in 0..n {
            self.tau_joint[k] = -self.joint_side_effects(k, q[k], qd[k]);
        }
        if let Some(hand) = &mut self.hand {
            hand.add_torque_moving(&self.model, q, qd, &self.hand_scheduled, &mut self.tau_joint);
        }
        match &self.scenario.effects.compliance {
            None => {
                for k in 0..n {
                    self.tau_joint[k] += tau[k] - self.cogging(k, q[k]);
                }
            }
            Some(c) => {
                let (theta, thetad) = (&x[2 * n..3 * n], &x[3 * n..]);
                for k in 0..n {
                    let spring = c.stiffness[k] * (theta[k] - q[k]) + c.damping[k] * (thetad[k] - qd[k]);
                    self.tau_joint[k] += spring;
                    dx[2 * n + k] = thetad[k];
                    dx[3 * n + k] = (tau[k] - spring - self.cogging(k, theta[k])) / c.motor_inertia[k];
                }
            }
        }
        let parameters = Parameters { params: &self.params, armature: self.armature.as_deref() };
        forward_dynamics_with_armature(&self.model, &mut self.data, q, qd, &self.tau_joint, parameters, &mut self.acc)
            .map_err(|source| PlantError::Dynamics { time: self.time, source })?;
        dx[..n].copy_from_slice(qd);
        dx[n..2 * n].copy_from_slice(&self.acc);
        Ok(())
    }

    /// Stribeck, asymmetric Coulomb and configuration-dependent torque on joint `k` (resisting:
    /// the motor must supply it).
    fn joint_side_effects(&self, k: usize, q: f64, qd: f64) -> f64 {
        let e = &self.scenario.effects;
        let direction = (qd / self.scenario.truth.coulomb_epsilon).tanh();
        let mut tau = 0.0;
        if let Some(s) = &e.stribeck {
            tau += self.drift_scale * s.static_excess[k] * (-(qd / s.velocity_scale[k]).powi(2)).exp() * direction;
        }
        if let Some(a) = &e.coulomb_asymmetry {
            tau += a.delta[k] * direction.abs();
        }
        if let Some(d) = &e.configuration_disturbance {
            tau += d.amplitude[k] * (2.0 * std::f64::consts::PI * q / d.period[k] + d.phase[k]).sin();
        }
        if let Some(v) = &e.viscous_nonlinear {
            tau += v.coefficient[k] * qd * qd.abs();
        }
        if let Some(p) = &e.position_friction {
            let joint = &self.model.joints[k];
            let x = (2.0 * q - joint.upper - joint.lower) / (joint.upper - joint.lower);
            tau += p.amplitude[k] * x * direction;
        }
        if let Some(h) = &e.hysteresis {
            tau += h.amplitude[k] * self.dahl[k];
        }
        tau
    }

    /// Advance the Dahl state of every joint over a step that moved the joints from `before`.
    fn update_dahl(&mut self, before: &[f64]) {
        let Some(h) = &self.scenario.effects.hysteresis else { return };
        for (k, z) in self.dahl.iter_mut().enumerate() {
            let dq = self.x[k] - before[k];
            if dq != 0.0 {
                let target = dq.signum();
                *z = target + (*z - target) * (-dq.abs() / h.travel[k]).exp();
            }
        }
    }

    /// Cogging torque at motor position `position` (joint units) of joint `k`.
    fn cogging(&self, k: usize, position: f64) -> f64 {
        match &self.scenario.effects.cogging {
            Some(c) => {
                let motor_angle = position / self.scenario.sensors.transmission[k];
                c.amplitude[k] * (c.periods_per_rev[k] * motor_angle + c.phase[k]).sin()
            }
            None => 0.0,
        }
    }

    /// Mechanical energy: kinetic (links, armature, motors), gravitational, cable stiffness and
    /// compliance springs (J). Conserved when friction and input are off.
    pub fn energy(&mut self) -> f64 {
        let n = self.model.dof();
        let x = self.x.clone();
        let (q, qd) = (&x[..n], &x[n..2 * n]);
        let mut e = kinetic_energy(&self.model, &mut self.data, q, qd, &self.params)
            + potential_energy(&self.model, &mut self.data, q, &self.params);
        let at = self.model.layout();
        for k in 0..n {
            e += 0.5 * self.params[at.stiffness(k)] * q[k] * q[k];
            if let Some(a) = &self.armature {
                e += 0.5 * a[k] * qd[k] * qd[k];
            }
            if let Some(c) = &self.scenario.effects.compliance {
                let (th, thd) = (x[2 * n + k], x[3 * n + k]);
                e += 0.5 * c.stiffness[k] * (th - q[k]).powi(2) + 0.5 * c.motor_inertia[k] * thd * thd;
            }
        }
        e
    }
}
