"""The zero-phase Butterworth filter against scipy.

arash evaluates the filtfilt function in second-order sections. scipy's filtfilt(b, a) evaluates the
same function in one b/a polynomial, and that form is badly conditioned at low cut-offs. So the
comparison is in two parts:

- against scipy.signal.sosfiltfilt, with filtfilt's default padding (odd, 3·(order + 1)), at every
  cut-off;
- against scipy.signal.filtfilt(b, a) itself, at 1e-9, wherever scipy's b/a result agrees with its
  own sections to 1e-10. The test also shows that elsewhere scipy is the one that is off.
"""

import numpy as np
import pytest
from scipy import signal

import arash

FS = 1000.0


def signal_3d(n=15_000, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    slow = np.stack([np.sin(2 * np.pi * 0.3 * t + k) * (k + 1) for k in range(3)], axis=1)
    return slow + 0.01 * rng.normal(size=(n, 3)) + np.array([0.1, -0.2, 0.05])


def relative(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


@pytest.mark.parametrize("order", [2, 3, 5, 6])
@pytest.mark.parametrize("cutoff", [0.5, 2.0, 10.0, 50.0, 200.0])
def test_coefficients_match_scipy_butter(order, cutoff):
    b, a = arash.butter(order, cutoff, FS)
    b_ref, a_ref = signal.butter(order, cutoff, fs=FS)
    assert b.shape == b_ref.shape and a.shape == a_ref.shape
    np.testing.assert_allclose(b, b_ref, rtol=1e-12, atol=0)
    np.testing.assert_allclose(a, a_ref, rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("order", [2, 5, 6])
@pytest.mark.parametrize("cutoff", [0.5, 2.0, 10.0, 50.0, 200.0])
def test_filtfilt_matches_scipy_sections_with_filtfilt_padding(order, cutoff):
    x = signal_3d()
    ours = arash.filtfilt(x, cutoff, FS, order=order)
    sos = signal.butter(order, cutoff, fs=FS, output="sos")
    ref = signal.sosfiltfilt(sos, x, axis=0, padtype="odd", padlen=3 * (order + 1))
    assert relative(ours, ref) < 1e-9
    # A 1-D input gives the same as its column.
    np.testing.assert_array_equal(arash.filtfilt(x[:, 1], cutoff, FS, order=order), ours[:, 1])


@pytest.mark.parametrize("cutoff", [0.5, 2.0, 10.0, 50.0, 100.0, 200.0, 400.0])
def test_filtfilt_matches_scipy_filtfilt_wherever_scipy_is_accurate(cutoff):
    x = signal_3d(seed=1)
    b, a = signal.butter(5, cutoff, fs=FS)
    ref_ba = signal.filtfilt(b, a, x, axis=0)  # scipy's default padding
    ref_sos = signal.sosfiltfilt(signal.butter(5, cutoff, fs=FS, output="sos"), x, axis=0,
                                 padtype="odd", padlen=18)
    ours = arash.filtfilt(x, cutoff, FS)
    scipy_self_agreement = relative(ref_ba, ref_sos)
    if scipy_self_agreement < 1e-10:
        assert relative(ours, ref_ba) < 1e-9, f"{cutoff} Hz"
    else:
        # scipy's b/a result is the outlier: we agree with its sections far better than it does.
        assert relative(ours, ref_sos) < 1e-3 * scipy_self_agreement, f"{cutoff} Hz"


def test_bad_filter_requests_raise():
    with pytest.raises(ValueError, match="Nyquist"):
        arash.filtfilt(np.zeros(100), 600.0, FS)
    with pytest.raises(ValueError, match="needs more than 18"):
        arash.filtfilt(np.zeros(10), 10.0, FS)
    with pytest.raises(ValueError, match="NaN"):
        arash.filtfilt(np.full(100, np.nan), 10.0, FS)
