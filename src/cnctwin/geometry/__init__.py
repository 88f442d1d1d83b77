"""Cutter geometry, tri-dexel stock, material removal and cutter-workpiece engagement.

Public API::

    from cnctwin.geometry import Cutter, DexelStock, cut

    cutter = Cutter.flat(diameter_mm=6.0, flute_length_mm=20.0, flutes=3)
    stock = DexelStock.box((0, 0, -30), (100, 100, 0), density_per_mm=10)
    previous = None
    for position in tcp_mm:                 # tool-tip positions, mm (SampleChunk.tcp_mm)
        engagement = cut(stock, cutter, position, previous, feed_per_tooth_mm=0.05,
                         cycle_s=0.0125)
        previous = position

Units: this package works in mm (every length's name ends in ``_mm``; volumes mm^3, MRR mm^3/s,
feed mm/min as in the NC layer), seconds and radians. See docs/dexel.md.
"""

from cnctwin.geometry.cutter import AXIAL_KINDS, Cutter, CutterSlices
from cnctwin.geometry.dexel import AXES, Axis, DexelGrid, DexelStock
from cnctwin.geometry.engagement import Engagement, cut, cut_path, slice_low_mm
from cnctwin.geometry.engagement_map import (
    EngagementMap,
    MapCursor,
    MapMatch,
    MapSlices,
    MatchStatus,
    load_engagement_map,
    save_engagement_map,
)
from cnctwin.geometry.height_map import HeightMap, height_map
from cnctwin.geometry.mesh import stock_mesh
from cnctwin.geometry.removal import ContactRecord, Removal, remove
from cnctwin.geometry.stl import write_stl

__all__ = [
    "AXES",
    "Axis",
    "ContactRecord",
    "AXIAL_KINDS",
    "Cutter",
    "CutterSlices",
    "DexelGrid",
    "DexelStock",
    "Engagement",
    "EngagementMap",
    "HeightMap",
    "MapCursor",
    "MapMatch",
    "MapSlices",
    "MatchStatus",
    "Removal",
    "cut",
    "cut_path",
    "height_map",
    "load_engagement_map",
    "remove",
    "save_engagement_map",
    "slice_low_mm",
    "stock_mesh",
    "write_stl",
]
