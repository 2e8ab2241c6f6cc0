//! The demo's real robot: the Stäubli TX40's measured log (FIGAROH's `staubli_TX40` example,
//! Apache-2.0, shipped in `data/staubli_tx40/` with its LICENSE and NOTICE), run through
//! identification and the diagnosis with the defaults, as a user would run a log of their own.
//! The log is motor-side (encoder angles and torques from the drive currents at 5 kHz); the
//! declared transmission maps it to the joints and names the wrist's coupled motor.

use std::io::Read;
use std::path::Path;

use anyhow::Context;
use arash_core::base_parameters::BaseParameterOptions;
use arash_core::diagnose::{diagnose, DiagnoseOptions, Diagnosis};
use arash_core::identify::{identify, Declared, IdentifyOptions, Log};
use arash_core::model_file::IdentifyMethod;
use arash_core::transmission::Transmission;
use arash_core::BaseParameters;

use crate::report::demo::{Comparison, RealRobot};

const POSITIONS_GZ: &[u8] = include_bytes!("../../../../../data/staubli_tx40/pos_read_data.csv.gz");
const TORQUES_GZ: &[u8] = include_bytes!("../../../../../data/staubli_tx40/curr_data.csv.gz");
const URDF: &str = include_str!("../../../../../data/staubli_tx40/tx40_mdh_modified.urdf");
/// Upstream's identified base parameters: name, value, relative σ (%), then a second estimator's.
const UPSTREAM_CSV: &str = include_str!("../../../../../data/staubli_tx40/TX40_bp_5.csv");

/// Upstream's sample rate, gear ratios (motor radians per joint radian), the wrist's coupling
/// (motor 6 turns with joint 5, 1-based) and the MDH offsets that match the URDF (T40X_config.yaml
/// and upstream's README).
const SAMPLE_RATE_HZ: f64 = 5000.0;
const SOURCE: &str = "the FIGAROH project (T. Nguyen et al., CNRS / Toward SAS), figaroh-plus, example staubli_TX40; \
                      Apache-2.0, shipped in data/staubli_tx40/ with its LICENSE and NOTICE";
const GEAR_RATIOS: [f64; 6] = [32.0, 32.0, 45.0, -48.0, 45.0, 32.0];
const COUPLING: (usize, usize, f64) = (6, 5, 32.0);
const OFFSETS_DEG: [f64; 6] = [0.0, -90.0, 90.0, 0.0, 0.0, 0.0];

/// Upstream's name for each coefficient of the effects its model holds and the declared one
/// lacks: rotor inertia per joint, and motor 6's inertia, viscous and dry friction.
fn upstream_name(finding: &arash_core::diagnose::Finding, column: usize) -> Option<String> {
    match (finding.name.as_str(), column) {
        ("armature", 0) => finding.joints.first().map(|k| format!("Ia{}", k + 1)),
        ("coupled_rotor", c) => ["Iam6", "fvm6", "fsm6"].get(c).map(|s| s.to_string()),
        _ => None,
    }
}

/// Identify and diagnose the TX40's log with the defaults, writing the diagnosis's outputs and
/// figures into `out`.
pub fn run(out: &Path) -> anyhow::Result<RealRobot> {
    let model = arash_core::parse_urdf(URDF).context("the TX40's URDF")?;
    let transmission =
        Transmission::new(model.dof(), &GEAR_RATIOS, &[COUPLING], Some(&OFFSETS_DEG.map(f64::to_radians)))?;
    let theta = read_gz_csv(POSITIONS_GZ, model.dof()).context("pos_read_data.csv.gz")?;
    let tau_motor = read_gz_csv(TORQUES_GZ, model.dof()).context("curr_data.csv.gz")?;
    let (q, tau) = transmission.to_joints(&theta, &tau_motor)?;
    let samples = q.len() / model.dof();
    let t: Vec<f64> = (0..samples).map(|i| i as f64 / SAMPLE_RATE_HZ).collect();
    println!(
        "    {samples} samples at {SAMPLE_RATE_HZ} Hz, motor-side, mapped through gear ratios {GEAR_RATIOS:?} and the \
         wrist's coupling (motor {}, joint {}, ratio {})",
        COUPLING.0, COUPLING.1, COUPLING.2
    );
    let log = Log { t: &t, q: &q, tau: &tau };
    let identified = BaseParameters::compute(&model, &BaseParameterOptions::default())?;
    let declared = Declared { model: &model, base: &identified, urdf: URDF };
    let identification =
        identify(declared, log, IdentifyMethod::Ols, &IdentifyOptions::default()).context("identifying the TX40")?;
    println!(
        "    identification (OLS, defaults): cut-off {:.2} Hz, FP% {}",
        identification.settings.cutoff_hz,
        identification.fitted.training.fp_percent.iter().map(|f| format!("{f:.1}")).collect::<Vec<_>>().join(" / ")
    );
    let exact = BaseParameters::compute(&model, &BaseParameterOptions::diagnosed())?;
    let options = DiagnoseOptions { motors: Some(transmission), ..DiagnoseOptions::default() };
    let diagnosis = diagnose(Declared { model: &model, base: &exact, urdf: URDF }, log, None, None, &options)
        .context("diagnosing the TX40")?;
    let report = diagnosis.report();
    super::super::diagnose::write_outputs(out, &diagnosis, &report)?;
    println!("{}", super::indent(&report));
    let against_upstream = against_upstream(&diagnosis);
    for c in &against_upstream {
        println!("    {}", c.line());
    }
    Ok(RealRobot {
        name: "Stäubli TX40".into(),
        source: SOURCE.into(),
        samples,
        sample_rate_hz: SAMPLE_RATE_HZ,
        identification,
        diagnosis,
        against_upstream,
    })
}

fn against_upstream(diagnosis: &Diagnosis) -> Vec<Comparison> {
    let published: Vec<(String, f64, f64)> = UPSTREAM_CSV
        .lines()
        .filter_map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            let value: f64 = fields.get(1)?.trim().parse().ok()?;
            let percent: f64 = fields.get(2)?.trim().parse().ok()?;
            Some((fields[0].trim().to_string(), value, (percent / 100.0 * value).abs()))
        })
        .collect();
    let mut comparisons = Vec::new();
    for finding in &diagnosis.accepted {
        for (c, column) in finding.term.columns.iter().enumerate() {
            let Some(name) = upstream_name(finding, c) else { continue };
            let Some((_, value, sigma)) = published.iter().find(|(n, _, _)| *n == name) else { continue };
            comparisons.push(Comparison {
                effect: finding.label.clone(),
                column: column.clone(),
                ours: (finding.term.coefficients[c], finding.term.sigma[c]),
                upstream: (name, *value, *sigma),
            });
        }
    }
    comparisons
}

/// A headed CSV of `dof` numeric columns, gzip-compressed, as one row-major series.
fn read_gz_csv(bytes: &[u8], dof: usize) -> anyhow::Result<Vec<f64>> {
    let mut text = String::new();
    flate2::read::GzDecoder::new(bytes).read_to_string(&mut text)?;
    let mut values = Vec::new();
    for (i, line) in text.lines().enumerate().skip(1).filter(|(_, l)| !l.trim().is_empty()) {
        let row: Vec<f64> = line
            .split(',')
            .map(|v| v.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("line {}: not numbers", i + 1))?;
        anyhow::ensure!(row.len() == dof, "line {}: {} columns, not {dof}", i + 1, row.len());
        values.extend(row);
    }
    Ok(values)
}
