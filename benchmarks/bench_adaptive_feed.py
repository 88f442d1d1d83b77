"""Benchmark: adaptive feed control (Ward 2021, Eq. 7) on the virtual machine, in lockstep.

The program ``examples/adaptive/pocket.ngc`` (a slot entry from outside the blank, then two
loops of 3 mm side cuts around it, with a full-width step at each corner) runs on the
in-process virtual machine, one machine step of 25 ms per twin cycle, four times:

1. *off*: ``[twin.adaptive_feed]`` disabled, the programmed feed;
2. *force*: the example's controller, holding the predicted XY force at its reference;
   and, without ``--quick``, the same with ``lookahead_mm = 0`` (the loop only reacts) and
   with ``source = "measured"`` (the machine's dynamometer instead of the twin's force);
3. *teach*: a teach-in cut (``quantity = "power"``): nothing commanded, the mean predicted
   spindle power of each program line learnt into a file;
4. *hold*: the same configuration with the file present: each line's learnt power held
   (reported: the largest error of the mean power, in closed loop, over the sections with
   at least ``LONG_SECTION`` closed-loop samples, against the learnt power).

For each: the peak and the mean of the XY force (the twin's prediction; the virtual
machine's measured force agrees with it to a few N) over the samples in contact, the mean
over the samples in closed loop, the program's machine time and the override's range. A
plot of force and override against machine time for runs 1 and 2 goes to ``--plot``.

Usage::

    python benchmarks/bench_adaptive_feed.py [--quick] [--plot FILE] [--json]

``--quick`` (CI): runs 1 and 2 only, no plot.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from cnctwin.twin import CycleState, LocalConnection, RunConfig, build_twin, load_run_config
from cnctwin.virtual import VirtualMachine

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "adaptive" / "adaptive.toml"
STEP_S = 0.025  # machine time per twin cycle, s
LONG_SECTION = 100  # closed-loop samples of a section whose held mean is reported


def with_adaptive(config: RunConfig, **changes: Any) -> RunConfig:
    """``config`` with ``[twin.adaptive_feed]`` changed."""
    adaptive = config.twin.adaptive_feed.model_copy(update=changes)
    return config.model_copy(
        update={"twin": config.twin.model_copy(update={"adaptive_feed": adaptive})}
    )


def run_lockstep(config: RunConfig, duration_s: float = 300.0) -> list[dict[str, float]]:
    """One run of the program on the in-process virtual machine; a record per cycle."""
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual, config)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    rows: list[dict[str, float]] = []

    def keep(state: CycleState) -> None:
        rows.append({**state.measured, **state.predicted, "line": float(state.line)})

    async def main() -> None:
        await conn.connect()
        try:
            twin = build_twin(config, conn, program=config.virtual.program, realtime=False)
            twin.runtime.on_cycle = keep
            await twin.runtime.run(duration_s=duration_s)
        finally:
            await conn.close()

    asyncio.run(main())
    return rows


def figures(rows: list[dict[str, float]], bounds: tuple[float, float]) -> dict[str, float]:
    """Peak and mean force (N) in contact, mean in closed loop, machine time (s), overrides."""
    force = np.array([r.get("predicted_force_xy_n", 0.0) for r in rows])
    contact = np.array([r.get("contact", 0.0) > 0.5 for r in rows])
    engaged = np.array([r.get("adaptive_feed_engaged", 0.0) > 0.5 for r in rows])
    measured = np.array(
        [math.hypot(r.get("force_x_n", 0.0), r.get("force_y_n", 0.0)) for r in rows]
    )
    override = np.array([r.get("feed_override_pct", math.nan) for r in rows])
    t = np.array([r.get("t_s", math.nan) for r in rows])
    ok = np.isfinite(override)
    return {
        "peak_force_n": float(force[contact].max()),
        "mean_force_n": float(force[contact].mean()),
        "mean_force_closed_loop_n": float(force[engaged].mean()) if engaged.any() else math.nan,
        "mean_measured_closed_loop_n": (
            float(measured[engaged].mean()) if engaged.any() else math.nan
        ),
        "machine_time_s": float(np.nanmax(t)),
        "override_min_pct": float(override[ok].min()),
        "override_max_pct": float(override[ok].max()),
        "override_outside_bounds": int(
            np.sum((override[ok] < bounds[0] - 1e-6) | (override[ok] > bounds[1] + 1e-6))
        ),
    }


def plot(
    off: list[dict[str, float]], on: list[dict[str, float]], reference: float, path: Path
) -> None:
    """Force and feed override against machine time, without and with the controller."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_f, ax_o) = plt.subplots(2, 1, figsize=(9, 5.5), sharex=True)
    for rows, label, colour in ((off, "programmed feed", "0.6"), (on, "adaptive feed", "C0")):
        t = [r.get("t_s", math.nan) for r in rows]
        ax_f.plot(t, [r.get("predicted_force_xy_n", 0.0) for r in rows], colour, lw=1, label=label)
        ax_o.plot(t, [r.get("feed_override_pct", math.nan) for r in rows], colour, lw=1)
    ax_f.axhline(reference, color="C3", ls="--", lw=1, label=f"reference {reference:g} N")
    ax_f.set_ylabel("XY force, N")
    ax_f.legend(loc="upper right", fontsize=8)
    ax_o.set_ylabel("feed override, %")
    ax_o.set_xlabel("machine time, s")
    ax_f.set_title("examples/adaptive/pocket.ngc on the virtual machine (lockstep)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    """Run the benchmark and print its figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="runs 1 and 2 only, no plot")
    parser.add_argument("--plot", type=Path, help="write the force/override plot here (PNG)")
    parser.add_argument("--json", action="store_true", help="print JSON")
    args = parser.parse_args()
    config = load_run_config(EXAMPLE)
    feed = config.control.feed_override
    bounds = (feed.min_pct, feed.max_pct)
    results: dict[str, dict[str, float]] = {}
    started = time.perf_counter()
    off = run_lockstep(with_adaptive(config, enabled=False))
    on = run_lockstep(config)
    results["off"], results["force"] = figures(off, bounds), figures(on, bounds)
    if not args.quick:
        results["no_lookahead"] = figures(
            run_lockstep(with_adaptive(config, lookahead_mm=0.0)), bounds
        )
        results["measured"] = figures(
            run_lockstep(with_adaptive(config, source="measured")), bounds
        )
        with tempfile.TemporaryDirectory() as folder:
            teach = with_adaptive(
                config, quantity="power", reference=None, teach_file=Path(folder) / "teach.json"
            )
            results["teach"] = figures(run_lockstep(teach), bounds)
            held = run_lockstep(teach)
            results["hold"] = figures(held, bounds)
            learnt = json.loads((Path(folder) / "teach.json").read_text())["sections"]
            power = {int(k): v for k, v in learnt.items()}
            errors = []
            for line, reference in power.items():
                values = [
                    r["predicted_power_w"]
                    for r in held
                    if int(r["line"]) == line and r.get("adaptive_feed_engaged", 0.0) > 0.5
                ]
                if len(values) >= LONG_SECTION:
                    errors.append(100.0 * (float(np.mean(values)) / reference - 1.0))
            results["hold"]["sections"] = len(power)
            results["hold"]["long_sections"] = len(errors)
            results["hold"]["long_section_power_error_pct_max"] = float(np.max(np.abs(errors)))
        if args.plot is not None:
            plot(off, on, float(config.twin.adaptive_feed.reference or 0.0), args.plot)
    wall = time.perf_counter() - started
    reference = float(config.twin.adaptive_feed.reference or math.nan)
    summary = {
        "reference_n": reference,
        "peak_reduction_pct": 100.0
        * (1.0 - results["force"]["peak_force_n"] / results["off"]["peak_force_n"]),
        "closed_loop_mean_error_pct": 100.0
        * (results["force"]["mean_force_closed_loop_n"] / reference - 1.0),
        "cycle_time_change_pct": 100.0
        * (results["force"]["machine_time_s"] / results["off"]["machine_time_s"] - 1.0),
        "wall_s": wall,
    }
    if args.json:
        print(json.dumps({"runs": results, "summary": summary}, indent=2))
        return
    for name, row in results.items():
        print(name, " ".join(f"{k}={v:.4g}" for k, v in row.items()))
    print("summary", " ".join(f"{k}={v:.4g}" for k, v in summary.items()))


if __name__ == "__main__":
    main()
