//! The force of an operator's hand, estimated from the calibrated model: the external joint
//! torque by a generalized momentum observer ([`MomentumObserver`]), and the force at a named
//! frame such as the instrument tip ([`FrameForce`]). Neither allocates after it is built.
//! [`Thresholds`] tell contact from collision at multiples of the model's held-out σ.

pub mod frame_force;
pub mod observer;
pub mod settings;
pub mod thresholds;

pub use frame_force::{FrameForce, FrameForceSample};
pub use observer::{MomentumObserver, ObserverError, TorqueTiming};
pub use thresholds::{episodes, Episode, Level, ThresholdError, Thresholds, COLLISION_SIGMAS, CONTACT_SIGMAS};
