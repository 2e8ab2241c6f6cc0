//! The operator's hand of a scenario ([`Hand`]): a force at a frame of the robot, as a function of
//! time, and the joint torque `J_vᵀ F` it exerts; with a grasp, also a spring and a damper to a
//! moving set-point, a force that depends on how the arm answers. The plant feels it; only the
//! truth records it.

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::scenario::{Grasp, Hand, RandomForce};
use crate::data::Data;
use crate::kinematics::{forward_kinematics, frame_jacobian, frame_placement};
use crate::model::{Frame, Model, UnknownFrame};
use crate::spatial::{Mat3, Vec3};

/// Sinusoids per axis of the random force: enough that its amplitude distribution is close to
/// Gaussian, few enough to cost nothing per step.
const TONES: usize = 16;

/// The hand's force over time and its map to joint torque; [`Self::add_torque`] does not allocate.
pub struct HandForce {
    hand: Hand,
    frame: Frame,
    data: Data,
    linear: Vec<f64>,
    angular: Vec<f64>,
    /// Per axis and tone: (angular frequency rad/s, phase rad).
    tones: [[(f64, f64); TONES]; 3],
    grasp: Option<GraspPath>,
}

/// A grasp and where its path is: the frame's placement when the hand took hold, and the
/// set-point's position and velocity at the present cycle (base frame).
struct GraspPath {
    grasp: Grasp,
    origin: Option<(Vec3, Mat3)>,
    set_point: Vec3,
    set_velocity: Vec3,
    /// The grasp's force summed over the evaluations since the cycle began, and how many.
    sum: Vec3,
    count: u32,
}

impl GraspPath {
    /// The set-point's offset from the origin and its rate at `t`, in the origin's axes.
    fn path(&self, t: f64) -> (Vec3, Vec3) {
        let g = &self.grasp;
        let s = t - g.at_s;
        let (mut offset, mut rate) = (Vec3::zeros(), Vec3::zeros());
        for axis in 0..3 {
            let w = std::f64::consts::TAU / g.period_s[axis];
            // The amplitude rises as 1 − cos over one period: the path starts at rest.
            let (ramp, ramp_rate) = match s < g.period_s[axis] {
                true => (0.5 * (1.0 - (0.5 * w * s).cos()), 0.25 * w * (0.5 * w * s).sin()),
                false => (1.0, 0.0),
            };
            let a = g.amplitude_m[axis];
            offset[axis] = a * ramp * (w * s).sin();
            rate[axis] = a * (ramp_rate * (w * s).sin() + ramp * w * (w * s).cos());
        }
        for p in &g.press {
            let u = (t - p.at_s) / p.duration_s;
            if (0.0..1.0).contains(&u) {
                let phase = std::f64::consts::PI * u;
                offset[2] += p.depth_m * phase.sin().powi(2);
                rate[2] += p.depth_m * (2.0 * phase).sin() * std::f64::consts::PI / p.duration_s;
            }
        }
        (offset, rate)
    }
}

impl HandForce {
    /// The hand of a scenario on `model`; the random force's phases come from `seed`.
    pub fn new(model: &Model, hand: &Hand, seed: u64) -> Result<Self, UnknownFrame> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(3);
        let band = hand.random.as_ref().map_or(0.0, |r| r.band_hz);
        let tones = std::array::from_fn(|_| {
            std::array::from_fn(|i| {
                let f = band * (i + 1) as f64 / TONES as f64;
                (std::f64::consts::TAU * f, rng.random_range(0.0..std::f64::consts::TAU))
            })
        });
        let n = model.dof();
        Ok(Self {
            frame: model.frame(&hand.frame)?,
            hand: hand.clone(),
            data: Data::new(model),
            linear: vec![0.0; 3 * n],
            angular: vec![0.0; 3 * n],
            tones,
            grasp: hand.grasp.as_ref().map(|g| GraspPath {
                grasp: g.clone(),
                origin: None,
                set_point: Vec3::zeros(),
                set_velocity: Vec3::zeros(),
                sum: Vec3::zeros(),
                count: 0,
            }),
        })
    }

    /// Start a cycle at time `t` with the robot at `q`: the grasp takes hold at the frame's
    /// placement once its time comes, and its set-point moves to where the path is at `t`
    /// (held over the cycle, which moves it by micrometres at a hand's speed).
    pub fn start_cycle(&mut self, model: &Model, t: f64, q: &[f64]) {
        let Some(g) = &mut self.grasp else { return };
        g.sum = Vec3::zeros();
        g.count = 0;
        if t < g.grasp.at_s {
            return;
        }
        if g.origin.is_none() {
            forward_kinematics(model, &mut self.data, q);
            let (rot, at) = frame_placement(&self.data, &self.frame);
            g.origin = Some((at, rot));
        }
        let (offset, rate) = g.path(t);
        let (origin, axes) = g.origin.expect("set above");
        g.set_point = origin + axes * offset;
        g.set_velocity = axes * rate;
    }

    /// The grasp's mean force over the evaluations since the cycle began (base frame, N).
    pub fn grasp_force(&self) -> [f64; 3] {
        match &self.grasp {
            Some(g) if g.count > 0 => (g.sum / f64::from(g.count)).into(),
            _ => [0.0; 3],
        }
    }

    /// The force at time `t` (s), base frame (N).
    pub fn force(&self, t: f64) -> [f64; 3] {
        let mut f = [0.0; 3];
        if let Some(r) = &self.hand.random {
            let w = window(r, t);
            if w > 0.0 {
                for (axis, out) in f.iter_mut().enumerate() {
                    // Equal amplitudes a over TONES tones have an RMS of a·√(TONES/2).
                    let a = r.rms[axis] * (2.0 / TONES as f64).sqrt();
                    *out +=
                        w * a * self.tones[axis].iter().map(|(omega, phase)| (omega * t + phase).sin()).sum::<f64>();
                }
            }
        }
        for p in &self.hand.press {
            let s = (t - p.at_s) / p.duration_s;
            if (0.0..1.0).contains(&s) {
                let shape = (std::f64::consts::PI * s).sin().powi(2);
                f.iter_mut().zip(&p.force).for_each(|(o, v)| *o += shape * v);
            }
        }
        for s in &self.hand.step {
            if t >= s.at_s && s.end_s.is_none_or(|e| t < e) {
                f.iter_mut().zip(&s.force).for_each(|(o, v)| *o += v);
            }
        }
        f
    }

    /// The joint torque `J_vᵀ F` of force `force` (base frame, N) at the frame's origin with the
    /// robot at `q`, added to `tau`.
    pub fn add_torque(&mut self, model: &Model, q: &[f64], force: &[f64; 3], tau: &mut [f64]) {
        if force.iter().all(|v| *v == 0.0) {
            return;
        }
        self.jacobian(model, q);
        self.add_force(model.dof(), &Vec3::from(*force), tau);
    }

    /// [`Self::add_torque`] of `force` and the grasp's spring and damper at state `q`, `qd`; the
    /// grasp's part is counted into the cycle's mean ([`Self::grasp_force`]).
    pub fn add_torque_moving(&mut self, model: &Model, q: &[f64], qd: &[f64], force: &[f64; 3], tau: &mut [f64]) {
        let held = self.grasp.as_ref().is_some_and(|g| g.origin.is_some());
        if !held {
            return self.add_torque(model, q, force, tau);
        }
        self.jacobian(model, q);
        let n = model.dof();
        let position = frame_placement(&self.data, &self.frame).1;
        let velocity: Vec3 =
            (0..n).map(|k| Vec3::new(self.linear[k], self.linear[n + k], self.linear[2 * n + k]) * qd[k]).sum();
        let g = self.grasp.as_mut().expect("held");
        let pull = g.grasp.stiffness * (g.set_point - position) + g.grasp.damping * (g.set_velocity - velocity);
        g.sum += pull;
        g.count += 1;
        self.add_force(n, &(pull + Vec3::from(*force)), tau);
    }

    fn jacobian(&mut self, model: &Model, q: &[f64]) {
        forward_kinematics(model, &mut self.data, q);
        frame_jacobian(model, &self.data, &self.frame, &mut self.linear, &mut self.angular);
    }

    fn add_force(&self, n: usize, force: &Vec3, tau: &mut [f64]) {
        for (k, out) in tau.iter_mut().enumerate().take(n) {
            *out += (0..3).map(|i| self.linear[i * n + k] * force[i]).sum::<f64>();
        }
    }
}

/// The random force's envelope: 0 outside its window, rising and falling as sin² over one period
/// of its band so that it does not start with a jump.
fn window(r: &RandomForce, t: f64) -> f64 {
    let ramp = 1.0 / r.band_hz;
    let from_start = t - r.start_s;
    let to_end = r.end_s.map_or(f64::INFINITY, |e| e - t);
    let edge = from_start.min(to_end);
    if edge <= 0.0 {
        0.0
    } else if edge >= ramp {
        1.0
    } else {
        (0.5 * std::f64::consts::PI * edge / ramp).sin().powi(2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::scenario::{Press, Step};

    fn arm() -> Model {
        crate::arash_asist()
    }

    #[test]
    fn the_random_force_has_its_rms_and_band() {
        let hand = Hand {
            random: Some(RandomForce { rms: [0.3, 0.6, 1.2], band_hz: 2.0, start_s: 0.0, end_s: None }),
            ..Hand::default()
        };
        let h = HandForce::new(&arm(), &hand, 7).unwrap();
        let (dt, n) = (1e-3, 200_000);
        let mut square = [0.0; 3];
        let mut fastest: f64 = 0.0;
        let mut last = h.force(1.0);
        for i in 1..n {
            let f = h.force(1.0 + i as f64 * dt);
            for a in 0..3 {
                square[a] += f[a] * f[a] / n as f64;
                fastest = fastest.max(((f[a] - last[a]) / dt).abs() / (hand.random.as_ref().unwrap().rms[a]));
            }
            last = f;
        }
        for (a, want) in [0.3, 0.6, 1.2].iter().enumerate() {
            let rms = square[a].sqrt();
            assert!((rms / want - 1.0).abs() < 0.1, "axis {a}: RMS {rms}, want {want}");
        }
        // A sum of tones up to 2 Hz changes no faster than 2π·2 Hz × its peak (≤ 4√2 RMS here).
        assert!(fastest < std::f64::consts::TAU * 2.0 * 4.0 * 2f64.sqrt(), "{fastest}");
    }

    #[test]
    fn presses_and_steps_have_their_shape() {
        let hand = Hand {
            press: vec![Press { at_s: 1.0, duration_s: 0.4, force: [0.0, 0.0, -2.0] }],
            step: vec![Step { at_s: 2.0, end_s: Some(3.0), force: [1.0, 0.0, 0.0] }],
            ..Hand::default()
        };
        let h = HandForce::new(&arm(), &hand, 1).unwrap();
        assert_eq!(h.force(0.99), [0.0; 3]);
        assert!((h.force(1.2)[2] + 2.0).abs() < 1e-12);
        assert!((h.force(1.1)[2] + 1.0).abs() < 1e-12);
        assert_eq!(h.force(1.5), [0.0; 3]);
        assert_eq!(h.force(2.0), [1.0, 0.0, 0.0]);
        assert_eq!(h.force(3.0), [0.0; 3]);
    }

    #[test]
    fn the_torque_does_the_forces_work() {
        // Power balance: the joint torque's power τ·q̇ equals the force's F·v at the frame, with v
        // from a finite difference of the frame's position (not the Jacobian the map uses).
        let model = arm();
        let mut h = HandForce::new(&model, &Hand::default(), 1).unwrap();
        let (q, qd) = ([0.1, -0.2, 0.05], [0.3, -0.4, 0.02]);
        let force = [0.7, -0.4, 1.1];
        let mut tau = [0.0; 3];
        h.add_torque(&model, &q, &force, &mut tau);
        let frame = model.frame("instrument_tip").unwrap();
        let mut data = Data::new(&model);
        let mut at = |s: f64| {
            let qs: Vec<f64> = q.iter().zip(&qd).map(|(a, b)| a + s * b).collect();
            forward_kinematics(&model, &mut data, &qs);
            crate::kinematics::frame_placement(&data, &frame).1
        };
        let v = (at(1e-6) - at(-1e-6)) / 2e-6;
        let power_force: f64 = (0..3).map(|i| force[i] * v[i]).sum();
        let power_joints: f64 = tau.iter().zip(&qd).map(|(t, w)| t * w).sum();
        assert!((power_force - power_joints).abs() < 1e-7 * power_force.abs().max(1.0), "{power_force} {power_joints}");
    }
}
