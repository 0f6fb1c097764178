"""Pure numba kernels: functions of floats and arrays, no Python objects, no globals that change.

- :mod:`.physics`   coefficients A, B, C, the effective potential, invariants, equations of motion,
                    contact forces;
- :mod:`.roots`     circular radius and turning points;
- :mod:`.carlson`   Carlson's symmetric elliptic integrals R_F, R_D, R_J, R_C;
- :mod:`.geometry`  classification and closed-form orbit geometry, one point and a parallel batch;
- :mod:`.tableaux`  Butcher tableaux (Dormand-Prince 5(4), 8(5,3)) and Yoshida weights as data;
- :mod:`.scenes`    right-hand sides with effects compiled in by flags, parameters in an array;
- :mod:`.integrators` adaptive Runge-Kutta loop, dense output, event location;
- :mod:`.symplectic` time-transformed leapfrog with Yoshida compositions.
"""
