//! The observer's settings that follow from a model file's held-out data, shared by the offline
//! estimate (`force_log`) and the daemon: the bandwidth, σ and thresholds, and the frame a force
//! is wanted at. Each default is here once, with why (docs/force.md, "How far the estimate can
//! be trusted").

use super::{ThresholdError, Thresholds};
use crate::choices::ForceChoice;
use crate::model::Model;
use crate::model_file::HeldOut;

/// The model's band over the observer's bandwidth for a model file that records no observer run
/// on held-out data: its σ was then measured in that band by a zero-phase Butterworth that cuts
/// steeply at its edge, and the observer's first-order lag, rolling off at only 20 dB per decade,
/// would at the full band pass what lies above it, which σ never saw. A quarter of the band keeps
/// the estimate's noise inside the σ it carries, at the price of speed: record the observer's own
/// run (`identify --validate`, `with_held_out`) to get a hand's bandwidth.
pub const BAND_PER_BANDWIDTH: f64 = 4.0;

/// The band of a hand's deliberate motion and force (Hz): voluntary movement lies below about
/// 2 Hz; physiological tremor, at 8–12 Hz, is not the trainee's intent and an order of magnitude
/// smaller.
pub const HAND_BAND_HZ: f64 = 2.0;

/// The least bandwidth over the hand's band: a first-order lag at ten times a force's frequency
/// follows it to 10 % (5 % RMS over a flat band), and at 20 Hz it reads a step of twice a
/// threshold across that threshold within ln 2/(2π·20 Hz) = 5.5 ms, inside the 20 ms a
/// collision must be found in.
pub const BANDWIDTH_PER_HAND_BAND: f64 = 10.0;

/// The bandwidths the observer is tried at on held-out data, as multiples of the least
/// ([`HAND_BAND_HZ`] × [`BANDWIDTH_PER_HAND_BAND`]), each up to a tenth of the sample rate.
pub const BANDWIDTH_GRID: [f64; 4] = [1.0, 2.0, 4.0, 8.0];

/// How far the hand-free RMS may grow over its value at the least bandwidth before a wider one
/// is refused: 25 %. White noise grows √2 per octave of bandwidth, so a noisy joint stays at the
/// least; an error no bandwidth changes (the model's own, slow beside the band) lets a joint
/// widen, and so detect sooner, for nearly nothing.
pub const NOISE_ALLOWANCE: f64 = 1.25;

/// The least bandwidth (Hz): ten times a hand's band.
pub(crate) const HAND_BANDWIDTH: f64 = HAND_BAND_HZ * BANDWIDTH_PER_HAND_BAND;

/// The bandwidths tried on a log sampled at `rate_hz`: the grid, capped at a tenth of the rate
/// (a first-order lag sampled fewer than ten times per time constant's 2π is no longer one).
pub fn bandwidth_grid(rate_hz: f64) -> Vec<f64> {
    let least = HAND_BANDWIDTH;
    let cap = 0.1 * rate_hz;
    let mut grid: Vec<f64> = BANDWIDTH_GRID.iter().map(|m| m * least).filter(|b| *b <= cap).collect();
    if grid.is_empty() {
        grid.push(cap);
    }
    grid
}

/// A frame the force is wanted at, and the frame its moment is taken about (default: the base).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameChoice {
    pub frame: String,
    pub about: Option<String>,
}

/// Multiple of the held-out runs' largest hand-free estimate the collision threshold keeps above:
/// a residual with heavy tails (friction at reversals) reaches 8σ and more without any hand, and
/// a longer run than the held-out ones reaches further than they did.
pub const PEAK_MARGIN: f64 = 1.5;

/// Thresholds at `contact` and `collision` times each joint's σ, the collision level raised to
/// [`PEAK_MARGIN`] times the largest hand-free estimate `held_out`'s observer run reached (where
/// σ came from that run); with why, when the peak was used. The daemon's thresholds too.
pub fn sigma_thresholds(
    sigma: &[f64],
    contact: f64,
    collision: f64,
    held_out: Option<&HeldOut>,
) -> Result<(Thresholds, Option<ForceChoice>), ThresholdError> {
    let t = Thresholds::from_sigma(sigma, contact, collision)?;
    let peak = held_out.and_then(|h| h.observer.as_ref()).map(|o| &o.peak).filter(|p| p.len() == sigma.len());
    Ok(match peak {
        Some(peak) => {
            let floor: Vec<f64> = peak.iter().map(|p| PEAK_MARGIN * p).collect();
            let why = ForceChoice::CollisionFloor { margin: PEAK_MARGIN, peak: peak.clone() };
            (t.with_collision_floor(&floor), Some(why))
        }
        None => (t, None),
    })
}

/// The robot's instrument tip and the remote centre its moment is taken about, where its URDF
/// names them (ARASH:ASiST's do): the frame a force is wanted at when none is named.
pub fn default_frame(model: &Model) -> Option<FrameChoice> {
    let has = |name: &str| model.frame(name).is_ok();
    (has("instrument_tip") && has("remote_centre"))
        .then(|| FrameChoice { frame: "instrument_tip".into(), about: Some("remote_centre".into()) })
}

/// The observer's bandwidth per joint when none is given, and why: the model file's held-out
/// observer run; else, for a model whose σ was measured in a band (`held_out`'s, else the fit's
/// `fitted_band_hz`), a quarter of it ([`BAND_PER_BANDWIDTH`]); else ten times a hand's band at
/// `rate_hz`. The daemon's default too.
pub fn default_bandwidth(
    held_out: Option<&HeldOut>,
    fitted_band_hz: Option<f64>,
    rate_hz: f64,
    n: usize,
) -> (Vec<f64>, ForceChoice) {
    if let Some(o) = held_out.and_then(|h| h.observer.as_ref()) {
        let run = Box::new(o.reason.clone());
        return (o.bandwidth_hz.clone(), ForceChoice::BandwidthFromRun { bandwidth_hz: o.bandwidth_hz.clone(), run });
    }
    match held_out.map(|h| h.cutoff_hz).or(fitted_band_hz) {
        Some(band) => {
            let hz = band / BAND_PER_BANDWIDTH;
            let why = ForceChoice::BandwidthFromBand { bandwidth_hz: hz, band_hz: band };
            (vec![hz; n], why)
        }
        None => {
            let hz = bandwidth_grid(rate_hz)[0];
            let why = ForceChoice::BandwidthFromHand {
                bandwidth_hz: hz,
                per_hand_band: BANDWIDTH_PER_HAND_BAND,
                hand_band_hz: HAND_BAND_HZ,
            };
            (vec![hz; n], why)
        }
    }
}

/// The σ per joint a model's held-out data gives the estimate, and why: its observer run's,
/// else its residual's RMS. The daemon's too.
pub fn held_out_sigma(h: &HeldOut) -> (Vec<f64>, ForceChoice) {
    match &h.observer {
        Some(o) => (o.sigma.clone(), ForceChoice::SigmaFromObserver { source: h.source.clone() }),
        None => (h.rms.clone(), ForceChoice::SigmaFromResidual { source: h.source.clone(), samples: h.samples }),
    }
}
