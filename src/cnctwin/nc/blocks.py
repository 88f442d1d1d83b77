"""Modal groups and the RS274NGC rules of a block: which codes may share a block, and
which words each code uses.

G-codes are keyed by ten times their number (G92.1 is 921). :func:`read_codes` sorts a
block's G- and M-codes into their modal groups (refusing two codes of one group and codes
cnctwin does not implement); :func:`check_words` refuses a word nothing in the block uses.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final, NoReturn

from cnctwin.nc.cursor import ProgramCursor
from cnctwin.nc.lexer import Block

__all__ = [
    "ARC_WORDS",
    "AXIS_WORDS",
    "CENTRE_WORDS",
    "CYCLES",
    "FAST_WORDS",
    "NON_MODAL_WITH_AXES",
    "BlockCodes",
    "check_words",
    "g_text",
    "read_codes",
]

#: Modal group of each G-code (group 0: non-modal codes).
G_GROUPS: Final[dict[int, int]] = {}
for _group, _codes in {
    1: (0, 10, 20, 30, 51, 331, 730, 800, 810, 820, 830, 840, 850, 860, 890),
    2: (170, 180, 190),
    3: (900, 910),
    4: (901, 911),
    5: (930, 940, 950),
    6: (200, 210, 7000, 7100),
    7: (400, 410, 420, 411, 421),
    8: (430, 431, 432, 490),
    10: (980, 990),
    12: (540, 550, 560, 570, 580, 590, 591, 592, 593),
    13: (610, 611, 640),
    14: (960, 970),
    15: (70, 80),
    0: (40, 100, 280, 281, 300, 301, 520, 530, 920, 921, 922, 923, 500),
}.items():
    for _code in _codes:
        G_GROUPS[_code] = _group

#: Modal groups of M-codes (RS274NGC): stops, tool change, spindle, coolant, overrides.
M_GROUPS: Final = {
    0: 4,
    1: 4,
    2: 4,
    30: 4,
    60: 4,
    6: 6,
    61: 6,
    3: 7,
    4: 7,
    5: 7,
    7: 8,
    8: 8,
    9: 8,
    48: 9,
    49: 9,
}
KNOWN_M: Final = frozenset((0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 30, 48, 49, 60, 61))

#: Words of a modal G0/G1 block that the block executor's shortcut takes.
FAST_WORDS: Final = frozenset("xyzf")
#: Words that every block may carry (feed, speed, tool, axes).
PLAIN_WORDS: Final = frozenset("fstxyzabc@^")
#: Words that move an axis; the centre words of an arc.
AXIS_WORDS: Final = frozenset("xyzabcuw@^")
CENTRE_WORDS: Final = frozenset("ijk")
#: Words an arc block (G2/G3) may carry.
ARC_WORDS: Final = PLAIN_WORDS | frozenset("ijkrp")
#: Non-modal codes that use the axis words themselves.
NON_MODAL_WITH_AXES: Final = frozenset((100, 280, 300, 520, 920))
#: The drilling cycles G73, G81-G86, G89.
CYCLES: Final = frozenset((730, 810, 820, 830, 840, 850, 860, 890))

#: G-codes recognised but not implemented, with what they are.
UNSUPPORTED_G: Final[dict[int, str]] = {
    50: "cubic spline (G5)",
    52: "NURBS (G5.2)",
    53: "NURBS (G5.3)",
    120: "circular pocket (G12)",
    130: "circular pocket (G13)",
    330: "spindle-synchronized motion (G33)",
    382: "probing (G38.2)",
    383: "probing (G38.3)",
    384: "probing (G38.4)",
    385: "probing (G38.5)",
    510: "scaling (G51)",
    541: "extended work offsets (G54.1)",
    680: "coordinate rotation (G68)",
    690: "coordinate rotation cancel (G69)",
    700: "lathe finishing cycle (G70)",
    710: "lathe roughing cycle (G71)",
    711: "lathe roughing cycle (G71.1)",
    712: "lathe roughing cycle (G71.2)",
    720: "lathe facing cycle (G72)",
    721: "lathe facing cycle (G72.1)",
    722: "lathe facing cycle (G72.2)",
    740: "left-hand tapping / lathe peck cycle (G74)",
    750: "lathe grooving cycle (G75)",
    760: "threading cycle (G76)",
    870: "back boring cycle (G87)",
    880: "boring cycle with manual retract (G88)",
    1000: "macro call (G100)",
}
UNSUPPORTED_M: Final[dict[int, str]] = {
    98: "Fanuc subprogram call (M98)",
    99: "Fanuc subprogram return (M99)",
}


@dataclass(frozen=True, slots=True)
class BlockCodes:
    """A block's G-codes sorted into modal groups.

    Attributes
    ----------
    groups
        The G-code of each modal group the block names (group -> code key).
    motion
        The group 1 code (G0, G1, G2, G3, G5.1, G33.1, G80 or a cycle), or ``None``.
    non_modal
        The group 0 code other than G53 (G4, G10, G28, G92, ...), or ``None``.
    g53
        G53 (move in machine coordinates) is in the block.
    cancels_cycle
        G80 shared the block with another motion code (a Fanuc/Haas safe-start line): the
        cycle's sticky R and hole bottom are forgotten, the other motion code is kept.
    """

    groups: dict[int, int]
    motion: int | None
    non_modal: int | None
    g53: bool
    cancels_cycle: bool


def g_text(code: int) -> str:
    """G-code key (ten times the number) back to its text, e.g. 921 -> '92.1'."""
    whole, tenth = divmod(code, 10)
    return f"{whole}.{tenth}" if tenth else f"{whole}"


def read_codes(block: Block, lathe: bool, where: ProgramCursor) -> BlockCodes:
    """Sort a block's G-codes into modal groups and check its M-codes.

    ``lathe``: Fanuc lathe meanings (G50 spindle clamp; G98/G99 select feed per minute
    or per revolution). Unknown M-codes are ignored with a warning at ``where``.

    Raises
    ------
    NCError
        For a G-code cnctwin does not implement, two codes of one modal group or two
        non-modal codes, G50 on a mill, and M98/M99.
    """
    groups: dict[int, int] = {}
    motion: int | None = None
    non_modal: int | None = None
    g53 = False
    gcodes = block.gcodes
    cancels_cycle = 800 in gcodes and any(G_GROUPS.get(c) == 1 and c != 800 for c in gcodes)
    if cancels_cycle:
        gcodes = [c for c in gcodes if c != 800]
    for code in gcodes:
        group = G_GROUPS.get(code)
        if group is None:
            _reject_g(code, where)
        if code == 530:
            g53 = True
        elif group == 0:
            if code == 500 and not lathe:
                raise where.error(
                    "G50 (spindle speed clamp) is a lathe code: use a lathe "
                    "configuration (machine.kind = 'lathe')"
                )
            if non_modal is not None:
                raise where.error(f"G{g_text(non_modal)} and G{g_text(code)} cannot share a block")
            non_modal = code
        else:
            if group in groups:
                raise where.error(
                    f"G{g_text(groups[group])} and G{g_text(code)} are in the same modal "
                    "group and cannot share a block"
                )
            groups[group] = code
            if group == 1:
                motion = code
    if lathe and (980 in groups.values() or 990 in groups.values()):
        # Fanuc lathe (G-code system A): G98/G99 select feed per minute/revolution.
        code = groups.pop(10)
        groups[5] = 940 if code == 980 else 950
    for m in block.mcodes:
        if m not in KNOWN_M:
            if m in UNSUPPORTED_M:
                raise where.error(f"{UNSUPPORTED_M[m]} is not supported")
            where.warn(f"M{m} is machine-specific and was ignored")
    return BlockCodes(groups, motion, non_modal, g53, cancels_cycle)


def _reject_g(code: int, where: ProgramCursor) -> NoReturn:
    if code in UNSUPPORTED_G:
        raise where.error(f"{UNSUPPORTED_G[code]} is not supported")
    raise where.error(
        f"G{g_text(code)} is not a G-code cnctwin knows; see docs/nc.md for the supported list"
    )


def check_words(
    block: Block,
    codes: BlockCodes,
    modal_motion: int | None,
    incremental: bool,
    lathe: bool,
    where: ProgramCursor,
) -> None:
    """RS274NGC block rules: one M-code per modal group, one user of the axis words, no
    G53 under G91, and no word that nothing in the block uses.

    ``modal_motion``: the motion mode in force before the block; ``incremental``: G91 in
    force before the block.

    Raises
    ------
    NCError
        Naming the codes or the word that break a rule.
    """
    words = block.words
    non_modal = codes.non_modal
    if (
        not block.mcodes
        and not codes.g53
        and non_modal not in NON_MODAL_WITH_AXES
        and words.keys() <= PLAIN_WORDS
    ):
        return
    motion_code = codes.motion
    motion = motion_code if motion_code not in (None, 800) else modal_motion
    if (
        (motion == 20 or motion == 30)
        and not block.mcodes
        and not codes.g53
        and non_modal is None
        and words.keys() <= ARC_WORDS
        and not (AXIS_WORDS.isdisjoint(words) and CENTRE_WORDS.isdisjoint(words))
    ):
        return  # an arc block: every word it carries is the arc's
    _check_m_groups(block.mcodes, where)
    if (
        non_modal in NON_MODAL_WITH_AXES
        and motion_code not in (None, 800)
        and not AXIS_WORDS.isdisjoint(words)
    ):
        raise where.error(
            f"G{g_text(motion_code)} and G{g_text(non_modal)} both use the axis words "
            "and cannot share a block"
        )
    groups = codes.groups
    if codes.g53 and (incremental and groups.get(3) != 900 or groups.get(3) == 910):
        raise where.error("G53 cannot be used in incremental mode (G91): use G90")
    allowed = _allowed_words(block, codes, motion, lathe)
    for letter in words:
        if letter not in allowed:
            raise where.error(
                f"word {letter.upper()}{words[letter]:g} is not used by anything in this "
                "block; remove it or add the G-code that takes it"
            )


def _check_m_groups(mcodes: list[int], where: ProgramCursor) -> None:
    seen: dict[int, int] = {}
    for m in mcodes:
        group = M_GROUPS.get(m)
        if group is None:
            continue
        if group in seen and not (group == 8 and {m, seen[group]} == {7, 8}):
            raise where.error(
                f"M{seen[group]} and M{m} are in the same modal group and cannot share a block"
            )
        seen[group] = m


def _allowed_words(block: Block, codes: BlockCodes, motion: int | None, lathe: bool) -> set[str]:
    """The word letters that something in the block uses."""
    words = block.words
    groups = codes.groups
    moving = not AXIS_WORDS.isdisjoint(words) or codes.motion in CYCLES
    allowed = set(PLAIN_WORDS)
    if lathe:
        allowed |= {"u", "w"}
    if motion in (20, 30) and (moving or not CENTRE_WORDS.isdisjoint(words)):
        allowed |= {"i", "j", "k", "r", "p"}
    if motion == 51 and moving:
        allowed |= {"i", "j"}
    if motion == 331 and moving:
        allowed.add("k")
    if motion in CYCLES and moving:
        allowed |= {"r", "l", "p"}
        if motion in (730, 830):
            allowed.add("q")
    if codes.non_modal == 40:
        allowed |= {"p", "x", "u"}
    if codes.non_modal == 100:
        allowed |= {"l", "p", "r", "q"}
    if groups.get(7) in (410, 420, 411, 421) or groups.get(14) == 960:
        allowed.add("d")
    if groups.get(8) in (430, 432):
        allowed.add("h")
    if groups.get(13) == 640:
        allowed |= {"p", "q"}
    if 61 in block.mcodes:
        allowed.add("q")
    return allowed
