//! Any text as a trajectory file: parsed and checked against ARASH:ASiST's limits without a panic
//! or a hang; a trajectory that passes evaluates to finite values inside the limits.

use std::sync::OnceLock;

use arash_core::control::{PlanLimits, Trajectory};

fn limits() -> &'static PlanLimits {
    static LIMITS: OnceLock<PlanLimits> = OnceLock::new();
    LIMITS.get_or_init(|| PlanLimits::from_model(&arash_core::arash_asist()))
}

pub fn check(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(trajectory) = Trajectory::from_json(text, 3) else { return };
    let duration = trajectory.default_duration();
    if trajectory.check_limits(limits(), duration, 1e-3).is_ok() {
        let (mut q, mut qd, mut qdd) = ([0.0; 3], [0.0; 3], [0.0; 3]);
        trajectory.eval(0.0, &mut q, &mut qd, &mut qdd);
        assert!(q.iter().chain(&qd).all(|x| x.is_finite()));
    }
    let _ = trajectory.to_json();
}
