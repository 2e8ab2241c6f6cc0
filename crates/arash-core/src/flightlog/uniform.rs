//! A daemon log's samples on a uniform time grid, which identification and the diagnosis need.
//!
//! The daemon logs each cycle with the drive's time of the measurement it used, so a cycle
//! without new telemetry repeats a time, and telemetry superseded within one cycle leaves a gap.
//! Repeats are dropped and gaps filled by linear interpolation at the median step, keeping one
//! sample per logged cycle. `arash identify`, `arash diagnose` and the demo read daemon logs
//! through this, and `arash.read_log` gives the result as `log["uniform"]`.

use crate::signal::resample::resample;

/// Channels on a uniform grid: `t` (N) and each channel row-major (N × its width, as given).
#[derive(Clone, Debug, PartialEq)]
pub struct Uniform {
    pub t: Vec<f64>,
    pub channels: Vec<Vec<f64>>,
    /// Samples that repeated a time, or were filled in between logged ones.
    pub repaired: usize,
}

/// `channels` (row-major, `width` values per sample of `t`) on a uniform grid at the median
/// step, with as many samples as cycles were logged: the daemon logs one cycle per drive period,
/// so the run's length (and with it the period averaging) is that of the log even when its last
/// measurements arrived late; the end holds the last measurement. `None` for a log already
/// uniform, or too short to have a step: it needs no grid of its own.
pub fn on_uniform_grid(t: &[f64], channels: &[&[f64]], width: usize) -> Option<Uniform> {
    let keep: Vec<usize> = (0..t.len()).filter(|&i| i == 0 || t[i] > t[i - 1]).collect();
    let mut steps: Vec<f64> = keep.windows(2).map(|w| t[w[1]] - t[w[0]]).collect();
    if steps.is_empty() {
        return None;
    }
    steps.sort_by(f64::total_cmp);
    let h = steps[steps.len() / 2];
    if keep.len() == t.len() && steps.iter().all(|s| (s - h).abs() < 1e-3 * h) {
        return None;
    }
    let (t0, t_end) = (t[keep[0]], t[keep[keep.len() - 1]]);
    let n = (((t_end - t0) / h).round() as usize + 1).max(t.len());
    let grid: Vec<f64> = (0..n).map(|i| t0 + i as f64 * h).collect();
    let kept_t: Vec<f64> = keep.iter().map(|&i| t[i]).collect();
    let kept: Vec<Vec<f64>> = channels
        .iter()
        .map(|x| keep.iter().flat_map(|&i| x[i * width..(i + 1) * width].iter().copied()).collect())
        .collect();
    // A grid point on a logged time takes that sample exactly: blended with a weight of
    // round-off, an encoder's positions leave its grid by 1e-14 and its step no longer shows
    // (`diagnose/band.rs` then reads the whole closed-loop motion as noise).
    let (channels, blended) = resample(&kept_t, &kept, &vec![width; kept.len()], &grid);
    Some(Uniform { t: grid, channels, repaired: t.len() - keep.len() + blended })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeats_are_dropped_and_gaps_interpolated() {
        // A ramp sampled at 1 ms with one repeat (t = 2 ms twice) and one gap (no 5 ms).
        let t = [0.0, 0.001, 0.002, 0.002, 0.003, 0.004, 0.006, 0.007];
        let q: Vec<f64> = t.iter().map(|t| 3.0 * t).collect();
        let out = on_uniform_grid(&t, &[&q], 1).expect("not uniform");
        assert_eq!(out.repaired, 2);
        assert_eq!(out.t.len(), 8, "one sample per logged cycle");
        for (i, (&t, &q)) in out.t.iter().zip(&out.channels[0]).enumerate() {
            assert!((t - i as f64 * 1e-3).abs() < 1e-12);
            assert!((q - 3.0 * t).abs() < 1e-12, "a ramp interpolates exactly");
        }
    }

    /// Encoder counts stay whole counts where the grid meets a logged time, however the step
    /// `h` (a median of differences) rounds; only the gap's sample is blended.
    #[test]
    fn resampled_positions_keep_the_logged_values_where_the_grid_meets_them() {
        let step = 1.917_475_984_857_162e-6;
        let mut t: Vec<f64> = (0..2000).map(|i| 12.345 + i as f64 * 1e-3).collect();
        t[700] = t[699]; // a repeat, then the same cycles go on: one gap
        let q: Vec<f64> = (0..2000).map(|i| ((i as f64 * 0.0123).sin() * 300.0).round() * step).collect();
        let out = on_uniform_grid(&t, &[&q], 1).expect("not uniform");
        assert_eq!(out.repaired, 2);
        let q_out = &out.channels[0];
        let off_grid = q_out.iter().filter(|x| ((*x / step) - (*x / step).round()).abs() > 1e-9).count();
        assert!(off_grid <= 1, "{off_grid} positions left the encoder's grid");
        assert!(q_out.iter().zip(&q).enumerate().all(|(i, (a, b))| i == 700 || a == b));
    }

    #[test]
    fn a_uniform_log_is_untouched() {
        let t: Vec<f64> = (0..10).map(|i| i as f64 * 1e-3).collect();
        assert_eq!(on_uniform_grid(&t, &[&t, &t], 1), None);
    }
}
