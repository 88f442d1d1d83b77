"""Benchmark: Heide use case 1 the hybrid way, physics-only band against physics + learned band.

The virtual machine cuts ``--true-material`` while the twin assumes the configuration's
material (the demo's AA6060-T6): the twin's mechanistic force is off by the coefficients'
mismatch. ``--teach`` clean lockstep runs of the demo program (the machine's noise seeded
differently each) are recorded; a Gaussian process learns the residual, measured minus
predicted XY force, from the twin's own engagement predictions (``cnctwin.learn``, grouped by
run, its 90 % band calibrated out of fold). The twin then monitors, with the residual model as
a ``[[twin.models]]`` stage, two new clean runs and one through the demo's hole in the blank.

Per run, over the cycles where the physics band is armed (in contact, settled):

- band half-width: physics ``(force_band_high_n - force_band_low_n) / 2``; hybrid
  ``STOP_FACTOR * residual_band`` around ``predicted_force_xy_n + residual``;
- the learned 90 % band's coverage (``hybrid_band_coverage``): the share of those cycles
  whose measured force lies within ``residual_band`` of the hybrid centre;
- false stops (clean runs): cycles out of the band (the demo's stop rule fires on the first);
- the hole: machine time from the tool first reaching the hole (its tip within a radius of
  the hole's box, at the hole's depth) to the first out-of-band cycle.

:func:`study` is the whole benchmark as a function (``tests/learn/test_hybrid_band.py`` runs
it small).

Usage::

    python benchmarks/bench_hybrid_band.py [--true-material AA7075-T6] [--teach 4]
                                           [--samples 1100] [--out FILE]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import tempfile
import time
import warnings
from importlib.resources import as_file, files
from pathlib import Path
from typing import Any

import numpy as np

from cnctwin.learn import FeatureSchema, FeatureSpec, Run, build_dataset, export_onnx, train
from cnctwin.twin import LocalConnection, RunConfig, load_run_config, run_session
from cnctwin.virtual import VirtualMachine

#: Machine time per twin cycle in lockstep (the demo's speed 2 at 12.5 ms).
STEP_S = 0.025
#: The hybrid stop band in multiples of the model's calibrated 90 % half-width (1.645 sigma
#: for a Gaussian residual; 2.5 x is about 4 sigma, near the physics band's k = 5 scatter).
STOP_FACTOR = 2.5
#: Successive out-of-band samples a stop rule waits for (1: the demo's rule; 3: ``for_s`` of
#: two samples).
HOLDS = (1, 3)
#: Twin predictions the residual model reads (its features), with units.
FEATURES = {
    "predicted_force_xy_n": "N",
    "ae_mm": "mm",
    "ap_mm": "mm",
    "feed_per_tooth_mm": "mm",
}
KEEP = (*FEATURES, "measured_force_xy_n", "force_band_low_n", "force_band_high_n",
        "force_band_armed", "force_out_of_band", "contact")  # fmt: skip


def _configs(base: RunConfig, true_material: str, hole: bool, model: Path | None) -> tuple:
    assert base.virtual is not None
    virtual = base.virtual.model_copy(update={"faults": base.virtual.faults if hole else []})
    twin = base.twin.model_dump()
    twin["models"] = [] if model is None else [{"name": "residual", "path": model}]
    config = RunConfig.from_machining(
        base, connection=base.connection, virtual=virtual, historian=base.historian,
        rules=[], control={"enabled": False}, twin=twin,
    )  # fmt: skip
    material = base.material.model_copy(update={"name": true_material})
    machine = base.model_copy(update={"material": material})
    return config, machine


def run_once(
    base: RunConfig, true_material: str, *, seed: int, hole: bool, samples: int,
    model: Path | None = None,
) -> dict[str, np.ndarray]:  # fmt: skip
    """One lockstep run; the columns of every new sample."""
    config, machine = _configs(base, true_material, hole, model)
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual.model_copy(update={"seed": seed}), machine)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    rows: list[dict[str, float]] = []
    stop = asyncio.Event()

    def keep(state: Any) -> None:
        if state.new_sample and state.connected:
            p = state.predicted
            row = {k: float(p.get(k, np.nan)) for k in KEEP}
            for k in ("residual", "residual_band", "residual_ready"):
                row[k] = float(p.get(k, np.nan))
            tip = state.position_mm
            row["x"], row["y"], row["z"] = (np.nan,) * 3 if tip is None else tuple(tip)
            row["t_s"] = state.measured.get("t_s", np.nan)
            rows.append(row)
        if len(rows) >= samples:
            stop.set()

    asyncio.run(
        run_session(config, connection=conn, stop_event=stop, on_cycle=keep, realtime=False)
    )
    return {k: np.array([r[k] for r in rows]) for k in rows[0]}


def hole_entry_s(run: dict[str, np.ndarray], base: RunConfig) -> float:
    """Machine time the tool's tip first reaches the hole (within its radius), s."""
    assert base.virtual is not None
    hole = next(f for f in base.virtual.faults if f.kind == "hole")
    radius = base.tools[0].diameter_mm / 2
    lo, hi = np.array(hole.min_mm), np.array(hole.max_mm)
    inside = (
        (run["x"] >= lo[0] - radius) & (run["x"] <= hi[0] + radius)
        & (run["y"] >= lo[1] - radius) & (run["y"] <= hi[1] + radius)
        & (run["z"] <= hi[2]) & (run["z"] >= lo[2])
    )  # fmt: skip
    return float(run["t_s"][np.argmax(inside)]) if inside.any() else float("nan")


def first_held(out: np.ndarray, t: np.ndarray, hold: int) -> float | None:
    """Machine time of the first sample ending ``hold`` successive out-of-band samples, s."""
    run = np.convolve(out.astype(int), np.ones(hold, dtype=int), mode="full")[: out.size]
    hit = run >= hold
    return float(t[np.argmax(hit)]) if hit.any() else None


def judge(run: dict[str, np.ndarray]) -> dict[str, Any]:
    """Band widths, centre errors, coverage and out-of-band cycles of one monitored run."""
    armed = run["force_band_armed"] == 1.0
    hybrid_ok = armed & (run["residual_ready"] == 1.0)
    measured = run["measured_force_xy_n"]
    physics_error = np.abs(measured - run["predicted_force_xy_n"])
    physics_half = (run["force_band_high_n"] - run["force_band_low_n"]) / 2
    physics_out = armed & (run["force_out_of_band"] == 1.0)
    hybrid_center = run["predicted_force_xy_n"] + run["residual"]
    hybrid_half = STOP_FACTOR * run["residual_band"]
    hybrid_out = hybrid_ok & (np.abs(measured - hybrid_center) > hybrid_half)
    t = run["t_s"]
    return {
        "armed_cycles": int(armed.sum()),
        "physics_half_width_n": float(np.median(physics_half[armed])),
        "hybrid_half_width_n": float(np.median(hybrid_half[hybrid_ok])),
        "physics_center_error_n": float(np.median(physics_error[armed])),
        "hybrid_center_error_n": float(np.median(np.abs(measured - hybrid_center)[hybrid_ok])),
        # the learned 90 % band itself (STOP_FACTOR 1): its coverage on this run
        "hybrid_band_coverage": float(
            np.mean(np.abs(measured - hybrid_center)[hybrid_ok] <= run["residual_band"][hybrid_ok])
        ),
        "physics_out_cycles": int(physics_out.sum()),
        "hybrid_out_cycles": int(hybrid_out.sum()),
        **{
            f"{key}_first_out_s_hold{hold}": first_held(out, t, hold)
            for key, out in (("physics", physics_out), ("hybrid", hybrid_out))
            for hold in HOLDS
        },
    }  # fmt: skip


def study(
    base: RunConfig, true_material: str, *, teach: int = 4, samples: int = 1100,
    clean_seeds: tuple[int, ...] = (201, 202),
) -> dict[str, Any]:  # fmt: skip
    """Teach on ``teach`` clean runs, monitor clean runs (one per seed) and one through the
    hole; the figures of each run and the hole's detection delays (s)."""
    started = time.time()
    runs = []
    for k in range(teach):
        run = run_once(base, true_material, seed=100 + k, hole=False, samples=samples)
        in_contact = run["force_band_armed"] == 1.0
        residual = np.where(
            in_contact, run["measured_force_xy_n"] - run["predicted_force_xy_n"], np.nan
        )
        runs.append(Run(str(k), {**{n: run[n] for n in FEATURES}, "residual_n": residual}))
    spec = FeatureSpec.model_validate({"sample_period_s": base.twin.cycle_s, "signals": FEATURES})
    schema = FeatureSchema.from_spec(spec)
    result = train(build_dataset(runs, schema), "residual_n", "gpr", "run", quick=True,
                   max_gpr_points=100)  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        model = export_onnx(result, schema, Path(tmp) / "residual.onnx")
        monitored = {
            f"clean_{k + 1}": run_once(base, true_material, seed=seed, hole=False,
                                       samples=samples, model=model)
            for k, seed in enumerate(clean_seeds)
        }  # fmt: skip
        monitored["hole"] = run_once(base, true_material, seed=203, hole=True,
                                     samples=samples, model=model)  # fmt: skip
    figures = {name: judge(run) for name, run in monitored.items()}
    entry = hole_entry_s(monitored["hole"], base)
    for key in ("physics", "hybrid"):
        for hold in HOLDS:
            first = figures["hole"][f"{key}_first_out_s_hold{hold}"]
            delay = None if first is None else first - entry
            figures["hole"][f"{key}_delay_s_hold{hold}"] = delay
    return {
        "true_material": true_material,
        "twin_material": base.material.name,
        "teach_runs": teach,
        "samples_per_run": samples,
        "stop_factor": STOP_FACTOR,
        "training": {"holdout": result.report["holdout"], "band_k": result.band},
        "hole_entry_s": entry,
        "runs": figures,
        "load": " ".join(f"{x:.1f}" for x in os.getloadavg()),
        "wall_s": time.time() - started,
    }


def demo_config() -> RunConfig:
    """The demo's run configuration (the program, the blank with its hole, the twin)."""
    with as_file(files("cnctwin.examples")) as examples:
        return load_run_config(Path(examples) / "demo_twin.toml")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--true-material", default="AA7075-T6")
    parser.add_argument("--teach", type=int, default=4, help="teach-in runs (>= 4)")
    parser.add_argument("--samples", type=int, default=1100, help="samples per run")
    parser.add_argument("--out", type=Path, help="write the figures as JSON here")
    parser.add_argument(
        "--quick", action="store_true", help="CI: the same run (it takes 20-30 s; no shorter one)"
    )
    args = parser.parse_args()
    warnings.filterwarnings("ignore")  # scikit-learn's GPR bound warnings
    out = study(demo_config(), args.true_material, teach=args.teach, samples=args.samples)
    text = json.dumps(out, indent=2, default=float)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
