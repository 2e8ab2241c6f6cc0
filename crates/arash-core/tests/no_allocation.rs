//! Evaluating the model never touches the heap: a counting global allocator watches 10^5
//! evaluations of each algorithm. This file holds one test so no other test allocates meanwhile.

mod common;

use arash_core::*;
use common::counting::{allocations, watch_this_thread, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn evaluations_do_not_allocate() {
    let model = arash_asist();
    let mut data = Data::new(&model);
    let (n, p) = (model.dof(), model.num_params());
    let pi = model.cad_parameters();
    let mut y = vec![0.0; n * p];
    let mut mat = vec![0.0; n * n];
    let mut vec3 = vec![0.0; n];
    let base = BaseParameters::compute(&model, &base_parameters::BaseParameterOptions::default()).unwrap();
    let bodies = regressor::bodies_of_columns(&model, &base.independent);
    let mut rotor = effects::EffectTerm::new(effects::EffectKind::Armature, None);
    rotor.coefficients = vec![1e-4, 1e-4, 0.02];
    let mut friction = effects::EffectTerm::new(effects::EffectKind::Stribeck, Some(2));
    friction.coefficients = vec![0.1];
    friction.scale = Some(0.01);
    let mut observer = force::MomentumObserver::new(
        &model,
        &pi,
        &[rotor, friction],
        &[10.0; 3],
        &[1e-3; 3],
        force::TorqueTiming::Sampled,
    )
    .unwrap();
    let mut tip = force::FrameForce::new(&model, "instrument_tip", "remote_centre", 1e-3).unwrap();
    let mut tip_force = 0.0;
    let evaluations = 100_000;
    watch_this_thread();
    let before = allocations();
    for i in 0..evaluations {
        let t = i as f64 * 1e-3;
        let q = [0.3 * t.sin(), 0.2 + 0.4 * t.cos(), 0.01 * t.sin()];
        let qd = [0.5 * t.cos(), -0.4 * t.sin(), 0.01 * t.cos()];
        let qdd = [-0.5 * t.sin(), -0.4 * t.cos(), -0.01 * t.sin()];
        regressor(&model, &mut data, &q, &qd, &qdd, &mut y);
        regressor_of_bodies(&model, &mut data, &q, &qd, &qdd, Some(&bodies), &mut y);
        slotine_li_regressor(&model, &mut data, &q, &qd, &qd, &qdd, &mut y);
        mass_matrix(&model, &mut data, &q, &pi, &mut mat);
        coriolis_matrix(&model, &mut data, &q, &qd, &pi, &mut mat);
        gravity_torque(&model, &mut data, &q, &pi, &mut vec3);
        inverse_dynamics(&model, &mut data, &q, &qd, &qdd, &pi, &mut vec3);
        let tau = [vec3[0], vec3[1], vec3[2]];
        forward_dynamics(&model, &mut data, &q, &qd, &tau, &pi, &mut vec3).unwrap();
        let external = observer.step(1e-3, &q, &qd, &tau).unwrap();
        tip_force += tip.map(&q, external, &[0.01, 0.01, 0.1]).force[2];
    }
    let allocations = allocations() - before;
    assert_eq!(allocations, 0, "{allocations} heap allocations in {evaluations} evaluations");
    assert!(y.iter().any(|v| *v != 0.0) && vec3.iter().all(|v| v.is_finite()) && tip_force.is_finite());
}
