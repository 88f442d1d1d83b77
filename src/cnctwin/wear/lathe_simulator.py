"""The lathe measurement simulator of Bolyn 2023, section IV, and its Tests 1-6.

A tool whose wear makes the produced dimension drift linearly turns a series of parts. Each
part's true dimension is ``target + drift * i + offset + e_i`` with ``e_i ~ N(0, scatter)``
the process scatter and ``offset`` the cumulative tool-offset correction in force; a gauge of
finite resolution reports it rounded. The tool twin of :mod:`cnctwin.wear.compensation` reads
each measured deviation and applies its correction, in steps of the lathe's resolution,
before the next part. Tests with heritage first run the same test without it (the previous
tool's life, as the paper's Test 2 inherits from Test 1), retire that twin into the lathe twin,
then run the new tool.

The paper gives the parameters of Tables 2-3 but neither the random draws nor the number of
parts per test; its figures show a few tens of parts, so a test runs 30 parts by default and
every result is a distribution over seeds (docs/validation.md).

All lengths in metres, drifts in metres per part.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cnctwin.errors import ConfigError, InputError
from cnctwin.wear.compensation import (
    Heritage,
    LatheTwin,
    ManufacturingParameters,
    Observation,
    round_to_resolution,
)

__all__ = [
    "DEFAULT_PARTS",
    "TESTS",
    "LatheRun",
    "LatheScenario",
    "run_test",
    "scenario",
    "simulate",
]

#: Parts per test: not stated in the paper; its figures span a few tens of parts.
DEFAULT_PARTS = 30

_UM = 1e-6

#: Conditions of the simulated tool. The paper gives none; any fixed set works, because the
#: heritage tests only need the previous tool to have worked in the same conditions.
_CONDITIONS = ManufacturingParameters(
    material="C45",
    tool_reference="CNMG 120408",
    cutting_speed=200.0 / 60.0,
    feed_per_rev=0.2e-3,
    depth_of_cut=1.0e-3,
)


@dataclass(frozen=True, slots=True)
class LatheScenario:
    """Parameters of one simulation (Bolyn 2023, Tables 2-3).

    Attributes
    ----------
    name
        Label, e.g. ``"Test 1"``.
    drift
        Growth of the dimension per part due to wear, m per part.
    scatter
        Standard deviation of the process, m.
    lower, upper
        Tolerance limits of the dimension, m; the target is their middle.
    measuring_resolution
        Resolution of the gauge, m (0: the exact value is measured).
    lathe_resolution
        Smallest tool-offset step, m.
    heritage
        Whether the tool inherits from a previous tool run under the same conditions.
    """

    name: str
    drift: float
    scatter: float
    lower: float
    upper: float
    measuring_resolution: float
    lathe_resolution: float
    heritage: bool

    def __post_init__(self) -> None:
        for name in ("drift", "scatter", "lower", "upper"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigError(
                    f"{self.name}: {name} must be finite; got {getattr(self, name)!r}"
                )
        if self.scatter < 0:
            raise ConfigError(f"{self.name}: scatter must be >= 0 m; got {self.scatter!r}")
        if not self.upper > self.lower:
            raise ConfigError(
                f"{self.name}: upper limit {self.upper!r} m must exceed "
                f"lower limit {self.lower!r} m"
            )
        for name in ("measuring_resolution", "lathe_resolution"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"{self.name}: {name} must be >= 0 m; got {value!r}")

    @property
    def target(self) -> float:
        """Target dimension, the middle of the tolerance interval, m."""
        return 0.5 * (self.lower + self.upper)


def _interval(nominal_mm: float, plus_mm: float, minus_mm: float) -> tuple[float, float]:
    """Tolerance limits in m of a dimension written ``nominal +plus -minus`` in mm."""
    return (nominal_mm - minus_mm) * 1e-3, (nominal_mm + plus_mm) * 1e-3


_NARROW = _interval(13.43, 0.07, 0.03)  # Tables 2-3, Tests 1-4: 13.43 +0.07 -0.03 mm
_CENTRED = _interval(13.45, 0.05, 0.05)  # Table 3, Tests 5-6: 13.45 +0.05 -0.05 mm

#: Tests 1-6 of Bolyn 2023 (Table 2: Tests 1-2; Table 3: Tests 3-6). Drift 3 um/part and lathe
#: resolution 5 um throughout; scatter 1 um (Tests 1-4) or 5 um (Tests 5-6); an exact gauge
#: (Tests 1-2) or a 10 um one (Tests 3-6); heritage in the even tests. Both intervals are
#: [13.40, 13.50] mm, so the target is 13.45 mm everywhere.
TESTS: dict[int, LatheScenario] = {
    number: LatheScenario(
        name=f"Test {number}",
        drift=3 * _UM,
        scatter=(1 if number <= 4 else 5) * _UM,
        lower=(_NARROW if number <= 4 else _CENTRED)[0],
        upper=(_NARROW if number <= 4 else _CENTRED)[1],
        measuring_resolution=0.0 if number <= 2 else 10 * _UM,
        lathe_resolution=5 * _UM,
        heritage=number % 2 == 0,
    )
    for number in range(1, 7)
}


def scenario(test: int) -> LatheScenario:
    """The scenario of the paper's Test ``test`` (1-6).

    Raises
    ------
    InputError
        If there is no such test.
    """
    try:
        return TESTS[test]
    except (KeyError, TypeError):
        raise InputError(f"no lathe test {test!r}; the paper has Tests 1-6") from None


@dataclass(frozen=True, slots=True)
class LatheRun:
    """One simulated tool life, part by part (arrays indexed by part, part 1 first).

    Attributes
    ----------
    scenario
        What was simulated.
    noise
        Process scatter drawn for each part, m.
    offset
        Cumulative correction in force when each part was made, m.
    true_dimension
        Dimension produced, m.
    measured_dimension
        Dimension the gauge reported, m.
    observations
        What the tool twin concluded after each part.
    heritage
        What the tool inherited, or None.
    lathe
        The lathe twin at the end of the run, the tool still mounted as ``"tool"``.
    """

    scenario: LatheScenario
    noise: np.ndarray
    offset: np.ndarray
    true_dimension: np.ndarray
    measured_dimension: np.ndarray
    observations: tuple[Observation, ...]
    heritage: Heritage | None
    lathe: LatheTwin

    @property
    def parts(self) -> int:
        """Number of parts produced."""
        return len(self.observations)

    @property
    def deviation(self) -> np.ndarray:
        """True dimension minus target, m."""
        return self.true_dimension - self.scenario.target

    @property
    def measured_deviation(self) -> np.ndarray:
        """Measured dimension minus target, m."""
        return self.measured_dimension - self.scenario.target

    @property
    def max_abs_deviation(self) -> float:
        """Largest distance of a true dimension from the target, m."""
        return float(np.max(np.abs(self.deviation)))

    @property
    def out_of_tolerance(self) -> int:
        """Parts whose true dimension lies outside the tolerance interval (scrap)."""
        dim = self.true_dimension
        return int(np.count_nonzero((dim < self.scenario.lower) | (dim > self.scenario.upper)))

    @property
    def trusted(self) -> np.ndarray:
        """Whether the slope met the stability criterion after each part."""
        return np.array([o.trusted for o in self.observations], dtype=bool)

    @property
    def first_trusted_part(self) -> int | None:
        """The first part after which the slope met the criterion, or None."""
        hits = np.flatnonzero(self.trusted)
        return int(hits[0]) + 1 if hits.size else None

    @property
    def parts_before_trusted(self) -> int | None:
        """Parts measured when the slope became trusted for good, or None if not at the end.

        The paper's "after the 6th part produced the digital twin definitively applies the
        slope it computes" (Test 1) is 6: the slope meets the criterion after part 6 and after
        every later part.
        """
        trusted = self.trusted
        if not trusted.size or not trusted[-1]:
            return None
        failed = np.flatnonzero(~trusted)
        return int(failed[-1]) + 2 if failed.size else 1


def simulate(
    case: LatheScenario,
    rng: np.random.Generator,
    parts: int = DEFAULT_PARTS,
    lathe: LatheTwin | None = None,
) -> LatheRun:
    """Produce and measure ``parts`` parts with a new tool under the tool twin's corrections.

    Parameters
    ----------
    case
        The scenario.
    rng
        Source of the process scatter.
    parts
        Number of parts, >= 1.
    lathe
        The lathe twin, holding retired twins the new tool may inherit from (its resolution
        must be the scenario's); default a new lathe twin with none. The new tool is mounted
        as ``"tool"`` and stays mounted.

    Returns
    -------
    LatheRun
        The run part by part.

    Raises
    ------
    InputError
        If ``parts`` < 1, the lathe's resolution differs from the scenario's, or the lathe
        already has a tool ``"tool"`` mounted.
    """
    if not (isinstance(parts, int) and parts >= 1):
        raise InputError(f"parts must be an integer >= 1; got {parts!r}")
    if lathe is None:
        lathe = LatheTwin(resolution=case.lathe_resolution)
    elif lathe.resolution != case.lathe_resolution:
        raise InputError(
            f"lathe resolution {lathe.resolution!r} m differs from the scenario's "
            f"{case.lathe_resolution!r} m"
        )
    twin = lathe.mount("tool", _CONDITIONS, inherit=case.heritage)
    noise = rng.normal(0.0, case.scatter, parts) if case.scatter > 0 else np.zeros(parts)
    offset = np.empty(parts)
    true = np.empty(parts)
    measured = np.empty(parts)
    observations = []
    for k in range(parts):
        offset[k] = twin.offset
        true[k] = case.target + case.drift * (k + 1) + offset[k] + noise[k]
        measured[k] = round_to_resolution(true[k], case.measuring_resolution)
        observations.append(twin.observe(measured[k] - case.target))
    return LatheRun(
        scenario=case,
        noise=noise,
        offset=offset,
        true_dimension=true,
        measured_dimension=measured,
        observations=tuple(observations),
        heritage=twin.heritage,
        lathe=lathe,
    )


def run_test(test: int, seed: int = 0, parts: int = DEFAULT_PARTS) -> LatheRun:
    """Run the paper's Test ``test`` with a seed.

    Test ``n`` with seed ``k`` draws its scatter from ``numpy.random.default_rng([k, n])``. A
    heritage test (2, 4, 6) first runs the test before it (1, 3, 5) with the same seed and
    :data:`DEFAULT_PARTS` parts, as the previous tool's life, and retires it into the lathe
    twin: Test 2 seed 7 inherits exactly what Test 1 seed 7 learnt.

    Parameters
    ----------
    test
        1-6.
    seed
        Seed, >= 0.
    parts
        Parts made by the tool under test, >= 1.

    Returns
    -------
    LatheRun
        The run of the tool under test.

    Raises
    ------
    InputError
        For an unknown test, a negative seed or fewer than 1 part.
    """
    case = scenario(test)
    if not (isinstance(seed, int) and seed >= 0):
        raise InputError(f"seed must be an integer >= 0; got {seed!r}")
    lathe = None
    if case.heritage:
        previous = run_test(test - 1, seed)
        lathe = previous.lathe
        lathe.retire("tool")
    return simulate(case, np.random.default_rng([seed, test]), parts, lathe)
