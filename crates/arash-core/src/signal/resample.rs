//! Channels logged at irregular times, put on a uniform grid.

/// A grid point within this share of the step of a logged time is that sample: an encoder's
/// positions, blended with a weight of round-off, would leave its grid.
const ON_A_SAMPLE: f64 = 1e-6;

/// `channels` (row-major, `widths[c]` values per sample of the increasing `t`) at the times of
/// `grid`, by linear interpolation between the logged samples around each point; a point on a
/// logged time (within `ON_A_SAMPLE` of the grid's step) takes that sample exactly, and points
/// beyond either end take the end sample. Also returns how many points were blended.
pub fn resample(t: &[f64], channels: &[Vec<f64>], widths: &[usize], grid: &[f64]) -> (Vec<Vec<f64>>, usize) {
    let h = match grid {
        [a, b, ..] => b - a,
        _ => 0.0,
    };
    let mut out: Vec<Vec<f64>> = widths.iter().map(|w| Vec::with_capacity(grid.len() * w)).collect();
    let mut blended = 0;
    let mut j = 0;
    for &at in grid {
        while j + 2 < t.len() && t[j + 1] <= at {
            j += 1;
        }
        let (a, b) = (j, (j + 1).min(t.len() - 1));
        let span = t[b] - t[a];
        let w = match ((at - t[a]).abs() <= ON_A_SAMPLE * h, (at - t[b]).abs() <= ON_A_SAMPLE * h) {
            (true, _) => 0.0,
            (_, true) => 1.0,
            _ if span > 0.0 => ((at - t[a]) / span).clamp(0.0, 1.0),
            _ => 0.0,
        };
        if w != 0.0 && w != 1.0 {
            blended += 1;
        }
        for ((x, y), &width) in channels.iter().zip(&mut out).zip(widths) {
            y.extend((0..width).map(|k| x[a * width + k] * (1.0 - w) + x[b * width + k] * w));
        }
    }
    (out, blended)
}
