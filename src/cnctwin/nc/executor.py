"""The block executor: one lexed block at a time, in LinuxCNC's order of execution.

Within a block, RS274NGC (and LinuxCNC) act in a fixed order whatever the order of the
words: comments and parameter settings, units, feed mode, F, S, T, M6/M61, spindle and
coolant, G4, plane, G7/G8, G96/G97, cutter compensation, tool length offset, coordinate
system, distance and retract modes, reference points and offsets (G10, G28, G30, G92),
motion, and program end. :meth:`BlockExecutor.execute` follows it, delegating to the modal
state, offsets, tool state, drilling cycles and motion.
"""

from __future__ import annotations

from typing import Final

from cnctwin.nc.blocks import (
    AXIS_WORDS,
    CENTRE_WORDS,
    CYCLES,
    FAST_WORDS,
    NON_MODAL_WITH_AXES,
    BlockCodes,
    check_words,
    read_codes,
)
from cnctwin.nc.canned_cycles import CycleModes
from cnctwin.nc.cursor import ProgramCursor
from cnctwin.nc.expressions import Parameters, expand_parameters
from cnctwin.nc.lexer import Block
from cnctwin.nc.modal import ModalState
from cnctwin.nc.motion import Motion
from cnctwin.nc.offsets import Offsets
from cnctwin.nc.segments import FeedMode, Plane
from cnctwin.nc.setup import NCSetup
from cnctwin.nc.tool_state import ToolState

__all__ = ["BlockExecutor"]

_READ_ONLY: Final = frozenset(("_x", "_y", "_z", "_abs_x", "_abs_y", "_abs_z"))
_COORD_SYSTEMS: Final = {540: 1, 550: 2, 560: 3, 570: 4, 580: 5, 590: 6, 591: 7, 592: 8, 593: 9}


class BlockExecutor:
    """Execute lexed blocks against the interpreter's state.

    Parameters
    ----------
    setup
        Machine set-up: tools, lathe flag, initial offsets and position (mm).
    where
        Where errors and warnings are reported.
    params
        The program's parameters.

    Attributes
    ----------
    modal, offsets, tools, cycles, motion
        The state the blocks change: modes, offsets, tools, drilling cycles, position.
    messages
        Texts of ``(MSG, ...)``, ``(DEBUG, ...)`` and ``(PRINT, ...)`` comments, in order.
    ended
        M2 or M30 was executed.
    """

    __slots__ = (
        "modal",
        "offsets",
        "tools",
        "cycles",
        "motion",
        "messages",
        "ended",
        "_params",
        "_where",
        "_lathe",
    )

    def __init__(self, setup: NCSetup, where: ProgramCursor, params: Parameters) -> None:
        self.modal = ModalState(where, setup.lathe, setup.max_spindle_rpm)
        self.offsets = Offsets(setup)
        self.tools = ToolState(setup, where)
        self.cycles = CycleModes(where)
        self.motion = Motion(
            where, self.modal, self.offsets, self.tools, self.cycles, setup.initial_position_mm
        )
        self.messages: list[str] = []
        self.ended = False
        self._params = params
        self._where = where
        self._lathe = setup.lathe

    def execute(self, block: Block) -> None:
        """Execute one block; its segments are appended to ``motion.out``.

        Raises
        ------
        NCError
            For anything the block asks that cnctwin cannot honour.
        """
        for key, value in block.assignments:
            if key in _READ_ONLY:
                raise self._where.error(
                    f"#<{key}> is a read-only system parameter and cannot be set"
                )
            self._params[key] = value
        for kind, text in block.messages:
            self.messages.append(text if kind == "msg" else expand_parameters(text, self._params))
        gcodes = block.gcodes
        words = block.words
        if not block.mcodes and self.motion.comp is None and words.keys() <= FAST_WORDS:
            # A G0/G1 block of X, Y, Z and F words only: the bulk of CAM output.
            if not gcodes:
                if not words:
                    return
                motion = self.modal.motion
                if motion == 10 or motion == 0:
                    self._fast_straight(words, motion)
                    return
            elif len(gcodes) == 1 and (gcodes[0] == 10 or gcodes[0] == 0) and words:
                self.modal.motion = gcodes[0]
                self._fast_straight(words, gcodes[0])
                return
        self._execute_general(block)

    def _fast_straight(self, words: dict[str, float], motion: int) -> None:
        if "f" in words:
            self.modal.set_feed(words["f"])
            if len(words) == 1:
                return
        self.motion.xyz_move(motion, words.get("x"), words.get("y"), words.get("z"), "f" in words)

    def _execute_general(self, block: Block) -> None:
        codes = read_codes(block, self._lathe, self._where)
        if codes.cancels_cycle:
            self.cycles.cancel()
        check_words(
            block, codes, self.modal.motion, self.modal.incremental, self._lathe, self._where
        )
        self._feed_speed_tool(block, codes)
        self._frame_modes(codes, block.words)
        self._offset_codes(codes.non_modal, block.words)
        self._motion(codes, block.words)
        # Program end (M0, M1 and M60 pauses do not change the path).
        if 2 in block.mcodes or 30 in block.mcodes:
            self.ended = True

    def _feed_speed_tool(self, block: Block, codes: BlockCodes) -> None:
        """Units, feed mode, F, S, T, M6/M61, spindle and coolant, G4 dwell."""
        words = block.words
        groups = codes.groups
        modal = self.modal
        # Units first: the F, S and axis words of this block are in the new units.
        if 6 in groups:
            modal.set_units("inch" if groups[6] in (200, 7000) else "mm")
        if 5 in groups:
            modal.set_feed_mode(FeedMode(groups[5] // 10))
        if "f" in words:
            modal.set_feed(words["f"])
        if "s" in words and codes.non_modal != 500:
            modal.set_speed(words["s"])
        if "t" in words:
            self._select_tool(words["t"])
        if 6 in block.mcodes:
            modal.set_tool(self.tools.load(self.tools.selected))
        elif 61 in block.mcodes:
            modal.set_tool(self.tools.load_without_change(words.get("q")))
        for m in block.mcodes:
            if m in (3, 4, 5):
                modal.set_spindle(m)
            elif m in (7, 8, 9):
                modal.set_coolant(m)
        if codes.non_modal == 40:
            self.motion.dwell(words)

    def _frame_modes(self, codes: BlockCodes, words: dict[str, float]) -> None:
        """Plane, G7/G8, G96/G97, G50 clamp, cutter compensation, tool length offset,
        coordinate system, distance and retract modes."""
        groups = codes.groups
        modal = self.modal
        if 2 in groups:
            plane = Plane(groups[2] // 10)
            if plane != modal.state.plane and self.motion.comp is not None:
                raise self._where.error("cannot change the plane while cutter compensation is on")
            modal.set_plane(plane)
        if 15 in groups:
            modal.set_diameter_mode(groups[15] == 70)
        if 14 in groups:
            modal.set_css(groups[14] == 960, words.get("d"))
        if codes.non_modal == 500:
            modal.clamp_spindle(words)
        if 7 in groups:
            self.motion.set_comp(groups[7], words)
        if 8 in groups:
            self.offsets.tool = self.tools.length_offset(
                groups[8], words, modal.state.tool, modal.factor, self.offsets.tool
            )
            self._reframe()
        if 12 in groups:
            if self.motion.comp is not None:
                raise self._where.error(
                    "cannot change the coordinate system while cutter compensation is on"
                )
            self.offsets.system = _COORD_SYSTEMS[groups[12]]
            self._reframe()
        # Path control mode (G61/G64, group 13) does not change the programmed path.
        if 3 in groups:
            modal.incremental = groups[3] == 910
        if 4 in groups:
            modal.arc_absolute = groups[4] == 901
        if 10 in groups:
            self.cycles.retract_to_r = groups[10] == 990

    def _offset_codes(self, non_modal: int | None, words: dict[str, float]) -> None:
        """G28/G30 returns, G28.1/G30.1, G10, and the G92/G52 family."""
        motion = self.motion
        if non_modal in (280, 300):
            motion.go_home(non_modal, words)
        elif non_modal in (281, 301):
            self.offsets.reference_point(non_modal)[:] = [*motion.pos, *motion.abc]
        elif non_modal == 100:
            self._g10(words)
        elif non_modal in (920, 921, 922, 923, 520):
            self._g92(non_modal, words)

    def _motion(self, codes: BlockCodes, words: dict[str, float]) -> None:
        """Set the motion mode and move, if the block has anything to move by."""
        modal = self.modal
        code = codes.motion
        if code is not None:
            if code == 800:
                modal.motion = None
                self.cycles.cancel()
            else:
                modal.motion = code
        if codes.non_modal in NON_MODAL_WITH_AXES or codes.groups.get(8) == 431:
            return
        motion = modal.motion
        if (
            not AXIS_WORDS.isdisjoint(words)
            or code in CYCLES
            or (motion in (20, 30) and not CENTRE_WORDS.isdisjoint(words))
        ):
            if motion is None:
                raise self._where.error(
                    "axis words after G80 with no motion mode: add G0 or G1"
                    if code == 800
                    else "axis words with no active motion mode: add G0, G1, G2 or G3"
                )
            self.motion.move(motion, words, codes.g53)

    # ------------------------------------------------------------------ tools and offsets
    def _select_tool(self, value: float) -> None:
        load, register = self.tools.select(value)
        if load:
            self.modal.set_tool(self.tools.load(self.tools.selected))
        if register is not None:
            self.offsets.tool = self.tools.register_offset(register, int(value))
            self._reframe()

    def _reframe(self) -> None:
        """Carry a change of the offsets into the modal state."""
        self.modal.state = self.offsets.frame(self.modal.state)

    def _g10(self, words: dict[str, float]) -> None:
        if "l" not in words:
            raise self._where.error("G10 needs an L word (L1, L2, L10, L11 or L20)")
        l_word = int(words["l"])
        p = words.get("p")
        modal = self.modal
        motion = self.motion
        offsets = self.offsets
        if l_word in (2, 20):
            if p is None or p != int(p) or not 0 <= p <= 9:
                raise self._where.error(f"G10 L{l_word} needs P0-P9 (coordinate system); got {p}")
            system = int(p) or offsets.system
            values = modal.axis_values(words)
            if l_word == 2:
                offsets.set_origin(system, values, words.get("r"))
            else:
                here = [*motion.pos, *motion.abc]
                offsets.set_origin_here(system, values, words.get("r"), modal.state, here)
            self._reframe()
        elif l_word in (1, 10, 11):
            if p is None or p != int(p) or p < 1:
                raise self._where.error(f"G10 L{l_word} needs P<tool number>; got {p}")
            origin = offsets.origins[9 if l_word == 11 else offsets.system]
            g92 = offsets.g92 if l_word == 10 else [0.0] * 6
            self.tools.set_entry(l_word, int(p), words, modal.factor, motion.pos, origin, g92)
        else:
            raise self._where.error(f"G10 L{l_word} is not supported (use L1, L2, L10, L11 or L20)")

    def _g92(self, code: int, words: dict[str, float]) -> None:
        modal = self.modal
        if code == 920:
            if not any(k in words for k in "xyzabc"):
                raise self._where.error("G92 needs at least one axis word")
            values = modal.axis_values(words)
        elif code == 520:
            values = {
                i: words[letter] * (modal.factor if i < 3 else 1.0)
                for i, letter in enumerate("xyzabc")
                if letter in words
            }
        else:
            values = {}
        here = [*self.motion.pos, *self.motion.abc]
        self.offsets.set_g92(code, values, modal.state, here)
        self._reframe()

    # ------------------------------------------------------------------ parameters
    def sync_parameters(self) -> None:
        """Refresh the read-only system parameters a program may read.

        Lengths are in the program's current units: #5210-#5399 (G92 offset, coordinate
        systems; see :meth:`Offsets.write_parameters`); #5400 tool number, #5401-#5403 its
        offsets X Y Z; #5420-#5425 the current position X Y Z A B C in the program frame;
        #<_x> #<_y> #<_z> (same) and #<_abs_x> #<_abs_y> #<_abs_z> (machine position).
        """
        params = self._params
        f = self.modal.factor
        state = self.modal.state
        offsets = self.offsets
        pos = (self.motion.pos[0], self.motion.pos[1], self.motion.pos[2])
        abc = self.motion.abc
        here = state.to_program(pos)
        offsets.write_parameters(params, f)
        params[5400] = float(state.tool)
        for i, axis in enumerate("xyz"):
            params[5401 + i] = offsets.tool[i] / f
            params[5420 + i] = here[i] / f
            params[5423 + i] = abc[i] - offsets.total[3 + i]
            params["_" + axis] = here[i] / f
            params["_abs_" + axis] = pos[i] / f
