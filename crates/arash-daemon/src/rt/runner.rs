//! The control thread: a [`ControlCycle`] on an absolute-deadline schedule, fed by an operator
//! request queue, feeding the logger queue. Queues are wait-free and bounded (rtrb); the thread
//! never blocks on them, never allocates, and counts what it had to drop.

use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::time::Duration;

use super::clock::{now_ns, sleep_until, Pace, Schedule};
use super::cycle::{ControlCycle, Event, Garbage, Request};
use super::reference::Phase;
use crate::link::{Command, LinkStats, MotorLink, Telemetry, MAX_JOINTS};
use arash_core::record::CycleSnapshot;

/// One cycle as the logger receives it: fixed-size, so queuing it never allocates.
#[derive(Clone, Copy, Debug)]
pub struct CycleSample {
    /// The cycle as the flight log records it, its `cycle` the runner's count.
    pub record: CycleSnapshot<MAX_JOINTS>,
    /// Wake-to-wake time (ns) and time spent in the cycle (ns).
    pub period_ns: u64,
    pub exec_ns: u64,
    /// Cycles skipped so far after overruns.
    pub missed: u64,
    pub link: LinkStats,
}

/// What the control thread tells the logger. Cycles travel by value: boxing them would allocate
/// on the real-time thread.
#[derive(Clone, Copy, Debug)]
#[allow(clippy::large_enum_variant)]
pub enum LogItem {
    Event { cycle: u64, t: f64, event: Event, drive: DriveReport },
    Cycle(CycleSample),
}

/// What the drives reported in the cycle of an event: their fault bits, and why a CANopen master
/// latched them off. A `motor` fault is named by it: the bit alone does not say which drive or
/// why.
#[derive(Clone, Copy, Debug, Default)]
pub struct DriveReport {
    pub faults: u8,
    pub master: Option<crate::link::master::MasterFault>,
}

impl DriveReport {
    /// The reason in words: the master's where it has one, else the drive's fault bits.
    pub fn describe(&self) -> String {
        match self.master {
            Some(fault) => fault.to_string(),
            None if self.faults == 0 => "no drive fault reported".into(),
            None => crate::link::frame::drive_fault::names(self.faults).join(", "),
        }
    }
}

/// State the control thread publishes for the operator interface and the watchdog.
#[derive(Default)]
pub struct Shared {
    /// Incremented every cycle: the heartbeat the systemd watchdog follows.
    pub cycle: AtomicU64,
    /// Operator requests the thread has applied and published the effect of: the operator
    /// interface waits for its ticket here instead of guessing how long a cycle takes.
    pub requests_handled: AtomicU64,
    pub mode: AtomicU32,
    pub faults: AtomicU32,
    pub controller: AtomicU32,
    pub phase: AtomicU32,
    /// Id of the run in progress (0: none) and of the last one that ended.
    pub run_id: AtomicU32,
    pub last_run_ended: AtomicU32,
    pub have_telemetry: AtomicBool,
    /// The hand's force level: 0 free, 1 contact, 2 collision.
    pub force_level: AtomicU32,
    /// The drive's last reported status bits (low byte) and fault bits (next byte).
    pub drive: AtomicU32,
    pub missed: AtomicU64,
    pub log_dropped: AtomicU64,
    /// Set by the logger thread if it stopped on an error (e.g. a full disk).
    pub logging_failed: AtomicBool,
    pub garbage_leaked: AtomicU64,
    /// The link's counters and state, as of the last cycle that found the lock free: the
    /// control thread only tries it, and the operator side holds it for a copy.
    pub link: std::sync::Mutex<LinkStats>,
    /// Joint positions as f64 bits.
    pub q: [AtomicU64; MAX_JOINTS],
    /// Set by the daemon to stop the thread (it disables the drive first).
    pub stop: AtomicBool,
    /// Set by the thread when its loop is running.
    pub running: AtomicBool,
}

/// The queues the control thread owns one end of.
pub struct Queues {
    pub requests: rtrb::Consumer<Request>,
    pub garbage: rtrb::Producer<Garbage>,
    pub log: rtrb::Producer<LogItem>,
}

/// Free slots the log queue keeps in lockstep before the next cycle: the events and the cycle of
/// one cycle, with room to spare.
const LOCKSTEP_LOG_ROOM: usize = 16;

/// How long, in lockstep, the cycle waits for the simulated rig's answer before it counts as a
/// cycle without telemetry: far beyond a pty's round trip and a loaded host's stalls, so that the
/// run is the same run however busy the host; a rig's injected silence costs this much wall time
/// per silent cycle.
const LOCKSTEP_PATIENCE: Duration = Duration::from_millis(100);

/// The link as the cycle sees it in lockstep: [`Lockstep::wait_for_telemetry`] polls until new telemetry has
/// come (or the patience is out) and holds it for the cycle's own poll. At the deadline pace it
/// passes everything through.
struct Lockstep<'a> {
    link: &'a mut dyn MotorLink,
    /// The newest telemetry, and the fault bits a link reports between telemetry.
    latest: Telemetry,
    held: bool,
}

impl<'a> Lockstep<'a> {
    fn new(link: &'a mut dyn MotorLink, joints: usize) -> Self {
        Self { link, latest: Telemetry::new(joints), held: false }
    }

    /// Poll until new telemetry is held or `patience` has passed, waiting on the link between.
    fn wait_for_telemetry(&mut self, patience: Duration) {
        let deadline = std::time::Instant::now() + patience;
        while !self.held {
            self.held = self.link.poll(&mut self.latest).unwrap_or(false);
            let now = std::time::Instant::now();
            if self.held || now >= deadline {
                return;
            }
            self.link.wait(deadline - now);
        }
    }
}

impl MotorLink for Lockstep<'_> {
    fn start(&mut self) -> Result<Vec<String>, Box<dyn std::error::Error + Send + Sync>> {
        self.link.start()
    }

    fn send(&mut self, command: &Command) -> std::io::Result<()> {
        self.link.send(command)
    }

    fn poll(&mut self, out: &mut Telemetry) -> std::io::Result<bool> {
        let fresh = self.link.poll(&mut self.latest)? | std::mem::take(&mut self.held);
        match fresh {
            true => *out = self.latest,
            false => out.faults = self.latest.faults,
        }
        Ok(fresh)
    }

    fn stats(&self) -> LinkStats {
        self.link.stats()
    }

    fn wait(&mut self, timeout: Duration) {
        self.link.wait(timeout);
    }

    fn clock_by_samples(&mut self) {
        self.link.clock_by_samples();
    }
}

/// Run the control loop until `shared.stop`; then disable the drive and return. The cycles go
/// at `pace`: a `period` apart, or in lockstep with a simulated rig.
pub fn run(
    mut cycle: ControlCycle,
    link: &mut dyn MotorLink,
    mut queues: Queues,
    shared: &Shared,
    period: Duration,
    pace: Pace,
) {
    let mut schedule = Schedule::new(period, now_ns());
    let mut previous_wake = now_ns();
    let mut missed = 0u64;
    let mut stopping: Option<u32> = None;
    shared.running.store(true, Ordering::Release);
    if pace == Pace::Lockstep {
        link.clock_by_samples();
    }
    let mut link = Lockstep::new(link, cycle.record().q.len());
    for n in 0u64.. {
        match pace {
            Pace::Deadline => sleep_until(schedule.next_deadline()),
            Pace::Lockstep => {
                // Between runs, no faster than the rig's own rate: an idle daemon and its
                // simulated rig spinning as fast as the host goes would take a core each from
                // whatever the host does meanwhile, and log millions of idle cycles.
                if cycle.phase() == Phase::Hold {
                    sleep_until(schedule.next_deadline());
                }
                // The simulated rig waits for its next command: a full log queue slows the run
                // rather than losing cycles from the log.
                while queues.log.slots() < LOCKSTEP_LOG_ROOM {
                    std::thread::sleep(Duration::from_micros(200));
                }
                link.wait_for_telemetry(LOCKSTEP_PATIENCE);
            }
        }
        let wake = now_ns();
        if stopping.is_none() && shared.stop.load(Ordering::Acquire) {
            let _ = cycle.request(Request::Disable);
            stopping = Some(5); // a few cycles to get the disable frame out
        }
        let mut handled = 0;
        while let Ok(request) = queues.requests.pop() {
            handled += 1;
            if let Some(g) = cycle.request(request) {
                hand_back(&mut queues.garbage, g, shared);
            }
        }
        cycle.step(&mut link, n);
        if let Some(g) = cycle.take_garbage() {
            hand_back(&mut queues.garbage, g, shared);
        }
        let exec = now_ns() - wake;
        let sample = sample(&cycle, &link, n, wake - previous_wake, exec, missed);
        previous_wake = wake;
        let t = sample.record.t;
        let drive = DriveReport { faults: cycle.drive_state().1, master: sample.link.latched };
        cycle.drain_events(|event| {
            if let Event::RunEnded(id) = event {
                shared.last_run_ended.store(id, Ordering::Release);
            }
            push(&mut queues.log, LogItem::Event { cycle: n, t, event, drive }, shared)
        });
        publish(shared, &cycle, &sample.link);
        shared.requests_handled.fetch_add(handled, Ordering::Release);
        push(&mut queues.log, LogItem::Cycle(sample), shared);
        if let Some(left) = stopping.as_mut() {
            *left -= 1;
            if *left == 0 {
                break;
            }
        }
        match pace {
            Pace::Deadline => {
                missed += schedule.advance(now_ns());
                shared.missed.store(missed, Ordering::Relaxed);
            }
            // A period from this cycle's end: a run's cycles go faster than the period, and a
            // schedule kept through them would be ahead of the clock by the time they saved.
            Pace::Lockstep => schedule = Schedule::new(period, now_ns()),
        }
    }
    shared.running.store(false, Ordering::Release);
}

fn sample(
    cycle: &ControlCycle,
    link: &dyn MotorLink,
    n: u64,
    period_ns: u64,
    exec_ns: u64,
    missed: u64,
) -> CycleSample {
    let mut record = CycleSnapshot::of(cycle.record());
    record.cycle = n;
    CycleSample { record, period_ns, exec_ns, missed, link: link.stats() }
}

/// Queue for the logger; a full queue drops the item and counts it.
fn push(log: &mut rtrb::Producer<LogItem>, item: LogItem, shared: &Shared) {
    if log.push(item).is_err() {
        shared.log_dropped.fetch_add(1, Ordering::Relaxed);
    }
}

/// Return a replaced trajectory or controller for dropping off this thread. If that queue is
/// full the object is leaked (counted) rather than freed here.
fn hand_back(garbage: &mut rtrb::Producer<Garbage>, g: Garbage, shared: &Shared) {
    if let Err(rtrb::PushError::Full(g)) = garbage.push(g) {
        std::mem::forget(g);
        shared.garbage_leaked.fetch_add(1, Ordering::Relaxed);
    }
}

fn publish(shared: &Shared, cycle: &ControlCycle, stats: &LinkStats) {
    let r = cycle.record();
    shared.cycle.fetch_add(1, Ordering::Release);
    shared.mode.store(r.mode as u32, Ordering::Relaxed);
    shared.faults.store(r.faults.0, Ordering::Relaxed);
    shared.controller.store(r.controller as u32, Ordering::Relaxed);
    shared.phase.store(
        match cycle.phase() {
            Phase::Hold if cycle.haptic() => 3,
            Phase::Hold => 0,
            Phase::Approach => 1,
            Phase::Run => 2,
        },
        Ordering::Relaxed,
    );
    shared.run_id.store(cycle.run_id().unwrap_or(0), Ordering::Relaxed);
    shared.have_telemetry.store(cycle.has_telemetry(), Ordering::Relaxed);
    shared.force_level.store(cycle.level() as u32, Ordering::Relaxed);
    let (status, faults) = cycle.drive_state();
    shared.drive.store(u32::from(status) | u32::from(faults) << 8, Ordering::Relaxed);
    for (a, &q) in shared.q.iter().zip(&r.q) {
        a.store(q.to_bits(), Ordering::Relaxed);
    }
    if let Ok(mut link) = shared.link.try_lock() {
        *link = *stats;
    }
}
