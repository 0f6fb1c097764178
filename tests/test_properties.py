"""Property-based tests (hypothesis): the survey parser over its whole valid and invalid
domain, the CLI's handling of bad definitions, and the exact kernels over the whole physical
domain against the class table of the README."""

from __future__ import annotations

import copy
import datetime as dt
import math
import re
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings, target
from hypothesis import strategies as st

import engine
from engine.api import METHODS
from engine.cli import main as cli_main
from engine.kernels.physics import BOUNDED, CIRCULAR, FORBIDDEN, HYPERBOLIC, RADIAL, SPILLS
from engine.surveyfile import AXES, SurveyError, parse_survey

PI_2 = math.pi / 2
BELOW_PI_2 = math.nextafter(PI_2, 0.0)
EPS = 2.220446049250313e-16
FLOAT_NAMES = (
    "r_min",
    "r_max",
    "r_circ",
    "period",
    "apsidal_angle",
    "precession_rate",
    "mu_required",
)

# --- a TOML writer ----------------------------------------------------------------------------

_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


def toml_string(s: str) -> str:
    """A TOML basic string; control characters (all must be escaped but tab) as \\uXXXX."""
    out = []
    for ch in s:
        o = ord(ch)
        if ch in '"\\':
            out.append("\\" + ch)
        elif (o < 0x20 and ch != "\t") or o == 0x7F:
            out.append(f"\\u{o:04X}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


def toml_key(k: str) -> str:
    return k if _BARE_KEY.fullmatch(k) else toml_string(k)


def toml_value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return toml_string(v)
    if isinstance(v, dt.date | dt.time):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


def to_toml(doc: dict, prefix: str = "") -> str:
    """Scalars and arrays of a table first, then its sub-tables as [headers]."""
    lines = [f"{toml_key(k)} = {toml_value(v)}" for k, v in doc.items() if not isinstance(v, dict)]
    for k, v in doc.items():
        if isinstance(v, dict):
            name = f"{prefix}{toml_key(k)}"
            lines.append(f"\n[{name}]")
            lines.append(to_toml(v, name + "."))
    return "\n".join(lines) + "\n"


def shown(v: object) -> str:
    """How an offending value must appear in an error message (TOML spelling)."""
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, list):
        return "[" + ", ".join(shown(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {shown(x)}" for k, x in v.items()) + "}"
    return toml_value(v)


_PATH_TOKEN = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def lookup(doc: object, key: str) -> tuple[bool, object]:
    """(found, value) of a key path such as ``axes.alpha.values[1]`` in a parsed document."""
    node = doc
    for m in _PATH_TOKEN.finditer(key):
        name, index = m.groups()
        if name is not None:
            if not isinstance(node, dict) or name not in node:
                return False, None
            node = node[name]
        else:
            i = int(index)
            if not isinstance(node, list) or i >= len(node):
                return False, None
            node = node[i]
    return True, node


def check_key_refers_to_document(err: SurveyError, doc: dict | None) -> None:
    """The error names a key path of the document ("" only for malformed TOML), or a missing
    key whose parent exists."""
    if err.key == "":
        assert "malformed TOML" in err.problem or "UTF-8" in err.problem, str(err)
        return
    assert doc is not None, str(err)
    found, _ = lookup(doc, err.key)
    if not found:
        parent = err.key.rsplit(".", 1)[0] if "." in err.key else ""
        parent_found = lookup(doc, parent)[0] if parent else True
        assert parent_found and "missing" in err.problem, str(err)


# --- strategies: valid survey documents -------------------------------------------------------

# Titles: any unicode but lone surrogates (not representable in TOML), quotes and
# backslashes and control characters included.
titles = st.text(st.characters(exclude_categories=("Cs",)), max_size=40)
# Strings inside error messages: no control characters (messages show them raw).
plain_text = st.text(st.characters(exclude_categories=("Cs", "Cc")), max_size=12)

finite = st.floats(allow_nan=False, allow_infinity=False)
positive = st.one_of(
    st.floats(min_value=0.0, exclude_min=True, allow_infinity=False),
    st.integers(1, 2**63 - 1),
)
nonneg = st.one_of(st.just(0), st.just(0.0), positive)
int64 = st.integers(-(2**63), 2**63 - 1)
numbers = st.one_of(finite, int64)
alpha_values = st.one_of(
    st.floats(0.0, PI_2, exclude_min=True, exclude_max=True),
    st.floats(0.0, 1e-6, exclude_min=True),
    st.floats(0.0, 1e-6).map(lambda d: min(PI_2 - d, BELOW_PI_2)),
    st.just(1),
)


@st.composite
def scenes(draw) -> dict:
    fields = {
        "M": positive,
        "g": st.one_of(st.just(0), st.just(0.0), positive),
        "a": positive,
        "k": st.one_of(st.sampled_from([0, 0.0, 0.4, 2 / 3]), st.floats(0.0, 5.0), nonneg),
        "rim": positive,
        "mu": positive,
        "c_rr": nonneg,
        "attitude": st.booleans(),
    }
    chosen = draw(st.lists(st.sampled_from(list(fields)), unique=True))
    return {name: draw(fields[name]) for name in chosen}


def _distinct_range(start: float, stop: float, num: int, scale: str) -> bool:
    """Enough room between start and stop for num distinct doubles (with a wide margin)."""
    if num == 1:
        return start == stop
    if scale == "log":  # subnormals are spaced too coarsely for a geometric progression
        return abs(math.log(stop) - math.log(start)) >= 1e-9 * num and min(start, stop) >= 1e-290
    span = abs(stop - start)  # may be inf for endpoints near +-DBL_MAX: fine
    return span >= 1e-9 * num * max(abs(start), abs(stop)) and span >= 1e-290


@st.composite
def axis_specs(draw, name: str) -> dict:
    elem = alpha_values if name == "alpha" else numbers
    spec: dict = {}
    if draw(st.booleans()):
        spec["values"] = draw(st.lists(elem, min_size=1, max_size=8, unique_by=float))
    else:
        scale = "linear" if name == "alpha" else draw(st.sampled_from(["linear", "log"]))
        if name == "alpha" and draw(st.booleans()):
            scale = "log"
        if name == "alpha":
            ends = alpha_values
        elif scale == "log":
            ends = positive
        else:
            ends = numbers
        num = draw(st.one_of(st.integers(1, 12), st.integers(13, 300)))
        start = draw(ends)
        stop = start if num == 1 else draw(ends)
        assume(_distinct_range(float(start), float(stop), num, scale))
        spec.update(start=start, stop=stop, num=num)
        if scale == "log" or draw(st.booleans()):
            spec["scale"] = scale
    if name == "energy" and draw(st.booleans()):
        spec["relative_to"] = "V_min"
    return spec


@st.composite
def valid_docs(draw) -> dict:
    doc: dict = {}
    if draw(st.booleans()):
        doc["title"] = draw(titles)
    if draw(st.booleans()):
        doc["method"] = draw(st.sampled_from(METHODS))
    if draw(st.booleans()):
        doc["rtol"] = draw(st.floats(0.0, 1.0, exclude_min=True, exclude_max=True))
    if draw(st.booleans()):
        doc["circular_tol"] = draw(nonneg)
    if draw(st.booleans()):
        doc["scene"] = draw(scenes())
    order = draw(st.permutations(AXES))
    doc["axes"] = {name: draw(axis_specs(name)) for name in order}
    return doc


def expected_linear(start: float, stop: float, num: int) -> np.ndarray:
    """The exactly rounded points start + i (stop - start)/(num - 1)."""
    if num == 1:
        return np.array([start])
    a, b = Fraction(start), Fraction(stop)
    return np.array([float(a + (b - a) * i / (num - 1)) for i in range(num)])


def check_axis(got: np.ndarray, spec: dict, name: str) -> None:
    assert got.dtype == np.float64 and got.ndim == 1 and not got.flags.writeable
    assert np.isfinite(got).all()
    if name == "alpha":
        assert ((got > 0.0) & (got < PI_2)).all()
    if "values" in spec:
        np.testing.assert_array_equal(got, [float(v) for v in spec["values"]])
        return
    start, stop, num = float(spec["start"]), float(spec["stop"]), spec["num"]
    assert got.size == num
    assert got[0] == start and got[-1] == stop  # exact end points
    if num > 1:  # strictly monotonic, hence distinct
        d = np.diff(got)
        assert (d > 0).all() if stop > start else (d < 0).all()
    if spec.get("scale", "linear") == "log":
        with np.errstate(over="ignore"):
            ref = np.geomspace(start, stop, num)
        np.testing.assert_allclose(got, ref, rtol=1e-13, atol=0)
    else:
        exact = expected_linear(start, stop, num)
        tol = 4 * EPS * abs(start) + 4 * EPS * abs(stop)  # no overflow near DBL_MAX
        assert np.all(np.abs(got - exact) <= tol), (got, exact)
        with np.errstate(over="ignore", invalid="ignore"):
            ref = np.linspace(start, stop, num)
        if np.isfinite(ref).all():
            np.testing.assert_allclose(got, ref, rtol=0, atol=tol)


# --- 1. parser: valid definitions -------------------------------------------------------------


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(doc=valid_docs())
def test_valid_definitions_parse_exactly(doc):
    text = to_toml(doc)
    s = parse_survey(text)
    assert s.source_text == text
    assert s.title == doc.get("title", s.title)
    assert s.method == doc.get("method", "exact")
    assert s.rtol == doc.get("rtol", 1e-10)
    assert s.circular_tol == float(doc.get("circular_tol", 1e-12))
    scene = doc.get("scene", {})
    expect = {k: (v if isinstance(v, bool) else float(v)) for k, v in scene.items()}
    assert s.scene == engine.Scene(**expect)
    assert s.scene.rim == (float(scene["rim"]) if "rim" in scene else None)
    assert s.energy_relative == ("relative_to" in doc["axes"]["energy"])
    for name in AXES:
        check_axis(getattr(s, name), doc["axes"][name], name)
    assert s.shape == tuple(getattr(s, n).size for n in AXES)


def test_wide_linear_range_has_finite_distinct_points():
    # start - stop overflows to inf; numpy.linspace then yields inf/nan interior points.
    text = to_toml(
        {
            "axes": {
                "alpha": {"values": [0.5]},
                "energy": {"start": -1e308, "stop": 1.7e308, "num": 7},
                "h": {"values": [0.0]},
                "Lz": {"values": [1.0]},
            }
        }
    )
    e = parse_survey(text).energy
    assert np.isfinite(e).all() and (np.diff(e) > 0).all()
    np.testing.assert_allclose(e, expected_linear(-1e308, 1.7e308, 7), rtol=1e-15)


# --- 2. parser: invalid definitions -----------------------------------------------------------

BASE: dict = {
    "title": "base",
    "scene": {"M": 1.0, "g": 9.81, "k": 0.4},
    "axes": {
        "alpha": {"values": [0.3, 0.6]},
        "energy": {"start": 1e-6, "stop": 10.0, "num": 4, "scale": "log", "relative_to": "V_min"},
        "h": {"values": [-1.0, 0.0, 1.0]},
        "Lz": {"start": 0.1, "stop": 1.0, "num": 3},
    },
}

bad_types_for_number = st.one_of(
    st.booleans(),
    plain_text,
    st.lists(st.floats(allow_nan=False), max_size=3),
    st.dictionaries(st.from_regex(r"\A[a-z]{1,4}\Z"), st.integers(0, 9), max_size=2),
    st.dates(),
    st.times().map(lambda t: t.replace(microsecond=0)),
)
huge_ints = st.integers(2**1024, 10**400).flatmap(lambda n: st.sampled_from([n, -n]))
nonfinite = st.sampled_from([math.nan, math.inf, -math.inf])
SCENE_BOUNDS = {  # field -> strategy of values the Scene refuses
    "M": st.one_of(st.floats(max_value=0.0, allow_infinity=False), st.integers(-99, 0)),
    "a": st.one_of(st.floats(max_value=0.0, allow_infinity=False), st.integers(-99, 0)),
    "rim": st.one_of(st.floats(max_value=0.0, allow_infinity=False), st.integers(-99, 0)),
    "mu": st.one_of(st.floats(max_value=0.0, allow_infinity=False), st.integers(-99, 0)),
    "g": st.floats(max_value=-5e-324, allow_infinity=False),
    "k": st.floats(max_value=-5e-324, allow_infinity=False),
    "c_rr": st.integers(-99, -1),
}


def number_slots(doc: dict) -> list[tuple]:
    """Paths of every place of the document where a number is expected."""
    slots: list[tuple] = [("rtol",), ("circular_tol",)]
    slots += [("scene", f) for f in ("M", "g", "a", "k", "rim", "mu", "c_rr")]
    for name, spec in doc["axes"].items():
        if "values" in spec:
            slots += [("axes", name, "values", i) for i in range(len(spec["values"]))]
        else:
            slots += [("axes", name, "start"), ("axes", name, "stop"), ("axes", name, "num")]
    return slots


def set_path(doc: dict, path: tuple, value: object) -> None:
    node = doc
    for p in path[:-1]:
        if isinstance(p, str) and p not in node:
            node[p] = {}
        node = node[p]
    node[path[-1]] = value


def key_of(path: tuple) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out


def nested(depth: int) -> str:
    return "[" * depth + "1" + "]" * depth


@st.composite
def invalid_cases(draw) -> dict:
    """A broken definition: {text, key (expected key path or None), shows (a fragment the
    message must contain, or None)}. ``key is None`` means any key of the document."""
    doc = draw(st.one_of(st.just(copy.deepcopy(BASE)), valid_docs()))
    axes = doc["axes"]
    kind = draw(
        st.sampled_from(
            [
                "unknown",
                "wrong_type",
                "not_a_table",
                "string_slot",
                "nonfinite",
                "huge_int",
                "alpha",
                "num",
                "empty",
                "log",
                "range_conflict",
                "duplicate",
                "bounds",
                "relative_to",
                "nested",
                "malformed",
            ]
        )
    )
    key: str | None = None
    shows: str | None = None
    raw: str | None = None
    if kind == "unknown":
        level = draw(st.sampled_from([(), ("scene",), ("axes",)] + [("axes", n) for n in AXES]))
        allowed = {
            (): {"title", "method", "rtol", "circular_tol", "scene", "axes"},
            ("scene",): {"M", "g", "a", "k", "rim", "mu", "c_rr", "attitude"},
            ("axes",): set(AXES),
        }.get(level, {"values", "start", "stop", "num", "scale", "relative_to"})
        if level == ("axes", "energy"):
            allowed = allowed | {"relative_to"}
        elif len(level) == 2 and level[0] == "axes":
            allowed = allowed - {"relative_to"}
        name = draw(st.from_regex(r"\A[A-Za-z_][A-Za-z0-9_-]{0,12}\Z").filter(lambda k: k))
        assume(name not in allowed)
        value = draw(st.one_of(numbers, plain_text, st.booleans(), st.just({"x": 1})))
        set_path(doc, (*level, name), value)
        key = key_of((*level, name))
    elif kind == "wrong_type":
        path = draw(st.sampled_from(number_slots(doc)))
        value = draw(bad_types_for_number)
        if path[-1] == "num":
            value = draw(st.one_of(st.just(value), st.floats(allow_nan=False)))
        set_path(doc, path, value)
        key, shows = key_of(path), shown(value)
    elif kind == "not_a_table":
        path = draw(st.sampled_from([("scene",), ("axes",)] + [("axes", n) for n in AXES]))
        if path == ("scene",) or len(path) == 2:
            value = draw(st.one_of(numbers, plain_text, st.booleans(), st.lists(numbers)))
        else:
            value = draw(st.one_of(numbers, st.booleans()))
        set_path(doc, path, value)
        key, shows = key_of(path), shown(value)
    elif kind == "string_slot":
        path = draw(
            st.sampled_from(
                [("title",), ("method",), ("axes", "energy", "relative_to"), ("scene", "attitude")]
                + [("axes", n, "values") for n in AXES]
            )
        )
        if path[-1] == "method":
            value = draw(st.one_of(plain_text.filter(lambda s: s not in METHODS), numbers))
        elif path[-1] == "relative_to":
            value = draw(st.one_of(plain_text.filter(lambda s: s != "V_min"), numbers))
        elif path[-1] == "attitude":
            value = draw(st.one_of(numbers, plain_text))
        elif path[-1] == "values":
            value = draw(st.one_of(numbers, plain_text, st.booleans()))
            axes[path[1]] = {}
        else:
            value = draw(st.one_of(numbers, st.booleans(), st.lists(st.integers(0, 9))))
        set_path(doc, path, value)
        key, shows = key_of(path), shown(value)
    elif kind in ("nonfinite", "huge_int"):
        path = draw(st.sampled_from(number_slots(doc)))
        value = draw(nonfinite if kind == "nonfinite" else huge_ints)
        set_path(doc, path, value)
        key, shows = key_of(path), shown(value)
    elif kind == "alpha":
        bad = draw(
            st.one_of(
                st.floats(max_value=0.0, allow_infinity=False),
                st.floats(min_value=PI_2, allow_infinity=False),
                st.integers(-(2**63), 0),
                st.integers(2, 2**63 - 1),
            )
        )
        spec = axes["alpha"]
        if "values" in spec:
            path = ("axes", "alpha", "values", draw(st.integers(0, len(spec["values"]) - 1)))
        else:
            path = ("axes", "alpha", draw(st.sampled_from(["start", "stop"])))
        set_path(doc, path, bad)
        key, shows = key_of(path), shown(bad)
    elif kind == "num":
        name = draw(st.sampled_from(AXES))
        bad = draw(
            st.one_of(
                st.integers(-(2**63), 0),
                st.floats(allow_nan=False, allow_infinity=False),
                st.integers(10**9, 2**63 - 1),  # far more points than any grid can hold
            )
        )
        lo, hi = (0.1, 0.2) if name == "alpha" else (1.0, 2.0)
        axes[name] = {"start": lo, "stop": hi, "num": bad}
        key, shows = f"axes.{name}.num", shown(bad)
    elif kind == "empty":
        name = draw(st.sampled_from(AXES))
        axes[name] = {"values": []}
        key = f"axes.{name}.values"
    elif kind == "log":
        name = draw(st.sampled_from(AXES[1:]))
        bad = draw(st.one_of(st.floats(max_value=0.0, allow_infinity=False), st.integers(-9, 0)))
        end = draw(st.sampled_from(["start", "stop"]))
        axes[name] = {"start": 1.0, "stop": 1.0e3, "num": 4, "scale": "log", end: bad}
        key, shows = f"axes.{name}.{end}", shown(bad)
    elif kind == "range_conflict":
        name = draw(st.sampled_from(AXES))
        x = draw(alpha_values if name == "alpha" else numbers)
        if draw(st.booleans()):
            y = draw(alpha_values if name == "alpha" else numbers)
            assume(float(x) != float(y))
            axes[name] = {"start": x, "stop": y, "num": 1}
            key, shows = f"axes.{name}.num", "1"
        else:
            axes[name] = {"start": x, "stop": x, "num": draw(st.integers(2, 50))}
            key, shows = f"axes.{name}.stop", shown(x)
    elif kind == "duplicate":
        name = draw(st.sampled_from(AXES))
        values = draw(
            st.lists(alpha_values if name == "alpha" else numbers, min_size=1, unique_by=float)
        )
        j = draw(st.integers(0, len(values)))
        dup = draw(st.sampled_from(values))
        values.insert(j, dup)
        first = [float(v) for v in values].index(float(dup))
        second = first + 1 + [float(v) for v in values[first + 1 :]].index(float(dup))
        axes[name] = {"values": values}
        key = f"axes.{name}.values[{second}]"
    elif kind == "bounds":
        which = draw(st.sampled_from(["rtol", "circular_tol", *SCENE_BOUNDS]))
        if which == "rtol":
            value = draw(
                st.one_of(
                    st.floats(max_value=0.0, allow_infinity=False),
                    st.floats(min_value=1.0, allow_infinity=False),
                    st.integers(-99, 99).filter(lambda n: n <= 0 or n >= 1),
                )
            )
            path = ("rtol",)
        elif which == "circular_tol":
            value = draw(st.floats(max_value=-5e-324, allow_infinity=False))
            path = ("circular_tol",)
        else:
            value = draw(SCENE_BOUNDS[which])
            path = ("scene", which)
        set_path(doc, path, value)
        key, shows = key_of(path), shown(value)
    elif kind == "relative_to":
        name = draw(st.sampled_from(AXES))
        value = draw(st.one_of(st.just("V_min"), plain_text))
        assume(name != "energy" or value != "V_min")
        axes[name]["relative_to"] = value
        key = f"axes.{name}.relative_to"
    elif kind == "nested":
        depth = draw(st.one_of(st.integers(1, 50), st.integers(1000, 20000)))
        raw = to_toml(doc)
        # put the nested array on a line of its own at the top (a key the doc already has or
        # not: either way it is not a number)
        raw = f"rtol = {nested(depth)}\n" + "\n".join(
            line for line in raw.splitlines() if not line.startswith("rtol =")
        )
        key = None
    else:  # malformed: truncated, spliced or random text
        text = to_toml(doc)
        how = draw(st.sampled_from(["truncate", "splice", "random", "bytes"]))
        if how == "truncate":
            raw = text[: draw(st.integers(0, len(text)))]
        elif how == "splice":
            i = draw(st.integers(0, len(text)))
            raw = text[:i] + draw(st.text(max_size=5)) + text[i:]
        elif how == "random":
            raw = draw(st.text(max_size=200))
        else:
            raw = draw(st.binary(max_size=200)).decode("utf-8", errors="replace")
        key = None
    if raw is None:
        raw = to_toml(doc)
    return {"text": raw, "key": key, "shows": shows}


def _parsed(text: str) -> dict | None:
    import tomllib

    try:
        return tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError):
        return None


def check_invalid(case: dict) -> SurveyError | None:
    """parse_survey raises SurveyError (nothing else) naming the right key and value."""
    text, key, shows = case["text"], case["key"], case["shows"]
    try:
        parse_survey(text, origin="bad.toml")
    except SurveyError as err:
        assert isinstance(err, ValueError)
        assert err.origin == "bad.toml"
        if key is not None:
            assert err.key == key, str(err)
        check_key_refers_to_document(err, _parsed(text))
        if shows is not None:
            assert shows in err.problem, (shows, str(err))
        return err
    # only a mangled (random/truncated/spliced) text may still happen to be a valid survey
    assert key is None, f"accepted an invalid definition (expected an error at {key!r})"
    return None


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=invalid_cases())
def test_invalid_definitions_raise_survey_error_naming_key_and_value(case):
    check_invalid(case)


@settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(case=invalid_cases(), raw_bytes=st.one_of(st.none(), st.binary(max_size=100)))
def test_cli_validate_exits_2_without_traceback(case, raw_bytes, tmp_path, capsys):
    path = tmp_path / "survey.toml"
    if raw_bytes is not None:  # any bytes at all, not only UTF-8
        path.write_bytes(raw_bytes)
    else:
        path.write_text(case["text"], encoding="utf-8")
        if check_invalid(case) is None:
            return  # a mangled text that is still a valid survey
    capsys.readouterr()
    try:
        status = cli_main(["validate", str(path)])
    except SystemExit as exc:  # pragma: no cover - argparse; should not happen here
        status = exc.code
    out, err = capsys.readouterr()
    if raw_bytes is not None and status == 0:
        return  # random bytes that happen to be a valid survey
    assert status == 2, (out, err)
    assert "Traceback" not in err and "Traceback" not in out
    assert err.startswith("conesurvey: error: ") and str(path) in err


# --- 3. kernels over the whole valid domain ---------------------------------------------------

# Input domain. A = Lz^2 (1 + k/(1+k) cot^2 a)/(2 M sin^2 a), B = k/(1+k) h Lz cos a/sin^2 a and
# C = M g cos a/(1+k) must neither overflow nor underflow in double precision, so:
# |h|, |Lz| in [1e-6, 1e6] or exactly 0; alpha in [1e-8, pi/2) (up to the largest double below
# pi/2, where cos a ~ 2.8e-16); M in [1e-3, 1e3]; g in {0} U [1e-3, 1e2]; k in {0} U [1e-4, 5]
# (k/(1+k) >= ~1e-4 keeps B clear of underflow). Then 1e-50 < |A|, |B|, C < 1e50 (or exactly
# 0). The energy is either absolute (0 or +-[1e-6, 1e6]) or V_min + x |V_min| with
# x in {0} U +-[1e-16, 1e3], so that bounded, circular and near-circular orbits occur at any
# scale of V_min.


def log_uniform(lo: float, hi: float) -> st.SearchStrategy[float]:
    return st.floats(lo, hi).map(lambda e: 10.0**e)


def signed(s: st.SearchStrategy[float]) -> st.SearchStrategy[float]:
    return st.tuples(st.sampled_from([1.0, -1.0]), s).map(lambda t: t[0] * t[1])


k_alpha = st.one_of(
    st.floats(0.0, PI_2, exclude_min=True, exclude_max=True).filter(lambda a: a >= 1e-8),
    log_uniform(-8, -6),  # within 1e-6 of 0
    log_uniform(-17, -6).map(lambda d: min(PI_2 - d, BELOW_PI_2)),  # within 1e-6 of pi/2
)


def weighted(*pairs: tuple[int, st.SearchStrategy]) -> st.SearchStrategy:
    """Branches drawn with the given integer weights (one_of's own choice is far from even)."""
    table = [s for w, s in pairs for _ in range(w)]
    return st.integers(0, len(table) - 1).flatmap(lambda i: table[i])


k_hl = weighted((4, signed(log_uniform(-6, 6))), (1, st.just(0.0)))
k_abs_energy = weighted((4, signed(log_uniform(-6, 6))), (1, st.just(0.0)))
k_rel_offset = weighted(
    (4, log_uniform(-16, 3)), (1, st.just(0.0)), (1, log_uniform(-16, 3).map(lambda x: -x))
)
k_M = log_uniform(-3, 3)
k_g = weighted((2, log_uniform(-3, 2)), (1, st.just(0.0)))
k_k = st.one_of(st.sampled_from([0.0, 0.4, 2 / 3]), st.floats(1e-4, 5.0))
k_rim = st.one_of(st.none(), log_uniform(-3, 6))

# --- regressions found by these properties (fixed in the kernels) ---

# 1. mu_required of a free-fall escape of a point particle (k = 0) with h != 0 was
#    k/(1+k) * inf = 0 * inf = NaN instead of 0.
K0_ESCAPE = dict(alpha=0.5, energy=1.0, h=1.0, Lz=1.0)

# 2. In a deep well (|V_min| >> the energy scale at r_max) the outer turning point found from
#    V(r) - V_min = (r - r_c)^2 G(r) carried an error ~eps |V_min| / V'(r_max) though r_max is
#    well conditioned (9 % here, the period 10 %); fixed by polishing on energy - V(r).
DEEP_WELL = dict(alpha=1.0, energy=0.0, h=-1e6, Lz=1e-6)
DEEP_WELL_SCENE = dict(M=1e3, g=1e-3, k=5.0)
DEEP_WELL_R_MAX = 2.6573322406479313  # mpmath, 50 digits: root of C r^3 + B r + A
DEEP_WELL_PERIOD = 291.07358395731396  # mpmath quadrature, 50 digits


@st.composite
def kernel_points(draw) -> tuple:
    n = draw(st.integers(1, 12))
    alpha = np.array([draw(k_alpha) for _ in range(n)])
    h = np.array([draw(k_hl) for _ in range(n)])
    Lz = np.array([draw(k_hl) for _ in range(n)])
    relative = np.array([draw(st.integers(0, 3)) < 3 for _ in range(n)])
    absolute = np.array([draw(k_abs_energy) for _ in range(n)])
    offset = np.array([draw(k_rel_offset) for _ in range(n)])
    return alpha, h, Lz, relative, absolute, offset


def _nan(x: float) -> bool:
    return math.isnan(x)


def _fin(x: float) -> bool:
    return math.isfinite(x)


def check_point(cls: int, o: dict, alpha, E, h, Lz, M, g, k, offset, vmin=None) -> float:
    """The README's class table for one point on the infinite cone. Returns the worst
    turning-point residual relative to its tolerance scale (for hypothesis.target)."""
    where = dict(alpha=alpha, energy=E, h=h, Lz=Lz, M=M, g=g, k=k, offset=offset, **o)
    assert cls in (FORBIDDEN, BOUNDED, CIRCULAR, HYPERBOLIC, RADIAL), where
    B_neg = k > 0 and h != 0 and (h < 0) != (Lz < 0)
    has_min = Lz != 0 and (g > 0 or B_neg)
    # class rules (reference README, rule order 1-4)
    if Lz == 0:
        assert cls == (RADIAL if g > 0 and E > 0 else FORBIDDEN), where
    elif offset is not None and has_min:
        if offset == 0.0:
            assert cls == CIRCULAR, where
        elif offset < -1e-11:
            assert cls == FORBIDDEN, where
        elif offset > 1e-11:
            expect = BOUNDED if g > 0 or E < 0 else HYPERBOLIC
            assert cls == expect, where
    if g > 0:
        assert cls != HYPERBOLIC, where
    # r_circ is a property of the potential
    assert _fin(o["r_circ"]) == has_min, where
    if has_min:
        assert o["r_circ"] > 0, where
    # which outputs are defined
    defined = {
        FORBIDDEN: (),
        BOUNDED: FLOAT_NAMES,
        CIRCULAR: FLOAT_NAMES,
        HYPERBOLIC: ("r_min", "apsidal_angle", "mu_required"),
        RADIAL: ("r_min", "r_max", "period", "mu_required"),
    }[cls]
    for name in FLOAT_NAMES:
        if name == "r_circ":
            continue
        x = o[name]
        if name in defined:
            if cls == HYPERBOLIC and name == "mu_required" and h != 0 and k > 0:
                assert x == math.inf, where  # spinning free-fall escape
            else:
                assert _fin(x), (name, where)
        elif cls == HYPERBOLIC and name == "r_max":
            assert x == math.inf, where
        else:
            assert _nan(x), (name, where)
    for name in ("r_min", "r_max", "apsidal_angle", "mu_required"):
        assert _nan(o[name]) or o[name] >= 0, (name, where)
    if _fin(o["period"]):
        assert o["period"] > 0, where
    if cls == CIRCULAR:
        assert o["r_min"] == o["r_max"] == o["r_circ"], where
    if cls == RADIAL:
        assert o["r_min"] == 0.0 and o["r_max"] > 0, where
    if cls in (BOUNDED, HYPERBOLIC):
        assert o["r_min"] > 0, where
    r1, rc, r2 = o["r_min"], o["r_circ"], o["r_max"]
    if _fin(r1) and _fin(rc) and _fin(r2):
        assert r1 <= rc <= r2, where
    # turning points are roots of E - V(r); V computed here independently of the kernels
    sa, ca = math.sin(alpha), math.cos(alpha)
    kk = k / (1.0 + k)
    A = Lz * Lz / (2.0 * M * sa * sa) * (1.0 + kk * (ca / sa) ** 2)
    B = kk * h * Lz * ca / (sa * sa)
    C = M * g * ca / (1.0 + k)
    worst = 0.0
    if cls in (BOUNDED, HYPERBOLIC):
        for r in (r1, r2):
            if _fin(r):
                scale = 2 * A / r**2 + abs(B) / r + C * r + abs(E)
                residual = abs(A / r**2 + B / r + C * r - E)
                worst = max(worst, residual / scale)
                tol = 1e-12 * scale
                assert residual <= tol, (r, where)
    if cls in (BOUNDED, CIRCULAR):
        prec = (2 * o["apsidal_angle"] - 2 * math.pi) / o["period"]
        assert math.isclose(o["precession_rate"], prec, rel_tol=1e-12, abs_tol=1e-300), where
    if g == 0 and cls != FORBIDDEN:  # free fall: psi = pi/Omega; an escape sweeps less
        omega = math.sqrt((sa * sa + k) / (1.0 + k))
        if cls == BOUNDED:
            assert math.isclose(o["apsidal_angle"], math.pi / omega, rel_tol=1e-13), where
        elif cls == HYPERBOLIC:
            assert 0 < o["apsidal_angle"] <= math.pi / omega * (1 + 1e-15), where
    if cls == RADIAL:
        assert math.isclose(o["r_max"], E / C, rel_tol=1e-15), where
    return worst


def _run_points(alpha, E, h, Lz, scene):
    ds = engine.evaluate(alpha, E, h, Lz, scene=scene)
    cls = ds.orbit_class.values
    f = {name: ds[name].values for name in FLOAT_NAMES}
    return cls, f


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(pts=kernel_points(), M=k_M, g=k_g, k=k_k, rim=k_rim)
def test_kernels_follow_the_class_table(pts, M, g, k, rim):
    alpha, h, Lz, relative, absolute, offset = pts
    scene = engine.Scene(M=M, g=g, k=k)
    vmin = engine.minimum_energy(alpha, h, Lz, scene=scene)
    use_rel = relative & np.isfinite(vmin)
    E = np.where(use_rel, vmin + offset * np.abs(vmin), absolute)
    assert np.isfinite(E).all()
    cls, f = _run_points(alpha, E, h, Lz, scene)
    assert cls.dtype == np.int8
    worst = 0.0
    for i in range(alpha.size):
        o = {name: float(f[name][i]) for name in FLOAT_NAMES}
        off = float(offset[i]) if use_rel[i] else None
        w = check_point(int(cls[i]), o, alpha[i], E[i], h[i], Lz[i], M, g, k, off, vmin[i])
        worst = max(worst, w)
    target(math.log10(worst + 1e-300), label="log10 relative turning-point residual")
    if rim is not None:  # the rim only relabels orbits reaching beyond it
        cls_r, f_r = _run_points(alpha, E, h, Lz, engine.Scene(M=M, g=g, k=k, rim=rim))
        for name in FLOAT_NAMES:
            np.testing.assert_array_equal(f_r[name], f[name])
        finite_cls = np.isin(cls, [BOUNDED, CIRCULAR, RADIAL])
        spills = finite_cls & (f["r_max"] > rim)
        np.testing.assert_array_equal(cls_r, np.where(spills, SPILLS, cls))


def test_regression_mu_required_point_particle_escape():
    """k = 0 (point particle) in free fall, escaping with h != 0. The friction force is
    k/(1+k) (...) = 0, so mu_required must be 0 (the README's +inf is for a *spinning* sphere,
    k > 0), not k/(1+k) * inf = NaN."""
    ds = engine.evaluate(**K0_ESCAPE, scene=engine.Scene(g=0.0, k=0.0))
    assert int(ds.orbit_class) == HYPERBOLIC
    assert float(ds.mu_required) == 0.0


def test_regression_deep_well_outer_turning_point():
    """A well-conditioned outer turning point (r_max ~ sqrt(-B/C)) in a potential whose
    minimum is 1e14 J deep (the kernel's r_max and period were ~10 % off)."""
    ds = engine.evaluate(**DEEP_WELL, scene=engine.Scene(**DEEP_WELL_SCENE))
    assert int(ds.orbit_class) == BOUNDED
    assert float(ds.r_max) == pytest.approx(DEEP_WELL_R_MAX, rel=1e-12)
    assert float(ds.period) == pytest.approx(DEEP_WELL_PERIOD, rel=1e-10)


# --- 4. invalid API inputs --------------------------------------------------------------------

GOOD = {"alpha": 0.5, "energy": 1.0, "h": 0.3, "Lz": 0.7}


@settings(max_examples=80, deadline=None)
@given(
    name=st.sampled_from(list(GOOD)),
    bad=st.one_of(nonfinite, st.floats(max_value=0.0), st.floats(min_value=PI_2)),
    n=st.integers(1, 5),
    data=st.data(),
)
def test_invalid_api_inputs_name_the_argument(name, bad, n, data):
    if name != "alpha":
        assume(not math.isfinite(bad))
    i = data.draw(st.integers(0, n - 1))
    values = {key: np.full(n, v) for key, v in GOOD.items()}
    values[name][i] = bad
    if data.draw(st.booleans()):  # scalar, broadcast against the others
        values[name] = bad
    for fn in (engine.evaluate, engine.survey):
        with pytest.raises(ValueError) as info:
            fn(**values)
        assert str(info.value).startswith(name), str(info.value)


@settings(max_examples=30, deadline=None)
@given(bad=st.one_of(nonfinite, st.floats(max_value=-5e-324)))
def test_invalid_circular_tol_is_named(bad):
    with pytest.raises(ValueError) as info:
        engine.evaluate(**GOOD, circular_tol=bad)
    assert str(info.value).startswith("circular_tol")


@settings(max_examples=20, deadline=None)
@given(bad=st.one_of(nonfinite, st.floats(max_value=0.0)))
def test_invalid_rtol_is_named_by_the_integrators(bad):
    # method="exact" never uses rtol; the integrator methods validate it
    with pytest.raises(ValueError) as info:
        engine.evaluate(**GOOD, method="rk45", rtol=bad)
    assert str(info.value).startswith("rtol")


@settings(max_examples=40, deadline=None)
@given(field=st.sampled_from(["M", "g", "a", "k", "rim", "mu", "c_rr"]), bad=nonfinite)
def test_non_finite_scene_fields_are_named(field, bad):
    with pytest.raises(ValueError) as info:
        engine.Scene(**{field: bad})
    assert str(info.value).startswith(f"Scene.{field}")
