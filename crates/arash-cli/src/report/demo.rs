//! The demo's report: `report.md` with the tables, `summary.json` with the headline numbers, and
//! figures in the spirit of the paper's Figs. 3–7 (the excitation, measured against predicted
//! torque, the tracking error, the control effort), beside the diagnosis's own in `diagnosis/`.
//!
//! Angles are shown in degrees and insertion in µm or mm here, at the edge where people read.

use std::fmt::Write as _;
use std::path::Path;

use crate::report::figures::{estimates_against_truth, panels, Panel};
use arash_core::control::fourier::Excitation;
use arash_core::diagnose::Diagnosis;
use arash_core::flightlog::read_log;
use arash_core::identify::ValidationSeries;
use arash_core::model::JointKind;
use arash_core::model_file::ModelFile;
use arash_core::Model;

/// What the calibration step produced.
pub struct Calibration {
    pub ols: ModelFile,
    /// IDIM-IV, the closed-loop estimator.
    pub closed_loop: ModelFile,
    /// Its physically consistent form: the model the controller gets.
    pub consistent: ModelFile,
    /// Where the consistent model was written.
    pub consistent_file: std::path::PathBuf,
    /// Table II, as printed.
    pub table_ii: String,
    /// Measured against predicted torque on one validation run (its ω).
    pub torque: Option<(f64, ValidationSeries)>,
    /// The simulated rig's own base parameters, in the models' order (`None` on a real rig).
    pub truth: Option<Vec<f64>>,
}

/// The estimates of OLS and IDIM-IV set against the simulated rig's own base parameters.
struct AgainstTruth {
    names: Vec<String>,
    truth: Vec<f64>,
    /// Per estimator (OLS, IDIM-IV): its name, estimates and standard deviations.
    estimators: Vec<(&'static str, Vec<f64>, Vec<f64>)>,
}

impl AgainstTruth {
    fn of(calibration: &Calibration) -> Option<Self> {
        let truth = calibration.truth.clone()?;
        let estimators = [("OLS", &calibration.ols), ("IDIM-IV", &calibration.closed_loop)]
            .into_iter()
            .map(|(name, m)| {
                let sigma =
                    m.fitted.beta.iter().zip(&m.fitted.sigma_percent).map(|(b, p)| p / 100.0 * b.abs()).collect();
                (name, m.fitted.beta.clone(), sigma)
            })
            .collect();
        Some(Self { names: calibration.ols.base_names.clone(), truth, estimators })
    }

    /// `(estimate − truth) / σ` of each estimator.
    fn z(&self) -> Vec<(&'static str, Vec<f64>)> {
        self.estimators
            .iter()
            .map(|(name, beta, sigma)| {
                (*name, beta.iter().zip(sigma).zip(&self.truth).map(|((b, s), t)| (b - t) / s).collect())
            })
            .collect()
    }

    /// How many of each estimator's parameters lie within 3σ of the truth.
    fn covered(&self) -> Vec<(&'static str, usize)> {
        self.z().into_iter().map(|(name, z)| (name, z.iter().filter(|v| v.abs() <= 3.0).count())).collect()
    }

    fn table(&self) -> String {
        let mut s = String::from("| # | parameter | truth |");
        for (name, _, _) in &self.estimators {
            let _ = write!(s, " {name} ± σ | (est. − truth)/σ |");
        }
        s.push_str("\n|---|---|---|");
        s.push_str(&"---|---|".repeat(self.estimators.len()));
        s.push('\n');
        let z = self.z();
        for (i, name) in self.names.iter().enumerate() {
            let _ = write!(s, "| {} | {name} | {:.4e} |", i + 1, self.truth[i]);
            for ((_, beta, sigma), (_, z)) in self.estimators.iter().zip(&z) {
                let _ = write!(s, " {:.4e} ± {:.1e} | {:+.1} |", beta[i], sigma[i], z[i]);
            }
            s.push('\n');
        }
        let covered: Vec<String> =
            self.covered().iter().map(|(name, n)| format!("{name} {n} of {}", self.names.len())).collect();
        let _ = writeln!(s, "\nWithin 3σ of the truth: {}.", covered.join(", "));
        s
    }
}

/// One tracking run: its errors, and the series the figures need.
pub struct TrackingRun {
    pub label: String,
    pub log: String,
    /// Per joint, SI.
    pub max_error: Vec<f64>,
    pub rms_error: Vec<f64>,
    t: Vec<f64>,
    /// Row-major N × dof.
    error: Vec<f64>,
    tau_cmd: Vec<f64>,
    /// Cycles after `settle_s` left out as [`disturbed`].
    pub left_out: usize,
    faults: u32,
}

impl TrackingRun {
    /// Read a tracking log and score the cycles from `settle_s` seconds into the run on (the
    /// transient after the start is not tracking: the validation trajectories start moving, the
    /// approach ends at rest), except those [`disturbed`] by the host.
    pub fn read(label: &str, path: &Path, settle_s: f64) -> anyhow::Result<Self> {
        let log = read_log(path)?;
        let c = &log.cycles;
        let dof = log.joint_names.len();
        anyhow::ensure!(!log.is_empty(), "the tracking log {} is empty", path.display());
        let disturbed = disturbed(&c.t);
        let scored = |i: usize| c.t[i] - c.t[0] >= settle_s;
        let kept: Vec<usize> = (0..log.len()).filter(|&i| scored(i) && !disturbed[i]).collect();
        let left_out = (0..log.len()).filter(|&i| scored(i) && disturbed[i]).count();
        anyhow::ensure!(!kept.is_empty(), "the tracking log {} is shorter than {settle_s} s", path.display());
        let rows = |x: &[f64]| -> Vec<f64> { kept.iter().flat_map(|&i| x[i * dof..(i + 1) * dof].to_vec()).collect() };
        let error: Vec<f64> = rows(&c.q).iter().zip(rows(&c.q_des)).map(|(q, d)| q - d).collect();
        let column = |k: usize| error.iter().skip(k).step_by(dof);
        let n = kept.len() as f64;
        let max_error = (0..dof).map(|k| column(k).fold(0.0_f64, |m, e| m.max(e.abs()))).collect();
        let rms_error = (0..dof).map(|k| (column(k).map(|e| e * e).sum::<f64>() / n).sqrt()).collect();
        let t0 = c.t[0];
        Ok(Self {
            label: label.into(),
            log: path.display().to_string(),
            max_error,
            rms_error,
            t: kept.iter().map(|&i| c.t[i] - t0).collect(),
            error,
            tau_cmd: rows(&c.tau_cmd),
            left_out,
            faults: c.faults.iter().fold(0, |a, f| a | f),
        })
    }
}

/// A stall of this many cycles or more is a missed deadline of the host...
const STALL_CYCLES: usize = 3;
/// ...and the controller's recovery from it takes this many cycles.
const RECOVERY_CYCLES: usize = 50;

/// Cycles whose error measures the host rather than the controller. A cycle without new
/// telemetry repeats the last measurement and its time (see `rt::cycle`) while the reference
/// moves on, so its "error" is the link's latency. After a stall of [`STALL_CYCLES`] or more,
/// which the daemon only suffers on a host that is not real-time (`--rt ignore`, as in the
/// demo), the mock motor applies the queued commands in a burst; the next [`RECOVERY_CYCLES`]
/// are the recovery from that, not tracking.
fn disturbed(t: &[f64]) -> Vec<bool> {
    let mut out = vec![false; t.len()];
    let mut missing = 0;
    for i in 1..t.len() {
        if t[i] > t[i - 1] {
            if missing >= STALL_CYCLES {
                let end = (i + RECOVERY_CYCLES).min(t.len());
                out[i..end].fill(true);
            }
            missing = 0;
        } else {
            out[i] = true;
            missing += 1;
        }
    }
    out
}

/// The three tracking runs at `omega`.
pub struct Tracking {
    pub omega: f64,
    /// Whether each joint is prismatic (shown in µm) or revolute (in degrees).
    pub prismatic: Vec<bool>,
    pub runs: Vec<TrackingRun>,
}

/// A joint quantity in its display unit: degrees, or metres times `prismatic_scale`.
fn shown(prismatic: bool, prismatic_scale: f64, x: f64) -> f64 {
    if prismatic {
        x * prismatic_scale
    } else {
        x.to_degrees()
    }
}

fn torque_unit(prismatic: bool) -> &'static str {
    if prismatic {
        "N"
    } else {
        "N·m"
    }
}

fn unit(prismatic: bool) -> &'static str {
    if prismatic {
        "µm"
    } else {
        "°"
    }
}

/// The label of the tracking run with the simulated rig's own parameters of the declared model.
pub const TRUTH_RUN: &str = "robust, the rig's own parameters of the declared model";

impl Tracking {
    /// What the run with the rig's own parameters says about the others, when there is one.
    fn against_truth(&self, joint_names: &[String]) -> Option<String> {
        let baseline = self.runs.first()?;
        let own = self.runs.iter().find(|r| r.label == TRUTH_RUN)?;
        let ratios: Vec<String> = joint_names
            .iter()
            .enumerate()
            .map(|(k, name)| format!("{name} {:.1}×", baseline.max_error[k] / own.max_error[k]))
            .collect();
        Some(format!(
            "The simulated rig has effects the declared model lacks. With the rig's own parameters the declared model \
             cuts the maximum error by {}: those effects, not the estimate, keep it from halving. A fitted model of \
             the declared form takes them up in its own way along the excitation, which can help or hurt on this \
             trajectory; the model with the effects found is the one that removes them (docs/demo.md, \"What the \
             declared model can do on this rig\").",
            ratios.join(", ")
        ))
    }

    /// Maximum and RMS error per joint for each run, and each run's improvement over the first
    /// (the CAD baseline) in maximum error.
    pub fn table(&self, joint_names: &[String]) -> String {
        let mut s = format!(
            "Tracking the validation trajectory at ω = {} rad/s: encoder-measured error over its second period \
             (cycles left out: without new telemetry, or recovering from a stall of the host)\n",
            self.omega
        );
        let _ = write!(s, "| controller |");
        for (name, &p) in joint_names.iter().zip(&self.prismatic) {
            let _ = write!(s, " {name} max ({u}) | {name} RMS ({u}) |", u = unit(p));
        }
        s.push_str(" cycles left out | faults |\n|---|");
        s.push_str(&"---|---|".repeat(joint_names.len()));
        s.push_str("---|---|\n");
        for run in &self.runs {
            let _ = write!(s, "| {} |", run.label);
            for (k, &p) in self.prismatic.iter().enumerate() {
                let _ = write!(s, " {:.4} | {:.4} |", shown(p, 1e6, run.max_error[k]), shown(p, 1e6, run.rms_error[k]));
            }
            let faults = if run.faults == 0 { "none".to_string() } else { format!("{:#x}", run.faults) };
            let _ = writeln!(s, " {} | {faults} |", run.left_out);
        }
        if let Some(baseline) = self.runs.first() {
            for run in &self.runs[1..] {
                let ratios: Vec<String> = joint_names
                    .iter()
                    .enumerate()
                    .map(|(k, name)| format!("{name} {:.1}×", baseline.max_error[k] / run.max_error[k]))
                    .collect();
                let _ = writeln!(s, "\n{}: max error cut by {} against the CAD baseline", run.label, ratios.join(", "));
            }
        }
        s
    }
}

pub fn prismatic(model: &Model) -> Vec<bool> {
    model.joints.iter().map(|j| j.kind == JointKind::Prismatic).collect()
}

/// Column `k` of a row-major N × dof array, in display units.
fn joint_column(x: &[f64], k: usize, dof: usize, prismatic: bool, prismatic_scale: f64) -> Vec<f64> {
    x.iter().skip(k).step_by(dof).map(|v| shown(prismatic, prismatic_scale, *v)).collect()
}

/// Write the report into `dir`; returns how many figures it holds (the diagnosis's included).
/// The report's directory of the real robot's diagnosis (outputs and figures).
pub const REAL_ROBOT_DIR: &str = "real_robot";

/// The demo's real robot: a measured log run through identification and the diagnosis with the
/// defaults, and each coefficient found that the robot's own authors also estimated.
pub struct RealRobot {
    pub name: String,
    /// Where the log and the published values come from, and their licence.
    pub source: String,
    pub samples: usize,
    pub sample_rate_hz: f64,
    pub identification: ModelFile,
    pub diagnosis: Diagnosis,
    pub against_upstream: Vec<Comparison>,
}

/// One coefficient found, beside the published estimate of the same quantity.
pub struct Comparison {
    pub effect: String,
    pub column: String,
    /// Ours and its σ.
    pub ours: (f64, f64),
    /// The published name, value and σ.
    pub upstream: (String, f64, f64),
}

impl Comparison {
    /// Standard deviations (ours and the published σ combined) between the two.
    pub fn z(&self) -> f64 {
        (self.ours.0 - self.upstream.1) / self.ours.1.hypot(self.upstream.2)
    }

    pub fn line(&self) -> String {
        let (name, value, sigma) = &self.upstream;
        format!(
            "{} {}: {:.4} ± {:.4}, published {name} {value:.4} ± {sigma:.4} ({:+.1} σ)",
            self.effect,
            self.column,
            self.ours.0,
            self.ours.1,
            self.z()
        )
    }
}

impl RealRobot {
    /// The report's chapter; its figures are in `figures_dir` (relative to the report).
    fn chapter(&self, figures_dir: &str, figures: &[String]) -> String {
        let d = &self.diagnosis;
        let mut s = format!(
            "## A real robot: the {}'s measured log\n\nSource: {}. {} samples at {} Hz, motor-side, mapped to the joints \
             through the declared transmission; identification and the diagnosis ran with the defaults, every choice \
             made from the data (the reasons are in the report below).\n\n",
            self.name, self.source, self.samples, self.sample_rate_hz
        );
        let _ = writeln!(
            s,
            "Identification (OLS): cut-off {:.2} Hz, training FP% {}.\n",
            self.identification.settings.cutoff_hz,
            self.identification
                .fitted
                .training
                .fp_percent
                .iter()
                .map(|f| format!("{f:.1}"))
                .collect::<Vec<_>>()
                .join(" / ")
        );
        let _ = writeln!(s, "Held-out error per joint before and after the effects found:\n");
        let _ = writeln!(s, "| joint | RMS before | RMS after | FP% before | FP% after |\n|---|---|---|---|---|");
        let (before, after) = (&d.before.heldout, &d.after.heldout);
        for (k, name) in d.joint_names.iter().enumerate() {
            let _ = writeln!(
                s,
                "| {name} | {:.3} | {:.3} | {:.1} | {:.1} |",
                before.rms[k], after.rms[k], before.fp_percent[k], after.fp_percent[k]
            );
        }
        if !self.against_upstream.is_empty() {
            let _ = writeln!(s, "\nThe coefficients found that the robot's authors also estimated:\n");
            for c in &self.against_upstream {
                let _ = writeln!(s, "- {}", c.line());
            }
        }
        let _ = writeln!(s, "\n```\n{}\n```\n", d.report());
        for name in figures {
            let _ = writeln!(s, "![{name}]({figures_dir}/{name})\n");
        }
        s
    }

    fn summary(&self) -> serde_json::Value {
        let against: Vec<serde_json::Value> = self
            .against_upstream
            .iter()
            .map(|c| serde_json::json!({"effect": c.effect, "column": c.column, "ours": c.ours.0, "sigma": c.ours.1,
                "published": c.upstream.0, "published_value": c.upstream.1, "published_sigma": c.upstream.2, "z": c.z()}))
            .collect();
        serde_json::json!({
            "robot": self.name,
            "samples": self.samples,
            "identification_cutoff_hz": self.identification.settings.cutoff_hz,
            "identification_fp_percent": self.identification.fitted.training.fp_percent,
            "accepted": accepted(&self.diagnosis),
            "error_before": self.diagnosis.before,
            "error_after": self.diagnosis.after,
            "against_published": against,
        })
    }
}

pub fn write(
    dir: &Path,
    model: &Model,
    excitation: &Excitation,
    calibration: &Calibration,
    diagnosis: &Diagnosis,
    tracking: &Tracking,
    real: Option<&RealRobot>,
) -> anyhow::Result<usize> {
    let names = model.joint_names();
    let dof = names.len();
    let kinds = prismatic(model);
    // (caption, file name) of each figure, by the report section that shows it.
    let mut excitation_figure = Vec::new();
    let mut calibration_figures = Vec::new();
    let mut tracking_figures = Vec::new();

    // Fig. 3: the excitation, one period.
    let (t, q, _, _) = excitation.sample(200.0, 1);
    let excitation_panels: Vec<Panel> = (0..dof)
        .map(|k| Panel {
            y_label: format!("{} ({})", names[k], if kinds[k] { "mm" } else { "°" }),
            series: vec![("q_d", &t[..], joint_column(&q, k, dof, kinds[k], 1e3))],
        })
        .collect();
    let path = dir.join("excitation.png");
    panels(
        &path,
        &format!("Excitation trajectory (κ = {:.3})", excitation.condition_number),
        "t (s)",
        &excitation_panels,
    )?;
    excitation_figure.push(("The excitation trajectory, one period", "excitation.png"));

    // Figs. 4–5: measured against predicted torque on a validation run.
    if let Some((omega, s)) = &calibration.torque {
        let torque_panels: Vec<Panel> = (0..dof)
            .map(|k| {
                let column = |x: &[f64]| x.iter().skip(k).step_by(dof).copied().collect::<Vec<f64>>();
                Panel {
                    y_label: format!("{} ({})", names[k], torque_unit(kinds[k])),
                    series: vec![
                        ("measured", &s.t[..], column(&s.measured)),
                        ("predicted", &s.t[..], column(&s.predicted)),
                    ],
                }
            })
            .collect();
        let path = dir.join("torque.png");
        panels(
            &path,
            &format!("Measured and predicted torque, validation at ω = {omega} rad/s (consistent model)"),
            "t (s)",
            &torque_panels,
        )?;
        calibration_figures.push(("Measured (filtered) against predicted torque on a validation run", "torque.png"));
    }
    if let Some(against) = AgainstTruth::of(calibration) {
        estimates_against_truth(
            &dir.join("parameters.png"),
            "Base parameters against the simulated rig's truth, ±3σ",
            &against.z(),
        )?;
        calibration_figures.push((
            "Each base parameter's estimate minus the truth, in its own σ, with ±3σ bars (OLS and IDIM-IV)",
            "parameters.png",
        ));
    }

    // Figs. 6–7: tracking error and control effort, one series per controller.
    for (file, title, caption, values) in [
        ("tracking_error.png", "Tracking error", "The tracking error of the three controllers", true),
        (
            "control_effort.png",
            "Control effort (commanded torque)",
            "The commanded torque of the three controllers",
            false,
        ),
    ] {
        let per_joint: Vec<Panel> = (0..dof)
            .map(|k| Panel {
                y_label: if values {
                    format!("{} error ({})", names[k], unit(kinds[k]))
                } else {
                    format!("{} ({})", names[k], torque_unit(kinds[k]))
                },
                series: tracking
                    .runs
                    .iter()
                    .map(|r| {
                        let y = if values {
                            joint_column(&r.error, k, dof, kinds[k], 1e6)
                        } else {
                            r.tau_cmd.iter().skip(k).step_by(dof).copied().collect()
                        };
                        (r.label.as_str(), &r.t[..], y)
                    })
                    .collect(),
            })
            .collect();
        let path = dir.join(file);
        panels(&path, &format!("{title}, ω = {} rad/s", tracking.omega), "t (s)", &per_joint)?;
        tracking_figures.push((caption, file));
    }

    let diagnosis_figures = list_pngs(&dir.join("diagnosis"))?;
    let figures = [excitation_figure, calibration_figures, tracking_figures];
    let mut markdown = markdown(model, excitation, calibration, diagnosis, tracking, &figures, &diagnosis_figures);
    let mut summary = summary(model, calibration, diagnosis, tracking);
    let mut real_figures = Vec::new();
    if let Some(real) = real {
        real_figures = list_pngs(&dir.join(REAL_ROBOT_DIR))?;
        markdown.push_str(&real.chapter(REAL_ROBOT_DIR, &real_figures));
        summary["real_robot"] = real.summary();
    }
    super::write_atomically(&dir.join("report.md"), &markdown)?;
    let summary = serde_json::to_string_pretty(&summary).expect("JSON values serialise");
    super::write_atomically(&dir.join("summary.json"), &summary)?;
    Ok(figures.iter().map(Vec::len).sum::<usize>() + diagnosis_figures.len() + real_figures.len())
}

fn list_pngs(dir: &Path) -> anyhow::Result<Vec<String>> {
    let mut names: Vec<String> = std::fs::read_dir(dir)?
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".png"))
        .collect();
    names.sort();
    Ok(names)
}

/// `figures` are (caption, file name) for the excitation, calibration and tracking sections.
fn markdown(
    model: &Model,
    excitation: &Excitation,
    calibration: &Calibration,
    diagnosis: &Diagnosis,
    tracking: &Tracking,
    figures: &[Vec<(&str, &str)>; 3],
    diagnosis_figures: &[String],
) -> String {
    let images = |s: &mut String, section: &[(&str, &str)]| {
        for (caption, file) in section {
            let _ = writeln!(s, "![{caption}]({file})\n");
        }
    };
    let mut s = String::from("# arash demo: calibration, diagnosis and control of the simulated rig\n\n");
    let _ = writeln!(
        s,
        "Excitation: L = {}, T = {} s, normalised condition number κ = {:.3}.\n",
        excitation.harmonics, excitation.period_s, excitation.condition_number
    );
    images(&mut s, &figures[0]);
    let _ = writeln!(s, "## Calibration\n\n```\nTable I (OLS)\n{}\n```\n", calibration.ols.table());
    let _ = writeln!(s, "```\nTable I (IDIM-IV, closed loop)\n{}\n```\n", calibration.closed_loop.table());
    let _ = writeln!(
        s,
        "```\nPhysically consistent fit (IDIM-IV; the model the robust controller gets)\n{}\n```\n",
        calibration.consistent.table()
    );
    if let Some(against) = AgainstTruth::of(calibration) {
        let _ = writeln!(s, "Estimates against the simulated rig's own base parameters:\n\n{}", against.table());
    }
    let _ = writeln!(s, "```\n{}\n```\n", calibration.table_ii);
    images(&mut s, &figures[1]);
    let _ = writeln!(s, "## Diagnosis\n\n```\n{}\n```\n", diagnosis.report());
    // What the undeclared effects did to Table I: fitted with them, the parameters they made
    // noisy are determined (docs/demo.md, "Table I's σ%").
    let _ = writeln!(
        s,
        "```\nTable I with the effects found (the diagnosis's least-squares fit, every exact base parameter)\n{}\n```\n",
        diagnosis.model.table()
    );
    for name in diagnosis_figures {
        let _ = writeln!(s, "![{name}](diagnosis/{name})\n");
    }
    let _ = writeln!(s, "## Tracking\n\n{}\n", tracking.table(&model.joint_names()));
    if let Some(text) = tracking.against_truth(&model.joint_names()) {
        let _ = writeln!(s, "{text}\n");
    }
    images(&mut s, &figures[2]);
    s
}

/// The effects a diagnosis accepted, as the summary lists them.
fn accepted(diagnosis: &Diagnosis) -> Vec<serde_json::Value> {
    diagnosis
        .accepted
        .iter()
        .map(|f| serde_json::json!({"name": f.name, "joints": f.joints, "heldout_gain": f.heldout_gain}))
        .collect()
}

/// The headline numbers, for scripts and tests.
fn summary(model: &Model, calibration: &Calibration, diagnosis: &Diagnosis, tracking: &Tracking) -> serde_json::Value {
    let runs: Vec<serde_json::Value> = tracking
        .runs
        .iter()
        .map(|r| {
            serde_json::json!({
                "controller": r.label, "log": r.log, "max_error": r.max_error, "rms_error": r.rms_error,
                "faults": r.faults, "cycles_left_out": r.left_out,
            })
        })
        .collect();
    serde_json::json!({
        "format": "arash-demo-summary/1",
        "joint_names": model.joint_names(),
        "training_fp_percent": {
            "ols": calibration.ols.fitted.training.fp_percent,
            "idim_iv": calibration.closed_loop.fitted.training.fp_percent,
            "consistent": calibration.consistent.fitted.training.fp_percent,
        },
        "table_i_causes": {
            "idim_iv": calibration.closed_loop.cause_counts(),
            "with_effects": diagnosis.model.cause_counts(),
        },
        "within_3_sigma_of_truth": AgainstTruth::of(calibration).map(|a| {
            let covered: serde_json::Map<String, serde_json::Value> =
                a.covered().into_iter().map(|(name, n)| (name.to_lowercase(), n.into())).collect();
            serde_json::json!({"of": a.names.len(), "covered": covered})
        }),
        "diagnosis": {
            "accepted": accepted(diagnosis),
            "error_before": diagnosis.before,
            "error_after": diagnosis.after,
        },
        "tracking": {"omega": tracking.omega, "runs": runs},
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stale_cycles_and_the_recovery_from_a_stall_are_left_out() {
        // 1 ms cycles; one stale cycle at 10, a stall of exactly STALL_CYCLES at 100..=102, and
        // a gap one cycle short of a stall at 200..=201.
        let mut t: Vec<f64> = (0..400).map(|i| i as f64 * 1e-3).collect();
        t[10] = t[9];
        for i in 100..100 + STALL_CYCLES {
            t[i] = t[99];
        }
        for i in 200..200 + STALL_CYCLES - 1 {
            t[i] = t[199];
        }
        let d = disturbed(&t);
        let left_out: Vec<usize> = (0..t.len()).filter(|&i| d[i]).collect();
        let mut expected = vec![10];
        expected.extend(100..100 + STALL_CYCLES + RECOVERY_CYCLES);
        expected.extend(200..200 + STALL_CYCLES - 1);
        assert_eq!(left_out, expected);
    }
}
