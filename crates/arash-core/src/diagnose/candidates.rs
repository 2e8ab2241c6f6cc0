//! The candidates a diagnosis tries on a log, from each effect's own bank ([`crate::effects`]).

use super::findings::{Rejection, RejectionReason};
use super::options::DiagnoseOptions;
use super::prepare::Prepared;
use super::regression::GroupTest;
use crate::base_parameters::BaseParameters;
use crate::effects::{EffectKind, EffectTerm, JointData, NotSearched};
use crate::model::Model;
use crate::model_file::ModelFile;
use crate::transmission::Transmission;

/// The candidate templates for this robot and training data: each effect's own bank per joint
/// (`crate::effects`), then rotor inertia on every joint at once, a payload on each body with
/// mass and the rotor of each declared motor that turns with several joints; and the effects not
/// searched, with the reason.
/// `laws_chosen`: the Coulomb laws were chosen from this log, the best of every friction
/// velocity, so `friction_velocity` has nothing left to find.
pub(super) fn candidates(
    model: &Model,
    train: &Prepared,
    options: &DiagnoseOptions,
    laws_chosen: bool,
) -> (Vec<EffectTerm>, Vec<Rejection>) {
    let dof = model.dof();
    let mut terms = Vec::new();
    let mut skipped = Vec::new();
    let motion = Motion::of(train);
    let wanted: Vec<EffectKind> = EffectKind::ALL.into_iter().filter(|k| options.searches(*k)).collect();
    let ratios = options.joint_per_motor_radian();
    for k in 0..dof {
        let mut weights = vec![0.0; dof];
        weights[k] = 1.0;
        let joint = motion.joint_data(k, &weights, model, ratios.as_ref().map(|r| r[k]), options);
        for &kind in wanted.iter().filter(|k| **k != EffectKind::CoupledRotor) {
            if kind == EffectKind::FrictionVelocity && laws_chosen {
                skipped.push(not_searched(kind, vec![k], &model.joints[k].name, NotSearched::LawChosenFromData));
                continue;
            }
            match kind.law().joint_candidates(&joint) {
                Ok(bank) => terms.extend(bank),
                Err(why) => skipped.push(not_searched(kind, vec![k], &model.joints[k].name, why)),
            }
        }
    }
    if wanted.contains(&EffectKind::Armature) && dof > 1 {
        terms.push(crate::effects::armature_on_every_joint(&model.joint_names()));
    }
    if wanted.contains(&EffectKind::Payload) {
        terms.extend(train.bodies.iter().map(|(b, _)| crate::effects::payload_on(&model.bodies[*b].name)));
    }
    if wanted.contains(&EffectKind::CoupledRotor) {
        let motors = options.motors.as_ref().map_or_else(Vec::new, Transmission::coupled_motors);
        if motors.is_empty() {
            let all = (0..dof).collect();
            skipped.push(not_searched(EffectKind::CoupledRotor, all, "any motor", NotSearched::NoCoupledMotor));
        }
        for (m, g) in motors {
            let motor = motion.joint_data(m, &g, model, None, options);
            let mut bank = EffectKind::CoupledRotor.law().joint_candidates(&motor).unwrap_or_default();
            bank.iter_mut().for_each(|t| t.coupling = Some(g.clone()));
            terms.extend(bank);
        }
    }
    for t in &mut terms {
        t.columns = t.column_names();
    }
    (terms, skipped)
}

fn not_searched(kind: EffectKind, joints: Vec<usize>, on: &str, why: NotSearched) -> Rejection {
    Rejection {
        name: kind.id().into(),
        joints,
        label: format!("{} on {on}", kind.id()),
        reason: RejectionReason::NotSearched { why },
        p_value: None,
        heldout_gain: None,
    }
}

/// The training data's motion at the kept samples (`samples × dof`, interleaved).
struct Motion {
    q: Vec<f64>,
    qd: Vec<f64>,
    qdd: Vec<f64>,
    time: (f64, f64),
}

impl Motion {
    fn of(train: &Prepared) -> Self {
        let t0 = train.pre.t[train.kept[0]];
        let t1 = train.pre.t[*train.kept.last().expect("prepared logs have samples")];
        Self {
            q: train.at_kept(&train.pre.q),
            qd: train.at_kept(&train.pre.qd),
            qdd: train.at_kept(&train.pre.qdd),
            time: (t0, t1),
        }
    }

    /// What a candidate bank is built from: the motion `weights·q` (one joint's, or a coupled
    /// motor's on its joint `k`'s scale), and joint `k`'s declared friction law.
    fn joint_data<'a>(
        &self,
        k: usize,
        weights: &[f64],
        model: &Model,
        transmission: Option<f64>,
        options: &'a DiagnoseOptions,
    ) -> JointData<'a> {
        let dof = weights.len();
        let combine = |x: &[f64]| -> Vec<f64> {
            x.chunks_exact(dof).map(|row| row.iter().zip(weights).map(|(a, b)| a * b).sum()).collect()
        };
        let (qk, vk, ak) = (combine(&self.q), combine(&self.qd), combine(&self.qdd));
        let peak = |x: &[f64]| x.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
        let lo = qk.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = qk.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        JointData {
            joint: k,
            span: (lo, hi),
            speed_rms: (vk.iter().map(|v| v * v).sum::<f64>() / vk.len() as f64).sqrt(),
            peak_speed: peak(&vk),
            peak_acceleration: peak(&ak),
            epsilon: model.coulomb_laws.shape(k).epsilon(),
            time: self.time,
            transmission,
            cogging_periods: &options.cogging_periods,
        }
    }
}

/// Why a `compliance` candidate is not a cable, if it is not. With the encoder on the motor, all
/// of a joint's Coulomb friction reaches the motor through the cable's stretch, so a cable's
/// term takes over most of the friction the declared `sign(q̇)` column carried; a small stretch
/// term beside an unchanged Coulomb term only reshapes the friction transition (docs/diagnosis.md
/// gives the shares measured on the simulated rig).
pub(super) fn not_the_cable(
    model: &Model,
    base: &BaseParameters,
    free: &[bool],
    coef: &[f64],
    given: Option<&ModelFile>,
    term: &EffectTerm,
    test: &GroupTest,
) -> Option<RejectionReason> {
    /// The least share of the joint's Coulomb friction a cable term carries.
    const CABLE_SHARE: f64 = 0.5;
    let (EffectKind::Compliance, Some(k)) = (term.kind, term.joint) else { return None };
    let j = base.independent.iter().position(|&p| p == model.layout().coulomb(k))?;
    let coulomb = if free[j] { coef[free[..j].iter().filter(|f| **f).count()] } else { given?.fitted.beta[j] };
    let p_value = test.p_value;
    if coulomb <= 0.0 {
        return Some(RejectionReason::NoFrictionForACable { p_value, coulomb });
    }
    let (coefficient, share) = (test.coefficients[0], test.coefficients[0] / coulomb);
    (share < CABLE_SHARE).then_some(RejectionReason::TooLittleFrictionForACable {
        p_value,
        share,
        coefficient,
        coulomb,
    })
}
