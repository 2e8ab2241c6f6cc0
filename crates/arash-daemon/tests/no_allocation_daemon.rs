//! The control thread allocates nothing per cycle: 10^4 cycles of the real loop
//! (`rt::runner::run`: request queue, control cycle, safety, log queue, status) against the mock
//! motor in process, enabling and playing a trajectory inside the counted window, with the
//! hand's force observer, its tip map and its thresholds running on every cycle.

#[path = "../../arash-core/tests/common/counting.rs"]
mod counting;

use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use arash_core::control::{standard_controller, ControllerKind, Faults, RobustGains, Trajectory};
use arash_core::sim::Scenario;
use arash_daemon::config::DaemonConfig;
use arash_daemon::drive_config::DriveConfig;
use arash_daemon::rt::clock::Pace;
use arash_daemon::rt::cycle::{ControlCycle, Request};
use arash_daemon::rt::reference::RunRequest;
use arash_daemon::rt::runner::{run, Queues, Shared};
use arash_mock::{FaultPlan, InProcessLink, MockMotor};
use counting::{allocations, watch_this_thread, Counting};

#[global_allocator]
static ALLOCATOR: Counting = Counting;

#[test]
fn thirteen_thousand_control_cycles_of_a_run_and_the_haptic_mode_allocate_nothing() {
    let model = arash_core::arash_asist();
    let cfg = DaemonConfig::default().cycle_config(&model).unwrap();
    let controller = standard_controller(
        ControllerKind::Robust,
        &model,
        &model.cad_parameters(),
        Some(&RobustGains::paper(&model).unwrap()),
    )
    .unwrap();
    // Thresholds far above anything the hand-free run reaches: every cycle evaluates them.
    let force = arash_daemon::rt::force::ForceConfig {
        contact: Some(vec![50.0; 3]),
        collision: Some(vec![100.0; 3]),
        ..Default::default()
    };
    let setup = arash_daemon::rt::force::ForceSetup::resolve(&model, &force, None, 1000.0).unwrap();
    assert_eq!(setup.frame.as_deref(), Some("instrument_tip"));
    let cycle =
        ControlCycle::new(cfg, controller).with_force(setup.build(&model, &model.cad_parameters(), &[]).unwrap());
    // The rig is the CAD model, so that the haptic mode's compensation holds the arm with no hand
    // on it (a perturbed rig drifts into its position limits meanwhile, as it should).
    let motor = MockMotor::new(&model, &cad_rig(&model), DriveConfig::default(), FaultPlan::default()).unwrap();
    let mut link = InProcessLink::new(motor);

    let (mut requests, request_rx) = rtrb::RingBuffer::new(8);
    let (garbage_tx, _garbage_rx) = rtrb::RingBuffer::new(8);
    let (log_tx, mut log_rx) = rtrb::RingBuffer::new(4096);
    let shared = Arc::new(Shared::default());
    let run_request =
        Box::new(RunRequest { id: 1, trajectory: Trajectory::PaperValidation { omega: 0.9 }, duration_s: 5.0 });
    // Then the haptic mode, every fixture engaged wherever the run leaves the arm (a wall behind
    // the remote centre, a cone narrower than any pose, a field and a spring), each with the
    // least stiffness, since with no hand on it a fixture moves a transparent arm to its limits.
    let fixtures = arash_core::haptics::Fixtures {
        wall: vec![arash_core::haptics::DepthWall { depth_m: -0.02, stiffness: 1e-6, damping: 0.0 }],
        cone: vec![arash_core::haptics::Cone {
            axis: [1.0, 0.0, 0.0],
            half_angle_deg: 1.0,
            stiffness: 1e-9,
            damping: 0.0,
        }],
        viscous: vec![arash_core::haptics::ViscousField { damping: 1e-6 }],
        spring: vec![arash_core::haptics::Spring { point: [0.0, 0.0, 0.0], stiffness: 1e-6, damping: 0.0 }],
        ..Default::default()
    };
    // With the inertia feed-forward on, whose matrices are the law's own buffers.
    let config = arash_daemon::rt::haptic::HapticConfig { inertia_compensation: 0.5, ..Default::default() };
    let haptic =
        arash_daemon::rt::haptic::HapticMode::build(&model, (&model.cad_parameters(), &[]), &config, &fixtures, 1e-3)
            .unwrap();
    let thread_shared = shared.clone();
    let control = std::thread::spawn(move || {
        let queues = Queues { requests: request_rx, garbage: garbage_tx, log: log_tx };
        watch_this_thread();
        // 0.2 ms periods: the loop is the real one, only faster than the rig's 1 kHz.
        run(cycle, &mut link, queues, &thread_shared, Duration::from_micros(200), Pace::Deadline);
    });
    let wait_for = |cycles: u64, log_rx: &mut rtrb::Consumer<_>| {
        while shared.cycle.load(Ordering::Acquire) < cycles {
            while log_rx.pop().is_ok() {}
            std::thread::sleep(Duration::from_micros(500));
        }
    };
    wait_for(100, &mut log_rx);
    let before = allocations();
    requests.push(Request::Enable).ok().unwrap();
    wait_for(200, &mut log_rx);
    requests.push(Request::Run(run_request)).ok().unwrap();
    wait_for(10_200, &mut log_rx);
    // Held to rest first: a transparent arm let go while it moves coasts into its limits.
    requests.push(Request::Hold).ok().unwrap();
    wait_for(11_200, &mut log_rx);
    requests.push(Request::Haptic(Box::new(haptic))).ok().unwrap();
    wait_for(13_200, &mut log_rx);
    let haptic_phase = shared.phase.load(Ordering::Relaxed);
    let faults = Faults(shared.faults.load(Ordering::Relaxed));
    let during = allocations() - before;
    shared.stop.store(true, Ordering::Release);
    control.join().unwrap();
    assert!(faults.is_empty(), "the run and the haptic mode went without faults: {:?}", faults.names());
    assert_eq!(shared.mode.load(Ordering::Relaxed), 0, "disabled after stopping");
    assert!(shared.run_id.load(Ordering::Relaxed) == 1 || shared.last_run_ended.load(Ordering::Relaxed) == 1);
    assert_eq!(haptic_phase, 3, "the haptic mode was on");
    assert_eq!(during, 0, "{during} allocations in 1.3·10^4 control cycles");
}

/// A simulated rig whose truth is the CAD model: its parameters, friction and cable stiffness.
fn cad_rig(model: &arash_core::Model) -> Scenario {
    let (params, layout) = (model.cad_parameters(), model.layout());
    let mut scenario = Scenario::default();
    let truth = &mut scenario.truth;
    truth.perturbation = 0.0;
    truth.viscous = (0..3).map(|k| params[layout.viscous(k)]).collect();
    truth.coulomb = (0..3).map(|k| params[layout.coulomb(k)]).collect();
    truth.stiffness = (0..3).map(|k| params[layout.stiffness(k)]).collect();
    scenario
}
