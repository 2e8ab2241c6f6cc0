//! An encoder's position: whole multiples of its step. What a log's positions say about the
//! encoder behind them, read by the band's choice (`diagnose::band`: the velocity noise the step
//! puts into each cut-off).

/// Positions that are whole multiples of a step, as an encoder's are, cut by at most this share of
/// the step.
pub const ON_THE_GRID: f64 = 1e-3;

/// The share of a joint's moves that must lie on its step's grid. A log resampled onto a uniform
/// grid where its time stamps jittered (the daemon's, `flightlog::on_uniform_grid`) holds a few interpolated
/// positions between the steps; they must not hide the encoder of all the others.
pub const ON_THE_GRID_SHARE: f64 = 0.99;

/// How many of the smallest distinct moves are tried as the step.
pub const STEP_CANDIDATES: usize = 32;

/// Joint `j`'s encoder step, when at least [`ON_THE_GRID_SHARE`] of its moves between two samples
/// are whole multiples of one of its smallest moves; `None` when they are not (filtered positions)
/// or the joint never moves. An interpolated move smaller than the step is tried first and fails,
/// unless it divides the step exactly; the largest candidate that passes is the step.
pub fn encoder_step(q: &[f64], dof: usize, j: usize) -> Option<f64> {
    let x: Vec<f64> = q.iter().skip(j).step_by(dof).copied().collect();
    let scale = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let mut moves: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]).abs()).filter(|d| *d > 1e-12 * scale).collect();
    moves.sort_by(f64::total_cmp);
    let mut candidates = moves.clone();
    candidates.dedup_by(|a, b| *a <= *b * (1.0 + ON_THE_GRID));
    let on_grid = |d: f64, step: f64| ((d / step) - (d / step).round()).abs() <= ON_THE_GRID;
    let passes = |step: f64| {
        moves.iter().filter(|&&d| on_grid(d, step)).count() as f64 >= ON_THE_GRID_SHARE * moves.len() as f64
    };
    candidates.into_iter().take(STEP_CANDIDATES).filter(|&step| passes(step)).reduce(f64::max)
}
