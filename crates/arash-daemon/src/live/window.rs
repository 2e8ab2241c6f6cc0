//! The display window: every `n` control cycles, the last cycle and the extremes of the tracking
//! error over the `n`, so that a display sampled at 100 Hz still shows a 1 ms spike.

use arash_core::flightlog::schema::TrackingError;
use arash_core::model::JointKind;
use arash_core::record::CycleRecord;
use arash_core::Model;

/// The display units of the tracking error: degrees and micrometres, the sizes a tracking error
/// of this robot has (the paper reports tenths of a degree and tens of µm).
pub fn display_scales(model: &Model) -> Vec<(f64, &'static str)> {
    model
        .joints
        .iter()
        .map(|j| if j.kind == JointKind::Prismatic { (1e6, "um") } else { (180.0 / std::f64::consts::PI, "deg") })
        .collect()
}

pub struct ErrorWindow {
    cycles: u32,
    scales: Vec<f64>,
    seen: u32,
    message: TrackingError,
}

impl ErrorWindow {
    /// Windows of `cycles` control cycles; `scales` takes each joint's error to display units.
    pub fn new(cycles: u32, scales: Vec<f64>) -> Self {
        let dof = scales.len();
        let message = TrackingError {
            error: vec![0.0; dof],
            error_min: vec![f64::INFINITY; dof],
            error_max: vec![f64::NEG_INFINITY; dof],
            ..Default::default()
        };
        Self { cycles: cycles.max(1), scales, seen: 0, message }
    }

    /// Add a cycle; when it closes a window, the window's message. Only a cycle that tracks
    /// (a reference is set) has an error; in a window without one the error is zero.
    pub fn push(&mut self, r: &CycleRecord) -> Option<&TrackingError> {
        let m = &mut self.message;
        if self.seen == 0 {
            m.error_min.fill(f64::INFINITY);
            m.error_max.fill(f64::NEG_INFINITY);
        }
        for (k, scale) in self.scales.iter().enumerate() {
            let e = match (r.q_des.get(k), r.q.get(k)) {
                (Some(d), Some(q)) if d.is_finite() && q.is_finite() => (d - q) * scale,
                _ => 0.0,
            };
            m.error[k] = e;
            m.error_min[k] = m.error_min[k].min(e);
            m.error_max[k] = m.error_max[k].max(e);
        }
        self.seen += 1;
        if self.seen < self.cycles {
            return None;
        }
        m.cycle = r.cycle;
        m.t = r.t;
        m.cycles = self.seen;
        self.seen = 0;
        Some(&self.message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(cycle: u64, e: [f64; 2]) -> CycleRecord {
        let mut r = CycleRecord::new(2);
        r.cycle = cycle;
        r.q = vec![0.1, 0.02];
        r.q_des = vec![0.1 + e[0], 0.02 + e[1]];
        r
    }

    #[test]
    fn a_one_cycle_spike_shows_in_the_extremes_of_its_window() {
        let mut w = ErrorWindow::new(10, vec![180.0 / std::f64::consts::PI, 1e6]);
        for c in 0..9 {
            let e = if c == 4 { [0.01, -3e-5] } else { [0.0, 1e-6] };
            assert!(w.push(&record(c, e)).is_none());
        }
        let m = w.push(&record(9, [0.0, 1e-6])).unwrap().clone();
        assert_eq!((m.cycle, m.cycles), (9, 10));
        assert!((m.error_max[0] - 0.01f64.to_degrees()).abs() < 1e-9, "{m:?}");
        assert!((m.error_min[1] + 30.0).abs() < 1e-6, "{m:?}");
        assert!((m.error[1] - 1.0).abs() < 1e-6 && m.error[0].abs() < 1e-12, "{m:?}");
        // The next window starts afresh.
        for c in 10..20 {
            if let Some(m) = w.push(&record(c, [0.0, 0.0])) {
                assert_eq!(m.error_max, vec![0.0, 0.0]);
                assert_eq!(m.error_min, vec![0.0, 0.0]);
            }
        }
    }
}
