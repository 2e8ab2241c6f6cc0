//! Identification on simulated data with known truth: torques from the model plus noise.

mod common;

// The consistent fit's SDP calls BLAS and LAPACK: arash's own, linked by naming the crate.
use arash_blas_lapack as _;
use arash_core::base_parameters::BaseParameterOptions;
use arash_core::choices::{Choice, Concern};
use arash_core::consistent::{identify_consistent_bounded, ExtraBound};
use arash_core::identify::{ConsistentOptions, PreprocessOptions};
use arash_core::signal::estimate::{fit, fit_stacked, ols_beta_and_metrics, EstimateError, Method};
use arash_core::signal::preprocess::{preprocess, Preprocessed};
use arash_core::*;
use common::*;
use faer::Mat;
use rand::RngExt;

/// A random 5-harmonic Fourier trajectory with period `period`, scaled into 80 % of the joint
/// range and the speed limits: returns (q, q̇, q̈) at time t.
#[derive(Clone)]
struct Fourier {
    w: f64,
    centre: Vec<f64>,
    a: Vec<[f64; 5]>,
    b: Vec<[f64; 5]>,
}

impl Fourier {
    fn random(model: &Model, period: f64, rng: &mut ChaCha8Rng) -> Self {
        let w = 2.0 * std::f64::consts::PI / period;
        let mut f = Fourier { w, centre: vec![], a: vec![], b: vec![] };
        for joint in &model.joints {
            let mut a = [0.0; 5];
            let mut b = [0.0; 5];
            for l in 0..5 {
                a[l] = rng.random_range(-1.0..1.0) / (l + 1) as f64;
                b[l] = rng.random_range(-1.0..1.0) / (l + 1) as f64;
            }
            // Worst-case amplitude and speed of the unscaled series bound the scale.
            let amp: f64 = (0..5).map(|l| a[l].hypot(b[l])).sum();
            let speed: f64 = (0..5).map(|l| a[l].hypot(b[l]) * w * (l + 1) as f64).sum();
            let half_range = 0.4 * (joint.upper - joint.lower);
            let scale = (half_range / amp).min(0.8 * joint.velocity / speed);
            a.iter_mut().chain(b.iter_mut()).for_each(|c| *c *= scale);
            f.centre.push(0.5 * (joint.upper + joint.lower));
            f.a.push(a);
            f.b.push(b);
        }
        f
    }

    fn at(&self, t: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = self.centre.len();
        let (mut q, mut qd, mut qdd) = (self.centre.clone(), vec![0.0; n], vec![0.0; n]);
        for j in 0..n {
            for l in 0..5 {
                let wl = self.w * (l + 1) as f64;
                let (s, c) = (wl * t).sin_cos();
                q[j] += self.a[j][l] * s + self.b[j][l] * c;
                qd[j] += wl * (self.a[j][l] * c - self.b[j][l] * s);
                qdd[j] += -wl * wl * (self.a[j][l] * s + self.b[j][l] * c);
            }
        }
        (q, qd, qdd)
    }
}

/// The "true" robot: each CAD body with its mass and rotational inertia scaled by up to ±30 % and
/// its centre of mass moved by up to 1 cm (so it stays physically consistent), plus friction and
/// cable stiffness.
fn true_parameters(model: &Model, rng: &mut ChaCha8Rng) -> Vec<f64> {
    use arash_core::spatial::{params_from_com, rotational_inertia, Mat3, Vec3};
    let mut pi = model.cad_parameters();
    for b in 0..model.bodies.len() {
        let p = &pi[10 * b..10 * b + 10];
        let m = p[0];
        let c = Vec3::new(p[1], p[2], p[3]) / m;
        let i_com = rotational_inertia(p) - (Mat3::identity() * c.dot(&c) - c * c.transpose()) * m;
        let shift =
            Vec3::new(rng.random_range(-0.01..0.01), rng.random_range(-0.01..0.01), rng.random_range(-0.01..0.01));
        let new = params_from_com(
            m * (1.0 + rng.random_range(-0.3..0.3)),
            &(c + shift),
            &(i_com * (1.0 + rng.random_range(-0.3..0.3))),
        );
        pi[10 * b..10 * b + 10].copy_from_slice(&new);
    }
    let fo = model.layout().friction().start;
    pi[fo..fo + 6].copy_from_slice(&[0.02, 0.03, 0.015, 0.025, 3.0, 0.4]);
    pi[model.layout().stiffnesses()].copy_from_slice(&[0.05, 0.08, 20.0]);
    pi
}

const NOISE: [f64; 3] = [0.003, 0.003, 0.05];

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    // Box–Muller: enough for test noise.
    let (u, v): (f64, f64) = (rng.random_range(1e-12..1.0), rng.random_range(0.0..1.0));
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

#[test]
fn ols_and_wls_recover_beta_within_three_sigma() {
    let model = arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default()).unwrap();
    let (mut within, mut total) = ([0usize; 2], 0usize);
    for seed in 0..8 {
        let counts = three_sigma_counts(&model, &base, seed);
        within[0] += counts[0];
        within[1] += counts[1];
        total += base.rank;
    }
    for (method, count) in ["OLS", "WLS"].iter().zip(within) {
        assert!(count as f64 >= 0.95 * total as f64, "{method}: only {count}/{total} within 3σ");
    }
}

/// For one random truth and trajectory: how many β̂ lie within 3σ̂ of β, for OLS and WLS.
/// The stacked reduced regressor of a random trajectory of `model` at exact states, the torque of
/// a random truth with white noise on it, and that truth's β.
fn exact_states_log(model: &Model, base: &BaseParameters, seed: u64) -> (Mat<f64>, Vec<f64>, Vec<f64>) {
    let mut rng = rng(100 + seed);
    let pi = true_parameters(model, &mut rng);
    let mut beta_true = vec![0.0; base.rank];
    base.project(&pi, &mut beta_true);
    let traj = Fourier::random(model, 15.0, &mut rng);
    let (samples, n, p) = (3000, model.dof(), base.rank);
    let mut data = Data::new(model);
    let (mut y, mut y_r) = (vec![0.0; n * model.num_params()], vec![0.0; n * p]);
    let mut w = Mat::<f64>::zeros(samples * n, p);
    let mut tau = Vec::with_capacity(samples * n);
    for s in 0..samples {
        let (q, qd, qdd) = traj.at(s as f64 * 15.0 / samples as f64);
        regressor(model, &mut data, &q, &qd, &qdd, &mut y);
        base.reduce(&y, &mut y_r);
        for k in 0..n {
            for c in 0..p {
                w[(s * n + k, c)] = y_r[k * p + c];
            }
            let exact: f64 = (0..p).map(|c| y_r[k * p + c] * beta_true[c]).sum();
            tau.push(exact + NOISE[k] * gaussian(&mut rng));
        }
    }
    (w, tau, beta_true)
}

fn three_sigma_counts(model: &Model, base: &BaseParameters, seed: u64) -> [usize; 2] {
    // Exact states, white torque noise: the setting in which eq. 16's σ is the true spread.
    let (w, tau, beta_true) = exact_states_log(model, base, seed);
    let (n, p) = (model.dof(), base.rank);
    // The corrected semi-normal equations agree with a Householder QR solve of the same system.
    let ols = fit_stacked(&w, &tau, n, base, Method::Ols, 1).unwrap();
    let rhs = Mat::<f64>::from_fn(tau.len(), 1, |i, _| tau[i]);
    let qr_beta = faer::prelude::SolveLstsq::solve_lstsq(&w.qr(), &rhs);
    let scale = ols.beta.iter().map(|b| b.abs()).fold(0.0, f64::max);
    for i in 0..p {
        assert!(
            (ols.beta[i] - qr_beta[(i, 0)]).abs() <= 1e-9 * scale,
            "β{i}: {} vs QR {}",
            ols.beta[i],
            qr_beta[(i, 0)]
        );
    }
    [Method::Ols, Method::Wls].map(|method| {
        let fit = fit_stacked(&w, &tau, n, base, method, 1).unwrap();
        assert!(fit.metrics.fp_percent.iter().all(|fp| *fp > 50.0), "{:?}", fit.metrics.fp_percent);
        (0..p).filter(|&i| (fit.beta[i] - beta_true[i]).abs() <= 3.0 * fit.sigma_beta[i]).count()
    })
}

/// The cut-off search reads only β and each joint's FP% of its many candidate fits, and takes
/// them without the covariance: they must be the full fit's to the bit (so that the search
/// chooses as it did), and a stack the fit refuses must be refused too (a candidate that cannot
/// be fitted is not one).
#[test]
fn the_searchs_ols_is_the_full_fits_beta_and_metrics_and_refuses_what_it_refuses() {
    let model = arash_core::arash_asist();
    let base = BaseParameters::compute(&model, &Default::default()).unwrap();
    let (w, tau, _) = exact_states_log(&model, &base, 5);
    let dof = model.dof();
    let noisy: Vec<f64> = tau.iter().enumerate().map(|(i, t)| t + 1e-3 * ((i * 7919) % 101) as f64 / 101.0).collect();
    let full = fit_stacked(&w, &noisy, dof, &base, Method::Ols, 7).unwrap();
    let (beta, metrics) = ols_beta_and_metrics(&w, &noisy, dof, &base).unwrap();
    assert_eq!(beta, full.beta);
    assert_eq!(metrics.fp_percent, full.metrics.fp_percent);
    assert_eq!(metrics.rms, full.metrics.rms);
    // A column the data never excite, and too few rows: both refused alike.
    let mut dead = w.clone();
    (0..dead.nrows()).for_each(|r| dead[(r, 0)] = 0.0);
    let both = |w: &Mat<f64>, tau: &[f64]| {
        let searched = ols_beta_and_metrics(w, tau, dof, &base).map(|_| ()).unwrap_err().to_string();
        let fitted = fit_stacked(w, tau, dof, &base, Method::Ols, 7).map(|_| ()).unwrap_err().to_string();
        assert_eq!(searched, fitted);
    };
    both(&dead, &noisy);
    let few = w.subrows(0, 3 * dof).to_owned();
    both(&few, &noisy[..3 * dof]);
}

/// What the table says sets each σ% is checked against regressing each column on the others
/// (faer's QR least squares, not the fit's Gram factor): the part left over, the largest
/// coefficient on unit columns, and the column's norm over the torque's on its largest joint.
#[test]
fn each_parameters_determination_is_what_regressing_its_column_on_the_others_leaves() {
    let model = arash_core::arash_asist();
    let base = BaseParameters::compute(&model, &Default::default()).unwrap();
    let (w, tau, _) = exact_states_log(&model, &base, 3);
    let fit = fit_stacked(&w, &tau, model.dof(), &base, Method::Ols, 1).unwrap();
    let p = base.rank;
    let norm = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>().sqrt();
    let column = |i: usize| (0..w.nrows()).map(|r| w[(r, i)]).collect::<Vec<f64>>();
    let mut collinear = 0;
    for i in 0..p {
        let others: Vec<usize> = (0..p).filter(|&j| j != i).collect();
        let rest = Mat::<f64>::from_fn(w.nrows(), p - 1, |r, c| w[(r, others[c])]);
        let target = Mat::<f64>::from_fn(w.nrows(), 1, |r, _| w[(r, i)]);
        let x = faer::prelude::SolveLstsq::solve_lstsq(&rest.qr(), &target);
        let left: Vec<f64> =
            (0..w.nrows()).map(|r| w[(r, i)] - (0..p - 1).map(|c| rest[(r, c)] * x[(c, 0)]).sum::<f64>()).collect();
        let apart = norm(&left) / norm(&column(i));
        let d = &fit.determination[i];
        // The Gram route loses κ²ε: a few parts in 10⁵ on the columns closest to the others'.
        assert!((d.apart - apart).abs() <= 1e-4 * apart + 1e-9, "β{i}: apart {} against {apart}", d.apart);
        let leans = (0..p - 1).max_by(|&a, &b| {
            let on_unit = |c: usize| (x[(c, 0)] * norm(&column(others[c]))).abs();
            on_unit(a).total_cmp(&on_unit(b))
        });
        assert_eq!(d.leans_on, leans.map(|c| others[c]), "β{i}");
        let dof = model.dof();
        let on_joint = |x: &[f64], k: usize| norm(&x.iter().skip(k).step_by(dof).copied().collect::<Vec<_>>());
        let ratio = (0..dof).map(|k| on_joint(&column(i), k) / on_joint(&tau, k)).fold(0.0, f64::max);
        assert!((d.column_over_torque - ratio).abs() <= 1e-9 * ratio, "β{i}: {} against {ratio}", d.column_over_torque);
        assert!((d.torque_share - fit.beta[i].abs() * ratio).abs() <= 1e-9 * d.torque_share, "β{i}");
        collinear += usize::from(apart < arash_core::model_file::COLLINEAR_APART);
    }
    // ARASH:ASiST's two rocker first moments differ only through small yaw-coupling terms.
    assert!(collinear >= 1, "no collinear column among {p}");
}

fn simulated_log(
    model: &Model,
    pi: &[f64],
    traj: &Fourier,
    periods: usize,
    rng: &mut ChaCha8Rng,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (fs, n) = (1000.0, model.dof());
    let total = (15.0 * fs) as usize * periods;
    let mut data = Data::new(model);
    let (mut t, mut q_log, mut tau_log) = (Vec::new(), Vec::new(), Vec::new());
    let mut tau = vec![0.0; n];
    for i in 0..total {
        let ti = i as f64 / fs;
        let (q, qd, qdd) = traj.at(ti);
        inverse_dynamics(model, &mut data, &q, &qd, &qdd, pi, &mut tau);
        t.push(ti);
        q_log.extend_from_slice(&q);
        tau_log.extend(tau.iter().enumerate().map(|(k, v)| v + NOISE[k] * gaussian(rng)));
    }
    (t, q_log, tau_log)
}

/// ARASH:ASiST with its base parameters, true parameters and a 15 s trajectory drawn from
/// `seed`, and the generator the rest of a test draws from.
fn drawn_truth(seed: u64) -> (Model, BaseParameters, Vec<f64>, Fourier, ChaCha8Rng) {
    let model = arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default()).unwrap();
    let mut rng = rng(seed);
    let pi = true_parameters(&model, &mut rng);
    let traj = Fourier::random(&model, 15.0, &mut rng);
    (model, base, pi, traj, rng)
}

/// The torque base parameters `beta` predict, and the true parameters `pi` give, at every 7th
/// millisecond of the first 15 s of `states` (q, q̇, q̈ at time t): the noise-free truth an
/// identified model is judged against. `fitted` is `model` with the Coulomb laws `beta` was fitted with (the file's, where they were
/// chosen from the data).
fn predicted_and_true(
    model: &Model,
    fitted: &Model,
    base: &BaseParameters,
    pi: &[f64],
    beta: &[f64],
    states: impl Fn(f64) -> (Vec<f64>, Vec<f64>, Vec<f64>),
) -> Vec<([f64; 3], [f64; 3])> {
    let mut data = Data::new(model);
    let (mut y, mut y_r) = (vec![0.0; 3 * model.num_params()], vec![0.0; 3 * base.rank]);
    (0..15_000)
        .step_by(7)
        .map(|i| {
            let (q, qd, qdd) = states(i as f64 / 1000.0);
            regressor(fitted, &mut data, &q, &qd, &qdd, &mut y);
            base.reduce(&y, &mut y_r);
            let (mut predicted, mut exact) = ([0.0; 3], [0.0; 3]);
            inverse_dynamics(model, &mut data, &q, &qd, &qdd, pi, &mut exact);
            for (k, p) in predicted.iter_mut().enumerate() {
                *p = (0..base.rank).map(|c| y_r[k * base.rank + c] * beta[c]).sum();
            }
            (predicted, exact)
        })
        .collect()
}

#[test]
fn the_preprocessing_pipeline_and_ols_recover_the_model() {
    let (model, base, pi, traj, mut rng) = drawn_truth(22);
    let (t, q, tau) = simulated_log(&model, &pi, &traj, 4, &mut rng);
    let options = PreprocessOptions { periods: Some(4), ..Default::default() };
    let pre: Preprocessed = preprocess(&t, &q, &tau, 3, &options).unwrap();
    let fit = fit(&model, &base, &pre, Method::Ols).unwrap();
    // Predict the noise-free torque on the true (unfiltered) states of one period.
    let (mut worst, mut scale) = ([0.0f64; 3], [0.0f64; 3]);
    for (predicted, exact) in predicted_and_true(&model, &model, &base, &pi, &fit.beta, |t| traj.at(t)) {
        for k in 0..3 {
            worst[k] = worst[k].max((predicted[k] - exact[k]).abs());
            scale[k] = scale[k].max(exact[k].abs());
        }
    }
    for k in 0..3 {
        assert!(worst[k] < 0.02 * scale[k], "joint {k}: prediction off by {} of peak {}", worst[k], scale[k]);
    }
    assert!(fit.metrics.fp_percent.iter().all(|fp| *fp > 90.0), "FP% {:?}", fit.metrics.fp_percent);
}

#[test]
fn data_that_does_not_move_a_joint_is_refused_naming_the_parameters() {
    let model = arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default()).unwrap();
    let mut rng = rng(23);
    let traj = Fourier::random(&model, 15.0, &mut rng);
    let pi = true_parameters(&model, &mut rng);
    let options = PreprocessOptions { periods: Some(2), ..Default::default() };
    // An insertion that never moves is refused before any fit, by joint.
    let mut still = traj.clone();
    still.a[2] = [0.0; 5];
    still.b[2] = [0.0; 5];
    let (t, q, tau) = simulated_log(&model, &pi, &still, 2, &mut rng);
    let refused = preprocess(&t, &q, &tau, 3, &options).unwrap_err().to_string();
    assert!(refused.contains("joint 3 never moves"), "{refused}");
    // Signals that reach the fit without moving it (held at its start after preprocessing)
    // leave parameters undetermined, and the fit names them.
    let (t, q, tau) = simulated_log(&model, &pi, &traj, 2, &mut rng);
    let mut pre = preprocess(&t, &q, &tau, 3, &options).unwrap();
    let held = pre.q[2];
    for signal in [&mut pre.q, &mut pre.qd, &mut pre.qdd, &mut pre.qd_friction] {
        signal.iter_mut().skip(2).step_by(3).for_each(|v| *v = 0.0);
    }
    pre.q.iter_mut().skip(2).step_by(3).for_each(|v| *v = held);
    let err = fit(&model, &base, &pre, Method::Ols).unwrap_err();
    let text = err.to_string();
    assert!(matches!(err, EstimateError::NotExcited(_) | EstimateError::IllConditioned { .. }), "{text}");
    assert!(text.contains("insertion"), "the message should name the insertion parameters: {text}");
}

/// Two noisy periods of a drawn truth's log, averaged and decimated by 5: the model, its base
/// parameters, the true parameters and the preprocessed data the consistent fits are checked on.
fn two_periods_preprocessed(seed: u64) -> (Model, BaseParameters, Vec<f64>, Preprocessed) {
    let (model, base, pi, traj, mut rng) = drawn_truth(seed);
    let (t, q, tau) = simulated_log(&model, &pi, &traj, 2, &mut rng);
    let pre = preprocess(&t, &q, &tau, 3, &PreprocessOptions { periods: Some(2), decimate: 5, ..Default::default() })
        .unwrap();
    (model, base, pi, pre)
}

/// The unfiltered prediction, taken as the inverse dynamics of β placed on its columns, is the
/// regressor's columns (their Coulomb ones switched by the friction velocity) times β, under a
/// sign law and a smooth one.
#[test]
fn the_unfiltered_prediction_is_the_regressor_times_beta() {
    use arash_core::signal::estimate::{apply, coulomb_positions, put_coulomb, regressor_rows, unfiltered_prediction};
    let (model, base, _, pre) = two_periods_preprocessed(11);
    for laws in [CoulombLaws::undeclared(3), CoulombLaws::uniform(CoulombShape::Tanh { epsilon: 0.02 }, 3)] {
        let model = Model { coulomb_laws: laws, ..model.clone() };
        let beta: Vec<f64> = (0..base.rank).map(|i| 0.3 + (i as f64 * 0.7).sin()).collect();
        let rows: Vec<usize> = pre.settled.clone().collect();
        let mut w = regressor_rows(&model, &pre, &base.independent, &rows);
        let directions = pre.friction.directions(&model.coulomb_laws);
        put_coulomb(&mut w, 3, &coulomb_positions(&model, &base.independent), &directions, &rows);
        let reference = apply(&w, &beta);
        let ours = unfiltered_prediction(&model, &pre, &base.independent, &beta);
        let scale = reference.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
        let worst = ours.iter().zip(&reference).fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()));
        assert_eq!(ours.len(), reference.len());
        assert!(worst < 1e-12 * scale, "{worst} against {scale}");
    }
}

#[test]
fn consistent_identification_is_physical_and_fits_like_ols() {
    use arash_core::consistent::identify_consistent;
    use arash_core::physical::min_pseudo_inertia_eigenvalues;
    use arash_core::signal::estimate::{joint_metrics, stack_full};
    let (model, base, pi, pre) = two_periods_preprocessed(24);
    let ols = fit(&model, &base, &pre, Method::Ols).unwrap();
    let (w, tau_f) = stack_full(&model, &pre);
    let consistent = identify_consistent(&model, &w, &tau_f, &ConsistentOptions::default()).unwrap();
    // Checked independently of Clarabel's status: our own eigen-decomposition of each body.
    for (b, e) in min_pseudo_inertia_eigenvalues(&model, &consistent.params).iter().enumerate() {
        assert!(*e >= -1e-9, "body {} pseudo-inertia eigenvalue {e}", model.bodies[b].name);
    }
    assert!(consistent.params[model.layout().friction()].iter().all(|f| *f >= -1e-9));
    // Consistency costs almost nothing here: the truth is consistent.
    let predicted: Vec<f64> = arash_core::signal::estimate::apply(&w, &consistent.params);
    let metrics = joint_metrics(&tau_f, &predicted, 3);
    for k in 0..3 {
        assert!(metrics.fp_percent[k] > ols.metrics.fp_percent[k] - 1.0, "joint {k}: {metrics:?} vs {:?}", ols.metrics);
    }
    // And its base parameters agree with the truth about as well as OLS's do.
    let (mut beta_c, mut beta_true) = (vec![0.0; base.rank], vec![0.0; base.rank]);
    base.project(&consistent.params, &mut beta_c);
    base.project(&pi, &mut beta_true);
    let err = |b: &[f64]| b.iter().zip(&beta_true).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt();
    assert!(err(&beta_c) < 2.0 * err(&ols.beta) + 1e-6, "consistent {} vs OLS {}", err(&beta_c), err(&ols.beta));
}

/// The consistent problem with one extra column, `q̇·|q̇|` on the insertion rows, last in `w`
/// (at `index`); `scale` is the coefficient that moves its largest row by 0.5.
struct WithExtraColumn {
    model: Model,
    w: Mat<f64>,
    tau: Vec<f64>,
    extra: Vec<f64>,
    index: usize,
    scale: f64,
}

impl WithExtraColumn {
    fn new() -> Self {
        let (model, _, _, pre) = two_periods_preprocessed(25);
        let (w, tau) = arash_core::signal::estimate::stack_full(&model, &pre);
        let index = w.ncols();
        let fv = model.layout().viscous(2);
        let extra: Vec<f64> = (0..w.nrows()).map(|r| w[(r, fv)] * w[(r, fv)].abs()).collect();
        let scale = 0.5 * extra.iter().map(|e| e.abs()).fold(0.0, f64::max).recip();
        let w = Mat::<f64>::from_fn(w.nrows(), index + 1, |r, c| if c < index { w[(r, c)] } else { extra[r] });
        Self { model, w, tau, extra, index, scale }
    }

    fn torque_with(&self, c: f64) -> Vec<f64> {
        self.tau.iter().zip(&self.extra).map(|(t, e)| t + c * e).collect()
    }

    fn fit(&self, tau: &[f64], bound: ExtraBound) -> Vec<f64> {
        identify_consistent_bounded(&self.model, &self.w, tau, &ConsistentOptions::default(), &[bound]).unwrap().params
    }
}

/// An extra column with a physical sign (an effect a diagnosis found) keeps it in the consistent
/// fit even where least squares wants the other sign; a free one follows the data.
#[test]
fn a_signed_extra_column_keeps_its_sign_in_the_consistent_fit() {
    let x = WithExtraColumn::new();
    // A torque with −0.5 of the column: energy fed in.
    let tau = x.torque_with(-x.scale);
    let free = x.fit(&tau, ExtraBound::default());
    let signed = x.fit(&tau, ExtraBound { sign: Some(1.0), magnitude: None });
    let (p, scale) = (x.index, x.scale);
    assert!((free[p] + scale).abs() < 0.05 * scale, "free: {} against {}", free[p], -scale);
    assert!(signed[p] >= -1e-9 * scale, "signed: {}", signed[p]);
    let cost = |params: &[f64]| {
        let r = arash_core::signal::estimate::apply(&x.w, params);
        r.iter().zip(&tau).map(|(a, b)| (a - b).powi(2)).sum::<f64>()
    };
    assert!(cost(&signed) > cost(&free), "the sign must cost fit when the data want the other one");
}

/// A magnitude bound on an extra column holds where the data want more (the coefficient sits on
/// it, on the side the data pull to), and with a sign it bounds only that side.
#[test]
fn an_extra_columns_magnitude_bound_holds_where_the_data_want_more() {
    let x = WithExtraColumn::new();
    let (p, scale) = (x.index, x.scale);
    let cap = 0.4 * scale;
    for want in [scale, -scale] {
        let tau = x.torque_with(want);
        let free = x.fit(&tau, ExtraBound::default())[p];
        assert!((free - want).abs() < 0.05 * scale, "free: {free} against {want}");
        let capped = x.fit(&tau, ExtraBound { sign: None, magnitude: Some(cap) })[p];
        assert!((capped - cap.copysign(want)).abs() < 1e-3 * scale, "capped: {capped}, want {want}, cap {cap}");
        let positive = x.fit(&tau, ExtraBound { sign: Some(1.0), magnitude: Some(cap) })[p];
        let expected = if want > 0.0 { cap } else { 0.0 };
        assert!((positive - expected).abs() < 1e-3 * scale, "signed and capped: {positive}, want {want}");
    }
}

#[test]
fn a_model_file_is_judged_by_its_parameters_not_by_what_it_claims() {
    use arash_core::identify::{identify, Declared, IdentifyOptions, Log};
    use arash_core::model_file::{IdentifyMethod, ModelFile};
    let (model, base, pi, traj, mut rng) = drawn_truth(25);
    let (t, q, tau) = simulated_log(&model, &pi, &traj, 2, &mut rng);
    let mut options = IdentifyOptions::default();
    options.preprocess.periods = Some(2);
    options.preprocess.decimate = 5;
    let load = |value: &serde_json::Value| ModelFile::from_json(&value.to_string()).unwrap();
    for method in [IdentifyMethod::Consistent, IdentifyMethod::Ols] {
        let id = identify(
            Declared { model: &model, base: &base, urdf: ARASH_ASIST_URDF },
            Log { t: &t, q: &q, tau: &tau },
            method,
            &options,
        )
        .unwrap();
        let recomputed = id.recomputed_pseudo_inertia_eigenvalues(&model).unwrap();
        for (a, b) in recomputed.iter().zip(&id.fitted.min_pseudo_inertia_eigenvalue) {
            assert!((a - b).abs() <= 1e-9 * b.abs().max(1.0), "{method:?}: {a} recomputed, {b} written");
        }
        let file: serde_json::Value = serde_json::from_str(&id.to_json()).unwrap();
        let honest = load(&file).consistent_controller_parameters(&model);
        assert_eq!(honest.is_ok(), recomputed.iter().all(|e| *e >= -1e-9), "{method:?}: {honest:?}");

        // A mass of −2 kg (π̂), or −2 on the first inertial base parameter (β̂), the file still
        // claiming positive eigenvalues.
        let mut tampered = file.clone();
        match method {
            IdentifyMethod::Consistent => tampered["params"][0] = (-2.0).into(),
            _ => tampered["beta"][0] = (-2.0).into(),
        }
        tampered["min_pseudo_inertia_eigenvalue"] = serde_json::json!(vec![1.0; model.bodies.len()]);
        let err = load(&tampered).consistent_controller_parameters(&model).unwrap_err().to_string();
        eprintln!("{method:?}, tampered: {err}");
        assert!(err.contains("not physically consistent"), "{method:?}: {err}");
        if method == IdentifyMethod::Consistent {
            assert!(err.contains("`yaw_yoke`") && err.contains("-2.0"), "the body and its eigenvalue: {err}");
        }
        assert!(load(&tampered).controller_parameters(&model).is_ok(), "PD needs no consistency");

        // Vectors that do not fit together are refused by name, for every controller.
        let mut short = file.clone();
        short["beta"].as_array_mut().unwrap().pop();
        let err = load(&short).controller_parameters(&model).unwrap_err().to_string();
        assert!(err.contains("`beta` has"), "{err}");

        // A Coulomb law of zero width is refused on loading, before it can make a NaN.
        let mut lawless = file.clone();
        lawless["settings"]["coulomb_epsilon"] = 0.0.into();
        let err = ModelFile::from_json(&lawless.to_string()).unwrap_err().to_string();
        assert!(err.contains("`settings.coulomb_epsilon` is 0"), "{err}");
    }
}

/// A closed-loop log: the controller differences the encoders for its velocity, so their noise
/// reaches the torque through its damping gain, and the motion carries a small 9 Hz ripple that
/// repeats every period (as the daemon's mock rig's insertion does), which puts the spectral
/// rule's cut-off, and so the search, far up into that noise. Scored on the torque of the
/// positions it is fitted from, a cut-off that lets the noise in wins: the model learns the
/// controller's damping as viscous friction. Scored on the other period's torque it cannot.
#[test]
fn a_closed_loop_log_does_not_lead_the_cutoff_into_the_encoders_noise() {
    use arash_core::identify::{identify, Declared, IdentifyOptions, Log};
    use arash_core::model_file::IdentifyMethod;
    let (model, base, pi, traj, mut rng) = drawn_truth(31);
    let (fs, periods) = (1000.0, 2);
    let ripple_hz = 9.0;
    // Ripple amplitude, encoder noise (rad, rad, m) and the controller's damping gain: a stiff
    // loop, whose response to the noise is most of the unfiltered torque. Scored on its own
    // period's torque the search picks its top, 152 Hz, and the model is 25 % off on yaw.
    let (ripple, encoder, damping) = ([3e-4, 3e-4, 3e-5], [5e-5, 5e-5, 5e-6], [5.0, 5.0, 200.0]);
    let states = |t: f64| {
        let (mut q, mut qd, mut qdd) = traj.at(t);
        let w = 2.0 * std::f64::consts::PI * ripple_hz;
        for k in 0..3 {
            let (s, c) = (w * t + k as f64).sin_cos();
            q[k] += ripple[k] * s;
            qd[k] += ripple[k] * w * c;
            qdd[k] -= ripple[k] * w * w * s;
        }
        (q, qd, qdd)
    };
    let mut data = Data::new(&model);
    let samples = (15.0 * fs) as usize * periods;
    let (mut t, mut q_log, mut tau_log) = (Vec::new(), Vec::new(), Vec::new());
    let (mut tau, mut noise_before) = (vec![0.0; 3], [0.0; 3]);
    for i in 0..samples {
        let ti = i as f64 / fs;
        let (q, qd, qdd) = states(ti);
        inverse_dynamics(&model, &mut data, &q, &qd, &qdd, &pi, &mut tau);
        t.push(ti);
        for k in 0..3 {
            let noise = encoder[k] * gaussian(&mut rng);
            q_log.push(q[k] + noise);
            // The loop acts against the velocity noise it measures: −Kd (e[i] − e[i−1]) / dt.
            tau_log.push(tau[k] - damping[k] * (noise - noise_before[k]) * fs + NOISE[k] * gaussian(&mut rng));
            noise_before[k] = noise;
        }
    }
    let file = identify(
        Declared { model: &model, base: &base, urdf: "" },
        Log { t: &t, q: &q_log, tau: &tau_log },
        IdentifyMethod::Ols,
        &IdentifyOptions::default(),
    )
    .unwrap();
    let reasons = file.settings.reasons.iter().map(|r| r.to_string()).collect::<Vec<_>>().join("\n");
    // Predict the noise-free torque on the true states of one period.
    let (mut error, mut power) = ([0.0f64; 3], [0.0f64; 3]);
    for (predicted, exact) in
        predicted_and_true(&model, &file.with_its_law(&model), &base, &pi, &file.fitted.beta, states)
    {
        for k in 0..3 {
            error[k] += (predicted[k] - exact[k]).powi(2);
            power[k] += exact[k].powi(2);
        }
    }
    let relative: Vec<f64> = (0..3).map(|k| (error[k] / power[k]).sqrt()).collect();
    eprintln!("cut-off {:.2} Hz, ‖e‖/‖τ‖ {relative:.4?}\n{reasons}", file.settings.cutoff_hz);
    assert!(relative.iter().all(|r| *r < 0.05), "‖e‖/‖τ‖ {relative:?} at {:.2} Hz\n{reasons}", file.settings.cutoff_hz);
}

/// What disturbs a simulated closed loop ([`closed_loop_log`]).
#[derive(Clone, Copy)]
struct LoopNoise {
    /// Noise the drive adds to the commanded torque, as a share of each joint's RMS torque, in a
    /// first-order 2 Hz band (the log records the torque applied).
    disturbance: f64,
    /// White noise on the encoder readings, in 16-bit counts, before they are quantised to whole
    /// counts; `None` reads the exact position.
    encoder_counts: Option<f64>,
}

/// A closed-loop log of the true robot `pi`: PD with gravity compensation from CAD (5 Hz,
/// damping 0.7 on the diagonal of `M(q₀)`) follows `traj` for `seconds` at 1 kHz. The
/// controller differences the encoders for its velocity, so their noise passes through its gain
/// into the torque the log holds. The plant is integrated by semi-implicit Euler in
/// quarter-millisecond steps (IDIM-IV's own simulation is RK4).
struct LoopLog {
    t: Vec<f64>,
    q: Vec<f64>,
    tau: Vec<f64>,
    reference: [Vec<f64>; 3],
    controller: arash_core::identify::closed_loop::LoggedController,
}

fn closed_loop_log(
    model: &Model,
    pi: &[f64],
    traj: &Fourier,
    seconds: f64,
    noise: LoopNoise,
    rng: &mut ChaCha8Rng,
) -> LoopLog {
    use arash_core::identify::closed_loop::LoggedController;
    let (fs, n, substeps) = (1000.0, model.dof(), 4);
    let (dt, h) = (1.0 / fs, 1.0 / fs / substeps as f64);
    let cad = model.cad_parameters();
    let mut data = Data::new(model);
    let (q0, qd0, _) = traj.at(0.0);
    let mut mass = vec![0.0; n * n];
    mass_matrix(model, &mut data, &q0, pi, &mut mass);
    let w = 2.0 * std::f64::consts::PI * 5.0;
    let kp: Vec<f64> = (0..n).map(|k| mass[k * n + k] * w * w).collect();
    let kd: Vec<f64> = (0..n).map(|k| 1.4 * mass[k * n + k] * w).collect();
    // The disturbance's scale: the RMS torque the trajectory needs.
    let mut scale = vec![0.0; n];
    let mut tau = vec![0.0; n];
    for i in 0..1000 {
        let (q, qd, qdd) = traj.at(i as f64 * 0.015);
        inverse_dynamics(model, &mut data, &q, &qd, &qdd, pi, &mut tau);
        scale.iter_mut().zip(&tau).for_each(|(s, t)| *s += t * t / 1000.0);
    }
    let scale: Vec<f64> = scale.iter().map(|s| noise.disturbance * s.sqrt()).collect();
    let quantum: Vec<f64> = model
        .joints
        .iter()
        .map(|j| if j.kind == JointKind::Prismatic { 0.2 } else { 2.0 * std::f64::consts::PI } / 65536.0)
        .collect();
    let a = (-2.0 * std::f64::consts::PI * 2.0 * dt).exp();
    let (mut q, mut qd) = (q0.clone(), qd0.clone());
    let (mut disturbance, mut read_before) = (vec![0.0; n], q0.clone());
    let controller = LoggedController::Pd { params: cad.clone(), kp: kp.clone(), kd: kd.clone() };
    let mut log = LoopLog { t: vec![], q: vec![], tau: vec![], reference: Default::default(), controller };
    let (mut gravity, mut qdd) = (vec![0.0; n], vec![0.0; n]);
    for i in 0..(seconds * fs) as usize {
        let ti = i as f64 * dt;
        let (q_d, qd_d, qdd_d) = traj.at(ti);
        let read: Vec<f64> = (0..n)
            .map(|k| match noise.encoder_counts {
                Some(counts) => ((q[k] / quantum[k]) + counts * gaussian(rng)).round() * quantum[k],
                None => q[k],
            })
            .collect();
        let velocity: Vec<f64> = match (i, noise.encoder_counts) {
            (0, _) => qd0.clone(),
            (_, Some(_)) => (0..n).map(|k| (read[k] - read_before[k]) / dt).collect(),
            (_, None) => qd.clone(),
        };
        read_before.clone_from(&read);
        gravity_torque(model, &mut data, &read, &cad, &mut gravity);
        for k in 0..n {
            disturbance[k] = a * disturbance[k] + (1.0 - a * a).sqrt() * gaussian(rng);
            tau[k] =
                gravity[k] - kp[k] * (read[k] - q_d[k]) - kd[k] * (velocity[k] - qd_d[k]) + scale[k] * disturbance[k];
        }
        log.t.push(ti);
        log.q.extend_from_slice(&read);
        log.tau.extend_from_slice(&tau);
        log.reference[0].extend_from_slice(&q_d);
        log.reference[1].extend_from_slice(&qd_d);
        log.reference[2].extend_from_slice(&qdd_d);
        for _ in 0..substeps {
            forward_dynamics(model, &mut data, &q, &qd, &tau, pi, &mut qdd).unwrap();
            for k in 0..n {
                qd[k] += h * qdd[k];
                q[k] += h * qd[k];
            }
        }
    }
    log
}

fn closed_loop_truth(seed: u64) -> (Model, BaseParameters, Vec<f64>, Fourier, ChaCha8Rng) {
    let (mut model, base, pi, _, mut rng) = drawn_truth(seed);
    model.coulomb_laws = CoulombLaws::uniform(CoulombShape::Tanh { epsilon: 0.01 }, model.dof());
    // Four 10 s periods.
    let traj = Fourier::random(&model, 10.0, &mut rng);
    (model, base, pi, traj, rng)
}

/// IDIM-IV's simulation of the loop is an independent integration of the same closed loop: on a
/// log with no noise and exact encoders it reproduces the logged positions.
#[test]
fn the_loop_idim_iv_simulates_follows_a_noise_free_closed_loop_log() {
    use arash_core::identify::closed_loop::{simulate_loop, ClosedLoop};
    let (model, _, pi, traj, mut rng) = closed_loop_truth(41);
    let log = closed_loop_log(&model, &pi, &traj, 10.0, LoopNoise { disturbance: 0.0, encoder_counts: None }, &mut rng);
    let closed_loop = ClosedLoop::new(&log.reference, &log.controller);
    let (q, tau) = simulate_loop(&model, &pi, &closed_loop, &log.t).unwrap();
    let n = model.dof();
    for k in 0..n {
        let column = |x: &[f64]| x.iter().skip(k).step_by(n).copied().collect::<Vec<f64>>();
        let (sim, logged, desired) = (column(&q), column(&log.q), column(&log.reference[0]));
        let error = sim.iter().zip(&logged).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let tracking = logged.iter().zip(&desired).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let (torque_sim, torque_log) = (column(&tau), column(&log.tau));
        let torque_error = torque_sim.iter().zip(&torque_log).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let torque_span = torque_log.iter().map(|x| x.abs()).fold(0.0, f64::max);
        eprintln!("joint {k}: |q_sim − q_log| ≤ {error:.2e}, tracking error ≤ {tracking:.2e}, |τ_sim − τ_log| ≤ {torque_error:.2e} of {torque_span:.2e}");
        // The two integrations differ by Euler's O(h) error; the loop's own tracking error is
        // what a wrong controller or plant would show.
        assert!(
            error < 0.02 * tracking,
            "joint {k}: the simulated loop is {error:.2e} off; tracking error {tracking:.2e}"
        );
        assert!(torque_error < 0.02 * torque_span, "joint {k}: torque {torque_error:.2e} off of {torque_span:.2e}");
    }
}

/// On closed-loop logs of a PD loop whose drive adds a disturbance in the identification's band
/// (a tenth of the RMS torque, in 2 Hz) and whose 16-bit encoders the controller differences,
/// IDIM-IV and DIDIM settle in a few iterations and their σ cover the truth. Both estimates come
/// from the simulated loop's regressor: a wrong solve or a wrong σ fails here.
#[test]
fn idim_iv_and_didim_settle_and_their_sigma_cover_the_truth_on_closed_loop_logs() {
    use arash_core::model_file::IdentifyMethod;
    for method in [IdentifyMethod::IdimIv, IdentifyMethod::Didim] {
        closed_loop_coverage(method);
    }
}

fn closed_loop_coverage(method: arash_core::model_file::IdentifyMethod) {
    use arash_core::identify::closed_loop::ClosedLoop;
    use arash_core::identify::{identify_in_closed_loop, Declared, IdentifyOptions, Log};
    let (mut covered, mut total) = (0, 0);
    for seed in 0..4 {
        let (model, base, pi, traj, mut rng) = closed_loop_truth(100 + seed);
        let noise = LoopNoise { disturbance: 0.1, encoder_counts: Some(0.0) };
        let log = closed_loop_log(&model, &pi, &traj, 40.0, noise, &mut rng);
        let mut beta_true = vec![0.0; base.rank];
        base.project(&pi, &mut beta_true);
        let closed_loop = ClosedLoop::new(&log.reference, &log.controller);
        let iv = identify_in_closed_loop(
            Declared { model: &model, base: &base, urdf: "" },
            Log { t: &log.t, q: &log.q, tau: &log.tau },
            closed_loop,
            method,
            &IdentifyOptions::default(),
        )
        .unwrap();
        let name = arash_core::identify::closed_loop::Estimator::of(method).unwrap().name();
        eprintln!("{method} seed {seed}: {}", iv.settings.reasons.last().unwrap());
        let unsettled = |w: &Concern| matches!(w, Concern::ClosedLoopNotSettled { estimator, .. } if estimator == name);
        assert!(!iv.settings.warnings.iter().any(unsettled), "{:?}", iv.settings.warnings);
        let simulated = |r: &Choice| matches!(r, Choice::ClosedLoop { estimator, .. } if estimator == name);
        assert!(iv.settings.reasons.iter().any(simulated), "{:?}", iv.settings.reasons);
        for ((beta, sigma_percent), truth) in iv.fitted.beta.iter().zip(&iv.fitted.sigma_percent).zip(&beta_true) {
            covered += usize::from((beta - truth).abs() <= 3.0 * sigma_percent / 100.0 * beta.abs());
            total += 1;
        }
    }
    let coverage = covered as f64 / total as f64;
    eprintln!("{method}: {covered} of {total} base parameters within 3σ of the truth");
    assert!(coverage >= 0.9, "{method}'s 3σ cover {:.1} % of the base parameters", 100.0 * coverage);
}

/// IDIM-IV without its closed loop, or with one that does not fit the log, is refused by name.
#[test]
fn idim_iv_names_what_its_closed_loop_lacks() {
    use arash_core::identify::closed_loop::{ClosedLoop, LoggedController};
    use arash_core::identify::{identify, identify_in_closed_loop, Declared, IdentifyOptions, Log};
    use arash_core::model_file::IdentifyMethod;
    let (model, base, pi, traj, mut rng) = closed_loop_truth(7);
    let log =
        closed_loop_log(&model, &pi, &traj, 20.0, LoopNoise { disturbance: 0.0, encoder_counts: Some(1.0) }, &mut rng);
    let declared = Declared { model: &model, base: &base, urdf: "" };
    let data = Log { t: &log.t, q: &log.q, tau: &log.tau };
    let options = IdentifyOptions::default();
    let message = identify(declared, data, IdentifyMethod::IdimIv, &options).unwrap_err().to_string();
    assert!(message.contains("reference") && message.contains("controller") && message.contains("ols"), "{message}");
    let short = &log.reference[1][..log.reference[1].len() - 3];
    let closed_loop =
        ClosedLoop { q_des: &log.reference[0], qd_des: short, qdd_des: &log.reference[2], controller: &log.controller };
    let message =
        identify_in_closed_loop(declared, data, closed_loop, IdentifyMethod::IdimIv, &options).unwrap_err().to_string();
    assert!(message.contains("qd_des"), "{message}");
    let mut nan = log.reference[2].clone();
    nan[30] = f64::NAN;
    let closed_loop =
        ClosedLoop { q_des: &log.reference[0], qd_des: &log.reference[1], qdd_des: &nan, controller: &log.controller };
    let message =
        identify_in_closed_loop(declared, data, closed_loop, IdentifyMethod::IdimIv, &options).unwrap_err().to_string();
    assert!(message.contains("qdd_des") && message.contains("sample 10"), "{message}");
    let wrong = LoggedController::Pd { params: vec![0.0; 5], kp: vec![1.0; 3], kd: vec![1.0; 3] };
    let closed_loop = ClosedLoop::new(&log.reference, &wrong);
    let message =
        identify_in_closed_loop(declared, data, closed_loop, IdentifyMethod::IdimIv, &options).unwrap_err().to_string();
    assert!(message.contains("5 entries"), "{message}");
}

/// An identification in the regrouped base parameters, placed in the exact ones
/// (`ModelFile::in_base`), predicts exactly as it did: the weak parameters at zero, every other
/// β̂ and its covariance where it was. The diagnosis starts from it so (diagnose/start.rs). The
/// exact file has a column the regrouped base lacks, and is refused there.
#[test]
fn an_identification_placed_in_the_exact_base_parameters_predicts_as_it_did() {
    use arash_core::identify::{identify, Declared, IdentifyOptions, Log};
    use arash_core::model_file::IdentifyMethod;
    let (model, exact, pi, traj, mut rng) = drawn_truth(31);
    let regrouped = exact.identifiable(&model, &BaseParameterOptions::fitted(false));
    assert!(regrouped.rank < exact.rank, "ARASH:ASiST has weak parameters to regroup");
    let (t, q, tau) = simulated_log(&model, &pi, &traj, 2, &mut rng);
    let mut options = IdentifyOptions::default();
    options.preprocess.periods = Some(2);
    options.preprocess.decimate = 5;
    let declared = Declared { model: &model, base: &regrouped, urdf: ARASH_ASIST_URDF };
    let file = identify(declared, Log { t: &t, q: &q, tau: &tau }, IdentifyMethod::Ols, &options).unwrap();
    let placed = file.in_base(&exact).unwrap();
    assert_eq!(placed.base_independent, exact.independent);
    assert_eq!(placed.fitted.beta.len(), exact.rank);
    let p = file.fitted.beta.len();
    for (i, j) in exact.independent.iter().enumerate() {
        match file.base_independent.iter().position(|k| k == j) {
            Some(a) => {
                assert_eq!(placed.fitted.beta[i], file.fitted.beta[a]);
                for (i2, j2) in exact.independent.iter().enumerate() {
                    let covariance = placed.fitted.beta_covariance[i * exact.rank + i2];
                    match file.base_independent.iter().position(|k| k == j2) {
                        Some(b) => assert_eq!(covariance, file.fitted.beta_covariance[a * p + b]),
                        None => assert_eq!(covariance, 0.0),
                    }
                }
            }
            None => assert_eq!(placed.fitted.beta[i], 0.0, "weak parameter {}", exact.names[i]),
        }
    }
    // The two predict alike on states the fit never saw, through the full regressor each.
    let mut states = common::rng(32);
    let (mut qs, mut qds, mut qdds) = (vec![], vec![], vec![]);
    let (mut a, mut b, mut c) = (vec![0.0; 3], vec![0.0; 3], vec![0.0; 3]);
    for _ in 0..200 {
        arash_core::base_parameters::random_state(&model, &mut states, &mut a, &mut b, &mut c);
        qs.extend_from_slice(&a);
        qds.extend_from_slice(&b);
        qdds.extend_from_slice(&c);
    }
    let before = file.predict(&model, &qs, &qds, &qdds);
    let after = placed.predict(&model, &qs, &qds, &qdds);
    let scale = before.iter().map(|v| v.abs()).fold(0.0, f64::max);
    for (x, y) in before.iter().zip(&after) {
        assert!((x - y).abs() <= 1e-12 * scale, "{x} against {y}");
    }
    assert!(placed.in_base(&regrouped).is_none(), "the regrouped base lacks the weak parameters' columns");
}
