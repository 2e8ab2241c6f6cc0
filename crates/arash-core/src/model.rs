//! The immutable description of a robot: a kinematic tree whose joints are each driven by one
//! actuated coordinate through a mimic coupling (`q_tree = multiplier · q[joint] + offset`).
//!
//! Closed chains such as ARASH:ASiST's parallelogram are described the ROS way: the loop is cut
//! into a tree and every passive joint mimics an actuated one. Build a [`Model`] once (usually with
//! [`crate::urdf::parse_urdf`]) and pair it with a [`crate::Data`] workspace for evaluation.

use crate::params::ParamLayout;
use crate::spatial::{Mat3, Vec3, BODY_PARAMS};

/// How a body moves relative to its parent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about `axis` (URDF `revolute` or `continuous`).
    Revolute,
    /// Translation along `axis`.
    Prismatic,
    /// Rigidly attached to its parent.
    Fixed,
}

/// The actuated coordinate that drives a tree joint: `q_tree = multiplier · q[index] + offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coupling {
    pub index: usize,
    pub multiplier: f64,
    pub offset: f64,
}

/// One moving rigid body and the joint that connects it to its parent.
#[derive(Clone, Debug)]
pub struct Body {
    /// URDF link name.
    pub name: String,
    /// URDF name of the joint into this body.
    pub joint: String,
    /// Index of the parent body, or `None` when the parent is the fixed base.
    pub parent: Option<usize>,
    pub kind: JointKind,
    /// Unit joint axis in this body's frame (the joint frame).
    pub axis: Vec3,
    /// Orientation of the joint frame at zero motion, in the parent frame.
    pub origin_rot: Mat3,
    /// Position of the joint frame origin, in the parent frame (m).
    pub origin_pos: Vec3,
    /// `None` for fixed joints.
    pub coupling: Option<Coupling>,
    /// CAD inertial parameters `[m, mcx, mcy, mcz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]` about this body's
    /// frame origin (kg, kg·m, kg·m²).
    pub inertial: [f64; BODY_PARAMS],
}

/// An actuated joint, one per generalised coordinate.
#[derive(Clone, Debug)]
pub struct ActuatedJoint {
    pub name: String,
    /// The body this joint moves directly (multiplier 1, offset 0).
    pub body: usize,
    pub kind: JointKind,
    /// Position limits (rad or m); infinite for continuous joints.
    pub lower: f64,
    pub upper: f64,
    /// Speed limit (rad/s or m/s); infinite when the URDF gives none.
    pub velocity: f64,
    /// Effort limit (N·m or N); infinite when the URDF gives none.
    pub effort: f64,
    /// CAD viscous friction (N·m·s/rad or N·s/m), URDF `<dynamics damping>`.
    pub viscous: f64,
    /// CAD Coulomb friction (N·m or N), URDF `<dynamics friction>`.
    pub coulomb: f64,
}

/// How the Coulomb friction columns turn velocity into a direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CoulombShape {
    /// `sign(q̇)`, with `sign(0) = 0`.
    Sign,
    /// `tanh(q̇ / epsilon)`: smooth through zero, for controllers.
    Tanh { epsilon: f64 },
}

/// `tanh(x)`, with the saturated tails (|x| ≥ 22, where `tanh` is ±1 to the last bit) taken
/// without the library call: a law's choice evaluates candidate laws at every sample of a log,
/// and at a narrow law's width most samples lie there.
#[inline]
fn saturating_tanh(x: f64) -> f64 {
    match x.abs() >= 22.0 {
        true => 1.0f64.copysign(x),
        false => x.tanh(),
    }
}

impl CoulombShape {
    #[inline]
    pub fn eval(self, qd: f64) -> f64 {
        match self {
            CoulombShape::Sign if qd > 0.0 => 1.0,
            CoulombShape::Sign if qd < 0.0 => -1.0,
            CoulombShape::Sign => 0.0,
            CoulombShape::Tanh { epsilon } => saturating_tanh(qd / epsilon),
        }
    }

    /// `tanh(q̇/epsilon)`, or `None` for a width that is not positive and finite: the check
    /// every front end that lets a user declare the law applies.
    pub fn tanh(epsilon: f64) -> Option<Self> {
        (epsilon.is_finite() && epsilon > 0.0).then_some(CoulombShape::Tanh { epsilon })
    }

    /// The law with width `epsilon` (`None`: `sign(q̇)`), as model files store it.
    pub fn of_epsilon(epsilon: Option<f64>) -> Self {
        epsilon.map_or(CoulombShape::Sign, |epsilon| CoulombShape::Tanh { epsilon })
    }

    /// The width of a `tanh` law (`None` for `sign(q̇)`).
    pub fn epsilon(self) -> Option<f64> {
        match self {
            CoulombShape::Sign => None,
            CoulombShape::Tanh { epsilon } => Some(epsilon),
        }
    }
}

impl std::fmt::Display for CoulombShape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CoulombShape::Sign => f.write_str("sign(q̇)"),
            CoulombShape::Tanh { epsilon } => write!(f, "tanh(q̇/{epsilon:.3e})"),
        }
    }
}

/// Every joint's Coulomb law, and whether it is the robot's declared law or left to the data.
///
/// A robot loaded from a URDF says nothing about how its friction rises through zero speed: its
/// laws are `sign(q̇)` and undeclared, and identification and the diagnosis choose each joint's
/// friction velocity from the data (`signal/friction_law.rs`). A law the user sets, or one a
/// model file was fitted with, is declared and used as it is: its Coulomb coefficients belong to
/// it.
#[derive(Clone, Debug, PartialEq)]
pub struct CoulombLaws {
    shapes: Vec<CoulombShape>,
    declared: bool,
}

impl CoulombLaws {
    /// `sign(q̇)` on each of `dof` joints, left to the data.
    pub fn undeclared(dof: usize) -> Self {
        Self { shapes: vec![CoulombShape::Sign; dof], declared: false }
    }

    /// These laws, one per joint, declared.
    pub fn declared(shapes: Vec<CoulombShape>) -> Self {
        Self { shapes, declared: true }
    }

    /// One law on every one of `dof` joints, declared.
    pub fn uniform(shape: CoulombShape, dof: usize) -> Self {
        Self::declared(vec![shape; dof])
    }

    /// The laws of friction velocities `velocities` (`None`: `sign(q̇)`), as model files store
    /// them, declared; `None` for a velocity that is not positive and finite, with its joint.
    pub fn of_velocities(velocities: &[Option<f64>]) -> Result<Self, (usize, f64)> {
        let shapes = velocities
            .iter()
            .enumerate()
            .map(|(k, v)| match *v {
                None => Ok(CoulombShape::Sign),
                Some(v) => CoulombShape::tanh(v).ok_or((k, v)),
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self::declared(shapes))
    }

    /// Joint `k`'s law.
    #[inline]
    pub fn shape(&self, k: usize) -> CoulombShape {
        self.shapes[k]
    }

    /// Joint `k`'s Coulomb direction at velocity `qd`.
    #[inline]
    pub fn eval(&self, k: usize, qd: f64) -> f64 {
        self.shapes[k].eval(qd)
    }

    pub fn shapes(&self) -> &[CoulombShape] {
        &self.shapes
    }

    /// Whether the laws are set (by the user, or by the model file a fit was made with) rather
    /// than left to the data.
    pub fn is_declared(&self) -> bool {
        self.declared
    }

    /// Each joint's friction velocity (`None`: `sign(q̇)`).
    pub fn velocities(&self) -> Vec<Option<f64>> {
        self.shapes.iter().map(|s| s.epsilon()).collect()
    }

    /// The one law every joint shares, if they share one.
    pub fn common(&self) -> Option<CoulombShape> {
        let first = *self.shapes.first()?;
        self.shapes.iter().all(|s| *s == first).then_some(first)
    }
}

impl std::fmt::Display for CoulombLaws {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.common() {
            Some(shape) => write!(f, "{shape}")?,
            None => {
                let laws: Vec<String> =
                    self.shapes.iter().enumerate().map(|(k, s)| format!("joint {k}: {s}")).collect();
                f.write_str(&laws.join(", "))?;
            }
        }
        if !self.declared {
            f.write_str(" (undeclared)")?;
        }
        Ok(())
    }
}

/// A robot model: bodies in topological order (parents first) and its actuated joints.
///
/// Parameter vector layout, `P = 10·bodies + 3·dof` entries:
/// - body `b` at `10b .. 10b+10`: `[m, mcx, mcy, mcz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`;
/// - joint `k` friction at `10·bodies + 2k` (viscous `fv`) and `10·bodies + 2k + 1` (Coulomb `fc`);
/// - joint `k` elastic stiffness `ke` at `10·bodies + 2·dof + k` (torque `ke·q_k`).
#[derive(Clone, Debug)]
pub struct Model {
    pub name: String,
    pub bodies: Vec<Body>,
    pub joints: Vec<ActuatedJoint>,
    /// Gravity acceleration in the base frame (m/s²).
    pub gravity: Vec3,
    /// Each joint's Coulomb law ([`CoulombLaws`]).
    pub coulomb_laws: CoulombLaws,
    /// What the URDF declared that loads but deserves a look (empty for a clean description).
    pub warnings: Vec<ModelWarning>,
    /// The named frames that are not bodies: the root link and every massless link on a fixed
    /// joint (a tool point, a sensor mount).
    pub frames: Vec<Frame>,
}

/// A named frame rigidly attached to a body or to the base, placed in that body's frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub name: String,
    /// The body it moves with; `None` for the base.
    pub body: Option<usize>,
    pub rot: Mat3,
    /// Its origin in the body's frame (m).
    pub pos: Vec3,
}

/// A frame name that is neither a body nor a frame of the model.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("robot `{robot}` has no frame `{name}` (its frames: {known})")]
pub struct UnknownFrame {
    pub robot: String,
    pub name: String,
    pub known: String,
}

/// Something a robot description declares that arash loads, but that its user should know.
#[derive(Clone, Debug, PartialEq)]
pub enum ModelWarning {
    /// A link whose rotational inertia about its centre of mass is only positive semidefinite:
    /// a point mass (all three principal moments zero) or a thin rod (one zero).
    SemidefiniteInertia { link: String, eigenvalues: [f64; 3] },
}

impl std::fmt::Display for ModelWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::SemidefiniteInertia { link, eigenvalues: [a, b, c] } => write!(
                f,
                "link `{link}`: inertia tensor is only positive semidefinite (principal moments {a:.3e}, {b:.3e}, {c:.3e} kg·m²); loaded as a point mass or rod"
            ),
        }
    }
}

impl Model {
    /// Number of actuated coordinates.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Where each parameter sits in π.
    pub fn layout(&self) -> ParamLayout {
        ParamLayout::new(self.bodies.len(), self.dof())
    }

    /// How far from body `b`'s frame a mass on that body can sit (m). A body that carries
    /// others reaches its children's joints (a prismatic child over its whole travel) and twice
    /// its own declared centre of mass; the last body of a chain carries whatever a user
    /// mounts, a tool, so it gets the whole robot's reach: every joint offset, every prismatic
    /// travel, and twice the farthest declared centre of mass.
    pub fn body_extent_m(&self, b: usize) -> f64 {
        // A child's joint, over its travel when it slides.
        let joint_reach = |i: usize| {
            let travel: f64 = self
                .joints
                .iter()
                .filter(|j| j.body == i && j.kind == JointKind::Prismatic)
                .map(|j| (j.upper - j.lower).abs())
                .filter(|t| t.is_finite())
                .sum();
            self.bodies[i].origin_pos.norm() + travel
        };
        let com = |body: &Body| match body.inertial[0] {
            m if m > 0.0 => (body.inertial[1].powi(2) + body.inertial[2].powi(2) + body.inertial[3].powi(2)).sqrt() / m,
            _ => 0.0,
        };
        let children: Vec<usize> = (0..self.bodies.len()).filter(|&c| self.bodies[c].parent == Some(b)).collect();
        if children.is_empty() {
            let offsets: f64 = (0..self.bodies.len()).map(joint_reach).sum();
            return offsets + 2.0 * self.bodies.iter().map(com).fold(0.0, f64::max);
        }
        children.into_iter().map(joint_reach).fold(2.0 * com(&self.bodies[b]), f64::max)
    }

    /// Length of the standard parameter vector.
    pub fn num_params(&self) -> usize {
        self.layout().len()
    }

    /// The frame called `name`: a body's own frame, or one of [`Self::frames`].
    pub fn frame(&self, name: &str) -> Result<Frame, UnknownFrame> {
        if let Some(b) = self.bodies.iter().position(|b| b.name == name) {
            return Ok(Frame { name: name.to_string(), body: Some(b), rot: Mat3::identity(), pos: Vec3::zeros() });
        }
        self.frames.iter().find(|f| f.name == name).cloned().ok_or_else(|| UnknownFrame {
            robot: self.name.clone(),
            name: name.to_string(),
            known: self
                .bodies
                .iter()
                .map(|b| b.name.as_str())
                .chain(self.frames.iter().map(|f| f.name.as_str()))
                .collect::<Vec<_>>()
                .join(", "),
        })
    }

    /// Names of the joints, in `q` order.
    pub fn joint_names(&self) -> Vec<String> {
        self.joints.iter().map(|j| j.name.clone()).collect()
    }

    /// Names of the standard parameters, in vector order: `link.m`, `link.mx`, …, `joint.fv`,
    /// `joint.fc`, `joint.ke`.
    pub fn parameter_names(&self) -> Vec<String> {
        const SUFFIX: [&str; BODY_PARAMS] = ["m", "mx", "my", "mz", "Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz"];
        let mut names = Vec::with_capacity(self.num_params());
        for body in &self.bodies {
            names.extend(SUFFIX.iter().map(|s| format!("{}.{}", body.name, s)));
        }
        for joint in &self.joints {
            names.push(format!("{}.fv", joint.name));
            names.push(format!("{}.fc", joint.name));
        }
        names.extend(self.joints.iter().map(|j| format!("{}.ke", j.name)));
        names
    }

    /// The CAD parameter vector: inertials from the URDF, friction from `<dynamics>`, and zero
    /// cable stiffness (CAD has no value for it).
    pub fn cad_parameters(&self) -> Vec<f64> {
        let mut p = Vec::with_capacity(self.num_params());
        for body in &self.bodies {
            p.extend_from_slice(&body.inertial);
        }
        for joint in &self.joints {
            p.push(joint.viscous);
            p.push(joint.coulomb);
        }
        p.extend(std::iter::repeat_n(0.0, self.dof()));
        p
    }

    /// The constant mimic coupling `G` (bodies × dof, row-major): `q̇_tree = G q̇`.
    pub fn coupling_matrix(&self) -> Vec<f64> {
        let n = self.dof();
        let mut g = vec![0.0; self.bodies.len() * n];
        for (b, body) in self.bodies.iter().enumerate() {
            if let Some(c) = body.coupling {
                g[b * n + c.index] = c.multiplier;
            }
        }
        g
    }

    /// Position limits as `(lower, upper)` per actuated joint.
    pub fn position_limits(&self) -> Vec<(f64, f64)> {
        self.joints.iter().map(|j| (j.lower, j.upper)).collect()
    }
}

#[cfg(test)]
mod tanh_tests {
    use super::saturating_tanh;

    /// The shortcut changes no value: where it answers ±1, so does `tanh`, to the last bit.
    #[test]
    fn the_saturating_tanh_is_the_librarys_bit_for_bit() {
        let mut x = -40.0;
        while x <= 40.0 {
            assert_eq!(saturating_tanh(x).to_bits(), x.tanh().to_bits(), "at {x}");
            x += 1.0 / 64.0;
        }
        for x in [21.999999999999996, 22.0, -22.0, f64::INFINITY, f64::NEG_INFINITY, 1e300, -0.0, 0.0] {
            assert_eq!(saturating_tanh(x).to_bits(), x.tanh().to_bits(), "at {x}");
        }
        assert!(saturating_tanh(f64::NAN).is_nan());
    }
}
