"""An independent yardstick for held-out prediction (issue 59): scipy's zero-phase Butterworth
at 8 Hz on q and τ, numpy's differences for q̇ and q̈, each model's ``predict``, and ‖e‖/‖τ‖ per
joint over the run (its filter's start-up left out). "Worse" is the mean over samples of
e_diagnosed² − e_identified² above twice its standard error from 1 s batch means.

The prediction goes through the torque's filter too (parallel filtering, as in Gautier's
identification and in arash's own columns). Without it a Coulomb law is judged by how well its
own width mimics the filter: at a reversal the filtered torque's friction step is spread over the
filter's memory (a 1/8 Hz stretch) and sign(q̇)'s predicted step is not, so the yardstick rewarded
any tanh law about as wide as that smear, whatever the joint's friction. On a Pinocchio log of
the declared model whose yaw has sign(q̇) friction (20-bit, 10 s; bench/from_identified_nulls.py),
the diagnosis's sign(q̇) was 2.6 times worse than the identification's tanh(q̇/0.034) on that
yardstick and 0.63 times as bad with the prediction filtered; on a third run 0.70 and 0.11."""

import numpy as np
from scipy.signal import butter, filtfilt

CUTOFF_HZ = 8.0  # the common yardstick
BATCH_S = 1.0
SIGMAS = 2.0


def yardstick(models, t, q, tau):
    """Per model, the residual on the filtered run; the filtered torque; samples per batch."""
    fs = 1.0 / np.median(np.diff(t))
    b, a = butter(4, CUTOFF_HZ / (fs / 2))
    qf, tauf = filtfilt(b, a, q, axis=0), filtfilt(b, a, tau, axis=0)
    qd = np.gradient(qf, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    edge = 3 * int(fs / CUTOFF_HZ)
    inner = slice(edge, len(t) - edge)
    predicted = [filtfilt(b, a, m.predict(qf, qd, qdd), axis=0) for m in models]
    return [(tauf - p)[inner] for p in predicted], tauf[inner], max(1, int(BATCH_S * fs))


def excess_in_sigmas(diagnosed, identified, batch):
    """Per joint, the mean of e_d² − e_i² in standard errors of batch means (0 where equal)."""
    d = diagnosed**2 - identified**2
    n = len(d) // batch
    means = d[: n * batch].reshape(n, batch, -1).mean(axis=1)
    se = means.std(axis=0, ddof=1) / np.sqrt(n)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(se > 0, d.mean(axis=0) / se, 0.0)


def relative(e, tau):
    return np.linalg.norm(e, axis=0) / np.linalg.norm(tau, axis=0)


def assert_no_joint_worse(identified, diagnosed, run, label):
    (e_i, e_d), tau, batch = yardstick([identified, diagnosed], *run)
    z = excess_in_sigmas(e_d, e_i, batch)
    print(f"\n{label}: ‖e‖/‖τ‖ identified {np.round(relative(e_i, tau), 3)}, "
          f"diagnosed {np.round(relative(e_d, tau), 3)}; excess in σ {np.round(z, 1)}")
    assert np.all(z <= SIGMAS), (label, z)
    return relative(e_i, tau), relative(e_d, tau)
