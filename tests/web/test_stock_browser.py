"""The 3D stock view (static/stock.js) renders a dexel stock in headless Chromium."""

import json
from importlib.resources import files

import numpy as np
from PIL import Image

from cnctwin.geometry import Cutter, DexelStock, cut
from cnctwin.web.server import plotly_js
from cnctwin.web.stock import stock_view


def distinct_colours(png: bytes) -> int:
    import io

    return len(np.unique(np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).reshape(-1, 3),
                         axis=0))  # fmt: skip


def test_stock_view_renders(page) -> None:
    stock = DexelStock.box((0, 0, -10), (40, 30, 0), density_per_mm=2)
    cutter = Cutter.flat(diameter_mm=6.0, flute_length_mm=20.0, flutes=3)
    previous = None
    for x in np.arange(5.0, 35.0, 0.25):
        position = np.array((x, 15.0, -3.0))
        cut(stock, cutter, position, previous, 0.05, 0.001)
        previous = position
    view = stock_view(stock, (35.0, 15.0, -3.0), cutter)
    page.set_content("<div id='s' style='width:800px;height:600px'></div>")
    blank = distinct_colours(page.locator("#s").screenshot())
    page.add_script_tag(path=str(plotly_js()))
    page.add_script_tag(content=(files("cnctwin.web") / "static" / "stock.js").read_text())
    page.evaluate("view => CnctwinStock.draw(document.getElementById('s'), view)",
                  json.loads(json.dumps(view)))  # fmt: skip
    page.wait_for_selector("#s .gl-container canvas")
    page.wait_for_timeout(500)
    shot = page.locator("#s").screenshot()
    assert blank == 1
    # A shaded surface and a tool: many colours (a blank or flat area has a handful).
    assert distinct_colours(shot) > 200
    # The colours span the stock's tops, the 3 mm slot's floor to the top (not the 10 mm
    # block), so the cut shows in the scale's full range.
    cmin, cmax = page.evaluate("[document.getElementById('s').data[0].cmin,"
                               " document.getElementById('s').data[0].cmax]")  # fmt: skip
    assert abs(cmin - -3.0) < 1e-3 and cmax == 0.0
