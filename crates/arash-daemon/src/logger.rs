//! The logger thread: drains the control thread's queue into MCAP flight logs.
//!
//! - **Segments.** Idle time goes to `daemon-<n>.mcap`, rotated by size or age; each trajectory
//!   run gets its own `run-<id>-<label>.mcap`, with time zero at the run's first cycle, so that
//!   `arash identify` takes it as is. Run numbers restart with the daemon, so a name already
//!   taken in the directory gets `-2`, `-3`, …: no session overwrites another's logs.
//! - **Crash safety.** A file is written as `<name>.mcap.part` and renamed when finished. A
//!   `.part` file found at start-up was cut off by a crash: [`recover`] rewrites what survived
//!   (up to its last flushed second) into `<name>.recovered.mcap`, a complete file with a
//!   summary that seeking readers open too.
//! - **Black box.** The last 2 s of cycles are kept in memory; a fault writes them, with the
//!   faulted cycle, to `blackbox-<cycle>.mcap`.
//! - **Timing.** Once a second, histograms of the period error and the execution time go to
//!   `/arash/timing`; events (faults, enables, runs, link errors) go to `/arash/event`.
//! - **Display.** Every `live.rate_hz` the tracking error's display window goes to
//!   `/arash/error`, and each file starts with the URDF on `/robot_description`; with `--live`
//!   the windows, the timing and the events are also handed to the stream ([`crate::live`]).

use std::collections::{BTreeMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use arash_core::control::Faults;
use arash_core::flightlog::schema::ERROR_SCHEMA;
use arash_core::flightlog::{LogHeader, LogWriter, ERROR_TOPIC, EVENT_TOPIC, ROBOT_DESCRIPTION_TOPIC, TIMING_TOPIC};
use arash_core::record::CycleRecord;
use prost::Message;

use crate::live::server::{LiveServer, Topic};
use crate::live::window::ErrorWindow;
use crate::rt::cycle::Event;
use crate::rt::runner::{CycleSample, DriveReport, LogItem, Shared};

/// Logger settings (the `[log]` table).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LogConfig {
    /// Directory of the flight logs.
    pub dir: PathBuf,
    /// Start a new idle file after this many MiB …
    pub rotate_mib: f64,
    /// … or this many seconds.
    pub rotate_s: f64,
    /// Length of the black box (s).
    pub blackbox_s: f64,
    /// Capacity of the queue from the control thread (cycles). Each cycle takes about 0.6 kB,
    /// locked in RAM. A disk that stalls for longer than the queue holds loses cycles from the
    /// log (counted as `log_dropped`), never from the control loop. 4,096 cycles are 4 s at 1 kHz
    /// in 2.6 MB; the 16,384 before took 10.4 MB of the daemon's memory budget (rt/memory.rs).
    pub queue: usize,
}

impl Default for LogConfig {
    fn default() -> Self {
        Self { dir: PathBuf::from("logs"), rotate_mib: 512.0, rotate_s: 3600.0, blackbox_s: 2.0, queue: 4_096 }
    }
}

/// A run as the operator requested it; the logger names and annotates its file from this.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RunInfo {
    pub label: String,
    /// Attached to the run's log; left out of `ctl status`, which polls often.
    #[serde(skip)]
    pub trajectory_json: String,
    /// The controller that runs it ([`arash_core::control::logged::LoggedController`]),
    /// attached to the run's log as `controller.json`.
    #[serde(skip)]
    pub controller_json: String,
    pub controller: String,
    /// The finished log file, once the run has ended.
    pub log: Option<PathBuf>,
    pub state: String,
}

/// Runs by id, shared between the operator interface and the logger.
pub type RunRegistry = Arc<Mutex<BTreeMap<u32, RunInfo>>>;

/// What every file's header carries.
#[derive(Clone)]
pub struct LogContext {
    pub urdf: String,
    pub joint_names: Vec<String>,
    pub config_toml: String,
    pub metadata: BTreeMap<String, String>,
    pub rate_hz: f64,
    /// Control cycles per `/arash/error` window (and per live sample).
    pub window_cycles: u32,
    /// Each joint's tracking error to display units (° or µm).
    pub error_scales: Vec<f64>,
}

/// Rewrite every `*.mcap.part` in `dir` (left by a crash) into a complete `*.recovered.mcap`
/// (see [`arash_core::flightlog::rewrite_complete`]); returns the recovered files and how many
/// cycles each still holds.
pub fn recover(dir: &Path) -> Vec<(PathBuf, Result<usize, String>)> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut out = Vec::new();
    for entry in entries.flatten() {
        let path = entry.path();
        let Some(name) = path.file_name().and_then(|n| n.to_str()) else { continue };
        let Some(stem) = name.strip_suffix(".mcap.part") else { continue };
        // Never over an earlier crash's file (see [`unused_name`]).
        let target = unused_file(dir, stem, "recovered.mcap");
        // Rewritten with a summary and a footer so that every MCAP reader opens it; the cut
        // original is kept only if that fails.
        match arash_core::flightlog::rewrite_complete(&path, &target) {
            Ok(_) => {
                let _ = std::fs::remove_file(&path);
            }
            Err(e) => {
                let kept = unused_file(dir, stem, "cut.mcap");
                let _ = std::fs::rename(&path, &kept);
                out.push((kept, Err(format!("could not rewrite it complete: {e}"))));
                continue;
            }
        }
        let cycles = arash_core::flightlog::read_log(&target).map(|l| l.len()).map_err(|e| e.to_string());
        out.push((target, cycles));
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// The file being written: its final path, and when and at what time it began.
struct Segment {
    writer: LogWriter,
    part: PathBuf,
    path: PathBuf,
    opened: Instant,
    /// Cycle time of the first cycle (s); the file's times start at zero there.
    t0: Option<f64>,
    /// File time of the last cycle written (s).
    last_t: f64,
    run: Option<u32>,
}

/// Period and execution-time histograms (µs bins, log-spaced upper edges).
#[derive(Default)]
struct Histograms {
    period_error: [u64; EDGES_US.len() + 1],
    exec: [u64; EDGES_US.len() + 1],
    max_period_error_us: f64,
    max_exec_us: f64,
}

const EDGES_US: [f64; 12] = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0, 5000.0];

fn bin(x_us: f64) -> usize {
    EDGES_US.iter().position(|&e| x_us < e).unwrap_or(EDGES_US.len())
}

pub struct Logger {
    cfg: LogConfig,
    ctx: LogContext,
    runs: RunRegistry,
    shared: Arc<Shared>,
    segment: Option<Segment>,
    idle_files: u32,
    record: CycleRecord,
    blackbox: VecDeque<CycleSample>,
    blackbox_len: usize,
    blackbox_pending: Option<Faults>,
    histograms: Histograms,
    /// Whole-run histograms at 1 µs resolution, for the closing summary's quantiles: bounded
    /// memory however long the daemon runs.
    period_errors_us: FineHistogram,
    exec_us: FineHistogram,
    last_link: crate::link::LinkStats,
    /// The link as of the newest cycle: each file's metadata gets it when the file closes.
    link_now: crate::link::LinkStats,
    last_dropped: u64,
    nominal_ns: f64,
    window: ErrorWindow,
    live: Option<Arc<LiveServer>>,
    /// The window's error, encoded (reused).
    encoded: Vec<u8>,
}

impl Logger {
    pub fn new(cfg: LogConfig, ctx: LogContext, runs: RunRegistry, shared: Arc<Shared>) -> anyhow::Result<Self> {
        std::fs::create_dir_all(&cfg.dir)
            .map_err(|e| anyhow::anyhow!("creating the log directory {}: {e}", cfg.dir.display()))?;
        let dof = ctx.joint_names.len();
        let capacity = (cfg.blackbox_s * ctx.rate_hz).ceil() as usize;
        Ok(Self {
            window: ErrorWindow::new(ctx.window_cycles, ctx.error_scales.clone()),
            live: None,
            encoded: Vec::with_capacity(1024),
            nominal_ns: 1e9 / ctx.rate_hz,
            blackbox: VecDeque::with_capacity(capacity + 1),
            blackbox_len: capacity.max(1),
            cfg,
            ctx,
            runs,
            shared,
            segment: None,
            idle_files: 0,
            record: CycleRecord::new(dof),
            blackbox_pending: None,
            histograms: Histograms::default(),
            period_errors_us: FineHistogram::default(),
            exec_us: FineHistogram::default(),
            last_link: Default::default(),
            link_now: Default::default(),
            last_dropped: 0,
        })
    }

    /// Also hand each window, the timing and the events to the live stream.
    pub fn with_live(mut self, live: Arc<LiveServer>) -> Self {
        self.live = Some(live);
        self
    }

    /// Drain `queue` until the control thread is gone, then finish the file.
    pub fn run(mut self, mut queue: rtrb::Consumer<LogItem>) -> anyhow::Result<TimingSummary> {
        self.open_idle()?;
        loop {
            let mut any = false;
            while let Ok(item) = queue.pop() {
                any = true;
                self.handle(item)?;
            }
            if !any {
                if queue.is_abandoned() && queue.is_empty() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(2));
            }
        }
        self.close()?;
        Ok(self.summary())
    }

    fn handle(&mut self, item: LogItem) -> anyhow::Result<()> {
        match item {
            LogItem::Event { cycle, t, event, drive } => self.event(cycle, t, event, drive),
            LogItem::Cycle(s) => self.cycle(&s),
        }
    }

    fn event(&mut self, cycle: u64, t: f64, event: Event, drive: DriveReport) -> anyhow::Result<()> {
        let description = match event {
            Event::Enabled => "motors enabled".to_string(),
            Event::Disabled => "motors disabled".to_string(),
            Event::EnableRefused => "enable refused (no telemetry yet, a latched fault, or already enabled)".into(),
            Event::FaultLatched(f) => {
                self.blackbox_pending = Some(f);
                let names = f.names().join(", ");
                match f.contains(Faults::MOTOR) {
                    true => format!("fault latched: {names} (the drive: {})", drive.describe()),
                    false => format!("fault latched: {names}"),
                }
            }
            Event::FaultsCleared => "faults cleared by the operator".into(),
            Event::RunStarted(id) => format!("run {id} started"),
            Event::RunEnded(id) => format!("run {id} ended"),
            Event::ControllerSwitched => "controller switched".into(),
            Event::ContactStarted => "contact: the hand's force estimate crossed the contact threshold".into(),
            Event::ContactEnded => "contact ended".into(),
            Event::RunRefused => "run refused: a collision is latched (reset it first)".into(),
            Event::HapticStarted => "haptic mode: the hand moves the instrument under the rendered fixtures".into(),
            Event::FixturesSwitched => "haptic mode: fixtures switched".into(),
            Event::HapticEnded => "haptic mode ended".into(),
            Event::HapticRefused => {
                "haptic mode refused: enable the motors and hold first, with no collision latched".into()
            }
        };
        self.write_event(cycle, t, &description)?;
        match event {
            Event::RunStarted(id) => self.open_run(id)?,
            Event::RunEnded(id) if self.segment.as_ref().is_some_and(|s| s.run == Some(id)) => {
                let path = self.finish_segment()?;
                if let Some(run) = self.runs.lock().expect("registry lock").get_mut(&id) {
                    run.log = path;
                    run.state = "done".into();
                }
                self.open_idle()?;
            }
            _ => {}
        }
        Ok(())
    }

    /// Log one line to the event channel and to stderr (the journal, under systemd).
    pub fn write_event(&mut self, cycle: u64, t: f64, description: &str) -> anyhow::Result<()> {
        eprintln!("arash-daemon: cycle {cycle}: {description}");
        let json = serde_json::json!({ "cycle": cycle, "t": t, "event": description }).to_string();
        if let Some(s) = self.segment.as_mut() {
            let t = t - s.t0.unwrap_or(t);
            s.writer.write_json(EVENT_TOPIC, t, &json)?;
            if let Some(live) = &self.live {
                live.publish(Topic::Event, s.writer.log_time(t.max(0.0)), json.as_bytes());
            }
        }
        Ok(())
    }

    fn cycle(&mut self, s: &CycleSample) -> anyhow::Result<()> {
        self.link_now = s.link;
        let r = &mut self.record;
        s.record.write_into(r);
        let segment = self.segment.as_mut().expect("a segment is open");
        let t0 = *segment.t0.get_or_insert(s.record.t);
        r.t = s.record.t - t0;
        segment.last_t = r.t;
        let log_time = segment.writer.log_time(r.t);
        let cycle = segment.writer.write_cycle(r)?;
        if let Some(error) = self.window.push(r) {
            // The window's last cycle (as the file has it) and its error, to the live stream and
            // the file at the same log time.
            self.encoded.clear();
            error.encode(&mut self.encoded).expect("a Vec grows as needed");
            if let Some(live) = &self.live {
                live.publish(Topic::Cycle, log_time, cycle);
                live.publish(Topic::Error, log_time, &self.encoded);
                live.publish_scene(log_time, &r.q, (&r.frame_force, &r.fixture_force));
            }
            segment.writer.write_protobuf(ERROR_TOPIC, ERROR_SCHEMA, r.t, &self.encoded)?;
        }
        self.timing(s)?;
        if self.blackbox.len() >= self.blackbox_len {
            self.blackbox.pop_front();
        }
        self.blackbox.push_back(*s);
        if let Some(faults) = self.blackbox_pending.take() {
            self.write_blackbox(s.record.cycle, faults)?;
        }
        self.rotate_if_due()
    }

    fn timing(&mut self, s: &CycleSample) -> anyhow::Result<()> {
        if s.record.cycle > 0 {
            let error_us = (s.period_ns as f64 - self.nominal_ns) / 1e3;
            let exec_us = s.exec_ns as f64 / 1e3;
            let h = &mut self.histograms;
            h.period_error[bin(error_us.abs())] += 1;
            h.exec[bin(exec_us)] += 1;
            h.max_period_error_us = h.max_period_error_us.max(error_us.abs());
            h.max_exec_us = h.max_exec_us.max(exec_us);
            self.period_errors_us.add(error_us.abs());
            self.exec_us.add(exec_us);
        }
        let per_second = self.ctx.rate_hz.round().max(1.0) as u64;
        if s.record.cycle % per_second != per_second - 1 {
            return Ok(());
        }
        let h = std::mem::take(&mut self.histograms);
        let dropped = self.shared.log_dropped.load(Ordering::Relaxed);
        let link = s.link;
        let json = serde_json::json!({
            "cycle": s.record.cycle,
            "bin_upper_edges_us": EDGES_US,
            "period_error_us": h.period_error,
            "exec_us": h.exec,
            "max_period_error_us": h.max_period_error_us,
            "max_exec_us": h.max_exec_us,
            "missed_cycles": s.missed,
            "log_dropped": dropped,
            "link": link,
        })
        .to_string();
        let segment = self.segment.as_mut().expect("a segment is open");
        let t = s.record.t - segment.t0.unwrap_or(s.record.t);
        segment.writer.write_json(TIMING_TOPIC, t, &json)?;
        if let Some(live) = &self.live {
            live.publish(Topic::Timing, segment.writer.log_time(t.max(0.0)), json.as_bytes());
        }
        if link.errors() > self.last_link.errors() || dropped > self.last_dropped {
            let (bus, was) = (link.bus.unwrap_or_default(), self.last_link.bus.unwrap_or_default());
            let text = format!(
                "link errors in the last second: {} CRC, {} framing, {} lost, {} stale, {} send; CAN adapter: {} \
                 refused, {} bus errors, {} overruns, {} malformed lines; {} log items dropped",
                link.crc_errors - self.last_link.crc_errors,
                link.framing_errors - self.last_link.framing_errors,
                link.lost - self.last_link.lost,
                link.stale - self.last_link.stale,
                link.send_errors - self.last_link.send_errors,
                bus.refused - was.refused,
                bus.bus_errors - was.bus_errors,
                bus.overruns - was.overruns,
                bus.malformed - was.malformed,
                dropped - self.last_dropped,
            );
            self.write_event(s.record.cycle, s.record.t, &text)?;
        }
        self.last_link = link;
        self.last_dropped = dropped;
        Ok(())
    }

    fn write_blackbox(&mut self, cycle: u64, faults: Faults) -> anyhow::Result<()> {
        let path = self.cfg.dir.join(format!("blackbox-{cycle}.mcap"));
        let mut header = self.header("blackbox", None);
        header.metadata.insert("faults".into(), faults.names().join(", "));
        let mut writer = LogWriter::create(&path, &header, self.ctx.rate_hz)?;
        let mut record = CycleRecord::new(self.ctx.joint_names.len());
        let t0 = self.blackbox.front().map_or(0.0, |s| s.record.t);
        for s in &self.blackbox {
            s.record.write_into(&mut record);
            record.t = s.record.t - t0;
            writer.write_cycle(&record)?;
        }
        writer.finish()?;
        eprintln!("arash-daemon: black box of the last {} cycles written to {}", self.blackbox.len(), path.display());
        Ok(())
    }

    fn header(&self, segment: &str, run: Option<(u32, &RunInfo)>) -> LogHeader {
        let mut metadata = self.ctx.metadata.clone();
        metadata.insert("source".into(), "arash-daemon".into());
        metadata.insert("segment".into(), segment.into());
        let mut attachments =
            vec![("daemon.toml".to_string(), "application/toml".to_string(), self.ctx.config_toml.as_bytes().to_vec())];
        if let Some((id, info)) = run {
            metadata.insert("run_id".into(), id.to_string());
            metadata.insert("run_label".into(), info.label.clone());
            metadata.insert("controller".into(), info.controller.clone());
            attachments.push((
                "trajectory.json".to_string(),
                "application/json".to_string(),
                info.trajectory_json.as_bytes().to_vec(),
            ));
            attachments.push((
                "controller.json".to_string(),
                "application/json".to_string(),
                info.controller_json.as_bytes().to_vec(),
            ));
        }
        let start_unix_ns =
            std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64);
        LogHeader {
            urdf: self.ctx.urdf.clone(),
            joint_names: self.ctx.joint_names.clone(),
            metadata,
            attachments,
            with_truth: false,
            start_unix_ns,
        }
    }

    fn open(&mut self, name: &str, segment: &str, run: Option<u32>) -> anyhow::Result<()> {
        let info = run.and_then(|id| self.runs.lock().expect("registry lock").get(&id).cloned());
        let header = self.header(segment, run.zip(info.as_ref()));
        let name = unused_name(&self.cfg.dir, name);
        let path = self.cfg.dir.join(format!("{name}.mcap"));
        let part = self.cfg.dir.join(format!("{name}.mcap.part"));
        let mut writer = LogWriter::create(&part, &header, self.ctx.rate_hz)?;
        // The URDF once more as a message, for Foxglove's URDF layer (it reads no attachment).
        let description = serde_json::json!({ "data": self.ctx.urdf }).to_string();
        writer.write_json(ROBOT_DESCRIPTION_TOPIC, 0.0, &description)?;
        self.segment = Some(Segment { writer, part, path, opened: Instant::now(), t0: None, last_t: 0.0, run });
        Ok(())
    }

    fn open_idle(&mut self) -> anyhow::Result<()> {
        self.idle_files += 1;
        let stamp = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs());
        self.open(&format!("daemon-{stamp}-{}", self.idle_files), "idle", None)
    }

    fn open_run(&mut self, id: u32) -> anyhow::Result<()> {
        self.finish_segment()?;
        let label = match self.runs.lock().expect("registry lock").get_mut(&id) {
            Some(run) => {
                run.state = "running".into();
                run.label.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect()
            }
            None => String::new(),
        };
        self.open(&format!("run-{id}-{label}"), "run", Some(id))
    }

    /// Finish the open file and give it its final name.
    fn finish_segment(&mut self) -> anyhow::Result<Option<PathBuf>> {
        let Some(mut s) = self.segment.take() else { return Ok(None) };
        s.writer.write_metadata(LINK_METADATA, link_metadata(&self.link_now))?;
        s.writer.finish()?;
        std::fs::rename(&s.part, &s.path)
            .map_err(|e| anyhow::anyhow!("renaming {} to {}: {e}", s.part.display(), s.path.display()))?;
        Ok(Some(s.path))
    }

    fn rotate_if_due(&mut self) -> anyhow::Result<()> {
        let Some(s) = &self.segment else { return Ok(()) };
        if s.run.is_some() || s.opened.elapsed().as_secs() < 1 {
            return Ok(());
        }
        let size_mib = std::fs::metadata(&s.part).map_or(0.0, |m| m.len() as f64 / (1024.0 * 1024.0));
        if size_mib >= self.cfg.rotate_mib || s.opened.elapsed().as_secs_f64() >= self.cfg.rotate_s {
            self.finish_segment()?;
            self.open_idle()?;
        }
        Ok(())
    }

    fn close(&mut self) -> anyhow::Result<()> {
        let summary = self.summary();
        if let Some(s) = self.segment.as_mut() {
            let json = serde_json::to_string(&summary).expect("the summary serialises");
            s.writer.write_json(TIMING_TOPIC, s.last_t, &json)?;
        }
        self.finish_segment()?;
        Ok(())
    }

    fn summary(&self) -> TimingSummary {
        let (p50, p99, max) = self.period_errors_us.quantiles();
        let (e50, e99, emax) = self.exec_us.quantiles();
        TimingSummary {
            cycles: self.exec_us.count as usize,
            period_error_abs_p50_us: p50,
            period_error_abs_p99_us: p99,
            period_error_abs_max_us: max,
            exec_p50_us: e50,
            exec_p99_us: e99,
            exec_max_us: emax,
        }
    }
}

/// The metadata record each file closes with: the link's counters and state then
/// ([`crate::link::LinkStats`], each field's JSON under its name).
pub const LINK_METADATA: &str = "arash.link";

fn link_metadata(link: &crate::link::LinkStats) -> std::collections::BTreeMap<String, String> {
    let json = serde_json::to_value(link).expect("the link's counters serialise");
    let fields = json.as_object().expect("a struct serialises as an object");
    fields.iter().map(|(k, v)| (k.clone(), v.to_string())).collect()
}

/// Whole-run timing: quantiles of the period error (actual − nominal period) and of the
/// execution time, in µs.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct TimingSummary {
    pub cycles: usize,
    pub period_error_abs_p50_us: f64,
    pub period_error_abs_p99_us: f64,
    pub period_error_abs_max_us: f64,
    pub exec_p50_us: f64,
    pub exec_p99_us: f64,
    pub exec_max_us: f64,
}

/// Counts in 1 µs bins up to 20 ms, one overflow bin, and the exact maximum.
struct FineHistogram {
    bins: Vec<u64>,
    count: u64,
    max: f64,
}

impl Default for FineHistogram {
    fn default() -> Self {
        Self { bins: vec![0; 20_001], count: 0, max: 0.0 }
    }
}

impl FineHistogram {
    fn add(&mut self, us: f64) {
        let i = (us.max(0.0) as usize).min(self.bins.len() - 1);
        self.bins[i] += 1;
        self.count += 1;
        self.max = self.max.max(us);
    }

    /// p50, p99 (upper edge of their 1 µs bin) and the maximum.
    fn quantiles(&self) -> (f64, f64, f64) {
        let at = |p: f64| -> f64 {
            let target = (p * self.count as f64).ceil().max(1.0) as u64;
            let mut seen = 0;
            for (i, &c) in self.bins.iter().enumerate() {
                seen += c;
                if seen >= target {
                    return if i + 1 == self.bins.len() { self.max } else { (i + 1) as f64 };
                }
            }
            self.max
        };
        if self.count == 0 {
            return (0.0, 0.0, 0.0);
        }
        (at(0.5), at(0.99), self.max)
    }
}

/// `dir/<stem>.<ext>`, or `<stem>-2.<ext>`, … if that file exists.
fn unused_file(dir: &Path, stem: &str, ext: &str) -> PathBuf {
    (1..)
        .map(|k| match k {
            1 => dir.join(format!("{stem}.{ext}")),
            k => dir.join(format!("{stem}-{k}.{ext}")),
        })
        .find(|p| !p.exists())
        .expect("an unused name")
}

/// `name`, or `name-2`, `name-3`, … if a log of that name is already in `dir`, finished, being
/// written or recovered from a crash: run numbers start again at 1 when the daemon restarts, and
/// a daemon restarted within the second of a crash stamps its idle log as the cut one was named
/// (a second crash would then be recovered over the first's file).
fn unused_name(dir: &std::path::Path, name: &str) -> String {
    let taken = |n: &str| {
        ["mcap", "mcap.part", "recovered.mcap", "cut.mcap"].iter().any(|ext| dir.join(format!("{n}.{ext}")).exists())
    };
    if !taken(name) {
        return name.to_string();
    }
    (2..).map(|k| format!("{name}-{k}")).find(|n| !taken(n)).expect("an unused name")
}

#[cfg(test)]
mod tests {
    use super::{unused_name, FineHistogram};

    #[test]
    fn a_log_never_takes_the_name_of_one_already_there() {
        let dir = std::env::temp_dir().join(format!("arash-logger-names-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        assert_eq!(unused_name(&dir, "run-1-x"), "run-1-x");
        std::fs::write(dir.join("run-1-x.mcap"), b"").unwrap();
        assert_eq!(unused_name(&dir, "run-1-x"), "run-1-x-2");
        std::fs::write(dir.join("run-1-x-2.mcap.part"), b"").unwrap();
        assert_eq!(unused_name(&dir, "run-1-x"), "run-1-x-3");
        std::fs::write(dir.join("run-1-x-3.recovered.mcap"), b"").unwrap();
        assert_eq!(unused_name(&dir, "run-1-x"), "run-1-x-4");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn recovering_a_crash_never_overwrites_an_earlier_crashs_file() {
        let dir = std::env::temp_dir().join(format!("arash-logger-recover-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        // An earlier crash's files, and a new `.part` of the same name (empty: cut before its
        // first flush).
        std::fs::write(dir.join("daemon-1-1.recovered.mcap"), b"earlier").unwrap();
        std::fs::write(dir.join("daemon-1-1.cut.mcap"), b"earlier").unwrap();
        std::fs::write(dir.join("daemon-1-1.mcap.part"), b"").unwrap();
        let out = super::recover(&dir);
        assert_eq!(out.len(), 1);
        let kept = out[0].0.file_name().unwrap().to_str().unwrap();
        assert!(["daemon-1-1-2.recovered.mcap", "daemon-1-1-2.cut.mcap"].contains(&kept), "{kept}");
        for earlier in ["daemon-1-1.recovered.mcap", "daemon-1-1.cut.mcap"] {
            assert_eq!(std::fs::read(dir.join(earlier)).unwrap(), b"earlier", "{earlier}");
        }
        assert!(!dir.join("daemon-1-1.mcap.part").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn quantiles_come_from_1_us_bins_and_the_maximum_is_exact() {
        let mut h = FineHistogram::default();
        for i in 0..1000 {
            h.add(f64::from(i) + 0.5);
        }
        h.add(123_456.7);
        let (p50, p99, max) = h.quantiles();
        assert_eq!((p50, p99, max), (501.0, 991.0, 123_456.7));
    }
}
