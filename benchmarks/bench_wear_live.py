"""Accuracy: the live twin's wear estimate against the virtual machine's true flank wear.

The twin of ``examples/wear/wear_twin.toml`` runs in lockstep (one machine step of 25 ms per
cycle, in process) against the virtual machine with its accelerated-wear fault: a true flank
wear by its own law and a rubbing torque linear in it (docs/virtual-machine.md), while the
twin's EKF predicts with a normal tool's logistic law and the paper's logarithmic wear torque
fitted to calibration pairs (docs/wear-ekf.md). For each seed of the machine's sensor noise:
the error of the estimate while the tool cuts, the true wear when the twin saw each stage
begin, and the run's end (stopped at stage IV by the example's rule). Then the same program
without the fault (a tool that does not wear): the largest estimate and stage. Last, the
faulty run once more on the wall clock, for each stage's median time per sample (the
accuracy runs keep time by the machine's clock, so that they are deterministic).

Usage::

    python benchmarks/bench_wear_live.py [--seeds 1 2 3] [--plot wear-live.png] [--json]
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np

from cnctwin.twin import CycleState, LocalConnection, RunConfig, build_twin, load_run_config
from cnctwin.virtual import VirtualMachine

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "wear" / "wear_twin.toml"
STEP_S = 0.025


def run(config: RunConfig, seed: int, fault: bool, wall_clock: bool = False) -> dict[str, Any]:
    """One lockstep run; per new sample the machine time, true wear and the predictions
    (the runtime's clock: the machine's, or with ``wall_clock`` the monotonic clock)."""
    assert config.virtual is not None
    virtual = config.virtual.model_copy(
        update={"seed": seed, "faults": config.virtual.faults if fault else []}
    )
    vm = VirtualMachine(virtual, config)
    conn = LocalConnection(vm, step_s=STEP_S, tick_s=vm.tick_s)
    rows: list[tuple[float, float, float, float, float, float]] = []
    messages: list[str] = []
    stages: dict[str, float] = {}

    def keep(state: CycleState) -> None:
        p = state.predicted
        if state.new_sample and "wear_vb_mm" in p:
            rows.append(
                (
                    state.measured["t_s"],
                    vm.tool_wear_mm,
                    p["wear_vb_mm"],
                    p["wear_sd_mm"],
                    p["wear_stage"],
                    p.get("contact", 0.0),
                )
            )
        messages.extend(e.message for e in state.events if e.kind == "wear_stage")

    async def main() -> str:
        await conn.connect()
        try:
            clock = time.monotonic if wall_clock else lambda: vm.time_s
            twin = build_twin(config, conn, program=virtual.program, realtime=False, clock=clock)
            twin.runtime.on_cycle = keep
            summary = await twin.runtime.run(duration_s=120.0)
            stages.update({k: v["p50_ms"] for k, v in summary.stages_ms.items()})
            return summary.ended
        finally:
            await conn.close()

    ended = asyncio.run(main())
    a = np.array(rows)
    cut = a[:, 5] > 0.0
    error = a[cut, 2] - a[cut, 1]
    entries = {}
    for stage in (2, 3, 4):
        hit = np.flatnonzero(a[:, 4] >= stage)
        if hit.size:
            entries[f"stage_{stage}"] = {"t_s": float(a[hit[0], 0]), "true_mm": float(a[hit[0], 1])}
    return {
        "seed": seed,
        "fault": fault,
        "ended": ended,
        "samples_cutting": int(cut.sum()),
        "true_final_mm": float(a[-1, 1]),
        "mean_abs_error_mm": float(np.mean(np.abs(error))),
        "rms_error_mm": float(np.sqrt(np.mean(error**2))),
        "max_abs_error_mm": float(np.max(np.abs(error))),
        "mean_error_mm": float(np.mean(error)),
        "max_estimate_mm": float(np.max(a[:, 2])),
        "max_stage": int(np.max(a[:, 4])),
        "stage_entries": entries,
        "events": messages,
        "stage_p50_ms": stages,
        "series": a,
    }


def plot(result: dict[str, Any], config: RunConfig, path: Path) -> None:
    """True wear, estimate and its 2-sigma band over machine time, stage boundaries."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    a = result["series"]
    fig, ax = plt.subplots(figsize=(8, 4.2), dpi=110)
    ax.fill_between(a[:, 0], a[:, 2] - 2 * a[:, 3], a[:, 2] + 2 * a[:, 3], alpha=0.25,
                    color="tab:blue", label="estimate +- 2 sd")  # fmt: skip
    ax.plot(a[:, 0], a[:, 1], color="black", lw=1.5, label="virtual machine's true VB")
    ax.plot(a[:, 0], a[:, 2], color="tab:blue", lw=1.0, label="twin's EKF estimate")
    for name, bound in zip(("II", "III", "IV"), config.twin.wear.stages_mm, strict=True):
        ax.axhline(bound, color="grey", ls=":", lw=0.8)
        ax.text(a[0, 0], bound, f" stage {name} begins", va="bottom", fontsize=8, color="grey")
    ax.set_xlabel("machine time, s (five 3 mm slots; the gaps are rapids)")
    ax.set_ylabel("flank wear VB, mm")
    ax.set_title(f"Live wear estimate, accelerated-wear fault (seed {result['seed']})")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--plot", type=Path, help="PNG of the first seed's run")
    parser.add_argument("--json", action="store_true", help="one JSON object")
    parser.add_argument("--quick", action="store_true", help="CI: the first seed only")
    args = parser.parse_args()
    if args.quick:
        args.seeds = args.seeds[:1]
    config = load_run_config(EXAMPLE)
    runs = [run(config, seed, True) for seed in args.seeds]
    clean = [run(config, seed, False) for seed in args.seeds]
    timed = run(config, args.seeds[0], True, wall_clock=True)
    if args.plot:
        plot(runs[0], config, args.plot)
    out = {
        "platform": f"{platform.machine()}, Python {platform.python_version()}",
        "load": " ".join(f"{x:.1f}" for x in os.getloadavg()),
        "stage_p50_ms": timed["stage_p50_ms"],
        "fault": [
            {k: v for k, v in r.items() if k not in ("series", "stage_p50_ms")} for r in runs
        ],
        "clean": [
            {k: v for k, v in r.items() if k not in ("series", "events", "stage_p50_ms")}
            for r in clean
        ],
    }
    if args.json:
        print(json.dumps(out, indent=1))
        return
    print(out["platform"], "load", out["load"])
    print(
        "| seed | ended | mean abs error mm | RMS mm | max mm | true VB at stage II / III / IV mm |"
    )
    print("|---|---|---:|---:|---:|---|")
    for r in runs:
        e = r["stage_entries"]
        at = " / ".join(f"{e[f'stage_{s}']['true_mm']:.3f}" for s in (2, 3, 4) if f"stage_{s}" in e)
        print(
            f"| {r['seed']} | {r['ended']} | {r['mean_abs_error_mm']:.3f} | "
            f"{r['rms_error_mm']:.3f} | {r['max_abs_error_mm']:.3f} | {at} |"
        )
    for r in clean:
        print(
            f"clean seed {r['seed']}: {r['ended']}, largest estimate "
            f"{r['max_estimate_mm']:.3f} mm, largest stage {r['max_stage']}"
        )
    print(runs[0]["events"])
    stages = ", ".join(f"{k} {v * 1e3:.0f}" for k, v in out["stage_p50_ms"].items())
    print(f"stage medians, us per sample (load {out['load']}): {stages}")


if __name__ == "__main__":
    main()
