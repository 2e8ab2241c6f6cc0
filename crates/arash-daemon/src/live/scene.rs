//! The rig in Foxglove's 3D panel: each URDF joint's transform at the displayed cycle, so that
//! the robot description on `/robot_description` moves as the arm does, the hand's force as an
//! arrow at the frame it is estimated at (docs/force.md, "In the daemon"), and in the haptic
//! mode the fixtures' rendered force as a second arrow at the instrument tip (docs/haptics.md).
//!
//! Foxglove's URDF layer places the fixed joints' links itself; the moving ones need a transform
//! from their parent link each time they move, as ROS's robot_state_publisher sends. The arrow
//! starts at the frame's origin and points along the force, in the base frame, with a length of
//! [`ARROW_M_PER_N`] per newton.

use arash_core::kinematics::{forward_kinematics, frame_placement};
use arash_core::spatial::{Mat3, Vec3};
use arash_core::{Data, Frame, Model, UnknownFrame};
use foxglove::messages::{
    ArrowPrimitive, Color, FrameTransform, FrameTransforms, Pose, Quaternion, SceneEntity, SceneUpdate, Timestamp,
    Vector3,
};
use nalgebra::{Rotation3, UnitQuaternion};

/// The arrow's length per newton of force (m/N): 20 mm per newton, so that a hand's few newtons
/// read against an eye of 24 mm and an instrument a few centimetres long.
pub const ARROW_M_PER_N: f64 = 0.02;

/// The force below which no arrow is drawn (N): an arrow of no length has no direction.
pub const LEAST_ARROW_N: f64 = 1e-3;

/// The arrows' entity ids in the scene: each update replaces the last.
pub const ARROW_ID: &str = "hand_force";
pub const FIXTURE_ARROW_ID: &str = "fixture_force";

/// The hand's arrow is orange, the fixtures' blue: what the trainee pushed and what the eye
/// pushed back.
const HAND_COLOR: Color = Color { r: 1.0, g: 0.35, b: 0.1, a: 1.0 };
const FIXTURE_COLOR: Color = Color { r: 0.1, g: 0.45, b: 1.0, a: 1.0 };

/// The kinematics the scene is drawn with, built once from the robot's URDF.
pub struct Scene {
    model: Model,
    data: Data,
    /// The root link's name: the parent of the bodies on the base and the arrow's frame.
    base: String,
    /// The frame the hand's force is estimated at (`force.frame`), if any.
    frame: Option<Frame>,
    /// The instrument tip the fixtures render at by default, if the robot names one.
    tip: Option<Frame>,
}

impl Scene {
    /// The scene of `model`, with the hand's force drawn at `frame` (a frame name), if any.
    pub fn new(model: Model, frame: Option<&str>) -> Result<Self, UnknownFrame> {
        let frame = frame.map(|name| model.frame(name)).transpose()?;
        let tip = arash_core::force::settings::default_frame(&model).map(|c| model.frame(&c.frame)).transpose()?;
        let base = model.frames.first().map_or_else(|| "base".to_string(), |f| f.name.clone());
        Ok(Self { data: Data::new(&model), model, base, frame, tip })
    }

    /// Place the links at `q` (joint units, SI): what [`Self::transforms`] and
    /// [`Self::hand_arrow`] then draw.
    pub fn place(&mut self, q: &[f64]) {
        forward_kinematics(&self.model, &mut self.data, q);
    }

    /// Each moving body's placement in its parent link, as last placed, stamped `time`.
    pub fn transforms(&self, time: Timestamp) -> FrameTransforms {
        let d = &self.data;
        let transforms = self
            .model
            .bodies
            .iter()
            .enumerate()
            .map(|(b, body)| {
                let (rot, pos) = match body.parent {
                    Some(p) => {
                        let back = d.world_rot[p].transpose();
                        (back * d.world_rot[b], back * (d.world_pos[b] - d.world_pos[p]))
                    }
                    None => (d.world_rot[b], d.world_pos[b]),
                };
                let parent = body.parent.map_or(self.base.clone(), |p| self.model.bodies[p].name.clone());
                FrameTransform {
                    timestamp: Some(time),
                    parent_frame_id: parent,
                    child_frame_id: body.name.clone(),
                    translation: Some(vector(&pos)),
                    rotation: Some(quaternion(&rot)),
                }
            })
            .collect();
        FrameTransforms { transforms }
    }

    /// The hand's force `force` (N, base frame) as an arrow at the frame's origin, as last
    /// placed; an update that deletes the arrow when the force is below [`LEAST_ARROW_N`] or not
    /// finite, or when there is no frame.
    pub fn hand_arrow(&self, force: &[f64], time: Timestamp) -> SceneUpdate {
        self.arrow((ARROW_ID, HAND_COLOR), self.frame.as_ref(), force, time)
    }

    /// The fixtures' rendered force `force` (N, base frame) as an arrow at the instrument tip
    /// (the fixtures' default frame), as [`Self::hand_arrow`] draws the hand's.
    pub fn fixture_arrow(&self, force: &[f64], time: Timestamp) -> SceneUpdate {
        self.arrow((FIXTURE_ARROW_ID, FIXTURE_COLOR), self.tip.as_ref(), force, time)
    }

    fn arrow(&self, (id, color): (&str, Color), frame: Option<&Frame>, force: &[f64], time: Timestamp) -> SceneUpdate {
        let (Some(frame), [x, y, z]) = (frame, force) else { return self.no_arrow(id, time) };
        let f = Vec3::new(*x, *y, *z);
        let size = f.norm();
        if !(size.is_finite() && size >= LEAST_ARROW_N) {
            return self.no_arrow(id, time);
        }
        let (_, origin) = frame_placement(&self.data, frame);
        // The arrow points along its pose's x axis: the rotation that takes x onto the force.
        let along = Rotation3::rotation_between(&Vec3::x(), &f)
            .unwrap_or_else(|| Rotation3::from_axis_angle(&Vec3::z_axis(), std::f64::consts::PI));
        let length = ARROW_M_PER_N * size;
        let arrow = ArrowPrimitive {
            pose: Some(Pose { position: Some(vector(&origin)), orientation: Some(quaternion(along.matrix())) }),
            shaft_length: 0.75 * length,
            shaft_diameter: 0.001,
            head_length: 0.25 * length,
            head_diameter: 0.003,
            color: Some(color),
        };
        let entity = SceneEntity {
            timestamp: Some(time),
            frame_id: self.base.clone(),
            id: id.into(),
            arrows: vec![arrow],
            ..Default::default()
        };
        SceneUpdate { entities: vec![entity], ..Default::default() }
    }

    fn no_arrow(&self, id: &str, time: Timestamp) -> SceneUpdate {
        let deletion = foxglove::messages::SceneEntityDeletion {
            timestamp: Some(time),
            r#type: foxglove::messages::scene_entity_deletion::Type::MatchingId as i32,
            id: id.into(),
        };
        SceneUpdate { deletions: vec![deletion], ..Default::default() }
    }
}

/// A log time in nanoseconds as Foxglove's timestamp.
pub fn timestamp(log_time_ns: u64) -> Timestamp {
    let sec = u32::try_from(log_time_ns / 1_000_000_000).unwrap_or(u32::MAX);
    Timestamp::new(sec, (log_time_ns % 1_000_000_000) as u32)
}

fn vector(v: &Vec3) -> Vector3 {
    Vector3 { x: v.x, y: v.y, z: v.z }
}

fn quaternion(rot: &Mat3) -> Quaternion {
    let q = UnitQuaternion::from_matrix(rot);
    Quaternion { x: q.i, y: q.j, z: q.k, w: q.w }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rotation(q: &Quaternion) -> Mat3 {
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z));
        q.to_rotation_matrix().into_inner()
    }

    fn position(v: &Vector3) -> Vec3 {
        Vec3::new(v.x, v.y, v.z)
    }

    /// Chained from the base, parent to child as Foxglove composes them, the published
    /// transforms give every body the placement forward kinematics does, at a pose away from
    /// zero on every joint.
    #[test]
    fn the_transforms_compose_to_every_bodys_placement() {
        let model = arash_core::arash_asist();
        let mut scene = Scene::new(model.clone(), Some("instrument_tip")).unwrap();
        let q = [0.3, -0.4, 0.012];
        scene.place(&q);
        let published = scene.transforms(timestamp(1_500_000_000));
        assert_eq!(published.transforms.len(), model.bodies.len());
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q);
        let by_name = |name: &str| published.transforms.iter().find(|t| t.child_frame_id == name);
        for (b, body) in model.bodies.iter().enumerate() {
            let (mut rot, mut pos) = (Mat3::identity(), Vec3::zeros());
            let mut link = body.name.clone();
            while let Some(t) = by_name(&link) {
                // child in parent, applied under what is already known of the parent's parents
                let (r, p) = (rotation(t.rotation.as_ref().unwrap()), position(t.translation.as_ref().unwrap()));
                (rot, pos) = (r * rot, r * pos + p);
                link = t.parent_frame_id.clone();
            }
            assert_eq!(link, "base", "{} is not chained to the base", body.name);
            assert!((rot - data.world_rot[b]).norm() < 1e-12, "{}: {rot} against {}", body.name, data.world_rot[b]);
            assert!((pos - data.world_pos[b]).norm() < 1e-12, "{}: {pos} against {}", body.name, data.world_pos[b]);
        }
    }

    /// The arrow starts at the tip, points along the force and is 20 mm per newton long; below
    /// the least force, and without a frame, the arrow is deleted instead.
    #[test]
    fn the_hand_force_is_an_arrow_from_the_tip_along_the_force() {
        let model = arash_core::arash_asist();
        let mut scene = Scene::new(model.clone(), Some("instrument_tip")).unwrap();
        let q = [0.2, 0.5, 0.018];
        let force = [0.3, -1.2, 0.4];
        scene.place(&q);
        let update = scene.hand_arrow(&force, timestamp(0));
        let arrow = &update.entities[0].arrows[0];
        let pose = arrow.pose.as_ref().unwrap();
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q);
        let (_, tip) = frame_placement(&data, &model.frame("instrument_tip").unwrap());
        assert!((position(pose.position.as_ref().unwrap()) - tip).norm() < 1e-12);
        let f = Vec3::from_column_slice(&force);
        let direction = rotation(pose.orientation.as_ref().unwrap()) * Vec3::x();
        assert!((direction - f.normalize()).norm() < 1e-12, "{direction} against {}", f.normalize());
        let length = arrow.shaft_length + arrow.head_length;
        assert!((length - ARROW_M_PER_N * f.norm()).abs() < 1e-12);
        assert_eq!(update.entities[0].frame_id, "base");
        for quiet in [[0.0, 0.0, 1e-4], [f64::NAN, 0.0, 0.0]] {
            let gone = scene.hand_arrow(&quiet, timestamp(0));
            assert!(gone.entities.is_empty() && gone.deletions[0].id == ARROW_ID);
        }
        let mut bare = Scene::new(model, None).unwrap();
        bare.place(&q);
        assert!(bare.hand_arrow(&force, timestamp(0)).entities.is_empty());
        // A force straight against x still has a direction.
        let back = scene.hand_arrow(&[-2.0, 0.0, 0.0], timestamp(0));
        let pose = back.entities[0].arrows[0].pose.as_ref().unwrap();
        let direction = rotation(pose.orientation.as_ref().unwrap()) * Vec3::x();
        assert!((direction + Vec3::x()).norm() < 1e-12, "{direction}");
    }

    /// The fixtures' arrow is at the instrument tip whichever frame the hand's force is estimated
    /// at, its own entity (so the two arrows do not replace each other), and deleted outside the
    /// mode, where the rendered force is zero.
    #[test]
    fn the_fixtures_force_is_its_own_arrow_at_the_tip() {
        let model = arash_core::arash_asist();
        let mut scene = Scene::new(model.clone(), Some("insertion_carriage")).unwrap();
        let q = [-0.1, 0.4, 0.02];
        scene.place(&q);
        let update = scene.fixture_arrow(&[0.0, 0.5, -0.5], timestamp(0));
        let entity = &update.entities[0];
        assert_eq!(entity.id, FIXTURE_ARROW_ID);
        assert_ne!(FIXTURE_ARROW_ID, ARROW_ID);
        let mut data = Data::new(&model);
        forward_kinematics(&model, &mut data, &q);
        let (_, tip) = frame_placement(&data, &model.frame("instrument_tip").unwrap());
        let at = position(entity.arrows[0].pose.as_ref().unwrap().position.as_ref().unwrap());
        assert!((at - tip).norm() < 1e-12, "{at} against the tip {tip}");
        let gone = scene.fixture_arrow(&[0.0; 3], timestamp(0));
        assert!(gone.entities.is_empty() && gone.deletions[0].id == FIXTURE_ARROW_ID);
    }
}
