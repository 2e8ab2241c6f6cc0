//! `arash-core`: the mathematics of the ARASH:ASiST haptic robot — its dynamic model, linear in
//! the parameters (`τ = Y(q, q̇, q̈) π`), and the base parameters that data can identify.
//!
//! The layout follows Pinocchio's Model/Data split: a [`Model`] is built once (from URDF), a
//! [`Data`] holds every scratch buffer, and the algorithms are free functions writing into
//! caller-provided outputs. Nothing on an evaluation path allocates.
//!
//! Units are SI throughout: rad, m, s, kg, N·m, N.

pub mod base_parameters;
#[cfg(feature = "blas-lapack")]
pub mod blas_lapack;
pub mod control;
pub mod data;
pub mod dense;
pub mod diagnose;
pub mod dynamics;
pub mod effects;
#[cfg(feature = "flightlog")]
pub mod flightlog;
pub mod force;
pub mod force_log;
pub mod identify;
pub mod kinematics;
pub mod model;
pub mod model_file;
pub mod parallel;
pub mod params;
pub mod physical;
pub mod record;
pub mod regressor;
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

/// The bundled ARASH:ASiST model.
pub fn arash_asist() -> Model {
    parse_urdf(ARASH_ASIST_URDF).expect("the bundled ARASH:ASiST URDF is valid")
}
