//! Criterion benches of one evaluation of each algorithm on the bundled ARASH:ASiST model.
//! Run: cargo bench -p arash-core --bench dynamics

use std::hint::black_box;

use arash_core::base_parameters::BaseParameterOptions;
use arash_core::*;
use criterion::{criterion_group, criterion_main, Criterion};

fn bench(c: &mut Criterion) {
    let model = arash_asist();
    let mut data = Data::new(&model);
    let (n, p) = (model.dof(), model.num_params());
    let pi = model.cad_parameters();
    let (q, qd, qdd) = ([0.3, 0.4, 0.01], [0.5, -0.7, 0.05], [1.1, 0.9, -0.3]);
    let mut y = vec![0.0; n * p];
    let mut mat = vec![0.0; n * n];
    let mut tau = vec![0.0; n];

    c.bench_function("regressor Y (arash_asist)", |b| {
        b.iter(|| regressor(&model, &mut data, black_box(&q), black_box(&qd), black_box(&qdd), &mut y))
    });
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default()).unwrap();
    let bodies = regressor::bodies_of_columns(&model, &base.independent);
    c.bench_function("regressor_of_bodies, the base columns' bodies (arash_asist)", |b| {
        b.iter(|| regressor_of_bodies(&model, &mut data, black_box(&q), &qd, &qdd, Some(&bodies), &mut y))
    });
    c.bench_function("slotine_li_regressor Y_S (arash_asist)", |b| {
        b.iter(|| slotine_li_regressor(&model, &mut data, black_box(&q), &qd, &qd, &qdd, &mut y))
    });
    c.bench_function("mass_matrix M (arash_asist)", |b| {
        b.iter(|| mass_matrix(&model, &mut data, black_box(&q), &pi, &mut mat))
    });
    c.bench_function("coriolis_matrix C (arash_asist)", |b| {
        b.iter(|| coriolis_matrix(&model, &mut data, black_box(&q), &qd, &pi, &mut mat))
    });
    c.bench_function("inverse_dynamics (arash_asist)", |b| {
        b.iter(|| inverse_dynamics(&model, &mut data, black_box(&q), &qd, &qdd, &pi, &mut tau))
    });
    c.bench_function("forward_dynamics (arash_asist)", |b| {
        b.iter(|| forward_dynamics(&model, &mut data, black_box(&q), &qd, &[0.1, 0.2, 0.3], &pi, &mut tau))
    });
    // The hand's force in the cycle: one observer step and the tip map, with a rotor inertia.
    let mut rotor = effects::EffectTerm::new(effects::EffectKind::Armature, None);
    rotor.coefficients = vec![1e-4, 1e-4, 0.02];
    let mut observer = force::MomentumObserver::new(
        &model,
        &pi,
        &[rotor.clone()],
        &[10.0; 3],
        &[1e-3; 3],
        force::TorqueTiming::Sampled,
    )
    .unwrap();
    let mut tip = force::FrameForce::new(&model, "instrument_tip", "remote_centre", 1e-3).unwrap();
    let mut t = 0.0_f64;
    c.bench_function("momentum observer step + instrument tip force (arash_asist)", |b| {
        b.iter(|| {
            t += 1e-3;
            let q = [0.3 * t.sin(), 0.4, 0.01];
            let external = observer.step(1e-3, black_box(&q), &qd, &[0.1, 0.2, 0.3]).unwrap();
            black_box(tip.map(&q, external, &[0.01, 0.01, 0.1]))
        })
    });
    // The haptic mode's cycle: the compensation and every kind of fixture, all engaged.
    let fixtures = haptics::Fixtures {
        wall: vec![haptics::DepthWall { depth_m: -0.05, stiffness: 500.0, damping: 1.0 }],
        cone: vec![haptics::Cone { axis: [1.0, 0.0, 0.0], half_angle_deg: 1.0, stiffness: 0.5, damping: 0.0 }],
        viscous: vec![haptics::ViscousField { damping: 1.0 }],
        spring: vec![haptics::Spring { point: [0.0; 3], stiffness: 50.0, damping: 0.0 }],
        ..Default::default()
    };
    let mut law = haptics::HapticLaw::new(&model, &pi, &[rotor], &[0.01, 0.01, 1e-3], 0.0, &fixtures).unwrap();
    c.bench_function("haptic law: compensation + wall, cone, field and spring (arash_asist)", |b| {
        b.iter(|| {
            t += 1e-3;
            let q = [0.3 * t.sin(), 0.4, 0.01];
            black_box(law.command(black_box(&q), &qd, &mut tau).unwrap())
        })
    });
    // The same with the optional inertia feed-forward: M(q) and C(q, q̇) each cycle.
    let mut heavy = law.clone().with_inertia(0.5, 40.0, 1e-3).unwrap();
    c.bench_function("haptic law with inertia feed-forward (arash_asist)", |b| {
        b.iter(|| {
            t += 1e-3;
            let q = [0.3 * t.sin(), 0.4, 0.01];
            black_box(heavy.command(black_box(&q), &qd, &mut tau).unwrap())
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
