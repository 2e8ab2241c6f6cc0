//! The daemon's safety rules, each at its exact boundary, driving the control cycle one cycle at
//! a time through a scripted motor link.

use arash_core::control::{Controller, ControllerKind, Desired, Faults};
use arash_core::record::Mode;
use arash_daemon::config::DaemonConfig;
use arash_daemon::link::frame::{drive_fault, status};
use arash_daemon::link::{Command, LinkStats, MotorLink, Telemetry};
use arash_daemon::rt::cycle::{ControlCycle, CycleConfig, Event, Request};

/// A drive that echoes the current it was sent, switches its power stage as commanded and
/// clears its faults on CLEAR_FAULT, unless told otherwise. Its telemetry answers the previous
/// command, as a real drive's does.
struct Script {
    telemetry: Telemetry,
    deliver: bool,
    echo: bool,
    /// Whether DISABLE switches the power stage off.
    obeys_disable: bool,
    /// Whether CLEAR_FAULT clears the fault bits.
    clears: bool,
    /// Whether ENABLE switches the power stage on.
    obeys_enable: bool,
    /// Whether the fault bits are reported on every poll, telemetry or not (a CANopen master's).
    faults_always: bool,
    sent: Vec<Command>,
}

impl Script {
    fn new() -> Self {
        Self {
            telemetry: Telemetry::new(3),
            deliver: true,
            echo: true,
            obeys_disable: true,
            clears: true,
            obeys_enable: true,
            faults_always: false,
            sent: Vec::new(),
        }
    }

    fn last(&self) -> Command {
        *self.sent.last().expect("something was sent")
    }
}

impl MotorLink for Script {
    fn send(&mut self, command: &Command) -> std::io::Result<()> {
        if let (true, Command::Current { amps, .. }) = (self.echo, command) {
            self.telemetry.amps = *amps;
        }
        match command {
            Command::Enable if self.telemetry.faults == 0 && self.obeys_enable => {
                self.telemetry.status = status::ENABLED
            }
            Command::Disable if self.obeys_disable => self.telemetry.status = status::BRAKE,
            Command::ClearFault if self.clears => self.telemetry.faults = 0,
            _ => {}
        }
        self.sent.push(*command);
        Ok(())
    }

    fn poll(&mut self, out: &mut Telemetry) -> std::io::Result<bool> {
        if !self.deliver {
            if self.faults_always {
                out.faults = self.telemetry.faults;
            }
            return Ok(false);
        }
        self.telemetry.seq = self.telemetry.seq.wrapping_add(1);
        self.telemetry.device_time_us = self.telemetry.device_time_us.wrapping_add(1000);
        *out = self.telemetry;
        Ok(true)
    }

    fn stats(&self) -> LinkStats {
        LinkStats::default()
    }
}

/// Commands a fixed torque.
struct Constant(Vec<f64>);

impl Controller for Constant {
    fn kind(&self) -> ControllerKind {
        ControllerKind::Pd
    }
    fn reset(&mut self) {}
    fn step(&mut self, _: f64, _: &[f64], _: &[f64], _: &Desired, tau: &mut [f64]) {
        tau.copy_from_slice(&self.0);
    }
}

fn config(edit: impl FnOnce(&mut DaemonConfig)) -> CycleConfig {
    let mut c = DaemonConfig::default();
    edit(&mut c);
    let mut cfg = c.cycle_config(&arash_core::arash_asist()).unwrap();
    cfg.approach_speed = vec![0.5, 0.5, 0.01];
    cfg
}

struct Rig {
    cycle: ControlCycle,
    link: Script,
    n: u64,
    kt: Vec<f64>,
}

impl Rig {
    fn new(torque: [f64; 3], edit: impl FnOnce(&mut DaemonConfig)) -> Self {
        let cfg = config(edit);
        let kt = cfg.drive.torque_constant.clone();
        Self { cycle: ControlCycle::new(cfg, Box::new(Constant(torque.to_vec()))), link: Script::new(), n: 0, kt }
    }

    fn step(&mut self) -> Vec<Event> {
        self.cycle.step(&mut self.link, self.n);
        self.n += 1;
        let mut events = Vec::new();
        self.cycle.drain_events(|e| events.push(e));
        events
    }

    fn steps(&mut self, n: usize) {
        for _ in 0..n {
            self.step();
        }
    }

    fn enable(&mut self) {
        self.cycle.request(Request::Enable);
        self.step();
        assert_eq!(self.cycle.mode(), Mode::Enabled);
        assert_eq!(self.link.last(), Command::Enable);
    }

    /// Joint torque of the last current command (zero for other frames).
    fn sent_torque(&self) -> [f64; 3] {
        match self.link.last() {
            Command::Current { amps, .. } => [0, 1, 2].map(|k| f64::from(amps[k]) * self.kt[k]),
            _ => [0.0; 3],
        }
    }
}

#[test]
fn enabling_needs_valid_telemetry_first() {
    let mut rig = Rig::new([0.0; 3], |_| {});
    rig.link.deliver = false;
    rig.cycle.request(Request::Enable);
    assert_eq!(rig.step(), vec![Event::EnableRefused]);
    assert_eq!(rig.cycle.mode(), Mode::Disabled);
    assert_eq!(rig.link.last(), Command::Disable, "a disabled daemon commands the drive off");
    rig.link.deliver = true;
    rig.step();
    rig.enable();
}

#[test]
fn the_link_timeout_holds_for_n_minus_1_cycles_and_trips_at_n_then_ramps_to_zero() {
    let mut rig = Rig::new([0.5, -0.5, 1.0], |_| {});
    let n = rig.cycle.record().q.len(); // 3 joints
    assert_eq!(n, 3);
    rig.step();
    rig.enable();
    rig.steps(20);
    let held = rig.sent_torque();
    assert!((held[2] - 1.0).abs() < 1e-6, "{held:?}");
    // A gap of N − 1 = 19 cycles: the last command is repeated, then the law at the reference is
    // sent (for this constant law, the same torque), and nothing latches.
    rig.link.deliver = false;
    for _ in 0..19 {
        rig.step();
        assert_eq!(rig.sent_torque(), held);
    }
    assert_eq!(rig.cycle.faults(), Faults::NONE);
    rig.link.deliver = true;
    rig.steps(5);
    assert_eq!(rig.cycle.mode(), Mode::Enabled);
    // A gap of N = 20 cycles latches on its 20th cycle.
    rig.link.deliver = false;
    for _ in 0..19 {
        rig.step();
    }
    assert_eq!(rig.cycle.faults(), Faults::NONE);
    let events = rig.step();
    assert!(events.contains(&Event::FaultLatched(Faults::LINK_TIMEOUT)), "{events:?}");
    assert_eq!(rig.cycle.mode(), Mode::Faulted);
    // Ramp: 10 cycles (10 ms) of shrinking torque, the last at zero, then the drive is disabled.
    let mut previous = held[2].abs();
    let first = rig.sent_torque()[2];
    assert!((first - 0.9).abs() < 1e-6, "the ramp starts one step down: {first}");
    for _ in 0..9 {
        rig.step();
        let now = rig.sent_torque()[2].abs();
        assert!(now < previous);
        previous = now;
    }
    assert_eq!(rig.sent_torque(), [0.0; 3]);
    rig.step();
    assert_eq!(rig.link.last(), Command::Disable);
    rig.link.deliver = true;
    rig.steps(10);
    assert_eq!(rig.cycle.mode(), Mode::Faulted, "faults latch after the link recovers");
}

#[test]
fn non_finite_telemetry_faults_with_zero_torque_at_once() {
    let mut rig = Rig::new([0.5, 0.5, 0.5], |_| {});
    rig.step();
    rig.enable();
    rig.steps(10);
    rig.link.echo = false;
    rig.link.telemetry.amps[1] = f32::NAN;
    let events = rig.step();
    assert!(events.contains(&Event::FaultLatched(Faults::NON_FINITE_STATE)), "{events:?}");
    assert_eq!(rig.link.last(), Command::Disable, "no current command in the faulting cycle");
}

#[test]
fn a_non_finite_command_faults_with_zero_torque_at_once() {
    for bad in [f64::NAN, f64::INFINITY] {
        let mut rig = Rig::new([0.0, bad, 0.0], |_| {});
        // Even a disabled daemon latches a controller that produces garbage.
        let events = rig.step();
        assert!(events.contains(&Event::FaultLatched(Faults::NON_FINITE_COMMAND)), "{events:?}");
        rig.cycle.request(Request::Enable);
        rig.steps(5);
        assert_eq!(rig.cycle.mode(), Mode::Faulted);
        assert!(rig.link.sent.iter().all(|c| !matches!(c, Command::Current { .. } | Command::Enable)));
    }
}

/// The rate limit is on what reaches the motor: a gap in telemetry, during which the last command
/// is repeated, must not let the limiter run ahead on commands that were never sent.
#[test]
fn the_rate_limit_holds_at_the_motor_across_a_gap_in_telemetry() {
    let mut rig = Rig::new([100.0, -100.0, 3.0], |c| c.link.hold_ms = 3.0);
    rig.step();
    rig.enable();
    rig.step();
    let first = rig.sent_torque();
    rig.link.deliver = false;
    for _ in 0..3 {
        rig.step();
        assert_eq!(rig.sent_torque(), first, "the last command is repeated during the hold");
        let logged = &rig.cycle.record().tau_cmd[..3];
        assert!(logged.iter().zip(first).all(|(l, f)| (l - f).abs() < 1e-6), "logged {logged:?}, sent {first:?}");
    }
    rig.link.deliver = true;
    rig.steps(3);
    // Default rate: 1 N·m per 1 ms cycle, between every two commands the motor gets.
    let torques: Vec<[f64; 3]> = rig
        .link
        .sent
        .iter()
        .filter_map(|c| match c {
            Command::Current { amps, .. } => Some([0, 1, 2].map(|k| f64::from(amps[k]) * rig.kt[k])),
            _ => None,
        })
        .collect();
    for pair in torques.windows(2) {
        for k in 0..3 {
            assert!((pair[1][k] - pair[0][k]).abs() <= 1.0 + 1e-6, "joint {k}: {:?} → {:?}", pair[0], pair[1]);
        }
    }
}

#[test]
fn torque_is_rate_limited_then_clamped_exactly_at_the_limit() {
    let mut rig = Rig::new([100.0, -100.0, 3.0], |_| {});
    rig.step();
    rig.enable();
    // Default rate: the full ±5 range in 10 ms, i.e. 1 N·m per 1 ms cycle.
    rig.step();
    let first = rig.sent_torque();
    assert!((first[0] - 1.0).abs() < 1e-6 && (first[1] + 1.0).abs() < 1e-6 && (first[2] - 1.0).abs() < 1e-6);
    rig.steps(10);
    let settled = rig.sent_torque();
    assert!((settled[0] - 5.0).abs() < 1e-6 && (settled[1] + 5.0).abs() < 1e-6, "clamped at ±5: {settled:?}");
    assert!((settled[2] - 3.0).abs() < 1e-6, "inside the limit, untouched: {settled:?}");
    assert_eq!(rig.cycle.faults(), Faults::NONE, "clamping is not a fault");
}

/// Counts that put joint `k` at `q`, rounding toward zero.
fn counts(cfg: &DaemonConfig, k: usize, q: f64) -> i32 {
    (q / cfg.drive.resolution(k)).trunc() as i32
}

#[test]
fn the_position_guard_trips_one_count_beyond_limit_plus_margin() {
    let relaxed = |c: &mut DaemonConfig| {
        c.safety.following_error = Some(vec![10.0; 3]);
        c.safety.velocity = Some(vec![1e6; 3]);
    };
    let mut c = DaemonConfig::default();
    relaxed(&mut c);
    let limits = c.safety_limits(&arash_core::arash_asist()).unwrap();
    let bound = limits.upper[0] + limits.margin[0];
    let inside = counts(&c, 0, bound);
    assert!(f64::from(inside) * c.drive.resolution(0) <= bound);
    assert!(f64::from(inside + 1) * c.drive.resolution(0) > bound);
    let mut rig = Rig::new([0.0; 3], relaxed);
    rig.step();
    rig.enable();
    rig.link.telemetry.counts[0] = inside;
    rig.steps(3);
    assert_eq!(rig.cycle.faults(), Faults::NONE);
    rig.link.telemetry.counts[0] = inside + 1;
    rig.step();
    assert_eq!(rig.cycle.faults(), Faults::POSITION_LIMIT);
}

#[test]
fn the_velocity_guard_trips_between_0_9_and_1_1_of_its_limit() {
    // The exact floating-point boundary is tested on the gate itself (arash-core safety tests);
    // here the estimated velocity from encoder counts brackets it.
    for (factor, trips) in [(0.9, false), (1.1, true)] {
        let mut rig = Rig::new([0.0; 3], |c| c.safety.following_error = Some(vec![10.0; 3]));
        let c = DaemonConfig::default();
        let limit = c.safety_limits(&arash_core::arash_asist()).unwrap().velocity[0];
        let start = -0.6;
        rig.link.telemetry.counts[0] = counts(&c, 0, start);
        rig.step();
        rig.enable();
        for i in 0..300 {
            let q = start + factor * limit * 1e-3 * f64::from(i);
            rig.link.telemetry.counts[0] = counts(&c, 0, q.min(0.7));
            rig.step();
        }
        assert_eq!(rig.cycle.faults().contains(Faults::VELOCITY_LIMIT), trips, "factor {factor}");
    }
}

#[test]
fn the_following_error_trips_one_count_beyond_its_limit() {
    let mut c = DaemonConfig::default();
    c.safety.velocity = Some(vec![1e6; 3]);
    let limit = c.following_error(&arash_core::arash_asist()).unwrap()[2];
    let inside = counts(&c, 2, limit);
    let mut rig = Rig::new([0.0; 3], |c| c.safety.velocity = Some(vec![1e6; 3]));
    rig.step();
    rig.enable(); // holds q = 0
    rig.link.telemetry.counts[2] = inside;
    rig.steps(3);
    assert_eq!(rig.cycle.faults(), Faults::NONE);
    rig.link.telemetry.counts[2] = inside + 1;
    rig.step();
    assert_eq!(rig.cycle.faults(), Faults::FOLLOWING_ERROR);
}

#[test]
fn a_current_mismatch_trips_after_exactly_its_cycle_count() {
    let mut rig = Rig::new([2.0, 0.0, 0.0], |_| {});
    rig.step();
    rig.enable();
    rig.steps(10);
    // The drive stops producing current on joint 0: it reports zero against 2 N·m sent, more
    // than 25 % of the 5 N·m limit.
    rig.link.echo = false;
    rig.link.telemetry.amps[0] = 0.0;
    for _ in 0..49 {
        rig.step();
    }
    assert_eq!(rig.cycle.faults(), Faults::NONE);
    rig.step();
    assert_eq!(rig.cycle.faults(), Faults::CURRENT_MISMATCH);
}

#[test]
fn a_drive_fault_latches_until_reset_and_reset_leaves_the_motors_disabled() {
    let mut rig = Rig::new([0.1; 3], |_| {});
    rig.step();
    rig.enable();
    rig.link.telemetry.faults = drive_fault::OVERCURRENT;
    rig.step();
    assert_eq!(rig.cycle.faults(), Faults::MOTOR);
    rig.link.telemetry.faults = 0;
    rig.steps(5);
    assert_eq!(rig.cycle.mode(), Mode::Faulted);
    rig.cycle.request(Request::Enable);
    assert_eq!(rig.step(), vec![Event::EnableRefused], "no enabling over a latched fault");
    rig.cycle.request(Request::ResetFault);
    rig.step();
    assert_eq!(rig.cycle.mode(), Mode::Disabled);
    assert_eq!(rig.link.last(), Command::ClearFault);
    rig.step();
    assert_eq!(rig.link.last(), Command::Disable);
    rig.enable();
}

#[test]
fn a_drive_left_powered_by_a_crashed_daemon_is_switched_off_in_the_first_cycle() {
    use arash_mock::{InProcessLink, MockMotor};
    let model = arash_core::arash_asist();
    let mut motor =
        MockMotor::new(&model, &arash_core::sim::Scenario::default(), Default::default(), Default::default()).unwrap();
    // The last current of the daemon that died: enough to swing the pitch joint.
    motor.power_on(&[0.0, 3.0, 0.0]);
    let mut link = InProcessLink::new(motor);
    let mut cycle = ControlCycle::new(config(|_| {}), Box::new(Constant(vec![0.0; 3])));
    cycle.step(&mut link, 0);
    assert!(!link.motor.enabled(), "the first frame of a new daemon switches the drive off");
    let pitch = link.motor.drive().encoder_counts(1);
    for n in 1..500 {
        cycle.step(&mut link, n);
        assert!(!link.motor.enabled(), "cycle {n}: the drive was powered again");
    }
    assert_eq!(link.motor.drive().encoder_counts(1), pitch, "the brake holds the pitch joint");
    assert_eq!(cycle.mode(), Mode::Disabled);
    assert_eq!(cycle.faults(), Faults::NONE, "a drive that obeys DISABLE is no fault");
}

#[test]
fn a_drive_that_stays_powered_against_disable_latches_drive_state_after_the_link_timeout() {
    let mut rig = Rig::new([0.0; 3], |_| {});
    rig.link.telemetry.status = status::ENABLED;
    rig.link.obeys_disable = false;
    for n in 1..20 {
        rig.step();
        assert_eq!(rig.link.last(), Command::Disable, "cycle {n}");
        assert_eq!(rig.cycle.faults(), Faults::NONE, "cycle {n}: within the drive's grace");
    }
    let events = rig.step();
    assert!(events.contains(&Event::FaultLatched(Faults::DRIVE_STATE)), "{events:?}");
    assert_eq!(rig.cycle.mode(), Mode::Faulted);
    rig.cycle.request(Request::Enable);
    assert_eq!(rig.step(), vec![Event::EnableRefused]);
    assert!(rig.link.sent.iter().all(|c| *c == Command::Disable), "nothing but DISABLE was ever sent");
}

/// Issue 57: a drive that switches its power stage off by itself (its e-stop input, safe torque
/// off), without a fault bit, latches in the cycle its telemetry says so. Nothing but DISABLE
/// follows until the operator resets and enables.
#[test]
fn a_drive_that_switches_itself_off_while_enabled_latches_drive_stopped_at_once() {
    let mut rig = Rig::new([0.1; 3], |_| {});
    rig.step();
    rig.enable();
    rig.steps(5);
    assert_eq!(rig.cycle.faults(), Faults::NONE);
    rig.link.telemetry.status = 0;
    let events = rig.step();
    assert!(events.contains(&Event::FaultLatched(Faults::DRIVE_STOPPED)), "{events:?}");
    assert_eq!(rig.cycle.mode(), Mode::Faulted);
    let before = rig.link.sent.len();
    rig.steps(50);
    assert!(rig.link.sent[before..].iter().all(|c| *c == Command::Disable), "never walked back to enabled");
    rig.cycle.request(Request::Enable);
    assert_eq!(rig.step(), vec![Event::EnableRefused]);
    rig.cycle.request(Request::ResetFault);
    rig.steps(3);
    assert_eq!(rig.cycle.mode(), Mode::Disabled, "the reset leaves it disabled");
    rig.enable();
    rig.steps(3);
    assert_eq!((rig.cycle.mode(), rig.cycle.faults()), (Mode::Enabled, Faults::NONE));
}

/// A drive that never confirms the enable latches after exactly `link.enable_timeout_ms` of
/// telemetry frames, rather than being commanded on until it enables by itself much later;
/// the link timeout (20 frames) is no limit on it: a CiA 402 drive walks three states first.
#[test]
fn a_drive_that_never_confirms_the_enable_latches_drive_stopped_after_the_enable_timeout() {
    let mut rig = Rig::new([0.1; 3], |c| c.link.enable_timeout_ms = 50.0);
    rig.link.obeys_enable = false;
    rig.step();
    rig.enable();
    for n in 1..50 {
        rig.step();
        assert_eq!(rig.cycle.faults(), Faults::NONE, "frame {n}: within the drive's grace");
    }
    let events = rig.step();
    assert!(events.contains(&Event::FaultLatched(Faults::DRIVE_STOPPED)), "{events:?}");
}

/// A drive that confirms the enable late (a brake's release) measures no current meanwhile:
/// that is no current mismatch, however long it takes within `link.enable_timeout_ms`; once it
/// has confirmed, a measurement that departs from the command latches as before.
#[test]
fn a_drive_that_confirms_late_is_no_current_mismatch_until_it_has_confirmed() {
    let torque = [0.1, -0.1, 0.2];
    let mut rig = Rig::new(torque, |c| c.safety.mismatch_fraction = Some(0.01));
    rig.link.obeys_enable = false;
    rig.link.echo = false; // a drive that is not enabled measures no current
    rig.step();
    rig.enable();
    for n in 1..300 {
        rig.step();
        assert_eq!(rig.cycle.faults(), Faults::NONE, "frame {n}: unconfirmed, within link.enable_timeout_ms");
    }
    rig.link.telemetry.status = status::ENABLED;
    rig.link.echo = true;
    rig.steps(100);
    assert_eq!((rig.cycle.mode(), rig.cycle.faults()), (Mode::Enabled, Faults::NONE));
    assert!(rig.sent_torque().iter().zip(torque).all(|(s, t)| (s - t).abs() < 1e-6), "{:?}", rig.sent_torque());
    // Confirmed: a drive that stops delivering the current it is sent is a mismatch again.
    rig.link.echo = false;
    rig.link.telemetry.amps.fill(0.0);
    rig.steps(60);
    assert!(rig.cycle.faults().contains(Faults::CURRENT_MISMATCH), "{:?}", rig.cycle.faults());
}

/// A link that supervises its drives itself reports a fault while no telemetry comes (a
/// CANopen drive that rebooted sends no process data): the cycle latches it, enabled or not.
#[test]
fn a_fault_the_link_reports_without_telemetry_latches() {
    let mut rig = Rig::new([0.0; 3], |_| {});
    rig.link.faults_always = true;
    rig.steps(3);
    rig.link.deliver = false;
    rig.link.telemetry.faults = drive_fault::FIELDBUS;
    let events = rig.step();
    assert!(events.contains(&Event::FaultLatched(Faults::MOTOR)), "{events:?}");
}

#[test]
fn a_reset_outlasts_the_stale_fault_in_the_drives_telemetry_and_then_enable_works() {
    // The drive latched HOST_TIMEOUT while no host talked to it (a daemon restart).
    let mut rig = Rig::new([0.1; 3], |_| {});
    rig.link.telemetry.faults = drive_fault::HOST_TIMEOUT;
    rig.step();
    assert_eq!(rig.cycle.faults(), Faults::MOTOR);
    rig.cycle.request(Request::ResetFault);
    // This cycle's telemetry still shows the fault: it answers the frame sent before the reset.
    let events = rig.step();
    assert_eq!(events, vec![Event::FaultsCleared], "the stale fault bit must not re-latch");
    assert_eq!(rig.link.last(), Command::ClearFault);
    assert_eq!(rig.cycle.mode(), Mode::Disabled);
    rig.step();
    assert_eq!(rig.link.last(), Command::Disable, "the drive confirmed: back to commanding it off");
    rig.enable();
    rig.steps(5);
    assert_eq!(rig.cycle.mode(), Mode::Enabled);
}

#[test]
fn enabling_waits_for_the_drive_to_confirm_a_reset_and_a_fault_that_stays_latches_again() {
    let mut rig = Rig::new([0.1; 3], |_| {});
    rig.link.telemetry.faults = drive_fault::OVERTEMPERATURE;
    rig.link.clears = false; // still hot
    rig.step();
    rig.cycle.request(Request::ResetFault);
    rig.step();
    rig.cycle.request(Request::Enable);
    assert_eq!(rig.step(), vec![Event::EnableRefused], "the drive has not confirmed the reset");
    // The reset lasts the link timeout (20 cycles), sending CLEAR_FAULT each cycle.
    rig.steps(17);
    assert_eq!(rig.cycle.mode(), Mode::Disabled);
    assert_eq!(rig.link.last(), Command::ClearFault);
    let events = rig.step();
    assert!(events.contains(&Event::FaultLatched(Faults::MOTOR)), "{events:?}");
    assert!(rig.link.sent.iter().all(|c| !matches!(c, Command::Current { .. } | Command::Enable)));
}

/// A CAN drive in the same process: answers every host frame with one telemetry set, until told
/// to fall silent.
struct CanDrive {
    bus: arash_daemon::link::can::InProcessBus,
    seq: u16,
    silent: bool,
}

impl CanDrive {
    fn answer(&mut self) {
        use arash_daemon::link::can::{telemetry_frame, CanBus};
        let mut frames = 0;
        while let Ok(Some(_)) = self.bus.receive() {
            frames += 1;
        }
        if frames == 0 || self.silent {
            return;
        }
        let mut t = Telemetry::new(3);
        t.seq = self.seq;
        self.seq = self.seq.wrapping_add(1);
        for j in 0..3 {
            self.bus.send(&telemetry_frame(&t, j)).unwrap();
        }
    }
}

#[test]
fn over_can_the_link_timeout_holds_for_n_minus_1_cycles_and_trips_at_n() {
    use arash_daemon::link::can::{CanLink, InProcessBus};
    for (gap, trips) in [(19, false), (20, true)] {
        let (host, drive) = InProcessBus::pair(256);
        let mut link = CanLink::new(host, 3);
        let mut drive = CanDrive { bus: drive, seq: 0, silent: false };
        let mut cycle = ControlCycle::new(config(|_| {}), Box::new(Constant(vec![0.2; 3])));
        let mut n = 0;
        let mut step = |cycle: &mut ControlCycle, link: &mut CanLink<InProcessBus>, drive: &mut CanDrive| {
            cycle.step(link, n);
            n += 1;
            drive.answer();
        };
        for _ in 0..3 {
            step(&mut cycle, &mut link, &mut drive);
        }
        cycle.request(Request::Enable);
        for _ in 0..10 {
            step(&mut cycle, &mut link, &mut drive);
        }
        assert_eq!(cycle.mode(), Mode::Enabled);
        drive.silent = true;
        // The last answered frame's telemetry is read in the next cycle; silence starts after it.
        step(&mut cycle, &mut link, &mut drive);
        for _ in 0..gap {
            step(&mut cycle, &mut link, &mut drive);
        }
        assert_eq!(cycle.faults().contains(Faults::LINK_TIMEOUT), trips, "gap of {gap} cycles");
    }
}

/// The mock motor in process, whose telemetry reaches the daemon only every `every`-th frame:
/// the plant still moves each period under the frame it was sent, as it does behind a stalled
/// pseudo-terminal (docs/demo.md, "A stall long enough to end a run").
struct Stalling {
    link: arash_mock::InProcessLink,
    every: u64,
    frames: u64,
}

impl MotorLink for Stalling {
    fn send(&mut self, command: &Command) -> std::io::Result<()> {
        self.frames += 1;
        self.link.send(command)
    }

    fn poll(&mut self, out: &mut Telemetry) -> std::io::Result<bool> {
        let mut latest = *out;
        if self.link.poll(&mut latest)? && self.frames.is_multiple_of(self.every) {
            *out = latest;
            return Ok(true);
        }
        Ok(false)
    }

    fn stats(&self) -> LinkStats {
        self.link.stats()
    }
}

/// Tracks the paper's validation trajectory with the robust controller (the paper's gains, CAD
/// parameters) while telemetry arrives only every `every`-th cycle; returns the faults and the
/// largest insertion error (m) of the run.
fn track_with_telemetry_every(every: u64, edit: impl FnOnce(&mut DaemonConfig)) -> (Faults, f64) {
    use arash_core::control::{standard_controller, RobustGains, Trajectory};
    use arash_daemon::rt::reference::{Phase, RunRequest};
    use arash_mock::{InProcessLink, MockMotor};
    let model = arash_core::arash_asist();
    let gains = RobustGains::paper(&model).unwrap();
    let controller =
        standard_controller(ControllerKind::Robust, &model, &model.cad_parameters(), Some(&gains)).unwrap();
    let mut cycle = ControlCycle::new(config(edit), controller);
    let motor =
        MockMotor::new(&model, &arash_core::sim::Scenario::default(), Default::default(), Default::default()).unwrap();
    let mut link = Stalling { link: InProcessLink::new(motor), every: 1, frames: 0 };
    let mut n = 0;
    let mut step = |cycle: &mut ControlCycle, link: &mut Stalling| {
        cycle.step(link, n);
        n += 1;
    };
    // The drive answers each frame in the next cycle: telemetry first, then enabling.
    step(&mut cycle, &mut link);
    step(&mut cycle, &mut link);
    cycle.request(Request::Enable);
    step(&mut cycle, &mut link);
    assert_eq!(cycle.mode(), Mode::Enabled);
    let run = RunRequest { id: 1, trajectory: Trajectory::PaperValidation { omega: 0.5 }, duration_s: 4.0 };
    cycle.request(Request::Run(Box::new(run)));
    while cycle.phase() != Phase::Run {
        step(&mut cycle, &mut link);
    }
    link.every = every;
    let mut worst = 0f64;
    while cycle.phase() == Phase::Run && cycle.mode() == Mode::Enabled {
        step(&mut cycle, &mut link);
        let r = cycle.record();
        worst = worst.max((r.q[2] - r.q_des[2]).abs());
    }
    (cycle.faults(), worst)
}

#[test]
fn telemetry_arriving_only_every_tenth_cycle_does_not_destabilise_the_robust_controller() {
    // Without stalls the paper's gains track the insertion to tens of µm.
    let (faults, steady) = track_with_telemetry_every(1, |_| {});
    assert_eq!(faults, Faults::NONE);
    assert!(steady < 1e-4, "insertion error {steady} m with every frame");
    // Nine stale cycles in ten, the longest stretch seen in the demo's logs on a loaded host, and
    // fourteen in fifteen: the last command is held for `link.hold_ms` (3 ms), then the law at the
    // reference is sent.
    for every in [10, 15] {
        let (faults, stalled) = track_with_telemetry_every(every, |_| {});
        assert_eq!(faults, Faults::NONE, "telemetry every {every}th cycle: insertion error reached {stalled} m");
        assert!(stalled < 1e-3, "insertion error {stalled} m with telemetry every {every}th cycle");
    }
    // Holding the last command until the link times out (the daemon's earlier rule) keeps the
    // feedback of a state 9 ms old: the insertion swings until the velocity limit latches.
    let (faults, _) = track_with_telemetry_every(10, |c| c.link.hold_ms = c.link.timeout_ms - 1.0);
    assert_eq!(faults, Faults::VELOCITY_LIMIT);
    // Sending only the feed-forward from the first stale cycle on lets the arm drift instead.
    let (faults, _) = track_with_telemetry_every(10, |c| c.link.hold_ms = 0.0);
    assert_eq!(faults, Faults::FOLLOWING_ERROR);
}

/// The hand's force observer in the cycle: an arm held at rest by its gravity torque, then a
/// torque it does not explain on the pitch (the drive's current rises as something pushes on
/// the instrument). The cycle whose estimate first reaches the collision threshold latches
/// `COLLISION` in its own record, abandons the run and floats the arm on the model's gravity
/// compensation with the drive still enabled; runs are refused until the operator's reset, which
/// holds the arm. Contacts come and go as events.
#[test]
fn a_collision_latches_in_the_cycle_its_estimate_crosses_the_threshold_and_the_arm_floats() {
    use arash_core::control::Trajectory;
    use arash_daemon::rt::force::ForceConfig;
    use arash_daemon::rt::force::ForceSetup;
    use arash_daemon::rt::reference::{Phase, RunRequest};
    let (model, params, gravity) = held_by_cad_gravity();
    let (contact, collision) = (vec![0.05, 0.05, 0.5], vec![0.2, 0.2, 2.0]);
    let force =
        ForceConfig { contact: Some(contact.clone()), collision: Some(collision.clone()), ..Default::default() };
    let setup = ForceSetup::resolve(&model, &force, None, 1000.0).unwrap();
    assert_eq!(setup.bandwidth_hz, vec![20.0; 3], "a hand's bandwidth without a model file's run");
    let monitor = setup.build(&model, &params, &[]).unwrap();
    let mut rig = Rig::new(gravity, |_| {});
    rig.cycle = ControlCycle::new(config(|_| {}), Box::new(Constant(gravity.to_vec()))).with_force(monitor);
    rig.step();
    rig.enable();
    let run = RunRequest { id: 7, trajectory: Trajectory::Hold { q: vec![0.0; 3] }, duration_s: 30.0 };
    assert!(rig.cycle.request(Request::Run(Box::new(run))).is_none());
    rig.steps(1200); // the approach lasts at least a second
    assert_eq!(rig.cycle.phase(), Phase::Run);
    let quiet = rig.cycle.record().tau_ext.iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(quiet < 1e-4, "held by its own gravity, nothing is external: {quiet}");
    // A push on the pitch: the drive's current now reads the gravity torque plus 0.5 N·m.
    rig.link.echo = false;
    let pushed = [gravity[0], gravity[1] + 0.5, gravity[2]];
    rig.link.telemetry.amps[..3].copy_from_slice(&[0, 1, 2].map(|k| (pushed[k] / rig.kt[k]) as f32));
    let (mut contact_at, mut latched_at) = (None, None);
    for i in 0..200 {
        let events = rig.step();
        let r = rig.cycle.record();
        let over = r.tau_ext.iter().zip(&collision).any(|(e, c)| e.abs() >= *c);
        if events.contains(&Event::ContactStarted) {
            contact_at.get_or_insert(i);
        }
        if events.contains(&Event::FaultLatched(Faults::COLLISION)) {
            assert!(over && r.faults.contains(Faults::COLLISION), "latched in the cycle that crossed: {r:?}");
            assert!(events.contains(&Event::RunEnded(7)), "{events:?}");
            latched_at = Some(i);
            break;
        }
        assert!(!over, "cycle {i} crossed the collision threshold without latching: {:?}", r.tau_ext);
    }
    let (contact_at, latched_at) = (contact_at.expect("a contact first"), latched_at.expect("a collision"));
    assert!(contact_at < latched_at, "{contact_at} {latched_at}");
    // 0.5 N·m through a 20 Hz lag reaches 0.2 N·m after ln(1/(1 − 0.4))/(2π·20) s = 4.1 ms.
    assert!((3..=6).contains(&latched_at), "latched after {latched_at} cycles");
    assert!(rig.cycle.take_garbage().is_some(), "the stopped run goes off the real-time thread");
    // Floating: enabled, holding where it is, commanding the model's gravity compensation.
    rig.steps(5);
    assert_eq!((rig.cycle.mode(), rig.cycle.phase()), (Mode::Enabled, Phase::Hold));
    let sent = rig.sent_torque();
    assert!((0..3).all(|k| (sent[k] - gravity[k]).abs() < 1e-5), "{sent:?} against {gravity:?}");
    let run = RunRequest { id: 8, trajectory: Trajectory::Hold { q: vec![0.0; 3] }, duration_s: 1.0 };
    assert!(rig.cycle.request(Request::Run(Box::new(run))).is_some(), "refused, handed back");
    assert_eq!(rig.step(), vec![Event::RunRefused]);
    // A model switch with its own observer does not walk the latch back: only the reset does.
    let switch = Request::Controller(
        Box::new(Constant(gravity.to_vec())),
        Some(Box::new(setup.build(&model, &params, &[]).unwrap())),
    );
    assert!(rig.cycle.request(switch).is_some(), "the old law and observer come back to be dropped");
    rig.steps(5);
    assert!(rig.cycle.record().faults.contains(Faults::COLLISION), "{:?}", rig.cycle.record().faults);
    let sent = rig.sent_torque();
    assert!((0..3).all(|k| (sent[k] - gravity[k]).abs() < 1e-5), "still floating: {sent:?}");
    // The push goes; the reset holds the arm and clears the fault.
    rig.link.telemetry.amps[..3].copy_from_slice(&[0, 1, 2].map(|k| (gravity[k] / rig.kt[k]) as f32));
    rig.steps(200);
    rig.cycle.request(Request::ResetFault);
    let events = rig.step();
    assert!(events.contains(&Event::FaultsCleared), "{events:?}");
    assert_eq!((rig.cycle.faults(), rig.cycle.record().faults), (Faults::NONE, Faults::NONE));
    assert_eq!(rig.cycle.mode(), Mode::Enabled);
}

/// ARASH:ASiST, its CAD parameters, and the CAD gravity torque at `q = 0`, which holds the arm
/// there.
fn held_by_cad_gravity() -> (arash_core::Model, Vec<f64>, [f64; 3]) {
    let model = arash_core::arash_asist();
    let params = model.cad_parameters();
    let mut gravity = [0.0; 3];
    arash_core::dynamics::gravity_torque(&model, &mut arash_core::Data::new(&model), &[0.0; 3], &params, &mut gravity);
    (model, params, gravity)
}

/// A model file switched to at run time (`ctl controller KIND --model FILE`) takes the hand's
/// observer with it. An arm held at rest by the CAD model's gravity torque reads nothing external
/// on the CAD model; switched to a model 20 % heavier, the observer on it reads the 20 % its
/// gravity says is missing (`τ_ext = g_model(q) − τ` at rest), and the old observer comes back to
/// be dropped off the real-time thread. Without a running observer the new one is handed back.
#[test]
fn a_model_switched_at_run_time_moves_the_force_observer_to_it() {
    use arash_daemon::rt::cycle::Garbage;
    use arash_daemon::rt::force::{ForceConfig, ForceSetup};
    let (model, params, gravity) = held_by_cad_gravity();
    let setup = ForceSetup::resolve(&model, &ForceConfig::default(), None, 1000.0).unwrap();
    let heavier: Vec<f64> = params.iter().map(|p| 1.2 * p).collect();
    let mut rig = Rig::new(gravity, |_| {});
    let monitor = setup.build(&model, &params, &[]).unwrap();
    rig.cycle = ControlCycle::new(config(|_| {}), Box::new(Constant(gravity.to_vec()))).with_force(monitor);
    rig.step();
    rig.enable();
    rig.steps(300);
    let held = rig.cycle.record().tau_ext.iter().map(|v| v.abs()).fold(0.0, f64::max);
    assert!(held < 1e-4, "held by the CAD gravity, nothing is external on the CAD model: {held}");
    let switch = Request::Controller(
        Box::new(Constant(gravity.to_vec())),
        Some(Box::new(setup.build(&model, &heavier, &[]).unwrap())),
    );
    let garbage = rig.cycle.request(switch);
    assert!(matches!(garbage, Some(Garbage::Controller(_, Some(_)))), "the old observer comes back to be dropped");
    rig.steps(300); // 20 Hz: 38 time constants
    let read = rig.cycle.record().tau_ext.clone();
    for k in 0..3 {
        let missing = 0.2 * gravity[k];
        assert!(
            (read[k] - missing).abs() <= 1e-3 * gravity[k].abs().max(1e-3),
            "joint {k}: {read:?} against {missing}"
        );
    }
    // A cycle without an observer keeps none, and hands the offered one back.
    let mut bare = Rig::new(gravity, |_| {});
    let offered = Request::Controller(
        Box::new(Constant(gravity.to_vec())),
        Some(Box::new(setup.build(&model, &heavier, &[]).unwrap())),
    );
    assert!(matches!(bare.cycle.request(offered), Some(Garbage::Controller(_, Some(_)))));
    bare.steps(10);
    assert!(bare.cycle.record().tau_ext.is_empty(), "no observer fields in a cycle that runs none");
}

/// The haptic mode: refused unless enabled and holding; once on, the command is the model's
/// compensation (the viscous friction's share left out) plus the fixtures' torque, handed over
/// from the controller's over 100 ms; hold hands it back the same way, with no step larger than
/// the difference over 100 cycles, and a fault ends it. A fixture file with a NaN or a stiffness over the passivity bound is refused before
/// anything is queued.
#[test]
fn the_haptic_mode_renders_its_wall_over_the_compensation_and_hands_over_without_a_step() {
    use arash_core::haptics::{DepthWall, FixtureRenderer, Fixtures};
    use arash_daemon::rt::cycle::Garbage;
    use arash_daemon::rt::force::{ForceConfig, ForceSetup};
    use arash_daemon::rt::haptic::{parse_fixtures, HapticConfig, HapticMode};
    let (model, params, gravity) = held_by_cad_gravity();
    let cfg = config(|_| {});
    assert_eq!(cfg.handover, 100, "the default handover");
    let setup = ForceSetup::resolve(&model, &ForceConfig::default(), None, 1000.0).unwrap();
    let mut rig = Rig::new(gravity, |_| {});
    rig.cycle = ControlCycle::new(cfg, Box::new(Constant(gravity.to_vec())))
        .with_force(setup.build(&model, &params, &[]).unwrap());
    // A wall 5 mm short of where the tip rests at q = 0, at a tenth of its bound.
    let wall =
        Fixtures { wall: vec![DepthWall { depth_m: -0.005, stiffness: 100.0, damping: 0.0 }], ..Default::default() };
    let haptic = || Box::new(HapticMode::build(&model, (&params, &[]), &HapticConfig::default(), &wall, 1e-3).unwrap());
    rig.step();
    assert!(matches!(rig.cycle.request(Request::Haptic(haptic())), Some(Garbage::Haptic(_))));
    assert_eq!(rig.step(), vec![Event::HapticRefused], "refused while disabled");
    rig.enable();
    rig.steps(50);
    assert!(rig.cycle.request(Request::Haptic(haptic())).is_none());
    assert_eq!(rig.step(), vec![Event::HapticStarted]);
    let mut expected = gravity;
    let rendered =
        FixtureRenderer::new(&model, &wall).unwrap().add_torque(&[0.0; 3], &[0.0; 3], &mut expected).unwrap();
    assert!((expected[2] - gravity[2]).abs() > 0.4, "the wall pushes 0.5 N: {expected:?} against {gravity:?}");
    // Entering and leaving, the command hands over from one source to the other over
    // `haptic.handover_ms` (100 cycles): no step larger than the wall's push over that many, and
    // none at the switch itself (to the current's single precision on the wire).
    let fade = (expected[2] - gravity[2]).abs() / 100.0;
    let walk = |rig: &mut Rig, mut last: [f64; 3]| {
        for _ in 0..200 {
            rig.step();
            let sent = rig.sent_torque();
            for k in 0..3 {
                assert!((sent[k] - last[k]).abs() <= fade + 1e-6, "joint {k}: {last:?} → {sent:?}");
            }
            last = sent;
        }
        last
    };
    let last = walk(&mut rig, gravity);
    assert!((0..3).all(|k| (last[k] - expected[k]).abs() < 1e-5), "{last:?} against {expected:?}");
    // The record carries the wall's force at the instrument, for the flight log.
    assert_eq!(rig.cycle.record().fixture_force, rendered.force.to_vec());
    // Hold leaves the mode; the command walks back to the law's.
    assert!(matches!(rig.cycle.request(Request::Hold), Some(Garbage::Haptic(_))));
    assert_eq!(rig.step(), vec![Event::HapticEnded]);
    let sent = rig.sent_torque();
    assert!((0..3).all(|k| (sent[k] - last[k]).abs() <= fade + 1e-6), "{last:?} → {sent:?}");
    let last = walk(&mut rig, sent);
    assert!((0..3).all(|k| (last[k] - gravity[k]).abs() < 1e-5), "{last:?} against {gravity:?}");
    assert_eq!(rig.cycle.record().fixture_force, vec![0.0; 3], "no fixtures outside the mode");
    // Fixtures switched in the mode hand over too: from free space to the wall under the tip,
    // no step larger than the same fade.
    let free = Box::new(
        HapticMode::build(&model, (&params, &[]), &HapticConfig::default(), &Fixtures::default(), 1e-3).unwrap(),
    );
    assert!(rig.cycle.request(Request::Haptic(free)).is_none());
    assert_eq!(rig.step(), vec![Event::HapticStarted]);
    let sent = rig.sent_torque();
    let last = walk(&mut rig, sent);
    assert!((0..3).all(|k| (last[k] - gravity[k]).abs() < 1e-5), "free space: {last:?} against {gravity:?}");
    assert!(matches!(rig.cycle.request(Request::Haptic(haptic())), Some(Garbage::Haptic(_))));
    assert_eq!(rig.step(), vec![Event::FixturesSwitched]);
    let sent = rig.sent_torque();
    assert!((0..3).all(|k| (sent[k] - last[k]).abs() <= fade + 1e-6), "{last:?} → {sent:?}");
    let last = walk(&mut rig, sent);
    assert!((0..3).all(|k| (last[k] - expected[k]).abs() < 1e-5), "{last:?} against {expected:?}");
    assert!(matches!(rig.cycle.request(Request::Hold), Some(Garbage::Haptic(_))));
    rig.step();
    let sent = rig.sent_torque();
    walk(&mut rig, sent);
    // A fault ends the mode, and the mode goes off the real-time thread.
    assert!(rig.cycle.request(Request::Haptic(haptic())).is_none());
    rig.step();
    rig.link.deliver = false;
    let mut events = Vec::new();
    for _ in 0..100 {
        events.extend(rig.step());
    }
    assert!(events.contains(&Event::HapticEnded), "{events:?}");
    assert_eq!(rig.cycle.mode(), Mode::Faulted);
    assert!(matches!(rig.cycle.take_garbage(), Some(Garbage::Haptic(_))));
    // Files refused by name: a NaN, an unknown field, a stiffness over the bound (2 N·s/m over
    // T/2 plus one period's latency: 1333 N/m).
    let nan = parse_fixtures("[[wall]]\ndepth_m = 0.01\nstiffness = nan\ndamping = 0.0\n").unwrap_err();
    assert!(nan.contains("wall[0].stiffness = NaN"), "{nan}");
    let typo = parse_fixtures("[[wall]]\ndepth_m = 0.01\nstifness = 10.0\ndamping = 0.0\n").unwrap_err();
    assert!(typo.contains("stifness"), "{typo}");
    let stiff = parse_fixtures("[[wall]]\ndepth_m = 0.01\nstiffness = 1400.0\ndamping = 0.0\n").unwrap();
    let over = HapticMode::build(&model, (&params, &[]), &HapticConfig::default(), &stiff, 1e-3).err().unwrap();
    assert!(over.contains("wall[0].stiffness = 1400 N/m is above the passivity bound 1333.3333 N/m"), "{over}");
}
