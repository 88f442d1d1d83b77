"""The feature schema: which signals a model reads, how they are filtered and windowed.

A :class:`FeatureSpec` is the TOML form (``examples/learn/*.toml``); a :class:`FeatureSchema`
adds what the spec implies: the ordered feature names, their units, the source signals and a
SHA-256 hash of the spec's canonical JSON. The schema is stored in every model file
(:mod:`cnctwin.learn.onnx_model`), so a model is only ever fed the features it was trained on.

The filter and window settings have the fields and defaults of the twin's ``[twin.filters.X]``
and ``[[twin.windows]]`` tables, and the features are built by the same filters and windows
(:mod:`cnctwin.signals`) the twin's filter and feature stages use.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from typing import Any, Literal

from pydantic import Field, ValidationError, model_validator

from cnctwin.config import Section, describe_validation_error, load_config
from cnctwin.errors import ConfigError, DataError

__all__ = [
    "WINDOW_FEATURES",
    "FeatureSchema",
    "FeatureSpec",
    "FilterSpec",
    "InvalidWhen",
    "WindowSpec",
    "load_feature_spec",
]

#: Features a window may compute (methods of :class:`cnctwin.signals.SlidingWindow`), the
#: same list as the twin's feature stage.
WINDOW_FEATURES = ("mean", "rms", "peak_to_peak", "slope")


class FilterSpec(Section):
    """A causal filter on one signal (also the twin's ``[twin.filters.SIGNAL]``).

    Attributes
    ----------
    kind
        ``"hampel"``, ``"kalman"`` (random walk) or ``"butterworth"`` (low pass).
    window, n_sigma
        Hampel: samples in the window; threshold in scaled median absolute deviations.
    process_var, measurement_var
        Kalman: variances per sample and of the measurement, signal unit squared.
    cutoff_hz, order
        Butterworth: cut-off (Hz, below half the sample rate) and order.
    """

    kind: Literal["hampel", "kalman", "butterworth"]
    window: int = Field(default=7, ge=3, le=1001)
    n_sigma: float = Field(default=3.0, gt=0.0, le=100.0)
    process_var: float = Field(default=1.0, gt=0.0, le=1e12)
    measurement_var: float = Field(default=25.0, gt=0.0, le=1e12)
    cutoff_hz: float = Field(default=10.0, gt=0.0, le=1e5)
    order: int = Field(default=2, ge=1, le=8)


class WindowSpec(Section):
    """A sliding window of one signal and its features (also the twin's ``[[twin.windows]]``).

    Attributes
    ----------
    signal
        One of the spec's signals (its filtered value where it has a filter).
    length
        Samples in the window.
    features
        Names from :data:`WINDOW_FEATURES`.
    """

    signal: str
    length: int = Field(default=80, ge=2, le=100_000)
    features: list[Literal["mean", "rms", "peak_to_peak", "slope"]] = Field(
        default_factory=lambda: ["mean", "rms"], min_length=1
    )


class InvalidWhen(Section):
    """A sample is invalid (all its signals missing) when ``signal`` reads exactly ``equals``.

    For known glitch values of a data source (UMich: ``X1_ActualPosition`` reading 198 mm).
    """

    signal: str
    equals: float


class FeatureSpec(Section):
    """The TOML form of a feature schema.

    Attributes
    ----------
    kind
        ``"series"``: each run is a time series passed through the filters and windows, one
        row per sample (every ``stride``-th); ``"table"``: each row of the data is one
        observation and the signals are its columns (no filters or windows).
    sample_period_s
        Sample period, s (the window times where the data has no ``time_s`` column, and the
        filters' sample rate).
    signals
        Source signal name -> unit, in feature order; each is a feature (its latest value,
        filtered where a filter is given, held over a missing sample).
    filters
        Filter by signal name.
    windows
        Windowed features, named ``<signal>_<feature>``.
    categories
        Categorical signal -> its values; one 0/1 feature ``<signal>=<value>`` per value.
    invalid_when
        Glitch rules: a matching sample counts as missing and gives no row.
    stride
        Offline only: every ``stride``-th sample of a run gives a row.
    """

    kind: Literal["series", "table"] = "series"
    sample_period_s: float = Field(default=0.0125, gt=0.0, le=3600.0)
    signals: dict[str, str] = Field(default_factory=dict)
    filters: dict[str, FilterSpec] = Field(default_factory=dict)
    windows: list[WindowSpec] = Field(default_factory=list)
    categories: dict[str, list[str]] = Field(default_factory=dict)
    invalid_when: list[InvalidWhen] = Field(default_factory=list)
    stride: int = Field(default=1, ge=1, le=1_000_000)

    @model_validator(mode="after")
    def _consistent(self) -> FeatureSpec:
        if not self.signals and not self.categories:
            raise ValueError("give at least one signal or category")
        for name in self.filters:
            if name not in self.signals:
                raise ValueError(f"filters.{name}: not one of the signals ({self._names()})")
        for k, window in enumerate(self.windows):
            if window.signal not in self.signals:
                raise ValueError(
                    f"windows[{k}].signal {window.signal!r}: not one of the signals "
                    f"({self._names()})"
                )
        for name, values in self.categories.items():
            if not values or len(set(values)) != len(values):
                raise ValueError(f"categories.{name}: give distinct values")
        if self.kind == "table" and (self.filters or self.windows):
            raise ValueError("a 'table' spec has no filters or windows (rows are observations)")
        return self

    def _names(self) -> str:
        return ", ".join(self.signals)


def load_feature_spec(path: str | os.PathLike[str]) -> FeatureSpec:
    """Read a feature spec from a TOML file.

    Raises
    ------
    cnctwin.errors.ConfigError
        For a missing file, bad TOML or an invalid key (named with its path).
    """
    return load_config(path, model=FeatureSpec)


@dataclass(frozen=True)
class FeatureSchema:
    """A spec with its derived names, units, sources and hash.

    Attributes
    ----------
    spec
        The spec.
    names
        Feature names in model-input order.
    units
        Unit of each feature (``"1"`` for a category's 0/1; a slope's unit is per s).
    sources
        The signals read, sorted.
    sha256
        Hex SHA-256 of the spec's canonical JSON (in the order given: reordering the signals
        reorders the features and changes the hash).
    """

    spec: FeatureSpec
    names: tuple[str, ...]
    units: tuple[str, ...]
    sources: tuple[str, ...]
    sha256: str

    @classmethod
    def from_spec(cls, spec: FeatureSpec) -> FeatureSchema:
        """Derive the schema of ``spec``."""
        names: list[str] = []
        units: list[str] = []
        for name, unit in spec.signals.items():
            names.append(name)
            units.append(unit)
        for window in spec.windows:
            unit = spec.signals[window.signal]
            for feature in window.features:
                names.append(f"{window.signal}_{feature}")
                units.append(f"{unit}/s" if feature == "slope" else unit)
        for name, values in spec.categories.items():
            for value in values:
                names.append(f"{name}={value}")
                units.append("1")
        if len(set(names)) != len(names):
            duplicate = next(n for n in names if names.count(n) > 1)
            raise ConfigError(f"feature spec gives the feature {duplicate!r} twice")
        sources = set(spec.signals) | set(spec.categories)
        sources |= {rule.signal for rule in spec.invalid_when}
        return cls(
            spec=spec,
            names=tuple(names),
            units=tuple(units),
            sources=tuple(sorted(sources)),
            sha256=hashlib.sha256(_canonical(spec).encode()).hexdigest(),
        )

    def to_json(self) -> str:
        """The schema as JSON (what a model file stores)."""
        # not sorted: the order of the signals, windows and categories is the features' order
        return json.dumps(
            {
                "spec": self.spec.model_dump(mode="json"),
                "names": list(self.names),
                "units": list(self.units),
                "sources": list(self.sources),
                "sha256": self.sha256,
            }
        )

    @classmethod
    def from_json(cls, text: str, where: str) -> FeatureSchema:
        """Read a schema that :meth:`to_json` wrote; check its hash.

        Raises
        ------
        cnctwin.errors.DataError
            When the text is no schema or its hash does not match its spec (``where`` names
            the file in the message).
        """
        try:
            raw: dict[str, Any] = json.loads(text)
            spec = FeatureSpec.model_validate(raw["spec"])
            stored = str(raw["sha256"])
        except (ValueError, KeyError, TypeError) as err:
            detail = (
                describe_validation_error(err, FeatureSpec)
                if isinstance(err, ValidationError)
                else str(err).splitlines()[0]
            )
            raise DataError(
                f"{where}: the stored feature schema is unreadable ({detail})"
            ) from None
        schema = cls.from_spec(spec)
        if schema.sha256 != stored or list(schema.names) != raw.get("names"):
            raise DataError(
                f"{where}: the feature schema's hash {stored[:12]}... does not match its "
                f"content ({schema.sha256[:12]}...); the file was altered"
            )
        return schema

    def require_signals(self, available: set[str] | frozenset[str], where: str) -> None:
        """Refuse a source that lacks one of the schema's signals.

        Raises
        ------
        cnctwin.errors.DataError
            Naming the missing signals and ``where``.
        """
        missing = [name for name in self.sources if name not in available]
        if missing:
            raise DataError(
                f"{where} lacks the signal(s) {', '.join(missing)} the feature schema reads "
                f"(it has: {', '.join(sorted(available)) or 'none'})"
            )


def _canonical(spec: FeatureSpec) -> str:
    """The spec's JSON: fields in declaration order, tables in the order given (the order of
    the features), no spaces."""
    return json.dumps(spec.model_dump(mode="json"), separators=(",", ":"))
