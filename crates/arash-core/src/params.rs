//! Where each standard parameter sits in π (and each column in Y): the one place that knows the
//! order, so that no other code writes index arithmetic by hand.
//!
//! π = [body 0's ten inertial parameters, …, body B−1's, then per joint (fv, fc), then per joint
//! ke]. A body's ten are `[m, mcx, mcy, mcz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]` about its frame
//! origin (kg, kg·m, kg·m²); fv is viscous friction (N·m·s/rad or N·s/m), fc Coulomb friction
//! (N·m or N), ke the cable stiffness (N·m/rad or N/m).

use std::ops::Range;

use crate::spatial::BODY_PARAMS;

/// Inertial parameters per body.
pub const PER_BODY: usize = BODY_PARAMS;

/// Body `b`'s ten inertial parameters in π (the same for every robot: bodies come first).
pub const fn body(b: usize) -> Range<usize> {
    PER_BODY * b..PER_BODY * (b + 1)
}

/// The layout of the standard parameter vector of a robot with `bodies` moving bodies and `dof`
/// actuated joints.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParamLayout {
    bodies: usize,
    dof: usize,
}

impl ParamLayout {
    pub const fn new(bodies: usize, dof: usize) -> Self {
        Self { bodies, dof }
    }

    /// Length of π.
    pub const fn len(&self) -> usize {
        PER_BODY * self.bodies + 3 * self.dof
    }

    /// Whether π is empty (a robot with nothing in it).
    pub const fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Body `b`'s ten inertial parameters.
    pub const fn body(&self, b: usize) -> Range<usize> {
        body(b)
    }

    /// The body that parameter `i` belongs to, if it is inertial.
    pub const fn body_of(&self, i: usize) -> Option<usize> {
        if i < PER_BODY * self.bodies {
            Some(i / PER_BODY)
        } else {
            None
        }
    }

    /// Every inertial parameter.
    pub const fn inertial(&self) -> Range<usize> {
        0..PER_BODY * self.bodies
    }

    /// Every friction parameter (fv and fc of each joint, interleaved).
    pub const fn friction(&self) -> Range<usize> {
        PER_BODY * self.bodies..PER_BODY * self.bodies + 2 * self.dof
    }

    /// Joint `k`'s viscous friction fv.
    pub const fn viscous(&self, k: usize) -> usize {
        PER_BODY * self.bodies + 2 * k
    }

    /// Joint `k`'s Coulomb friction fc.
    pub const fn coulomb(&self, k: usize) -> usize {
        self.viscous(k) + 1
    }

    /// Every stiffness parameter.
    pub const fn stiffnesses(&self) -> Range<usize> {
        self.friction().end..self.len()
    }

    /// Joint `k`'s cable stiffness ke.
    pub const fn stiffness(&self, k: usize) -> usize {
        self.friction().end + k
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_layout_matches_the_models_parameter_names() {
        let model = crate::arash_asist();
        let names = model.parameter_names();
        let layout = model.layout();
        assert_eq!(layout.len(), names.len());
        for (k, joint) in model.joints.iter().enumerate() {
            assert_eq!(names[layout.viscous(k)], format!("{}.fv", joint.name));
            assert_eq!(names[layout.coulomb(k)], format!("{}.fc", joint.name));
            assert_eq!(names[layout.stiffness(k)], format!("{}.ke", joint.name));
        }
        for (b, body) in model.bodies.iter().enumerate() {
            assert_eq!(names[layout.body(b).start], format!("{}.m", body.name));
            assert_eq!(names[layout.body(b).start + 3], format!("{}.mz", body.name));
            assert_eq!(names[layout.body(b).end - 1], format!("{}.Iyz", body.name));
            assert_eq!(layout.body_of(layout.body(b).start), Some(b));
        }
        assert_eq!(layout.body_of(layout.friction().start), None);
        assert_eq!(layout.inertial().end, layout.friction().start);
        assert_eq!(layout.stiffnesses().end, layout.len());
    }
}
