//! Zero-phase Butterworth low-pass filtering: the function `scipy.signal.filtfilt(b, a, x)` computes
//! for `b, a = scipy.signal.butter(order, cutoff, fs=fs)`, with its default padding.
//!
//! That function is: odd extension of `x` by `3·(order + 1)` samples at each end; the filter run
//! forward from its steady state for the first sample; the result run backward the same way; the
//! padding cut off. We evaluate it in second-order sections rather than in scipy's single b/a
//! polynomial. At low cut-offs the b/a form is badly conditioned: at 2 Hz of 1 kHz, scipy's own
//! b/a result is off from the exact filter by ~1e-5 relative. Sections give the same function to
//! rounding. The design (analog prototype, pre-warping, bilinear transform, pairing into sections)
//! comes from the `sci-rs` crate, a port of scipy's.

use sci_rs::signal::filter::design::{butter_dyn, DigitalFilter, FilterBandType, FilterOutputType, Sos};
use sci_rs::signal::filter::sosfilt_zi_dyn;

/// Why a filter could not be designed or applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FilterError {
    #[error("cut-off {cutoff_hz} Hz must lie strictly between 0 and the Nyquist frequency {nyquist_hz} Hz")]
    CutoffOutOfRange { cutoff_hz: f64, nyquist_hz: f64 },
    #[error("filter order {0} must be between 1 and 12")]
    BadOrder(usize),
    #[error("{what} has {len} samples; zero-phase filtering needs more than {padlen}")]
    TooShort { what: String, len: usize, padlen: usize },
}

/// The share of a zero-phase pass's impulse-response energy that [`Butterworth::memory_s`] spans.
pub const MEMORY_ENERGY: f64 = 0.99;

/// A digital Butterworth low-pass filter as cascaded second-order sections.
#[derive(Clone, Debug)]
pub struct Butterworth {
    order: usize,
    /// Samples after which the filter's response to a start has decayed below 10⁻¹² of it.
    settle: usize,
    /// Sections with their steady-state initial conditions for a unit step (`sosfilt_zi`).
    sections: Vec<Sos<f64>>,
    /// The same filter as one transfer function, `a[0] = 1` (for reporting and comparison).
    b: Vec<f64>,
    a: Vec<f64>,
}

/// Whether `cutoff_hz` lies below the Nyquist frequency of `sample_rate_hz` by more than the
/// rounding of a rate read from time stamps: a log's rate is a mean of its steps, and "500 Hz" on
/// a 1 kHz log whose rate reads 1000.0000000000005 Hz is the Nyquist frequency, where the
/// bilinear design's prewarping diverges (sci-rs then panics).
pub fn below_nyquist(cutoff_hz: f64, sample_rate_hz: f64) -> bool {
    cutoff_hz < 0.5 * sample_rate_hz * (1.0 - 1e-9)
}

impl Butterworth {
    /// Design an `order`-th order low-pass with −3 dB at `cutoff_hz` for data sampled at
    /// `sample_rate_hz`.
    pub fn lowpass(order: usize, cutoff_hz: f64, sample_rate_hz: f64) -> Result<Self, FilterError> {
        if !(1..=12).contains(&order) {
            return Err(FilterError::BadOrder(order));
        }
        let nyquist_hz = 0.5 * sample_rate_hz;
        if !(cutoff_hz > 0.0 && below_nyquist(cutoff_hz, sample_rate_hz)) {
            return Err(FilterError::CutoffOutOfRange { cutoff_hz, nyquist_hz });
        }
        let design = |output| {
            butter_dyn(
                order,
                vec![cutoff_hz],
                Some(FilterBandType::Lowpass),
                Some(false),
                Some(output),
                Some(sample_rate_hz),
            )
        };
        let DigitalFilter::Sos(sos) = design(FilterOutputType::Sos) else { unreachable!("asked sci-rs for sections") };
        let DigitalFilter::Ba(ba) = design(FilterOutputType::Ba) else { unreachable!("asked sci-rs for b/a") };
        let mut sections = sos.sos;
        sosfilt_zi_dyn::<f64, _, ()>(sections.iter_mut());
        // sci-rs returns the polynomials zero-padded; an order-n filter has n + 1 coefficients.
        let (mut b, mut a) = (ba.b, ba.a);
        b.truncate(order + 1);
        a.truncate(order + 1);
        // The slowest pole of an order-n Butterworth has damping sin(π/2n); its envelope falls by
        // e⁻²⁸ ≈ 10⁻¹² in 28 of its time constants.
        let damping = (std::f64::consts::PI / (2.0 * order as f64)).sin();
        let settle = (28.0 * sample_rate_hz / (2.0 * std::f64::consts::PI * damping * cutoff_hz)).ceil() as usize;
        Ok(Self { order, settle, sections, b, a })
    }

    /// Numerator and denominator coefficients, as `scipy.signal.butter(..., output="ba")`.
    pub fn coefficients(&self) -> (&[f64], &[f64]) {
        (&self.b, &self.a)
    }

    /// How far the zero-phase pass spreads one sample (s): the half-width of its impulse response
    /// that holds [`MEMORY_ENERGY`] of the response's energy. Filtered samples further apart than
    /// twice this share almost none of the noise they were filtered from (about 0.79 cut-off
    /// periods for order 5).
    pub fn memory_s(&self, sample_rate_hz: f64) -> f64 {
        let half = self.settle.max(1);
        let mut impulse = vec![0.0; 2 * half + 1];
        impulse[half] = 1.0;
        let mut response = vec![0.0; impulse.len()];
        if self.filtfilt(&impulse, &mut response).is_err() {
            return self.settle as f64 / sample_rate_hz;
        }
        let total: f64 = response.iter().map(|r| r * r).sum();
        let mut held = response[half] * response[half];
        let mut width = 0;
        while held < MEMORY_ENERGY * total && width < half {
            width += 1;
            held += response[half - width].powi(2) + response[half + width].powi(2);
        }
        width as f64 / sample_rate_hz
    }

    /// Samples of odd extension at each end: scipy's default `padlen`.
    pub fn padlen(&self) -> usize {
        3 * (self.order + 1)
    }

    /// Zero-phase filtering of `x` into `out` (same length), as `scipy.signal.filtfilt(b, a, x)`.
    pub fn filtfilt(&self, x: &[f64], out: &mut [f64]) -> Result<(), FilterError> {
        self.filtfilt_rows(x, 1, out)
    }

    /// Zero-phase filtering of every column of a row-major `N × width` signal into `out` (same
    /// shape): `scipy.signal.filtfilt(b, a, x, axis=0)`.
    ///
    /// Each sample runs through a recursion that waits on the previous sample, so one channel at a
    /// time leaves the processor idle between dependent multiply-adds. Up to [`LANES`] channels
    /// go through side by side instead, with each channel's arithmetic exactly as it would be
    /// alone, so the result does not depend on `width`.
    pub fn filtfilt_rows(&self, x: &[f64], width: usize, out: &mut [f64]) -> Result<(), FilterError> {
        self.filtfilt_wrapped(x, width, 0, out)
    }

    /// [`Self::filtfilt_rows`] for a periodic signal (one period, or several end to end): the
    /// result of filtering three copies of `x` end to end and keeping the middle one, so that the
    /// filter sees no ends. The copies are read in place, not built; of a signal longer than the
    /// filter's memory only that much of each neighbouring copy is read, which leaves the result
    /// within 10⁻¹² of the three copies'.
    pub fn filtfilt_rows_periodic(&self, x: &[f64], width: usize, out: &mut [f64]) -> Result<(), FilterError> {
        let n = x.len() / width.max(1);
        self.filtfilt_wrapped(x, width, n.min(self.settle), out)
    }

    /// Filter `x` with `wrap` samples of its other end before and after it (read circularly);
    /// write the part that is `x` to `out`.
    ///
    /// A long signal is filtered in pieces side by side, one run of them per core. Each piece is
    /// read with the filter's memory of its neighbours on either side, as a periodic signal is
    /// read with that much of its copies, so its result is the whole's to 10⁻¹² (the pieces
    /// depend on the length alone, never on the cores, so the result does not either).
    fn filtfilt_wrapped(&self, x: &[f64], width: usize, wrap: usize, out: &mut [f64]) -> Result<(), FilterError> {
        assert!(width > 0 && x.len().is_multiple_of(width), "x must hold whole rows of {width} values");
        assert_eq!(out.len(), x.len(), "output must match the input shape");
        let (n, pad) = (x.len() / width, self.padlen());
        if n + 2 * wrap <= pad {
            return Err(FilterError::TooShort { what: "the signal".into(), len: n + 2 * wrap, padlen: pad });
        }
        let rows = n.div_ceil(self.pieces(n, wrap));
        let parts: Vec<(usize, &mut [f64])> =
            out.chunks_mut(rows * width).enumerate().map(|(i, part)| (i * rows, part)).collect();
        crate::parallel::map(parts, |(start, part)| {
            let len = part.len() / width;
            // The neighbours' memory: circular for a periodic signal, else what the log holds.
            let (before, after) = match wrap {
                0 if rows == n => (0, 0),
                0 => (start.min(self.settle), (n - start - len).min(self.settle)),
                _ => (wrap, wrap),
            };
            let from = (start + n - before % n) % n;
            self.filter_piece(x, width, Piece { from, before, len, after }, part);
        });
        Ok(())
    }

    /// How many pieces [`Self::filtfilt_wrapped`] cuts `n` samples into: one unless each is long
    /// enough that reading the filter's memory of its neighbours adds little.
    fn pieces(&self, n: usize, wrap: usize) -> usize {
        if wrap >= n {
            return 1;
        }
        (n / PIECE_SAMPLES.max(4 * self.settle)).max(1)
    }

    /// Filter the rows `piece` reads (from row `from`, circularly) and write its own `len` rows,
    /// those after its first `before`, into `out`.
    fn filter_piece(&self, x: &[f64], width: usize, piece: Piece, out: &mut [f64]) {
        let (n, pad) = (x.len() / width, self.padlen());
        let Piece { from, before, len, after } = piece;
        let total = before + len + after;
        let kept = pad + before;
        let mut padded: Vec<Lanes> = Vec::with_capacity(total + 2 * pad);
        for first in (0..width).step_by(LANES) {
            let used = (width - first).min(LANES);
            let lanes = |sample: usize| -> Lanes {
                let at = sample * width + first;
                std::array::from_fn(|l| if l < used { x[at + l] } else { 0.0 })
            };
            // Row `k` of the piece is sample `(from + k) mod n` of `x`.
            let row = |k: usize| lanes((from + k) % n);
            // Odd extension: 2·x[0] − x[pad..1] before, 2·x[N−1] − x[N−2..N−pad−1] after.
            let odd = |edge: Lanes, inner: Lanes| -> Lanes { std::array::from_fn(|l| 2.0 * edge[l] - inner[l]) };
            let (head, tail) = (row(0), row(total - 1));
            padded.clear();
            padded.extend((1..=pad).rev().map(|i| odd(head, row(i))));
            // In order, without a division per sample: the long signals' filters read millions.
            padded.extend((from..n).chain((0..n).cycle()).take(total).map(lanes));
            padded.extend((2..pad + 2).map(|i| odd(tail, row(total - i))));
            self.run_from_steady_state(padded.iter_mut());
            self.run_from_steady_state(padded.iter_mut().rev());
            for (k, v) in padded[kept..kept + len].iter().enumerate() {
                out[k * width + first..k * width + first + used].copy_from_slice(&v[..used]);
            }
        }
    }

    /// Filter the samples in iteration order, in place, starting every section from the steady
    /// state for a constant input equal to the first sample
    /// (`sosfilt(sos, y, zi=sosfilt_zi(sos)·y[0])`), transposed direct form II.
    fn run_from_steady_state<'a>(&self, samples: impl Iterator<Item = &'a mut Lanes>) {
        // A fixed number of sections lets the states live in registers: kept in a heap vector,
        // every sample's recursion would wait on a store and a reload of each state.
        match self.sections.len() {
            1 => self.run_sections::<1>(samples),
            2 => self.run_sections::<2>(samples),
            3 => self.run_sections::<3>(samples),
            4 => self.run_sections::<4>(samples),
            5 => self.run_sections::<5>(samples),
            6 => self.run_sections::<6>(samples),
            n => unreachable!("orders 1 to 12 give 1 to 6 sections, not {n}"),
        }
    }

    fn run_sections<'a, const S: usize>(&self, samples: impl Iterator<Item = &'a mut Lanes>) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx") {
            // SAFETY: the processor has just been found to support AVX.
            return unsafe { self.run_sections_avx::<S>(samples) };
        }
        self.run_sections_with::<S>(samples)
    }

    /// [`Self::run_sections_with`] compiled for AVX, whose sixteen four-wide registers hold a
    /// sample's lanes in one and most of the sections' states besides: with two-wide SSE2
    /// registers the states spill to memory on every sample. The arithmetic is the same
    /// operations in the same order (Rust never fuses a multiply and an add on its own), so the
    /// result is bit for bit the portable one's.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn run_sections_avx<'a, const S: usize>(&self, samples: impl Iterator<Item = &'a mut Lanes>) {
        self.run_sections_with::<S>(samples)
    }

    #[inline(always)]
    fn run_sections_with<'a, const S: usize>(&self, mut samples: impl Iterator<Item = &'a mut Lanes>) {
        let Some(first) = samples.next() else { return };
        let y0 = *first;
        let section = |i: usize| &self.sections[i];
        let coefficients: [([f64; 3], [f64; 3]); S] = std::array::from_fn(|i| (section(i).b, section(i).a));
        let mut z0: [Lanes; S] = std::array::from_fn(|i| y0.map(|v| section(i).zi0 * v));
        let mut z1: [Lanes; S] = std::array::from_fn(|i| y0.map(|v| section(i).zi1 * v));
        for sample in std::iter::once(first).chain(samples) {
            let mut x = *sample;
            for (i, (b, a)) in coefficients.iter().enumerate() {
                let mut y = [0.0; LANES];
                for l in 0..LANES {
                    y[l] = b[0] * x[l] + z0[i][l];
                    z0[i][l] = b[1] * x[l] - a[1] * y[l] + z1[i][l];
                    z1[i][l] = b[2] * x[l] - a[2] * y[l];
                }
                x = y;
            }
            *sample = x;
        }
    }
}

/// Channels filtered side by side (see [`Butterworth::filtfilt_rows`]).
pub const LANES: usize = 4;
type Lanes = [f64; LANES];

/// A signal is cut into pieces of at least this many samples to be filtered side by side.
const PIECE_SAMPLES: usize = 1 << 16;

/// The rows one piece of a signal reads: `before` of its neighbour's, its own `len`, `after` of
/// the next one's, from row `from` on.
#[derive(Clone, Copy)]
struct Piece {
    from: usize,
    before: usize,
    len: usize,
    after: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Filtered white noise at two samples `lag` apart is correlated as the impulse response with
    /// itself shifted: nearly uncorrelated at twice the memory, still clearly at half of it; and
    /// the memory scales with the cut-off's period.
    #[test]
    fn samples_twice_the_memory_apart_share_almost_no_noise() {
        let fs = 1000.0;
        let mut per_period = Vec::new();
        for cutoff in [2.0, 20.0] {
            let filter = Butterworth::lowpass(5, cutoff, fs).unwrap();
            let memory = filter.memory_s(fs);
            let n = 2 * filter.settle + 1;
            let mut impulse = vec![0.0; n];
            impulse[n / 2] = 1.0;
            let mut h = vec![0.0; n];
            filter.filtfilt(&impulse, &mut h).unwrap();
            let correlation = |lag: usize| h.iter().zip(&h[lag..]).map(|(a, b)| a * b).sum::<f64>();
            let lag = |s: f64| (s * fs).round() as usize;
            assert!(correlation(lag(2.0 * memory)).abs() < 0.05 * correlation(0), "{cutoff} Hz");
            assert!(correlation(lag(0.5 * memory)) > 0.3 * correlation(0), "{cutoff} Hz");
            per_period.push(memory * cutoff);
        }
        assert!((per_period[0] / per_period[1] - 1.0).abs() < 0.05, "{per_period:?}");
    }

    #[test]
    fn passes_dc_and_stops_high_frequencies() {
        let filter = Butterworth::lowpass(5, 10.0, 1000.0).unwrap();
        let (b, a) = filter.coefficients();
        let dc_gain = b.iter().sum::<f64>() / a.iter().sum::<f64>();
        // The b/a form at a low cut-off is ill-conditioned; scipy's own DC gain is off by ~1e-9 too.
        assert!((dc_gain - 1.0).abs() < 1e-8, "DC gain {dc_gain}");
        let n = 4000;
        let x: Vec<f64> =
            (0..n).map(|i| 1.0 + (2.0 * std::f64::consts::PI * 200.0 * i as f64 / 1000.0).sin()).collect();
        let mut y = vec![0.0; n];
        filter.filtfilt(&x, &mut y).unwrap();
        // Away from the ends, where the padding transient has died out.
        assert!(y[1000..n - 1000].iter().all(|v| (v - 1.0).abs() < 1e-6), "200 Hz should vanish, DC stay");
    }

    /// The previous evaluation order, one channel and one section at a time over the whole
    /// padded signal, kept here as the reference the side-by-side evaluation must equal exactly.
    fn one_channel_at_a_time(filter: &Butterworth, x: &[f64]) -> Vec<f64> {
        let (n, pad) = (x.len(), filter.padlen());
        let mut y: Vec<f64> = (1..=pad).rev().map(|i| 2.0 * x[0] - x[i]).collect();
        y.extend_from_slice(x);
        y.extend((2..pad + 2).map(|i| 2.0 * x[n - 1] - x[n - i]));
        for _ in 0..2 {
            let y0 = y[0];
            for section in &filter.sections {
                let (b, a) = (&section.b, &section.a);
                let (mut z0, mut z1) = (section.zi0 * y0, section.zi1 * y0);
                for sample in y.iter_mut() {
                    let x = *sample;
                    let out = b[0] * x + z0;
                    z0 = b[1] * x - a[1] * out + z1;
                    z1 = b[2] * x - a[2] * out;
                    *sample = out;
                }
            }
            y.reverse();
        }
        y[pad..pad + n].to_vec()
    }

    #[test]
    fn channels_side_by_side_equal_each_channel_alone_bit_for_bit() {
        let filter = Butterworth::lowpass(5, 3.0, 1000.0).unwrap();
        let n = 2000;
        // Seven channels: one full group of lanes and a partial one.
        let width = 7;
        let x: Vec<f64> = (0..n * width).map(|i| ((i * 7919) as f64).sin() + 0.01 * i as f64).collect();
        let mut rows = vec![0.0; x.len()];
        filter.filtfilt_rows(&x, width, &mut rows).unwrap();
        for j in 0..width {
            let column: Vec<f64> = x.iter().skip(j).step_by(width).copied().collect();
            let reference = one_channel_at_a_time(&filter, &column);
            let ours: Vec<f64> = rows.iter().skip(j).step_by(width).copied().collect();
            assert!(ours.iter().zip(&reference).all(|(a, b)| a.to_bits() == b.to_bits()), "channel {j} differs");
        }
    }

    #[test]
    fn periodic_filtering_is_the_middle_of_three_copies_bit_for_bit() {
        let filter = Butterworth::lowpass(5, 2.0, 1000.0).unwrap();
        let (n, width) = (1500, 5);
        let x: Vec<f64> = (0..n * width).map(|i| ((i * 104_729) as f64).cos() + 0.002 * i as f64).collect();
        let mut periodic = vec![0.0; x.len()];
        filter.filtfilt_rows_periodic(&x, width, &mut periodic).unwrap();
        for j in 0..width {
            let column: Vec<f64> = x.iter().skip(j).step_by(width).copied().collect();
            let reference = one_channel_at_a_time(&filter, &column.repeat(3));
            let ours = periodic.iter().skip(j).step_by(width);
            assert!(ours.zip(&reference[n..2 * n]).all(|(a, b)| a.to_bits() == b.to_bits()), "channel {j} differs");
        }
    }

    #[test]
    fn a_long_periodic_signal_reads_only_the_filters_memory_of_its_copies() {
        // 14 s of memory (1 Hz, order 5) against 40 s of signal: the neighbours are read only
        // partly, and the result is the three copies' to round-off.
        let filter = Butterworth::lowpass(5, 1.0, 1000.0).unwrap();
        assert!(filter.settle < 20_000, "{}", filter.settle);
        let n = 40_000;
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.0123).sin() + ((i * 7919) as f64).sin()).collect();
        let mut periodic = vec![0.0; n];
        filter.filtfilt_rows_periodic(&x, 1, &mut periodic).unwrap();
        let reference = one_channel_at_a_time(&filter, &x.repeat(3));
        let worst = periodic.iter().zip(&reference[n..2 * n]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-12, "{worst}");
    }

    /// A signal long enough to be cut into pieces gives the whole's result to round-off, periodic
    /// or not, at the pieces' seams as everywhere else.
    #[test]
    fn a_signal_filtered_in_pieces_is_the_whole_signal_filtered() {
        let filter = Butterworth::lowpass(5, 20.0, 1000.0).unwrap();
        let n = 3 * PIECE_SAMPLES + 1234;
        assert!(filter.pieces(n, 0) >= 3, "{} pieces", filter.pieces(n, 0));
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.00123).sin() + ((i * 7919) as f64).sin()).collect();
        let worst = |ours: &[f64], reference: &[f64]| {
            ours.iter().zip(reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
        };
        let mut pieces = vec![0.0; n];
        filter.filtfilt(&x, &mut pieces).unwrap();
        assert!(worst(&pieces, &one_channel_at_a_time(&filter, &x)) < 1e-12);
        filter.filtfilt_rows_periodic(&x, 1, &mut pieces).unwrap();
        let three = one_channel_at_a_time(&filter, &x.repeat(3));
        assert!(worst(&pieces, &three[n..2 * n]) < 1e-12);
    }

    #[test]
    fn bad_designs_and_short_signals_are_refused() {
        assert!(matches!(Butterworth::lowpass(5, 600.0, 1000.0), Err(FilterError::CutoffOutOfRange { .. })));
        assert!(matches!(Butterworth::lowpass(0, 10.0, 1000.0), Err(FilterError::BadOrder(0))));
        let filter = Butterworth::lowpass(5, 10.0, 1000.0).unwrap();
        let err = filter.filtfilt(&[0.0; 18], &mut [0.0; 18]).unwrap_err();
        assert_eq!(err, FilterError::TooShort { what: "the signal".into(), len: 18, padlen: 18 });
    }
}
