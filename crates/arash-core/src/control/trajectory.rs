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

use crate::identify::excitation::Excitation;
use crate::identify::paper_validation_state;

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
}

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
                if !(e.period_s.is_finite() && e.period_s > 0.0) {
                    return Err(TrajectoryError::Value("period_s"));
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
                if !(omega.is_finite() && *omega > 0.0) {
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
