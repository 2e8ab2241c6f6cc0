//! Identification of a robot logged in closed loop, from the loop simulated with the current
//! estimate: IDIM-IV (Janot, Vandanjon and Gautier, "A generic instrumental variable approach for
//! industrial robot identification", IEEE TCST 22(1), 2014) and DIDIM (Gautier, Janot and
//! Vandanjon, "A new closed-loop output error method for parameter identification of robot
//! dynamics", IEEE TCST 21(2), 2013).
//!
//! In closed loop the controller turns the encoders' noise (and the torque noise, through the
//! plant) into torque, so the regressor built from the measured positions is correlated with the
//! error of the torque it explains, and least squares is biased. `Z` is the same regressor built
//! from a simulation of the same loop: the same reference, the same controller, and a plant with
//! the current estimate β̂. That simulation carries none of the log's noise, but tracks the
//! measured motion closely. Each iteration solves
//!
//!   IDIM-IV: β̂ₖ₊₁ = (Zₖᵀ W)⁻¹ Zₖᵀ τ   (Z instruments the measured regressor W)
//!   DIDIM:   β̂ₖ₊₁ = (Zₖᵀ Zₖ)⁻¹ Zₖᵀ τ  (the simulated torque Z β fitted to the measured one)
//!
//! Both start from least squares and stop when no β̂ moves by more than
//! [`IvOptions::tolerance`] of its σ (the papers report two to five iterations).
//!
//! The simulated signals go through exactly the preprocessing the log went through (the same
//! period, cut-offs and decimation), so `Z` and `W` hold the same samples filtered alike.
//!
//! The physically consistent forms solve the consistent problem, after the plain iteration has
//! settled `Z`, on the instrumented regressor `P_Z W` for IV (two-stage least squares: with as
//! many instruments as parameters it is the IV estimate) and on `Z` itself for DIDIM.

use crate::signal::options::PreprocessOptions;
use faer::Mat;

use crate::base_parameters::BaseParameters;
use crate::consistent::{identify_consistent, ConsistentOptions};
use crate::control::Desired;
use crate::data::Data;
use crate::dense;
use crate::dynamics::forward_dynamics;
use crate::model::Model;
use crate::model_file::IdentifyMethod;
use crate::signal::estimate::{self, stack, stack_full, Fit};
use crate::signal::preprocess::{preprocess, PreprocessError, Preprocessed};

pub use crate::control::logged::{LoggedController, LoggedControllerError};

/// What a closed-loop log holds beyond `(t, q, τ)`: the reference the controller followed at each
/// sample (`samples × dof` each, SI) and the controller.
#[derive(Clone, Copy, Debug)]
pub struct ClosedLoop<'a> {
    pub q_des: &'a [f64],
    pub qd_des: &'a [f64],
    pub qdd_des: &'a [f64],
    pub controller: &'a LoggedController,
}

impl<'a> ClosedLoop<'a> {
    /// The loop of a reference held as `[q_des, qd_des, qdd_des]` and its controller.
    pub fn new(reference: &'a [Vec<f64>; 3], controller: &'a LoggedController) -> Self {
        Self { q_des: &reference[0], qd_des: &reference[1], qdd_des: &reference[2], controller }
    }
}

/// Settings of the IDIM-IV and DIDIM iteration, with their defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct IvOptions {
    /// Most simulations of the loop (each one IV solve).
    pub max_iterations: usize,
    /// Stop when no β̂ moves by more than this fraction of its σ.
    pub tolerance: f64,
}

impl Default for IvOptions {
    fn default() -> Self {
        // The papers see convergence in 2–5 iterations; a tenth of σ is far below what the
        // estimate can resolve.
        Self { max_iterations: 10, tolerance: 0.1 }
    }
}

impl IvOptions {
    pub fn validate(&self) -> Result<(), ClosedLoopError> {
        if self.max_iterations == 0 {
            return Err(ClosedLoopError::Setting("max_iterations must be at least 1".into()));
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(ClosedLoopError::Setting(format!(
                "tolerance must be a positive number, not {}",
                self.tolerance
            )));
        }
        Ok(())
    }
}

/// Why IDIM-IV could not run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ClosedLoopError {
    #[error("closed-loop identification: {0}")]
    Controller(#[from] LoggedControllerError),
    #[error("closed-loop identification: {0}")]
    Setting(String),
    #[error(
        "closed-loop identification: the reference's `{name}` has {got} values, the log {expected} ({samples} samples × {dof} joints)"
    )]
    Reference { name: &'static str, got: usize, expected: usize, samples: usize, dof: usize },
    #[error("closed-loop identification: the reference's `{name}` is not finite at sample {sample}")]
    ReferenceNotFinite { name: &'static str, sample: usize },
    #[error(
        "closed-loop identification: the loop simulated with the estimate of iteration {iteration} diverged at t = {time:.3} s \
         ({why}); the estimate is too far from the robot for the simulation to follow the log (try more or richer \
         data, or the least-squares methods)"
    )]
    Diverged { iteration: usize, time: f64, why: String },
    #[error(
        "closed-loop identification: the simulated regressor does not determine the parameters (its normal matrix \
         is singular at iteration {iteration}): the simulated loop does not excite what the log does"
    )]
    Singular { iteration: usize },
    #[error(
        "closed-loop identification: the loop simulated with the estimate of iteration {iteration} cannot be \
         preprocessed as the log was ({source}); the estimate does not reproduce the logged motion (try more or \
         richer data, or the least-squares methods)"
    )]
    SimulatedLog { iteration: usize, source: PreprocessError },
}

/// The IDIM-IV or DIDIM estimate, with the iteration's history.
#[derive(Clone, Debug)]
pub struct IvFit {
    /// β̂, σ and the training metrics (the prediction `W β̂` against the filtered torque).
    pub fit: Fit,
    /// The last simulated regressor (`Z`, stacked like `W`), for the consistent solve.
    pub instruments: Mat<f64>,
    /// Iterations run, and the largest move of any β̂ in its σ at the last one.
    pub iterations: usize,
    pub last_change_sigma: f64,
    /// Whether the last move was within [`IvOptions::tolerance`].
    pub converged: bool,
    /// The iterations whose estimate did not simulate, and why: their `Z` came from the nearest
    /// physically consistent model.
    pub detours: Vec<String>,
}

/// Check the reference against the log's length and the robot's joints.
fn check_reference(closed_loop: &ClosedLoop, samples: usize, dof: usize) -> Result<(), ClosedLoopError> {
    let channels = [("q_des", closed_loop.q_des), ("qd_des", closed_loop.qd_des), ("qdd_des", closed_loop.qdd_des)];
    for (name, x) in channels {
        if x.len() != samples * dof {
            return Err(ClosedLoopError::Reference { name, got: x.len(), expected: samples * dof, samples, dof });
        }
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            return Err(ClosedLoopError::ReferenceNotFinite { name, sample: i / dof });
        }
    }
    Ok(())
}

/// The loop simulated over the log's samples `t`: positions and the torque the controller
/// applied (`samples × dof` each). The plant is `model` with the parameter vector `params` (its
/// product with the regressor is the model's torque: β̂ placed on the independent columns will
/// do, since `M`, `C` and `g` are linear in π); the controller sees the exact state (the
/// instruments carry no noise), its torque is held over each sample (zero-order hold), and the
/// plant is integrated by RK4 in steps of at most a millisecond, or, where a joint's dry friction
/// follows sign(q̇), by `DryFriction`'s set-valued steps of at most a tenth of one.
pub fn simulate_loop(
    model: &Model,
    params: &[f64],
    closed_loop: &ClosedLoop,
    t: &[f64],
) -> Result<(Vec<f64>, Vec<f64>), (f64, String)> {
    let n = model.dof();
    let samples = t.len();
    let mut controller = closed_loop.controller.build(model).map_err(|e| (t[0], e.to_string()))?;
    let mut data = Data::new(model);
    let mut plant = PlantState { q: closed_loop.q_des[..n].to_vec(), qd: closed_loop.qd_des[..n].to_vec() };
    let mut q_out = Vec::with_capacity(samples * n);
    let mut tau_out = Vec::with_capacity(samples * n);
    let mut tau = vec![0.0; n];
    let mut stages = Stages::new(n);
    let mut dry = DryFriction::of(model, &mut data, params, &plant.q);
    for i in 0..samples {
        let range = i * n..(i + 1) * n;
        let desired = Desired {
            q: &closed_loop.q_des[range.clone()],
            qd: &closed_loop.qd_des[range.clone()],
            qdd: &closed_loop.qdd_des[range],
        };
        let dt = if i + 1 < samples { t[i + 1] - t[i] } else { t[i] - t[i.saturating_sub(1)] };
        controller.step(dt, &plant.q, &plant.qd, &desired, &mut tau);
        if let Some(x) = tau.iter().find(|x| !x.is_finite()) {
            return Err((t[i], format!("the controller commanded {x}")));
        }
        q_out.extend_from_slice(&plant.q);
        tau_out.extend_from_slice(&tau);
        if i + 1 == samples {
            break;
        }
        match &mut dry {
            None => {
                let substeps = (dt / RK4_STEP_S).ceil().max(1.0) as usize;
                let h = dt / substeps as f64;
                for _ in 0..substeps {
                    stages.rk4(model, &mut data, params, &tau, h, &mut plant).map_err(|why| (t[i], why))?;
                }
            }
            Some(dry) => {
                let substeps = (dt / DryFriction::MAX_STEP_S).ceil().max(1.0) as usize;
                let h = dt / substeps as f64;
                for _ in 0..substeps {
                    dry.step(model, &mut data, &tau, h, &mut plant).map_err(|why| (t[i], why))?;
                }
            }
        }
        if plant.q.iter().chain(&plant.qd).any(|x| !x.is_finite()) {
            return Err((t[i], "the state is no longer finite".into()));
        }
    }
    Ok((q_out, tau_out))
}

/// The simulated plant's positions and velocities.
struct PlantState {
    q: Vec<f64>,
    qd: Vec<f64>,
}

/// The longest RK4 step of the simulated plant.
const RK4_STEP_S: f64 = 1e-3;

/// RK4 is stable for ẋ = −λx while hλ ≤ 2.785 (the real axis of its stability region).
const RK4_STABLE_REAL: f64 = 2.785;

/// A plant whose dry friction follows sign(q̇) on some joints, stepped as a set-valued law
/// (Moreau's time-stepping): over a step h the velocity is the one that minimises
/// ½ (v − v_free)ᵀ M (v − v_free) + Σ_k h f_c,k |v_k|, where v_free is what every other force gives.
/// A joint sticks (v_k = 0 exactly) wherever the rest cannot overcome its friction. Stepped
/// explicitly, as RK4 does, sign(q̇) flips every step where the plant should stick, and the
/// simulated loop chatters: IDIM-IV's instruments on a sign-law closed loop then predicted the
/// insertion at −154 % (bench/sign_closed_loop.py).
struct DryFriction {
    /// `params` with the set-valued joints' f_c taken out (the other forces).
    others: Vec<f64>,
    /// h-free impulse bound per joint: f_c where the joint's law is sign(q̇) and f_c > 0, else 0.
    friction: Vec<f64>,
    mass: Vec<f64>,
    /// The torque of every other force at zero acceleration, and the zero acceleration.
    bias: Vec<f64>,
    zeros: Vec<f64>,
}

impl DryFriction {
    /// The longest set-valued step: first order, so ten per millisecond keep it as close to the
    /// plant as RK4's one (the independent generator steps its plant alike at 10 kHz).
    const MAX_STEP_S: f64 = 1e-4;

    /// `None` where no joint's dry friction is a positive f_c under sign(q̇), or under a
    /// tanh(q̇/v) so sharp that RK4's millisecond cannot follow it: near zero speed the law is a
    /// damping f_c / v, and where h f_c / (v M_kk) (M at `q`) passes RK4's stability bound on the
    /// real axis, 2.785, the explicit step chatters as under sign(q̇); the law is then stepped as
    /// its limit. (The laws chosen from a sign-law closed loop come out that sharp: 2·10⁻⁵ m/s on
    /// its insertion.)
    fn of(model: &Model, data: &mut Data, params: &[f64], q: &[f64]) -> Option<Self> {
        let (n, layout) = (model.dof(), model.layout());
        let mut mass = vec![0.0; n * n];
        crate::dynamics::mass_matrix(model, data, q, params, &mut mass);
        let mut others = params.to_vec();
        let mut friction = vec![0.0; n];
        for (k, f) in friction.iter_mut().enumerate() {
            let fc = params[layout.coulomb(k)];
            let set_valued = match model.coulomb_laws.shape(k) {
                crate::model::CoulombShape::Sign => true,
                crate::model::CoulombShape::Tanh { epsilon } => {
                    RK4_STEP_S * fc / (epsilon * mass[k * n + k]) > RK4_STABLE_REAL
                }
            };
            if set_valued && fc > 0.0 {
                *f = fc;
                others[layout.coulomb(k)] = 0.0;
            }
        }
        friction.iter().any(|f| *f > 0.0).then(|| Self {
            others,
            friction,
            mass: vec![0.0; n * n],
            bias: vec![0.0; n],
            zeros: vec![0.0; n],
        })
    }

    fn step(
        &mut self,
        model: &Model,
        data: &mut Data,
        tau: &[f64],
        h: f64,
        plant: &mut PlantState,
    ) -> Result<(), String> {
        let PlantState { q, qd } = plant;
        let n = q.len();
        // One mass matrix per step: its Cholesky factor both checks it (an estimate that is not
        // physical cannot drive the plant) and gives the inverse the friction's impulses need.
        crate::dynamics::inverse_dynamics(model, data, q, qd, &self.zeros, &self.others, &mut self.bias);
        crate::dynamics::mass_matrix(model, data, q, &self.others, &mut self.mass);
        let mass = Mat::from_fn(n, n, |i, j| self.mass[i * n + j]);
        let inverse = dense::spd_inverse(mass.as_ref())
            .ok_or_else(|| "the mass matrix is not positive definite; the parameters are not physical".to_string())?;
        let force: Vec<f64> = tau.iter().zip(&self.bias).map(|(t, b)| t - b).collect();
        let acceleration = dense::times(inverse.as_ref(), &force);
        let free: Vec<f64> = (0..n).map(|k| qd[k] + h * acceleration[k]).collect();
        let velocity = stick_or_slip(&inverse, &free, &self.friction.iter().map(|f| h * f).collect::<Vec<_>>());
        qd.copy_from_slice(&velocity);
        for (q, qd) in q.iter_mut().zip(qd.iter()) {
            *q += h * qd;
        }
        Ok(())
    }
}

/// The velocity `v = v_free − M⁻¹ λ` with each friction impulse λ_k in [−impulse_k, impulse_k]
/// that stops joint k where it can: projected Gauss–Seidel on λ, which converges for the
/// positive-definite M⁻¹.
fn stick_or_slip(inverse: &Mat<f64>, free: &[f64], impulse: &[f64]) -> Vec<f64> {
    let n = free.len();
    let mut lambda = vec![0.0; n];
    let largest = impulse.iter().copied().fold(0.0, f64::max);
    for _ in 0..1000 {
        let mut moved = 0.0f64;
        for k in 0..n {
            if impulse[k] == 0.0 {
                continue;
            }
            let v_k = free[k] - (0..n).map(|j| inverse[(k, j)] * lambda[j]).sum::<f64>();
            let next = (lambda[k] + v_k / inverse[(k, k)]).clamp(-impulse[k], impulse[k]);
            moved = moved.max((next - lambda[k]).abs());
            lambda[k] = next;
        }
        if moved <= 1e-14 * largest {
            break;
        }
    }
    (0..n).map(|k| free[k] - (0..n).map(|j| inverse[(k, j)] * lambda[j]).sum::<f64>()).collect()
}

/// RK4's stage buffers for `ẋ = [q̇, q̈(q, q̇, τ)]`.
struct Stages {
    q: Vec<f64>,
    qd: Vec<f64>,
    k_q: [Vec<f64>; 4],
    k_qd: [Vec<f64>; 4],
}

impl Stages {
    fn new(n: usize) -> Self {
        Self {
            q: vec![0.0; n],
            qd: vec![0.0; n],
            k_q: std::array::from_fn(|_| vec![0.0; n]),
            k_qd: std::array::from_fn(|_| vec![0.0; n]),
        }
    }

    fn rk4(
        &mut self,
        model: &Model,
        data: &mut Data,
        params: &[f64],
        tau: &[f64],
        h: f64,
        plant: &mut PlantState,
    ) -> Result<(), String> {
        let PlantState { q, qd } = plant;
        let n = q.len();
        for stage in 0..4 {
            let a = [0.0, 0.5, 0.5, 1.0][stage] * h;
            for k in 0..n {
                let (dq, dqd) = if stage == 0 { (0.0, 0.0) } else { (self.k_q[stage - 1][k], self.k_qd[stage - 1][k]) };
                self.q[k] = q[k] + a * dq;
                self.qd[k] = qd[k] + a * dqd;
            }
            self.k_q[stage].copy_from_slice(&self.qd);
            forward_dynamics(model, data, &self.q, &self.qd, tau, params, &mut self.k_qd[stage])
                .map_err(|e| e.to_string())?;
        }
        for k in 0..n {
            let (kq, kqd) = (&self.k_q, &self.k_qd);
            q[k] += h / 6.0 * (kq[0][k] + 2.0 * kq[1][k] + 2.0 * kq[2][k] + kq[3][k]);
            qd[k] += h / 6.0 * (kqd[0][k] + 2.0 * kqd[1][k] + 2.0 * kqd[2][k] + kqd[3][k]);
        }
        Ok(())
    }
}

/// The preprocessing `pre` was made with, fixed: what the simulated log must go through so that
/// its regressor matches the log's sample for sample.
fn same_preprocessing(pre: &Preprocessed, options: &PreprocessOptions) -> PreprocessOptions {
    PreprocessOptions {
        periods: if pre.periodic { None } else { Some(1) },
        period_s: pre.period_s,
        cutoff_hz: Some(pre.cutoff_hz),
        friction_cutoff_hz: Some(pre.friction_cutoff_hz),
        order: pre.order,
        decimate: pre.decimate,
        ..options.clone()
    }
}

/// β placed on the independent columns of a full parameter vector.
fn placed(base: &BaseParameters, beta: &[f64]) -> Vec<f64> {
    let mut full = vec![0.0; base.num_params];
    for (&j, b) in base.independent.iter().zip(beta) {
        full[j] = *b;
    }
    full
}

/// What is solved on the simulated loop's regressor `Z` at each iteration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Estimator {
    /// IDIM-IV: `Z` instruments the measured regressor, `β = (ZᵀW)⁻¹ Zᵀ τ`.
    InstrumentalVariables,
    /// DIDIM (Gautier, Janot and Vandanjon, IEEE TCST 21(2), 2013): the simulated loop's torque
    /// `Z β` is fitted to the measured torque, `β = (ZᵀZ)⁻¹ Zᵀ τ`, an output error through the
    /// closed loop. Nothing measured enters the regressor, so its noise cannot either.
    OutputError,
}

impl Estimator {
    /// The estimator of a closed-loop method (`None` for the others).
    pub fn of(method: IdentifyMethod) -> Option<Self> {
        match method {
            IdentifyMethod::IdimIv | IdentifyMethod::IdimIvConsistent => Some(Self::InstrumentalVariables),
            IdentifyMethod::Didim | IdentifyMethod::DidimConsistent => Some(Self::OutputError),
            IdentifyMethod::Ols | IdentifyMethod::Wls | IdentifyMethod::Consistent => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::InstrumentalVariables => "IDIM-IV",
            Self::OutputError => "DIDIM",
        }
    }

    /// The regressor `Z` is paired with: the measured `W` for IV, `Z` itself for DIDIM.
    fn partner<'a>(self, w: &'a Mat<f64>, z: &'a Mat<f64>) -> &'a Mat<f64> {
        match self {
            Self::InstrumentalVariables => w,
            Self::OutputError => z,
        }
    }

    /// The full regressor whose consistent fit against the log's filtered torque is this
    /// estimator's with the constraints: `P_Z W_full` (two-stage least squares) for IV, with
    /// `w_full` the log's own ([`stack_full`]), and `Z_full = Z B` for DIDIM.
    pub fn full(self, base: &BaseParameters, w_full: &Mat<f64>, z: &Mat<f64>) -> Mat<f64> {
        match self {
            Self::InstrumentalVariables => instrumented(w_full, z),
            Self::OutputError => {
                let (p, big_p) = (base.rank, base.num_params);
                z * Mat::<f64>::from_fn(p, big_p, |i, j| base.b[i * big_p + j])
            }
        }
    }
}

/// Where a closed-loop fit starts: the log's times, the log as preprocessed (with the options
/// that preprocessed it, which the simulated logs get too), and the least-squares fit on it.
pub struct ClosedLoopStart<'a> {
    pub t: &'a [f64],
    pub pre: &'a Preprocessed,
    pub preprocess: &'a PreprocessOptions,
    pub fit: &'a Fit,
}

/// How a closed-loop fit iterates: the estimator, its iterations, and the consistent fit a
/// detour takes.
pub struct ClosedLoopSettings<'a> {
    pub estimator: Estimator,
    pub iv: &'a IvOptions,
    pub consistent: &'a ConsistentOptions,
}

/// IDIM-IV or DIDIM (`settings.estimator`) on the log of `start`, from its least-squares fit.
pub fn closed_loop_fit(
    model: &Model,
    base: &BaseParameters,
    closed_loop: &ClosedLoop,
    start: ClosedLoopStart,
    settings: ClosedLoopSettings,
) -> Result<IvFit, ClosedLoopError> {
    let ClosedLoopStart { t, pre, preprocess: options, fit: start } = start;
    let ClosedLoopSettings { estimator, iv, consistent } = settings;
    iv.validate()?;
    check_reference(closed_loop, t.len(), model.dof())?;
    closed_loop.controller.build(model)?;
    let (w, tau) = stack(model, base, pre);
    let fixed = same_preprocessing(pre, options);
    let instruments = |params: &[f64], iteration: usize| -> Result<Mat<f64>, ClosedLoopError> {
        let (q_sim, tau_sim) = simulate_loop(model, params, closed_loop, t)
            .map_err(|(time, why)| ClosedLoopError::Diverged { iteration, time, why })?;
        let simulated = preprocess(t, &q_sim, &tau_sim, model.dof(), &fixed)
            .map_err(|source| ClosedLoopError::SimulatedLog { iteration, source })?;
        // The log's resting rows are left out of the instruments too: DIDIM regresses the
        // measured torque, zero there, on them.
        let (mut z, mut unused) = stack(model, base, &simulated);
        estimate::leave_out_rests(pre, &mut z, &mut unused, pre.settled.clone());
        Ok(z)
    };
    // An estimate whose mass matrix is not positive definite somewhere on the way cannot drive a
    // simulation. Its instruments then come from the physically consistent model nearest the
    // data (the consistent fit of the current, instrumented, problem), which always simulates.
    let mut detours = Vec::new();
    // The log's full regressor, stacked only when a detour first needs it.
    let w_full = std::cell::OnceCell::new();
    let mut simulated = |beta: &[f64], z: Option<&Mat<f64>>, iteration: usize| -> Result<Mat<f64>, ClosedLoopError> {
        match instruments(&placed(base, beta), iteration) {
            Err(ClosedLoopError::Diverged { time, why, .. }) => {
                let w_full = w_full.get_or_init(|| {
                    let (mut w, mut tau) = stack_full(model, pre);
                    estimate::leave_out_rests(pre, &mut w, &mut tau, pre.settled.clone());
                    w
                });
                let projected = z.map(|z| estimator.full(base, w_full, z));
                let physical = identify_consistent(model, projected.as_ref().unwrap_or(w_full), &tau, consistent)
                    .map_err(|e| ClosedLoopError::Diverged { iteration, time, why: format!("{why}; {e}") })?;
                detours.push(format!("{iteration} (t = {time:.3} s: {why})"));
                instruments(&physical.params, iteration)
            }
            other => other,
        }
    };
    let (mut beta, mut sigma) = (start.beta.clone(), start.sigma_beta.clone());
    let mut z = simulated(&beta, None, 1)?;
    let mut iteration = 1;
    loop {
        let partner = estimator.partner(&w, &z);
        let products = cross(&z, partner, &tau);
        let next = iv_solve(&products, partner).ok_or(ClosedLoopError::Singular { iteration })?;
        let change =
            next.iter().zip(&beta).zip(&sigma).map(|((a, b), s)| (a - b).abs() / s.max(1e-300)).fold(0.0, f64::max);
        beta = next;
        let fit = iv_fit(model, base, pre, Instrumented { z: &z, w: &w, tau: &tau }, &beta, &products.0, start);
        sigma = fit.sigma_beta.clone();
        let converged = change <= iv.tolerance;
        if converged || iteration >= iv.max_iterations {
            return Ok(IvFit {
                fit,
                instruments: z,
                iterations: iteration,
                last_change_sigma: change,
                converged,
                detours,
            });
        }
        iteration += 1;
        z = simulated(&beta, Some(&z), iteration)?;
    }
}

/// `(Zᵀ W)⁻¹ Zᵀ τ` from the products `(ZᵀW, Zᵀτ)`, with W's columns scaled to unit norm for
/// the solve; `None` when singular.
fn iv_solve((zw, zt): &(Mat<f64>, Mat<f64>), w: &Mat<f64>) -> Option<Vec<f64>> {
    let p = zw.ncols();
    // β = D x with D = diag(1 / ‖W_j‖): Zᵀ W D has columns of like size.
    let scale: Vec<f64> = (0..p).map(|j| 1.0 / w.col(j).norm_l2().max(f64::MIN_POSITIVE)).collect();
    let scaled = Mat::from_fn(p, p, |i, j| zw[(i, j)] * scale[j]);
    let x = dense::solve(scaled.as_ref(), zt.as_ref())?;
    Some((0..p).map(|j| x[(j, 0)] * scale[j]).collect())
}

/// `Zᵀ W` and `Zᵀ τ` (a column).
fn cross(z: &Mat<f64>, w: &Mat<f64>, tau: &[f64]) -> (Mat<f64>, Mat<f64>) {
    let tau_mat = Mat::<f64>::from_fn(tau.len(), 1, |i, _| tau[i]);
    (z.transpose() * w, z.transpose() * &tau_mat)
}

/// The instrumental-variable problem: instruments `z`, regressor `w` and torque `tau`, row for
/// row.
struct Instrumented<'a> {
    z: &'a Mat<f64>,
    w: &'a Mat<f64>,
    tau: &'a [f64],
}

/// The estimate `beta` as a [`Fit`]: σ from the sandwich `(ZᵀX)⁻¹ Ω (XᵀZ)⁻¹` (`zx` is ZᵀX, X
/// the partner: W for IV, Z for DIDIM), Ω the long-run covariance of Z's scores on the unfiltered residual of
/// the measured motion (the torque's noise), in blocks as least squares takes them
/// ([`estimate::fit`]). The training metrics are the measured motion's prediction `W β`.
fn iv_fit(
    model: &Model,
    base: &BaseParameters,
    pre: &Preprocessed,
    Instrumented { z, w, tau }: Instrumented,
    beta: &[f64],
    zx: &Mat<f64>,
    start: &Fit,
) -> Fit {
    let dof = model.dof();
    let predicted = estimate::apply(w, beta);
    let residual: Vec<f64> = tau.iter().zip(&predicted).map(|(t, p)| t - p).collect();
    let (m, p) = (w.nrows(), w.ncols());
    let sigma_p2 = residual.iter().map(|e| e * e).sum::<f64>() / (m - p) as f64;
    let meat_residual = estimate::unfiltered_residual(model, pre, &base.independent, beta);
    let bread = dense::inverse(zx.as_ref()).unwrap_or_else(|| Mat::from_fn(p, p, |_, _| f64::NAN));
    let block = ((2.0 * pre.rate_hz() / pre.cutoff_hz).ceil() as usize).max(1);
    let covariance = estimate::sandwich_covariance(z, &meat_residual, dof, block, &bread);
    let sigma_beta = dense::standard_deviations(covariance.as_ref());
    let sigma_percent = sigma_beta.iter().zip(beta).map(|(s, b)| 100.0 * s / b.abs()).collect();
    Fit {
        method: estimate::Method::Ols,
        beta: beta.to_vec(),
        sigma_beta,
        covariance,
        sigma_percent,
        sigma_p2,
        joint_weights: vec![1.0; dof],
        condition_number: start.condition_number,
        metrics: estimate::joint_metrics(tau, &predicted, dof),
        determination: start.determination.iter().zip(beta).map(|(d, b)| d.at(*b)).collect(),
    }
}

/// `w_full` projected on the instruments' span, `P_Z W_full`: the consistent problem on it is
/// two-stage least squares, the IV estimate with the consistent constraints.
fn instrumented(w_full: &Mat<f64>, z: &Mat<f64>) -> Mat<f64> {
    let (p, big_p) = (z.ncols(), w_full.ncols());
    let gram = z.transpose() * z;
    let mut rhs = z.transpose() * w_full;
    let solved = match dense::cholesky(gram.as_ref()) {
        Some(l) => {
            dense::cholesky_solve(&l, rhs.as_mut());
            rhs
        }
        None => dense::solve(gram.as_ref(), rhs.as_ref()).unwrap_or_else(|| Mat::zeros(p, big_p)),
    };
    z * solved
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// The set-valued step satisfies the law's optimality conditions, checked directly: with
    /// λ = M (v_free − v), a joint that moves is braked by its whole impulse against its motion,
    /// and a stuck one by at most its impulse. Random positive-definite M, some joints free.
    #[test]
    fn a_stick_or_slip_step_brakes_each_joint_as_dry_friction_does() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (mut stuck, mut slipping) = (0, 0);
        for _ in 0..200 {
            let n = 3;
            let a = Mat::from_fn(n, n, |_, _| rng.random_range(-1.0..1.0));
            let mass = &a * a.transpose() + Mat::<f64>::identity(n, n) * faer::Scale(0.1);
            let inverse = dense::inverse(mass.as_ref()).unwrap();
            let free: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
            let impulse: Vec<f64> =
                (0..n).map(|k| if k == 2 && rng.random_bool(0.3) { 0.0 } else { rng.random_range(0.0..1.0) }).collect();
            let v = stick_or_slip(&inverse, &free, &impulse);
            let dv: Vec<f64> = free.iter().zip(&v).map(|(f, v)| f - v).collect();
            let lambda = dense::times(mass.as_ref(), &dv);
            for k in 0..n {
                let tolerance = 1e-9 * (1.0 + impulse[k]);
                assert!(lambda[k].abs() <= impulse[k] + tolerance, "joint {k}: λ {} beyond {}", lambda[k], impulse[k]);
                if v[k].abs() > 1e-7 {
                    slipping += 1;
                    assert!(
                        (lambda[k] - impulse[k] * v[k].signum()).abs() <= tolerance,
                        "joint {k} slips at {}, λ {} impulse {}",
                        v[k],
                        lambda[k],
                        impulse[k]
                    );
                } else {
                    stuck += 1;
                }
            }
        }
        assert!(stuck > 50 && slipping > 50, "{stuck} stuck, {slipping} slipping: both cases must be exercised");
    }
}
