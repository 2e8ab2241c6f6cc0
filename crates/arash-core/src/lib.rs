//! `arash-core`: the mathematics of the ARASH:ASiST haptic robot — its dynamic model, linear in
//! the parameters (`τ = Y(q, q̇, q̈) π`), and the base parameters that data can identify.
//!
//! The layout follows Pinocchio's Model/Data split: a [`Model`] is built once (from URDF), a
//! [`Data`] holds every scratch buffer, and the algorithms are free functions writing into
//! caller-provided outputs. Nothing on an evaluation path allocates.
//!
//! Units are SI throughout: rad, m, s, kg, N·m, N.

pub mod base_parameters;
pub mod choices;
#[cfg(feature = "identification")]
pub mod consistent;
pub mod control;
pub mod data;
pub mod dense;
#[cfg(feature = "identification")]
pub mod diagnose;
pub mod dynamics;
pub mod effects;
#[cfg(feature = "flightlog")]
pub mod flightlog;
pub mod force;
#[cfg(feature = "identification")]
pub mod force_log;
pub mod haptics;
#[cfg(feature = "identification")]
pub mod identify;
pub mod kinematics;
pub mod model;
pub mod model_file;
pub mod parallel;
pub mod params;
pub mod physical;
pub mod record;
pub mod regressor;
pub mod signal;
#[cfg(feature = "simulation")]
pub mod sim;
pub mod spatial;
pub mod transmission;
pub mod urdf;

pub use base_parameters::{BaseParameterError, BaseParameters};
pub use data::Data;
pub use dynamics::{
    coriolis_matrix, forward_dynamics, gravity_torque, inverse_dynamics, kinetic_energy, mass_matrix, momentum_terms,
    potential_energy, DynamicsError, MomentumTerms,
};
pub use kinematics::forward_kinematics;
pub use model::{ActuatedJoint, Body, CoulombLaws, CoulombShape, Frame, JointKind, Model, ModelWarning, UnknownFrame};
pub use model_file::ModelFile;
pub use params::ParamLayout;
pub use regressor::{regressor, regressor_of_bodies, slotine_li_regressor};
pub use urdf::{load_urdf, parse_urdf, UrdfError};

/// The bundled reconstruction of ARASH:ASiST (`robots/arash_asist.urdf`, kept inside the crate so
/// that a packaged crate or sdist carries it; `robots/` links to it).
pub const ARASH_ASIST_URDF: &str = include_str!("../robots/arash_asist.urdf");

/// ARASH:ASiST's encoders: counts per motor revolution after quadrature, per joint (the drive
/// configuration's and the simulated rig's default).
pub const ARASH_ASIST_COUNTS_PER_REV: [f64; 3] = [8192.0; 3];

/// ARASH:ASiST's transmissions: joint motion per motor radian (rad/rad for the yaw's and the
/// pitch's 12:1 cable drives, m/rad for the insertion's capstan of 2.5 mm radius).
pub const ARASH_ASIST_TRANSMISSION: [f64; 3] = [1.0 / 12.0, 1.0 / 12.0, 0.0025];

/// The bundled ARASH:ASiST model.
pub fn arash_asist() -> Model {
    parse_urdf(ARASH_ASIST_URDF).expect("the bundled ARASH:ASiST URDF is valid")
}
