//! Drive gains identified with a known load (Gautier and Briot, "Global identification of joint
//! drive gains and dynamic parameters of robots", ASME J. Dyn. Sys. Meas. Control 136(5), 2014).
//!
//! A rig that logs motor currents `i` has joint torques `kⱼ iⱼ`, with each joint's gain `kⱼ`
//! (torque constant × gear or drum ratio × the current sensor's scale) known to ±10 % at best.
//! Least squares on currents fits `β/kⱼ` joint by joint: every mass comes out in amperes, and
//! a common scale of the gains cannot be told from the parameters' at all. A load of known mass,
//! carried in some runs and not in others, fixes that scale:
//!
//! ```text
//! unloaded runs:  W β             − diag(i) k = 0
//! loaded runs:    W β + W B_b,u δ − diag(i) k = −W B_b,k π_k
//! ```
//!
//! `W` is the base regressor, `B_b` the base map's columns of the body `b` the load rides on: the
//! load adds its ten inertial parameters to that body's, so it reaches the torque as `W B_b π_L`.
//! Its known part `π_k` (the mass, and the first moments and inertia where they are known) moves
//! to the right-hand side; its unknown part enters through those of `B_b`'s columns that are
//! independent (`δ`: the load's identifiable combinations, estimated with the gains). The
//! problem is linear in `(β, δ, k)` and is solved by the least squares of [`crate::signal::estimate`], its
//! σ the same block sandwich, its conditioning named by parameter where a gain is not fixed.

use crate::base_parameters::BaseParameters;
use crate::choices::{Choice, Concern, JointGain, LooseGain};
use crate::dense;
use crate::model::Model;
use crate::params::{body as body_params, PER_BODY};
use crate::signal::estimate::{fit_stacked, sandwich_covariance, stack, EstimateError, Fit, Method};
use crate::signal::preprocess::Preprocessed;
use faer::prelude::*;
use faer::Mat;

pub use crate::model_file::GainEstimator;

/// A load of known mass, and where known its centre of mass and inertia, fixed to one body. As a
/// file (TOML or JSON): `body = "link_6"`, `mass = 2.805`, and optionally `com = [x, y, z]` and
/// `inertia = [Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KnownLoad {
    /// The body (URDF link) it rides on.
    pub body: String,
    /// kg.
    pub mass: f64,
    /// Its centre of mass in the body's frame (m), when known.
    pub com: Option<[f64; 3]>,
    /// Its inertia about its centre of mass, in the body frame's axes, `[Ixx, Iyy, Izz, Ixy, Ixz,
    /// Iyz]` (kg·m²), when known; needs `com`.
    pub inertia: Option<[f64; 6]>,
}

/// Why a known-load identification cannot be made, naming the input.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GainsError {
    #[error("no {0} run: drive gains need runs both with and without the known load")]
    MissingRuns(&'static str),
    #[error(
        "total least squares has no solution here: the smallest singular direction of the stacked system leaves out \
         the load's torque (the load does not reach the currents); use the default gains fit"
    )]
    NoTotalLeastSquares,
    #[error("the load is on body `{name}`, which the robot does not have (bodies: {bodies})")]
    UnknownBody { name: String, bodies: String },
    #[error("the load's {what}")]
    BadLoad { what: String },
    #[error(
        "a load on `{body}` known by {known} only cannot fix the gains: its known part acts on the base parameters \
         exactly as its unknown {unknown} can, so the fit would take it for them (relative residual {residual:.1e}). \
         Give its centre of mass (and inertia), or put it on a body whose mass the torque sees apart from its first \
         moments"
    )]
    NotSeparable { body: String, known: String, unknown: String, residual: f64 },
    #[error("datasheet gains: {0}")]
    BadDatasheet(String),
    #[error("run {run} has {dof} joints; the robot has {expected}")]
    WrongRobot { run: usize, dof: usize, expected: usize },
    #[error(transparent)]
    Estimate(#[from] EstimateError),
}

impl KnownLoad {
    /// The body's index, once every value is checked: a positive finite mass, a finite centre of
    /// mass, an inertia that is physical (positive semi-definite, each principal moment at most
    /// the sum of the other two) and given with its centre of mass.
    pub fn validate(&self, model: &Model) -> Result<usize, GainsError> {
        let body = model.bodies.iter().position(|b| b.name == self.body).ok_or_else(|| GainsError::UnknownBody {
            name: self.body.clone(),
            bodies: model.bodies.iter().map(|b| b.name.as_str()).collect::<Vec<_>>().join(", "),
        })?;
        let bad = |what: String| Err(GainsError::BadLoad { what });
        if !(self.mass.is_finite() && self.mass > 0.0) {
            return bad(format!("mass must be positive and finite, not {} kg", self.mass));
        }
        if let Some(c) = self.com.filter(|c| c.iter().any(|x| !x.is_finite())) {
            return bad(format!("centre of mass must be finite, not {c:?} m"));
        }
        if let Some(i) = self.inertia {
            if self.com.is_none() {
                return bad("inertia is about its centre of mass, which must then be given too".into());
            }
            let m = nalgebra::Matrix3::new(i[0], i[3], i[4], i[3], i[1], i[5], i[4], i[5], i[2]);
            let eigen = m.symmetric_eigenvalues();
            let (lo, sum) = (eigen.min(), eigen.sum());
            let tolerance = 1e-12 * eigen.amax().max(f64::MIN_POSITIVE);
            if i.iter().any(|x| !x.is_finite()) || lo < -tolerance || eigen.iter().any(|e| *e > sum - e + tolerance) {
                return bad(format!(
                    "inertia {i:?} kg·m² is not physical: principal moments {:?} must be non-negative, each at most \
                     the sum of the other two",
                    eigen.as_slice()
                ));
            }
        }
        Ok(body)
    }

    /// The load's ten standard parameters about the body's frame origin (`[m, mcx, mcy, mcz,
    /// Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`), `None` where unknown.
    pub fn parameters(&self) -> [Option<f64>; PER_BODY] {
        let mut known = [None; PER_BODY];
        known[0] = Some(self.mass);
        if let Some(c) = self.com {
            for a in 0..3 {
                known[1 + a] = Some(self.mass * c[a]);
            }
            if let Some(i) = self.inertia {
                // Parallel axes, from the centre of mass to the frame origin.
                let m = self.mass;
                let sq = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
                let about = [
                    i[0] + m * (sq - c[0] * c[0]),
                    i[1] + m * (sq - c[1] * c[1]),
                    i[2] + m * (sq - c[2] * c[2]),
                    i[3] - m * c[0] * c[1],
                    i[4] - m * c[0] * c[2],
                    i[5] - m * c[1] * c[2],
                ];
                for (a, v) in about.into_iter().enumerate() {
                    known[4 + a] = Some(v);
                }
            }
        }
        known
    }
}

/// The names of a body's ten parameters, as the load's are reported.
const LOAD_NAMES: [&str; PER_BODY] = ["m", "mcx", "mcy", "mcz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"];

/// What a calibration from currents is given besides the runs: the known load, gains from a
/// datasheet if any (each `(k, σ)`, [`with_datasheet`]), and how to solve.
#[derive(Clone, Copy, Debug)]
pub struct Calibration<'a> {
    pub load: &'a KnownLoad,
    pub datasheet: Option<&'a [(f64, f64)]>,
    pub estimator: GainEstimator,
}

/// One preprocessed run: its currents in place of the torque, and whether it carries the load.
pub struct GainRun<'a> {
    pub data: &'a Preprocessed,
    pub loaded: bool,
}

/// The gains, the robot's base parameters and the load's unknowns, fitted together.
#[derive(Clone, Debug)]
pub struct GainFit {
    /// Each joint's drive gain (N·m/A or N/A) and its σ.
    pub gains: Vec<f64>,
    pub gain_sigma: Vec<f64>,
    /// The gains' covariance (row-major, joints × joints): `gain_sigma` is its diagonal's root.
    pub gain_covariance: Vec<f64>,
    /// The robot's base parameters (without the load) in physical units.
    pub beta: Vec<f64>,
    pub beta_sigma: Vec<f64>,
    /// The load's identifiable unknowns: name, value and σ (first moments in kg·m, inertias about
    /// the body's frame origin in kg·m²).
    pub load: Vec<(String, f64, f64)>,
    /// Per joint: the RMS of the known load's torque over the loaded runs, as a share of the
    /// joint's RMS torque there. A joint where it is nil gets its scale only through parameters it
    /// shares with the others.
    pub load_torque_share: Vec<f64>,
    /// Per joint: the RMS of the known load's torque over the RMS of the torque the model leaves
    /// unexplained. Only where it is well above 1 does the load, rather than the model's error, set
    /// the gain.
    pub load_over_unexplained: Vec<f64>,
    /// Whether the load fixes each gain ([`fixed`]).
    pub fixed: Vec<bool>,
    /// The fit of the stacked problem (conditioning, σ%, what sets each σ).
    pub fit: Fit,
    pub reasons: Vec<Choice>,
    /// Gains the load does not fix.
    pub warnings: Vec<Concern>,
}

/// Fit the drive gains, the base parameters and the load's unknowns from `runs` (at least one with
/// the load and one without), the known `load` on body `body` ([`KnownLoad::validate`]).
pub fn fit_gains(
    model: &Model,
    base: &BaseParameters,
    runs: &[GainRun],
    load: &KnownLoad,
    body: usize,
    method: Method,
    estimator: GainEstimator,
) -> Result<GainFit, GainsError> {
    let dof = model.dof();
    for (run, r) in runs.iter().enumerate() {
        if r.data.dof != dof {
            return Err(GainsError::WrongRobot { run, dof: r.data.dof, expected: dof });
        }
    }
    if !runs.iter().any(|r| r.loaded) {
        return Err(GainsError::MissingRuns("loaded"));
    }
    if !runs.iter().any(|r| !r.loaded) {
        return Err(GainsError::MissingRuns("unloaded"));
    }
    let p = base.rank;
    let b_body = base_map_of_body(base, body);
    let known = load.parameters();
    let unknown: Vec<usize> = independent_columns(&b_body, p, (0..PER_BODY).filter(|&c| known[c].is_none()).collect());
    separable(&b_body, p, &known, &unknown).map_err(|residual| GainsError::NotSeparable {
        body: load.body.clone(),
        known: names_of((0..PER_BODY).filter(|&c| known[c].is_some())),
        unknown: names_of(unknown.iter().copied()),
        residual,
    })?;
    let columns = p + unknown.len() + dof;
    let stacked: Vec<(Mat<f64>, Vec<f64>, bool)> = runs
        .iter()
        .map(|r| {
            let (w, current) = stack(model, base, r.data);
            (w, current, r.loaded)
        })
        .collect();
    let rows: usize = stacked.iter().map(|(w, _, _)| w.nrows()).sum();
    let mut x = Mat::<f64>::zeros(rows, columns);
    let mut y = vec![0.0; rows];
    let mut load_torque = vec![(0.0, 0.0); dof];
    let mut offset = 0;
    for (w, current, loaded) in &stacked {
        for r in 0..w.nrows() {
            let (row, joint) = (offset + r, r % dof);
            let wr: Vec<f64> = (0..p).map(|c| w[(r, c)]).collect();
            for (c, v) in wr.iter().enumerate() {
                x[(row, c)] = *v;
            }
            x[(row, p + unknown.len() + joint)] = -current[r];
            if *loaded {
                // The load's columns on this row: W B_b.
                let on = |c: usize| wr.iter().enumerate().map(|(j, v)| v * b_body[j * PER_BODY + c]).sum::<f64>();
                for (u, &c) in unknown.iter().enumerate() {
                    x[(row, p + u)] = on(c);
                }
                let known_torque: f64 = (0..PER_BODY).filter_map(|c| known[c].map(|v| on(c) * v)).sum();
                y[row] = -known_torque;
                load_torque[joint].0 += known_torque * known_torque;
            }
        }
        offset += w.nrows();
    }
    let names = fitted_names(model, base, &unknown);
    let augmented = BaseParameters { rank: columns, names, expressions: vec![], weak: vec![], ..base.clone() };
    let rate = runs.iter().map(|r| r.data.rate_hz() / r.data.cutoff_hz).fold(1.0, f64::max);
    let block = (2.0 * rate).ceil() as usize;
    // The linear problem in torque units starts the fit in current units, whose σ is reported.
    let problem = CurrentUnits { x: &x, y: &y, dof, q: p + unknown.len() };
    let fit = match estimator {
        GainEstimator::CurrentUnits => {
            let linear = fit_stacked(&x, &y, dof, &augmented, method, block)?;
            let (j, z) = problem.solve_from(&linear.beta);
            fit_stacked(&j, &z, dof, &augmented, method, block)?
        }
        GainEstimator::TotalLeastSquares => {
            let theta = total_least_squares(&x, &y).ok_or(GainsError::NoTotalLeastSquares)?;
            problem.at_total_least_squares(&theta, &augmented, block)?
        }
    };
    let theta = &fit.beta;
    let inverse = &theta[p + unknown.len()..];
    let gains: Vec<f64> = inverse.iter().map(|c| 1.0 / c).collect();
    let gain_sigma: Vec<f64> =
        fit.sigma_beta[p + unknown.len()..].iter().zip(inverse).map(|(s, c)| s / (c * c)).collect();
    // k = 1/c moves by −dc/c² on each joint: the two signs cancel in the covariance.
    let at = p + unknown.len();
    let gain_covariance: Vec<f64> = (0..dof * dof)
        .map(|ij| {
            let (i, j) = (ij / dof, ij % dof);
            fit.covariance[(at + i, at + j)] * gains[i] * gains[i] * gains[j] * gains[j]
        })
        .collect();
    // Each joint's torque over the loaded runs, from the fitted gains: what the load's share is of.
    for (_, current, _) in stacked.iter().filter(|s| s.2) {
        for (r, i) in current.iter().enumerate() {
            load_torque[r % dof].1 += (gains[r % dof] * i).powi(2);
        }
    }
    let load_torque_share: Vec<f64> =
        load_torque.iter().map(|(l, t)| if *t > 0.0 { (l / t).sqrt() } else { 0.0 }).collect();
    // What the model leaves unexplained on each joint, in torque: the residual in current units
    // times the gain, over every run, against the load's torque over the loaded runs.
    let residual = problem.residual(theta);
    let loaded_rows: usize = stacked.iter().filter(|s| s.2).map(|s| s.0.nrows()).sum();
    let load_over_unexplained: Vec<f64> = (0..dof)
        .map(|k| {
            let unexplained = residual.iter().skip(k).step_by(dof).map(|e| e * e).sum::<f64>() / (rows / dof) as f64;
            let load = load_torque[k].0 / (loaded_rows / dof).max(1) as f64;
            (load / (gains[k] * gains[k] * unexplained).max(f64::MIN_POSITIVE)).sqrt()
        })
        .collect();
    let load_params: Vec<(String, f64, f64)> = unknown
        .iter()
        .enumerate()
        .map(|(u, &c)| (format!("load.{}", LOAD_NAMES[c]), theta[p + u], fit.sigma_beta[p + u]))
        .collect();
    let fixed: Vec<bool> =
        (0..dof).map(|k| fixed(gains[k], gain_sigma[k], load_torque_share[k], load_over_unexplained[k])).collect();
    let judged = Judged { gains: &gains, sigma: &gain_sigma, share: &load_torque_share, over: &load_over_unexplained };
    let (reasons, warnings) = explain(model, judged, &unknown, load);
    Ok(GainFit {
        gain_sigma,
        gain_covariance,
        gains,
        beta: theta[..p].to_vec(),
        beta_sigma: fit.sigma_beta[..p].to_vec(),
        load: load_params,
        load_torque_share,
        load_over_unexplained,
        fixed,
        fit,
        reasons,
        warnings,
    })
}

/// A datasheet has one finite, non-zero gain per joint, each with a finite, non-negative σ;
/// checked before the calibration's fit, so that a bad one is refused at once.
pub fn check_datasheet(datasheet: &[(f64, f64)], joints: &[String]) -> Result<(), GainsError> {
    if datasheet.len() != joints.len() {
        return Err(GainsError::BadDatasheet(format!("{} given for {} joints", datasheet.len(), joints.len())));
    }
    if let Some((j, (k, s))) =
        datasheet.iter().enumerate().find(|(_, (k, s))| !(k.is_finite() && *k != 0.0 && s.is_finite() && *s >= 0.0))
    {
        return Err(GainsError::BadDatasheet(format!(
            "{}'s is {k} ± {s}: a gain must be finite and non-zero, its σ finite and non-negative",
            joints[j]
        )));
    }
    Ok(())
}

/// Gains from a datasheet, each `(k, σ)`, checked against the load's: where the load fixes a gain
/// ([`fixed`]) its own value is kept, and a datasheet value more than 3 combined σ away is a
/// warning (a wrong datasheet, a wrong current scale, or a load that was not what was declared);
/// where it does not, the datasheet's value and σ are taken.
pub fn with_datasheet(fit: &GainFit, datasheet: &[(f64, f64)], joints: &[String]) -> Result<Checked, GainsError> {
    check_datasheet(datasheet, joints)?;
    let dof = joints.len();
    let (mut gains, mut sigma, mut taken) = (fit.gains.clone(), fit.gain_sigma.clone(), vec![false; dof]);
    let mut covariance = fit.gain_covariance.clone();
    let (mut reasons, mut warnings) = (Vec::new(), Vec::new());
    for (j, &(k, s)) in datasheet.iter().enumerate() {
        let z = (fit.gains[j] - k) / (fit.gain_sigma[j].powi(2) + s * s).sqrt();
        let (joint, datasheet, load) = (joints[j].clone(), [k, s], [fit.gains[j], fit.gain_sigma[j]]);
        match fit.fixed[j] {
            true if z.abs() > 3.0 => warnings.push(Concern::DatasheetDisagrees { joint, datasheet, load, z }),
            true => reasons.push(Choice::DatasheetAgrees { joint, datasheet, load, z }),
            false => {
                (gains[j], sigma[j], taken[j]) = (k, s, true);
                // A datasheet's error is its own, independent of the fit's.
                for i in 0..dof {
                    (covariance[i * dof + j], covariance[j * dof + i]) = (0.0, 0.0);
                }
                covariance[j * dof + j] = s * s;
                reasons.push(Choice::DatasheetUsed { joint, datasheet, load });
            }
        }
    }
    Ok(Checked { gains, sigma, covariance, from_datasheet: taken, reasons, warnings })
}

/// The gains to use after [`with_datasheet`]: each with its σ, whether it is the datasheet's, and
/// what the check found.
pub struct Checked {
    pub gains: Vec<f64>,
    pub sigma: Vec<f64>,
    /// Row-major, joints × joints.
    pub covariance: Vec<f64>,
    pub from_datasheet: Vec<bool>,
    pub reasons: Vec<Choice>,
    pub warnings: Vec<Concern>,
}

/// Steps of the fit in current units, at most this many; each one forms the stacked Jacobian
/// and its Gram matrix.
const MARQUARDT_STEPS: usize = 50;

/// The damping of the first step, relative to the Gram matrix's diagonal (Marquardt's scaling):
/// small, so that a well-posed problem takes Gauss–Newton's step from the start.
const FIRST_DAMPING: f64 = 1e-6;

/// A step that does not lower the cost at this damping lowers it nowhere: the fit is at a
/// minimum to rounding.
const MOST_DAMPING: f64 = 1e12;

/// The fit has converged when a step lowers the cost by less than this share of it.
const COST_TOLERANCE: f64 = 1e-12;

/// The drive-gain problem in current units: the stacked regressor `x` (the torque's `q`
/// parameters, then one current column per joint) and the known load's torque `y`, row for row.
struct CurrentUnits<'a> {
    x: &'a Mat<f64>,
    y: &'a [f64],
    dof: usize,
    q: usize,
}

impl CurrentUnits<'_> {
    /// The problem refitted in current units: each row's residual `cⱼ τ̂ − i` with `cⱼ = 1/kⱼ`, where
    /// the torque-unit problem `x θ = y` (columns: the torque's `q` parameters, then `−diag(i)`) has the
    /// residual `kⱼ` times as large. In torque units a joint whose current the model explains poorly
    /// lowers that residual by lowering its gain: the least squares shrink the gain toward zero by
    /// `l²/(l² + 2u²)` for a load torque `l` and an unexplained torque `u` (the real KUKA's first joint
    /// came out at 17 % of its gain). In current units the unexplained current is the same whatever the
    /// gain, and only the load's current sets it: the errors-in-variables model of currents measured
    /// with noise. Solved by Levenberg–Marquardt from the torque-unit fit `start`; returns the Jacobian at the
    /// optimum and the target `J θ* − e*`, whose least squares are `θ*` with the optimum's residual,
    /// so that [`fit_stacked`] gives its σ (the sandwich of the linearised problem) and conditioning.
    fn solve_from(&self, start: &[f64]) -> (Mat<f64>, Vec<f64>) {
        let (dof, q) = (self.dof, self.q);
        let largest = start[q..].iter().fold(0.0f64, |m, k| m.max(k.abs()));
        let mut theta: Vec<f64> = start[..q].to_vec();
        theta.extend(start[q..].iter().map(|k| 1.0 / k.abs().max(1e-3 * largest)));
        let (mut j, mut e) = self.linearised(&theta);
        let mut damping = FIRST_DAMPING;
        for _ in 0..MARQUARDT_STEPS {
            let now = cost(&e);
            let Some((next, lowered)) = self.damped_step(&j, &e, &theta, &mut damping) else { break };
            let moved = (q..q + dof).map(|i| ((next[i] - theta[i]) / theta[i]).abs()).fold(0.0, f64::max);
            theta = next;
            (j, e) = self.linearised(&theta);
            if moved < 1e-10 || now - lowered <= COST_TOLERANCE * now {
                break;
            }
        }
        let z = linear_target(&j, &theta, &e);
        (j, z)
    }

    /// Levenberg–Marquardt's step from `theta`: `(JᵀJ + λ diag(JᵀJ)) δ = −Jᵀe`, with `λ` raised
    /// tenfold until the cost falls and lowered tenfold after. The damping is what lets a joint
    /// whose gain the load does not fix converge: its gain and the parameters only it moves
    /// trade against each other at no cost, so Gauss–Newton's undamped step along that direction
    /// is arbitrary, and halving it (the first method) crawled through all its steps at a
    /// ten-thousandth of a step each. The new point and its cost; `None` when no damping lowers
    /// the cost.
    fn damped_step(&self, j: &Mat<f64>, e: &[f64], theta: &[f64], damping: &mut f64) -> Option<(Vec<f64>, f64)> {
        let now = cost(e);
        let gram = j.transpose() * j;
        let descent: Vec<f64> = (0..j.ncols()).map(|c| -dense::dot(j.col_as_slice(c), e)).collect();
        while *damping <= MOST_DAMPING {
            let damped = Mat::from_fn(gram.nrows(), gram.ncols(), |a, b| match a == b {
                true => gram[(a, b)] * (1.0 + *damping),
                false => gram[(a, b)],
            });
            let trial = dense::solve_gram(damped.as_ref(), &descent, dense::Unseen::Pinned)
                .map(|step| theta.iter().zip(&step).map(|(t, s)| t + s).collect::<Vec<f64>>());
            if let Some(trial) = trial {
                let lowered = cost(&self.residual(&trial));
                if lowered < now {
                    *damping = (*damping / 10.0).max(f64::EPSILON);
                    return Some((trial, lowered));
                }
            }
            *damping *= 10.0;
        }
        None
    }

    /// Each row's residual in current units at `theta` (the torque's `q` parameters, then `cⱼ =
    /// 1/kⱼ`): `cⱼ (x θ − y) − i`, the current being `−x` in the row's gain column.
    fn residual(&self, theta: &[f64]) -> Vec<f64> {
        self.residual_of(theta, &self.torques(theta))
    }

    /// [`CurrentUnits::residual`] from the rows' torques at `theta`.
    fn residual_of(&self, theta: &[f64], torques: &[f64]) -> Vec<f64> {
        let (dof, q) = (self.dof, self.q);
        let currents: Vec<&[f64]> = (0..dof).map(|j| self.x.col_as_slice(q + j)).collect();
        torques.iter().enumerate().map(|(r, t)| theta[q + r % dof] * t + currents[r % dof][r]).collect()
    }

    /// The model's torque on every row beyond the known load's: `x θ − y` over the torque's
    /// columns. Summed a column at a time, as `x` is stored: the fit's steps and their
    /// trials evaluate it hundreds of times on a calibration's tens of thousands of rows.
    fn torques(&self, theta: &[f64]) -> Vec<f64> {
        let mut torques: Vec<f64> = self.y.iter().map(|v| -v).collect();
        for (c, t) in theta.iter().enumerate().take(self.q) {
            torques.iter_mut().zip(self.x.col_as_slice(c)).for_each(|(sum, x)| *sum += x * t);
        }
        torques
    }

    /// The Jacobian of [`CurrentUnits::residual`] at `theta`, and that residual.
    fn linearised(&self, theta: &[f64]) -> (Mat<f64>, Vec<f64>) {
        let (x, dof, q) = (self.x, self.dof, self.q);
        let torques = self.torques(theta);
        let j = Mat::<f64>::from_fn(x.nrows(), q + dof, |r, c| match c < q {
            true => theta[q + r % dof] * x[(r, c)],
            false if c - q == r % dof => torques[r],
            false => 0.0,
        });
        (j, self.residual_of(theta, &torques))
    }

    /// The fit at the total-least-squares estimate `theta` (torque units: the parameters, then the
    /// gains): the problem linearised in current units there, as [`CurrentUnits::solve_from`] linearises it
    /// at its own optimum, for the conditioning; its σ the sandwich of that linearisation on the
    /// residual at `theta`.
    fn at_total_least_squares(&self, theta: &[f64], base: &BaseParameters, block: usize) -> Result<Fit, GainsError> {
        let (dof, q) = (self.dof, self.q);
        let mut point: Vec<f64> = theta[..q].to_vec();
        point.extend(theta[q..].iter().map(|k| 1.0 / k));
        let (j, e) = self.linearised(&point);
        let z = linear_target(&j, &point, &e);
        let mut fit = fit_stacked(&j, &z, dof, base, Method::Ols, block)?;
        let gram = j.transpose() * &j;
        let bread = dense::inverse(gram.as_ref()).ok_or(GainsError::NoTotalLeastSquares)?;
        fit.covariance = sandwich_covariance(&j, &e, dof, block, &bread);
        fit.sigma_beta = dense::standard_deviations(fit.covariance.as_ref());
        fit.sigma_percent = fit.sigma_beta.iter().zip(&point).map(|(s, b)| 100.0 * s / b.abs()).collect();
        fit.beta = point;
        Ok(fit)
    }
}

/// The sum of squares of a residual.
fn cost(e: &[f64]) -> f64 {
    e.iter().map(|v| v * v).sum()
}

/// `J θ − e`: the target whose least squares on `J` is `θ` at a stationary point, with the
/// residual `e`, so that [`fit_stacked`] gives the linearised problem's σ and conditioning.
fn linear_target(j: &Mat<f64>, theta: &[f64], e: &[f64]) -> Vec<f64> {
    let mut target: Vec<f64> = e.iter().map(|v| -v).collect();
    for (c, t) in theta.iter().enumerate() {
        target.iter_mut().zip(j.col_as_slice(c)).for_each(|(sum, x)| *sum += x * t);
    }
    target
}

/// Total least squares of `x θ = y` (Golub and Van Loan): the smallest correction of `[x y]` in
/// Frobenius norm that makes the system consistent, from the right singular vector of the
/// smallest singular value. Columns are scaled to unit norm first, so that N·m, amperes and the
/// load's torque weigh alike; the singular vectors come from the small triangular factor of a QR,
/// not from the tall matrix. `None` when that vector has no component along `y`.
fn total_least_squares(x: &Mat<f64>, y: &[f64]) -> Option<Vec<f64>> {
    let (m, n) = (x.nrows(), x.ncols());
    let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|a| a * a).sum::<f64>().sqrt().max(f64::MIN_POSITIVE);
    let mut norms: Vec<f64> = (0..n).map(|c| norm(&mut (0..m).map(|r| x[(r, c)]))).collect();
    norms.push(norm(&mut y.iter().copied()));
    let a = Mat::<f64>::from_fn(m, n + 1, |r, c| if c < n { x[(r, c)] } else { y[r] } / norms[c]);
    let r = a.qr().thin_R().to_owned();
    let r = Mat::from_fn(n + 1, n + 1, |i, j| if j >= i { r[(i, j)] } else { 0.0 });
    let v = dense::weakest_direction(r.as_ref())?;
    if v[n].abs() < 1e-12 {
        return None;
    }
    Some((0..n).map(|c| -v[c] / v[n] * norms[n] / norms[c]).collect())
}

/// How a model fitted by least squares on `data`'s torque `kⱼ iⱼ` moves with the gains: per
/// joint j, `∂β/∂ln kⱼ`, the fit of joint j's torque alone (the other joints' rows zero), with the
/// joint weights `method` gives the whole torque. A gain's error scales its joint's torque, and a
/// model fitted on it takes up part of that scale: what a later diagnosis sees of the error is the
/// rest (`diagnose::gain_share`). Exact for least squares; for a physically consistent fit whose
/// constraints hold with margin, the same to first order.
pub fn beta_per_gain(
    model: &Model,
    base: &BaseParameters,
    data: &Preprocessed,
    gains: &[f64],
    method: Method,
) -> Result<Vec<Vec<f64>>, EstimateError> {
    let dof = model.dof();
    let (w, current) = stack(model, base, data);
    let torque: Vec<f64> = current.iter().enumerate().map(|(r, i)| i * gains[r % dof]).collect();
    // Least squares weighs every joint alike; only WLS needs a fit for its weights.
    let weights = match method {
        Method::Ols => vec![1.0; dof],
        Method::Wls => fit_stacked(&w, &torque, dof, base, method, 1)?.joint_weights,
    };
    let weighted = Mat::<f64>::from_fn(w.nrows(), w.ncols(), |r, c| w[(r, c)] * weights[r % dof]);
    let rhs = Mat::<f64>::from_fn(w.nrows(), dof, |r, j| if r % dof == j { torque[r] * weights[j] } else { 0.0 });
    let solved = weighted.qr().solve_lstsq(&rhs);
    Ok((0..dof).map(|j| (0..w.ncols()).map(|c| solved[(c, j)]).collect()).collect())
}

/// `B`'s columns of body `b`'s ten parameters (`p × 10`, row-major).
fn base_map_of_body(base: &BaseParameters, b: usize) -> Vec<f64> {
    let big_p = base.num_params;
    let columns = body_params(b);
    (0..base.rank).flat_map(|i| columns.clone().map(move |c| base.b[i * big_p + c])).collect()
}

/// Column `c` of the `p × 10` map `b_body`.
fn column(b_body: &[f64], p: usize, c: usize) -> Vec<f64> {
    (0..p).map(|i| b_body[i * PER_BODY + c]).collect()
}

/// An orthonormal basis, grown one vector at a time (Gram–Schmidt).
#[derive(Default)]
struct Span(Vec<Vec<f64>>);

impl Span {
    /// `v` less its projection on the span, and that part's norm over `v`'s (0 for a zero `v`).
    fn outside(&self, mut v: Vec<f64>) -> (Vec<f64>, f64) {
        let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        for e in &self.0 {
            let d: f64 = v.iter().zip(e).map(|(a, b)| a * b).sum();
            v.iter_mut().zip(e).for_each(|(a, b)| *a -= d * b);
        }
        let left = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        (v, if norm > 0.0 { left / norm } else { 0.0 })
    }

    /// Add `v` where more than `tolerance` of it (relative) lies outside; whether it was added.
    fn add(&mut self, v: Vec<f64>, tolerance: f64) -> bool {
        let (outside, share) = self.outside(v);
        if share <= tolerance {
            return false;
        }
        let n = outside.iter().map(|x| x * x).sum::<f64>().sqrt();
        self.0.push(outside.iter().map(|x| x / n).collect());
        true
    }
}

/// Those of `candidates` (columns of `b_body`) that are independent of the ones before them: the
/// load's unknowns that the torque can tell apart. A column within 10⁻⁸ of the others' span
/// (relative) adds nothing the others do not.
fn independent_columns(b_body: &[f64], p: usize, candidates: Vec<usize>) -> Vec<usize> {
    let mut span = Span::default();
    candidates.into_iter().filter(|&c| span.add(column(b_body, p, c), 1e-8)).collect()
}

/// Whether the known part of the load, `B_b π_k`, has a part outside the span of the unknowns'
/// columns `B_b,u`: otherwise the load's unknowns take it up exactly and the gains are free
/// (the fit sets them to zero). `Err` holds the relative residual.
fn separable(b_body: &[f64], p: usize, known: &[Option<f64>; PER_BODY], unknown: &[usize]) -> Result<(), f64> {
    let mut span = Span::default();
    for &c in unknown {
        span.add(column(b_body, p, c), 0.0);
    }
    let image: Vec<f64> =
        (0..p).map(|i| (0..PER_BODY).filter_map(|c| known[c].map(|x| x * b_body[i * PER_BODY + c])).sum()).collect();
    let (_, residual) = span.outside(image);
    if residual > SEPARABLE {
        Ok(())
    } else {
        Err(residual)
    }
}

/// A known load whose base-parameter image lies within this relative distance of its unknowns'
/// span is taken up by them: far above round-off (10⁻¹⁵), far below any load that acts apart.
const SEPARABLE: f64 = 1e-6;

fn names_of(columns: impl Iterator<Item = usize>) -> String {
    columns.map(|c| LOAD_NAMES[c]).collect::<Vec<_>>().join(", ")
}

/// The names of the stacked problem's unknowns: the base parameters, the load's, the gains.
fn fitted_names(model: &Model, base: &BaseParameters, unknown: &[usize]) -> Vec<String> {
    let load = unknown.iter().map(|&c| format!("load.{}", LOAD_NAMES[c]));
    let gains = model.joint_names().into_iter().map(|j| format!("k.{j}"));
    base.names.iter().cloned().chain(load).chain(gains).collect()
}

/// A known load's torque under this share of a joint's torque leaves that joint's gain to what the
/// joint shares with the others: the reasons say so.
pub const LOAD_SHARE_FLOOR: f64 = 0.01;

/// A gain known to worse than this share of it is not fixed by the load: a datasheet gives ±10 %,
/// which is two such σ.
pub const NOT_FIXED: f64 = 0.05;

/// Whether a gain is fixed by the load ([`NOT_FIXED`]): its σ, and on a joint the load loads
/// (`share` of its torque at least [`LOAD_SHARE_FLOOR`]) the load's torque over what the model
/// leaves unexplained (`over`). The gain comes from matching the load's current, and a residual
/// `u` that correlates with the load's torque `l` moves it by up to `‖u‖/‖l‖` (Cauchy–Schwarz),
/// which the noise's σ does not count: on the real KUKA a load 2 × the unexplained torque left a
/// gain 68 % off with a σ of 5 %. A joint the load does not load is fixed, if at all, through the
/// parameters it shares, and its σ says how well.
pub fn fixed(gain: f64, sigma: f64, share: f64, over: f64) -> bool {
    let loaded = share >= LOAD_SHARE_FLOOR;
    sigma <= NOT_FIXED * gain.abs() && (!loaded || over * NOT_FIXED >= 1.0)
}

/// The least mass, at the same place, that would fix a gain that `mass` does not on a joint the
/// load loads ([`fixed`]): the load's torque, and with it both the ratio to the unexplained torque
/// and the σ's inverse, grows in proportion to the mass (σ the more slowly where the model's
/// error, not the noise, sets it: a lower bound then).
fn least_mass(mass: f64, gain: f64, sigma: f64, over: f64) -> f64 {
    let by_ratio = 1.0 / (NOT_FIXED * over.max(f64::MIN_POSITIVE));
    let by_sigma = sigma / (NOT_FIXED * gain.abs());
    mass * by_ratio.max(by_sigma).max(1.0)
}

/// The reasons (each gain with its σ, the load's share of each joint's torque, the joints the load
/// barely reaches) and the warnings (the gains it does not fix).
/// Per joint, a gain as the fit judged it: its value and σ, the load's share of its joint's
/// torque, and the load over what the model leaves unexplained there.
struct Judged<'a> {
    gains: &'a [f64],
    sigma: &'a [f64],
    share: &'a [f64],
    over: &'a [f64],
}

fn explain(model: &Model, judged: Judged, unknown: &[usize], load: &KnownLoad) -> (Vec<Choice>, Vec<Concern>) {
    let Judged { gains, sigma, share, over } = judged;
    let joints = model.joint_names();
    let each = (0..joints.len())
        .map(|j| JointGain {
            joint: joints[j].clone(),
            gain: gains[j],
            sigma: sigma[j],
            load_share: share[j],
            over_unexplained: over[j],
        })
        .collect();
    let estimated = unknown.iter().map(|&c| LOAD_NAMES[c].to_string()).collect();
    let mut reasons =
        vec![Choice::DriveGainsFitted { mass_kg: load.mass, body: load.body.clone(), estimated, joints: each }];
    let loose: Vec<LooseGain> = (0..joints.len())
        .filter(|&j| !fixed(gains[j], sigma[j], share[j], over[j]))
        .map(|j| LooseGain {
            joint: joints[j].clone(),
            relative_sigma: sigma[j] / gains[j].abs(),
            over_unexplained: over[j],
            mass_that_fixes_kg: (share[j] >= LOAD_SHARE_FLOOR)
                .then(|| least_mass(load.mass, gains[j], sigma[j], over[j])),
        })
        .collect();
    let mut warnings = Vec::new();
    if !loose.is_empty() {
        warnings.push(Concern::GainsNotFixed { joints: loose, max_sigma: NOT_FIXED, min_over: 1.0 / NOT_FIXED });
    }
    let barely: Vec<String> =
        joints.iter().zip(share).filter(|(_, s)| **s < LOAD_SHARE_FLOOR).map(|(j, _)| j.clone()).collect();
    if !barely.is_empty() {
        reasons.push(Choice::LoadBarelyLoads { floor: LOAD_SHARE_FLOOR, joints: barely });
    }
    (reasons, warnings)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn load(body: &str) -> KnownLoad {
        KnownLoad { body: body.into(), mass: 0.3, com: None, inertia: None }
    }

    /// Errors in every column of `[x y]`, equal once each is scaled to unit norm, as TLS assumes:
    /// TLS recovers θ where least squares attenuates it by the noise's share of each regressor's
    /// variance (regression dilution, here 1/1.09).
    #[test]
    fn total_least_squares_is_not_diluted_by_noisy_regressors() {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let (m, theta, noise): (usize, [f64; 2], f64) = (20_000, [2.0, -1.0], 0.3);
        let mut normal = || -> f64 { (0..12).map(|_| rng.random_range(0.0..1.0)).sum::<f64>() - 6.0 };
        let truth: Vec<[f64; 2]> = (0..m).map(|_| [normal(), normal()]).collect();
        let y_noise = noise * (theta[0] * theta[0] + theta[1] * theta[1]).sqrt();
        let y: Vec<f64> = truth.iter().map(|r| theta[0] * r[0] + theta[1] * r[1] + y_noise * normal()).collect();
        let x = Mat::<f64>::from_fn(m, 2, |r, c| truth[r][c] + noise * normal());
        let tls = total_least_squares(&x, &y).unwrap();
        let ls = x.qr().solve_lstsq(Mat::<f64>::from_fn(m, 1, |r, _| y[r]));
        for c in 0..2 {
            assert!((tls[c] - theta[c]).abs() < 0.03 * theta[c].abs(), "TLS {tls:?}");
            assert!((ls[(c, 0)] - theta[c]).abs() > 0.05 * theta[c].abs(), "LS was not diluted: {:?}", ls[(c, 0)]);
        }
    }

    #[test]
    fn a_load_is_refused_by_what_is_wrong_with_it() {
        let model = crate::arash_asist();
        let error = |l: KnownLoad| l.validate(&model).unwrap_err().to_string();
        assert!(error(load("gripper")).contains("body `gripper`, which the robot does not have"));
        assert!(error(KnownLoad { mass: 0.0, ..load("insertion_carriage") }).contains("mass must be positive"));
        let no_com = KnownLoad { inertia: Some([1e-3; 6]), ..load("insertion_carriage") };
        assert!(error(no_com).contains("about its centre of mass, which must then be given"));
        // Ixx beyond Iyy + Izz: no body has that.
        let flat = KnownLoad { com: Some([0.0; 3]), inertia: Some([1.0, 0.1, 0.1, 0.0, 0.0, 0.0]), ..load("coupler") };
        assert!(error(flat).contains("is not physical"));
        assert_eq!(load("insertion_carriage").validate(&model).unwrap(), 4);
    }

    /// A point mass at c has, about the origin, the inertia m(|c|²E − ccᵀ) and first moments mc.
    #[test]
    fn a_known_centre_and_inertia_move_to_the_frame_origin_by_parallel_axes() {
        let (m, c) = (2.0, [0.1, -0.2, 0.3]);
        let known = KnownLoad { body: "b".into(), mass: m, com: Some(c), inertia: Some([0.0; 6]) }.parameters();
        let sq = c.iter().map(|x| x * x).sum::<f64>();
        let expected = [
            m,
            m * c[0],
            m * c[1],
            m * c[2],
            m * (sq - c[0] * c[0]),
            m * (sq - c[1] * c[1]),
            m * (sq - c[2] * c[2]),
            -m * c[0] * c[1],
            -m * c[0] * c[2],
            -m * c[1] * c[2],
        ];
        for (got, want) in known.iter().zip(expected) {
            assert!((got.unwrap() - want).abs() < 1e-15);
        }
        let mass_only = KnownLoad { body: "b".into(), mass: m, com: None, inertia: None };
        assert_eq!(mass_only.parameters().iter().filter(|p| p.is_some()).count(), 1);
    }

    /// Columns (1, 0), (2, 0), (0, 1) of a 2 × 10 map: the second adds nothing to the first.
    #[test]
    fn dependent_load_columns_are_left_out_and_a_known_part_in_their_span_is_refused() {
        let mut b = vec![0.0; 2 * PER_BODY];
        (b[0], b[1], b[PER_BODY + 2]) = (1.0, 2.0, 1.0);
        assert_eq!(independent_columns(&b, 2, vec![0, 1, 2]), vec![0, 2]);
        let mut known = [None; PER_BODY];
        known[0] = Some(1.0);
        // The known column (1, 0) lies in the span of column 1, (2, 0): refused.
        assert!(separable(&b, 2, &known, &[1]).is_err());
        assert!(separable(&b, 2, &known, &[2]).is_ok());
    }
}
