//! A finite Fourier series per joint (paper eq. 18), the shape of the excitation trajectories:
//!
//!   q(t) = q₀ + Σₗ [aₗ/(ω l) sin(ω l t) − bₗ/(ω l) cos(ω l t)],   ω = 2π/T.
//!
//! `crate::identify::excitation` designs its coefficients; here it is only evaluated.

use serde::{Deserialize, Serialize};

/// The rate a trajectory is sampled at when nobody says (Hz): the rig's control rate.
pub const DEFAULT_SAMPLE_RATE_HZ: f64 = 1000.0;

/// A designed excitation: the Fourier coefficients and what they achieve.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Excitation {
    pub harmonics: usize,
    pub period_s: f64,
    /// Offsets q₀ per joint (rad or m).
    pub q0: Vec<f64>,
    /// `a[j][l]`, `b[j][l]` for joint j and harmonic l + 1 (rad/s or m/s).
    pub a: Vec<Vec<f64>>,
    pub b: Vec<Vec<f64>>,
    /// Normalised condition number achieved over the base parameters it was designed for (see
    /// `crate::identify::excitation`).
    pub condition_number: f64,
    /// The same with the weak base parameters kept (`crate::base_parameters`); equal to
    /// `condition_number` when none was regrouped, NaN when unknown (files written before it).
    #[serde(default = "unknown")]
    pub condition_number_with_weak: f64,
}

fn unknown() -> f64 {
    f64::NAN
}

impl Excitation {
    fn omega(&self) -> f64 {
        2.0 * std::f64::consts::PI / self.period_s
    }

    /// Position, velocity and acceleration at time `t` (SI).
    pub fn state(&self, t: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
        let n = self.q0.len();
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        self.state_into(t, &mut q, &mut qd, &mut qdd);
        (q, qd, qdd)
    }

    /// [`Excitation::state`] into caller buffers, without allocating.
    pub fn state_into(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        let w = self.omega();
        for j in 0..self.q0.len() {
            (q[j], qd[j], qdd[j]) = (self.q0[j], 0.0, 0.0);
            for l in 0..self.harmonics {
                let wl = w * (l + 1) as f64;
                let (s, c) = (wl * t).sin_cos();
                let (a, b) = (self.a[j][l], self.b[j][l]);
                q[j] += a / wl * s - b / wl * c;
                qd[j] += a * c + b * s;
                qdd[j] += wl * (-a * s + b * c);
            }
        }
    }

    /// Sampled at `rate_hz` over `periods` periods: (t, q, q̇, q̈), the latter row-major N × dof.
    pub fn sample(&self, rate_hz: f64, periods: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let count = (self.period_s * rate_hz).round() as usize * periods;
        let (mut t, mut q, mut qd, mut qdd) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for i in 0..count {
            let ti = i as f64 / rate_hz;
            let (a, b, c) = self.state(ti);
            t.push(ti);
            q.extend(a);
            qd.extend(b);
            qdd.extend(c);
        }
        (t, q, qd, qdd)
    }
}
