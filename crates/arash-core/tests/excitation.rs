//! Excitation design: feasibility checked independently of the designer, rest at both ends,
//! determinism, and an improvement over where the optimiser started.

use arash_core::base_parameters::BaseParameterOptions;
use arash_core::identify::excitation::{design_excitation, normalised_condition_number, ExcitationOptions};
use arash_core::*;

fn quick() -> ExcitationOptions {
    ExcitationOptions { restarts: 2, iterations: 600, ..Default::default() }
}

#[test]
fn designed_trajectory_respects_the_limits_and_starts_and_ends_at_rest() {
    let model = arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default()).unwrap();
    let mut reports = Vec::new();
    let traj = design_excitation(&model, &base, &quick(), &mut |p| reports.push(p)).unwrap();
    assert_eq!(reports.len(), 2, "one progress report per restart");
    assert!(reports.windows(2).all(|w| w[1].best_condition_number <= w[0].best_condition_number));
    // Independently of the designer's own check: 1 kHz over a whole period.
    let (_, q, qd, qdd) = traj.sample(1000.0, 1);
    for (k, joint) in model.joints.iter().enumerate() {
        let col = |x: &[f64]| x.iter().skip(k).step_by(3).copied().collect::<Vec<_>>();
        assert!(col(&q).iter().all(|v| *v >= joint.lower && *v <= joint.upper), "{} position", joint.name);
        assert!(col(&qd).iter().all(|v| v.abs() <= joint.velocity), "{} speed", joint.name);
        assert!(col(&qdd).iter().all(|v| v.abs() <= 5.0 * joint.velocity + 1e-9), "{} acceleration", joint.name);
    }
    for t in [0.0, traj.period_s] {
        let (_, v, a) = traj.state(t);
        assert!(v.iter().chain(&a).all(|x| x.abs() < 1e-12), "not at rest at t = {t}: {v:?} {a:?}");
    }
    let kappa = normalised_condition_number(&model, &base, &traj, 300);
    assert!((kappa - traj.condition_number).abs() < 0.2 * kappa, "reported κ {} vs {kappa}", traj.condition_number);
}

#[test]
fn the_same_seed_gives_the_same_trajectory() {
    let model = arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default()).unwrap();
    let options = ExcitationOptions { restarts: 1, iterations: 200, ..Default::default() };
    let a = design_excitation(&model, &base, &options, &mut |_| {}).unwrap();
    let b = design_excitation(&model, &base, &options, &mut |_| {}).unwrap();
    assert_eq!(a.a, b.a);
    assert_eq!(a.b, b.b);
    let other = design_excitation(&model, &base, &ExcitationOptions { seed: 2, ..options }, &mut |_| {}).unwrap();
    assert_ne!(a.a, other.a);
}

#[test]
fn optimising_lowers_the_condition_number() {
    let model = arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default()).unwrap();
    let barely = design_excitation(
        &model,
        &base,
        &ExcitationOptions { restarts: 1, iterations: 1, ..Default::default() },
        &mut |_| {},
    )
    .unwrap();
    let optimised = design_excitation(
        &model,
        &base,
        &ExcitationOptions { restarts: 1, iterations: 800, ..Default::default() },
        &mut |_| {},
    )
    .unwrap();
    assert!(
        optimised.condition_number < 0.5 * barely.condition_number,
        "{} vs {}",
        optimised.condition_number,
        barely.condition_number
    );
}
