//! Feedforward of the effects a diagnosis added to a model (see `docs/diagnosis.md`), so that a
//! model-based controller compensates them too.
//!
//! A term acts per cycle through [`EffectTerm::features`], the same function the diagnosis fitted
//! it with. A payload is not a feedforward: it is a change of one body's inertial parameters, so
//! [`EffectFeedforward::new`] folds it into the parameter vector the controller already uses.
//! A joint term is evaluated with the joint's motion clamped into the range it was fitted on
//! ([`EffectTerm::within_fitted`]), so its torque stays what the data checked.
//! Two effects are properties of a log, not of the robot, and are left out: `delay` and `drift`
//! (a function of the log's own clock).

use crate::effects::{EffectKind, EffectTerm, TermState};
use crate::model::Model;

/// The joint-wise effect terms of a model file, with their state, evaluated once per cycle
/// without allocating.
#[derive(Clone, Debug, Default)]
pub struct EffectFeedforward {
    terms: Vec<EffectTerm>,
    states: Vec<TermState>,
    /// A zero acceleration per joint, for [`Self::add_forces`].
    zeros: Vec<f64>,
}

impl EffectFeedforward {
    /// Keep the terms that act at run time; fold payloads into `params`. A friction term fitted
    /// with `sign(q̇)` switches with the controller's `tanh(q̇/ε)` instead (`epsilon`, per joint),
    /// as the controller's own Coulomb term does: a sign of a noisy velocity would chatter.
    pub fn new(model: &Model, effects: &[EffectTerm], epsilon: &[f64], params: &mut [f64]) -> Self {
        let mut terms = Vec::new();
        for term in effects.iter().filter(|t| t.kind.at_run_time()) {
            if term.kind == EffectKind::Payload {
                if let Some(b) = model.bodies.iter().position(|b| Some(&b.name) == term.body.as_ref()) {
                    for (p, c) in params[model.layout().body(b)].iter_mut().zip(&term.coefficients) {
                        *p += c;
                    }
                }
                continue;
            }
            let mut term = term.clone();
            if let (None, Some(k)) = (term.epsilon, term.joint) {
                term.epsilon = epsilon.get(k).copied();
            }
            terms.push(term);
        }
        // A drive's gain scales everything commanded through it, the other effects' torque too.
        terms.sort_by_key(|t| t.kind == EffectKind::DriveGain);
        let states = vec![TermState::default(); terms.len()];
        Self { terms, states, zeros: vec![0.0; model.dof()] }
    }

    /// Forget the terms' state (the hysteresis term's direction of travel, the cable's stretch).
    pub fn reset(&mut self) {
        self.states.fill(TermState::default());
    }

    /// Add the effects' torques at position `q`, velocity `qd` and acceleration `qdd` to `tau`,
    /// which holds the model's torque (the command) on entry; drive gains scale the sum last.
    pub fn add(&mut self, q: &[f64], qd: &[f64], qdd: &[f64], tau: &mut [f64]) {
        self.accumulate(q, qd, qdd, tau, true);
    }

    /// Add the effects' torques at `(q, q̇)` and zero acceleration to `tau`, with no drive gain:
    /// the torques the joints feel from friction, cables and wiring. With [`Self::add_inertia`]
    /// and [`Self::drive_gain`] this is the same model as [`Self::add`], taken apart as a
    /// momentum observer needs it.
    pub fn add_forces(&mut self, q: &[f64], qd: &[f64], tau: &mut [f64]) {
        let zeros = std::mem::take(&mut self.zeros);
        self.accumulate(q, qd, &zeros, tau, false);
        self.zeros = zeros;
    }

    /// Add the inertia the effects put on the joints to the mass matrix `mass` (row-major,
    /// dof × dof): a rotor inertia on its joint's diagonal, a coupled rotor's `c g gᵀ` on every
    /// joint its motor turns with. Both are constant.
    pub fn add_inertia(&self, mass: &mut [f64]) {
        let n = self.zeros.len();
        for term in &self.terms {
            match (term.kind, &term.coupling) {
                (EffectKind::Armature, _) => {
                    for (k, c) in term.coefficients.iter().enumerate().take(n) {
                        mass[k * n + k] += c;
                    }
                }
                (EffectKind::CoupledRotor, Some(g)) => {
                    for (i, gi) in g.iter().enumerate() {
                        for (j, gj) in g.iter().enumerate() {
                            mass[i * n + j] += term.coefficients[0] * gi * gj;
                        }
                    }
                }
                _ => {}
            }
        }
    }

    /// The factor joint `k`'s drive puts on its torque, `1 + g` (1 without a drive-gain term):
    /// the measured torque is this times the torque the joint feels.
    pub fn drive_gain(&self, k: usize) -> f64 {
        let gains = self.terms.iter().filter(|t| t.kind == EffectKind::DriveGain && t.joint == Some(k));
        gains.map(|t| 1.0 + t.coefficients[0]).product()
    }

    fn accumulate(&mut self, q: &[f64], qd: &[f64], qdd: &[f64], tau: &mut [f64], with_gains: bool) {
        let mut features = [0.0; 8];
        for (term, state) in self.terms.iter().zip(&mut self.states) {
            if !with_gains && term.kind == EffectKind::DriveGain {
                continue;
            }
            match term.joint {
                Some(k) => {
                    let width = term.width();
                    let x = term.sample_of(q, qd, qdd, 0.0, tau).expect("a term on a joint");
                    term.features(term.within_fitted(x), state, &mut features[..width]);
                    let torque = features[..width].iter().zip(&term.coefficients).map(|(a, c)| a * c).sum::<f64>();
                    match term.coupling {
                        None => tau[k] += torque,
                        // A coupled rotor acts on every joint its motor turns with.
                        Some(_) => tau.iter_mut().enumerate().for_each(|(j, t)| *t += term.weight_on(j) * torque),
                    }
                }
                // Armature fitted on every joint at once: one coefficient per joint.
                None if term.kind == EffectKind::Armature => {
                    for ((t, a), c) in tau.iter_mut().zip(qdd).zip(&term.coefficients) {
                        *t += c * a;
                    }
                }
                None => {}
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_wiring_term_adds_its_cosine_series_and_a_payload_moves_the_body_parameters() {
        let model = crate::arash_asist();
        let mut wiring = EffectTerm::new(EffectKind::ConfigurationDisturbance, Some(1));
        wiring.span = Some((-0.5, 1.0));
        wiring.coefficients = vec![0.02, -0.01, 0.005, 0.001];
        let mut payload = EffectTerm::new(EffectKind::Payload, None);
        payload.body = Some(model.bodies[2].name.clone());
        payload.coefficients = vec![0.05, 0.001, 0.0, -0.002, 1e-4, 0.0, 0.0, 0.0, 0.0, 0.0];
        let mut delay = EffectTerm::new(EffectKind::Delay, None);
        delay.scale = Some(3.0);
        let cad = model.cad_parameters();
        let mut params = cad.clone();
        let mut ff = EffectFeedforward::new(&model, &[wiring, payload, delay], &[0.01, 0.01, 0.001], &mut params);
        let changed: Vec<usize> = (0..params.len()).filter(|&i| params[i] != cad[i]).collect();
        assert_eq!(changed, vec![20, 21, 23, 24], "the payload's m, m·cx, m·cz and Ixx on body 2");
        assert!((params[20] - cad[20] - 0.05).abs() < 1e-15);

        let q = [0.1, 0.4, 0.01];
        let mut tau = [1.0, 2.0, 3.0];
        ff.add(&q, &[0.0; 3], &[0.0; 3], &mut tau);
        let x = (0.4 + 0.5) / 1.5;
        let pi = std::f64::consts::PI;
        let expected = 0.02 * (pi * x).cos() - 0.01 * (2.0 * pi * x).cos()
            + 0.005 * (3.0 * pi * x).cos()
            + 0.001 * (4.0 * pi * x).cos();
        assert_eq!(tau[0], 1.0);
        assert_eq!(tau[2], 3.0);
        assert!((tau[1] - 2.0 - expected).abs() < 1e-15, "{} vs {expected}", tau[1] - 2.0);
    }

    /// A term fitted on slow motion is evaluated at the edge of what it was fitted on, not
    /// extrapolated: its torque at twice the fitted speed is its torque at the fitted speed.
    #[test]
    fn a_term_is_evaluated_within_the_motion_it_was_fitted_on() {
        use crate::effects::FittedRange;
        let model = crate::arash_asist();
        let mut term = EffectTerm::new(EffectKind::ViscousNonlinear, Some(2));
        term.coefficients = vec![40.0];
        let torque = |term: &EffectTerm, v: f64| {
            let mut params = model.cad_parameters();
            let mut ff = EffectFeedforward::new(&model, std::slice::from_ref(term), &[0.01; 3], &mut params);
            let mut tau = [0.0; 3];
            ff.add(&[0.0, 0.0, 0.01], &[0.0, 0.0, v], &[0.0; 3], &mut tau);
            tau[2]
        };
        assert!((torque(&term, -0.02) + 40.0 * 0.02 * 0.02).abs() < 1e-15, "unbounded without a range");
        term.fitted_on = Some(FittedRange { position: (0.0, 0.02), speed: 0.01, acceleration: 0.1 });
        assert!((torque(&term, 0.005) - 40.0 * 0.005 * 0.005).abs() < 1e-15, "inside: unchanged");
        assert!((torque(&term, -0.02) + 40.0 * 0.01 * 0.01).abs() < 1e-15, "outside: held at the edge");
    }

    /// A model whose effect feeds energy in, or holds a non-number, builds no controller, and
    /// the error names the term; a bound's round-off zero and a rotor inertia nil within its σ
    /// are accepted.
    #[test]
    fn a_controller_refuses_an_effect_with_the_wrong_sign_or_no_value() {
        use crate::control::gains::PaperUnits;
        use crate::control::{controller_with_effects, ControllerError, ControllerKind, RobustGains};
        let model = crate::arash_asist();
        let gains = RobustGains::from_paper(&model, PaperUnits::Si).unwrap();
        let build = |term: &EffectTerm| {
            controller_with_effects(
                ControllerKind::Robust,
                &model,
                &model.cad_parameters(),
                std::slice::from_ref(term),
                Some(&gains),
            )
        };
        let mut friction = EffectTerm::new(EffectKind::ViscousNonlinear, Some(2));
        friction.coefficients = vec![-8.79e3];
        let Err(error) = build(&friction) else { panic!("a negative q̇·|q̇| friction was accepted") };
        assert!(matches!(error, ControllerError::UnphysicalEffect { .. }), "{error}");
        assert!(error.to_string().contains("viscous_nonlinear on insertion"), "{error}");
        friction.coefficients = vec![-1e-15];
        assert!(build(&friction).is_ok(), "a refit's round-off zero must pass");
        let mut offset = EffectTerm::new(EffectKind::Offset, Some(0));
        offset.coefficients = vec![f64::NAN];
        let Err(error) = build(&offset) else { panic!("a NaN offset was accepted") };
        assert!(error.to_string().contains("not a number"), "{error}");
        offset.coefficients = vec![-0.3];
        assert!(build(&offset).is_ok(), "an offset may have either sign");
        let mut armature = EffectTerm::new(EffectKind::Armature, None);
        armature.coefficients = vec![1e-4, -1e-6, 2e-4];
        armature.sigma = vec![1e-5, 1e-6, 1e-5];
        assert!(build(&armature).is_ok(), "one joint's rotor inertia nil within 2σ");
        armature.coefficients[1] = -3e-6;
        assert!(build(&armature).is_err(), "clearly negative rotor inertia");
        // A drive's factor 1 + g at or below zero reverses the command, whatever the gain's σ.
        let mut gain = EffectTerm::new(EffectKind::DriveGain, Some(1));
        (gain.coefficients, gain.sigma) = (vec![-0.6], vec![0.01]);
        assert!(build(&gain).is_ok(), "a drive giving 40 % of its torque");
        for factor_below in [-1.0, -1.04] {
            (gain.coefficients, gain.sigma) = (vec![factor_below], vec![0.5]);
            let Err(error) = build(&gain) else { panic!("a drive gain of {factor_below} was accepted") };
            assert!(error.to_string().contains("1 + g must be positive"), "{error}");
        }
    }

    /// A drive's gain g scales the whole command on its joint, the other effects' torque too:
    /// measured (and delivered) torque is (1 + g) times what was asked of the drive.
    #[test]
    fn a_drive_gain_scales_the_command_and_the_other_effects_on_its_joint_only() {
        let model = crate::arash_asist();
        let mut gain = EffectTerm::new(EffectKind::DriveGain, Some(2));
        gain.coefficients = vec![0.1];
        let mut offset = EffectTerm::new(EffectKind::Offset, Some(2));
        offset.coefficients = vec![0.5];
        let mut params = model.cad_parameters();
        // The gain first in the file: it must still act last.
        let mut ff = EffectFeedforward::new(&model, &[gain, offset], &[0.01; 3], &mut params);
        let mut tau = [1.0, 2.0, 3.0];
        ff.add(&[0.0, 0.3, 0.02], &[0.1; 3], &[0.0; 3], &mut tau);
        assert_eq!(&tau[..2], &[1.0, 2.0]);
        assert!((tau[2] - 1.1 * (3.0 + 0.5)).abs() < 1e-12, "{}", tau[2]);
    }
}
