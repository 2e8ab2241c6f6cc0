//! Excitation design: feasibility checked independently of the designer, rest at both ends,
//! determinism, and an improvement over where the optimiser started.

use arash_core::base_parameters::BaseParameterOptions;
use arash_core::identify::excitation::{design_excitation, normalised_condition_number, sigma_factors};
use arash_core::identify::options::ExcitationOptions;
use arash_core::*;

fn quick() -> ExcitationOptions {
    ExcitationOptions { restarts: 2, iterations: 600, ..Default::default() }
}

/// Each joint's covered share of its usable range (limits less the 5 % margins) and peak speed
/// against the fastest a 5-harmonic series over 15 s can move over that range, from 1 kHz samples.
fn coverage(model: &Model, q: &[f64], qd: &[f64]) -> Vec<(f64, f64)> {
    let n = model.dof();
    model
        .joints
        .iter()
        .enumerate()
        .map(|(k, joint)| {
            let col = |x: &[f64]| x.iter().skip(k).step_by(n).copied().collect::<Vec<_>>();
            let (q, qd) = (col(q), col(qd));
            let usable = 0.9 * (joint.upper - joint.lower);
            let covered =
                q.iter().copied().fold(f64::NEG_INFINITY, f64::max) - q.iter().copied().fold(f64::INFINITY, f64::min);
            let fastest = joint.velocity.min(2.0 * std::f64::consts::PI * 5.0 / 15.0 * usable / 2.0);
            (covered / usable, qd.iter().fold(0.0_f64, |m, v| m.max(v.abs())) / fastest)
        })
        .collect()
}

#[test]
fn designed_trajectory_respects_the_limits_and_starts_and_ends_at_rest() {
    let model = arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default().identifiable()).unwrap();
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
    // Every joint, the insertion too, sweeps most of its range at a good share of its speed.
    for (joint, (range, speed)) in model.joints.iter().zip(coverage(&model, &q, &qd)) {
        assert!(range >= 0.7 - 1e-3, "{}: covers {:.1} % of its range", joint.name, 100.0 * range);
        assert!(speed >= 0.5 - 1e-3, "{}: peak speed {:.1} % of the fastest", joint.name, 100.0 * speed);
    }
}

/// The weak base parameter is weak for any trajectory: an optimiser that tries to separate it
/// (designing for every exact base parameter) still leaves κ above 10³, where the design for the
/// identifiable ones reaches far below.
#[test]
fn no_design_separates_the_weak_base_parameter() {
    let model = arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default().identifiable()).unwrap();
    let exact = BaseParameters::compute(&model, &BaseParameterOptions::default().keep_weak()).unwrap();
    assert_eq!(exact.rank, base.rank + 1);
    let trying = design_excitation(&model, &exact, &ExcitationOptions::default(), &mut |_| {}).unwrap();
    let designed = design_excitation(&model, &base, &ExcitationOptions::default(), &mut |_| {}).unwrap();
    assert!(trying.condition_number > 1e3, "κ with the weak parameter {}", trying.condition_number);
    assert!(designed.condition_number < 300.0, "κ without it {}", designed.condition_number);
    assert!(designed.condition_number_with_weak > 1e3, "{}", designed.condition_number_with_weak);
    assert_eq!(trying.condition_number_with_weak, trying.condition_number);
    // Per parameter: on the trajectory that tried, the weak one's σ factor dwarfs the rest; on the
    // design for the identifiable ones, every factor (friction and stiffness included) is modest.
    let trying_factors = sigma_factors(&model, &exact, &trying, 300).unwrap();
    let weak = exact.names.iter().position(|n| n == "instrument_holder.my_R").unwrap();
    assert!(trying_factors[weak] > 1e3, "{trying_factors:?}");
    let factors = sigma_factors(&model, &base, &designed, 300).unwrap();
    assert!(factors.iter().all(|f| (1.0..50.0).contains(f)), "{factors:?}");
}

#[test]
fn the_same_seed_gives_the_same_trajectory() {
    let model = arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default().identifiable()).unwrap();
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
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default().identifiable()).unwrap();
    // One iteration from the start, which is feasible without the least range and speed.
    let barely = design_excitation(
        &model,
        &base,
        &ExcitationOptions {
            restarts: 1,
            iterations: 1,
            min_range_fraction: 0.0,
            min_speed_fraction: 0.0,
            ..Default::default()
        },
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
