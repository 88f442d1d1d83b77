"""Readers of measurement files: tap tests, tables of cuts, sampled signals, torque series.

The physics packages (:mod:`cnctwin.dynamics`, :mod:`cnctwin.quality`, :mod:`cnctwin.wear`)
take arrays and do no file I/O; these readers turn the files a shop floor or a lab produces
into their inputs. Each reader raises :class:`~cnctwin.errors.DataError` with one line naming
the file (and line) and what would be valid.

Public API::

    from cnctwin.measurements import load_tap_test, read_columns, read_signal_csv, read_torque_csv

    test = load_tap_test(Path("tap.txt"))          # FRF table, impact record or .mat
    cuts = read_columns(Path("cuts.csv"), ["ap_mm", "spindle_rpm"])
    samples, rate_hz, name = read_signal_csv(Path("vibration.csv"), None, None)
"""

from cnctwin.measurements.columns import read_columns
from cnctwin.measurements.signals import TIME_NAMES, read_signal_csv
from cnctwin.measurements.tap_test import (
    EXCITED_DB,
    IMPACT_STEP_LIMIT,
    TapTest,
    TapTestKind,
    load_tap_test,
    read_frf_mat,
    read_impact_record,
    read_table,
)
from cnctwin.measurements.torque import TORQUE_COLUMNS, read_torque_csv

__all__ = [
    "EXCITED_DB",
    "IMPACT_STEP_LIMIT",
    "TIME_NAMES",
    "TORQUE_COLUMNS",
    "TapTest",
    "TapTestKind",
    "load_tap_test",
    "read_columns",
    "read_frf_mat",
    "read_impact_record",
    "read_signal_csv",
    "read_table",
    "read_torque_csv",
]
