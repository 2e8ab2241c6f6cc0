"""What the Python tests and the benches share, none of it a test: where things are
(``paths``), the independent Pinocchio generator (``independent``) and its closed loop
(``closed_loop``), the simulated data with known truth (``simulated``) and the independent
references the defaults are compared against (``references``: cvxpy's consistent fit, the best
hand-set cut-off)."""
