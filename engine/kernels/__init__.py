"""Pure numba kernels: functions of floats and arrays, no Python objects, no globals that change.

- :mod:`.model`      the model interface: what the drivers ask of the physics, the registry of
                     models (the cone first), the right-hand side with the effects compiled in;
- :mod:`.layouts`    the parameter array's slots and the state vector, declared once;
- :mod:`.effects`    the effects table; :mod:`.forces` the effects' forces and couples;
- :mod:`.cone`       the cone: one copy of each of its formulas (A, B, C, V, the invariants, the
                     contact forces, its equations of motion); :mod:`.cone_starts` where its
                     runs start;
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
- :mod:`.orbit`      the run kernels by method id, one radial period, the parallel batch.
"""
