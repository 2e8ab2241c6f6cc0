//! Criterion benches of the identification pipeline on a simulated 300,000-sample log (300 s at
//! 1 kHz of a 15 s, 5-harmonic excitation; CAD torques plus noise), step by step and whole.
//! Run: cargo bench -p arash-core --bench identification

// The consistent fit's SDP calls BLAS and LAPACK: arash's own, linked by naming the crate.
use arash_blas_lapack as _;
use arash_core::identify::{ConsistentOptions, PreprocessOptions};
use std::hint::black_box;

use arash_core::base_parameters::BaseParameterOptions;
use arash_core::consistent::identify_consistent;
use arash_core::control::fourier::Excitation;
use arash_core::identify::{identify, Declared, IdentifyOptions, Log};
use arash_core::model_file::IdentifyMethod;
use arash_core::signal::estimate::{fit, stack, Method};
use arash_core::signal::preprocess::preprocess;
use arash_core::*;
use criterion::{criterion_group, criterion_main, Criterion};

/// A smooth excitation within ARASH:ASiST's limits (fixed coefficients: the bench measures speed).
fn excitation(model: &Model) -> Excitation {
    let harmonics = 5;
    let coefficient = |j: usize, l: usize, phase: f64| {
        0.25 * model.joints[j].velocity * (phase + j as f64 + l as f64).sin() / (l + 1) as f64
    };
    Excitation {
        harmonics,
        period_s: 15.0,
        q0: model.joints.iter().map(|j| 0.5 * (j.lower + j.upper)).collect(),
        a: (0..model.dof()).map(|j| (0..harmonics).map(|l| coefficient(j, l, 0.3)).collect()).collect(),
        b: (0..model.dof()).map(|j| (0..harmonics).map(|l| coefficient(j, l, 1.9)).collect()).collect(),
        condition_number: f64::NAN,
        condition_number_with_weak: f64::NAN,
    }
}

/// 20 periods at 1 kHz: t, q and τ (CAD parameters, deterministic pseudo-noise of encoder and
/// current-sensor size).
fn simulated_log(model: &Model) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let (t, q, qd, qdd) = excitation(model).sample(1000.0, 20);
    let (n, pi) = (model.dof(), model.cad_parameters());
    let mut data = Data::new(model);
    let mut tau = vec![0.0; q.len()];
    let noise = [0.003, 0.003, 0.05];
    for (s, out) in tau.chunks_mut(n).enumerate() {
        let range = s * n..(s + 1) * n;
        inverse_dynamics(model, &mut data, &q[range.clone()], &qd[range.clone()], &qdd[range], &pi, out);
        for (k, v) in out.iter_mut().enumerate() {
            *v += noise[k] * ((s * 7919 + k * 104_729) as f64).sin();
        }
    }
    (t, q, tau)
}

fn bench(c: &mut Criterion) {
    let model = arash_asist();
    let base = BaseParameters::compute(&model, &BaseParameterOptions::default()).unwrap();
    let (t, q, tau) = simulated_log(&model);
    let mut group = c.benchmark_group("identification, 300,000 samples");
    group.sample_size(10);
    for (label, periods) in [("20 periods averaged", Some(20)), ("no averaging", Some(1))] {
        // Both cut-offs set: the pipeline alone, as the peer in bench/identification_vs_scipy.py.
        let options = PreprocessOptions {
            periods,
            cutoff_hz: Some(1.6667),
            friction_cutoff_hz: Some(20.0),
            ..Default::default()
        };
        group.bench_function(format!("preprocess ({label})"), |b| {
            b.iter(|| preprocess(black_box(&t), &q, &tau, 3, &options).unwrap())
        });
        let pre = preprocess(&t, &q, &tau, 3, &options).unwrap();
        group.bench_function(format!("stack W ({label})"), |b| b.iter(|| stack(&model, &base, black_box(&pre))));
        group.bench_function(format!("OLS fit ({label})"), |b| {
            b.iter(|| fit(&model, &base, black_box(&pre), Method::Ols).unwrap())
        });
        let whole = IdentifyOptions { preprocess: options.clone(), ..Default::default() };
        // Every choice left to the data: the period found, the cut-off and the friction
        // velocity searched (signal/cutoff.rs).
        let defaults = IdentifyOptions {
            preprocess: PreprocessOptions { periods: (periods == Some(1)).then_some(1), ..Default::default() },
            ..Default::default()
        };
        for (name, settings) in [("identify OLS", &whole), ("identify OLS, choices from the data", &defaults)] {
            group.bench_function(format!("{name} ({label})"), |b| {
                b.iter(|| {
                    let declared = Declared { model: &model, base: &base, urdf: "" };
                    let log = Log { t: black_box(&t), q: &q, tau: &tau };
                    identify(declared, log, IdentifyMethod::Ols, settings).unwrap()
                })
            });
        }
    }
    group.finish();
}

/// The physically consistent fit (Clarabel with eight 4 × 4 semidefinite cones, whose BLAS and
/// LAPACK calls `blas_lapack` serves) on `samples` samples of the excitation: W is 3·samples × 89.
fn consistent(c: &mut Criterion) {
    let model = arash_asist();
    let (n, p, pi) = (model.dof(), model.num_params(), model.cad_parameters());
    let mut group = c.benchmark_group("consistent SDP");
    group.sample_size(20);
    for samples in [1000, 3000] {
        let (_, q, qd, qdd) = excitation(&model).sample(samples as f64 / 15.0, 1);
        let mut data = Data::new(&model);
        let mut y = vec![0.0; n * p];
        let mut w = faer::Mat::<f64>::zeros(n * samples, p);
        for s in 0..samples {
            let range = s * n..(s + 1) * n;
            regressor(&model, &mut data, &q[range.clone()], &qd[range.clone()], &qdd[range], &mut y);
            for (k, j) in (0..n).flat_map(|k| (0..p).map(move |j| (k, j))) {
                w[(s * n + k, j)] = y[k * p + j];
            }
        }
        let tau: Vec<f64> = (0..n * samples)
            .map(|r| (0..p).map(|j| w[(r, j)] * pi[j]).sum::<f64>() + 0.003 * ((r * 7919) as f64).sin())
            .collect();
        let options = ConsistentOptions::default();
        group.bench_function(format!("{} x {p} W", n * samples), |b| {
            b.iter(|| identify_consistent(&model, black_box(&w), &tau, &options).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, bench, consistent);
criterion_main!(benches);
