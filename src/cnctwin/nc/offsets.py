"""Coordinate systems and offsets: G54-G59.3 origins and their XY rotation (G10 L2/L20),
the G92/G52 offset (G92.1-G92.3), the tool length offset vector, and the G28/G30
reference points.

Positions are machine coordinates of the controlled point, in mm (degrees for A, B, C);
``machine = origin + Rz(rotation) (program + G92 offset) + tool offset`` (see
:meth:`~cnctwin.nc.segments.MachineState.to_machine`). Axes are indexed 0-5 for X Y Z A B C.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from cnctwin.nc.expressions import Parameters
from cnctwin.nc.segments import MachineState
from cnctwin.nc.setup import NCSetup

__all__ = ["Offsets"]


class Offsets:
    """Offsets from program to machine coordinates.

    Parameters
    ----------
    setup
        Initial origins of the coordinate systems and the reference points, mm.

    Attributes
    ----------
    origins
        Origin of each coordinate system 1 (G54) to 9 (G59.3): X Y Z in mm, A B C in degrees.
    system
        Active coordinate system, 1-9.
    rotation_deg
        XY rotation of each coordinate system (G10 L2 R), degrees counter-clockwise.
    g92, g92_saved
        The G92/G52 offset in force and the stored one (G92.2 suspends, G92.3 restores).
    g92_enabled
        A G92/G52 offset is in force.
    tool
        Tool length offset vector (x, y, z), mm (G43, G43.1, G43.2; zero after G49).
    total
        Sum of origin, G92 offset and tool offset per axis: what is added to a program
        coordinate on an axis the rotation does not turn. Updated in place.
    g28, g30
        The G28 and G30 reference points, machine coordinates (G28.1, G30.1 store them).
    """

    __slots__ = (
        "origins",
        "system",
        "rotation_deg",
        "g92",
        "g92_saved",
        "g92_enabled",
        "tool",
        "total",
        "g28",
        "g30",
    )

    def __init__(self, setup: NCSetup) -> None:
        self.origins: dict[int, list[float]] = {
            n: [*setup.work_offsets_mm.get(n, (0.0, 0.0, 0.0)), 0.0, 0.0, 0.0] for n in range(1, 10)
        }
        self.system = 1
        self.rotation_deg: dict[int, float] = dict.fromkeys(range(1, 10), 0.0)
        self.g92 = [0.0] * 6
        self.g92_saved = [0.0] * 6
        self.g92_enabled = False
        self.tool = [0.0, 0.0, 0.0]
        self.total = [0.0] * 6
        self.g28 = [*setup.g28_home_mm, 0.0, 0.0, 0.0]
        self.g30 = [*setup.g30_home_mm, 0.0, 0.0, 0.0]

    def frame(self, state: MachineState) -> MachineState:
        """``state`` with this frame's origin, G92 offset, tool offset, rotation and system
        (``state`` itself when they are unchanged); updates :attr:`total`."""
        origin = self.origins[self.system]
        g92 = self.g92
        tool = self.tool
        self.total[:] = [origin[i] + g92[i] + (tool[i] if i < 3 else 0.0) for i in range(6)]
        new = (
            (origin[0], origin[1], origin[2]),
            (g92[0], g92[1], g92[2]),
            (tool[0], tool[1], tool[2]),
            self.rotation_deg[self.system],
            self.system,
        )
        if new == (
            state.work_offset_mm,
            state.axis_offset_mm,
            state.tool_offset_mm,
            state.xy_rotation_deg,
            state.coordinate_system,
        ):
            return state
        return replace(
            state,
            work_offset_mm=new[0],
            axis_offset_mm=new[1],
            tool_offset_mm=new[2],
            xy_rotation_deg=new[3],
            coordinate_system=new[4],
        )

    def set_origin(
        self,
        system: int,
        values: dict[int, float],
        rotation_deg: float | None,
    ) -> None:
        """G10 L2: origin of coordinate system ``system`` (1-9) on the axes given in
        ``values`` (axis index -> mm or degrees) and, if given, its XY rotation."""
        origin = self.origins[system]
        for i, v in values.items():
            origin[i] = v
        if rotation_deg is not None:
            self.rotation_deg[system] = rotation_deg

    def set_origin_here(
        self,
        system: int,
        values: dict[int, float],
        rotation_deg: float | None,
        state: MachineState,
        position: Sequence[float],
    ) -> None:
        """G10 L20: set coordinate system ``system``'s origin so that the current machine
        ``position`` (x, y, z mm, a, b, c degrees) reads ``values`` (axis index -> program
        coordinate, mm or degrees) there; ``state`` gives the current program frame."""
        origin = self.origins[system]
        if rotation_deg is not None:
            self.rotation_deg[system] = rotation_deg
        rotation = self.rotation_deg[system]
        frame = replace(
            state,
            work_offset_mm=(0.0, 0.0, 0.0),
            axis_offset_mm=(self.g92[0], self.g92[1], self.g92[2]),
            xy_rotation_deg=rotation,
        )
        prog = list(state.to_program((position[0], position[1], position[2])))
        for i, v in values.items():
            if i < 3:
                prog[i] = v
            else:
                origin[i] = position[i] - self.g92[i] - v
        shifted = frame.to_machine((prog[0], prog[1], prog[2]))
        for i in range(3):
            if i in values or rotation != 0.0:
                origin[i] = position[i] - shifted[i]

    def set_g92(
        self, code: int, values: dict[int, float], state: MachineState, position: Sequence[float]
    ) -> None:
        """G92 (``code`` 920: ``position`` reads ``values`` in the program frame), G52 (520:
        the offset is ``values``), G92.1 (921: clear), G92.2 (922: suspend), G92.3 (923:
        restore). ``values``: axis index -> mm or degrees; ``position``: x, y, z mm,
        a, b, c degrees; ``state`` gives the current program frame."""
        if code == 920:
            unshifted = replace(state, axis_offset_mm=(0.0, 0.0, 0.0))
            here = unshifted.to_program((position[0], position[1], position[2]))
            for i, v in values.items():
                if i < 3:
                    self.g92[i] = here[i] - v
                else:
                    self.g92[i] = position[i] - self.origins[self.system][i] - v
            self.g92_saved = list(self.g92)
        elif code == 520:
            for i, v in values.items():
                self.g92[i] = v
            self.g92_saved = list(self.g92)
        elif code == 921:
            self.g92 = [0.0] * 6
            self.g92_saved = [0.0] * 6
        elif code == 922:
            self.g92 = [0.0] * 6
        elif code == 923:
            self.g92 = list(self.g92_saved)
        self.g92_enabled = code in (920, 520, 923)

    def reference_point(self, code: int) -> list[float]:
        """The G28 (``code`` 280 or 281) or G30 (300, 301) reference point, to read or store."""
        return self.g28 if code in (280, 281) else self.g30

    def write_parameters(self, params: Parameters, factor: float) -> None:
        """Write the read-only system parameters of the offsets, lengths in program units
        (``factor`` mm per unit): #5210 G92 enabled (1/0), #5211-#5216 the stored G92/G52
        offset; #5220 the coordinate system (1-9); #5221 + 20 (n - 1) + i the origin of
        system n on axis i (X Y Z A B C), #5230 + 20 (n - 1) its rotation in degrees."""
        params[5210] = 1.0 if self.g92_enabled else 0.0
        for i in range(6):
            scale = factor if i < 3 else 1.0
            params[5211 + i] = self.g92_saved[i] / scale
            for n in range(1, 10):
                params[5201 + 20 * n + i] = self.origins[n][i] / scale
        for n in range(1, 10):
            params[5210 + 20 * n] = self.rotation_deg[n]
        params[5220] = float(self.system)
