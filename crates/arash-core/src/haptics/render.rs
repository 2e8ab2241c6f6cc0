//! The fixtures' joint torque at one sample: each fixture's force (or moment, for a cone) from
//! its potential and its damper, mapped through the instrument's Jacobian. Built once;
//! [`FixtureRenderer::add_torque`] does not allocate.

use super::fixtures::{FixtureError, Fixtures};
use super::geometry::Geometry;
use crate::dense::{axpy, dot};
use crate::model::Model;
use crate::spatial::Vec3;

/// What the fixtures rendered at one sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Rendered {
    /// The force at the tip, base frame (N): the walls', the springs' and the fields'.
    pub force: [f64; 3],
    /// The moment about the entry point, base frame (N·m): the cones' and the force's.
    pub moment: [f64; 3],
    /// The energy the fixtures' springs hold (J): what a passive rendering never lets grow
    /// beyond the work the hand did.
    pub energy: f64,
    /// Whether a wall or a cone is engaged.
    pub contact: bool,
}

/// A sample the fixtures cannot render: the state or the result is not a number.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RenderError {
    #[error("the fixtures were given {what} {value} on joint {joint}")]
    NotFinite { what: &'static str, joint: usize, value: f64 },
    #[error("the fixtures rendered a torque that is not a number on joint {joint}")]
    Rendered { joint: usize },
}

/// The fixtures of one file on one robot.
#[derive(Clone, Debug)]
pub struct FixtureRenderer {
    fixtures: Fixtures,
    /// Each cone's unit axis and half angle (rad).
    cones: Vec<(Vec3, f64)>,
    geometry: Geometry,
    gradient: Vec<f64>,
    torque: Vec<f64>,
}

impl FixtureRenderer {
    /// The renderer of `fixtures` on `model`, its fields checked (not its passivity: see
    /// [`super::check_passivity`]).
    pub fn new(model: &Model, fixtures: &Fixtures) -> Result<Self, FixtureError> {
        fixtures.validate()?;
        let cones =
            fixtures.cone.iter().map(|c| (Vec3::from(c.axis).normalize(), c.half_angle_deg.to_radians())).collect();
        let n = model.dof();
        Ok(Self {
            fixtures: fixtures.clone(),
            cones,
            geometry: Geometry::new(model, fixtures)?,
            gradient: vec![0.0; n],
            torque: vec![0.0; n],
        })
    }

    /// Add the fixtures' joint torque at state `q`, `qd` to `tau`. A non-finite state or result
    /// is refused and leaves `tau` as it was.
    pub fn add_torque(&mut self, q: &[f64], qd: &[f64], tau: &mut [f64]) -> Result<Rendered, RenderError> {
        for (what, x) in [("the position", q), ("the velocity", qd)] {
            if let Some((joint, &value)) = x.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                return Err(RenderError::NotFinite { what, joint, value });
            }
        }
        self.geometry.at(q);
        self.torque.fill(0.0);
        let mut out = Rendered::default();
        let mut force = Vec3::zeros();
        let mut moment = Vec3::zeros();
        let velocity = self.geometry.tip_velocity(qd);
        // Every wall is at a depth along the same instrument: one depth, gradient and rate.
        let (depth, rate) = match self.fixtures.wall.is_empty() {
            true => (0.0, 0.0),
            false => (self.geometry.depth(&mut self.gradient), dot(&self.gradient, qd)),
        };
        for wall in &self.fixtures.wall {
            let past = depth - wall.depth_m;
            if past <= 0.0 {
                continue;
            }
            // A wall pushes; it never holds the tip in when the hand pulls out fast.
            let push = (wall.stiffness * past + wall.damping * rate).max(0.0);
            axpy(&mut self.torque, -push, &self.gradient);
            force -= push * self.geometry.direction;
            out.energy += 0.5 * wall.stiffness * past * past;
            out.contact = true;
        }
        for (cone, (axis, half_angle)) in self.fixtures.cone.iter().zip(&self.cones) {
            let (angle, about) = self.geometry.angle(axis, &mut self.gradient);
            let past = angle - half_angle;
            if past <= 0.0 {
                continue;
            }
            let rate = dot(&self.gradient, qd);
            let turn = (cone.stiffness * past + cone.damping * rate).max(0.0);
            axpy(&mut self.torque, -turn, &self.gradient);
            moment -= turn * about;
            out.energy += 0.5 * cone.stiffness * past * past;
            out.contact = true;
        }
        let mut tip = -self.fixtures.viscous.iter().map(|v| v.damping).sum::<f64>() * velocity;
        for spring in &self.fixtures.spring {
            let stretch = self.geometry.tip - Vec3::from(spring.point);
            tip -= spring.stiffness * stretch + spring.damping * velocity;
            out.energy += 0.5 * spring.stiffness * stretch.norm_squared();
        }
        for (k, t) in self.torque.iter_mut().enumerate() {
            *t += self.geometry.column(k).0.dot(&tip);
        }
        force += tip;
        moment += (self.geometry.tip - self.geometry.entry).cross(&force);
        if let Some(joint) = self.torque.iter().position(|t| !t.is_finite()) {
            return Err(RenderError::Rendered { joint });
        }
        tau.iter_mut().zip(&self.torque).for_each(|(t, r)| *t += r);
        out.force = force.into();
        out.moment = moment.into();
        Ok(out)
    }
}
