//! The simulated ARASH:ASiST rig: a stand-in for the hardware that produces "measured" data with
//! declared and undeclared effects. `docs/simulator.md` documents every equation and default.
//!
//! - [`scenario`]: the TOML description of a rig and the effects switched on;
//! - [`truth`]: the true parameters (CAD plus a seeded perturbation);
//! - [`hand`]: an operator's hand, a force at the instrument the plant feels;
//! - [`plant`]: the continuous-time robot and its fixed-step integrator;
//! - [`drive`]: amplifiers, encoders and current sensing around the plant;
//! - [`rig`]: the drive, amplifiers and the control loop around the plant;
//! - [`run`]: a whole run (what `arash simulate` and `arash.simulate` execute);
//! - [`trainee`]: a trainee's trials in the haptic mode, read from the truth.

pub mod drive;
pub mod hand;
pub mod plant;
pub mod rig;
pub mod run;
pub mod scenario;
pub mod trainee;
pub mod truth;

pub use drive::Drive;
pub use plant::{Plant, PlantError};
pub use rig::Rig;
pub use run::{named_parameters, ControllerChoice, RunSpec};
pub use scenario::{Integrator, Scenario, ScenarioError};
pub use truth::true_parameters;
