"""Pure numba kernels: functions of floats and arrays, no Python objects, no globals that change.

- :mod:`.model`      one copy of each formula: coefficients A, B, C, the effective potential,
                     invariants, contact forces, the parameter array, effect bits and the
                     scene's right-hand side with the effects compiled in by flags;
- :mod:`.roots`      circular radius and turning points;
- :mod:`.carlson`    Carlson's symmetric elliptic integrals R_F, R_D, R_J, R_C and Bulirsch's cel;
- :mod:`.geometry`   classification and closed-form orbit geometry, one point and a parallel batch;
- :mod:`.tableaux`   Runge-Kutta pairs (:data:`~.tableaux.RK_TABLEAUX`) and composition weights;
- :mod:`.protocol`   the run protocol: statuses, event kinds, buffers, shared event helpers, Brent;
- :mod:`.rk_codegen` Runge-Kutta steps generated from tableau data;
- :mod:`.rk_events`  a step's dense output, event location, apsides polished to step accuracy;
- :mod:`.rk`         the adaptive Runge-Kutta run kernel and its step-size control;
- :mod:`.lanes_step` the vectorised step and step-size control of several orbits at once;
- :mod:`.lanes`      the batch of the Runge-Kutta methods on the SIMD lanes (bit for bit the run
                     kernel's results);
- :mod:`.symplectic` time-transformed leapfrog with Yoshida compositions, on the same protocol;
- :mod:`.orbit`      start state, tolerances, one radial period, the parallel batch over points.
"""
