//! Logged runs for identification, from either of two formats:
//! - an MCAP flight log (`.mcap`) from `arash simulate` or the daemon: `t`, measured `q` and the
//!   torque measured from motor current;
//! - CSV: a header naming `t`, then `q.<joint>` and `tau.<joint>` for every actuated joint (SI
//!   units: s, rad or m, N·m or N). Other columns are ignored, and column order is free.

use std::path::Path;

use anyhow::{bail, Context};
use arash_core::control::Trajectory;
use arash_core::flightlog::on_uniform_grid;
use arash_core::force::TorqueTiming;
use arash_core::identify::closed_loop::LoggedController;
use arash_core::Model;

/// A log: `t` (N) and row-major `q`, `tau` (N × dof).
#[derive(Clone)]
pub struct Log {
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub tau: Vec<f64>,
    /// The reference the run followed, when the log says (flight logs of `arash simulate` and
    /// of daemon runs).
    pub trajectory: Option<Trajectory>,
    /// What a closed-loop estimator needs beyond `t`, `q`, `τ`, when the log has it.
    pub closed_loop: Option<ClosedLoopChannels>,
    /// Where each run after the first begins, when this is several runs concatenated: the robot
    /// moved between them, so nothing is to be filtered across these samples.
    pub starts: Vec<usize>,
    /// What `--repair` did to the runs ([`Log::repaired`]), one line per change, each naming its file.
    pub repairs: Vec<arash_core::choices::Choice>,
    /// How the logged torque acted between its sample and the next: the daemon's telemetry
    /// reports the current over the cycle that ended at its sample, `arash simulate` records the
    /// one over the cycle that follows, a CSV is taken as sampled.
    pub timing: TorqueTiming,
}

impl Log {
    /// Where this joined log jumps: each run start at which some joint moves by more than
    /// [`JUMP_OVER_STEP`] times its largest step within [`JUMP_WINDOW`] samples either side, as
    /// (sample, joint, jump). A fit filters its training log as one series, and rings across such
    /// a jump; logs that continue one another do not jump.
    pub fn jumps(&self) -> Vec<(usize, usize, f64)> {
        let n = self.t.len();
        if self.starts.is_empty() || n < 2 {
            return Vec::new();
        }
        let dof = self.q.len() / n;
        let step = |i: usize, k: usize| (self.q[i * dof + k] - self.q[(i - 1) * dof + k]).abs();
        let mut jumps = Vec::new();
        for &s in &self.starts {
            let around = (s.saturating_sub(JUMP_WINDOW).max(1)..(s + JUMP_WINDOW + 1).min(n)).filter(|&i| i != s);
            for k in 0..dof {
                let largest = around.clone().map(|i| step(i, k)).fold(0.0, f64::max);
                if step(s, k) > JUMP_OVER_STEP * largest {
                    jumps.push((s, k, step(s, k)));
                }
            }
        }
        jumps
    }

    /// This log repaired ([`arash_core::signal::repair`]): a corrupt block at either end trimmed
    /// and irregular stamps resampled, the reference alike. Returns the log and what was done.
    pub fn repaired(self) -> Result<(Log, Vec<arash_core::choices::Choice>), arash_core::signal::repair::RepairError> {
        let dof = self.q.len() / self.t.len().max(1);
        let mut signals = vec![("q", self.q.as_slice(), dof), ("tau", self.tau.as_slice(), dof)];
        if let Some(c) = &self.closed_loop {
            signals.extend(
                ["q_des", "qd_des", "qdd_des"].into_iter().zip(&c.reference).map(|(n, r)| (n, r.as_slice(), dof)),
            );
        }
        let repaired = arash_core::signal::repair::repair(&self.t, &signals)?;
        let mut columns = repaired.signals.into_iter();
        let (q, tau) = (columns.next().unwrap_or_default(), columns.next().unwrap_or_default());
        let closed_loop = self.closed_loop.map(|c| ClosedLoopChannels {
            reference: [columns.next(), columns.next(), columns.next()].map(Option::unwrap_or_default),
            controller: c.controller,
        });
        let (trajectory, starts, repairs, timing) = (self.trajectory, self.starts, self.repairs, self.timing);
        let log = Log { t: repaired.t, q, tau, trajectory, closed_loop, starts, repairs, timing };
        Ok((log, repaired.report))
    }

    /// The held-out runs as the diagnosis takes them.
    pub fn runs(&self) -> arash_core::diagnose::Runs<'_> {
        let log = arash_core::identify::Log { t: &self.t, q: &self.q, tau: &self.tau };
        arash_core::diagnose::Runs { log, starts: &self.starts }
    }
}

/// The reference `(q_des, q̇_des, q̈_des)` at every sample (row-major N × dof each), and the
/// controller the run was made with, or why the log does not name one.
#[derive(Clone)]
pub struct ClosedLoopChannels {
    pub reference: [Vec<f64>; 3],
    pub controller: Result<LoggedController, String>,
}

/// What a run's `tau` is to hold: the joint torque, or the motor currents a calibration from
/// currents fits (`arash identify --loaded`, `arash diagnose --currents`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Effort {
    Torque,
    Current,
}

/// Read a run, by extension: `.mcap` is a flight log, anything else CSV. With `repair`, a CSV
/// cell that is not a finite number reads as NaN, for [`Log::repaired`] to trim, instead of
/// refusing the file. A CSV holds what `effort` asks for; a daemon's flight log holds torques,
/// which [`Effort::Current`] turns back into currents by the torque constants it ran with.
pub fn read(path: &Path, model: &Model, repair: bool, effort: Effort) -> anyhow::Result<Log> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("mcap")) {
        read_flight_log(path, model, effort)
    } else {
        read_csv(path, model, repair)
    }
}

/// The torque per ampere a daemon's flight log was written with: its `torque_constant`
/// metadata, or for a log written before it was kept, the attached configuration's.
fn logged_torque_constant(log: &arash_core::flightlog::FlightLog, path: &Path) -> anyhow::Result<Vec<f64>> {
    if let Some(text) = log.metadata.get("torque_constant") {
        return serde_json::from_str(text).with_context(|| format!("{}: torque_constant metadata", path.display()));
    }
    let config = log.attachment_text("daemon.toml").with_context(|| {
        format!(
            "{} was not written by arash daemon (no torque constants): it holds torques, not currents",
            path.display()
        )
    })?;
    let config = arash_daemon::config::DaemonConfig::parse(&config)
        .with_context(|| format!("{}: daemon.toml", path.display()))?;
    Ok(config.drive.torque_constant)
}

fn read_flight_log(path: &Path, model: &Model, effort: Effort) -> anyhow::Result<Log> {
    let mut log = arash_core::flightlog::read_log(path)?;
    let expected: Vec<&str> = model.joints.iter().map(|j| j.name.as_str()).collect();
    if log.joint_names != expected {
        bail!("{} logs joints {:?}; the robot has {:?}", path.display(), log.joint_names, expected);
    }
    if log.truncated {
        eprintln!("warning: {} was cut off (crash?); using its {} complete cycles", path.display(), log.len());
    }
    if log.is_empty() {
        bail!("{} has no cycles", path.display());
    }
    let dof = model.dof();
    let trajectory = logged_trajectory(&log, dof);
    let controller = match log.logged_controller() {
        Some(named) => named.map_err(|e| e.to_string()),
        None => Err(format!(
            "{} names no controller (neither controller.json nor run.json is attached); give it with --controller",
            path.display()
        )),
    };
    if effort == Effort::Current {
        let k = logged_torque_constant(&log, path)?;
        anyhow::ensure!(k.len() == dof, "{}: {} torque constants for {dof} joints", path.display(), k.len());
        log.cycles.tau_meas.iter_mut().enumerate().for_each(|(i, tau)| *tau /= k[i % dof]);
    }
    let c = log.cycles;
    let closed_loop = ClosedLoopChannels { reference: [c.q_des, c.qd_des, c.qdd_des], controller };
    let (mut log, repaired) = regrid(
        Log {
            t: c.t,
            q: c.q,
            tau: c.tau_meas,
            trajectory: None,
            closed_loop: Some(closed_loop),
            starts: vec![],
            repairs: vec![],
            timing: match log.metadata.get("source").map(String::as_str) {
                Some("simulator") => TorqueTiming::Held,
                _ => TorqueTiming::Preceding,
            },
        },
        dof,
    );
    log.trajectory = trajectory;
    if repaired > 0 {
        eprintln!(
            "note: {}: {repaired} cycles repeated or skipped a measurement (link jitter); \
             resampled onto a uniform grid by linear interpolation",
            path.display()
        );
    }
    Ok(log)
}

/// The trajectory a flight log followed: the daemon attaches `trajectory.json` to a run's log,
/// `arash simulate` its whole run specification as `run.json`.
fn logged_trajectory(log: &arash_core::flightlog::FlightLog, dof: usize) -> Option<Trajectory> {
    if let Some(text) = log.attachment_text("trajectory.json") {
        return Trajectory::from_json(&text, dof).ok();
    }
    let run: serde_json::Value = serde_json::from_str(&log.attachment_text("run.json")?).ok()?;
    Trajectory::from_json(&run.get("trajectory")?.to_string(), dof).ok()
}

/// Measurements on a uniform time grid (`arash_core::flightlog::on_uniform_grid`: repeats
/// dropped, gaps filled, one sample per logged cycle). Returns the log and how many samples were
/// repaired.
fn regrid(log: Log, dof: usize) -> (Log, usize) {
    let mut channels: Vec<&[f64]> = vec![&log.q, &log.tau];
    if let Some(c) = &log.closed_loop {
        channels.extend(c.reference.iter().map(Vec::as_slice));
    }
    let Some(uniform) = on_uniform_grid(&log.t, &channels, dof) else {
        return (log, 0);
    };
    let mut columns = uniform.channels.into_iter();
    let (q, tau) = (columns.next().unwrap_or_default(), columns.next().unwrap_or_default());
    let closed_loop = log.closed_loop.map(|c| ClosedLoopChannels {
        reference: [columns.next(), columns.next(), columns.next()].map(Option::unwrap_or_default),
        controller: c.controller,
    });
    (
        Log {
            t: uniform.t,
            q,
            tau,
            trajectory: log.trajectory,
            closed_loop,
            starts: log.starts,
            repairs: log.repairs,
            timing: log.timing,
        },
        uniform.repaired,
    )
}

fn read_csv(path: &Path, model: &Model, repair: bool) -> anyhow::Result<Log> {
    let mut reader = csv::Reader::from_path(path).with_context(|| format!("opening log {}", path.display()))?;
    let headers = reader.headers().with_context(|| format!("reading the header of {}", path.display()))?.clone();
    let find = |name: &str| -> anyhow::Result<usize> {
        headers.iter().position(|h| h.trim() == name).with_context(|| {
            format!(
                "{} has no column `{name}` (columns: {})",
                path.display(),
                headers.iter().collect::<Vec<_>>().join(", ")
            )
        })
    };
    let t_col = find("t")?;
    let q_cols: Vec<usize> = model.joints.iter().map(|j| find(&format!("q.{}", j.name))).collect::<Result<_, _>>()?;
    let tau_cols: Vec<usize> =
        model.joints.iter().map(|j| find(&format!("tau.{}", j.name))).collect::<Result<_, _>>()?;
    let reference_cols: Option<Vec<Vec<usize>>> = ["q_des", "qd_des", "qdd_des"]
        .iter()
        .map(|channel| {
            model.joints.iter().map(|j| find(&format!("{channel}.{}", j.name)).ok()).collect::<Option<Vec<usize>>>()
        })
        .collect();
    let mut log = Log {
        t: Vec::new(),
        q: Vec::new(),
        tau: Vec::new(),
        trajectory: None,
        closed_loop: None,
        starts: vec![],
        repairs: vec![],
        timing: TorqueTiming::Sampled,
    };
    let mut reference: [Vec<f64>; 3] = Default::default();
    for (line, record) in reader.records().enumerate() {
        let record = record.with_context(|| format!("{}: record {}", path.display(), line + 1))?;
        let value = |col: usize| -> anyhow::Result<f64> {
            let text = record.get(col).unwrap_or("");
            match text.trim().parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ if repair => Ok(f64::NAN),
                _ => bail!(
                    "{}: row {} column `{}` is `{text}`, not a finite number (--repair trims a corrupt block at \
                     either end of a log)",
                    path.display(),
                    line + 2,
                    &headers[col]
                ),
            }
        };
        log.t.push(value(t_col)?);
        for &c in &q_cols {
            log.q.push(value(c)?);
        }
        for &c in &tau_cols {
            log.tau.push(value(c)?);
        }
        for (columns, out) in reference_cols.iter().flatten().zip(&mut reference) {
            for &c in columns {
                out.push(value(c)?);
            }
        }
    }
    if reference_cols.is_some() {
        let controller =
            Err(format!("{} is a CSV log, which names no controller; give it with --controller", path.display()));
        log.closed_loop = Some(ClosedLoopChannels { reference, controller });
    }
    if log.t.is_empty() {
        bail!("{} has no data rows", path.display());
    }
    Ok(log)
}

/// How many times a joint's largest step nearby a move at a run's start must exceed to count as
/// a jump between runs...
pub const JUMP_OVER_STEP: f64 = 10.0;
/// ... nearby meaning within this many samples either side.
pub const JUMP_WINDOW: usize = 50;

/// Concatenate logs recorded back to back at the same rate (their time stamps are re-based). One
/// log keeps its closed-loop channels; several runs have no single reference and controller.
pub fn concatenate(mut logs: Vec<Log>) -> Log {
    let trajectory = logs.first().and_then(|l| l.trajectory.clone());
    let closed_loop = match logs.as_mut_slice() {
        [one] => one.closed_loop.take(),
        _ => None,
    };
    let timing = logs.first().map_or(TorqueTiming::Sampled, |l| l.timing);
    let mut out = Log {
        t: Vec::new(),
        q: Vec::new(),
        tau: Vec::new(),
        trajectory,
        closed_loop,
        starts: vec![],
        repairs: vec![],
        timing,
    };
    for log in logs {
        if !out.t.is_empty() {
            out.starts.push(out.t.len());
        }
        let dt = if log.t.len() > 1 { log.t[1] - log.t[0] } else { 0.0 };
        let offset = out.t.last().map_or(0.0, |last| last + dt) - log.t[0];
        out.t.extend(log.t.iter().map(|t| t + offset));
        out.q.extend(log.q);
        out.tau.extend(log.tau);
        out.repairs.extend(log.repairs);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A daemon-like flight log of ARASH:ASiST whose logged torque is `tau` on every joint, with
    /// `metadata`; its path.
    fn flight_log(name: &str, tau: [f64; 3], metadata: &[(&str, &str)]) -> std::path::PathBuf {
        use arash_core::flightlog::{LogHeader, LogWriter};
        let model = arash_core::arash_asist();
        let path = std::env::temp_dir().join(format!("arash-runlog-{name}-{}.mcap", std::process::id()));
        let header = LogHeader {
            urdf: arash_core::ARASH_ASIST_URDF.into(),
            joint_names: model.joint_names(),
            metadata: metadata.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect(),
            attachments: vec![],
            with_truth: false,
            start_unix_ns: 0,
        };
        let mut writer = LogWriter::create(&path, &header, 1000.0).unwrap();
        let mut record = arash_core::record::CycleRecord::new(3);
        for cycle in 0..5 {
            record.cycle = cycle;
            record.t = cycle as f64 * 1e-3;
            record.tau_meas.copy_from_slice(&tau);
            writer.write_cycle(&record).unwrap();
        }
        writer.finish().unwrap();
        path
    }

    /// Read as currents, a daemon's log gives its torques over the torque constants it ran with;
    /// a log without them is refused by name, not read as amperes.
    #[test]
    fn a_daemon_log_read_as_currents_divides_by_its_torque_constants() {
        let model = arash_core::arash_asist();
        let path = flight_log("k", [1.0, 2.0, 3.0], &[("torque_constant", "[0.5, 4.0, 2.0]")]);
        let currents = read(&path, &model, false, Effort::Current).unwrap();
        assert_eq!(&currents.tau[..3], &[2.0, 0.5, 1.5]);
        assert_eq!(&read(&path, &model, false, Effort::Torque).unwrap().tau[..3], &[1.0, 2.0, 3.0]);
        let bare = flight_log("bare", [1.0, 2.0, 3.0], &[]);
        let error = read(&bare, &model, false, Effort::Current).map(|_| ()).map_err(|e| format!("{e:#}")).unwrap_err();
        assert!(error.contains("not written by arash daemon"), "{error}");
        for p in [path, bare] {
            std::fs::remove_file(p).unwrap();
        }
    }

    /// A repeated time is dropped from every channel alike: the reference stays aligned with the
    /// measurement, and the controller is kept.
    #[test]
    fn regridding_moves_the_reference_with_the_measurement() {
        let t = vec![0.0, 0.001, 0.002, 0.002, 0.003, 0.004, 0.006, 0.007];
        let q: Vec<f64> = t.iter().map(|t| 3.0 * t).collect();
        let reference = [q.clone(), q.clone(), q.clone()];
        let closed_loop = Some(ClosedLoopChannels { reference, controller: Err("none".into()) });
        let (out, repaired) = regrid(
            Log {
                t,
                q: q.clone(),
                tau: q,
                trajectory: None,
                closed_loop,
                starts: vec![],
                repairs: vec![],
                timing: TorqueTiming::Sampled,
            },
            1,
        );
        assert_eq!(repaired, 2);
        let c = out.closed_loop.expect("kept");
        assert!(c.reference.iter().all(|r| *r == out.q) && c.controller.is_err());
    }

    /// A daemon run's log starts at the daemon's clock: one log is re-based to 0 like several, and
    /// keeps its reference and controller; two runs have no single one, and say where the second
    /// begins.
    #[test]
    fn one_log_is_rebased_and_keeps_its_closed_loop_and_two_do_not() {
        let run = |t0: f64| Log {
            t: (0..4).map(|i| t0 + i as f64 * 1e-3).collect(),
            q: vec![0.0; 4],
            tau: vec![0.0; 4],
            trajectory: None,
            closed_loop: Some(ClosedLoopChannels {
                reference: [vec![0.0; 4], vec![0.0; 4], vec![0.0; 4]],
                controller: Err("none".into()),
            }),
            starts: vec![],
            repairs: vec![],
            timing: TorqueTiming::Sampled,
        };
        let one = concatenate(vec![run(12.5)]);
        assert!((one.t[0] - 0.0).abs() < 1e-12 && (one.t[3] - 3e-3).abs() < 1e-12, "{:?}", one.t);
        assert!(one.closed_loop.is_some());
        let two = concatenate(vec![run(12.5), run(40.0)]);
        assert_eq!(two.t.len(), 8);
        assert!((two.t[4] - 4e-3).abs() < 1e-12, "{:?}", two.t);
        assert!(two.closed_loop.is_none());
        assert!(one.starts.is_empty() && two.starts == [4], "{:?}", two.starts);
    }

    /// A joined log names where the robot moved between runs, and only there.
    #[test]
    fn a_jump_between_runs_is_found_and_a_continuous_junction_is_not() {
        let run = |q0: f64| Log {
            t: (0..5).map(|i| i as f64 * 1e-3).collect(),
            q: (0..5).flat_map(|i| [q0 + 1e-4 * i as f64, 0.0]).collect(),
            tau: vec![0.0; 10],
            trajectory: None,
            closed_loop: None,
            starts: vec![],
            repairs: vec![],
            timing: TorqueTiming::Sampled,
        };
        // Continuous: the second run starts one step on from where the first ended.
        assert!(concatenate(vec![run(0.0), run(5e-4)]).jumps().is_empty());
        let jumped = concatenate(vec![run(0.0), run(5e-4), run(3e-3)]);
        let jumps = jumped.jumps();
        assert_eq!(jumps.len(), 1, "{jumps:?}");
        assert_eq!((jumps[0].0, jumps[0].1), (10, 0));
        assert!((jumps[0].2 - (3e-3 - 9e-4)).abs() < 1e-12, "{jumps:?}");
        // A fast move far from the junction does not hide a jump where the robot was at rest.
        let moving = |q0: f64| Log {
            t: (0..200).map(|i| i as f64 * 1e-3).collect(),
            q: (0..200).flat_map(|i: usize| [q0 + 1e-2 * i.clamp(90, 110).saturating_sub(90) as f64, 0.0]).collect(),
            tau: vec![0.0; 400],
            trajectory: None,
            closed_loop: None,
            starts: vec![],
            repairs: vec![],
            timing: TorqueTiming::Sampled,
        };
        let jumps = concatenate(vec![moving(0.0), moving(0.2 + 3e-3)]).jumps();
        assert_eq!(jumps.iter().map(|j| (j.0, j.1)).collect::<Vec<_>>(), [(200, 0)], "{jumps:?}");
    }
}
