//! The haptic mode's fixtures: their torque is the gradient of their energy (finite differences
//! of the energy, not the Jacobian the renderer uses), the passivity bound is Colgate and
//! Schenkel's on the joint a wall moves, and a sampled wall at the bound neither gives nor takes
//! energy in the way the bound says.

use arash_core::haptics::{
    check_passivity, Cone, DepthWall, FixtureError, FixtureRenderer, Fixtures, RenderLoop, Spring, ViscousField,
};

fn model() -> arash_core::Model {
    arash_core::arash_asist()
}

/// The CAD model's loop at 1 kHz with no viscous friction compensated.
fn cad_loop(latency_s: f64) -> RenderLoop {
    let m = model();
    RenderLoop::of_model(&m, &m.cad_parameters(), 0.0, 1e-3, latency_s).unwrap()
}

fn wall(depth_m: f64, stiffness: f64, damping: f64) -> Fixtures {
    Fixtures { wall: vec![DepthWall { depth_m, stiffness, damping }], ..Default::default() }
}

/// Everything at once, engaged at `q`: a wall short of the tip, a cone narrower than the
/// instrument's tilt, a field and a spring.
fn all_engaged() -> Fixtures {
    Fixtures {
        wall: vec![DepthWall { depth_m: 0.005, stiffness: 500.0, damping: 0.0 }],
        cone: vec![Cone { axis: [0.0, 0.0, -1.0], half_angle_deg: 5.0, stiffness: 0.5, damping: 0.0 }],
        viscous: vec![ViscousField { damping: 0.0 }],
        spring: vec![Spring { point: [0.01, -0.02, 0.0], stiffness: 50.0, damping: 0.0 }],
        ..Default::default()
    }
}

/// With no damping, every fixture is a potential: the joint torque it renders is −∂E/∂q, which
/// central differences of the energy give without the renderer's Jacobians or gradients.
#[test]
fn the_rendered_torque_is_minus_the_gradient_of_the_fixtures_energy() {
    let m = model();
    let mut renderer = FixtureRenderer::new(&m, &all_engaged()).unwrap();
    let qd = [0.0; 3];
    for q in [[0.3, 0.4, 0.02], [-0.5, 0.1, 0.015], [0.2, 0.8, 0.025]] {
        let mut tau = [0.0; 3];
        let at = renderer.add_torque(&q, &qd, &mut tau).unwrap();
        assert!(at.contact && at.energy > 0.0, "{at:?} at {q:?}");
        for k in 0..3 {
            let h = 1e-7;
            let mut energy = |x: f64| {
                let mut p = q;
                p[k] += x;
                renderer.add_torque(&p, &qd, &mut [0.0; 3]).unwrap().energy
            };
            let slope = (energy(h) - energy(-h)) / (2.0 * h);
            let scale = tau.iter().map(|t| t.abs()).fold(1e-6, f64::max);
            assert!(
                (tau[k] + slope).abs() < 1e-5 * scale,
                "joint {k} at {q:?}: τ {} against −∂E/∂q {}",
                tau[k],
                -slope
            );
        }
    }
}

/// The wall pushes along the instrument against the depth it is past, its force's power is the
/// joint torque's (`Fᵀ v = τᵀ q̇`), and short of the wall nothing is rendered.
#[test]
fn a_wall_pushes_the_tip_back_along_the_instrument_and_only_past_its_depth() {
    let m = model();
    let q = [0.2, 0.3, 0.02];
    let qd = [0.1, -0.2, 0.01];
    let mut free = FixtureRenderer::new(&m, &wall(0.5, 1000.0, 5.0)).unwrap();
    let mut tau = [0.0; 3];
    let nothing = free.add_torque(&q, &qd, &mut tau).unwrap();
    assert_eq!((tau, nothing.contact, nothing.energy), ([0.0; 3], false, 0.0));
    let mut pressed = FixtureRenderer::new(&m, &wall(0.0, 1000.0, 5.0)).unwrap();
    let at = pressed.add_torque(&q, &qd, &mut tau).unwrap();
    assert!(at.contact);
    // The tip's velocity from differences of its position, independent of the Jacobian.
    let tip = |q: &[f64; 3]| {
        let mut p = arash_core::force::FrameForce::new(&m, "instrument_tip", "remote_centre", 1e-3).unwrap();
        p.map(q, &[0.0; 3], &[0.0; 3]).position
    };
    let h = 1e-7;
    let ahead: [f64; 3] = std::array::from_fn(|k| q[k] + h * qd[k]);
    let behind: [f64; 3] = std::array::from_fn(|k| q[k] - h * qd[k]);
    let (a, b) = (tip(&ahead), tip(&behind));
    let v: [f64; 3] = std::array::from_fn(|i| (a[i] - b[i]) / (2.0 * h));
    let power_tip: f64 = (0..3).map(|i| at.force[i] * v[i]).sum();
    let power_joints: f64 = (0..3).map(|k| tau[k] * qd[k]).sum();
    assert!(
        (power_tip - power_joints).abs() < 1e-6 * power_joints.abs().max(1e-9),
        "{power_tip} against {power_joints}"
    );
    // Along the instrument, into the eye: the tip's direction from the remote centre.
    let centre = {
        let mut p = arash_core::force::FrameForce::new(&m, "remote_centre", "remote_centre", 1e-3).unwrap();
        p.map(&q, &[0.0; 3], &[0.0; 3]).position
    };
    let tip_now = tip(&q);
    let along: [f64; 3] = std::array::from_fn(|i| tip_now[i] - centre[i]);
    let norm = along.iter().map(|x| x * x).sum::<f64>().sqrt();
    let cosine = (0..3).map(|i| at.force[i] * along[i]).sum::<f64>() / (norm * norm_of(&at.force));
    assert!((cosine + 1.0).abs() < 1e-9, "the wall's force is not against the instrument: cos {cosine}");
}

fn norm_of(v: &[f64; 3]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// On ARASH:ASiST the depth moves with the insertion alone, so a wall meets the insertion's
/// damping `b` (the URDF's 2 N·s/m): the bound is Colgate and Schenkel's `(b − |B|)/(T/2 + L)`.
#[test]
fn a_walls_bound_is_colgate_and_schenkels_on_the_insertion() {
    let m = model();
    let b = m.cad_parameters()[m.layout().viscous(2)];
    for (latency, damping) in [(0.0, 0.0), (0.0, 0.5), (1e-3, 0.0)] {
        let looped = cad_loop(latency);
        let bound = (b - damping) / (0.5e-3 + latency);
        let below = check_passivity(&m, &wall(0.01, 0.99 * bound, damping), &looped).unwrap();
        let found = below.fixtures[0].stiffness_bound.unwrap();
        assert!((found - bound).abs() < 1e-9 * bound, "bound {found} against Colgate's {bound}");
        let refused = check_passivity(&m, &wall(0.01, 1.01 * bound, damping), &looped).unwrap_err();
        match &refused {
            FixtureError::AbovePassivity { field, bound: said, .. } => {
                assert_eq!(field, "wall[0].stiffness");
                assert!((said - bound).abs() < 1e-9 * bound);
            }
            other => panic!("{other}"),
        }
        assert!(refused.to_string().contains(&format!("{:.4}", bound)), "{refused}");
    }
    // Compensating half the viscous friction halves what is left, and the bound with it.
    let half = RenderLoop::of_model(&m, &m.cad_parameters(), 0.5, 1e-3, 0.0).unwrap();
    let bound = check_passivity(&m, &wall(0.01, 1.0, 0.0), &half).unwrap().fixtures[0].stiffness_bound.unwrap();
    assert!((bound - 0.5 * b / 0.5e-3).abs() < 1e-9 * bound);
}

/// A joint with no damping left cannot render a spring passively in any direction it moves, and
/// fixtures each within their own bound are refused together where they add up past it.
#[test]
fn fixtures_are_refused_where_nothing_damps_them_or_where_they_add_up_past_the_damping() {
    let m = model();
    let mut params = m.cad_parameters();
    params[m.layout().viscous(2)] = 0.0;
    let undamped = RenderLoop::of_model(&m, &params, 0.0, 1e-3, 0.0).unwrap();
    let e = check_passivity(&m, &wall(0.01, 1.0, 0.0), &undamped).unwrap_err().to_string();
    assert!(e.starts_with("wall[0].stiffness = 1 N/m is above the passivity bound 0.0000 N/m"), "{e}");
    let looped = cad_loop(0.0);
    let alone = check_passivity(&m, &wall(0.01, 3000.0, 0.0), &looped).unwrap();
    assert!(alone.together < 1.0);
    let mut two = wall(0.01, 3000.0, 0.0);
    two.wall.push(DepthWall { depth_m: 0.02, stiffness: 3000.0, damping: 0.0 });
    match check_passivity(&m, &two, &looped).unwrap_err() {
        FixtureError::TogetherAbovePassivity { share_percent, .. } => {
            assert!((share_percent - 150.0).abs() < 1e-6, "{share_percent}")
        }
        other => panic!("{other}"),
    }
}

/// A sampled wall on the insertion (mass, the damping left, the wall's spring held between
/// samples), driven through a sinusoidal press at every frequency up to Nyquist: at the bound
/// the port takes in energy at every frequency (passive), and 20 % above it there is a frequency
/// at which it gives energy out. The wall's torque comes from the renderer.
#[test]
fn at_its_bound_a_sampled_wall_is_passive_and_above_it_gives_energy_out() {
    let m = model();
    let b = m.cad_parameters()[m.layout().viscous(2)];
    let looped = cad_loop(0.0);
    let bound = check_passivity(&m, &wall(0.0, 1.0, 0.0), &looped).unwrap().fixtures[0].stiffness_bound.unwrap();
    let least = |stiffness: f64| {
        let mut renderer = FixtureRenderer::new(&m, &wall(0.0, stiffness, 0.0)).unwrap();
        let (t, steps, sub) = (looped.period_s, 1000, 100);
        let mut worst = f64::INFINITY;
        // Whole cycles in a one-second window, at frequencies up to just below Nyquist.
        for cycles in (1..500).step_by(6).chain(490..500) {
            let w = std::f64::consts::TAU * cycles as f64 / (steps as f64 * t);
            let x = |s: f64| 0.01 + 0.002 * (w * s).sin();
            // The energy into the port, ∫ F dx with F = b ẋ − f_wall: the hand's force on it (the
            // device's mass stores nothing over whole cycles).
            let mut energy = 0.0;
            for n in 0..steps {
                let s0 = n as f64 * t;
                let mut tau = [0.0; 3];
                renderer.add_torque(&[0.0, 0.3, x(s0)], &[0.0; 3], &mut tau).unwrap();
                for j in 0..sub {
                    let (a, c) = (s0 + t * j as f64 / sub as f64, s0 + t * (j + 1) as f64 / sub as f64);
                    let v = 0.002 * w * (w * 0.5 * (a + c)).cos();
                    energy += (b * v - tau[2]) * (x(c) - x(a));
                }
            }
            worst = worst.min(energy / cycles as f64);
        }
        worst
    };
    assert!(least(0.999 * bound) >= -1e-12, "at the bound the wall gave energy out: {}", least(0.999 * bound));
    assert!(least(1.2 * bound) < 0.0, "20 % above the bound the wall is still passive");
}
