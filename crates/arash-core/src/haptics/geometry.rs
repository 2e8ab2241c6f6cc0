//! Where the instrument is, as the fixtures see it: its tip, its direction (the frame's z), the
//! entry point, and the Jacobians that turn a fixture's force into joint torque. Built once;
//! [`Geometry::at`] does not allocate.

use super::fixtures::{FixtureError, Fixtures};
use crate::data::Data;
use crate::force::settings::default_frame;
use crate::kinematics::{forward_kinematics, frame_jacobian, frame_placement};
use crate::model::{Frame, Model};
use crate::spatial::Vec3;

/// The instrument at one configuration.
#[derive(Clone, Debug)]
pub struct Geometry {
    model: Model,
    data: Data,
    tip_frame: Frame,
    entry_frame: Frame,
    /// The tip's linear velocity and its frame's angular velocity per unit joint rate, base
    /// frame (3 × dof, row-major).
    pub linear: Vec<f64>,
    pub angular: Vec<f64>,
    /// The tip, the instrument's direction (unit) and the entry point, base frame.
    pub tip: Vec3,
    pub direction: Vec3,
    pub entry: Vec3,
}

impl Geometry {
    /// The frames `fixtures` names on `model`, else the robot's instrument tip and remote centre.
    pub fn new(model: &Model, fixtures: &Fixtures) -> Result<Self, FixtureError> {
        let named = default_frame(model);
        let resolve = |field: &'static str, given: &str, default: Option<String>| {
            let name = match (given, default) {
                ("", Some(d)) => d,
                ("", None) => {
                    return Err(FixtureError::Frame {
                        field,
                        why: format!(
                            "robot `{}` names no instrument tip and remote centre; name the frame",
                            model.name
                        ),
                    })
                }
                (g, _) => g.to_string(),
            };
            model.frame(&name).map_err(|e| FixtureError::Frame { field, why: e.to_string() })
        };
        let tip_frame = resolve("frame", &fixtures.frame, named.as_ref().map(|c| c.frame.clone()))?;
        let entry_frame = resolve("entry", &fixtures.entry, named.and_then(|c| c.about))?;
        let n = model.dof();
        Ok(Self {
            model: model.clone(),
            data: Data::new(model),
            tip_frame,
            entry_frame,
            linear: vec![0.0; 3 * n],
            angular: vec![0.0; 3 * n],
            tip: Vec3::zeros(),
            direction: Vec3::z(),
            entry: Vec3::zeros(),
        })
    }

    pub fn dof(&self) -> usize {
        self.model.dof()
    }

    /// Place the instrument at `q`.
    pub fn at(&mut self, q: &[f64]) {
        forward_kinematics(&self.model, &mut self.data, q);
        frame_jacobian(&self.model, &self.data, &self.tip_frame, &mut self.linear, &mut self.angular);
        let (rot, tip) = frame_placement(&self.data, &self.tip_frame);
        self.tip = tip;
        self.direction = rot.column(2).into_owned();
        self.entry = frame_placement(&self.data, &self.entry_frame).1;
    }

    /// Joint `k`'s column of the linear and of the angular Jacobian.
    pub fn column(&self, k: usize) -> (Vec3, Vec3) {
        let n = self.dof();
        let at = |m: &[f64]| Vec3::new(m[k], m[n + k], m[2 * n + k]);
        (at(&self.linear), at(&self.angular))
    }

    /// The tip's velocity at joint rates `qd` (base frame).
    pub fn tip_velocity(&self, qd: &[f64]) -> Vec3 {
        (0..self.dof()).map(|k| self.column(k).0 * qd[k]).sum()
    }

    /// The tip's depth beyond the entry point along the instrument, `s = (p − c)·z` (m), with its
    /// gradient `∂s/∂q` into `gradient` (the entry point is fixed in the base).
    pub fn depth(&self, gradient: &mut [f64]) -> f64 {
        let arm = self.tip - self.entry;
        for (k, g) in gradient.iter_mut().enumerate() {
            let (v, w) = self.column(k);
            *g = v.dot(&self.direction) + arm.dot(&w.cross(&self.direction));
        }
        arm.dot(&self.direction)
    }

    /// The angle `θ` between the instrument and the unit vector `axis` (rad) and the unit axis
    /// `n` it grows about, with its gradient `∂θ/∂q = J_ωᵀ n` into `gradient`. Where the
    /// instrument lies along the axis, `n` is undefined: zero, and so is the gradient.
    pub fn angle(&self, axis: &Vec3, gradient: &mut [f64]) -> (f64, Vec3) {
        let cross = axis.cross(&self.direction);
        let sin = cross.norm();
        let theta = sin.atan2(axis.dot(&self.direction));
        let about = if sin > 1e-12 { cross / sin } else { Vec3::zeros() };
        for (k, g) in gradient.iter_mut().enumerate() {
            *g = self.column(k).1.dot(&about);
        }
        (theta, about)
    }
}
