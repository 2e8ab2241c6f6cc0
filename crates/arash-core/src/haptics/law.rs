//! The haptic mode's command, one law for the daemon and the simulated rig: the model's
//! compensation at the measured state with no motion asked of it, and the fixtures' torque.
//!
//! The compensation is gravity, the cables' stiffness, each joint's Coulomb friction with the
//! smooth law `tanh(q̇/ε)` (a sign of an encoder's velocity would chatter at rest by the whole
//! friction), the effects' forces (the wiring disturbance, Stribeck friction, whatever the
//! diagnosis added), and a share of the viscous friction: what is left uncompensated is the
//! damping that renders the fixtures passively ([`super::passivity`]). Drive gains scale the sum,
//! as the drives are commanded.
//!
//! Optionally ([`HapticLaw::with_inertia`]) a share of the arm's inertial torque `M(q) q̈ + C q̇`
//! is fed forward, `q̈` differenced from the velocity and low-passed, so that the trainee feels a
//! lighter instrument. Off by default: along a trainee's path of a few millimetres a second it
//! buys little, and the filter the differenced velocity needs lags, which takes damping away
//! (docs/haptics.md, "Inertia").

use super::fixtures::{FixtureError, Fixtures};
use super::render::{FixtureRenderer, RenderError, Rendered};
use crate::control::feedforward::EffectFeedforward;
use crate::control::{Controller, ControllerKind, Desired};
use crate::data::Data;
use crate::dynamics::{coriolis_matrix, gravity_torque, mass_matrix};
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
    inertia: Option<InertiaFeedforward>,
}

/// The inertia feed-forward's state: the acceleration estimate, a first-order low-pass of the
/// velocity's difference, and the matrices' buffers.
#[derive(Clone, Debug)]
struct InertiaFeedforward {
    share: f64,
    /// The low-pass's weight on each new difference: `1 − exp(−2π f_c T)`.
    weight: f64,
    period_s: f64,
    previous_qd: Vec<f64>,
    qdd: Vec<f64>,
    primed: bool,
    mass: Vec<f64>,
    coriolis: Vec<f64>,
}

impl InertiaFeedforward {
    /// The estimate after a cycle at velocity `qd`.
    fn update(&mut self, qd: &[f64]) {
        if self.primed {
            for ((a, v), p) in self.qdd.iter_mut().zip(qd).zip(&self.previous_qd) {
                *a += self.weight * ((v - p) / self.period_s - *a);
            }
        }
        self.previous_qd.copy_from_slice(qd);
        self.primed = true;
    }
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
            inertia: None,
        })
    }

    /// Also feed forward `share` (in [0, 1)) of the inertial torque `M(q) q̈ + C(q, q̇) q̇`, with
    /// `q̈` the velocity's difference over `period_s` low-passed at `cutoff_hz`. A share of 1
    /// would cancel the arm's mass outright, which no filtered estimate can do stably; 0 leaves
    /// the law as it was.
    pub fn with_inertia(mut self, share: f64, cutoff_hz: f64, period_s: f64) -> Result<Self, FixtureError> {
        if !(0.0..1.0).contains(&share) {
            return Err(FixtureError::Loop(format!("the inertia's compensated share is {share}, not in [0, 1)")));
        }
        if !(period_s.is_finite() && period_s > 0.0 && cutoff_hz.is_finite() && cutoff_hz > 0.0)
            || cutoff_hz >= 0.5 / period_s
        {
            return Err(FixtureError::Loop(format!(
                "the acceleration's cut-off {cutoff_hz} Hz must be positive and below the loop's Nyquist frequency at a \
                 period of {period_s} s"
            )));
        }
        let n = self.model.dof();
        self.inertia = (share > 0.0).then(|| InertiaFeedforward {
            share,
            weight: 1.0 - (-std::f64::consts::TAU * cutoff_hz * period_s).exp(),
            period_s,
            previous_qd: vec![0.0; n],
            qdd: vec![0.0; n],
            primed: false,
            mass: vec![0.0; n * n],
            coriolis: vec![0.0; n * n],
        });
        Ok(self)
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

    /// The compensation alone at `q`, `qd` (finite) into `out`. With the inertia feed-forward each
    /// call is one cycle: it advances the acceleration estimate.
    pub fn compensation(&mut self, q: &[f64], qd: &[f64], out: &mut [f64]) {
        let layout = self.model.layout();
        gravity_torque(&self.model, &mut self.data, q, &self.params, out);
        self.forces.fill(0.0);
        self.effects.add_forces(q, qd, &mut self.forces);
        if let Some(inertia) = self.inertia.as_mut() {
            inertia.update(qd);
            let n = qd.len();
            mass_matrix(&self.model, &mut self.data, q, &self.params, &mut inertia.mass);
            coriolis_matrix(&self.model, &mut self.data, q, qd, &self.params, &mut inertia.coriolis);
            for (k, f) in self.forces.iter_mut().enumerate() {
                let row = k * n..(k + 1) * n;
                let inertial = crate::dense::dot(&inertia.mass[row.clone()], &inertia.qdd)
                    + crate::dense::dot(&inertia.coriolis[row], qd);
                *f += inertia.share * inertial;
            }
        }
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
        if let Some(inertia) = self.inertia.as_mut() {
            inertia.primed = false;
            inertia.qdd.fill(0.0);
        }
    }

    fn step(&mut self, _dt: f64, q: &[f64], qd: &[f64], _desired: &Desired, tau: &mut [f64]) {
        if self.command(q, qd, tau).is_err() {
            tau.fill(f64::NAN);
        }
    }
}
