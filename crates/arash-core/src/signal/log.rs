//! What a choice is made from: one log, and the robot as declared.

use crate::base_parameters::BaseParameters;
use crate::model::Model;
use xxhash_rust::xxh3::Xxh3;

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
    /// The log's fingerprint: `xxh3:` and XXH3-64 of its times, positions and torques, bit for bit
    /// (little-endian), in hexadecimal. A model file keeps its fit's, so that a diagnosis can tell
    /// the log the model was fitted on from an independent one (`diagnose/calibration_error.rs`).
    pub fn fingerprint(&self) -> String {
        let mut hasher = Xxh3::new();
        let mut buffer = Vec::with_capacity(8 * HASHED_PER_UPDATE);
        for chunk in [self.t, self.q, self.tau].into_iter().flat_map(|values| values.chunks(HASHED_PER_UPDATE)) {
            buffer.clear();
            buffer.extend(chunk.iter().flat_map(|v| v.to_le_bytes()));
            hasher.update(&buffer);
        }
        format!("{FINGERPRINT_PREFIX}{:016x}", hasher.digest())
    }

    /// Whether `stored`, a model file's fingerprint, is this log's, given `own`, what
    /// [`Self::fingerprint`] gave for it (a caller keeps it for the file it writes): today's
    /// hash, or the FNV-1a (64 bits, byte by byte, no prefix) of files written before
    /// 2026-12-06, which is 15 times slower and so only computed for such a file.
    pub fn has_fingerprint(&self, stored: &str, own: &str) -> bool {
        match stored.starts_with(FINGERPRINT_PREFIX) {
            true => stored == own,
            false => self.fnv1a() == stored,
        }
    }

    fn fnv1a(&self) -> String {
        const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
        const PRIME: u64 = 0x0100_0000_01b3;
        let bytes = [self.t, self.q, self.tau].into_iter().flatten().flat_map(|v| v.to_le_bytes());
        let hash = bytes.fold(OFFSET, |h, b| (h ^ u64::from(b)).wrapping_mul(PRIME));
        format!("{hash:016x}")
    }
}

/// What a fingerprint of today's hash starts with.
const FINGERPRINT_PREFIX: &str = "xxh3:";

/// Values turned into bytes per update of the hash: a buffer that stays in the first-level cache.
const HASHED_PER_UPDATE: usize = 512;

#[cfg(test)]
mod tests {
    use super::*;

    fn log_of<'a>(t: &'a [f64], q: &'a [f64], tau: &'a [f64]) -> Log<'a> {
        Log { t, q, tau }
    }

    /// XXH3-64 of the bytes written out by hand, against the crate's one-shot function: the
    /// buffered updates hash exactly the log's bytes, in order, across the buffer's boundary.
    #[test]
    fn the_fingerprint_is_xxh3_of_the_logs_bytes() {
        let t: Vec<f64> = (0..1500).map(|i| i as f64 * 1e-3).collect();
        let q: Vec<f64> = t.iter().map(|x| x.sin()).collect();
        let tau: Vec<f64> = t.iter().map(|x| -x.cos()).collect();
        let bytes: Vec<u8> = [&t, &q, &tau].into_iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        let expected = format!("xxh3:{:016x}", xxhash_rust::xxh3::xxh3_64(&bytes));
        let log = log_of(&t, &q, &tau);
        assert_eq!(log.fingerprint(), expected);
        assert!(log.has_fingerprint(&expected, &log.fingerprint()));
        let mut other = tau.clone();
        other[1499] = f64::from_bits(other[1499].to_bits() ^ 1);
        let changed = log_of(&t, &q, &other);
        assert!(!changed.has_fingerprint(&expected, &changed.fingerprint()), "one bit of one torque changes it");
    }

    /// A file written before 2026-12-06 keeps FNV-1a: its log is still recognised, and another
    /// is not. The reference is FNV-1a's published test vector for "a" (0xaf63dc4c8601ec8c).
    #[test]
    fn an_older_files_fnv_fingerprint_still_matches_its_log() {
        const OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
        const PRIME: u64 = 0x0100_0000_01b3;
        assert_eq!((OFFSET ^ u64::from(b'a')).wrapping_mul(PRIME), 0xaf63_dc4c_8601_ec8c);
        let (t, q, tau) = ([0.0, 1e-3], [0.5, 0.25], [1.0, -2.0]);
        let log = log_of(&t, &q, &tau);
        let bytes = [&t[..], &q, &tau].into_iter().flatten().flat_map(|v| v.to_le_bytes());
        let legacy = format!("{:016x}", bytes.fold(OFFSET, |h, b| (h ^ u64::from(b)).wrapping_mul(PRIME)));
        assert!(log.has_fingerprint(&legacy, &log.fingerprint()));
        let other = log_of(&t, &q, &[1.0, -2.5]);
        assert!(!other.has_fingerprint(&legacy, &other.fingerprint()));
        assert!(!log.fingerprint().ends_with(&legacy), "today's hash is not FNV-1a");
    }
}
