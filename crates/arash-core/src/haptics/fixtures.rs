//! The virtual fixtures a training session renders at the instrument (docs/haptics.md), as a
//! fixture file gives them: each kind in its own table array, every stiffness and damping in SI
//! units. [`Fixtures::validate`] names the first field that cannot be rendered.

use serde::{Deserialize, Serialize};

/// A fixture file: the frames the fixtures act at and the fixtures themselves.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Fixtures {
    /// The frame whose origin and z axis are the instrument's tip and direction; empty: the
    /// robot's instrument tip (`instrument_tip` on ARASH:ASiST).
    pub frame: String,
    /// The entry point depths and angles are measured from, fixed in the base; empty: the
    /// robot's remote centre.
    pub entry: String,
    pub wall: Vec<DepthWall>,
    pub cone: Vec<Cone>,
    pub viscous: Vec<ViscousField>,
    pub spring: Vec<Spring>,
}

/// A depth the tip must not pass: `depth_m` beyond the entry point along the instrument (the
/// frame's z, into the eye). Past it the wall pushes back along the instrument, never pulls.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DepthWall {
    pub depth_m: f64,
    /// N/m.
    pub stiffness: f64,
    /// N·s/m, while in contact.
    pub damping: f64,
}

/// The angles the instrument may take about the entry point: its direction (the frame's z) at
/// most `half_angle_deg` from `axis`. Beyond it a moment about the entry point turns it back.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cone {
    /// The cone's axis, base frame (any length but zero).
    pub axis: [f64; 3],
    /// Degrees, in (0, 90): the file's one angle, as a surgeon states it.
    pub half_angle_deg: f64,
    /// N·m/rad.
    pub stiffness: f64,
    /// N·m·s/rad, while outside.
    pub damping: f64,
}

/// A force against the tip's velocity everywhere: `F = −b·v`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViscousField {
    /// N·s/m.
    pub damping: f64,
}

/// A spring and damper pulling the tip to a point: `F = −k (p − p₀) − b·v`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Spring {
    /// Base frame (m).
    pub point: [f64; 3],
    /// N/m.
    pub stiffness: f64,
    /// N·s/m.
    pub damping: f64,
}

/// A fixture file that cannot be rendered, naming the field.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FixtureError {
    #[error("{field} = {value}: {why}")]
    Field { field: String, value: String, why: &'static str },
    #[error("{field}: {why}")]
    Frame { field: &'static str, why: String },
    #[error(
        "{field} = {value} {unit} is above the passivity bound {bound:.4} {unit}: the damping left along it \
         is {damping:.4} {damping_unit} where it is least, and a sampled spring renders passively only while \
         b > K·(T/2 + latency) + |B| (Colgate and Schenkel), here with T/2 + latency = {delay_ms:.3} ms"
    )]
    AbovePassivity {
        field: String,
        value: f64,
        unit: &'static str,
        bound: f64,
        damping: f64,
        damping_unit: &'static str,
        delay_ms: f64,
    },
    #[error(
        "together the fixtures need {share_percent:.0} % of the damping the joints have left at q = {q:?}: \
         each is within its own bound but they act at once there ({shares}); lower a stiffness or a damping"
    )]
    TogetherAbovePassivity { share_percent: f64, q: Vec<f64>, shares: String },
    #[error("{0}")]
    Loop(String),
}

impl Fixtures {
    /// Every number finite, every stiffness and damping at or above zero, every direction a
    /// direction, every angle a cone can have.
    pub fn validate(&self) -> Result<(), FixtureError> {
        for (i, w) in self.wall.iter().enumerate() {
            finite(&format!("wall[{i}].depth_m"), w.depth_m)?;
            gain(&format!("wall[{i}].stiffness"), w.stiffness)?;
            gain(&format!("wall[{i}].damping"), w.damping)?;
        }
        for (i, c) in self.cone.iter().enumerate() {
            direction(&format!("cone[{i}].axis"), &c.axis)?;
            let field = format!("cone[{i}].half_angle_deg");
            finite(&field, c.half_angle_deg)?;
            if !(c.half_angle_deg > 0.0 && c.half_angle_deg < 90.0) {
                return Err(bad(&field, c.half_angle_deg, "a cone's half angle is between 0 and 90 degrees"));
            }
            gain(&format!("cone[{i}].stiffness"), c.stiffness)?;
            gain(&format!("cone[{i}].damping"), c.damping)?;
        }
        for (i, v) in self.viscous.iter().enumerate() {
            gain(&format!("viscous[{i}].damping"), v.damping)?;
        }
        for (i, s) in self.spring.iter().enumerate() {
            for (axis, x) in s.point.iter().enumerate() {
                finite(&format!("spring[{i}].point[{axis}]"), *x)?;
            }
            gain(&format!("spring[{i}].stiffness"), s.stiffness)?;
            gain(&format!("spring[{i}].damping"), s.damping)?;
        }
        Ok(())
    }
}

fn bad(field: &str, value: impl std::fmt::Display, why: &'static str) -> FixtureError {
    FixtureError::Field { field: field.to_string(), value: value.to_string(), why }
}

fn finite(field: &str, x: f64) -> Result<(), FixtureError> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(bad(field, x, "must be a finite number"))
    }
}

/// A stiffness or a damping: finite and not negative (a negative one feeds energy in).
fn gain(field: &str, x: f64) -> Result<(), FixtureError> {
    finite(field, x)?;
    if x < 0.0 {
        return Err(bad(field, x, "must be at least 0: a negative stiffness or damping feeds energy in"));
    }
    Ok(())
}

fn direction(field: &str, v: &[f64; 3]) -> Result<(), FixtureError> {
    let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
    if !(norm.is_finite() && norm > 1e-9) {
        return Err(bad(field, format!("{v:?}"), "must be a finite direction, not zero"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wall(stiffness: f64) -> Fixtures {
        Fixtures { wall: vec![DepthWall { depth_m: 0.01, stiffness, damping: 0.0 }], ..Default::default() }
    }

    #[test]
    fn a_non_finite_or_negative_gain_is_refused_by_its_field() {
        assert!(wall(100.0).validate().is_ok());
        let nan = wall(f64::NAN).validate().unwrap_err().to_string();
        assert!(nan.starts_with("wall[0].stiffness = NaN"), "{nan}");
        let negative = wall(-1.0).validate().unwrap_err().to_string();
        assert!(negative.contains("wall[0].stiffness = -1") && negative.contains("at least 0"), "{negative}");
    }

    #[test]
    fn a_cone_needs_a_direction_and_an_angle_a_cone_can_have() {
        let cone = |axis: [f64; 3], half_angle_deg: f64| Fixtures {
            cone: vec![Cone { axis, half_angle_deg, stiffness: 1.0, damping: 0.0 }],
            ..Default::default()
        };
        assert!(cone([0.0, 0.0, 1.0], 30.0).validate().is_ok());
        let zero = cone([0.0; 3], 30.0).validate().unwrap_err().to_string();
        assert!(zero.starts_with("cone[0].axis"), "{zero}");
        for angle in [0.0, 90.0, 120.0] {
            let e = cone([0.0, 0.0, 1.0], angle).validate().unwrap_err().to_string();
            assert!(e.starts_with("cone[0].half_angle_deg"), "{e}");
        }
    }
}
