"""The survey file format in words, written from the tables the parser reads: its top-level keys
(:data:`TOP_KEYS`), the ``[horizon]`` keys, the fields of :class:`engine.Scene` (from its
docstring), the axes (:data:`engine.schema.AXES`: units and long names) and their syntax
(:mod:`engine.surveyaxes`). ``conesurvey run --help`` prints :func:`survey_file_help`, so that
a key the parser takes cannot be missing from the help (a test compares the two).
"""

from __future__ import annotations

import dataclasses
import re
import textwrap

from .checks import PRECISIONS
from .kernels.geometry import CIRCULAR_TOL
from .methods import DEFAULT_RTOL, METHODS, RTOL_RANGE
from .scene import Scene
from .schema import AXES, DIMS, LAUNCH_DIMS, RELEASE, RELEASE_AXES
from .surfaces import SURFACES
from .surveyaxes import RELATIVE_TO, SCALES

__all__ = ["HORIZON_KEYS", "TOP_KEYS", "scene_keys", "survey_file_help"]

#: The top level of a survey file: each key the parser reads and what it holds.
TOP_KEYS: dict[str, str] = {
    "title": "free text, stored with the results (optional)",
    "method": f"{' | '.join(METHODS)} (default exact)",
    "rtol": f"relative tolerance of the integrators, in [{RTOL_RANGE[0]:g}, {RTOL_RANGE[1]:g}] "
    f"(default {DEFAULT_RTOL:g})",
    "circular_tol": f"relative width of the circular class (default {CIRCULAR_TOL:g})",
    "precision": " | ".join(f'"{p}"' for p in PRECISIONS)
    + ': "single" stores float results as float32 (default "double")',
    "scene": "the [scene] table",
    "horizon": "the [horizon] table",
    "axes": "the [axes.NAME] tables",
    "surface": "the [surface] table: a surface of revolution instead of the cone",
}
#: The ``[horizon]`` table: how long a fate map follows each orbit.
HORIZON_KEYS: dict[str, str] = {
    "time": "how long each orbit is followed [s], and/or",
    "revolutions": "how many revolutions about the axis",
}
_WIDTH = 92


def scene_keys() -> str:
    """One line per field of :class:`engine.Scene`, from the dataclass and its docstring (so the
    list cannot drift from the scene the engine reads)."""
    doc: dict[str, str] = {}
    name = None
    for line in (Scene.__doc__ or "").splitlines():
        m = re.match(r"\s*(\w+) : (.*)", line)
        if m:
            name = m.group(1)
            doc[name] = m.group(2).strip()
        elif name and line.startswith(" " * 8) and line.strip():  # the field's next lines
            doc[name] += " " + line.strip()
        else:
            name = None
    lines = []
    for f in dataclasses.fields(Scene):
        if f.name.startswith("_"):
            continue
        first = re.split(r"(?<=[a-z)])\. ", doc.get(f.name, ""))[0]  # its first sentence
        text = first.replace("``", "").replace("None =", "absent =").rstrip(".")
        default = f.default
        if default is None or isinstance(default, bool):  # as TOML would say it
            default = "absent" if default is None else str(default).lower()
        text = f"{text}; default {default}" if text else f"default {default}"
        lines += textwrap.wrap(
            text, _WIDTH, initial_indent=f"  {f.name:<9} ", subsequent_indent=" " * 12
        )
    return "\n".join(lines)


def _axis(name: str, extra: str = "") -> str:
    """``  [axes.h]       spin invariant h = ... [m s-1]``, from the schema's axis table."""
    var = AXES[name]
    units = f" [{var.units}]" if var.units and var.units != "1" else ""
    text = f"{var.long_name}{units}{extra}"
    head = f"  {'[axes.' + name + ']':<16} "
    return "\n".join(textwrap.wrap(text, _WIDTH, initial_indent=head,
                                   subsequent_indent=" " * len(head)))  # fmt: skip


def _keys(table: dict[str, str], indent: int = 2) -> str:
    return "\n".join(f"{' ' * indent}{k:<15}{v}" for k, v in table.items())


def survey_file_help() -> str:
    """The survey file format, key by key (``conesurvey run --help``)."""
    top = {k: v for k, v in TOP_KEYS.items() if k not in ("scene", "horizon", "axes")}
    relative = f'; relative_to = "{RELATIVE_TO[0]}": offsets (energy - V_min)/|V_min|'
    alpha = ", in (0, pi/2)"
    sliding = [_axis(n) for n in RELEASE] + [_axis("backspin", ", instead of slip_u")]
    extra = [n for n in RELEASE_AXES if n not in RELEASE]
    assert extra == ["backspin"], extra  # every axis of the release is listed above
    return "\n".join(
        [
            "top level:",
            _keys(top),
            "[scene], any of:",
            scene_keys(),
            "[horizon], required by a fate map (an integrator on a scene with c_rr, rim, mu):",
            _keys(HORIZON_KEYS),
            "the axes, each values = [...] or start, stop, num with scale = "
            + " or ".join(f'"{s}"' for s in SCALES)
            + ":",
            _axis(DIMS[0], alpha) + ", and either the invariants",
            *(_axis(n, relative if n == "energy" else "") for n in DIMS[1:]),
            "  or the launch states (released with radial speed 0):",
            *(_axis(n, ", > 0" if n == "r0" else "") for n in LAUNCH_DIMS[1:]),
            "  and, on a scene with mu_k (sliding), the release (each absent axis is 0):",
            *sliding,
            *surface_help(),
        ]
    )


def surface_help() -> list[str]:
    """The ``[surface]`` table and its launch axes: one line per kind, from
    :data:`engine.surfaces.SURFACES` (each parameter may be an axis instead)."""
    lines = ["[surface], a surface of revolution instead of the cone: kind = one of"]
    for kind, cls in SURFACES.items():
        params = ", ".join(f"{p} [{u}]" for p, u in cls.parameters.items())
        if kind == "profile":
            params = 'profile = "FILE" (two columns, rho and z [m])'
        lines.append(f"  {kind:<15}{params or 'no parameters'}")
    lines += [
        "  each parameter a number in [surface], or an axis of the same name; then the axes",
        _axis("rho0", " (the cylinder: [axes.z0], its height [m])"),
        "  with [axes.v0] and [axes.w0] as above",
    ]
    return lines
