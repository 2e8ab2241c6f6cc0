//! The saved model: what an identification (and a diagnosis) produced, as the JSON file that
//! `arash identify` writes and the daemon's model-based controllers load. Its format is
//! `arash-model/1`; the URDF it was identified with is embedded, so the file stands alone.
//!
//! A file is never trusted: [`ModelFile::controller_parameters`] checks its shape against the
//! robot, and [`ModelFile::consistent_controller_parameters`] recomputes its physical consistency.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::base_parameters::BaseParameters;
use crate::choices::{Choice, Concern, ForceChoice};
use crate::data::Data;
use crate::model::{CoulombLaws, CoulombShape, Model};
use crate::physical::{min_pseudo_inertia_eigenvalues, nearest_standard_parameters, CONSISTENCY_TOLERANCE};
use crate::regressor::regressor;

/// The format identifier this version reads and writes.
pub const FORMAT: &str = "arash-model/1";

/// Why a model file cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ModelFileError {
    #[error("model file: not readable as JSON: {0}")]
    Json(String),
    #[error("model file: unknown format `{0}` (expected {FORMAT})")]
    Format(String),
    #[error("model file: {0}")]
    Shape(String),
    #[error(
        "model file: not physically consistent: body `{body}` has a pseudo-inertia eigenvalue of {eigenvalue:.3e} \
         recomputed from its parameters (the file states {claimed:.3e}); a model-based controller needs a consistent \
         model: identify with --method consistent"
    )]
    NotConsistent { body: String, eigenvalue: f64, claimed: f64 },
    #[error(transparent)]
    Base(#[from] crate::base_parameters::BaseParameterError),
}

/// The estimation method, as named on the command line and in Python.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum IdentifyMethod {
    /// Ordinary least squares on the base parameters (the default: the paper's first fit).
    #[default]
    Ols,
    /// Least squares weighted per joint by the inverse residual standard deviation.
    Wls,
    /// Full standard parameters with every body physically consistent (SDP).
    Consistent,
    /// IDIM-IV for closed-loop logs: instruments from the loop simulated with the estimate
    /// ([`crate::identify::closed_loop`]).
    #[serde(rename = "idim-iv")]
    IdimIv,
    /// IDIM-IV with every body physically consistent (the SDP on the instrumented regressor).
    #[serde(rename = "idim-iv-consistent")]
    IdimIvConsistent,
    /// DIDIM for closed-loop logs: the simulated loop's torque fitted to the measured torque.
    #[serde(rename = "didim")]
    Didim,
    /// DIDIM with every body physically consistent.
    #[serde(rename = "didim-consistent")]
    DidimConsistent,
}

impl IdentifyMethod {
    /// The name on the command line and in Python.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ols => "ols",
            Self::Wls => "wls",
            Self::Consistent => "consistent",
            Self::IdimIv => "idim-iv",
            Self::IdimIvConsistent => "idim-iv-consistent",
            Self::Didim => "didim",
            Self::DidimConsistent => "didim-consistent",
        }
    }

    /// Whether the method needs the closed loop's reference and controller.
    pub fn closed_loop(self) -> bool {
        matches!(self, Self::IdimIv | Self::IdimIvConsistent | Self::Didim | Self::DidimConsistent)
    }

    /// Whether the result is a physically consistent π̂.
    pub fn consistent(self) -> bool {
        matches!(self, Self::Consistent | Self::IdimIvConsistent | Self::DidimConsistent)
    }

    pub const ALL: [Self; 7] = [
        Self::Ols,
        Self::Wls,
        Self::Consistent,
        Self::IdimIv,
        Self::IdimIvConsistent,
        Self::Didim,
        Self::DidimConsistent,
    ];
}

impl std::fmt::Display for IdentifyMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for IdentifyMethod {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Self::ALL.into_iter().find(|m| m.name() == s).ok_or_else(|| {
            let names: Vec<&str> = Self::ALL.iter().map(|m| m.name()).collect();
            format!("unknown method `{s}` ({})", names.join(", "))
        })
    }
}

/// Fit quality per joint, serialisable.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Metrics {
    pub fp_percent: Vec<f64>,
    pub relative_error: Vec<f64>,
    pub rms: Vec<f64>,
}

/// Settings an identification was made with, kept in the model file: the values used, whether
/// the user set them or the data chose them (`reasons` says which, and why).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Settings {
    pub method: IdentifyMethod,
    /// Periods averaged; `None` when the data were not treated as periodic.
    pub periods: Option<usize>,
    /// The period averaged over (s).
    #[serde(default)]
    pub period_s: Option<f64>,
    pub cutoff_hz: f64,
    /// Cut-off of the velocity that switches Coulomb friction (Hz).
    #[serde(default)]
    pub friction_cutoff_hz: Option<f64>,
    /// The Coulomb law every joint's friction was fitted with, where they share one:
    /// `tanh(q̇/ε)` with this ε (rad/s or m/s), or `sign(q̇)` when `None` (files before this
    /// field were fitted with the declared law, `sign(q̇)` unless it was set). Files that hold
    /// [`Self::friction_velocities`] are read by it instead.
    #[serde(default)]
    pub coulomb_epsilon: Option<f64>,
    /// Each joint's friction velocity: its Coulomb law is `tanh(q̇/v)` with this v (rad/s or
    /// m/s), `sign(q̇)` where `None`; chosen from the data unless the robot declared its laws.
    /// The Coulomb coefficients belong to these laws. Files before it have `coulomb_epsilon`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction_velocities: Option<Vec<Option<f64>>>,
    pub order: usize,
    pub decimate: usize,
    pub pull: f64,
    /// Cable stiffness bounds; `None` is unbounded (JSON has no infinity).
    pub stiffness_bounds: (Option<f64>, Option<f64>),
    /// Each preprocessing choice: its value and why, as data with its text (files before these
    /// fields read as empty, files before they were data as their text).
    #[serde(default, with = "crate::choices::said")]
    pub reasons: Vec<Choice>,
    /// Choices the data support only weakly.
    #[serde(default, with = "crate::choices::said")]
    pub warnings: Vec<Concern>,
}

impl Settings {
    /// `coulomb_epsilon` and `friction_velocities` as a file records `laws`: the width every joint
    /// shares (if any), and each joint's.
    pub fn law_fields(laws: &CoulombLaws) -> (Option<f64>, Option<Vec<Option<f64>>>) {
        (laws.common().and_then(CoulombShape::epsilon), Some(laws.velocities()))
    }
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
    /// The fitted log's fingerprint (`signal::log::Log::fingerprint`: `xxh3:` and 16 hexadecimal
    /// digits; 16 digits of FNV-1a alone in files written before 2026-12-06, none before it was
    /// kept).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fingerprint: Option<String>,
}

/// A saved model: base parameters with their uncertainty, and, when consistent, the full
/// standard parameter vector. Saved as JSON by [`ModelFile::to_json`].
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ModelFile {
    /// [`FORMAT`].
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
    /// What the estimator produced, its fields at the file's top level.
    #[serde(flatten)]
    pub fitted: Fitted,
    pub settings: Settings,
    pub data: DataSummary,
    /// Effects beyond the declared model, added by `arash diagnose` (see `docs/diagnosis.md`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<crate::effects::EffectTerm>,
    /// The drive gains, when the model was identified from motor currents with a known load: the
    /// torque of joint j is `gains[j]` times its current, and the model's parameters are in
    /// physical units.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drive_gains: Option<DriveGains>,
    /// The model's residual on data it was not fitted on, per joint: what a force estimate's σ
    /// and its detection thresholds are set from (docs/force.md). `arash identify --validate`
    /// and `arash diagnose` record it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub held_out: Option<HeldOut>,
}

/// A model's residual on held-out data: measured torque minus the model's prediction, in the
/// band the model was fitted in, each sample on its own (periods not averaged, as a force
/// estimate sees them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldOut {
    /// RMS per joint (N·m or N).
    pub rms: Vec<f64>,
    /// The samples pooled over.
    pub samples: usize,
    /// The band's cut-off (Hz).
    pub cutoff_hz: f64,
    /// Which data: the validation runs' names, or the training log's held-out blocks.
    pub source: String,
    /// The momentum observer run on the same held-out data with no hand: the bandwidth chosen
    /// per joint and the estimate's RMS there, the σ a force estimate carries
    /// (`force_log::observer_held_out`). Absent in files from before it was measured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub observer: Option<ObserverHeldOut>,
}

/// The observer's hand-free estimate on held-out data, over a grid of bandwidths.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObserverHeldOut {
    /// The bandwidth chosen per joint (Hz).
    pub bandwidth_hz: Vec<f64>,
    /// The estimate's RMS per joint at that bandwidth (N·m or N).
    pub sigma: Vec<f64>,
    /// The bandwidths tried (Hz) and the RMS at each, per joint (`grid × dof`, row-major).
    pub grid_hz: Vec<f64>,
    pub grid_sigma: Vec<f64>,
    /// Why each joint's bandwidth was chosen (text in files before it was data).
    #[serde(with = "crate::choices::said::one")]
    pub reason: ForceChoice,
    /// The largest hand-free estimate per joint at its bandwidth (N·m or N): the collision
    /// threshold stays above it. Empty in files from before it was kept.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub peak: Vec<f64>,
}

impl HeldOut {
    /// One finite, non-negative RMS per joint, and a positive cut-off: σ and thresholds are made
    /// from them.
    fn check(&self, dof: usize) -> Result<(), ModelFileError> {
        if self.rms.len() != dof {
            return Err(ModelFileError::Shape(format!(
                "`held_out.rms` has {} values for {dof} joints",
                self.rms.len()
            )));
        }
        if let Some((k, v)) = self.rms.iter().enumerate().find(|(_, v)| !(v.is_finite() && **v >= 0.0)) {
            return Err(ModelFileError::Shape(format!(
                "`held_out.rms[{k}]` is {v}; a residual's RMS must be finite and not negative"
            )));
        }
        if !(self.cutoff_hz.is_finite() && self.cutoff_hz > 0.0) {
            return Err(ModelFileError::Shape(format!(
                "`held_out.cutoff_hz` is {}; it must be positive and finite",
                self.cutoff_hz
            )));
        }
        if let Some(o) = &self.observer {
            let checks = [
                ("bandwidth_hz", &o.bandwidth_hz, dof, true),
                ("sigma", &o.sigma, dof, false),
                ("grid_sigma", &o.grid_sigma, o.grid_hz.len() * dof, false),
                ("peak", &o.peak, if o.peak.is_empty() { 0 } else { dof }, false),
            ];
            for (name, values, len, positive) in checks {
                if values.len() != len {
                    return Err(ModelFileError::Shape(format!(
                        "`held_out.observer.{name}` has {} values; it needs {len}",
                        values.len()
                    )));
                }
                if let Some((k, v)) =
                    values.iter().enumerate().find(|(_, v)| !(v.is_finite() && **v >= 0.0) || (positive && **v == 0.0))
                {
                    return Err(ModelFileError::Shape(format!(
                        "`held_out.observer.{name}[{k}]` is {v}; it must be finite and {}",
                        if positive { "positive" } else { "not negative" }
                    )));
                }
            }
        }
        Ok(())
    }
}

/// How the stacked problem is solved. Both treat the currents as measured with noise, which plain
/// least squares in torque units does not: it shrinks a gain toward zero where the model leaves
/// torque unexplained (`identify::drive_gains`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum GainEstimator {
    /// Least squares of each row's residual in amperes, by Gauss–Newton (the default).
    #[default]
    #[serde(rename = "current")]
    CurrentUnits,
    /// Total least squares of the stacked system, every column scaled to unit norm (Gautier and
    /// Briot's): errors in every column alike, the currents' among them.
    #[serde(rename = "tls")]
    TotalLeastSquares,
}

impl std::str::FromStr for GainEstimator {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "current" => Ok(Self::CurrentUnits),
            "tls" => Ok(Self::TotalLeastSquares),
            other => Err(format!("gains fit `{other}`: use `current` (least squares in amperes) or `tls`")),
        }
    }
}

impl GainEstimator {
    /// Its name on the command line and in Python.
    pub fn id(self) -> &'static str {
        match self {
            Self::CurrentUnits => "current",
            Self::TotalLeastSquares => "tls",
        }
    }
}

/// Drive gains identified with a known load (`identify::drive_gains`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DriveGains {
    /// Per joint (N·m/A or N/A).
    pub gains: Vec<f64>,
    /// Their standard deviations.
    pub sigma: Vec<f64>,
    /// How the stacked problem was solved.
    #[serde(default)]
    pub estimator: GainEstimator,
    /// Their covariance, row-major (joints × joints; `sigma` is its diagonal's root). Files
    /// written before it was kept read as empty: the gains are then taken as independent.
    #[serde(default)]
    pub covariance: Vec<f64>,
    /// Per joint j, how the model's base parameters move with its gain, `∂β/∂ln kⱼ`
    /// (`identify::drive_gains::beta_per_gain`): a later diagnosis counts the gains' σ through it.
    #[serde(default)]
    pub beta_per_gain: Vec<Vec<f64>>,
    /// Whether each gain is a datasheet's, taken where the load does not fix it.
    #[serde(default)]
    pub from_datasheet: Vec<bool>,
    /// The body the known load rode on, and its mass (kg).
    pub load_body: String,
    pub load_mass: f64,
    /// The load's unknowns estimated with the gains: name, value, σ (SI, about the body's frame
    /// origin).
    pub load_estimate: Vec<(String, f64, f64)>,
    /// Scaled condition number of the stacked problem of gains, base and load parameters.
    pub condition_number: f64,
    /// Per joint: the known load's share of its torque, the load's torque over what the model
    /// leaves unexplained, and whether the load fixes its gain (`identify::drive_gains::NOT_FIXED`).
    pub load_share: Vec<f64>,
    pub load_over_unexplained: Vec<f64>,
    pub fixed: Vec<bool>,
}

impl DriveGains {
    /// Lengths against `dof` joints and `p` base parameters, and values a torque can be computed
    /// with: each gain finite and non-zero, each σ finite and non-negative.
    fn check_shape(&self, dof: usize, p: usize) -> Result<(), String> {
        let per_joint = [("gains", self.gains.len()), ("sigma", self.sigma.len())];
        if let Some((name, n)) = per_joint.iter().find(|(_, n)| *n != dof) {
            return Err(format!("`drive_gains.{name}` has {n} entries; the robot has {dof} joints"));
        }
        if !(self.covariance.is_empty() || self.covariance.len() == dof * dof) {
            return Err(format!("`drive_gains.covariance` has {} entries, not {dof} × {dof}", self.covariance.len()));
        }
        if !(self.beta_per_gain.is_empty()
            || self.beta_per_gain.len() == dof && self.beta_per_gain.iter().all(|b| b.len() == p))
        {
            return Err(format!("`drive_gains.beta_per_gain` must be {dof} rows of {p} (one per base parameter)"));
        }
        if let Some(k) = self.gains.iter().find(|k| !(k.is_finite() && **k != 0.0)) {
            return Err(format!("a drive gain is {k}; each must be finite and non-zero"));
        }
        let rest = self.sigma.iter().chain(&self.covariance).chain(self.beta_per_gain.iter().flatten());
        match rest.copied().find(|x| !x.is_finite()) {
            Some(x) => Err(format!("a drive gain's σ, covariance or sensitivity is {x}; each must be finite")),
            None => Ok(()),
        }
    }
}

/// Write `text` to `path` through a temporary file and a rename, so that a crash never leaves half
/// a model or trajectory file behind.
pub fn write_atomically(path: &Path, text: &str) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".partial");
    std::fs::write(&tmp, text)?;
    std::fs::rename(&tmp, path)
}

/// What sets a base parameter's σ% besides the torque's noise. Its σ is about the residual over
/// `‖w‖ · apart` (`w` its column), so σ% = σ/|β| is large for a column the others nearly explain
/// (small `apart`), or for a parameter that moves little torque (small |β|·‖w‖) against what the
/// model leaves unexplained. The table names the cause of each σ% above
/// [`WELL_DETERMINED_PERCENT`].
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Determination {
    /// The part of the parameter's column, at unit norm, outside the span of all the others'
    /// (1/√VIF): 1 for a column orthogonal to the rest, 0 for one they explain.
    pub apart: f64,
    /// The base parameter (index) whose column it leans on most, when there are others.
    pub leans_on: Option<usize>,
    /// Its column's norm over the torque's, on the joint where that is largest: times |β|, the
    /// share of that joint's torque it moves.
    pub column_over_torque: f64,
    /// That share for the estimate whose σ% the file reports (for a consistent fit, the
    /// unconstrained one its σ% come from, not the constrained β).
    pub torque_share: f64,
}

/// σ% up to which a parameter counts as well determined (the paper's Table I reading; issue 18).
pub const WELL_DETERMINED_PERCENT: f64 = 10.0;

/// Whether a σ% is at most [`WELL_DETERMINED_PERCENT`] (a NaN σ% is not).
pub fn well_determined(sigma_percent: f64) -> bool {
    sigma_percent <= WELL_DETERMINED_PERCENT
}

/// A column this close to the others' span is collinear with them: VIF above 100.
pub const COLLINEAR_APART: f64 = 0.1;

/// A parameter that moves less than this share of its joint's torque is small in it.
pub const SMALL_TORQUE_SHARE: f64 = 0.01;

impl Determination {
    /// Its column within [`COLLINEAR_APART`] of the others' span.
    pub fn collinear(&self) -> bool {
        self.apart < COLLINEAR_APART
    }

    /// Under [`SMALL_TORQUE_SHARE`] of its joint's torque.
    pub fn small(&self) -> bool {
        self.torque_share < SMALL_TORQUE_SHARE
    }

    /// The same with its torque share taken at the estimate `beta`.
    pub fn at(&self, beta: f64) -> Self {
        Self { torque_share: beta.abs() * self.column_over_torque, ..self.clone() }
    }

    /// Why a σ% is above [`WELL_DETERMINED_PERCENT`], `names` the base parameters' names:
    /// collinear (with the one it leans on), small in its joint's torque, or, when neither,
    /// noisy (what the model leaves unexplained is large against what it moves).
    pub fn cause(&self, names: &[String]) -> String {
        let share = self.torque_share;
        let mut causes = Vec::new();
        if self.collinear() {
            let on = self.leans_on.and_then(|j| names.get(j)).map_or(String::new(), |n| format!(", on {n}"));
            causes.push(format!("collinear ({:.1} % apart{on})", 100.0 * self.apart));
        }
        if self.small() {
            causes.push(format!("small ({:.2} % of its joint's torque)", 100.0 * share));
        }
        if causes.is_empty() {
            causes.push(format!(
                "noisy ({:.0} % apart, {:.1} % of its joint's torque)",
                100.0 * self.apart,
                100.0 * share
            ));
        }
        causes.join(", ")
    }
}

/// Table I's causes counted: see [`ModelFile::cause_counts`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CauseCounts {
    pub well_determined: usize,
    pub collinear: usize,
    pub small: usize,
    pub noisy: usize,
}

/// The fitted part of a model file: what an estimator produced. The file lists these fields
/// at its top level (`#[serde(flatten)]`), so this is their one definition.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Fitted {
    /// β̂ (for `consistent`, `B π̂`).
    pub beta: Vec<f64>,
    /// Relative standard deviation of each β̂ from the least-squares fit (%).
    pub sigma_percent: Vec<f64>,
    /// The covariance of β̂ from the least-squares fit (the block sandwich whose diagonal gives
    /// `sigma_percent`), row-major: a diagnosis against this model counts its parameters' own
    /// error (`diagnose/calibration_error.rs`). Empty in files written before it was kept.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub beta_covariance: Vec<f64>,
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
    /// Per base parameter, what sets its σ% (files written before it was kept have none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub determination: Vec<Determination>,
}

impl ModelFile {
    /// A model file of this version for the robot `model` (its base parameters `base`, from the
    /// URDF text `urdf`), holding `fitted`, made with `settings` from `data`; no effects yet.
    pub fn new(
        model: &Model,
        base: &BaseParameters,
        urdf: &str,
        fitted: Fitted,
        settings: Settings,
        data: DataSummary,
    ) -> Self {
        Self {
            format: FORMAT.into(),
            software_version: env!("CARGO_PKG_VERSION").into(),
            robot_name: model.name.clone(),
            urdf: urdf.to_string(),
            parameter_names: model.parameter_names(),
            base_names: base.names.clone(),
            base_expressions: base.expressions.clone(),
            base_independent: base.independent.clone(),
            fitted,
            settings,
            data,
            effects: vec![],
            drive_gains: None,
            held_out: None,
        }
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("an identification always serialises")
    }

    /// Write the model file (JSON, URDF embedded), atomically.
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        write_atomically(path, &self.to_json())
    }

    pub fn from_json(text: &str) -> Result<Self, ModelFileError> {
        let id: Self = serde_json::from_str(text).map_err(|e| ModelFileError::Json(e.to_string()))?;
        if id.format != FORMAT {
            return Err(ModelFileError::Format(id.format));
        }
        // Every use of the file's friction takes its law (`with_its_law`): a width of zero would
        // make its Coulomb columns NaN.
        if let Some(epsilon) = id.settings.coulomb_epsilon.filter(|e| CoulombShape::tanh(*e).is_none()) {
            return Err(ModelFileError::Shape(format!(
                "`settings.coulomb_epsilon` is {epsilon}; a tanh law's width must be positive and finite"
            )));
        }
        if let Some(velocities) = &id.settings.friction_velocities {
            let dof = id.dof();
            if velocities.len() != dof {
                return Err(ModelFileError::Shape(format!(
                    "`settings.friction_velocities` has {} values for {dof} joints",
                    velocities.len()
                )));
            }
            if let Err((k, v)) = CoulombLaws::of_velocities(velocities) {
                return Err(ModelFileError::Shape(format!(
                    "`settings.friction_velocities[{k}]` is {v}; a friction velocity must be positive and finite \
                     (null for sign(q̇))"
                )));
            }
        }
        if let Some(held_out) = &id.held_out {
            held_out.check(id.dof())?;
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
    pub fn controller_parameters(&self, model: &Model) -> Result<Vec<f64>, ModelFileError> {
        self.check_shape(model)?;
        Ok(self.full_or_base_vector())
    }

    /// [`Self::controller_parameters`] for a law that inverts M(q): also refused unless every
    /// body's pseudo-inertia, recomputed from the file's own parameters, is positive
    /// semidefinite (an indefinite one can make M(q) indefinite and the loop unstable). The
    /// file's `min_pseudo_inertia_eigenvalue` is a report, never trusted.
    pub fn consistent_controller_parameters(&self, model: &Model) -> Result<Vec<f64>, ModelFileError> {
        let eigenvalues = self.recomputed_pseudo_inertia_eigenvalues(model)?; // checks the shape too
        let (body, worst) =
            eigenvalues.iter().copied().enumerate().min_by(|a, b| a.1.total_cmp(&b.1)).unwrap_or((0, f64::INFINITY));
        if worst < -CONSISTENCY_TOLERANCE {
            let claimed = self.fitted.min_pseudo_inertia_eigenvalue.iter().copied().fold(f64::INFINITY, f64::min);
            return Err(ModelFileError::NotConsistent {
                body: model.bodies[body].name.clone(),
                eigenvalue: worst,
                claimed,
            });
        }
        Ok(self.full_or_base_vector())
    }

    /// The smallest pseudo-inertia eigenvalue of each body from the file's parameters: π̂, or the
    /// standard parameters nearest CAD that reproduce β̂.
    pub fn recomputed_pseudo_inertia_eigenvalues(&self, model: &Model) -> Result<Vec<f64>, ModelFileError> {
        self.check_shape(model)?;
        if let Some(params) = &self.fitted.params {
            return Ok(min_pseudo_inertia_eigenvalues(model, params));
        }
        let Some(base) = BaseParameters::with_independent(model, &self.base_independent)? else {
            return Err(ModelFileError::Shape(
                "its base parameters are not this robot's (independent columns differ)".into(),
            ));
        };
        Ok(min_pseudo_inertia_eigenvalues(model, &nearest_standard_parameters(model, &base, &self.fitted.beta)))
    }

    /// The file's vectors against `model`: same robot, matching lengths, finite values.
    fn check_shape(&self, model: &Model) -> Result<(), ModelFileError> {
        let file = |text: String| Err(ModelFileError::Shape(text));
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
        if let Some(p) = &self.fitted.params {
            if p.len() != big_p {
                return file(format!("`params` has {} entries; the robot has {big_p} parameters", p.len()));
            }
        }
        if self.fitted.beta.len() != self.base_independent.len() {
            return file(format!(
                "`beta` has {} entries but `base_independent` names {} columns",
                self.fitted.beta.len(),
                self.base_independent.len()
            ));
        }
        if let Some(&j) = self.base_independent.iter().find(|&&j| j >= big_p) {
            return file(format!("`base_independent` names column {j}; the robot has {big_p} parameters"));
        }
        let values = self.fitted.beta.iter().chain(self.fitted.params.iter().flatten());
        if let Some(x) = values.copied().find(|x| !x.is_finite()) {
            return file(format!("a parameter is {x}; every value must be finite"));
        }
        match &self.drive_gains {
            Some(g) => g.check_shape(model.dof(), self.fitted.beta.len()).map_err(ModelFileError::Shape),
            None => Ok(()),
        }
    }

    /// A P-vector whose product with the full regressor is the prediction: π̂, or β̂ placed on the
    /// independent columns (zeros elsewhere).
    pub fn full_or_base_vector(&self) -> Vec<f64> {
        self.fitted.params.clone().unwrap_or_else(|| {
            let mut v = vec![0.0; self.parameter_names.len()];
            for (&j, b) in self.base_independent.iter().zip(&self.fitted.beta) {
                v[j] = *b;
            }
            v
        })
    }

    /// The same model in the base parameters `base`, whose columns include this file's: β̂ on
    /// its own columns and zero on the others (the weak ones an identification regrouped), so
    /// that it predicts exactly as before, and its covariance likewise. `None` where `base` lacks
    /// one of this file's columns. What sets each σ% is not carried over: it was measured among
    /// the file's own columns.
    pub fn in_base(&self, base: &BaseParameters) -> Option<Self> {
        if self.base_independent == base.independent {
            return Some(self.clone());
        }
        let at: Vec<Option<usize>> =
            base.independent.iter().map(|j| self.base_independent.iter().position(|i| i == j)).collect();
        if at.iter().flatten().count() != self.base_independent.len() {
            return None;
        }
        let (p, r) = (self.base_independent.len(), at.len());
        let placed = |v: &[f64]| -> Vec<f64> {
            match v.len() == p {
                true => at.iter().map(|i| i.map_or(0.0, |i| v[i])).collect(),
                false => v.to_vec(),
            }
        };
        let mut out = self.clone();
        out.fitted.beta = placed(&self.fitted.beta);
        out.fitted.sigma_percent = placed(&self.fitted.sigma_percent);
        if self.fitted.beta_covariance.len() == p * p {
            let entry = |k: usize| match (at[k / r], at[k % r]) {
                (Some(a), Some(b)) => self.fitted.beta_covariance[a * p + b],
                _ => 0.0,
            };
            out.fitted.beta_covariance = (0..r * r).map(entry).collect();
        }
        out.fitted.determination.clear();
        out.base_names = base.names.clone();
        out.base_expressions = base.expressions.clone();
        out.base_independent = base.independent.clone();
        Some(out)
    }

    /// The joints of the robot the file describes (one stiffness each).
    fn dof(&self) -> usize {
        self.parameter_names.iter().filter(|n| n.ends_with(".ke")).count()
    }

    /// Each joint's Coulomb law the friction was fitted with, declared: its coefficients belong
    /// to it.
    pub fn coulomb_laws(&self) -> CoulombLaws {
        match &self.settings.friction_velocities {
            Some(velocities) => CoulombLaws::of_velocities(velocities).expect("checked when the file was read"),
            None => CoulombLaws::uniform(CoulombShape::of_epsilon(self.settings.coulomb_epsilon), self.dof()),
        }
    }

    /// `model` with the Coulomb laws this file's friction was fitted with, which every use of
    /// its coefficients must share.
    pub fn with_its_law<'a>(&self, model: &'a Model) -> std::borrow::Cow<'a, Model> {
        let laws = self.coulomb_laws();
        if laws == model.coulomb_laws {
            return std::borrow::Cow::Borrowed(model);
        }
        let mut with_law = model.clone();
        with_law.coulomb_laws = laws;
        std::borrow::Cow::Owned(with_law)
    }

    /// Per base parameter, why its σ% is above [`WELL_DETERMINED_PERCENT`] (`None` where it is
    /// not); `None` for a file without [`Determination`]s.
    pub fn causes(&self) -> Option<Vec<Option<String>>> {
        if self.fitted.determination.len() != self.fitted.beta.len() {
            return None;
        }
        let causes = self.fitted.determination.iter().zip(&self.fitted.sigma_percent);
        Some(causes.map(|(d, s)| (!well_determined(*s)).then(|| d.cause(&self.base_names))).collect())
    }

    /// How many base parameters have σ% at or under [`WELL_DETERMINED_PERCENT`], and of the
    /// others how many are collinear, small and noisy (one can be both collinear and small);
    /// `None` for a file without [`Determination`]s.
    pub fn cause_counts(&self) -> Option<CauseCounts> {
        if self.fitted.determination.len() != self.fitted.beta.len() {
            return None;
        }
        let mut counts = CauseCounts::default();
        for (d, s) in self.fitted.determination.iter().zip(&self.fitted.sigma_percent) {
            if well_determined(*s) {
                counts.well_determined += 1;
                continue;
            }
            counts.collinear += usize::from(d.collinear());
            counts.small += usize::from(d.small());
            counts.noisy += usize::from(!d.collinear() && !d.small());
        }
        Some(counts)
    }

    /// Table I shape: each base parameter, its value and σ%, and the training fit.
    pub fn table(&self) -> String {
        let mut s = format!(
            "Identified base parameters ({:?}, {} samples used of {}, cut-off {:.2} Hz, κ = {:.1})\n",
            self.settings.method,
            self.data.samples_used,
            self.data.samples_in,
            self.settings.cutoff_hz,
            self.fitted.condition_number
        );
        // The consistent β is a constrained estimate; its spread is reported from the least squares.
        let sigma = match self.settings.method {
            IdentifyMethod::Consistent => "σ% (OLS)",
            IdentifyMethod::IdimIvConsistent => "σ% (IV)",
            IdentifyMethod::DidimConsistent => "σ% (DIDIM)",
            _ => "σ%",
        };
        s += &format!("  Coulomb friction as {}\n", self.coulomb_laws());
        s += &self.settings.reasons.iter().map(|r| format!("  {r}\n")).collect::<String>();
        s += &self.settings.warnings.iter().map(|w| format!("  warning: {w}\n")).collect::<String>();
        let causes = self.causes();
        let why = causes.as_ref().map_or(String::new(), |_| format!("  why σ% > {WELL_DETERMINED_PERCENT}"));
        s += &format!("{:<4} {:<34} {:>14} {:>10}{why}\n", "", "parameter", "value", sigma);
        for (i, name) in self.base_names.iter().enumerate() {
            s += &format!(
                "β{:<3} {:<34} {:>14.6e} {:>10.2}",
                i + 1,
                name,
                self.fitted.beta[i],
                self.fitted.sigma_percent[i]
            );
            match causes.as_ref().and_then(|c| c[i].as_ref()) {
                Some(cause) => s += &format!("  {cause}\n"),
                None => s += "\n",
            }
        }
        s += "\nTraining fit per joint:      ";
        s += &(0..self.fitted.training.fp_percent.len())
            .map(|k| format!("{:>10}", format!("joint {}", k + 1)))
            .collect::<String>();
        let row = |label: &str, v: &[f64], fmt: &dyn Fn(f64) -> String| {
            format!("\n  {label:<26} {}", v.iter().map(|x| format!("{:>10}", fmt(*x))).collect::<String>())
        };
        s += &row("FP% (this model)", &self.fitted.training.fp_percent, &|x| format!("{x:.2}"));
        s += &row("FP% (OLS)", &self.fitted.training_ols.fp_percent, &|x| format!("{x:.2}"));
        s += &row("‖τ − τ̂‖/‖τ‖", &self.fitted.training.relative_error, &|x| format!("{x:.4}"));
        s += &row("RMS (N·m or N)", &self.fitted.training.rms, &|x| format!("{x:.2e}"));
        if let Some(g) = &self.drive_gains {
            s += &row("drive gain (per A)", &g.gains, &|x| format!("{x:.4}"));
            s += &row("  its σ", &g.sigma, &|x| format!("{x:.4}"));
            let fixed: Vec<f64> = g.fixed.iter().map(|f| f64::from(u8::from(*f))).collect();
            s += &row("  fixed by the load (1/0)", &fixed, &|x| format!("{x:.0}"));
        }
        let worst = self.fitted.min_pseudo_inertia_eigenvalue.iter().copied().fold(f64::INFINITY, f64::min);
        s += &format!(
            "\n\nSmallest pseudo-inertia eigenvalue over bodies: {worst:.3e} ({})\n",
            if worst >= -CONSISTENCY_TOLERANCE { "physical" } else { "NOT physical" }
        );
        s
    }
}
