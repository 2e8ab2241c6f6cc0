//! The real-time side of the daemon.
//!
//! - [`mod@reference`]: hold / approach / run a trajectory;
//! - [`cycle`]: one control cycle and the daemon's safety rules;
//! - [`force`]: the hand's force observer in the cycle;
//! - [`haptic`]: the haptic mode's compensation and fixtures;
//! - [`clock`]: absolute deadlines, overrun skipping, SCHED_FIFO and mlockall;
//! - [`runner`]: the control thread and its queues;
//! - [`memory`]: what the locked process holds, and the stack and arena limits that keep it small.

pub mod clock;
pub mod cycle;
pub mod force;
pub mod haptic;
pub mod memory;
pub mod reference;
pub mod runner;
