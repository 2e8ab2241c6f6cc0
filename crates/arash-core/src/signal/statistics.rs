//! The standard error of a mean over correlated samples, by batch means: the yardstick every
//! held-out comparison of the choices and of the diagnosis's guard is read with.

/// The mean of `x` and its standard error from the scatter of the means of consecutive blocks
/// of `block` values (the values are correlated within a block, not between blocks).
pub fn mean_and_block_error(x: &[f64], block: usize) -> (f64, f64) {
    let n = x.len().max(1);
    let mean = x.iter().sum::<f64>() / n as f64;
    let blocks: Vec<f64> = x.chunks(block.max(1)).map(|b| b.iter().sum::<f64>() / b.len() as f64).collect();
    if blocks.len() < 2 {
        return (mean, f64::INFINITY);
    }
    let m = blocks.len() as f64;
    let scatter = blocks.iter().map(|b| (b - mean).powi(2)).sum::<f64>() / (m - 1.0);
    (mean, (scatter / m).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Independent standard normal values in blocks of one: the batch-means error is the
    /// textbook σ/√n, within its own sampling error (√(1/(2(n−1))) relative).
    #[test]
    fn independent_values_give_the_textbook_error() {
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = 20_000;
        // Box–Muller: an independent reference for normal draws.
        let x: Vec<f64> = (0..n)
            .map(|_| (-2.0 * uniform().max(1e-300).ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos())
            .collect();
        let (mean, error) = mean_and_block_error(&x, 1);
        let expected = 1.0 / (n as f64).sqrt();
        assert!((error / expected - 1.0).abs() < 0.05, "{error} against {expected}");
        assert!(mean.abs() < 4.0 * expected, "{mean}");
    }

    /// A value repeated in runs of 50 is 50 times less informative than its count says: batches
    /// of the run's length see it, batches of one do not.
    #[test]
    fn batches_as_long_as_the_correlation_see_it() {
        let runs: Vec<f64> = (0..400).map(|k| if k % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let x: Vec<f64> = runs.iter().flat_map(|&v| std::iter::repeat_n(v, 50)).collect();
        let (_, naive) = mean_and_block_error(&x, 1);
        let (_, batched) = mean_and_block_error(&x, 50);
        // Batches of one: σ/√20000; batches of a run: σ/√400.
        assert!((batched / naive - (50f64).sqrt()).abs() < 0.1, "{batched} against {naive}");
        assert_eq!(mean_and_block_error(&[1.0, 2.0], 5).1, f64::INFINITY);
    }
}
