//! A control cycle never touches the heap: the simulated rig (plant with every undeclared effect,
//! encoders, estimator, controller, safety gate) runs 10^4 cycles per controller under a counting
//! global allocator. This file holds one test so no other test allocates meanwhile.

mod common;

use arash_core::control::{standard_controller, ControllerKind, RobustGains, Trajectory};
use arash_core::sim::scenario::*;
use arash_core::sim::{true_parameters, Rig, Scenario};
use common::counting::{allocations, watch_this_thread, Counting};

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn control_cycles_do_not_allocate() {
    let model = arash_core::arash_asist();
    // Every effect but armature, which compliance replaces.
    let effects = Effects {
        stribeck: Some(Stribeck::default()),
        coulomb_asymmetry: Some(CoulombAsymmetry::default()),
        torque_offset: Some(TorqueOffset::default()),
        armature: None,
        configuration_disturbance: Some(ConfigurationDisturbance::default()),
        compliance: Some(Compliance::default()),
        cogging: Some(Cogging::default()),
        delay: Some(Delay::default()),
        friction_drift: Some(FrictionDrift::default()),
        payload: Some(Payload { at_s: 5.0, ..Payload::default() }),
        viscous_nonlinear: Some(ViscousNonlinear::default()),
        position_friction: Some(PositionFriction::default()),
        hysteresis: Some(Hysteresis::default()),
        torque_drift: Some(TorqueDrift::default()),
    };
    let scenario = Scenario { effects, ..Scenario::default() };
    let params = true_parameters(&model, &scenario);
    watch_this_thread();
    for kind in [ControllerKind::Pd, ControllerKind::Idc, ControllerKind::Robust] {
        let controller =
            standard_controller(kind, &model, &params, Some(&RobustGains::paper(&model).unwrap())).unwrap();
        let mut rig = Rig::new(&model, &scenario, Trajectory::PaperValidation { omega: 0.9 }, controller).unwrap();
        let cycles = 10_000;
        let before = allocations();
        for _ in 0..cycles {
            rig.step().unwrap();
        }
        let allocations = allocations() - before;
        assert_eq!(allocations, 0, "{kind:?}: {allocations} heap allocations in {cycles} cycles");
        assert!(rig.record().faults.is_empty(), "{kind:?}: {:?}", rig.record().faults);
        assert!(rig.record().tau_cmd.iter().any(|t| *t != 0.0));
    }
}
