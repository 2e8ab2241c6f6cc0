//! The haptic mode's command, one law for the daemon and the simulated rig: the model's
//! compensation at the measured state with no motion asked of it, and the fixtures' torque.
//!
//! The compensation is gravity, the cables' stiffness, each joint's Coulomb friction with the
//! smooth law `tanh(q̇/ε)` (a sign of an encoder's velocity would chatter at rest by the whole
//! friction), the effects' forces (the wiring disturbance, Stribeck friction, whatever the
//! diagnosis added), and a share of the viscous friction: what is left uncompensated is the
//! damping that renders the fixtures passively ([`super::passivity`]). Drive gains scale the sum,
//! as the drives are commanded. Inertia is not fed forward: the hand moves the arm, and an
//! acceleration differenced from encoders at 1 kHz is noise.

use super::fixtures::{FixtureError, Fixtures};
use super::render::{FixtureRenderer, RenderError, Rendered};
use crate::control::feedforward::EffectFeedforward;
use crate::control::{Controller, ControllerKind, Desired};
use crate::data::Data;
use crate::dynamics::gravity_torque;
use crate::effects::EffectTerm;
use crate::model::Model;

/// The law, built once; [`Self::command`] does not allocate.
#[derive(Clone, Debug)]
pub struct HapticLaw {
    model: Model,
    data: Data,
    params: Vec<f64>,
    effects: EffectFeedforward,
    epsilon: Vec<f64>,
    viscous: f64,
    renderer: FixtureRenderer,
    forces: Vec<f64>,
    scratch: Vec<f64>,
}

impl HapticLaw {
    /// The law on `model` with parameters `params` and `effects`, Coulomb widths `epsilon` per
    /// joint, the share `viscous_compensation` of the viscous friction compensated, rendering
    /// `fixtures` (checked by field here; their passivity is [`super::check_passivity`]'s).
    pub fn new(
        model: &Model,
        params: &[f64],
        effects: &[EffectTerm],
        epsilon: &[f64],
        viscous_compensation: f64,
        fixtures: &Fixtures,
    ) -> Result<Self, FixtureError> {
        let n = model.dof();
        if params.len() != model.num_params() || epsilon.len() != n {
            return Err(FixtureError::Loop(format!(
                "the haptic law needs {} parameters and {n} friction widths, not {} and {}",
                model.num_params(),
                params.len(),
                epsilon.len()
            )));
        }
        if let Some(e) = epsilon.iter().find(|e| !(e.is_finite() && **e > 0.0)) {
            return Err(FixtureError::Loop(format!("a Coulomb width ε is {e}; it must be positive")));
        }
        if !(0.0..=1.0).contains(&viscous_compensation) {
            return Err(FixtureError::Loop(format!(
                "the viscous friction's compensated share is {viscous_compensation}, not in [0, 1]"
            )));
        }
        let mut params = params.to_vec();
        let effects = EffectFeedforward::new(model, effects, epsilon, &mut params);
        Ok(Self {
            model: model.clone(),
            data: Data::new(model),
            params,
            effects,
            epsilon: epsilon.to_vec(),
            viscous: viscous_compensation,
            renderer: FixtureRenderer::new(model, fixtures)?,
            forces: vec![0.0; n],
            scratch: vec![0.0; n],
        })
    }

    /// The command at state `q`, `qd` into `tau`. A non-finite state, or a fixture that renders
    /// a non-number, is refused and leaves `tau` as it was.
    pub fn command(&mut self, q: &[f64], qd: &[f64], tau: &mut [f64]) -> Result<Rendered, RenderError> {
        let mut out = std::mem::take(&mut self.scratch);
        self.compensation(q, qd, &mut out);
        let rendered = self.renderer.add_torque(q, qd, &mut out);
        if rendered.is_ok() {
            tau[..out.len()].copy_from_slice(&out);
        }
        self.scratch = out;
        rendered
    }

    /// The compensation alone at `q`, `qd` (finite) into `out`.
    pub fn compensation(&mut self, q: &[f64], qd: &[f64], out: &mut [f64]) {
        let layout = self.model.layout();
        gravity_torque(&self.model, &mut self.data, q, &self.params, out);
        self.forces.fill(0.0);
        self.effects.add_forces(q, qd, &mut self.forces);
        for (k, o) in out.iter_mut().enumerate() {
            let friction = self.viscous * self.params[layout.viscous(k)] * qd[k]
                + self.params[layout.coulomb(k)] * (qd[k] / self.epsilon[k]).tanh()
                + self.params[layout.stiffness(k)] * q[k];
            *o = (*o + friction + self.forces[k]) * self.effects.drive_gain(k);
        }
    }
}

/// The law as a controller of the simulated rig: the reference is ignored, the hand moves the
/// arm. A state the fixtures refuse commands zero torque.
impl Controller for HapticLaw {
    fn kind(&self) -> ControllerKind {
        ControllerKind::Haptic
    }

    fn reset(&mut self) {
        self.effects.reset();
    }

    fn step(&mut self, _dt: f64, q: &[f64], qd: &[f64], _desired: &Desired, tau: &mut [f64]) {
        if self.command(q, qd, tau).is_err() {
            tau.fill(f64::NAN);
        }
    }
}
