"""Pure numba kernels: functions of floats and arrays, no Python objects, no globals that change.

- :mod:`.physics`   coefficients A, B, C, the effective potential, invariants, equations of motion,
                    contact forces;
- :mod:`.roots`     circular radius and turning points;
- :mod:`.carlson`   Carlson's symmetric elliptic integrals R_F, R_D, R_J, R_C;
- :mod:`.geometry`  classification and closed-form orbit geometry, one point and a parallel batch.
"""
