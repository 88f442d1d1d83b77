"""The tool-path picture's views: limited to the stock and the feed moves, rapids faint and
clipped (with a note), the stock outlined in 3D and from above. Checked on the figure's axes
and artists against limits computed here from the inputs."""

from __future__ import annotations

from pathlib import Path

import pytest
from matplotlib.colors import to_rgb

from cnctwin.nc.plot import VIEW_MARGIN, ToolpathPlot
from cnctwin.nc.segments import MachineState, MotionKind, Segment

STATE = MachineState()
STOCK = ((150.0, 100.0, -320.0), (230.0, 160.0, -300.0))


def move(kind: MotionKind, start: tuple[float, ...], end: tuple[float, ...]) -> Segment:
    feed = 0.0 if kind == MotionKind.RAPID else 600.0
    return Segment(kind, 1, start, end, feed, 0.0, STATE)  # type: ignore[arg-type]


def program() -> ToolpathPlot:
    """A rapid from the machine origin to above the stock, a slot cut, and back home."""
    plot = ToolpathPlot()
    plot.add(move(MotionKind.RAPID, (0.0, 0.0, 0.0), (170.0, 130.0, -295.0)))
    plot.add(move(MotionKind.LINEAR, (170.0, 130.0, -295.0), (170.0, 130.0, -303.0)))
    plot.add(move(MotionKind.LINEAR, (170.0, 130.0, -303.0), (210.0, 130.0, -303.0)))
    plot.add(move(MotionKind.RAPID, (210.0, 130.0, -303.0), (210.0, 130.0, 0.0)))
    return plot


def test_views_are_limited_to_the_stock_and_the_feed_moves() -> None:
    figure = program().figure(title="slot", stock_mm=STOCK)
    view3d, top = figure.axes
    # Stock and feeds span x 150..230, y 100..160, z -320..-295; margin 5 % of 80 mm = 4 mm.
    margin = VIEW_MARGIN * 80.0
    assert top.get_xlim() == pytest.approx((150.0 - margin, 230.0 + margin))
    assert top.get_ylim() == pytest.approx((100.0 - margin, 160.0 + margin))
    assert view3d.get_xlim() == pytest.approx((150.0 - margin, 230.0 + margin))
    assert view3d.get_zlim() == pytest.approx((-320.0 - margin, -295.0 + margin))
    # Not the machine origin the rapids come from and go to.
    assert not (view3d.get_zlim()[0] <= 0.0 <= view3d.get_zlim()[1])
    # Both rapid runs leave the view: a note says so.
    [note] = [t.get_text() for t in figure.texts if t.get_text() != "slot"]
    assert note.startswith("2 rapid run(s) leave the view")
    assert top.get_title() == "top view (XY)" and top.get_aspect() == 1.0


def test_rapids_are_thin_light_and_dashed_feeds_solid_and_the_stock_outlined() -> None:
    figure = program().figure(stock_mm=STOCK)
    view3d, top = figure.axes
    lines = {line.get_label(): line for line in top.get_lines()}
    rapid, feed, stock = lines["rapid"], lines["feed"], lines["stock"]
    assert rapid.get_linestyle() == "--" and feed.get_linestyle() == "-"
    assert rapid.get_linewidth() < feed.get_linewidth()
    assert min(to_rgb(rapid.get_color())) > 0.5  # light: every channel above half
    # The stock's outline from above is its rectangle, closed.
    assert list(zip(stock.get_xdata(), stock.get_ydata(), strict=True)) == [
        (150.0, 100.0), (230.0, 100.0), (230.0, 160.0), (150.0, 160.0), (150.0, 100.0)
    ]  # fmt: skip
    # In 3D: the twelve edges of the box, and rapids clipped at the view's limits.
    edges = [line for line in view3d.get_lines() if line.get_color() == stock.get_color()]
    assert len(edges) == 12 + 1  # the edges and the legend's entry
    rapid3d = next(line for line in view3d.get_lines() if line.get_label() == "rapid")
    assert rapid3d.get_linestyle() == "--" and rapid3d._axlim_clip  # noqa: SLF001


def test_without_a_stock_the_view_is_the_feed_moves() -> None:
    figure = program().figure()
    _, top = figure.axes
    # Feeds: x 170..210, y 130, z -303..-295: the largest span 40 mm, margin 2 mm.
    assert top.get_xlim() == pytest.approx((168.0, 212.0))
    assert not any(line.get_label() == "stock" for line in top.get_lines())


def test_only_rapids_show_them_all(tmp_path: Path) -> None:
    plot = ToolpathPlot()
    plot.add(move(MotionKind.RAPID, (0.0, 0.0, 0.0), (100.0, 50.0, -10.0)))
    box = plot.view_box()
    assert box is not None
    assert [*box[0], *box[1]] == pytest.approx([-5.0, -5.0, -15.0, 105.0, 55.0, 5.0])
    assert ToolpathPlot().view_box() is None
    plot.save(tmp_path / "r.png", stock_mm=None)
    assert (tmp_path / "r.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_top_view_of_sampled_steps_as_the_signals_plot_draws_them() -> None:
    from matplotlib.figure import Figure

    from cnctwin.nc import draw_top_view

    axes = Figure().add_subplot()
    # In air from the origin, cutting inside the stock, in air to the tool change above.
    runs = [
        (True, [(0.0, 0.0, 0.0), (160.0, 110.0, -305.0)]),
        (False, [(160.0, 110.0, -305.0), (200.0, 110.0, -305.0), (200.0, 150.0, -305.0)]),
        (True, [(200.0, 150.0, -305.0), (200.0, 150.0, -295.0)]),
    ]
    assert draw_top_view(axes, runs, STOCK, labels=("cutting", "not cutting")) == 1
    assert axes.get_xlim() == pytest.approx((146.0, 234.0))
    styles = {line.get_label(): line.get_linestyle() for line in axes.get_lines()}
    assert styles == {"cutting": "-", "not cutting": "--", "stock": "-"}
