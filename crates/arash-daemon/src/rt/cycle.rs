//! One control cycle of the daemon, free of threads and clocks so that tests can drive it cycle
//! by cycle: read telemetry, estimate q and q̇, step the controller, pass the safety gate, write
//! the motor currents. Never allocates.
//!
//! Safety rules beyond [`SafetyGate`] (each has a test at its boundary in `tests/safety.rs`):
//! - **stale telemetry:** a cycle without new valid telemetry repeats the last command for up to
//!   `hold` cycles (the law is not stepped; the log and the rate limit see the repeated command,
//!   so the limit holds between the commands the motor gets); later ones command the control
//!   law at the reference (q = q_d, q̇ = q̇_d): its feed-forward, without feedback. Feedback held
//!   on an ever older state is a sampled loop with a long hold: telemetry every 10th cycle (seen on
//!   a loaded host behind a pseudo-terminal) made the paper's insertion loop, near 150 rad/s, swing
//!   until the velocity limit latched. Without any feedback the arm drifts, so a short gap keeps it
//!   (`tests/safety.rs` measures both);
//! - **link timeout:** the `link_timeout`-th cycle without telemetry in a row latches
//!   `LINK_TIMEOUT` and ramps the torque to zero over `ramp` cycles, then disables the drive;
//! - **disabled means commanded off:** while the host is not enabled, every frame it sends is
//!   DISABLE (zero current, power stage off), from the first cycle on. A drive left powered by a
//!   crashed daemon, or one that reports power on at start-up, is switched off at once; one that
//!   still reports its power stage on after `link_timeout` telemetry frames latches
//!   `DRIVE_STATE`;
//! - **drive stopped by itself:** while the host has the drive enabled, telemetry that reports
//!   its power stage off latches `DRIVE_STOPPED` once the drive has confirmed the enable, and
//!   so does a drive that has not confirmed it within `enable_timeout` telemetry frames. Until
//!   it confirms, the current it measures is not compared with the command (below). Nothing
//!   walks a drive stopped by its e-stop or safe torque off back to enabled; only the
//!   operator's reset and enable do;
//! - **drive faults:** any fault bit the link reports latches `MOTOR`, with or without new
//!   telemetry (a CANopen master reports its drives' faults every cycle);
//! - **reset:** [`Request::ResetFault`] sends CLEAR_FAULT every cycle until the drive reports no
//!   fault (its telemetry lags the command by a cycle or more, so a stale fault bit must not
//!   re-latch `MOTOR`). A drive still reporting a fault after `link_timeout` cycles latches
//!   `MOTOR` again;
//! - **following error:** |q − q_d| beyond the limit latches `FOLLOWING_ERROR` (a stuck encoder);
//! - **current mismatch:** measured torque differing from the command by more than a fraction of
//!   the torque limit for `mismatch_cycles` cycles in a row latches `CURRENT_MISMATCH`, from the
//!   drive's confirmation of the enable on: before it, a drive still walking to enabled (or
//!   releasing its brake) measures no current, and the link passes torque on to each of its
//!   drives only once that one is enabled, so the others hold the arm meanwhile;
//! - **start-up:** the drive cannot be enabled before valid telemetry arrives;
//! - faults latch until [`Request::ResetFault`], which leaves the drive disabled; enabling waits
//!   until the drive has confirmed the reset;
//! - **collision:** with a force observer ([`ControlCycle::with_force`]), an estimate at the
//!   collision level during an approach or a run latches `COLLISION` in the same cycle: the run
//!   is abandoned and the joints float under the model's gravity and friction compensation,
//!   the drive still enabled, so that whatever the instrument hit is not pushed further and a
//!   hand can move the arm away. New runs and enabling are refused until
//!   [`Request::ResetFault`], which holds the arm where it is. Contacts are events;
//! - **haptic mode** ([`Request::Haptic`]): only from hold, enabled, with no collision latched. The reference follows the arm, so
//!   there is no following error, and every other rule holds: the gate's limits and rate limit,
//!   the faults. A fixture that renders a non-number latches `NON_FINITE_COMMAND`. Hold, a run,
//!   disabling and any fault leave the mode; a new request in the mode switches its fixtures.
//!   Entering, switching and leaving for hold or a run, the new
//!   source's command starts where the old one's left off and the difference fades out over
//!   `handover` cycles, so that a wall the hand pressed into does not vanish in one cycle.

use arash_core::control::{Controller, ControllerKind, Desired, Faults, SafetyGate, SafetyLimits, VelocityEstimator};
use arash_core::record::{CycleRecord, Mode};

use super::force::ForceMonitor;
use super::haptic::HapticMode;
use super::reference::{Phase, PhaseChange, Reference, RunRequest};
use crate::drive_config::DriveConfig;
use crate::link::frame::status;
use crate::link::{Command, MotorLink, Telemetry, MAX_JOINTS};
use arash_core::force::Level;

/// What the cycle is configured with (SI).
#[derive(Clone, Debug)]
pub struct CycleConfig {
    /// Nominal period (s).
    pub dt: f64,
    pub drive: DriveConfig,
    pub limits: SafetyLimits,
    /// Consecutive cycles without telemetry that latch a link timeout; also the cycles a drive
    /// has to obey DISABLE or to confirm CLEAR_FAULT.
    pub link_timeout: u32,
    /// Telemetry frames a drive has to confirm the host's enable (`link.enable_timeout_ms`).
    pub enable_timeout: u32,
    /// Cycles over which the torque ramps to zero after a link timeout.
    pub ramp: u32,
    /// Cycles without telemetry that repeat the last command; later ones command the law at the
    /// reference.
    pub hold: u32,
    /// Per-joint following-error limit (rad or m).
    pub following_error: Vec<f64>,
    /// Current mismatch threshold, as a fraction of the torque limit.
    pub mismatch_fraction: f64,
    pub mismatch_cycles: u32,
    pub velocity_cutoff_hz: f64,
    /// Approach speed per joint (rad/s or m/s).
    pub approach_speed: Vec<f64>,
    /// Cycles over which the command hands over between the haptic mode and the controller.
    pub handover: u32,
}

/// An operator's request, applied at the start of a cycle.
pub enum Request {
    Enable,
    Disable,
    ResetFault,
    /// Hold the present reference position (abandoning a run).
    Hold,
    Run(Box<RunRequest>),
    /// A control law, and with a model file the hand's force observer on the same model (built
    /// off the real-time thread with the daemon's `[force]` settings; ignored, and handed back,
    /// when the daemon runs no observer).
    Controller(Box<dyn Controller>, Option<Box<ForceMonitor>>),
    /// Enter the haptic mode with these fixtures (built and checked off the real-time thread).
    Haptic(Box<HapticMode>),
}

/// Something that came back from the cycle and must be dropped off the real-time thread.
pub enum Garbage {
    Run(Box<RunRequest>),
    Controller(Box<dyn Controller>, Option<Box<ForceMonitor>>),
    Haptic(Box<HapticMode>),
}

/// A notable change in one cycle, for the event log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Event {
    Enabled,
    Disabled,
    /// Enabling was refused: no valid telemetry yet, a latched fault, a reset the drive has not
    /// confirmed yet, or already enabled.
    EnableRefused,
    FaultLatched(Faults),
    FaultsCleared,
    RunStarted(u32),
    RunEnded(u32),
    ControllerSwitched,
    /// The hand's force estimate crossed the contact level, or fell back below it.
    ContactStarted,
    ContactEnded,
    /// A run was refused: a collision is latched.
    RunRefused,
    HapticStarted,
    /// New fixtures in the haptic mode, handed over like an entry.
    FixturesSwitched,
    HapticEnded,
    /// The haptic mode was refused: not enabled, not holding, or a collision latched.
    HapticRefused,
}

pub struct ControlCycle {
    cfg: CycleConfig,
    dof: usize,
    resolution: [f64; MAX_JOINTS],
    estimator: VelocityEstimator,
    controller: Box<dyn Controller>,
    gate: SafetyGate,
    reference: Reference,
    mode: Mode,
    /// The ENABLE frame is still to be sent (in place of the first current command). A disabled
    /// or faulted cycle needs no such flag: it sends DISABLE, or CLEAR_FAULT during a reset.
    enabling: bool,
    telemetry: Telemetry,
    have_telemetry: bool,
    missing: u32,
    last_device_us: u32,
    /// Device time of the last telemetry (s, unwrapped): the time of the logged measurement.
    device_time: f64,
    /// Time of the reference (s): the device time extrapolated over cycles without telemetry,
    /// never going back when late telemetry arrives.
    reference_time: f64,
    /// Torque sent last (N·m or N) and the ramp after a link timeout.
    last_sent: [f64; MAX_JOINTS],
    ramp_from: [f64; MAX_JOINTS],
    ramp_left: u32,
    mismatch_count: [u32; MAX_JOINTS],
    /// Cycles left for the drive to confirm a reset (0: no reset under way).
    clearing: u32,
    /// Consecutive telemetry frames with the power stage on while the host commands it off.
    powered_while_off: u32,
    /// Since the last enable: whether the drive has reported its power stage on, and how many
    /// telemetry frames have come without it before it did.
    enable_confirmed: bool,
    unconfirmed: u32,
    tau_out: Vec<f64>,
    record: CycleRecord,
    events: [Option<Event>; 8],
    /// The hand's force observer, its last level, and the collision it latched (the joints
    /// float while it is latched and the drive enabled).
    force: Option<Box<ForceMonitor>>,
    level: Level,
    collision: bool,
    floating: bool,
    /// Seconds between the last two telemetry frames.
    telemetry_dt: f64,
    /// A run a collision stopped, for dropping off the real-time thread.
    stopped: Option<Box<RunRequest>>,
    /// The haptic mode, while it is on, and one a fault ended, for dropping.
    haptic: Option<Box<HapticMode>>,
    left_haptic: Option<Box<HapticMode>>,
    /// A handover between the mode and the controller: the command the last source gave, until
    /// the new one's first cycle sets the offset, then the offset fading over the cycles left.
    handover_from: Option<[f64; MAX_JOINTS]>,
    handover_offset: [f64; MAX_JOINTS],
    handover_left: u32,
}

impl ControlCycle {
    pub fn new(cfg: CycleConfig, controller: Box<dyn Controller>) -> Self {
        let dof = cfg.limits.torque.len();
        assert!(dof <= MAX_JOINTS, "at most {MAX_JOINTS} joints");
        let mut resolution = [0.0; MAX_JOINTS];
        for (k, r) in resolution.iter_mut().enumerate().take(dof) {
            *r = cfg.drive.resolution(k);
        }
        let mut record = CycleRecord::new(dof);
        record.controller = controller.kind();
        // Every cycle carries the fixtures' force, zero outside the haptic mode, so that a log's
        // columns line up whether or not the mode ran.
        record.fixture_force = vec![0.0; 3];
        Self {
            estimator: VelocityEstimator::new(dof, cfg.velocity_cutoff_hz),
            gate: SafetyGate::new(cfg.limits.clone()),
            reference: Reference::new(&vec![0.0; dof], &cfg.approach_speed),
            cfg,
            dof,
            resolution,
            controller,
            mode: Mode::Disabled,
            enabling: false,
            telemetry: Telemetry::new(dof),
            have_telemetry: false,
            missing: 0,
            last_device_us: 0,
            device_time: 0.0,
            reference_time: 0.0,
            last_sent: [0.0; MAX_JOINTS],
            ramp_from: [0.0; MAX_JOINTS],
            ramp_left: 0,
            mismatch_count: [0; MAX_JOINTS],
            clearing: 0,
            powered_while_off: 0,
            enable_confirmed: false,
            unconfirmed: 0,
            tau_out: vec![0.0; dof],
            record,
            events: [None; 8],
            force: None,
            level: Level::Free,
            collision: false,
            floating: false,
            telemetry_dt: 0.0,
            stopped: None,
            haptic: None,
            left_haptic: None,
            handover_from: None,
            handover_offset: [0.0; MAX_JOINTS],
            handover_left: 0,
        }
    }

    /// Run the hand's force observer `monitor` on every telemetry frame.
    pub fn with_force(mut self, monitor: ForceMonitor) -> Self {
        monitor.prepare(&mut self.record);
        self.force = Some(Box::new(monitor));
        self
    }

    /// The hand's force level at the last telemetry frame.
    pub fn level(&self) -> Level {
        self.level
    }

    /// A run or a haptic mode the cycle stopped by itself (a collision, a fault), to drop off
    /// the real-time thread.
    pub fn take_garbage(&mut self) -> Option<Garbage> {
        match self.stopped.take() {
            Some(run) => Some(Garbage::Run(run)),
            None => self.left_haptic.take().map(Garbage::Haptic),
        }
    }

    /// Whether the haptic mode is on.
    pub fn haptic(&self) -> bool {
        self.haptic.is_some()
    }

    /// Leave the haptic mode, if it is on; it comes back for dropping. The controller takes
    /// over from the mode's last command ([`Self::hand_over`]).
    fn leave_haptic(&mut self) -> Option<Garbage> {
        let left = self.haptic.take()?;
        self.record.controller = self.controller.kind();
        self.event(Event::HapticEnded);
        self.begin_handover();
        Some(Garbage::Haptic(left))
    }

    /// The command is about to change source: the next one starts from the last.
    fn begin_handover(&mut self) {
        if self.mode == Mode::Enabled {
            self.handover_from = Some(fixed(&self.record.tau_cmd));
        }
    }

    /// No handover under way: the motors were disabled, re-enabled or a fault latched.
    fn cancel_handover(&mut self) {
        (self.handover_from, self.handover_left) = (None, 0);
    }

    /// Start the new source's command (the record's `tau_cmd`) where the old one left off and
    /// fade the difference out over the handover's cycles, so that neither entering nor leaving
    /// the haptic mode steps the torque.
    fn hand_over(&mut self) {
        let (n, tau) = (self.dof, &mut self.record.tau_cmd);
        if let Some(from) = self.handover_from.take() {
            for ((offset, f), t) in self.handover_offset.iter_mut().zip(&from).zip(&tau[..n]) {
                *offset = f - t;
            }
            self.handover_left = self.cfg.handover;
        }
        if self.handover_left == 0 {
            return;
        }
        let share = f64::from(self.handover_left) / f64::from(self.cfg.handover.max(1));
        for (t, offset) in tau[..n].iter_mut().zip(&self.handover_offset) {
            *t += share * offset;
        }
        self.handover_left -= 1;
    }

    pub fn mode(&self) -> Mode {
        self.mode
    }

    pub fn faults(&self) -> Faults {
        self.gate.faults()
    }

    pub fn phase(&self) -> Phase {
        self.reference.phase()
    }

    pub fn run_id(&self) -> Option<u32> {
        self.reference.run_id()
    }

    pub fn has_telemetry(&self) -> bool {
        self.have_telemetry
    }

    /// The drive's last reported status bits ([`status`]) and fault bits.
    pub fn drive_state(&self) -> (u8, u8) {
        (self.telemetry.status, self.telemetry.faults)
    }

    /// Consecutive cycles without new telemetry.
    pub fn missing(&self) -> u32 {
        self.missing
    }

    /// The last cycle.
    pub fn record(&self) -> &CycleRecord {
        &self.record
    }

    /// The torque sent in the last cycle (N·m or N).
    pub fn sent(&self) -> &[f64] {
        &self.last_sent[..self.dof]
    }

    /// Hand over the events since the last call (requests and cycles).
    pub fn drain_events(&mut self, mut f: impl FnMut(Event)) {
        for e in self.events.iter_mut() {
            if let Some(e) = e.take() {
                f(e);
            }
        }
    }

    fn event(&mut self, e: Event) {
        if let Some(slot) = self.events.iter_mut().find(|s| s.is_none()) {
            *slot = Some(e);
        }
    }

    /// Apply an operator request; what it replaces comes back for dropping elsewhere. A run
    /// that is abandoned (hold, re-enable, another run) ends with [`Event::RunEnded`].
    pub fn request(&mut self, request: Request) -> Option<Garbage> {
        let playing = self.reference.run_id().filter(|_| self.reference.phase() == Phase::Run);
        let garbage = self.apply(request);
        if let (Some(id), Some(Garbage::Run(_))) = (playing, &garbage) {
            self.event(Event::RunEnded(id));
        }
        garbage
    }

    fn apply(&mut self, request: Request) -> Option<Garbage> {
        match request {
            Request::Enable => {
                if self.mode == Mode::Disabled
                    && self.have_telemetry
                    && self.missing < self.cfg.link_timeout
                    && self.clearing == 0
                    && self.telemetry.faults == 0
                    && self.telemetry.status & status::ENABLED == 0
                    && !self.collision
                {
                    self.mode = Mode::Enabled;
                    self.enabling = true;
                    self.enable_confirmed = false;
                    self.unconfirmed = 0;
                    self.controller.reset();
                    self.gate.clear();
                    self.mismatch_count = [0; MAX_JOINTS];
                    self.last_sent = [0.0; MAX_JOINTS];
                    self.cancel_handover();
                    let q = fixed(&self.record.q);
                    let old = self.reference.hold_at(&q[..self.dof]);
                    self.event(Event::Enabled);
                    return old.map(Garbage::Run);
                }
                self.event(Event::EnableRefused);
                None
            }
            Request::Disable => {
                self.floating = false;
                if self.mode == Mode::Enabled {
                    self.mode = Mode::Disabled;
                    self.event(Event::Disabled);
                }
                self.cancel_handover();
                self.leave_haptic()
            }
            Request::ResetFault => {
                if self.collision {
                    // The arm is held where the hand left it.
                    self.collision = false;
                    self.floating = false;
                    let q = fixed(&self.record.q);
                    self.controller.reset();
                    self.event(Event::FaultsCleared);
                    if self.mode != Mode::Faulted {
                        return self.reference.hold_at(&q[..self.dof]).map(Garbage::Run);
                    }
                }
                if self.mode == Mode::Faulted {
                    self.gate.clear();
                    self.mode = Mode::Disabled;
                    self.ramp_left = 0;
                    self.clearing = self.reset_cycles();
                    self.powered_while_off = 0;
                    self.event(Event::FaultsCleared);
                }
                None
            }
            Request::Hold => {
                self.floating = false;
                let q = fixed(&self.record.q_des);
                let run = self.reference.hold_at(&q[..self.dof]).map(Garbage::Run);
                run.or_else(|| self.leave_haptic())
            }
            Request::Run(run) if self.collision => {
                self.event(Event::RunRefused);
                Some(Garbage::Run(run))
            }
            Request::Run(run) => {
                let q = fixed(&self.record.q_des);
                let t = self.time();
                let old = self.reference.start(t, &q[..self.dof], run).map(Garbage::Run);
                old.or_else(|| self.leave_haptic())
            }
            Request::Haptic(mode) => {
                let holding = self.reference.phase() == Phase::Hold && !self.floating;
                if self.mode != Mode::Enabled || !holding || self.collision {
                    self.event(Event::HapticRefused);
                    return Some(Garbage::Haptic(mode));
                }
                // Entering, or new fixtures under the hand (a wall that appears where the tip
                // already is): either way the new command starts where the last left off.
                self.event(match self.haptic {
                    None => Event::HapticStarted,
                    Some(_) => Event::FixturesSwitched,
                });
                self.begin_handover();
                self.record.controller = ControllerKind::Haptic;
                self.haptic.replace(mode).map(Garbage::Haptic)
            }
            Request::Controller(mut c, monitor) => {
                c.reset();
                self.record.controller = c.kind();
                self.event(Event::ControllerSwitched);
                // The new observer starts from the present sample: its estimate rises from zero
                // through its lag, as at start-up. The level and a latched collision stay.
                let monitor = match (monitor, self.force.as_mut()) {
                    (Some(new), Some(running)) => Some(std::mem::replace(running, new)),
                    (unused, _) => unused,
                };
                Some(Garbage::Controller(std::mem::replace(&mut self.controller, c), monitor))
            }
        }
    }

    /// Time of the reference (s): the drive's clock at the last telemetry plus nominal periods
    /// since, kept monotonic.
    fn time(&self) -> f64 {
        self.reference_time.max(self.device_time + f64::from(self.missing) * self.cfg.dt)
    }

    /// Run one cycle against `link`.
    pub fn step(&mut self, link: &mut dyn MotorLink, cycle: u64) {
        let fresh = self.read(link);
        if fresh {
            self.observe();
        }
        self.count_down_reset();
        let t = self.time();
        self.reference_time = t;
        let r = &mut self.record;
        r.cycle = cycle;
        // The log's time is that of the measurement; a cycle without telemetry repeats it.
        r.t = self.device_time;
        match self.reference.eval(t, &mut r.q_des, &mut r.qd_des, &mut r.qdd_des) {
            Some(PhaseChange::RunStarted(id)) => self.event(Event::RunStarted(id)),
            Some(PhaseChange::RunEnded(id)) => self.event(Event::RunEnded(id)),
            None => {}
        }
        let blind = self.blind();
        let r = &mut self.record;
        let desired = Desired { q: &r.q_des, qd: &r.qd_des, qdd: &r.qdd_des };
        // Past the hold, the law is evaluated at the reference: its feed-forward, with no feedback
        // on a measurement that is getting old (see the module's "stale telemetry").
        let (q, qd) = match blind {
            false => (&r.q, &r.qd),
            true => (&r.q_des, &r.qd_des),
        };
        r.fixture_force.fill(0.0);
        if self.missing > 0 && !blind {
            // The hold repeats the last command: it is what the log records and what the gate
            // sees, so that the rate limit does not run ahead on commands never sent.
            r.tau_cmd[..self.dof].copy_from_slice(&self.last_sent[..self.dof]);
        } else if let (true, Some(force)) = (self.floating, &self.force) {
            force.compensation(&mut r.tau_cmd);
        } else if let Some(haptic) = self.haptic.as_mut() {
            match haptic.command(&r.q, &r.qd, &mut r.tau_cmd) {
                Ok(rendered) => r.fixture_force.copy_from_slice(&rendered.force),
                Err(_) => self.gate.latch(Faults::NON_FINITE_COMMAND),
            }
            self.hand_over();
        } else {
            self.controller.step(self.cfg.dt, q, qd, &desired, &mut r.tau_cmd);
            self.hand_over();
        }
        if self.mode == Mode::Enabled {
            self.check_link();
            if !self.floating && self.haptic.is_none() {
                self.check_following();
            }
            if fresh && self.enable_confirmed {
                self.check_current();
            }
        }
        let r = &self.record;
        let faults = self.gate.apply(self.cfg.dt, &r.q, &r.qd, &r.tau_cmd, &mut self.tau_out);
        if !faults.is_empty() && self.mode != Mode::Faulted {
            self.latch(faults);
        }
        let command = self.command();
        let _ = link.send(&command); // a failed send is counted by the link, like a lost frame
        let r = &mut self.record;
        r.mode = self.mode;
        r.faults = self.gate.faults() | if self.collision { Faults::COLLISION } else { Faults::NONE };
    }

    /// The hand's force on this telemetry frame: the estimate into the record, contacts as
    /// events, and a collision during an approach or a run latched at once.
    fn observe(&mut self) {
        let Some(force) = self.force.as_mut() else { return };
        let Some(level) = force.step(self.telemetry_dt, &mut self.record) else { return };
        let was = std::mem::replace(&mut self.level, level);
        match (was, level) {
            (Level::Free, Level::Contact | Level::Collision) => self.event(Event::ContactStarted),
            (Level::Contact | Level::Collision, Level::Free) => self.event(Event::ContactEnded),
            _ => {}
        }
        let moving = matches!(self.reference.phase(), Phase::Approach | Phase::Run);
        if level == Level::Collision && moving && self.mode == Mode::Enabled && !self.collision {
            self.collision = true;
            self.floating = true;
            self.event(Event::FaultLatched(Faults::COLLISION));
            if let Some(id) = self.reference.run_id().filter(|_| self.reference.phase() == Phase::Run) {
                self.event(Event::RunEnded(id));
            }
        }
        if self.floating || self.haptic.is_some() {
            // The reference follows the floating or hand-moved arm: no following error, and hold
            // or a reset holds it where it is. The run a collision stopped goes off the
            // real-time thread.
            let q = fixed(&self.record.q);
            if let Some(run) = self.reference.hold_at(&q[..self.dof]) {
                self.stopped = Some(run);
            }
        }
    }

    /// Poll the link; on new telemetry update q, q̇, τ and the clock. Returns whether it was new.
    fn read(&mut self, link: &mut dyn MotorLink) -> bool {
        let fresh = link.poll(&mut self.telemetry).unwrap_or(false) && self.telemetry.joints == self.dof;
        if !fresh {
            self.missing = self.missing.saturating_add(1);
            // Faults a link reports between telemetry latch now; a reset is confirmed only by
            // telemetry that arrived after it.
            if self.clearing == 0 && self.telemetry.faults != 0 {
                self.gate.latch(Faults::MOTOR);
            }
            return false;
        }
        let t = &self.telemetry;
        let dt = if self.have_telemetry {
            let du = t.device_time_us.wrapping_sub(self.last_device_us);
            (f64::from(du) * 1e-6).clamp(0.25 * self.cfg.dt, 20.0 * self.cfg.dt)
        } else {
            self.cfg.dt
        };
        self.last_device_us = t.device_time_us;
        if self.have_telemetry {
            self.device_time += dt;
        }
        self.telemetry_dt = dt;
        self.missing = 0;
        let r = &mut self.record;
        for k in 0..self.dof {
            r.q[k] = f64::from(t.counts[k]) * self.resolution[k];
            r.tau_meas[k] = f64::from(t.amps[k]) * self.cfg.drive.torque_constant[k];
        }
        if self.have_telemetry {
            r.qd.copy_from_slice(self.estimator.update(dt, &r.q));
        } else {
            self.estimator.prime(&r.q, &[0.0; MAX_JOINTS][..self.dof]);
            let q = fixed(&r.q);
            self.reference.hold_at(&q[..self.dof]);
        }
        self.have_telemetry = true;
        if r.tau_meas.iter().any(|x| !x.is_finite()) {
            self.gate.latch(Faults::NON_FINITE_STATE);
        }
        self.check_drive();
        true
    }

    /// Compare the drive's reported state with what the host commands.
    fn check_drive(&mut self) {
        let (powered, faults) = (self.telemetry.status & status::ENABLED != 0, self.telemetry.faults);
        if self.clearing > 0 {
            // Only telemetry after the first CLEAR_FAULT confirms the reset.
            if faults == 0 && self.clearing < self.reset_cycles() {
                self.clearing = 0;
            }
        } else if faults != 0 {
            self.gate.latch(Faults::MOTOR);
        }
        // During the ramp after a link timeout the host still drives currents on purpose.
        if powered && self.mode != Mode::Enabled && self.ramp_left == 0 {
            self.powered_while_off = self.powered_while_off.saturating_add(1);
            if self.powered_while_off >= self.cfg.link_timeout {
                self.gate.latch(Faults::DRIVE_STATE);
            }
        } else {
            self.powered_while_off = 0;
        }
        if self.mode == Mode::Enabled && !self.enabling {
            self.check_still_enabled(powered);
        }
    }

    /// The drive the host has enabled must confirm it, and then stay enabled: one that switches
    /// its power stage off by itself (an e-stop on its quick-stop input, safe torque off) is
    /// stopped until the operator restarts it, however the drive could be walked back.
    fn check_still_enabled(&mut self, powered: bool) {
        if powered {
            self.enable_confirmed = true;
        } else if self.enable_confirmed {
            self.gate.latch(Faults::DRIVE_STOPPED);
        } else {
            self.unconfirmed += 1;
            if self.unconfirmed >= self.cfg.enable_timeout.max(1) {
                self.gate.latch(Faults::DRIVE_STOPPED);
            }
        }
    }

    /// Cycles a drive has to confirm a reset.
    fn reset_cycles(&self) -> u32 {
        self.cfg.link_timeout.max(1)
    }

    /// One cycle less for the drive to confirm a reset; at the end, a fault it still reports
    /// latches again (telemetry without a fault has already ended the wait in `check_drive`).
    fn count_down_reset(&mut self) {
        if self.clearing == 0 {
            return;
        }
        self.clearing -= 1;
        if self.clearing == 0 && self.telemetry.faults != 0 {
            self.gate.latch(Faults::MOTOR);
        }
    }

    /// Telemetry has been missing for longer than the last command may be held.
    fn blind(&self) -> bool {
        self.missing > self.cfg.hold
    }

    fn check_link(&mut self) {
        if self.missing >= self.cfg.link_timeout {
            self.gate.latch(Faults::LINK_TIMEOUT);
        }
    }

    fn check_following(&mut self) {
        let r = &self.record;
        if (0..self.dof).any(|k| (r.q[k] - r.q_des[k]).abs() > self.cfg.following_error[k]) {
            self.gate.latch(Faults::FOLLOWING_ERROR);
        }
    }

    /// The telemetry answers the previous command: compare what was measured with what was sent.
    fn check_current(&mut self) {
        for k in 0..self.dof {
            let limit = self.cfg.mismatch_fraction * self.cfg.limits.torque[k];
            if (self.record.tau_meas[k] - self.last_sent[k]).abs() > limit {
                self.mismatch_count[k] += 1;
            } else {
                self.mismatch_count[k] = 0;
            }
        }
        if self.mismatch_count[..self.dof].iter().any(|&c| c >= self.cfg.mismatch_cycles) {
            self.gate.latch(Faults::CURRENT_MISMATCH);
        }
    }

    fn latch(&mut self, faults: Faults) {
        let was_enabled = self.mode == Mode::Enabled;
        self.cancel_handover();
        self.mode = Mode::Faulted;
        self.event(Event::FaultLatched(faults));
        if let Some(Garbage::Haptic(left)) = self.leave_haptic() {
            self.left_haptic = Some(left);
        }
        if was_enabled && faults.contains(Faults::LINK_TIMEOUT) {
            // The drive may still hear us: bring the torque down gently rather than at once.
            self.ramp_from = self.last_sent;
            self.ramp_left = self.cfg.ramp;
        } else {
            self.ramp_left = 0;
        }
    }

    /// The frame for this cycle.
    fn command(&mut self) -> Command {
        let (n, blind) = (self.dof, self.blind());
        let mut amps = [0f32; MAX_JOINTS];
        let mut currents = |tau: &[f64]| {
            for k in 0..n {
                amps[k] = (tau[k] / self.cfg.drive.torque_constant[k]) as f32;
            }
            Command::Current { joints: n, amps }
        };
        match self.mode {
            Mode::Enabled => {
                if std::mem::take(&mut self.enabling) {
                    // The drive gets no current this cycle: the rate limit starts from zero.
                    self.gate.clear();
                    return Command::Enable;
                }
                if self.missing == 0 || blind {
                    self.last_sent[..n].copy_from_slice(&self.tau_out);
                }
                currents(&self.last_sent[..n])
            }
            Mode::Faulted if self.ramp_left > 0 => {
                self.ramp_left -= 1;
                let scale = f64::from(self.ramp_left) / f64::from(self.cfg.ramp);
                for k in 0..n {
                    self.last_sent[k] = self.ramp_from[k] * scale;
                }
                currents(&self.last_sent[..n])
            }
            Mode::Faulted | Mode::Disabled => {
                self.last_sent = [0.0; MAX_JOINTS];
                self.enabling = false;
                if self.clearing > 0 {
                    Command::ClearFault
                } else {
                    Command::Disable
                }
            }
        }
    }
}

/// A joint vector copied into a fixed array (no allocation).
fn fixed(v: &[f64]) -> [f64; MAX_JOINTS] {
    let mut out = [0.0; MAX_JOINTS];
    out[..v.len()].copy_from_slice(v);
    out
}
