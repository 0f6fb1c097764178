"""High-precision oracle for tests (mpmath): an independent second method.

Turning points and circular radius from mpmath.polyroots; period and apsidal angle by
tanh-sinh quadrature of the defining integrals (no elliptic integrals, no Carlson); relative
condition numbers by perturbing every input by a relative 1e-30 at 60 digits, the same
definition the reference data use (the error rounding alone puts into a backward-stable code).
"""

from __future__ import annotations

import mpmath as mp

OUTPUTS = ("r1", "r2", "r_c", "T_r", "psi", "precession_rate")
INPUTS = ("alpha", "calE", "h", "Lz", "M", "g", "k")


def _real_roots(coeffs):
    roots = mp.polyroots(coeffs, maxsteps=400, extraprec=400)
    return sorted(mp.re(z) for z in roots if abs(mp.im(z)) <= mp.mpf(10) ** (-mp.mp.dps // 2))


def solve(alpha, calE, h, Lz, M, g, k, circ_tol=1e-12):
    """Class and outputs of one orbit at the current mpmath precision (inputs exact)."""
    alpha, calE, h, Lz, M, g, k = (mp.mpf(x) for x in (alpha, calE, h, Lz, M, g, k))
    s, c = mp.sin(alpha), mp.cos(alpha)
    kk = k / (1 + k)
    A = Lz**2 / (2 * M * s**2) * (1 + kk * (c / s) ** 2)
    B = kk * h * Lz * c / s**2
    C = M * g * c / (1 + k)
    K = abs(Lz) / (M * s**2)
    out = dict.fromkeys(OUTPUTS)
    out["sweep"] = None
    if Lz == 0:
        if g > 0 and calE > 0:
            out.update(cls="radial", r1=mp.mpf(0), r2=calE / C)
            out["T_r"] = 2 * mp.sqrt(2 * M * out["r2"] / C)
        else:
            out["cls"] = "forbidden"
        return out
    rc = None
    if C > 0:
        rc = [r for r in _real_roots([C, 0, -B, -2 * A]) if r > 0][0]
    elif B < 0:
        rc = -2 * A / B
    out["r_c"] = rc
    mp.sqrt(1 - c**2 / (1 + k))
    if rc is not None:
        Vmin = A / rc**2 + B / rc + C * rc
        terms = A / rc**2 + abs(B) / rc + C * rc  # the size of V_min's terms (docs "Classes")
        if abs(calE - Vmin) <= circ_tol * terms:
            w_r = mp.sqrt((6 * A / rc**4 + 2 * B / rc**3) / M)
            T = 2 * mp.pi / w_r
            psi = mp.pi * K / rc**2 / w_r
            out.update(cls="circular", r1=rc, r2=rc, T_r=T, psi=psi)
            out["precession_rate"] = (2 * psi - 2 * mp.pi) / T
            return out
        if calE < Vmin:
            out["cls"] = "forbidden"
            return out
    if g == 0:
        if calE >= 0 and (B < 0 or calE > 0):
            W1 = (-B + mp.sqrt(B**2 + 4 * A * calE)) / (2 * A)  # 1/r_min
            W2 = (-B - mp.sqrt(B**2 + 4 * A * calE)) / (2 * A)
            f = lambda W: 1 / mp.sqrt((2 / M) * A * (W1 - W) * (W - W2))  # noqa: E731
            half = K * mp.re(mp.quad(f, [0, W1]))
            out.update(cls="hyperbolic", r1=1 / W1, psi=half)
            out["sweep"] = 2 * half
            return out
        if rc is None or calE >= 0:
            out["cls"] = "forbidden"
            return out
        r1, r2 = _real_roots([-calE, B, A])  # |calE| r^2 + B r + A
        r3 = None
        kin = lambda r: (2 / M) * (-calE)  # noqa: E731  (energy - V) r^2 / ((r-r1)(r2-r))
    else:
        r3, r1, r2 = _real_roots([C, -calE, B, A])
        kin = lambda r: (2 / M) * C * (r - r3)  # noqa: E731
    # r = r1 + (r2 - r1) sin^2(t) removes the endpoint singularities.
    rr = lambda t: r1 + (r2 - r1) * mp.sin(t) ** 2  # noqa: E731
    T = 2 * mp.quad(lambda t: 2 * rr(t) / mp.sqrt(kin(rr(t))), [0, mp.pi / 2])
    psi = K * mp.quad(lambda t: 2 / (rr(t) * mp.sqrt(kin(rr(t)))), [0, mp.pi / 2])
    out.update(cls="bounded", r1=r1, r2=r2, T_r=T, psi=psi)
    out["precession_rate"] = (2 * psi - 2 * mp.pi) / T
    return out


def reference(alpha, calE, h, Lz, M=1.0, g=9.81, k=0.4, circ_tol=1e-12, with_cond=True):
    """Outputs (floats) and their relative condition numbers for double inputs."""
    args = dict(alpha=alpha, calE=calE, h=h, Lz=Lz, M=M, g=g, k=k)
    with mp.workdps(60):
        base = solve(**args, circ_tol=circ_tol)
        vals = {n: base[n] for n in (*OUTPUTS, "sweep") if base.get(n) is not None}
        cond = {}
        if with_cond and base["cls"] in ("bounded", "hyperbolic"):
            d = mp.mpf(10) ** -30
            for n in vals:
                cond[n] = mp.mpf(0)
            for name in INPUTS:
                x = mp.mpf(args[name])
                if x == 0:
                    continue
                pert = dict(args)
                pert[name] = x * (1 + d)
                p = solve(**pert, circ_tol=circ_tol)
                for n in vals:
                    if vals[n] != 0 and p.get(n) is not None:
                        cond[n] += abs((p[n] - vals[n]) / (d * vals[n]))
    return (
        base["cls"],
        {n: float(v) for n, v in vals.items()},
        {n: float(v) for n, v in cond.items()},
    )


def tolerance(cond: float | None) -> float:
    """The reference data's test tolerance: max(1e-12, 50 cond 2.2e-16), relative."""
    return max(1e-12, 50.0 * (cond or 1.0) * 2.2e-16)
