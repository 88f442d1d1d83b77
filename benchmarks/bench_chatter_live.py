"""Online chatter detection and avoidance on the virtual machine (docs/chatter-live.md).

``examples/chatter_live/chatter_live.toml``: a half-immersion side cut, 12 mm 4-flute end
mill with Royandi 2026's modes, AA6060-T6, 8000 rpm, 0.05 mm per tooth. The virtual machine
integrates the cut's regenerative vibration with the tool's modes and serves a tool-tip
displacement sensor at 10 kHz; the twin (``[twin.chatter]``) detects chatter in it and moves
the spindle override to the stability roadmap's nearest stable speed, the feed override
scaled with it. In lockstep (10 ms of machine time per twin cycle, as fast as the CPU goes):

1. ap 2.5 mm (unstable at 8000 rpm): detection and avoidance;
2. ap 1.0 mm (stable): any detection is a false one;
3. without ``--quick``: ap 2.5 mm with ``avoid = false`` (chatter left alone, the reference);
4. without ``--quick``: ap 2.5 mm with the roadmap's margin 1.2 instead of the example's 1.5
   (a speed nearer the lobe: the chatter that grew at 8000 rpm outlives the change).

Measured per run: the entry (the first cycle with a measured cutting force), the onset
(full engagement: the tool's axis one radius inside the stock's end face, 0.22 s later; the
cut is unstable from there on, and where it is the vibration grows), the detection
(the sensor time of the confirming window's end), the command, and stable cutting (the end of
the vibration's change over one tooth period at the new speed, r(t) - r(t - T), below
10 % of its level at the command for good; the spectral detector cannot judge the first
windows at the new speed, whose tooth-passing harmonic may sit on the old chatter
frequency), the vibration RMS before (onset to command) and after (0.5 s after the command to the
end of the steady cut), and the chatter stage's time per cycle.

Usage::

    python benchmarks/bench_chatter_live.py [--quick] [--plot FILE] [--json]

``--quick`` (CI): runs 1 and 2, no plot.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import os
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from cnctwin.twin import CycleState, LocalConnection, RunConfig, build_twin, load_run_config
from cnctwin.virtual import VirtualMachine

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "chatter_live" / "chatter_live.toml"
STEP_S = 0.01  # machine time per twin cycle, s
FORCE_ON_N = 10.0  # a measured XY force above this is the cut


def with_depth(config: RunConfig, depth_mm: float, folder: Path, **chatter: Any) -> RunConfig:
    """The example with the side cut ``depth_mm`` deep (a program written to ``folder``) and
    ``[twin.chatter]`` changed."""
    assert config.virtual is not None and config.virtual.program is not None
    text = config.virtual.program.read_text(encoding="utf-8").replace("Z-2.5", f"Z-{depth_mm:g}")
    program = folder / f"side_cut_{depth_mm:g}.ngc"
    program.write_text(text, encoding="utf-8")
    virtual = config.virtual.model_copy(update={"program": program})
    twin = config.twin.model_copy(
        update={"chatter": config.twin.chatter.model_copy(update=chatter)}
    )
    return config.model_copy(update={"virtual": virtual, "twin": twin})


def run_lockstep(config: RunConfig) -> dict[str, Any]:
    """One run of the program on the in-process virtual machine: rows, events, samples."""
    assert config.virtual is not None
    vm = VirtualMachine(config.virtual, config)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    rows: list[dict[str, float]] = []
    events: list[dict[str, Any]] = []
    decisions: list[dict[str, Any]] = []
    blocks: list[np.ndarray] = []
    taken = [0]

    def keep(state: CycleState) -> None:
        rows.append({**state.measured, **state.predicted, "line": float(state.line)})
        events.extend({"kind": e.kind, "message": e.message, **e.data} for e in state.events)
        decisions.extend(
            {"t_s": state.measured.get("t_s", math.nan), "target": r.verdict.command,
             "value": r.verdict.value, "outcome": r.verdict.outcome,
             "reason": r.verdict.decision.reason} for r in state.decisions
        )  # fmt: skip
        block = vm.block("vibration", taken[0])
        blocks.append(block.samples)
        taken[0] = block.end_index

    wall = time.perf_counter()
    timings: dict[str, Any] = {}

    async def main() -> None:
        await conn.connect()
        try:
            twin = build_twin(config, conn, program=config.virtual.program, realtime=False)
            twin.runtime.on_cycle = keep
            await twin.runtime.run(duration_s=60.0)
            timings.update(twin.runtime.timings["chatter"].summary())
        finally:
            await conn.close()

    asyncio.run(main())
    samples = np.vstack(blocks)
    return {
        "rows": rows,
        "events": events,
        "decisions": decisions,
        "samples": samples,
        "rate_hz": config.virtual.vibration.sample_rate_hz,
        "wall_s": time.perf_counter() - wall,
        "stage_ms": timings,
    }


def figures(run: dict[str, Any], config: RunConfig) -> dict[str, Any]:
    """Onset, detection, command and stable times (machine s) and the RMS before and after."""
    rows, rate = run["rows"], run["rate_hz"]
    t = np.array([r.get("t_s", math.nan) for r in rows])
    force = np.array([math.hypot(r.get("force_x_n", 0.0), r.get("force_y_n", 0.0)) for r in rows])
    cutting = np.flatnonzero(force > FORCE_ON_N)
    entry = float(t[cutting[0]]) if cutting.size else math.nan
    cut_end = float(t[cutting[-1]]) if cutting.size else math.nan
    # full engagement: the tool's axis at the stock's end face (X min): the steady arc of
    # contact lies in the quadrant ahead of the axis, all in the material from there on
    full_x = config.stock.min_mm[0]
    x = np.array([r.get("x_mm", math.nan) for r in rows])
    inside = np.flatnonzero((x >= full_x) & (force > FORCE_ON_N))
    onset = float(t[inside[0]]) if inside.size else math.nan
    # the exit begins where the tool's front reaches the far face (X max)
    exit_x = config.stock.max_mm[0] - 0.5 * config.tools[0].diameter_mm
    leaving = np.flatnonzero((x >= exit_x) & (force > FORCE_ON_N))
    steady_end = float(t[leaving[0]]) if leaving.size else cut_end
    found = [e for e in run["events"] if e["kind"] == "chatter"]
    detected = float(found[0]["window_end_s"]) if found else math.nan
    sent = [d for d in run["decisions"] if d["target"] == "spindle_override_pct"]
    command = float(sent[0]["t_s"]) if sent else math.nan
    out: dict[str, Any] = {
        "entry_s": entry,
        "onset_s": onset,
        "cut_end_s": cut_end,
        "steady_end_s": steady_end,
        "detections": len(found),
        "detected_s": detected,
        "detection_latency_s": detected - onset,
        "detection_after_entry_s": detected - entry,
        "command_s": command,
        "spindle_override_pct": float(sent[0]["value"]) if sent else math.nan,
        "feed_override_pct": next(
            (float(d["value"]) for d in run["decisions"] if d["target"] == "feed_override_pct"),
            math.nan,
        ),
        "roadmap_rpm": next(
            (
                r["chatter_stable_rpm"]
                for r in rows
                if "chatter_stable_rpm" in r and math.isfinite(r["chatter_stable_rpm"])
            ),
            math.nan,
        ),  # fmt: skip
        "stage_ms_p50": run["stage_ms"].get("p50_ms", math.nan),
        "stage_ms_p99": run["stage_ms"].get("p99_ms", math.nan),
        "wall_s": run["wall_s"],
    }
    samples = run["samples"]
    times = np.arange(samples.shape[0]) / rate
    teeth = config.tools[0].flutes
    c = config.twin.chatter
    rpm_end = next(
        (r["spindle_rpm"] for r in reversed(rows) if t_between(r, onset, cut_end)), math.nan
    )
    out["final_rpm"] = rpm_end
    if math.isfinite(command):
        # Stable cutting: the vibration's change over one tooth period at the new speed,
        # r(t) - r(t - T) (what a stable cut's periodic motion does not have; the growth
        # measure of cnctwin.dynamics.time_domain), RMS per 10 ms, has fallen below 10 % of
        # its level at the command and stays there to the end of the cut.
        period = 60.0 / (teeth * rpm_end)
        diff = samples - np.column_stack(
            [np.interp(times - period, times, samples[:, k]) for k in (0, 1)]
        )
        edges = np.arange(command, steady_end - 0.01, 0.01)
        level = np.array([
            float(np.sqrt(np.mean(diff[(times >= a) & (times < a + 0.01)] ** 2)))
            for a in edges
        ])  # fmt: skip
        high = np.flatnonzero(level > 0.1 * level[0])
        stable_from = float(edges[high[-1]] + 0.01) if high.size else command
        out["stable_s"] = stable_from
        out["onset_to_stable_s"] = stable_from - onset
        out["command_to_stable_s"] = stable_from - command
        twin_low = [r["t_s"] for r in rows if r.get("t_s", 0.0) > command
                    and r.get("chatter_ratio", 1.0) < c.threshold]  # fmt: skip
        out["twin_ratio_below_threshold_s"] = float(twin_low[0]) if twin_low else math.nan
        late = (times >= command + 0.5) & (times <= steady_end)
        out["rms_after_um"] = float(np.std(samples[late], axis=0).max())
    if math.isfinite(onset):
        before_end = command if math.isfinite(command) else cut_end
        early = (times >= onset) & (times <= min(before_end, steady_end))
        out["rms_before_um"] = float(np.std(samples[early], axis=0).max())
    return out


def t_between(row: dict[str, float], low: float, high: float) -> bool:
    """Whether the row's machine time lies in ``[low, high]`` (s)."""
    return low <= row.get("t_s", math.nan) <= high


def plot(path: Path, runs: dict[str, dict[str, Any]], found: dict[str, dict[str, Any]]) -> None:
    """Displacement, spindle speed and overrides, energy ratio of the avoided run and the
    stable one."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(10, 9), sharex=True)
    for name, colour in (("no_avoid", "C3"), ("avoid", "C0"), ("stable", "C2")):
        if name not in runs:
            continue
        run = runs[name]
        samples = run["samples"]
        times = np.arange(samples.shape[0]) / run["rate_hz"]
        axes[0].plot(times, samples[:, 1] - np.median(samples[:, 1]), colour, lw=0.4,
                     label=name.replace("_", " "))  # fmt: skip
        rows = run["rows"]
        t = [r.get("t_s", math.nan) for r in rows]
        axes[1].plot(t, [r.get("spindle_rpm", math.nan) for r in rows], colour, label=name)
        axes[2].plot(t, [r.get("chatter_ratio", math.nan) for r in rows], colour, label=name)
    f = found["avoid"]
    for ax in axes:
        for key, style in (("onset_s", "k:"), ("detected_s", "r--"), ("stable_s", "g--")):
            if math.isfinite(f.get(key, math.nan)):
                ax.axvline(f[key], color=style[0], ls=style[1:], lw=1)
    axes[0].set_ylabel("tool-tip y, um (median removed)")
    axes[0].legend(loc="upper right")
    axes[0].set_title(
        f"chatter at onset {f['onset_s']:.2f} s, detected {f['detected_s']:.3f} s "
        f"(+{1e3 * f['detection_latency_s']:.0f} ms), "
        f"stable from {f.get('stable_s', math.nan):.3f} s"
    )
    axes[1].set_ylabel("spindle, rpm")
    axes[1].axhline(f["roadmap_rpm"], color="g", lw=0.8, ls=":")
    axes[2].set_ylabel("energy ratio off harmonics")
    axes[2].axhline(0.2, color="k", lw=0.8, ls=":")
    axes[2].set_xlabel("machine time, s")
    lo, hi = f["entry_s"] - 0.1, f["cut_end_s"] + 0.1
    axes[2].set_xlim(lo, hi)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    """Run, print the figures, optionally plot."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="runs 1 and 2 only, no plot")
    parser.add_argument("--plot", type=Path, help="write the figure to this PNG")
    parser.add_argument("--json", action="store_true", help="one JSON object")
    args = parser.parse_args()
    base = load_run_config(EXAMPLE)
    started = time.perf_counter()
    runs: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory() as folder:
        where = Path(folder)
        runs["avoid"] = run_lockstep(with_depth(base, 2.5, where))
        runs["stable"] = run_lockstep(with_depth(base, 1.0, where))
        if not args.quick:
            runs["no_avoid"] = run_lockstep(with_depth(base, 2.5, where, avoid=False))
            runs["margin_1.2"] = run_lockstep(with_depth(base, 2.5, where, margin=1.2))
    found = {name: figures(run, base) for name, run in runs.items()}
    report = {
        "runs": found,
        "wall_s": time.perf_counter() - started,
        "load": os.getloadavg()[0],
    }
    if args.plot is not None and not args.quick:
        plot(args.plot, runs, found)
    if args.json:
        print(json.dumps(report, indent=2, default=float))
        return
    for name, f in found.items():
        print(name, {k: (round(v, 4) if isinstance(v, float) else v) for k, v in f.items()})
    print(f"wall {report['wall_s']:.1f} s, load {report['load']:.1f}")


if __name__ == "__main__":
    main()
