//! The bundled ARASH:ASiST reconstruction keeps its remote centre of motion: for every
//! configuration within the limits, the instrument axis passes through the RCM.

mod common;

use arash_core::*;
use common::*;

#[test]
fn instrument_axis_passes_through_the_rcm_everywhere() {
    let model = arash_asist();
    let mut data = Data::new(&model);
    let yoke = model.bodies.iter().position(|b| b.name == "yaw_yoke").unwrap();
    let carriage = model.bodies.iter().position(|b| b.name == "insertion_carriage").unwrap();
    let axis_in_carriage = model.bodies[carriage].axis;
    let mut rng = rng(11);
    let mut worst: f64 = 0.0;
    for _ in 0..10_000 {
        let s = state(&model, &mut rng);
        forward_kinematics(&model, &mut data, &s.q);
        // The RCM is the yaw frame origin: on the yaw axis, and fixed in the base.
        let rcm = data.world_pos[yoke];
        let point = data.world_pos[carriage];
        let direction = data.world_rot[carriage] * axis_in_carriage;
        let offset = rcm - point;
        let distance = (offset - direction * direction.dot(&offset)).norm();
        worst = worst.max(distance);
    }
    assert!(worst < 1e-12, "instrument axis misses the RCM by {worst} m");
    // And the RCM itself does not move with q.
    forward_kinematics(&model, &mut data, &[0.0, 0.0, 0.0]);
    let at_zero = data.world_pos[yoke];
    forward_kinematics(&model, &mut data, &[0.5, 0.8, 0.02]);
    assert!((data.world_pos[yoke] - at_zero).norm() < 1e-15);
}

#[test]
fn limits_are_the_papers() {
    let model = arash_asist();
    let deg = std::f64::consts::PI / 180.0;
    let expect = [(-42.5 * deg, 42.5 * deg, 200.0 * deg), (-25.0 * deg, 55.0 * deg, 200.0 * deg), (-0.014, 0.027, 0.1)];
    for (joint, (lo, hi, v)) in model.joints.iter().zip(expect) {
        assert!((joint.lower - lo).abs() < 1e-9 && (joint.upper - hi).abs() < 1e-9, "{} limits", joint.name);
        assert!((joint.velocity - v).abs() < 1e-9, "{} speed limit", joint.name);
    }
    let total_mass: f64 = model.bodies.iter().map(|b| b.inertial[0]).sum();
    assert!((1.0..=2.0).contains(&total_mass), "moving mass {total_mass} kg");
}
