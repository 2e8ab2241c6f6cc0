//! Whether a fixture file can be rendered passively by the loop that renders it.
//!
//! A spring sampled every `T` and held in between acts like the spring and a negative damping of
//! `K·T/2`; a delay `L` between the measurement and the command adds `K·L`. Colgate and
//! Schenkel's condition for a sampled wall of stiffness `K` and virtual damping `B` on a device of
//! physical damping `b` is `b > K·T/2 + |B|` ("Passivity of a class of sampled-data systems",
//! J. Robotic Systems 14(1), 1997); with the delay, `b > K·(T/2 + L) + |B|`. On a robot the
//! damping a fixture meets depends on the direction it pushes in: along the gradient `g` of its
//! coordinate (the depth, the angle) it is `b = 1/(gᵀ D⁻¹ g)`, `D` the joints' own damping the
//! compensation leaves (their viscous friction, less the share compensated); a spring or a field
//! at the tip meets the least over directions, `1/λ_max(J D⁻¹ Jᵀ)`. Several fixtures acting at
//! once pass together when their shares `(K·(T/2 + L) + |B|)/b` add to less than one (by
//! Cauchy–Schwarz, that keeps `D − Σ (K·(T/2 + L) + |B|) g gᵀ` positive definite).
//!
//! The bound is checked over the joints' whole range, sampled on a grid, wherever the fixture
//! could act: conservative, so that no configuration the instrument reaches renders actively.

use nalgebra::{Matrix3, SymmetricEigen};

use super::fixtures::{FixtureError, Fixtures};
use super::geometry::Geometry;
use crate::model::Model;
use crate::params::ParamLayout;
use crate::spatial::Vec3;

/// Configurations the grid samples at most: enough for ARASH:ASiST's three joints at 16 points
/// each, and two or three points per joint on a seven-joint arm.
const GRID_CONFIGURATIONS: usize = 4096;

/// The loop a fixture file is rendered by.
#[derive(Clone, Debug)]
pub struct RenderLoop {
    /// Each joint's physical damping the compensation leaves (N·m·s/rad or N·s/m).
    pub damping: Vec<f64>,
    /// The cycle's period `T` (s).
    pub period_s: f64,
    /// The delay between a measurement and the command computed from it acting, beyond the
    /// hold's `T/2` (s).
    pub latency_s: f64,
}

impl RenderLoop {
    /// The loop at `period_s` and `latency_s` on a model whose parameters are `params`, with the
    /// share `viscous_compensation` (in [0, 1)) of each joint's viscous friction compensated: what
    /// is left damps the fixtures. A negative identified friction counts as none.
    pub fn of_model(
        model: &Model,
        params: &[f64],
        viscous_compensation: f64,
        period_s: f64,
        latency_s: f64,
    ) -> Result<Self, FixtureError> {
        if !(0.0..1.0).contains(&viscous_compensation) {
            return Err(FixtureError::Loop(format!(
                "the viscous friction's compensated share is {viscous_compensation}; it must be in [0, 1): \
                 what is left is the damping that keeps a rendered wall passive"
            )));
        }
        let layout: ParamLayout = model.layout();
        if params.len() != layout.len() {
            return Err(FixtureError::Loop(format!("the model has {} parameters, not {}", layout.len(), params.len())));
        }
        let damping =
            (0..model.dof()).map(|k| params[layout.viscous(k)].max(0.0) * (1.0 - viscous_compensation)).collect();
        let looped = Self { damping, period_s, latency_s };
        looped.check()?;
        Ok(looped)
    }

    /// `T/2 + L` (s): how long a rendered spring's force lags the position it answers.
    pub fn delay_s(&self) -> f64 {
        0.5 * self.period_s + self.latency_s
    }

    fn check(&self) -> Result<(), FixtureError> {
        let ok =
            self.period_s.is_finite() && self.period_s > 0.0 && self.latency_s.is_finite() && self.latency_s >= 0.0;
        if !ok {
            return Err(FixtureError::Loop(format!(
                "the loop's period {} s and latency {} s must be finite, the period above 0 and the latency not below",
                self.period_s, self.latency_s
            )));
        }
        if let Some(d) = self.damping.iter().find(|d| !(d.is_finite() && **d >= 0.0)) {
            return Err(FixtureError::Loop(format!("a joint's damping is {d}; it must be finite and at least 0")));
        }
        Ok(())
    }
}

/// One fixture's bound, as the check found it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FixtureBound {
    /// The fixture, as the file names it (`wall[0]`).
    pub fixture: String,
    /// The least damping it meets over the range (N·s/m or N·m·s/rad).
    pub damping_left: f64,
    /// The largest stiffness it may have with its damping (N/m or N·m/rad; none for a field).
    pub stiffness_bound: Option<f64>,
    /// Its share of the damping where it is largest.
    pub share: f64,
}

/// What the check found: every fixture's bound, and the fixtures' largest share together.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Passivity {
    pub fixtures: Vec<FixtureBound>,
    pub together: f64,
    pub configurations: usize,
}

/// One fixture's demand on the damping: `K·(T/2 + L) + |B|`, and how it meets the joints.
struct Demand {
    name: String,
    stiffness: f64,
    damping: f64,
    units: (&'static str, &'static str),
    along: Along,
}

enum Along {
    Depth,
    /// The angles off a cone's axis: the worst direction across the instrument.
    Tilt,
    /// Every direction at the tip.
    Tip,
}

/// Check `fixtures` on `model` against `looped`: each within its own bound, all together within
/// the damping, everywhere on the grid. The error names the fixture and gives its bound.
pub fn check_passivity(model: &Model, fixtures: &Fixtures, looped: &RenderLoop) -> Result<Passivity, FixtureError> {
    fixtures.validate()?;
    looped.check()?;
    if looped.damping.len() != model.dof() {
        return Err(FixtureError::Loop(format!(
            "the loop gives {} joints' damping; the robot has {}",
            looped.damping.len(),
            model.dof()
        )));
    }
    let demands = demands(fixtures);
    let mut geometry = Geometry::new(model, fixtures)?;
    let mut least = vec![f64::INFINITY; demands.len()];
    let mut worst = (0.0, Vec::new());
    let mut most = vec![0.0f64; demands.len()];
    let grid = grid(model);
    for q in &grid {
        geometry.at(q);
        let mut together = 0.0;
        for (i, d) in demands.iter().enumerate() {
            let inverse = inverse_damping(&geometry, &d.along, &looped.damping);
            least[i] = least[i].min(1.0 / inverse);
            let demand = d.stiffness * looped.delay_s() + d.damping;
            let share = if demand > 0.0 { demand * inverse } else { 0.0 };
            most[i] = most[i].max(share);
            together += share;
        }
        if together > worst.0 {
            worst = (together, q.clone());
        }
    }
    let mut bounds = Vec::new();
    for (i, d) in demands.iter().enumerate() {
        let (stiffness_unit, damping_unit) = d.units;
        let bound = (least[i] - d.damping) / looped.delay_s();
        if d.damping >= least[i] && d.damping > 0.0 {
            return Err(FixtureError::AbovePassivity {
                field: format!("{}.damping", d.name),
                value: d.damping,
                unit: damping_unit,
                bound: least[i],
                damping: least[i],
                damping_unit,
                delay_ms: 1e3 * looped.delay_s(),
            });
        }
        if most[i] >= 1.0 {
            return Err(FixtureError::AbovePassivity {
                field: format!("{}.stiffness", d.name),
                value: d.stiffness,
                unit: stiffness_unit,
                bound: bound.max(0.0),
                damping: least[i],
                damping_unit,
                delay_ms: 1e3 * looped.delay_s(),
            });
        }
        let field = !stiffness_unit.is_empty();
        bounds.push(FixtureBound {
            fixture: d.name.clone(),
            damping_left: least[i],
            stiffness_bound: field.then_some(bound),
            share: most[i],
        });
    }
    if worst.0 >= 1.0 {
        let shares = bounds
            .iter()
            .map(|b| format!("{} {:.0} % alone", b.fixture, 100.0 * b.share))
            .collect::<Vec<_>>()
            .join(", ");
        return Err(FixtureError::TogetherAbovePassivity { share_percent: 100.0 * worst.0, q: worst.1, shares });
    }
    Ok(Passivity { fixtures: bounds, together: worst.0, configurations: grid.len() })
}

fn demands(fixtures: &Fixtures) -> Vec<Demand> {
    let linear = ("N/m", "N·s/m");
    let demand =
        |name: String, stiffness: f64, damping: f64, units, along| Demand { name, stiffness, damping, units, along };
    let walls = fixtures.wall.iter().enumerate();
    let cones = fixtures.cone.iter().enumerate();
    let fields = fixtures.viscous.iter().enumerate();
    let springs = fixtures.spring.iter().enumerate();
    walls
        .map(|(i, w)| demand(format!("wall[{i}]"), w.stiffness, w.damping, linear, Along::Depth))
        .chain(
            cones.map(|(i, c)| {
                demand(format!("cone[{i}]"), c.stiffness, c.damping, ("N·m/rad", "N·m·s/rad"), Along::Tilt)
            }),
        )
        .chain(fields.map(|(i, v)| demand(format!("viscous[{i}]"), 0.0, v.damping, ("", "N·s/m"), Along::Tip)))
        .chain(springs.map(|(i, s)| demand(format!("spring[{i}]"), s.stiffness, s.damping, linear, Along::Tip)))
        .collect()
}

/// `1/b` along `along` at the geometry's configuration: `gᵀ D⁻¹ g`, or the largest over its
/// directions. Infinite where a joint with no damping left moves it.
fn inverse_damping(geometry: &Geometry, along: &Along, damping: &[f64]) -> f64 {
    let n = geometry.dof();
    let weight = |k: usize, x: f64| {
        if x * x <= 1e-24 {
            0.0
        } else if damping[k] > 0.0 {
            x * x / damping[k]
        } else {
            f64::INFINITY
        }
    };
    match along {
        Along::Depth => {
            let mut gradient = vec![0.0; n];
            geometry.depth(&mut gradient);
            gradient.iter().enumerate().map(|(k, g)| weight(k, *g)).sum()
        }
        Along::Tilt => {
            let z = geometry.direction;
            let across = Matrix3::identity() - z * z.transpose();
            largest(n, damping, |k| across * geometry.column(k).1)
        }
        Along::Tip => largest(n, damping, |k| geometry.column(k).0),
    }
}

/// `λ_max(Σ_k c_k c_kᵀ / D_k)`, infinite where a joint with no damping has a column.
fn largest(n: usize, damping: &[f64], column: impl Fn(usize) -> Vec3) -> f64 {
    let mut sum = Matrix3::zeros();
    for (k, &d) in damping.iter().enumerate().take(n) {
        let c = column(k);
        if c.norm_squared() <= 1e-24 {
            continue;
        }
        if d <= 0.0 {
            return f64::INFINITY;
        }
        sum += c * c.transpose() / d;
    }
    SymmetricEigen::new(sum).eigenvalues.max()
}

/// The joints' ranges sampled evenly, corners included; a joint without finite limits over a
/// turn.
fn grid(model: &Model) -> Vec<Vec<f64>> {
    let n = model.dof().max(1);
    let per = ((GRID_CONFIGURATIONS as f64).powf(1.0 / n as f64).floor() as usize).clamp(2, 16);
    let ranges: Vec<(f64, f64)> = model
        .joints
        .iter()
        .map(|j| match (j.lower.is_finite() && j.upper.is_finite(), j.lower < j.upper) {
            (true, true) => (j.lower, j.upper),
            _ => (-std::f64::consts::PI, std::f64::consts::PI),
        })
        .collect();
    let total = per.pow(model.dof() as u32);
    (0..total)
        .map(|mut index| {
            ranges
                .iter()
                .map(|(lo, hi)| {
                    let i = index % per;
                    index /= per;
                    lo + (hi - lo) * i as f64 / (per - 1) as f64
                })
                .collect()
        })
        .collect()
}
