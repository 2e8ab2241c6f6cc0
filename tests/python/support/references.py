"""Independent references the defaults are compared against: the physically consistent fit
written in cvxpy (not arash's Clarabel problem), and the best any hand-set cut-off gives."""

import numpy as np

import arash

# The cut-offs a default is compared with: this many, log-spaced from 0.5 Hz to a quarter of the
# sample rate, ...
GRID_POINTS = 16
# ... that pass the trajectory: at least this many times its highest frequency. A cut-off below
# the motion's own harmonics filters them out of the torque and the regressor alike, and the fit
# of what is left can score a higher training FP% (the TX40 log in test_preprocessing_choices.py:
# 98.5 at 0.5 Hz, where its harmonics reach 1 Hz) while its model predicts the log's torque at
# −459 %. That is no model of the log, and no cut-off a user should be pointed to.
PASSES_THE_MOTION = 2.0


def cvxpy_consistent(cp, robot, W, tau, pull):
    """The consistent problem written independently in cvxpy (see consistent.rs)."""
    m = W.shape[0]
    cad = robot.cad_parameters()
    ell = 0.1
    scales = []
    for b in range(8):
        mass = cad[10 * b]
        scales += [mass] + [mass * ell] * 3 + [mass * ell**2] * 6
    scales = np.array(scales + [1.0] * 9)
    gram_diag = (W**2).sum(axis=0)
    mean_curv = np.mean(gram_diag * scales**2)
    lam = pull * (gram_diag + 1e-3 * mean_curv / scales**2)
    x = cp.Variable(89)
    objective = (cp.sum_squares(W @ x - tau) + cp.sum(cp.multiply(lam, cp.square(x - cad)))) / m
    constraints = [x[80:86] >= 0, x[86:89] >= 0]
    for b in range(8):
        m_, hx, hy, hz, ixx, iyy, izz, ixy, ixz, iyz = [x[10 * b + i] for i in range(10)]
        J = cp.bmat([
            [0.5 * (-ixx + iyy + izz), -ixy, -ixz, hx],
            [-ixy, 0.5 * (ixx - iyy + izz), -iyz, hy],
            [-ixz, -iyz, 0.5 * (ixx + iyy - izz), hz],
            [hx, hy, hz, m_],
        ])
        constraints.append(J >> 0)
    problem = cp.Problem(cp.Minimize(objective), constraints)
    problem.solve(solver=cp.CLARABEL)
    assert problem.status == "optimal"
    value = lambda v: (((W @ v - tau) ** 2).sum() + (lam * (v - cad) ** 2).sum()) / m
    return x.value, problem.value, value


def fits_by_cutoff(robot, log, fs, top_frequency=0.0):
    """FP% per joint at each cut-off of the grid at or above PASSES_THE_MOTION × `top_frequency`
    (the period left to arash): rows are cut-offs."""
    rows = []
    grid = np.geomspace(0.5, fs / 4, GRID_POINTS)
    for cutoff in grid[grid >= PASSES_THE_MOTION * top_frequency]:
        try:
            rows.append(arash.identify(robot, *log, cutoff_hz=float(cutoff)).fp_percent)
        except ValueError:  # a cut-off the log cannot be filtered or fitted at is no candidate
            continue
    return np.array(rows)
