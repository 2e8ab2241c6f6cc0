//! Identification (paper sections III–IV): preprocessing, least squares, and physically consistent
//! estimation, tied together by [`identify`] into an [`Identification`] that can be saved, loaded,
//! printed as the paper's tables and used for prediction.

pub mod consistent;
pub mod estimate;
pub mod excitation;
pub mod filter;
pub mod preprocess;

use serde::{Deserialize, Serialize};

use crate::base_parameters::BaseParameters;
use crate::data::Data;
use crate::model::Model;
use crate::regressor::regressor;
use consistent::{identify_consistent, min_pseudo_inertia_eigenvalues, ConsistentError, ConsistentOptions};
use estimate::{fit, joint_metrics, stack_full, EstimateError, JointMetrics, Method};
use preprocess::{preprocess, PreprocessError, PreprocessOptions};

/// The estimation method, as named on the command line and in Python.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IdentifyMethod {
    /// Ordinary least squares on the base parameters.
    Ols,
    /// Least squares weighted per joint by the inverse residual standard deviation.
    Wls,
    /// Full standard parameters with every body physically consistent (SDP).
    Consistent,
}

impl std::str::FromStr for IdentifyMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "ols" => Ok(Self::Ols),
            "wls" => Ok(Self::Wls),
            "consistent" => Ok(Self::Consistent),
            other => Err(format!("unknown method `{other}` (ols, wls or consistent)")),
        }
    }
}

/// Everything [`identify`] can be told.
#[derive(Clone, Debug, Default)]
pub struct IdentifyOptions {
    pub preprocess: PreprocessOptions,
    pub consistent: ConsistentOptions,
}

#[derive(Debug, thiserror::Error)]
pub enum IdentifyError {
    #[error(transparent)]
    Preprocess(#[from] PreprocessError),
    #[error(transparent)]
    Estimate(#[from] EstimateError),
    #[error(transparent)]
    Consistent(#[from] ConsistentError),
    #[error(transparent)]
    Base(#[from] crate::base_parameters::BaseParameterError),
    #[error("model file: {0}")]
    File(String),
}

/// Fit quality per joint, serialisable.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Metrics {
    pub fp_percent: Vec<f64>,
    pub relative_error: Vec<f64>,
    pub rms: Vec<f64>,
}

impl From<JointMetrics> for Metrics {
    fn from(m: JointMetrics) -> Self {
        Self { fp_percent: m.fp_percent, relative_error: m.relative_error, rms: m.rms }
    }
}

/// Settings an identification was made with, kept in the model file.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Settings {
    pub method: IdentifyMethod,
    pub periods: Option<usize>,
    pub cutoff_hz: f64,
    pub order: usize,
    pub decimate: usize,
    pub pull: f64,
    /// Cable stiffness bounds; `None` is unbounded (JSON has no infinity).
    pub stiffness_bounds: (Option<f64>, Option<f64>),
}

/// Where the data came from.
#[derive(Clone, Debug, Serialize, Deserialize, Default)]
pub struct DataSummary {
    /// Files (or other sources) the samples were read from.
    pub sources: Vec<String>,
    pub samples_in: usize,
    pub samples_used: usize,
    pub sample_rate_hz: f64,
    pub periods_averaged: usize,
}

/// An identified model: base parameters with their uncertainty, and, when consistent, the full
/// standard parameter vector. Saved as JSON by [`Identification::to_json`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Identification {
    /// `"arash-model/1"`.
    pub format: String,
    pub software_version: String,
    pub robot_name: String,
    /// The URDF the model was identified with, so the file stands alone.
    pub urdf: String,
    pub parameter_names: Vec<String>,
    pub base_names: Vec<String>,
    pub base_expressions: Vec<String>,
    /// Indices of the standard parameters forming `Y_r`.
    pub base_independent: Vec<usize>,
    /// β̂ (for `consistent`, `B π̂`).
    pub beta: Vec<f64>,
    /// Relative standard deviation of each β̂ from the least-squares fit (%).
    pub sigma_percent: Vec<f64>,
    /// The full standard parameters (only for `consistent`).
    pub params: Option<Vec<f64>>,
    /// Fit quality on the training data of the returned model.
    pub training: Metrics,
    /// Fit quality of plain OLS on the same data (to show what consistency costs).
    pub training_ols: Metrics,
    /// Smallest pseudo-inertia eigenvalue per body: of the consistent estimate, or of the standard
    /// parameters nearest CAD that reproduce the OLS/WLS β (negative = not physical).
    pub min_pseudo_inertia_eigenvalue: Vec<f64>,
    /// Scaled condition number of the stacked reduced regressor.
    pub condition_number: f64,
    pub settings: Settings,
    pub data: DataSummary,
    /// Effects beyond the declared model, added by `arash diagnose` (see `docs/diagnosis.md`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<crate::diagnose::EffectTerm>,
}

/// Identify `model` from a log: `t` (N), `q` and `tau` (N × dof, row-major, SI). `base` is the
/// model's [`BaseParameters`], computed once by the caller: they depend only on the model.
#[allow(clippy::too_many_arguments)]
pub fn identify(
    model: &Model,
    base: &BaseParameters,
    urdf: &str,
    t: &[f64],
    q: &[f64],
    tau: &[f64],
    method: IdentifyMethod,
    options: &IdentifyOptions,
) -> Result<Identification, IdentifyError> {
    let pre = preprocess(t, q, tau, model.dof(), &options.preprocess)?;
    let ls_method = if method == IdentifyMethod::Wls { Method::Wls } else { Method::Ols };
    let ls = fit(model, base, &pre, ls_method)?;
    let ols_metrics: Metrics = if ls_method == Method::Ols {
        ls.metrics.clone().into()
    } else {
        fit(model, base, &pre, Method::Ols)?.metrics.into()
    };
    let (beta, params, training, min_eig) = if method == IdentifyMethod::Consistent {
        let (w, tau_f) = stack_full(model, &pre);
        let c = identify_consistent(model, &w, &tau_f, &options.consistent)?;
        let predicted: Vec<f64> = estimate::apply(&w, &c.params);
        let mut beta = vec![0.0; base.rank];
        base.project(&c.params, &mut beta);
        let metrics = joint_metrics(&tau_f, &predicted, model.dof()).into();
        (beta, Some(c.params), metrics, c.min_pseudo_inertia_eigenvalue)
    } else {
        let nearest = nearest_standard_parameters(model, base, &ls.beta);
        let min_eig = min_pseudo_inertia_eigenvalues(model, &nearest);
        (ls.beta.clone(), None, ls.metrics.clone().into(), min_eig)
    };
    Ok(Identification {
        format: "arash-model/1".into(),
        software_version: env!("CARGO_PKG_VERSION").into(),
        robot_name: model.name.clone(),
        urdf: urdf.to_string(),
        parameter_names: model.parameter_names(),
        base_names: base.names.clone(),
        base_expressions: base.expressions.clone(),
        base_independent: base.independent.clone(),
        beta,
        sigma_percent: ls.sigma_percent.clone(),
        params,
        training,
        training_ols: ols_metrics,
        min_pseudo_inertia_eigenvalue: min_eig,
        condition_number: ls.condition_number,
        settings: Settings {
            method,
            periods: options.preprocess.periods,
            cutoff_hz: pre.cutoff_hz,
            order: options.preprocess.order,
            decimate: options.preprocess.decimate,
            pull: options.consistent.pull,
            stiffness_bounds: {
                let finite = |x: f64| x.is_finite().then_some(x);
                (finite(options.consistent.stiffness_bounds.0), finite(options.consistent.stiffness_bounds.1))
            },
        },
        data: DataSummary {
            sources: vec![],
            samples_in: t.len(),
            samples_used: pre.samples(),
            sample_rate_hz: pre.sample_rate_hz,
            periods_averaged: pre.periods_averaged,
        },
        effects: vec![],
    })
}

/// How far below zero a pseudo-inertia eigenvalue may be and still count as physical: the
/// consistent solve's own tolerance.
pub const CONSISTENCY_TOLERANCE: f64 = 1e-9;

/// Write `text` to `path` through a temporary file and a rename, so that a crash never leaves half
/// a model or trajectory file behind.
pub fn write_atomically(path: &std::path::Path, text: &str) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".partial");
    std::fs::write(&tmp, text)?;
    std::fs::rename(&tmp, path)
}

/// The standard parameters closest to CAD (in the scaled norm of [`consistent::parameter_scales`])
/// whose base parameters are exactly `beta`: `π = π_CAD + S²Bᵀ(B S² Bᵀ)⁻¹(β − B π_CAD)`.
pub fn nearest_standard_parameters(model: &Model, base: &BaseParameters, beta: &[f64]) -> Vec<f64> {
    let (p, big_p) = (base.rank, base.num_params);
    let cad = model.cad_parameters();
    let s2: Vec<f64> = consistent::parameter_scales(model, 0.1).iter().map(|s| s * s).collect();
    let b = nalgebra::DMatrix::from_row_slice(p, big_p, &base.b);
    let b_s2 = nalgebra::DMatrix::from_fn(p, big_p, |i, j| b[(i, j)] * s2[j]);
    let gram = &b_s2 * b.transpose();
    let mut beta_cad = vec![0.0; p];
    base.project(&cad, &mut beta_cad);
    let gap = nalgebra::DVector::from_iterator(p, beta.iter().zip(&beta_cad).map(|(a, c)| a - c));
    let y = gram.lu().solve(&gap).expect("B has full row rank");
    let correction = b_s2.transpose() * y;
    cad.iter().zip(correction.iter()).map(|(c, d)| c + d).collect()
}

impl Identification {
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("an identification always serialises")
    }

    /// Write the model file (JSON, URDF embedded), atomically.
    pub fn save(&self, path: &std::path::Path) -> std::io::Result<()> {
        write_atomically(path, &self.to_json())
    }

    pub fn from_json(text: &str) -> Result<Self, IdentifyError> {
        let id: Self = serde_json::from_str(text).map_err(|e| IdentifyError::File(e.to_string()))?;
        if id.format != "arash-model/1" {
            return Err(IdentifyError::File(format!("unknown format `{}` (expected arash-model/1)", id.format)));
        }
        Ok(id)
    }

    /// Predicted torques (row-major N × dof) for states (row-major N × dof): `Y π̂` when the full
    /// parameters are known, else `Y_r β̂`.
    ///
    /// Effects added by a diagnosis are included where they are a function of the state: all
    /// but `delay` (a property of the log), `compliance` (whose proxy needs the measured torque)
    /// and `drift` (a function of the log's own time).
    pub fn predict(&self, model: &Model, q: &[f64], qd: &[f64], qdd: &[f64]) -> Vec<f64> {
        let (n, big_p) = (model.dof(), model.num_params());
        let mut data = Data::new(model);
        let mut y = vec![0.0; n * big_p];
        let mut full = self.full_or_base_vector();
        // The controllers' evaluation of the effects; no ε given, so each term keeps the
        // direction function it was fitted with.
        let mut effects = crate::control::EffectFeedforward::new(model, &self.effects, &[], &mut full);
        let mut out = vec![0.0; q.len() / n * n];
        for (s, tau) in out.chunks_mut(n).enumerate() {
            let range = s * n..(s + 1) * n;
            regressor(model, &mut data, &q[range.clone()], &qd[range.clone()], &qdd[range.clone()], &mut y);
            for (t, row) in tau.iter_mut().zip(y.chunks(big_p)) {
                *t = row.iter().zip(&full).map(|(a, b)| a * b).sum::<f64>();
            }
            effects.add(&q[range.clone()], &qd[range.clone()], &qdd[range], tau);
        }
        out
    }

    /// The parameter vector a model-based controller needs for `model`: π̂, or β̂ on the
    /// independent columns. Refused when the file was identified for a different robot or its
    /// vectors do not fit together (a file edited by hand).
    pub fn controller_parameters(&self, model: &Model) -> Result<Vec<f64>, IdentifyError> {
        self.check_shape(model)?;
        Ok(self.full_or_base_vector())
    }

    /// [`Self::controller_parameters`] for a law that inverts M(q): also refused unless every
    /// body's pseudo-inertia, recomputed from the file's own parameters, is positive
    /// semidefinite (an indefinite one can make M(q) indefinite and the loop unstable). The
    /// file's `min_pseudo_inertia_eigenvalue` is a report, never trusted.
    pub fn consistent_controller_parameters(&self, model: &Model) -> Result<Vec<f64>, IdentifyError> {
        let eigenvalues = self.recomputed_pseudo_inertia_eigenvalues(model)?; // checks the shape too
        let (body, worst) =
            eigenvalues.iter().copied().enumerate().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap_or((0, f64::INFINITY));
        if worst < -CONSISTENCY_TOLERANCE {
            let claimed = self.min_pseudo_inertia_eigenvalue.iter().copied().fold(f64::INFINITY, f64::min);
            return Err(IdentifyError::File(format!(
                "not physically consistent: body `{}` has a pseudo-inertia eigenvalue of {worst:.3e} recomputed from \
                 its parameters (the file states {claimed:.3e}); a model-based controller needs a consistent model: \
                 identify with --method consistent",
                model.bodies[body].name
            )));
        }
        Ok(self.full_or_base_vector())
    }

    /// The smallest pseudo-inertia eigenvalue of each body from the file's parameters: π̂, or the
    /// standard parameters nearest CAD that reproduce β̂.
    pub fn recomputed_pseudo_inertia_eigenvalues(&self, model: &Model) -> Result<Vec<f64>, IdentifyError> {
        self.check_shape(model)?;
        if let Some(params) = &self.params {
            return Ok(min_pseudo_inertia_eigenvalues(model, params));
        }
        let base = BaseParameters::compute(model, &Default::default())?;
        if base.independent != self.base_independent {
            return Err(IdentifyError::File(
                "its base parameters are not this robot's (independent columns differ)".into(),
            ));
        }
        Ok(min_pseudo_inertia_eigenvalues(model, &nearest_standard_parameters(model, &base, &self.beta)))
    }

    /// The file's vectors against `model`: same robot, matching lengths, finite values.
    fn check_shape(&self, model: &Model) -> Result<(), IdentifyError> {
        let file = |text: String| Err(IdentifyError::File(text));
        if self.parameter_names != model.parameter_names() {
            return file(format!(
                "the model was identified for robot `{}` with {} parameters; this robot (`{}`) has {} with other names",
                self.robot_name,
                self.parameter_names.len(),
                model.name,
                model.num_params()
            ));
        }
        let big_p = model.num_params();
        if let Some(p) = &self.params {
            if p.len() != big_p {
                return file(format!("`params` has {} entries; the robot has {big_p} parameters", p.len()));
            }
        }
        if self.beta.len() != self.base_independent.len() {
            return file(format!(
                "`beta` has {} entries but `base_independent` names {} columns",
                self.beta.len(),
                self.base_independent.len()
            ));
        }
        if let Some(&j) = self.base_independent.iter().find(|&&j| j >= big_p) {
            return file(format!("`base_independent` names column {j}; the robot has {big_p} parameters"));
        }
        let values = self.beta.iter().chain(self.params.iter().flatten());
        if let Some(x) = values.copied().find(|x| !x.is_finite()) {
            return file(format!("a parameter is {x}; every value must be finite"));
        }
        Ok(())
    }

    /// A P-vector whose product with the full regressor is the prediction: π̂, or β̂ placed on the
    /// independent columns (zeros elsewhere).
    pub fn full_or_base_vector(&self) -> Vec<f64> {
        self.params.clone().unwrap_or_else(|| {
            let mut v = vec![0.0; self.parameter_names.len()];
            for (&j, b) in self.base_independent.iter().zip(&self.beta) {
                v[j] = *b;
            }
            v
        })
    }

    /// Table I shape: each base parameter, its value and σ%, and the training fit.
    pub fn table(&self) -> String {
        let mut s = format!(
            "Identified base parameters ({:?}, {} samples used of {}, cut-off {:.2} Hz, κ = {:.1})\n",
            self.settings.method,
            self.data.samples_used,
            self.data.samples_in,
            self.settings.cutoff_hz,
            self.condition_number
        );
        // The consistent β is a constrained estimate; its spread is reported from the least squares.
        let sigma = if self.settings.method == IdentifyMethod::Consistent { "σ% (OLS)" } else { "σ%" };
        s += &format!("{:<4} {:<34} {:>14} {:>10}\n", "", "parameter", "value", sigma);
        for (i, name) in self.base_names.iter().enumerate() {
            s += &format!("β{:<3} {:<34} {:>14.6e} {:>10.2}\n", i + 1, name, self.beta[i], self.sigma_percent[i]);
        }
        s += "\nTraining fit per joint:      ";
        s += &(0..self.training.fp_percent.len())
            .map(|k| format!("{:>10}", format!("joint {}", k + 1)))
            .collect::<String>();
        let row = |label: &str, v: &[f64], fmt: &dyn Fn(f64) -> String| {
            format!("\n  {label:<26} {}", v.iter().map(|x| format!("{:>10}", fmt(*x))).collect::<String>())
        };
        s += &row("FP% (this model)", &self.training.fp_percent, &|x| format!("{x:.2}"));
        s += &row("FP% (OLS)", &self.training_ols.fp_percent, &|x| format!("{x:.2}"));
        s += &row("‖τ − τ̂‖/‖τ‖", &self.training.relative_error, &|x| format!("{x:.4}"));
        s += &row("RMS (N·m or N)", &self.training.rms, &|x| format!("{x:.2e}"));
        let worst = self.min_pseudo_inertia_eigenvalue.iter().copied().fold(f64::INFINITY, f64::min);
        s += &format!(
            "\n\nSmallest pseudo-inertia eigenvalue over bodies: {worst:.3e} ({})\n",
            if worst >= -CONSISTENCY_TOLERANCE { "physical" } else { "NOT physical" }
        );
        s
    }
}

/// Table II shape: FP% per joint (rows, named by `joints`) for each validation run (columns).
pub fn validation_table(joints: &[String], labels: &[String], fp_percent: &[Vec<f64>]) -> String {
    let dof = fp_percent.first().map_or(0, Vec::len);
    let width = labels.iter().map(|l| l.chars().count() + 2).max().unwrap_or(0).max(12);
    let mut s = format!("{:<12}", "FP%");
    for l in labels {
        s += &format!("{l:>width$}");
    }
    s.push('\n');
    for k in 0..dof {
        let name = joints.get(k).cloned().unwrap_or_else(|| format!("joint {}", k + 1));
        s += &format!("{name:<12}");
        for run in fp_percent {
            s += &format!("{:>width$.2}", run[k]);
        }
        s.push('\n');
    }
    s
}

/// The paper's validation trajectory at `omega` (rad/s): φ = 35° sin ωt, ψ = 40° cos ωt + 15°,
/// d = 1.8 cm sin ωt + 0.4 cm. Returns (q, q̇, q̈) in SI units.
///
/// The paper prints d = −1.8 cm sin ωt − 0.4 cm, which spans −22…14 mm and leaves its own
/// insertion range of −14…27 mm. Its d must be counted the other way: reversed, it spans
/// −14…22 mm and touches the lower limit exactly as ψ touches both of its limits.
pub fn paper_validation_state(omega: f64, t: f64) -> ([f64; 3], [f64; 3], [f64; 3]) {
    let deg = std::f64::consts::PI / 180.0;
    let (s, c) = (omega * t).sin_cos();
    let amp = [35.0 * deg, 40.0 * deg, 0.018];
    let q = [amp[0] * s, amp[1] * c + 15.0 * deg, amp[2] * s + 0.004];
    let qd = [amp[0] * omega * c, -amp[1] * omega * s, amp[2] * omega * c];
    let qdd = [-amp[0] * omega * omega * s, -amp[1] * omega * omega * c, -amp[2] * omega * omega * s];
    (q, qd, qdd)
}

/// FP% per joint of `identification` on one validation log (same preprocessing as training).
pub fn validate(
    model: &Model,
    identification: &Identification,
    t: &[f64],
    q: &[f64],
    tau: &[f64],
    preprocess_options: &PreprocessOptions,
) -> Result<Metrics, IdentifyError> {
    let series = validation_series(model, identification, t, q, tau, preprocess_options)?;
    Ok(joint_metrics(&series.measured, &series.predicted, model.dof()).into())
}

/// A validation run preprocessed as for [`validate`]: the time of each sample, the filtered
/// measured torque and the model's prediction (both N × dof, row-major).
#[derive(Clone, Debug)]
pub struct ValidationSeries {
    pub t: Vec<f64>,
    pub measured: Vec<f64>,
    pub predicted: Vec<f64>,
}

/// The series [`validate`] scores, for plotting measured against predicted torque.
pub fn validation_series(
    model: &Model,
    identification: &Identification,
    t: &[f64],
    q: &[f64],
    tau: &[f64],
    preprocess_options: &PreprocessOptions,
) -> Result<ValidationSeries, IdentifyError> {
    let options =
        PreprocessOptions { cutoff_hz: Some(identification.settings.cutoff_hz), ..preprocess_options.clone() };
    let pre = preprocess(t, q, tau, model.dof(), &options)?;
    // Through the stacked regressor, so that the Coulomb columns are filtered like the torque.
    let (w, measured) = stack_full(model, &pre);
    let full = identification.full_or_base_vector();
    let predicted: Vec<f64> = estimate::apply(&w, &full);
    Ok(ValidationSeries { t: pre.t.clone(), measured, predicted })
}
