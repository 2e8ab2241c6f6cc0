//! The candidates a diagnosis tries on a log, from each effect's own bank ([`crate::effects`]).

use super::findings::{Rejection, RejectionReason};
use super::options::DiagnoseOptions;
use super::prepare::Prepared;
use super::regression::GroupTest;
use crate::base_parameters::BaseParameters;
use crate::effects::{EffectKind, EffectTerm, JointData};
use crate::model::{CoulombShape, Model};
use crate::model_file::ModelFile;

/// The candidate templates for this robot and training data: each effect's own bank per joint
/// (`crate::effects`), then rotor inertia on every joint at once and a payload on each body with
/// mass; and the effects not searched, with the reason.
pub(super) fn candidates(
    model: &Model,
    train: &Prepared,
    options: &DiagnoseOptions,
) -> (Vec<EffectTerm>, Vec<Rejection>) {
    let dof = model.dof();
    let mut terms = Vec::new();
    let mut skipped = Vec::new();
    let q = train.at_kept(&train.pre.q);
    let qd = train.at_kept(&train.pre.qd);
    let qdd = train.at_kept(&train.pre.qdd);
    let t0 = train.pre.t[train.kept[0]];
    let t1 = train.pre.t[*train.kept.last().expect("prepared logs have samples")];
    let wanted: Vec<EffectKind> = EffectKind::ALL.into_iter().filter(|k| options.searches(*k)).collect();
    for k in 0..dof {
        let column = |x: &[f64]| x.iter().skip(k).step_by(dof).copied().collect::<Vec<f64>>();
        let (qk, vk, ak) = (column(&q), column(&qd), column(&qdd));
        let peak = |x: &[f64]| x.iter().fold(0.0, |m: f64, v| m.max(v.abs()));
        let lo = qk.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = qk.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let joint = JointData {
            joint: k,
            span: (lo, hi),
            speed_rms: (vk.iter().map(|v| v * v).sum::<f64>() / vk.len() as f64).sqrt(),
            peak_speed: peak(&vk),
            peak_acceleration: peak(&ak),
            epsilon: match model.coulomb_shape {
                CoulombShape::Tanh { epsilon } => Some(epsilon),
                CoulombShape::Sign => None,
            },
            time: (t0, t1),
            transmission: options.transmission.as_ref().and_then(|t| t.get(k)).copied(),
            cogging_periods: &options.cogging_periods,
        };
        for &kind in &wanted {
            match kind.law().joint_candidates(&joint) {
                Ok(bank) => terms.extend(bank),
                Err(why) => skipped.push(Rejection {
                    name: kind.id().into(),
                    joints: vec![k],
                    label: format!("{} on {}", kind.id(), model.joints[k].name),
                    reason: RejectionReason::NotSearched { why },
                    p_value: None,
                    heldout_gain: None,
                }),
            }
        }
    }
    for t in &mut terms {
        t.columns = t.column_names();
    }
    if wanted.contains(&EffectKind::Armature) && dof > 1 {
        terms.push(crate::effects::armature_on_every_joint(&model.joint_names()));
    }
    if wanted.contains(&EffectKind::Payload) {
        terms.extend(train.bodies.iter().map(|(b, _)| crate::effects::payload_on(&model.bodies[*b].name)));
    }
    (terms, skipped)
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
    let coulomb = if free[j] { coef[free[..j].iter().filter(|f| **f).count()] } else { given?.beta[j] };
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
