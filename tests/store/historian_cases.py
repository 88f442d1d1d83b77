"""What the historian tests record, and the exact comparison of what comes back (shared by
the SQLite and PostgreSQL tests)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cnctwin.store import DecisionRecord, EventRecord, Historian

__all__ = ["Recorded", "assert_bits_equal", "check_roundtrip", "record_everything"]

#: Values a float64 historian must keep bit for bit.
AWKWARD = [
    np.nan,
    np.inf,
    -np.inf,
    -0.0,
    5e-324,
    1.7976931348623157e308,
    0.1 + 0.2,
    1 / 3,
    -123456.789e-200,
]


@dataclass
class Recorded:
    """What went in: per kind, the times and a list of {name: value} per instant."""

    run_id: int
    times: dict[bool, list[float]] = field(default_factory=lambda: {False: [], True: []})
    frames: dict[bool, list[dict[str, float]]] = field(
        default_factory=lambda: {False: [], True: []}
    )
    events: list[EventRecord] = field(default_factory=list)
    decisions: list[DecisionRecord] = field(default_factory=list)

    def columns(self, predicted: bool) -> dict[str, np.ndarray]:
        """The expected columns: time, then each signal in first-seen order, NaN if absent."""
        names: dict[str, None] = {}
        for frame in self.frames[predicted]:
            names.update(dict.fromkeys(frame))
        out = {"time_s": np.array(self.times[predicted])}
        for name in names:
            out[name] = np.array([f.get(name, np.nan) for f in self.frames[predicted]])
        return out


def record_everything(h: Historian, n: int = 600, seed: int = 7) -> Recorded:
    """Record a run with two signal layouts, predictions, events and decisions."""
    rng = np.random.default_rng(seed)
    run = h.start_run({"program": "pocket.nc", "endpoint": "opc.tcp://127.0.0.1:4840"})
    rec = Recorded(run)
    full = ["x_mm", "y_mm", "spindle_rpm", "force_x_n", "run_state"]
    seq = -1  # the historian numbers every record; we follow its counter
    for i in range(n):
        t = i * 0.0125
        names = full if (i // 200) != 1 else ["force_x_n", "x_mm", "spindle_power_w"]
        values = {name: float(rng.normal() * 10.0 ** rng.integers(-5, 5)) for name in names}
        values[names[i % len(names)]] = AWKWARD[i % len(AWKWARD)]
        h.record_samples(run, t, values)
        seq += 1
        rec.times[False].append(t)
        rec.frames[False].append(values)
        if i % 5 == 0:
            predicted = {"force_x_n": float(rng.normal()), "form_error_um": float(i)}
            h.record_prediction(run, t, predicted)
            seq += 1
            rec.times[True].append(t)
            rec.frames[True].append(predicted)
        if i % 97 == 0:
            data = {"cycle": i, "force_n": [1.5, -2.25], "note": "ünïcode"}
            h.record_event(run, t, "anomaly", f"force out of band at {i}", data)
            seq += 1
            rec.events.append(EventRecord(seq, t, "anomaly", f"force out of band at {i}", data))
        if i % 131 == 0:
            readback = None if i == 0 else 50.0 + i
            h.record_decision(
                run, t, "form_error", "feed_override_pct", 50.0 + i, "err > 40 um", i > 0, readback
            )
            seq += 1
            rec.decisions.append(
                DecisionRecord(
                    seq, t, "form_error", "feed_override_pct", 50.0 + i, "err > 40 um", i > 0,
                    readback,
                )
            )  # fmt: skip
    return rec


def assert_bits_equal(got: np.ndarray, want: np.ndarray, what: str) -> None:
    """Equal bit for bit (NaN, -0.0 and all)."""
    assert got.dtype == np.float64 and got.shape == want.shape, what
    assert np.array_equal(got.view(np.int64), want.astype(np.float64).view(np.int64)), what


def check_roundtrip(h: Historian, rec: Recorded) -> None:
    """What went in comes out, exactly."""
    h.flush()
    detail = h.run(rec.run_id)
    for predicted in (False, True):
        want = rec.columns(predicted)
        got = h.samples(rec.run_id, predicted=predicted)
        assert list(got) == list(want)
        for name in want:
            assert_bits_equal(got[name], want[name], name)
        assert (detail.predicted if predicted else detail.signals) == tuple(want)[1:]
    assert detail.events == rec.events
    assert detail.decisions == rec.decisions
    s = detail.summary
    assert s.frames == len(rec.frames[False])
    assert s.values == sum(len(f) for f in rec.frames[False])
    assert s.predicted_values == sum(len(f) for f in rec.frames[True])
    assert (s.events, s.decisions) == (len(rec.events), len(rec.decisions))
    assert s.last_t_s == rec.times[False][-1]
    assert s.meta == {"program": "pocket.nc", "endpoint": "opc.tcp://127.0.0.1:4840"}
