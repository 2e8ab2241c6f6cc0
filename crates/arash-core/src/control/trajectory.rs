//! Reference trajectories for the controllers, read from `arash-trajectory/1` JSON files.
//!
//! Three kinds:
//! - `"fourier"`: the excitation written by `arash excite` (its coefficients; the sampled copy in
//!   the same file is ignored). Files without `kind` but with `harmonics` are read as this kind.
//! - `"paper-validation"`: the paper's validation trajectory at `omega` (rad/s).
//! - `"hold"`: a constant position `q` (SI).
//!
//! Evaluation never allocates.

use serde::{Deserialize, Serialize};

use super::fourier::Excitation;
use crate::model::{JointKind, Model};

/// Why a trajectory file was refused.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    #[error("the trajectory is not valid JSON: {0}")]
    Json(#[from] serde_json::Error),
    #[error("the trajectory has format `{0}`; arash reads `arash-trajectory/1`")]
    Format(String),
    #[error("unknown trajectory kind `{0}`; use fourier, paper-validation or hold")]
    Kind(String),
    #[error("the trajectory has {found} joints, the robot has {expected}")]
    Joints { found: usize, expected: usize },
    #[error("trajectory field `{0}` is not finite or not positive")]
    Value(&'static str),
    #[error(
        "the trajectory cannot be followed: at sample {sample} (t = {t:.3} s) joint {joint} `{name}` has {quantity} \
         {value:.6} {unit}, beyond its limit {limit:.6} {unit}; refused before anything moved"
    )]
    Limit {
        sample: usize,
        t: f64,
        joint: usize,
        name: String,
        /// `position` or `speed`.
        quantity: &'static str,
        value: f64,
        limit: f64,
        unit: &'static str,
    },
}

/// What a reference may ask of each joint (SI): inside `[lower, upper]`, no faster than
/// `velocity`.
#[derive(Clone, Debug, PartialEq)]
pub struct PlanLimits {
    pub names: Vec<String>,
    pub prismatic: Vec<bool>,
    pub lower: Vec<f64>,
    pub upper: Vec<f64>,
    pub velocity: Vec<f64>,
}

impl PlanLimits {
    /// The URDF's position and speed limits of `model`'s joints.
    pub fn from_model(model: &Model) -> Self {
        let joints = &model.joints;
        Self {
            names: model.joint_names(),
            prismatic: joints.iter().map(|j| matches!(j.kind, JointKind::Prismatic)).collect(),
            lower: joints.iter().map(|j| j.lower).collect(),
            upper: joints.iter().map(|j| j.upper).collect(),
            velocity: joints.iter().map(|j| j.velocity).collect(),
        }
    }
}

/// Longest period a trajectory file may have (s): the limit check samples one period.
pub const MAX_PERIOD_S: f64 = 3600.0;
/// Most harmonics of a Fourier trajectory (the paper's excitation has 5).
pub const MAX_HARMONICS: usize = 100;
/// Most samples the limit check evaluates; beyond, its step grows past the control period, still
/// far below the period of the highest harmonic (at least 3.6 ms against 36 s).
const MAX_CHECK_SAMPLES: f64 = 1e6;

/// A reference `q_d(t)` with its first two derivatives.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Trajectory {
    Fourier(Excitation),
    PaperValidation { omega: f64 },
    Hold { q: Vec<f64> },
}

impl Trajectory {
    /// Parse an `arash-trajectory/1` document and check it against a robot with `dof` joints.
    pub fn from_json(text: &str, dof: usize) -> Result<Self, TrajectoryError> {
        let mut value: serde_json::Value = serde_json::from_str(text)?;
        let object = value.as_object_mut().ok_or_else(|| TrajectoryError::Format("not an object".into()))?;
        match object.get("format").and_then(|f| f.as_str()) {
            Some("arash-trajectory/1") | None => {}
            Some(other) => return Err(TrajectoryError::Format(other.into())),
        }
        if !object.contains_key("kind") && object.contains_key("harmonics") {
            object.insert("kind".into(), "fourier".into());
        }
        if let Some(kind) = object.get("kind").and_then(|k| k.as_str()) {
            if !["fourier", "paper-validation", "hold"].contains(&kind) {
                return Err(TrajectoryError::Kind(kind.into()));
            }
        }
        let trajectory: Trajectory = serde_json::from_value(value)?;
        trajectory.check(dof)?;
        Ok(trajectory)
    }

    /// The JSON document for this trajectory.
    pub fn to_json(&self) -> String {
        let mut value = serde_json::to_value(self).expect("trajectories serialise");
        value["format"] = "arash-trajectory/1".into();
        serde_json::to_string_pretty(&value).expect("JSON values serialise")
    }

    fn check(&self, dof: usize) -> Result<(), TrajectoryError> {
        let joints = match self {
            Trajectory::Fourier(e) => {
                if !(e.period_s.is_finite() && e.period_s > 0.0 && e.period_s <= MAX_PERIOD_S) {
                    return Err(TrajectoryError::Value("period_s (at most one hour)"));
                }
                if !(1..=MAX_HARMONICS).contains(&e.harmonics) {
                    return Err(TrajectoryError::Value("harmonics (1 to 100)"));
                }
                if e.q0.iter().chain(e.a.iter().flatten()).chain(e.b.iter().flatten()).any(|x| !x.is_finite()) {
                    return Err(TrajectoryError::Value("q0/a/b"));
                }
                if e.a.len() != e.q0.len()
                    || e.b.len() != e.q0.len()
                    || e.a.iter().chain(&e.b).any(|c| c.len() != e.harmonics)
                {
                    return Err(TrajectoryError::Value("a/b (one row of `harmonics` coefficients per joint)"));
                }
                e.q0.len()
            }
            Trajectory::PaperValidation { omega } => {
                if !(omega.is_finite() && *omega > 0.0 && 2.0 * std::f64::consts::PI / omega <= MAX_PERIOD_S) {
                    return Err(TrajectoryError::Value("omega"));
                }
                3
            }
            Trajectory::Hold { q } => {
                if q.iter().any(|x| !x.is_finite()) {
                    return Err(TrajectoryError::Value("q"));
                }
                q.len()
            }
        };
        if joints != dof {
            return Err(TrajectoryError::Joints { found: joints, expected: dof });
        }
        Ok(())
    }

    /// A natural length for a run: 20 periods of an excitation (the paper's logging run), one
    /// period of a validation trajectory, 10 s of a hold.
    pub fn default_duration(&self) -> f64 {
        match self {
            Trajectory::Fourier(e) => 20.0 * e.period_s,
            Trajectory::PaperValidation { omega } => 2.0 * std::f64::consts::PI / omega,
            Trajectory::Hold { .. } => 10.0,
        }
    }

    /// The highest frequency in the reference (Hz): the top harmonic of an excitation, the
    /// single frequency of a validation run; `None` for a hold.
    pub fn bandwidth_hz(&self) -> Option<f64> {
        match self {
            Trajectory::Fourier(e) => Some(e.harmonics as f64 / e.period_s),
            Trajectory::PaperValidation { omega } => Some(omega / (2.0 * std::f64::consts::PI)),
            Trajectory::Hold { .. } => None,
        }
    }

    /// One period of a periodic reference (s); `None` for a hold.
    pub fn period_s(&self) -> Option<f64> {
        match self {
            Trajectory::Fourier(e) => Some(e.period_s),
            Trajectory::PaperValidation { omega } => Some(2.0 * std::f64::consts::PI / omega),
            Trajectory::Hold { .. } => None,
        }
    }

    /// Check the reference against `limits` at every `dt` over a run of `duration_s` (over one
    /// period when the run is longer: the reference repeats). The error names the first sample,
    /// joint and limit broken. Run before anything moves: the safety gate would trip only once
    /// the robot is already on its way out.
    pub fn check_limits(&self, limits: &PlanLimits, duration_s: f64, dt: f64) -> Result<(), TrajectoryError> {
        let n = limits.lower.len();
        let span = self.period_s().map_or(0.0, |p| p.min(duration_s));
        let step = dt.max(span / MAX_CHECK_SAMPLES);
        let samples = (span / step).ceil() as usize + 1;
        let (mut q, mut qd, mut qdd) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for sample in 0..samples {
            let t = (sample as f64 * step).min(span);
            self.eval(t, &mut q, &mut qd, &mut qdd);
            for k in 0..n {
                let (position, speed) = if limits.prismatic[k] { ("m", "m/s") } else { ("rad", "rad/s") };
                let broken = |quantity, value: f64, limit: f64, unit| TrajectoryError::Limit {
                    sample,
                    t,
                    joint: k,
                    name: limits.names[k].clone(),
                    quantity,
                    value,
                    limit,
                    unit,
                };
                // A reference that touches a limit exactly (the paper's validation trajectories
                // do) is inside it; rounding in the evaluation must not refuse it.
                let slack = |limit: f64| 1e-9 * limit.abs().max(1.0);
                if !q[k].is_finite() || q[k] > limits.upper[k] + slack(limits.upper[k]) {
                    return Err(broken("position", q[k], limits.upper[k], position));
                }
                if q[k] < limits.lower[k] - slack(limits.lower[k]) {
                    return Err(broken("position", q[k], limits.lower[k], position));
                }
                if !qd[k].is_finite() || qd[k].abs() > limits.velocity[k] + slack(limits.velocity[k]) {
                    return Err(broken("speed", qd[k].abs(), limits.velocity[k], speed));
                }
            }
        }
        Ok(())
    }

    /// `q_d`, `q̇_d`, `q̈_d` at `t` into the caller's buffers.
    pub fn eval(&self, t: f64, q: &mut [f64], qd: &mut [f64], qdd: &mut [f64]) {
        match self {
            Trajectory::Fourier(e) => e.state_into(t, q, qd, qdd),
            Trajectory::PaperValidation { omega } => {
                let (a, b, c) = paper_validation_state(*omega, t);
                q.copy_from_slice(&a);
                qd.copy_from_slice(&b);
                qdd.copy_from_slice(&c);
            }
            Trajectory::Hold { q: hold } => {
                q.copy_from_slice(hold);
                qd.fill(0.0);
                qdd.fill(0.0);
            }
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_refuses_bad_documents() {
        let t = Trajectory::PaperValidation { omega: 0.5 };
        let back = Trajectory::from_json(&t.to_json(), 3).unwrap();
        assert!(matches!(back, Trajectory::PaperValidation { omega } if omega == 0.5));
        assert!(matches!(
            Trajectory::from_json(&t.to_json(), 2),
            Err(TrajectoryError::Joints { found: 3, expected: 2 })
        ));
        let bad = r#"{"format": "arash-trajectory/1", "kind": "spline"}"#;
        assert!(matches!(Trajectory::from_json(bad, 3), Err(TrajectoryError::Kind(k)) if k == "spline"));
        let bad = r#"{"kind": "paper-validation", "omega": -1}"#;
        assert!(matches!(Trajectory::from_json(bad, 3), Err(TrajectoryError::Value("omega"))));
        let bad = r#"{"format": "other/2", "kind": "hold", "q": [0, 0, 0]}"#;
        assert!(matches!(Trajectory::from_json(bad, 3), Err(TrajectoryError::Format(_))));
    }

    fn limits() -> PlanLimits {
        PlanLimits::from_model(&crate::arash_asist())
    }

    #[test]
    fn the_papers_validation_trajectories_touch_the_limits_and_pass() {
        for omega in [0.3, 0.5, 0.7, 0.9] {
            Trajectory::PaperValidation { omega }.check_limits(&limits(), 100.0, 1e-3).unwrap();
        }
    }

    #[test]
    fn a_position_beyond_a_limit_is_refused_with_sample_joint_and_limit() {
        let hold = Trajectory::Hold { q: vec![1.5, 0.0, 0.0] };
        let err = hold.check_limits(&limits(), 10.0, 1e-3).unwrap_err();
        match &err {
            TrajectoryError::Limit { sample: 0, joint: 0, quantity: "position", value, limit, .. } => {
                assert_eq!(*value, 1.5);
                assert!((limit - 42.5f64.to_radians()).abs() < 1e-9);
            }
            other => panic!("{other:?}"),
        }
        let text = err.to_string();
        assert!(text.contains("sample 0") && text.contains("joint 0") && text.contains("0.741765"), "{text}");
        let below = Trajectory::Hold { q: vec![0.0, -0.5, 0.0] };
        assert!(matches!(
            below.check_limits(&limits(), 10.0, 1e-3),
            Err(TrajectoryError::Limit { joint: 1, quantity: "position", .. })
        ));
    }

    #[test]
    fn a_speed_beyond_the_limit_is_refused_at_the_first_sample_that_breaks_it() {
        // Yaw q = 0.1 sin(120 t): inside the position limits, 12 rad/s at t = 0 against 3.49 rad/s.
        let mut e: Excitation = serde_json::from_str(
            r#"{"harmonics": 1, "period_s": 0.05235987755982988, "q0": [0, 0.2, 0.005],
                "a": [[12.0], [0], [0]], "b": [[0], [0], [0]], "condition_number": 1}"#,
        )
        .unwrap();
        let fast = Trajectory::Fourier(e.clone());
        let err = fast.check_limits(&limits(), 10.0, 1e-3).unwrap_err();
        assert!(
            matches!(err, TrajectoryError::Limit { sample: 0, joint: 0, quantity: "speed", value, .. } if (value - 12.0).abs() < 1e-6),
            "{err}"
        );
        // A tenth of it passes: 1.2 rad/s.
        e.a[0][0] = 1.2;
        Trajectory::Fourier(e).check_limits(&limits(), 10.0, 1e-3).unwrap();
    }

    #[test]
    fn periods_and_harmonics_are_bounded_so_that_the_check_cannot_hang() {
        let fourier = |period: f64, harmonics: usize| {
            format!(
                r#"{{"kind": "fourier", "harmonics": {harmonics}, "period_s": {period}, "q0": [0, 0.2, 0.005],
                    "a": [{z}, {z}, {z}], "b": [{z}, {z}, {z}], "condition_number": 1}}"#,
                z = format!("[{}]", vec!["1e-5"; harmonics].join(","))
            )
        };
        assert!(matches!(Trajectory::from_json(&fourier(1e9, 5), 3), Err(TrajectoryError::Value(_))));
        assert!(matches!(Trajectory::from_json(&fourier(15.0, 1000), 3), Err(TrajectoryError::Value(_))));
        let omega = r#"{"kind": "paper-validation", "omega": 1e-9}"#;
        assert!(matches!(Trajectory::from_json(omega, 3), Err(TrajectoryError::Value(_))));
        // The longest period allowed is checked over a day of run at a bounded number of samples.
        let longest = Trajectory::from_json(&fourier(MAX_PERIOD_S, 5), 3).unwrap();
        longest.check_limits(&limits(), 86_400.0, 1e-3).unwrap();
    }

    #[test]
    fn derivatives_are_consistent() {
        let t = Trajectory::PaperValidation { omega: 0.9 };
        let (mut q0, mut q1, mut qd, mut qdd) = ([0.0; 3], [0.0; 3], [0.0; 3], [0.0; 3]);
        let (mut v0, mut v1) = ([0.0; 3], [0.0; 3]);
        let h = 1e-6;
        t.eval(1.3 - h, &mut q0, &mut v0, &mut qdd);
        t.eval(1.3 + h, &mut q1, &mut v1, &mut qdd);
        t.eval(1.3, &mut [0.0; 3], &mut qd, &mut qdd);
        for k in 0..3 {
            assert!(((q1[k] - q0[k]) / (2.0 * h) - qd[k]).abs() < 1e-8);
            assert!(((v1[k] - v0[k]) / (2.0 * h) - qdd[k]).abs() < 1e-8);
        }
    }
}
