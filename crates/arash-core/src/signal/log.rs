//! What a choice is made from: one log, and the robot as declared.

use crate::base_parameters::BaseParameters;
use crate::model::Model;

/// The robot as declared: its model, its base parameters (computed once by the caller: they
/// depend only on the model), and the URDF it came from (embedded in the model file).
#[derive(Clone, Copy)]
pub struct Declared<'a> {
    pub model: &'a Model,
    pub base: &'a BaseParameters,
    pub urdf: &'a str,
}

/// One log: `t` (N), `q` and `tau` (N × dof, row-major, SI).
#[derive(Clone, Copy, Debug)]
pub struct Log<'a> {
    pub t: &'a [f64],
    pub q: &'a [f64],
    pub tau: &'a [f64],
}

impl Log<'_> {
    /// The log's fingerprint: FNV-1a (64 bits) of its times, positions and torques, bit for bit,
    /// in hexadecimal. A model file keeps its fit's, so that a diagnosis can tell the log the
    /// model was fitted on from an independent one (`diagnose/calibration_error.rs`).
    pub fn fingerprint(&self) -> String {
        const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
        const PRIME: u64 = 0x0100_0000_01b3;
        let bytes = [self.t, self.q, self.tau].into_iter().flatten().flat_map(|v| v.to_le_bytes());
        let hash = bytes.fold(OFFSET, |h, b| (h ^ u64::from(b)).wrapping_mul(PRIME));
        format!("{hash:016x}")
    }
}
