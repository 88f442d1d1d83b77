"""``cnctwin demo``: the main job on its packaged default.

Interprets the packaged example program with the packaged configuration, samples the
motion at the twin's cycle time and prints a summary. Later this grows into the live twin.
"""

from __future__ import annotations

from importlib.resources import as_file

from rich.console import Console

from cnctwin.cli.nc import inspect_report, report_table
from cnctwin.config import load_config
from cnctwin.examples import example_file
from cnctwin.nc.segments import Segment

__all__ = ["CYCLE_S", "demo"]

#: The twin's cycle time in s (Heide 2025, Fig. 5: 12.5 ms).
CYCLE_S = 0.0125


def demo() -> None:
    """Interpret the packaged example, sample it every 12.5 ms and summarize it."""
    from cnctwin.nc.sampler import sample  # being grown with the twin; heavy to import

    with as_file(example_file("demo.toml")) as config_path, as_file(
        example_file("demo.ngc")
    ) as program:
        config = load_config(config_path)
        segments: list[Segment] = []  # the packaged program is small
        report = inspect_report(program, config, on_segment=segments.append)
    report["file"] = "cnctwin/examples/demo.ngc"
    samples = list(sample(segments, cycle_s=CYCLE_S))
    console = Console()
    table = report_table(report)
    table.add_row("cycle time", f"{CYCLE_S * 1000:.1f} ms")
    table.add_row("samples", str(len(samples)))
    console.print(table)
