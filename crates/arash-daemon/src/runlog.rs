//! Logged runs for identification, from either of two formats:
//! - an MCAP flight log (`.mcap`) from `arash simulate` or the daemon: `t`, measured `q` and the
//!   torque measured from motor current;
//! - CSV: a header naming `t`, then `q.<joint>` and `tau.<joint>` for every actuated joint (SI
//!   units: s, rad or m, N·m or N). Other columns are ignored, and column order is free.

use std::path::Path;

use anyhow::{bail, Context};
use arash_core::control::Trajectory;
use arash_core::identify::closed_loop::LoggedController;
use arash_core::Model;

/// A log: `t` (N) and row-major `q`, `tau` (N × dof).
pub struct Log {
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub tau: Vec<f64>,
    /// The reference the run followed, when the log says (flight logs of `arash simulate` and
    /// of daemon runs).
    pub trajectory: Option<Trajectory>,
    /// What a closed-loop estimator needs beyond `t`, `q`, `τ`, when the log has it.
    pub closed_loop: Option<ClosedLoopChannels>,
}

/// The reference `(q_des, q̇_des, q̈_des)` at every sample (row-major N × dof each), and the
/// controller the run was made with, or why the log does not name one.
pub struct ClosedLoopChannels {
    pub reference: [Vec<f64>; 3],
    pub controller: Result<LoggedController, String>,
}

/// Read a run, by extension: `.mcap` is a flight log, anything else CSV.
pub fn read(path: &Path, model: &Model) -> anyhow::Result<Log> {
    if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("mcap")) {
        read_flight_log(path, model)
    } else {
        read_csv(path, model)
    }
}

fn read_flight_log(path: &Path, model: &Model) -> anyhow::Result<Log> {
    let log = arash_core::flightlog::read_log(path)?;
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
    let c = log.cycles;
    let closed_loop = ClosedLoopChannels { reference: [c.q_des, c.qd_des, c.qdd_des], controller };
    let (mut log, repaired) =
        regrid(Log { t: c.t, q: c.q, tau: c.tau_meas, trajectory: None, closed_loop: Some(closed_loop) }, dof);
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

/// Measurements on a uniform time grid. The daemon logs each cycle with the drive's time of
/// the measurement it used, so a cycle without new telemetry repeats a time, and telemetry
/// superseded within one cycle leaves a gap. Repeats are dropped and gaps filled by linear
/// interpolation at the median step, keeping one sample per logged cycle. Returns the log and
/// how many samples were repaired.
fn regrid(log: Log, dof: usize) -> (Log, usize) {
    let keep: Vec<usize> = (0..log.t.len()).filter(|&i| i == 0 || log.t[i] > log.t[i - 1]).collect();
    let mut steps: Vec<f64> = keep.windows(2).map(|w| log.t[w[1]] - log.t[w[0]]).collect();
    if steps.is_empty() {
        return (log, 0);
    }
    steps.sort_by(f64::total_cmp);
    let h = steps[steps.len() / 2];
    let uniform = keep.len() == log.t.len() && steps.iter().all(|s| (s - h).abs() < 1e-3 * h);
    if uniform {
        return (log, 0);
    }
    let (t0, t_end) = (log.t[keep[0]], log.t[*keep.last().expect("not empty")]);
    // As many samples as cycles: the daemon logs one cycle per drive period, so the run's
    // length (and with it the period averaging) is that of the log even when its last
    // measurements arrived late; the end holds the last measurement.
    let n = (((t_end - t0) / h).round() as usize + 1).max(log.t.len());
    let mut out = Log {
        t: Vec::with_capacity(n),
        q: Vec::with_capacity(n * dof),
        tau: Vec::with_capacity(n * dof),
        trajectory: log.trajectory,
        closed_loop: log
            .closed_loop
            .as_ref()
            .map(|c| ClosedLoopChannels { reference: Default::default(), controller: c.controller.clone() }),
    };
    let mut repaired = log.t.len() - keep.len();
    let mut j = 0;
    for i in 0..n {
        let t = t0 + i as f64 * h;
        while j + 2 < keep.len() && log.t[keep[j + 1]] <= t {
            j += 1;
        }
        let (a, b) = (keep[j], keep[(j + 1).min(keep.len() - 1)]);
        let span = log.t[b] - log.t[a];
        // A grid point on a logged time takes that sample exactly: blended with a weight of
        // round-off, an encoder's positions leave its grid by 1e-14 and its step no longer shows
        // (`diagnose/band.rs` then reads the whole closed-loop motion as noise).
        let w = match ((t - log.t[a]).abs() <= ON_A_SAMPLE * h, (t - log.t[b]).abs() <= ON_A_SAMPLE * h) {
            (true, _) => 0.0,
            (_, true) => 1.0,
            _ if span > 0.0 => ((t - log.t[a]) / span).clamp(0.0, 1.0),
            _ => 0.0,
        };
        if (t - log.t[a]).abs() > 0.1 * h && (t - log.t[b]).abs() > 0.1 * h {
            repaired += 1;
        }
        out.t.push(t);
        let between = |x: &[f64], k: usize| x[a * dof + k] * (1.0 - w) + x[b * dof + k] * w;
        for k in 0..dof {
            out.q.push(between(&log.q, k));
            out.tau.push(between(&log.tau, k));
        }
        if let (Some(from), Some(to)) = (&log.closed_loop, &mut out.closed_loop) {
            for (x, y) in from.reference.iter().zip(&mut to.reference) {
                y.extend((0..dof).map(|k| between(x, k)));
            }
        }
    }
    (out, repaired)
}

/// A grid point within this share of the step of a logged time is that sample: the drive's
/// clock ticks in whole periods, and what is left is round-off of the sum.
const ON_A_SAMPLE: f64 = 1e-6;

fn read_csv(path: &Path, model: &Model) -> anyhow::Result<Log> {
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
    let mut log = Log { t: Vec::new(), q: Vec::new(), tau: Vec::new(), trajectory: None, closed_loop: None };
    let mut reference: [Vec<f64>; 3] = Default::default();
    for (line, record) in reader.records().enumerate() {
        let record = record.with_context(|| format!("{}: record {}", path.display(), line + 1))?;
        let value = |col: usize| -> anyhow::Result<f64> {
            let text = record.get(col).unwrap_or("");
            match text.trim().parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(v),
                _ => bail!(
                    "{}: row {} column `{}` is `{text}`, not a finite number",
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

/// Concatenate logs recorded back to back at the same rate (their time stamps are re-based). One
/// log keeps its closed-loop channels; several runs have no single reference and controller.
pub fn concatenate(mut logs: Vec<Log>) -> Log {
    let trajectory = logs.first().and_then(|l| l.trajectory.clone());
    let closed_loop = match logs.as_mut_slice() {
        [one] => one.closed_loop.take(),
        _ => None,
    };
    let mut out = Log { t: Vec::new(), q: Vec::new(), tau: Vec::new(), trajectory, closed_loop };
    for log in logs {
        let dt = if log.t.len() > 1 { log.t[1] - log.t[0] } else { 0.0 };
        let offset = out.t.last().map_or(0.0, |last| last + dt) - log.t[0];
        out.t.extend(log.t.iter().map(|t| t + offset));
        out.q.extend(log.q);
        out.tau.extend(log.tau);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeats_are_dropped_and_gaps_interpolated() {
        // A ramp sampled at 1 ms with one repeat (t = 2 ms twice) and one gap (no 5 ms).
        let t = [0.0, 0.001, 0.002, 0.002, 0.003, 0.004, 0.006, 0.007];
        let q: Vec<f64> = t.iter().map(|t| 3.0 * t).collect();
        let log = Log { t: t.to_vec(), q: q.clone(), tau: q, trajectory: None, closed_loop: None };
        let (out, repaired) = regrid(log, 1);
        assert_eq!(repaired, 2);
        assert_eq!(out.t.len(), 8, "one sample per logged cycle");
        for (i, (&t, &q)) in out.t.iter().zip(&out.q).enumerate() {
            assert!((t - i as f64 * 1e-3).abs() < 1e-12);
            assert!((q - 3.0 * t).abs() < 1e-12, "a ramp interpolates exactly");
        }
    }

    /// A daemon run's log starts at the daemon's clock: one log is re-based to 0 like several, and
    /// keeps its reference and controller; two runs have no single one.
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
        };
        let one = concatenate(vec![run(12.5)]);
        assert!((one.t[0] - 0.0).abs() < 1e-12 && (one.t[3] - 3e-3).abs() < 1e-12, "{:?}", one.t);
        assert!(one.closed_loop.is_some());
        let two = concatenate(vec![run(12.5), run(40.0)]);
        assert_eq!(two.t.len(), 8);
        assert!((two.t[4] - 4e-3).abs() < 1e-12, "{:?}", two.t);
        assert!(two.closed_loop.is_none());
    }

    /// Encoder counts stay whole counts where the grid meets a logged time, however the step
    /// `h` (a median of differences) rounds; only the gap's sample is blended.
    #[test]
    fn resampled_positions_keep_the_logged_values_where_the_grid_meets_them() {
        let step = 1.917_475_984_857_162e-6;
        let mut t: Vec<f64> = (0..2000).map(|i| 12.345 + i as f64 * 1e-3).collect();
        t[700] = t[699]; // a repeat, then the same cycles go on: one gap
        let q: Vec<f64> = (0..2000).map(|i| ((i as f64 * 0.0123).sin() * 300.0).round() * step).collect();
        let log = Log { t: t.clone(), q: q.clone(), tau: q.clone(), trajectory: None, closed_loop: None };
        let (out, repaired) = regrid(log, 1);
        assert_eq!(repaired, 2);
        let off_grid = out.q.iter().filter(|x| ((*x / step) - (*x / step).round()).abs() > 1e-9).count();
        assert!(off_grid <= 1, "{off_grid} positions left the encoder's grid");
        assert!(out.q.iter().zip(&q).enumerate().all(|(i, (a, b))| i == 700 || a == b));
    }

    #[test]
    fn a_uniform_log_is_untouched() {
        let t: Vec<f64> = (0..10).map(|i| i as f64 * 1e-3).collect();
        let log = Log { t: t.clone(), q: t.clone(), tau: t.clone(), trajectory: None, closed_loop: None };
        let (out, repaired) = regrid(log, 1);
        assert_eq!((repaired, out.t), (0, t));
    }
}
