"""The effects table: every effect beyond the ideal cone that a scene can call for, one row each.

A row (:class:`Effect`) says all the package needs to know about an effect: its name (as in
:attr:`engine.Scene.effects`, survey files and messages), its bit in the ``effects`` mask the
kernels compile in, the :class:`engine.Scene` field that calls for it and the parameter slots
that field fills, whether it dissipates energy, which terminal events it brings into a run, what
a method must be able to do to honour it, and which output variables it adds. Everything else
derives from the rows: the bit masks below, ``Scene.effects`` and the scene's parameter array,
the kind of map (``engine.schema.map_kind``: a dissipative effect or a terminal event makes an
integrator follow each orbit to its fate), the variable lists, the terminal events a run checks
(``.protocol.kind_enabled``) and every method's refusals (``engine.methods``: a method declares
the :data:`CAPABILITIES` it has; an effect needing one it lacks is refused with the method's
reason for lacking it).

A new effect is one row here (its parameter slots named here, laid out by :mod:`.layouts`), its
forces and couples in :mod:`.forces` (every model asks them, rolling and sliding) and its
:class:`engine.Scene` field; docs/architecture.md "A new effect".

Gravity (g = 0 is free fall) and the spin coupling (k = 0) are parameters, not effects. This
module is plain data (no numba): the kernels read its masks as compile-time constants.
"""

from __future__ import annotations

from typing import NamedTuple

#: What a method may need to be able to do to honour an effect -> what that means. Every method
#: declares, for each, that it can or why it cannot (``engine.methods``).
CAPABILITIES: dict[str, str] = {
    "dissipative forces": "follow forces that do work on the sphere (energy not conserved)",
    "rigid-body state": "carry the sphere's orientation in the state",
    "terminal events": "end a run where the sphere leaves the rolling regime",
    "sliding contact": "release the rolling constraint: follow a sliding sphere's full angular "
    "velocity under kinetic friction, and its return to rolling",
}

#: How a scene field calls for its effect: "coefficient" (a number >= 0; on when > 0),
#: "limit" (None or a number > 0; on when given), "flag" (a bool; on when true).
SWITCHES = ("coefficient", "limit", "flag")

#: Where an effect's output variables go: "closed form" (maps by the closed form), "period"
#: (one integrated radial period, ``engine.integrated``), "fate" (fate maps), "trajectory"
#: (``engine.simulate``).
OUTPUTS = ("closed form", "period", "fate", "trajectory")


class Effect(NamedTuple):
    """One effect beyond the ideal cone (see the module docstring)."""

    name: str
    bit: int
    scene_field: str
    switch: str
    #: Parameter slots (names; :mod:`.layouts` gives each its index) the scene field's value
    #: fills (None -> +inf).
    params: tuple[str, ...]
    #: Acts through a force on the centre or a couple on the sphere: its terms are in
    #: :mod:`.forces`, which every model asks in every mode (rolling and sliding).
    forces: bool
    #: Does work on the sphere: the state carries the work done (the last component), the energy
    #: balance E + W is checked, and an integrator follows each orbit to its fate.
    dissipative: bool
    #: Terminal event kinds (``.protocol.EVENT_NAMES``) it brings into a run.
    events: tuple[str, ...]
    #: :data:`CAPABILITIES` a method needs to honour it.
    needs: tuple[str, ...]
    #: (output, variable names) it adds (:data:`OUTPUTS`; names from ``engine.schema``).
    variables: tuple[tuple[str, tuple[str, ...]], ...]
    doc: str


_ENDING = ("end_r", "end_time", "end_theta")

#: Every effect, in the order of ``Scene.effects``.
EFFECTS: tuple[Effect, ...] = (
    Effect(
        name="rolling_resistance",
        bit=1,
        scene_field="c_rr",
        switch="coefficient",
        params=("c_rr",),
        forces=True,
        dissipative=True,
        events=("rest", "vertex"),
        needs=("dissipative forces",),
        variables=(("period", ("energy_loss",)),),
        doc="a couple c_rr N a opposing the rolling",
    ),
    Effect(
        name="rim",
        bit=2,
        scene_field="rim",
        switch="limit",
        params=("rim",),
        forces=False,
        dissipative=False,
        events=("spill", "vertex"),  # any orbit of small L_z enters the vertex region
        needs=("terminal events",),
        variables=(("closed form", _ENDING),),
        doc="the cone ends at slant length rim: the sphere spills over its edge",
    ),
    Effect(
        name="slip_check",
        bit=4,
        scene_field="mu",
        switch="limit",
        params=("mu",),
        forces=False,
        dissipative=False,
        events=("slip", "vertex"),
        needs=("terminal events",),
        variables=(("closed form", _ENDING), ("trajectory", ("friction_ratio",))),
        doc="rolling ends where the friction needed exceeds mu N",
    ),
    Effect(
        name="attitude",
        bit=8,
        scene_field="attitude",
        switch="flag",
        params=(),
        forces=False,
        dissipative=False,
        events=(),
        needs=("rigid-body state",),
        variables=(
            (
                "trajectory",
                ("quat_w", "quat_x", "quat_y", "quat_z", "quat_norm_error", "contact_speed"),
            ),
        ),
        doc="the sphere's orientation, a unit quaternion, integrated with the motion",
    ),
    Effect(
        name="sliding",
        bit=32,
        scene_field="mu_k",
        switch="limit",
        params=(),
        forces=False,
        dissipative=True,
        events=(),
        needs=("dissipative forces", "sliding contact"),
        variables=(
            (
                "fate",
                (
                    "slide_time",
                    "slip_episodes",
                    "fate_speed",
                    "final_energy",
                    "final_h",
                    "final_Lz",
                    "lost_effects",
                    "lost_sliding_friction",
                    "lost_spin_friction",
                    "fate_spin",
                ),
            ),
        ),  # fmt: skip
        doc="a slip is a transition: the sphere slides under kinetic friction mu_k N and may "
        "roll again (engine.story; the hybrid kernels, not the rolling ones)",
    ),
    Effect(
        name="spin_friction",
        bit=64,
        scene_field="c_spin",
        switch="coefficient",
        params=(),
        forces=False,
        dissipative=True,
        events=(),
        needs=("dissipative forces", "sliding contact"),
        variables=(),
        doc="a couple c_spin a N against the spin about the contact normal (engine.story)",
    ),
)

#: Effect name -> row.
BY_NAME: dict[str, Effect] = {e.name: e for e in EFFECTS}
#: Effect name -> bit.
EFFECT_BITS: dict[str, int] = {e.name: e.bit for e in EFFECTS}


def mask_of(names) -> int:
    """The bit mask of the effects named."""
    out = 0
    for name in names:
        out |= BY_NAME[name].bit
    return out


def mask_where(predicate) -> int:
    """The bit mask of the effects whose row satisfies ``predicate``."""
    return mask_of(e.name for e in EFFECTS if predicate(e))


def names_of(mask: int) -> tuple[str, ...]:
    """The names of the effects in ``mask``, in table order."""
    return tuple(e.name for e in EFFECTS if e.bit & mask)


def bringing(event: str) -> int:
    """The bit mask of the effects that bring the terminal event ``event``."""
    return mask_where(lambda e: event in e.events)


def needing_any(capabilities) -> int:
    """The bit mask of the effects that need any of ``capabilities``."""
    wanted = set(capabilities)
    return mask_where(lambda e: bool(wanted & set(e.needs)))


#: Every effect.
ALL_EFFECTS = mask_where(lambda e: True)
#: The effects that do work on the sphere.
DISSIPATIVE = mask_where(lambda e: e.dissipative)
#: The effects that act through forces and couples (:mod:`.forces`).
FORCE_EFFECTS = mask_where(lambda e: e.forces)
#: The effects the rolling kernels compile in (the others need the hybrid kernels).
ROLLING_EFFECTS = mask_where(lambda e: "sliding contact" not in e.needs)
#: Run option (not a scene effect): stop after ``P_THETA_MAX`` radians of azimuth (fate maps);
#: it brings the terminal event "horizon".
REVOLUTIONS = 1 << 16


def _check_table() -> None:
    seen = 0
    for e in EFFECTS:
        assert e.bit > 0 and e.bit & (e.bit - 1) == 0, f"{e.name}: bit must be a power of two"
        assert not e.bit & seen and e.bit < REVOLUTIONS, f"{e.name}: bit {e.bit} is taken"
        seen |= e.bit
        assert e.switch in SWITCHES, f"{e.name}: switch {e.switch!r} not in {SWITCHES}"
        assert set(e.needs) <= set(CAPABILITIES), f"{e.name}: unknown need in {e.needs}"
        assert not e.dissipative or "dissipative forces" in e.needs, (
            f"{e.name}: a dissipative effect needs 'dissipative forces'"
        )
        assert all(out in OUTPUTS for out, _ in e.variables), f"{e.name}: unknown output"
    assert len(BY_NAME) == len(EFFECTS), "effect names must be unique"


_check_table()
