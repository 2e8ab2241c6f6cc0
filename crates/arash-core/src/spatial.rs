//! Spatial (6-D) motion and force vectors, angular part first (Featherstone's convention).
//!
//! Every vector here is expressed in the coordinates of one body frame and referred to that frame's
//! origin. The ten inertial parameters of a body are ordered
//! `[m, m·cx, m·cy, m·cz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]`: mass, first moment of mass, and the inertia
//! tensor about the frame origin, in the frame. `Ixy` is the tensor element `I[0][1] = −∫xy dm`,
//! the same sign convention as URDF's `ixy`.

use nalgebra::{Matrix3, Vector3};

pub type Vec3 = Vector3<f64>;
pub type Mat3 = Matrix3<f64>;

/// Number of inertial parameters per body.
pub const BODY_PARAMS: usize = 10;

/// A spatial motion vector: angular velocity `w` and the linear velocity `v` of the frame origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    pub w: Vec3,
    pub v: Vec3,
}

/// A spatial force: moment `n` about the frame origin and force `f`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Force {
    pub n: Vec3,
    pub f: Vec3,
}

impl Motion {
    pub const ZERO: Motion = Motion { w: Vec3::new(0.0, 0.0, 0.0), v: Vec3::new(0.0, 0.0, 0.0) };

    pub fn new(w: Vec3, v: Vec3) -> Self {
        Self { w, v }
    }

    /// Spatial motion cross product `self × m`.
    #[inline]
    pub fn cross(&self, m: &Motion) -> Motion {
        Motion { w: self.w.cross(&m.w), v: self.w.cross(&m.v) + self.v.cross(&m.w) }
    }

    /// Spatial force cross product `self ×* f`.
    #[inline]
    pub fn cross_force(&self, f: &Force) -> Force {
        Force { n: self.w.cross(&f.n) + self.v.cross(&f.f), f: self.w.cross(&f.f) }
    }

    #[inline]
    pub fn scaled(&self, s: f64) -> Motion {
        Motion { w: self.w * s, v: self.v * s }
    }

    /// `self += s · m`
    #[inline]
    pub fn axpy(&mut self, s: f64, m: &Motion) {
        self.w += m.w * s;
        self.v += m.v * s;
    }

    #[inline]
    pub fn add(&self, m: &Motion) -> Motion {
        Motion { w: self.w + m.w, v: self.v + m.v }
    }

    #[inline]
    pub fn sub(&self, m: &Motion) -> Motion {
        Motion { w: self.w - m.w, v: self.v - m.v }
    }

    /// Re-express a motion given in a parent frame in a child frame whose orientation is `rot`
    /// (child axes in parent coordinates) and whose origin is at `pos` (parent coordinates).
    #[inline]
    pub fn to_child(&self, rot: &Mat3, pos: &Vec3) -> Motion {
        Motion { w: rot.tr_mul(&self.w), v: rot.tr_mul(&(self.v + self.w.cross(pos))) }
    }

    /// Power pairing `self · f`.
    #[inline]
    pub fn dot(&self, f: &Force) -> f64 {
        self.w.dot(&f.n) + self.v.dot(&f.f)
    }
}

impl Force {
    pub const ZERO: Force = Force { n: Vec3::new(0.0, 0.0, 0.0), f: Vec3::new(0.0, 0.0, 0.0) };

    /// Re-express a force given in a child frame in its parent frame, the child's orientation
    /// being `rot` and its origin `pos` in the parent (the dual of [`Motion::to_child`]: the
    /// power `m · f` is the same in either frame).
    #[inline]
    pub fn to_parent(&self, rot: &Mat3, pos: &Vec3) -> Force {
        let f = rot * self.f;
        Force { n: rot * self.n + pos.cross(&f), f }
    }

    #[inline]
    pub fn add(&self, g: &Force) -> Force {
        Force { n: self.n + g.n, f: self.f + g.f }
    }
}

/// `I(π) x`: the spatial inertia of a body with parameters `p` applied to motion `x`.
#[inline]
pub fn apply_inertia(p: &[f64], x: &Motion) -> Force {
    let h = Vec3::new(p[1], p[2], p[3]);
    let rot_inertia = rotational_inertia(p);
    Force { n: rot_inertia * x.w + h.cross(&x.v), f: x.v * p[0] - h.cross(&x.w) }
}

/// The 3×3 inertia tensor about the frame origin held in parameters `p[4..10]`.
pub fn rotational_inertia(p: &[f64]) -> Mat3 {
    Mat3::new(p[4], p[7], p[8], p[7], p[5], p[9], p[8], p[9], p[6])
}

/// The ten coefficients `ρ` with `u · (I(π) w) = ρ · π`: the bilinear form of the spatial inertia,
/// symmetric in `u` and `w`. Every regressor in this crate is a sum of these.
#[inline]
pub fn inertia_coefficients(u: &Motion, w: &Motion) -> [f64; BODY_PARAMS] {
    let h = w.v.cross(&u.w) + u.v.cross(&w.w);
    let (a, b) = (&u.w, &w.w);
    [
        u.v.dot(&w.v),
        h.x,
        h.y,
        h.z,
        a.x * b.x,
        a.y * b.y,
        a.z * b.z,
        a.x * b.y + a.y * b.x,
        a.x * b.z + a.z * b.x,
        a.y * b.z + a.z * b.y,
    ]
}

/// Standard parameters from mass, centre of mass `c` and the inertia tensor about the centre of
/// mass `inertia_com`, all in the body frame (parallel-axis theorem).
pub fn params_from_com(mass: f64, c: &Vec3, inertia_com: &Mat3) -> [f64; BODY_PARAMS] {
    let i_o = inertia_com + (Mat3::identity() * c.dot(c) - c * c.transpose()) * mass;
    [
        mass,
        mass * c.x,
        mass * c.y,
        mass * c.z,
        i_o[(0, 0)],
        i_o[(1, 1)],
        i_o[(2, 2)],
        i_o[(0, 1)],
        i_o[(0, 2)],
        i_o[(1, 2)],
    ]
}

/// The 4×4 pseudo-inertia matrix `[[Σ, h], [hᵀ, m]]` with `Σ = ½ tr(I)·1 − I` (Wensing, Kim and
/// Slotine 2017). The parameters are physically consistent exactly when it is positive semidefinite.
pub fn pseudo_inertia(p: &[f64]) -> nalgebra::Matrix4<f64> {
    let i = rotational_inertia(p);
    let sigma = Mat3::identity() * (0.5 * i.trace()) - i;
    let mut j = nalgebra::Matrix4::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&sigma);
    for k in 0..3 {
        j[(k, 3)] = p[1 + k];
        j[(3, k)] = p[1 + k];
    }
    j[(3, 3)] = p[0];
    j
}

/// Rotation matrix from URDF roll-pitch-yaw (fixed axes X, then Y, then Z).
pub fn rpy_to_rotation(roll: f64, pitch: f64, yaw: f64) -> Mat3 {
    *nalgebra::Rotation3::from_euler_angles(roll, pitch, yaw).matrix()
}

/// Rotation by `angle` about the unit `axis`.
#[inline]
pub fn axis_angle(axis: &Vec3, angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    axis_rotation(axis, s, c)
}

/// Rotation about the unit `axis` by the angle whose sine and cosine are `s` and `c`.
#[inline]
pub fn axis_rotation(axis: &Vec3, s: f64, c: f64) -> Mat3 {
    // Rodrigues as c·1 + s·[a]× + (1 − c)·a aᵀ: no normalisation, no allocation, few products.
    let t = 1.0 - c;
    let (x, y, z) = (axis.x, axis.y, axis.z);
    Mat3::new(
        c + t * x * x,
        t * x * y - s * z,
        t * x * z + s * y,
        t * x * y + s * z,
        c + t * y * y,
        t * y * z - s * x,
        t * x * z - s * y,
        t * y * z + s * x,
        c + t * z * z,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motion(seed: f64) -> Motion {
        Motion::new(
            Vec3::new(seed.sin(), (2.0 * seed).cos(), 0.3 * seed),
            Vec3::new(-seed, (3.0 * seed).sin(), 1.0 - seed),
        )
    }

    #[test]
    fn coefficients_reproduce_the_inertia_pairing() {
        let p = params_from_com(
            1.3,
            &Vec3::new(0.1, -0.2, 0.05),
            &Mat3::new(0.02, 0.001, -0.002, 0.001, 0.03, 0.0005, -0.002, 0.0005, 0.025),
        );
        for s in [0.1, 0.7, 2.3] {
            let (u, w) = (motion(s), motion(s + 1.1));
            let direct = u.dot(&apply_inertia(&p, &w));
            let coeffs = inertia_coefficients(&u, &w);
            let via: f64 = coeffs.iter().zip(p.iter()).map(|(a, b)| a * b).sum();
            assert!((direct - via).abs() < 1e-14, "{direct} vs {via}");
            let swapped = w.dot(&apply_inertia(&p, &u));
            assert!((direct - swapped).abs() < 1e-14, "spatial inertia must be symmetric");
        }
    }

    #[test]
    fn rodrigues_matches_nalgebra() {
        let axis = Vec3::new(0.3, -0.5, 0.8).normalize();
        let ours = axis_angle(&axis, 0.77);
        let theirs = *nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), 0.77).matrix();
        assert!((ours - theirs).norm() < 1e-15);
    }

    #[test]
    fn pseudo_inertia_of_a_point_mass_is_rank_one() {
        let p = params_from_com(2.0, &Vec3::new(0.1, 0.2, 0.3), &Mat3::zeros());
        let eig = pseudo_inertia(&p).symmetric_eigenvalues();
        let mut e: Vec<f64> = eig.iter().copied().collect();
        e.sort_by(f64::total_cmp);
        assert!(e[0].abs() < 1e-12 && e[1].abs() < 1e-12 && e[2].abs() < 1e-12 && e[3] > 1.0);
    }
}
