//! `arash-mock`: the mock motor, the far end of the motor link with the simulated plant behind it
//! (`arash_core::sim::Drive`: true parameters, undeclared effects, encoders, current sensing).
//!
//! It is clocked by the host: every host frame is one control period of simulated time, and is
//! answered by one telemetry frame. Host jitter therefore changes nothing physical, which keeps
//! runs over a pseudo-terminal reproducible. While the drive is disabled a brake holds the
//! joints (the plant does not move). [`FaultPlan`] injects link and sensor faults.
//!
//! A test double, not part of the rig: `arash mock-motor` and the tests link it, the daemon
//! binary does not (docs/architecture.md, "Crates").

use std::io::{Read, Write};

use arash_core::sim::{Drive, Scenario};
use arash_core::Model;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use arash_daemon::drive_config::DriveConfig;
use arash_daemon::link::frame::{drive_fault, status, Command, FrameError, Message, Telemetry, MAX_JOINTS, MAX_WIRE};
use arash_daemon::link::serial::Endpoint;

/// Faults to inject, by probability per telemetry frame or from a simulated time on.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FaultPlan {
    /// Seed of the fault draws (independent of the plant's).
    pub seed: u64,
    /// Probability that a telemetry frame is not sent.
    pub drop: f64,
    /// Probability that one byte of a telemetry frame is flipped.
    pub corrupt: f64,
    /// Probability that a telemetry frame is held back and sent `delay_frames` frames later.
    pub delay: f64,
    pub delay_frames: usize,
    /// Probability that a telemetry frame is swapped with the next one.
    pub reorder: f64,
    /// Stop answering at this simulated time (s), for good.
    pub silent_at_s: Option<f64>,
    /// Stop answering for `silence_frames` host frames from simulated time `silence_at_s`.
    pub silence_at_s: Option<f64>,
    pub silence_frames: usize,
    /// Freeze the encoder of joint `stuck_joint` from this simulated time (s).
    pub stuck_at_s: Option<f64>,
    pub stuck_joint: usize,
    /// From this simulated time (s), joint `mismatch_joint` produces and reports only
    /// `mismatch_factor` of the commanded current (a failing winding or amplifier).
    pub mismatch_at_s: Option<f64>,
    pub mismatch_joint: usize,
    pub mismatch_factor: f64,
}

impl FaultPlan {
    pub fn validate(&self, dof: usize) -> Result<(), MockError> {
        for (name, p) in
            [("drop", self.drop), ("corrupt", self.corrupt), ("delay", self.delay), ("reorder", self.reorder)]
        {
            if !(0.0..=1.0).contains(&p) {
                return Err(MockError::Probability { name, value: p });
            }
        }
        for (name, j) in [("stuck_joint", self.stuck_joint), ("mismatch_joint", self.mismatch_joint)] {
            if j >= dof {
                return Err(MockError::Joint { name, joint: j, dof });
            }
        }
        Ok(())
    }
}

/// Why a mock motor cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum MockError {
    #[error("fault `{name}` is a probability in [0, 1], not {value}")]
    Probability { name: &'static str, value: f64 },
    #[error("fault `{name}` = {joint}, but the robot has joints 0..{}", dof - 1)]
    Joint { name: &'static str, joint: usize, dof: usize },
    #[error(transparent)]
    Drive(#[from] arash_daemon::drive_config::DriveConfigError),
    #[error(transparent)]
    Plant(#[from] arash_core::sim::PlantError),
}

/// The mock drive behind one link endpoint.
pub struct MockMotor {
    drive: Drive,
    config: DriveConfig,
    faults: FaultPlan,
    rng: ChaCha8Rng,
    dof: usize,
    dt: f64,
    enabled: bool,
    drive_faults: u8,
    setpoint: [f64; MAX_JOINTS],
    /// Encoder zero (counts), set by ZERO_ENCODERS.
    zero: [i64; MAX_JOINTS],
    stuck_counts: Option<i64>,
    /// Host frames received (the simulated clock: one period each).
    frames: u64,
    silence_left: usize,
    silence_done: bool,
    telemetry_seq: u16,
    last_host_seq: u16,
    last_host_frame: std::time::Instant,
    /// Frames held back for the delay and reorder faults: (send at frame, encoded bytes, length).
    held: Vec<(u64, [u8; MAX_WIRE], usize)>,
    /// How long the drive waits for a host frame before it faults (its own watchdog).
    pub watchdog: std::time::Duration,
    /// Where each powered cycle's truth goes (`--truth`), and its row's buffer.
    truth: Option<(std::io::BufWriter<std::fs::File>, String)>,
}

/// A pseudo-terminal for the mock motor to play a drive on: the master end, set for
/// [`MockMotor::serve`] (reads return at once), the slave end, and the slave's path, which the
/// daemon opens as its serial port. Keep the slave open while daemons come and go, or the master
/// sees a hang-up between them.
pub fn pseudo_terminal() -> anyhow::Result<(serialport::TTYPort, serialport::TTYPort, String)> {
    use anyhow::Context;
    use serialport::SerialPort;
    let (mut master, slave) = serialport::TTYPort::pair().context("opening a pseudo-terminal")?;
    master.set_timeout(std::time::Duration::ZERO)?;
    let path = slave.name().context("the pseudo-terminal has no name")?;
    Ok((master, slave, path))
}

impl MockMotor {
    pub fn new(model: &Model, scenario: &Scenario, config: DriveConfig, faults: FaultPlan) -> Result<Self, MockError> {
        let dof = model.dof();
        config.validate(dof)?;
        faults.validate(dof)?;
        let mut sensed = scenario.clone();
        sensed.sensors.counts_per_rev.clone_from(&config.counts_per_rev);
        sensed.sensors.transmission.clone_from(&config.transmission);
        let drive = Drive::new(model, &sensed)?;
        Ok(Self {
            drive,
            rng: ChaCha8Rng::seed_from_u64(faults.seed),
            config,
            faults,
            dof,
            dt: 1.0 / scenario.physics.rate_hz,
            enabled: false,
            drive_faults: 0,
            setpoint: [0.0; MAX_JOINTS],
            zero: [0; MAX_JOINTS],
            stuck_counts: None,
            frames: 0,
            silence_left: 0,
            silence_done: false,
            telemetry_seq: 0,
            last_host_seq: 0,
            last_host_frame: std::time::Instant::now(),
            held: Vec::with_capacity(16),
            watchdog: std::time::Duration::from_millis(100),
            truth: None,
        })
    }

    /// Write each powered cycle's truth to `path` as CSV (`Drive::truth_csv_header`).
    pub fn record_truth(&mut self, path: &std::path::Path) -> anyhow::Result<()> {
        use anyhow::Context;
        use std::io::Write;
        let file = std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let mut out = std::io::BufWriter::new(file);
        writeln!(out, "{}", self.drive.truth_csv_header())?;
        out.flush()?;
        self.truth = Some((out, String::with_capacity(512)));
        Ok(())
    }

    /// Append the last cycle's truth, flushed every tenth of a second of simulated time so that
    /// a reader following the file lags little and a killed mock loses little.
    fn write_truth(&mut self) -> anyhow::Result<()> {
        use std::io::Write;
        if let Some((out, row)) = self.truth.as_mut() {
            self.drive.truth_csv_row(row);
            writeln!(out, "{row}")?;
            if self.drive.truth().cycle.is_multiple_of(100) {
                out.flush()?;
            }
        }
        Ok(())
    }

    /// The simulated drive (plant and truth), e.g. for tests.
    pub fn drive(&self) -> &Drive {
        &self.drive
    }

    /// Whether the power stage is on.
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// Switch the power stage on as if an earlier host had enabled it (a drive left powered by a
    /// crashed host, or one that powers up enabled), holding `amps` per joint.
    pub fn power_on(&mut self, amps: &[f64]) {
        self.enabled = true;
        self.setpoint[..amps.len()].copy_from_slice(amps);
        self.last_host_frame = std::time::Instant::now();
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.frames as f64 * self.dt
    }

    /// Serve `port` until `stop` is set: answer every host frame. Blocks in `poll(2)` between
    /// frames when the port has a descriptor.
    pub fn serve<P: Read + Write + std::os::fd::AsRawFd>(
        &mut self,
        port: P,
        stop: &std::sync::atomic::AtomicBool,
    ) -> anyhow::Result<()> {
        let fd = port.as_raw_fd();
        let mut endpoint = Endpoint::new(port);
        let mut inbox: Vec<Result<Message, FrameError>> = Vec::with_capacity(64);
        while !stop.load(std::sync::atomic::Ordering::Relaxed) {
            // A wake-up on a pty's bytes can come late on a loaded host; with a 10 ms timeout
            // the daemon saw stale stretches of up to 9 cycles (docs/demo.md).
            arash_daemon::link::wait_readable(fd, std::time::Duration::from_millis(1));
            inbox.clear();
            endpoint.receive(|m| inbox.push(m))?;
            for m in inbox.drain(..) {
                if let Ok(Message::Command { seq, command, .. }) = m {
                    self.last_host_frame = std::time::Instant::now();
                    self.last_host_seq = seq;
                    self.on_command(&command)?;
                    self.answer(&mut endpoint);
                }
            }
            if self.enabled && self.last_host_frame.elapsed() > self.watchdog {
                self.enabled = false;
                self.drive_faults |= drive_fault::HOST_TIMEOUT;
            }
        }
        Ok(())
    }

    /// Apply one host command and advance one period.
    pub fn on_command(&mut self, command: &Command) -> anyhow::Result<()> {
        match command {
            Command::Enable if self.drive_faults == 0 => self.enabled = true,
            Command::Enable => {}
            Command::Disable => {
                self.enabled = false;
                self.setpoint = [0.0; MAX_JOINTS];
            }
            Command::Current { joints, amps } if *joints == self.dof => {
                for (s, &a) in self.setpoint.iter_mut().zip(&amps[..self.dof]) {
                    *s = f64::from(a);
                }
            }
            Command::Current { .. } => self.drive_faults |= drive_fault::ENCODER,
            Command::ZeroEncoders => {
                for k in 0..self.dof {
                    self.zero[k] = self.drive.encoder_counts(k);
                }
            }
            Command::ClearFault => self.drive_faults = 0,
            Command::Heartbeat => {}
        }
        self.frames += 1;
        if self.enabled {
            let mut tau = [0.0; MAX_JOINTS];
            for (k, t) in tau.iter_mut().enumerate().take(self.dof) {
                *t = self.setpoint[k] * self.config.torque_constant[k] * self.mismatch(k);
            }
            self.drive.apply(self.dt, &tau[..self.dof])?;
            self.write_truth()?;
        }
        Ok(())
    }

    fn mismatch(&self, joint: usize) -> f64 {
        match self.faults.mismatch_at_s {
            Some(at) if joint == self.faults.mismatch_joint && self.time() >= at => self.faults.mismatch_factor,
            _ => 1.0,
        }
    }

    /// The telemetry for the current state.
    pub fn telemetry(&mut self) -> Telemetry {
        let mut t = Telemetry::new(self.dof);
        t.seq = self.telemetry_seq;
        self.telemetry_seq = self.telemetry_seq.wrapping_add(1);
        t.device_time_us = (self.frames as f64 * self.dt * 1e6).round() as u64 as u32;
        t.ack_seq = self.last_host_seq;
        t.status = if self.enabled { status::ENABLED } else { status::BRAKE };
        t.faults = self.drive_faults;
        for k in 0..self.dof {
            let mut counts = self.drive.encoder_counts(k) - self.zero[k];
            if self.faults.stuck_at_s.is_some_and(|at| k == self.faults.stuck_joint && self.time() >= at) {
                counts = *self.stuck_counts.get_or_insert(counts);
            }
            t.counts[k] = counts as i32;
            t.amps[k] = if self.enabled {
                (self.drive.measured_torque()[k] / self.config.torque_constant[k]) as f32
            } else {
                0.0
            };
        }
        t
    }

    /// This period's telemetry, unless the drive is silent now.
    pub fn reply(&mut self) -> Option<Telemetry> {
        let telemetry = self.telemetry();
        (!self.silenced()).then_some(telemetry)
    }

    /// Send this period's telemetry through the fault plan.
    fn answer<P: Read + Write>(&mut self, endpoint: &mut Endpoint<P>) {
        self.release_held(endpoint);
        let Some(telemetry) = self.reply() else { return };
        let mut wire = [0u8; MAX_WIRE];
        let n = arash_daemon::link::frame::encode(&Message::Telemetry(telemetry), &mut wire);
        let f = &self.faults;
        let (drop, corrupt, delay, reorder) = (f.drop, f.corrupt, f.delay, f.reorder);
        if self.rng.random_bool(drop) {
            return;
        }
        if self.rng.random_bool(corrupt) {
            let i = self.rng.random_range(0..n - 1);
            wire[i] ^= self.rng.random_range(1..=255u8);
            if wire[i] == 0 {
                wire[i] = 0x55;
            }
        }
        if self.rng.random_bool(delay) {
            self.held.push((self.frames + self.faults.delay_frames as u64, wire, n));
        } else if self.rng.random_bool(reorder) {
            self.held.push((self.frames + 1, wire, n));
        } else {
            send(endpoint, &wire[..n]);
        }
    }

    fn release_held<P: Read + Write>(&mut self, endpoint: &mut Endpoint<P>) {
        let now = self.frames;
        let mut i = 0;
        while i < self.held.len() {
            if self.held[i].0 <= now {
                let (_, wire, n) = self.held.swap_remove(i);
                send(endpoint, &wire[..n]);
            } else {
                i += 1;
            }
        }
    }

    fn silenced(&mut self) -> bool {
        let t = self.time();
        if self.faults.silent_at_s.is_some_and(|at| t >= at) {
            return true;
        }
        if !self.silence_done && self.faults.silence_frames > 0 && self.faults.silence_at_s.is_some_and(|at| t >= at) {
            if self.silence_left == 0 {
                self.silence_left = self.faults.silence_frames;
            }
            self.silence_left -= 1;
            self.silence_done = self.silence_left == 0;
            return true;
        }
        false
    }
}

/// A full output buffer loses the frame, as a real link would; the host counts the gap.
fn send<P: Read + Write>(endpoint: &mut Endpoint<P>, bytes: &[u8]) {
    let _ = endpoint.write_raw(bytes);
}

/// The mock motor in the same process, as a [`arash_daemon::link::MotorLink`]: each command is answered at once,
/// through the fault plan's silences (byte-level faults need the serial path).
pub struct InProcessLink {
    pub motor: MockMotor,
    inbox: Option<Telemetry>,
    stats: arash_daemon::link::LinkStats,
}

impl InProcessLink {
    pub fn new(motor: MockMotor) -> Self {
        Self { motor, inbox: None, stats: Default::default() }
    }
}

impl arash_daemon::link::MotorLink for InProcessLink {
    fn send(&mut self, command: &Command) -> std::io::Result<()> {
        self.motor.on_command(command).map_err(std::io::Error::other)?;
        self.stats.frames_sent += 1;
        self.inbox = self.motor.reply();
        Ok(())
    }

    fn poll(&mut self, out: &mut Telemetry) -> std::io::Result<bool> {
        match self.inbox.take() {
            Some(t) => {
                *out = t;
                self.stats.frames_received += 1;
                Ok(true)
            }
            None => Ok(false),
        }
    }

    fn stats(&self) -> arash_daemon::link::LinkStats {
        self.stats
    }
}
