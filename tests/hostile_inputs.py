"""Hostile inputs for the property tests: NC programs and machining configurations.

Shared by the tests of the interpreter and the configuration loader (tests/nc, tests/config)
and of the commands that read them (tests/cli): the values a careless or hostile user, or a
corrupted file, would write. :data:`FUZZ` is the Hypothesis profile of these tests:
derandomized for reproducible CI, no deadline (the work per example is bounded by the
program's and configuration's own limits, not by wall-clock time).
"""

from __future__ import annotations

import copy
import json
import math
from typing import Any

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

FUZZ = settings(
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)

# --- NC programs ------------------------------------------------------------------------------

#: Segments and lines read again allowed per hostile program: the work cap of an example.
WORK_CAP = 2000

EXTREME_NUMBER = st.sampled_from(
    [
        "9" * 400,
        "1" * 65,
        "1" * 64,
        "0." + "0" * 70 + "1",
        "1e308",
        "1e-308",
        "nan",
        "inf",
        "-inf",
        "-0",
        "1000001",
        "999999.9999",
        "[10**400]",
        "[10**300*10**300]",
        "exp[1000]",
        "[1/0]",
        "[0 mod 0]",
        "[sqrt[-1]]",
        "[2**1024]",
        "[-8**0.5]",
        "[1e3]",
        "#<undefined>",
        "#99999",
        "[" * 120 + "1" + "]" * 120,
    ]
)
NUMBER = st.one_of(
    st.integers(-(10**12), 10**12).map(str),
    st.floats(allow_nan=False, allow_infinity=False).map(lambda v: f"{v:.6f}"),
    st.floats(-1e4, 1e4).map(lambda v: f"{v:.3f}"),
    st.floats(-100, 100).map(lambda v: f"{v:.3f}"),
    st.integers(0, 100).map(str),
    EXTREME_NUMBER,
)
LETTER = st.sampled_from(list("GMXYZABCIJKRFSPQLTHDNUWE@^XYZXYZ"))
WORD = st.tuples(LETTER, NUMBER).map("".join)
JUNK = st.text(alphabet=st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=12)
STATEMENT = st.sampled_from(
    [
        "G21 G90 F100 S1000 M3",
        "G20",
        "G91",
        "G83 X0 Y0 Z-50 R1 Q0.001",
        "G81 X1 Z-1 R1 L9999",
        "G73 Z-1000000 R0 Q1",
        "o1 while [1]",
        "o1 endwhile",
        "o2 repeat [99999]",
        "o2 endrepeat",
        "o3 sub",
        "o3 call",
        "o3 endsub",
        "G5.1 X1000000 I-1000000 J1000000",
        "G2 X1 Y1 R0.5 P999999",
        "G93 G1 X0.000001 F999999999",
        "#1=[#1+1]",
        "(MSG, \u00e9\u4e2d)",
        "",
        "%",
    ]
)
SANE = st.floats(-100, 100).map(lambda v: f"{v:.3f}")
VALID_MOVE = st.tuples(
    st.sampled_from(["G0", "G1", ""]),
    st.lists(st.sampled_from("XYZ"), min_size=1, max_size=3, unique=True),
    st.lists(SANE, min_size=3, max_size=3),
).map(lambda t: " ".join([t[0]] + [f"{a}{v}" for a, v in zip(t[1], t[2], strict=False)]))
BIG = st.sampled_from(
    ["1000001", "99999999", "123456789012", "1" + "0" * 40, "-" + "9" * 30, "[10**20]"]
)
EXTREME_MOVE = st.tuples(
    st.sampled_from(["G0", "G1", "G91 G0", "G20 G1", "G0 G93 F1 G1"]),
    st.sampled_from(list("XYZABC")),
    st.one_of(BIG, EXTREME_NUMBER),
).map(lambda t: f"{t[0]} {t[1]}{t[2]}")
HOSTILE_LINE = st.one_of(
    EXTREME_MOVE,
    EXTREME_MOVE,
    st.lists(WORD, min_size=1, max_size=5).map(" ".join),
    st.tuples(st.sampled_from(["G0", "G1", "G2", "G3"]), WORD, WORD).map(" ".join),
    STATEMENT,
    STATEMENT,
    JUNK,
    st.tuples(STATEMENT, JUNK).map("".join),
)
HEADER = "G21 G90 G17 G0 F100 S1000 M3"


def hostile_program(
    header: bool, valid: list[str], hostile: list[tuple[int, str]], eol: str
) -> str:
    """Valid moves with a few hostile lines inserted, joined by ``eol``."""
    lines = list(valid)
    for at, line in hostile:
        lines.insert(at % (len(lines) + 1), line)
    return eol.join(([HEADER] if header else []) + lines)


PROGRAMS = st.builds(
    hostile_program,
    st.sampled_from([True, True, True, False]),
    st.lists(VALID_MOVE, min_size=1, max_size=10),
    st.lists(st.tuples(st.integers(0, 10), HOSTILE_LINE), min_size=0, max_size=3),
    st.sampled_from(["\n", "\r", "\r\n"]),
)
LINES = st.one_of(VALID_MOVE, HOSTILE_LINE)


# --- machining configurations -----------------------------------------------------------------

BASE: dict[str, Any] = {
    "machine": {
        "rapid_mm_min": 6000.0,
        "max_spindle_rpm": 12000.0,
        "axes": {"x": {"max_velocity_mm_min": 8000.0}, "z": {"max_accel_mm_s2": 1000.0}},
        "work_offsets": {"g54": [0.0, 0.0, 0.0]},
        "spindle": {"rated_power_kw": 15.0},
    },
    "tools": [
        {
            "number": 1,
            "kind": "flat",
            "diameter_mm": 6.0,
            "flute_length_mm": 15.0,
            "flutes": 2,
            "helix_deg": 30.0,
            "length_mm": 0.0,
        }
    ],
    "stock": {"min_mm": [0.0, 0.0, -5.0], "max_mm": [20.0, 10.0, 0.0]},
    "material": {"name": "AA6060-T6", "density_kg_m3": 2700.0},
    "simulation": {"density_per_mm": 2.0, "cycle_ms": 12.5},
}

#: The keys the fuzzer replaces: table path and key.
KEYS: list[tuple[Any, ...]] = [
    ("machine", "rapid_mm_min"),
    ("machine", "max_spindle_rpm"),
    ("machine", "axes", "x", "max_velocity_mm_min"),
    ("machine", "axes", "z", "max_accel_mm_s2"),
    ("machine", "work_offsets", "g54"),
    ("machine", "spindle", "rated_power_kw"),
    ("tools", 0, "number"),
    ("tools", 0, "diameter_mm"),
    ("tools", 0, "flute_length_mm"),
    ("tools", 0, "flutes"),
    ("tools", 0, "helix_deg"),
    ("tools", 0, "length_mm"),
    ("stock", "min_mm"),
    ("stock", "max_mm"),
    ("material", "density_kg_m3"),
    ("simulation", "density_per_mm"),
    ("simulation", "cycle_ms"),
]

CONFIG_PROGRAM = """G21 G90 G94 G17
T1 M6
S8000 M3
G0 X-5 Y5 Z2
G1 Z-1 F300
G1 X25 F900
G0 Z5
M30
"""

EXTREMES = [
    math.nan,
    math.inf,
    -math.inf,
    1e308,
    -1e308,
    1e-308,
    -0.0,
    0,
    -1,
    10**30,
    -(10**30),
    2**63,
    1e9,
    1e6,
    # the largest valid coordinate and density, and a long flute: valid, but their product
    # must hit the work limit
    1e5,
    -1e5,
    100.0,
    0.1,
    2000.0,
    "x",
    True,
    [1.0],
]
SCALAR = st.one_of(
    st.sampled_from(EXTREMES),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**20), max_value=10**20),
)
VALUE = st.one_of(SCALAR, st.lists(SCALAR, min_size=3, max_size=3))
MUTATIONS = st.lists(st.tuples(st.sampled_from(KEYS), VALUE), min_size=1, max_size=3)


def toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        # repr gives nan, inf, -inf, 1e+308, -0.0: all valid TOML floats.
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    return "[" + ", ".join(toml_value(v) for v in value) + "]"


def toml(data: dict[str, Any], prefix: str = "") -> str:
    """TOML text of nested tables of scalars and arrays (``tools`` as ``[[tools]]``)."""
    lines = [f"{k} = {toml_value(v)}" for k, v in data.items() if not isinstance(v, dict | list)]
    lines += [f"{k} = {toml_value(v)}" for k, v in data.items() if isinstance(v, list)
              and not (v and isinstance(v[0], dict))]  # fmt: skip
    text = "\n".join(lines) + "\n"
    for key, value in data.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            text += f"\n[{name}]\n" + toml(value, f"{name}.")
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            for item in value:
                text += f"\n[[{name}]]\n" + toml(item, f"{name}.")
    return text


def mutated(mutations: list[tuple[tuple[Any, ...], Any]]) -> dict[str, Any]:
    data = copy.deepcopy(BASE)
    for path, value in mutations:
        table: Any = data
        for part in path[:-1]:
            table = table[part]
        table[path[-1]] = value
    return data
