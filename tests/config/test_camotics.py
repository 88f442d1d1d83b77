"""CAMotics projects as configuration."""

from __future__ import annotations

from pathlib import Path

import pytest

from cnctwin.config import load_config
from cnctwin.errors import ConfigError


@pytest.mark.validation
def test_heart_project_tools_and_stock(shared_data: Path) -> None:
    config = load_config(shared_data / "gcode" / "camotics" / "heart" / "heart.camotics")
    # heart.camotics: T1 imperial ballnose 0.1 in x 0.625 in, T2 cylindrical 0.0625 in x 1 in;
    # workpiece -40..40 x -40..40 x -12.7..0 mm.
    t1, t2 = config.tools
    assert (t1.number, t1.kind, t2.kind) == (1, "ball", "flat")
    assert t1.diameter_mm == pytest.approx(2.54) and t1.flute_length_mm == pytest.approx(15.875)
    assert t2.diameter_mm == pytest.approx(1.5875)
    assert config.stock.min_mm == (-40.0, -40.0, -12.7) and config.stock.max_mm == (40, 40, 0)


def test_unsupported_shape_and_bad_json(tmp_path: Path) -> None:
    project = tmp_path / "v.camotics"
    project.write_text(
        '{"units": "metric", "tools": {"3": {"units": "metric", "shape": "conical",'
        ' "diameter": 6, "length": 10}}, "workpiece": {"bounds": {"min": [0,0,-5],'
        ' "max": [10,10,0]}}}'
    )
    with pytest.raises(ConfigError, match=r"tools\.3\.shape: 'conical' is not supported"):
        load_config(project)
    project.write_text("{not json")
    with pytest.raises(ConfigError, match="invalid JSON"):
        load_config(project)
    project.write_text(
        '{"units": "metric", "tools": {}, "workpiece": {"bounds": '
        '{"min": [0,0,0], "max": [10,10,-5]}}}'
    )
    with pytest.raises(ConfigError, match="stock.max_mm"):
        load_config(project)
