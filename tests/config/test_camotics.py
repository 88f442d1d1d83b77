"""CAMotics projects as configuration."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import pytest

from cnctwin.config import load_config
from cnctwin.config.camotics import camotics_tools
from cnctwin.errors import ConfigError
from cnctwin.geometry import Cutter


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


@pytest.mark.validation
def test_every_example_project_loads_with_its_cones(
    shared_data: Path, caplog: pytest.LogCaptureFixture
) -> None:
    projects = sorted((shared_data / "gcode" / "camotics").glob("*/*.camotics"))
    assert len(projects) == 9
    with caplog.at_level(logging.WARNING, logger="cnctwin.config.camotics"):
        for project in projects:
            config = load_config(project)
            configured = {tool.number: tool for tool in config.tools}
            # Every tool is configured with its kind and size, or named in a warning as left
            # out (a kind the [[tools]] model does not describe).
            for number, tool in camotics_tools(project).items():
                if number in configured:
                    assert configured[number].kind == tool.kind
                    assert configured[number].diameter_mm == pytest.approx(tool.diameter_mm)
                else:
                    assert f"tool {number} is {tool.kind}" in caplog.text
    # The projects' files: vcarve T1 conical 2 x 2 mm, wave T1 conical 12.5 x 15.088835 mm,
    # buildbotics T2 conical 0.25 x 0.125 in, slant_test T1 snubnose 4 mm (snub 2) x 5.5 mm.
    cones = {
        "vcarve": (1, "conical", 2.0, 2.0, 0.0),
        "wave": (1, "conical", 12.5, 15.088835, 0.0),
        "buildbotics": (2, "conical", 6.35, 3.175, 0.0),
        "slant_test": (1, "snub", 4.0, 5.5, 2.0),
    }
    for name, (number, kind, diameter, length, tip) in cones.items():
        tool = camotics_tools(shared_data / "gcode" / "camotics" / name / f"{name}.camotics")[
            number
        ]
        assert (tool.kind, tool.tip_diameter_mm) == (kind, pytest.approx(tip))
        assert (tool.diameter_mm, tool.flute_length_mm) == pytest.approx((diameter, length))
        # CAMotics' cone spans the whole length: tip angle 2 atan((D - d) / 2L), e.g. the
        # buildbotics V-bit is 90 degrees and wave's 45 degrees.
        angle = math.degrees(2.0 * math.atan((diameter - tip) / (2.0 * length)))
        assert tool.tip_angle_deg == pytest.approx(angle)
        cutter = (
            Cutter.conical(diameter, length)
            if kind == "conical"
            else Cutter.snub(diameter, tip, length)
        )
        assert math.degrees(cutter.tip_angle_rad) == pytest.approx(angle)
        assert cutter.cone_height_mm == pytest.approx(length)
    assert camotics_tools(shared_data / "gcode" / "camotics" / "wave" / "wave.camotics")[
        1
    ].tip_angle_deg == pytest.approx(45.0, abs=1e-4)


def test_unsupported_shape_and_bad_json(tmp_path: Path) -> None:
    project = tmp_path / "v.camotics"
    project.write_text(
        '{"units": "metric", "tools": {"3": {"units": "metric", "shape": "spheroid",'
        ' "diameter": 6, "length": 10}}, "workpiece": {"bounds": {"min": [0,0,-5],'
        ' "max": [10,10,0]}}}'
    )
    with pytest.raises(ConfigError, match=r"tools\.3\.shape: 'spheroid' is not a CAMotics"):
        load_config(project)
    project.write_text(
        '{"units": "imperial", "tools": {"2": {"shape": "snubnose", "diameter": 0.25,'
        ' "snub_diameter": 0.05, "length": "long"}}, "workpiece": {"bounds": {"min": [0,0,-1],'
        ' "max": [1,1,0]}}}'
    )
    with pytest.raises(ConfigError, match=r"tools\.2\.length: 'long' is not a number"):
        camotics_tools(project)
    project.write_text("{not json")
    with pytest.raises(ConfigError, match="invalid JSON"):
        load_config(project)
    project.write_text(
        '{"units": "metric", "tools": {}, "workpiece": {"bounds": '
        '{"min": [0,0,0], "max": [10,10,-5]}}}'
    )
    with pytest.raises(ConfigError, match="stock.max_mm"):
        load_config(project)


def test_imperial_snub_nose_in_mm(tmp_path: Path) -> None:
    project = tmp_path / "s.camotics"
    project.write_text(
        '{"units": "metric", "tools": {"2": {"units": "imperial", "shape": "snubnose",'
        ' "diameter": 0.25, "snub_diameter": 0.05, "length": 0.5}}, "workpiece": {"bounds":'
        ' {"min": [0,0,-1], "max": [1,1,0]}}}'
    )
    (tool,) = camotics_tools(project).values()
    assert (tool.number, tool.kind) == (2, "snub")
    assert (tool.diameter_mm, tool.tip_diameter_mm, tool.flute_length_mm) == pytest.approx(
        (6.35, 1.27, 12.7)
    )
