//! The haptic mode's virtual fixtures (docs/haptics.md): a depth wall, a cone of instrument
//! angles about the entry point, a viscous field and a spring, read from a file
//! ([`Fixtures`]), refused where the loop cannot render them passively ([`check_passivity`]),
//! and rendered as joint torque each cycle without allocating ([`FixtureRenderer`]) over the
//! model's compensation ([`HapticLaw`]).

pub mod fixtures;
pub mod geometry;
pub mod law;
pub mod passivity;
pub mod render;

pub use fixtures::{Cone, DepthWall, FixtureError, Fixtures, Spring, ViscousField};
pub use law::HapticLaw;
pub use passivity::{check_passivity, FixtureBound, Passivity, RenderLoop};
pub use render::{FixtureRenderer, RenderError, Rendered};
