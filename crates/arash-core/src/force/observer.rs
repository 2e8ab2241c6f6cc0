//! The generalized momentum observer (De Luca and Mattone 2003; Haddadin, De Luca and
//! Albu-Schäffer, IEEE T-RO 33(6), 2017): the external joint torque from the model, the joint
//! state and the applied torque, with no acceleration and no inverse of `M`.
//!
//! The robot's momentum `p = M(q) q̇` obeys `ṗ = τ + τ_ext + Cᵀ(q, q̇) q̇ − g(q) − f(q, q̇)`
//! (since `Ṁ = C + Cᵀ`), so the difference between the momentum's change and what the model
//! explains is the external torque. Filtered at a bandwidth `K` per joint, the estimate `r`
//! obeys `ṙ = K (τ_ext − r)`: a first-order low-pass of the true external torque, plus the
//! model's own error through the same filter.
//!
//! In discrete time the momentum's change over a cycle is compared with the trapezoid of the
//! model's torques at both ends, which is exact to second order in the cycle time, and with the
//! applied torque as it acted over the cycle ([`TorqueTiming`]). The filter is the exact step of
//! the first-order lag, stable at any bandwidth.

use crate::control::EffectFeedforward;
use crate::data::Data;
use crate::dynamics::{momentum_terms, MomentumTerms};
use crate::effects::{first_unphysical, EffectTerm, Unphysical};
use crate::model::Model;

/// Why an observer could not be built, or a sample not taken.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ObserverError {
    #[error("{what} has {got} entries; the robot has {dof} joints")]
    Length { what: &'static str, got: usize, dof: usize },
    #[error("π has {got} entries; the robot's model has {needed} parameters")]
    Params { got: usize, needed: usize },
    #[error("the observer's bandwidth on joint {joint} is {value} Hz; it must be positive and finite")]
    Bandwidth { joint: usize, value: f64 },
    #[error("the Coulomb switching velocity on joint {joint} is {value}; it must be positive and finite")]
    Epsilon { joint: usize, value: f64 },
    #[error("the observer was given a cycle of {0} s; it must be positive and finite")]
    Step(f64),
    #[error("{what} on joint {joint} is not a number ({value})")]
    NotFinite { what: &'static str, joint: usize, value: f64 },
    #[error(
        "the model's effect {label} has coefficient {index} = {value:e}, which {why}: the observer would \
         read the torque through it wrongly. Refit it or remove it from the model file"
    )]
    UnphysicalEffect { label: String, index: usize, value: f64, why: &'static str },
}

/// How a logged torque acted between its sample and the next.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TorqueTiming {
    /// A command, held from its sample until the next: a drive's torque command, the daemon's
    /// and the simulator's record. Half a cycle's change of the command per cycle would
    /// otherwise be read as a hand.
    Held,
    /// A measurement at its sample's instant (a torque sensor, a current read back), taken as
    /// varying linearly between samples.
    Sampled,
    /// A drive's report of the torque over the cycle that ended at its sample, beside the
    /// position at that sample: the daemon's telemetry, its cycle and its flight log. Taking it
    /// as held would read one cycle's change of the torque as a hand.
    Preceding,
}

/// The generalized momentum observer on one model, with its scratch, built once; [`Self::step`]
/// does not allocate.
#[derive(Clone, Debug)]
pub struct MomentumObserver {
    model: Model,
    data: Data,
    params: Vec<f64>,
    effects: EffectFeedforward,
    /// `K` per joint (1/s).
    gain: Vec<f64>,
    /// The Coulomb terms' `tanh(q̇/ε)` width per joint.
    epsilon: Vec<f64>,
    /// The estimate `r` of the external torque (N·m or N).
    estimate: Vec<f64>,
    timing: TorqueTiming,
    /// `p`, the applied torque `τ/(1 + g)` and the model's `Cᵀq̇ − g − f` at the previous
    /// sample, once there is one.
    momentum: Vec<f64>,
    applied: Vec<f64>,
    explained: Vec<f64>,
    primed: bool,
    /// The effects' constant inertia (rotors), dof × dof row-major.
    effect_inertia: Vec<f64>,
    coriolis_t: Vec<f64>,
    gravity: Vec<f64>,
    forces: Vec<f64>,
    friction: Vec<f64>,
    now_momentum: Vec<f64>,
    now_applied: Vec<f64>,
    now_explained: Vec<f64>,
}

impl MomentumObserver {
    /// An observer of `model` with parameters `params` and the effects a diagnosis added
    /// (payloads fold into `params`, as in the controllers), a bandwidth per joint in Hz, and
    /// the Coulomb terms' switching velocity per joint (the controllers' ε: a sign of a noisy
    /// velocity would make the estimate chatter by the whole Coulomb force at rest). `timing`
    /// says how the torque it is given acted between samples.
    pub fn new(
        model: &Model,
        params: &[f64],
        effects: &[EffectTerm],
        bandwidth_hz: &[f64],
        epsilon: &[f64],
        timing: TorqueTiming,
    ) -> Result<Self, ObserverError> {
        let n = model.dof();
        for (what, got) in [("the bandwidth", bandwidth_hz.len()), ("ε", epsilon.len())] {
            if got != n {
                return Err(ObserverError::Length { what, got, dof: n });
            }
        }
        if params.len() != model.num_params() {
            return Err(ObserverError::Params { got: params.len(), needed: model.num_params() });
        }
        if let Some((joint, &value)) = bandwidth_hz.iter().enumerate().find(|(_, b)| !(b.is_finite() && **b > 0.0)) {
            return Err(ObserverError::Bandwidth { joint, value });
        }
        if let Some((joint, &value)) = epsilon.iter().enumerate().find(|(_, e)| !(e.is_finite() && **e > 0.0)) {
            return Err(ObserverError::Epsilon { joint, value });
        }
        // The controllers' rule: a drive's factor 1 + g at or below zero would divide the logged
        // torque by nothing.
        if let Some(Unphysical { label, index, value, why }) = first_unphysical(effects, &model.joint_names()) {
            return Err(ObserverError::UnphysicalEffect { label, index, value, why });
        }
        let mut params = params.to_vec();
        let effects = EffectFeedforward::new(model, effects, epsilon, &mut params);
        let mut effect_inertia = vec![0.0; n * n];
        effects.add_inertia(&mut effect_inertia);
        let zeros = vec![0.0; n];
        Ok(Self {
            model: model.clone(),
            data: Data::new(model),
            params,
            effects,
            gain: bandwidth_hz.iter().map(|f| std::f64::consts::TAU * f).collect(),
            epsilon: epsilon.to_vec(),
            timing,
            estimate: zeros.clone(),
            momentum: zeros.clone(),
            applied: zeros.clone(),
            explained: zeros.clone(),
            primed: false,
            effect_inertia,
            coriolis_t: zeros.clone(),
            gravity: zeros.clone(),
            forces: zeros.clone(),
            friction: zeros.clone(),
            now_momentum: zeros.clone(),
            now_applied: zeros.clone(),
            now_explained: zeros,
        })
    }

    /// The estimated external joint torque (N·m or N) after the last step; zero until two
    /// samples have been seen.
    pub fn estimate(&self) -> &[f64] {
        &self.estimate
    }

    /// The torque to command for the model to carry the arm at the last sample's state, with
    /// no motion asked of it: gravity, friction, cable stiffness and the effects' forces, times
    /// the drive gain (as the drives are commanded). What the joints float under when a
    /// collision stops a run: a hand moves them against nothing but the model's error.
    pub fn compensation(&self, out: &mut [f64]) {
        for (k, o) in out.iter_mut().enumerate().take(self.model.dof()) {
            *o = (self.gravity[k] + self.friction[k] + self.forces[k]) * self.effects.drive_gain(k);
        }
    }

    /// Start again from the next sample (after a gap in the data, or when the motors are
    /// re-enabled): the estimate returns to zero.
    pub fn reset(&mut self) {
        self.primed = false;
        self.estimate.fill(0.0);
        self.effects.reset();
    }

    /// Take one sample `dt` seconds after the previous one: the joint state `q`, `q̇` and the
    /// torque `tau` the drives applied (as measured, before any drive gain the model knows).
    /// A non-finite input is refused by name and leaves the observer as it was.
    pub fn step(&mut self, dt: f64, q: &[f64], qd: &[f64], tau: &[f64]) -> Result<&[f64], ObserverError> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(ObserverError::Step(dt));
        }
        for (what, x) in [("the position", q), ("the velocity", qd), ("the torque", tau)] {
            if let Some((joint, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(ObserverError::NotFinite { what, joint, value });
            }
        }
        self.momentum_and_explained(q, qd, tau);
        if self.primed {
            for k in 0..self.model.dof() {
                let change = (self.now_momentum[k] - self.momentum[k]) / dt;
                let applied = match self.timing {
                    TorqueTiming::Held => self.applied[k],
                    TorqueTiming::Preceding => self.now_applied[k],
                    TorqueTiming::Sampled => 0.5 * (self.applied[k] + self.now_applied[k]),
                };
                let unexplained = change - applied - 0.5 * (self.now_explained[k] + self.explained[k]);
                let alpha = -(-self.gain[k] * dt).exp_m1();
                self.estimate[k] += alpha * (unexplained - self.estimate[k]);
            }
        }
        self.primed = true;
        self.momentum.copy_from_slice(&self.now_momentum);
        self.applied.copy_from_slice(&self.now_applied);
        self.explained.copy_from_slice(&self.now_explained);
        Ok(self.estimate.as_slice())
    }

    /// `p = (M + M_effects) q̇`, `τ/(1 + g)` and `Cᵀq̇ − g(q) − f(q, q̇)` at the sample, into
    /// the `now_` buffers.
    fn momentum_and_explained(&mut self, q: &[f64], qd: &[f64], tau: &[f64]) {
        let n = self.model.dof();
        let terms = MomentumTerms {
            momentum: &mut self.now_momentum,
            coriolis_t: &mut self.coriolis_t,
            gravity: &mut self.gravity,
        };
        momentum_terms(&self.model, &mut self.data, q, qd, &self.params, terms);
        self.forces.fill(0.0);
        self.effects.add_forces(q, qd, &mut self.forces);
        let layout = self.model.layout();
        for k in 0..n {
            let row = &self.effect_inertia[k * n..(k + 1) * n];
            self.now_momentum[k] += row.iter().zip(qd).map(|(m, v)| m * v).sum::<f64>();
            self.friction[k] = self.params[layout.viscous(k)] * qd[k]
                + self.params[layout.coulomb(k)] * (qd[k] / self.epsilon[k]).tanh()
                + self.params[layout.stiffness(k)] * q[k];
            self.now_applied[k] = tau[k] / self.effects.drive_gain(k);
            self.now_explained[k] = self.coriolis_t[k] - self.gravity[k] - self.friction[k] - self.forces[k];
        }
    }
}
