//! Logged runs for identification, from either of two formats:
//! - an MCAP flight log (`.mcap`) from `arash simulate` or the daemon: `t`, measured `q` and the
//!   torque measured from motor current;
//! - CSV: a header naming `t`, then `q.<joint>` and `tau.<joint>` for every actuated joint (SI
//!   units: s, rad or m, N·m or N). Other columns are ignored, and column order is free.

use std::path::Path;

use anyhow::{bail, Context};
use arash_core::Model;

/// A log: `t` (N) and row-major `q`, `tau` (N × dof).
pub struct Log {
    pub t: Vec<f64>,
    pub q: Vec<f64>,
    pub tau: Vec<f64>,
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
    Ok(Log { t: log.cycles.t, q: log.cycles.q, tau: log.cycles.tau_meas })
}

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
    let mut log = Log { t: Vec::new(), q: Vec::new(), tau: Vec::new() };
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
    }
    if log.t.is_empty() {
        bail!("{} has no data rows", path.display());
    }
    Ok(log)
}

/// Concatenate logs recorded back to back at the same rate (their time stamps are re-based).
pub fn concatenate(logs: Vec<Log>) -> Log {
    let mut out = Log { t: Vec::new(), q: Vec::new(), tau: Vec::new() };
    for log in logs {
        let dt = if log.t.len() > 1 { log.t[1] - log.t[0] } else { 0.0 };
        let offset = out.t.last().map_or(0.0, |last| last + dt) - log.t[0];
        out.t.extend(log.t.iter().map(|t| t + offset));
        out.q.extend(log.q);
        out.tau.extend(log.tau);
    }
    out
}
