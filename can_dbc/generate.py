"""A DBC for any gearbox: the sensor's frames generated from its published components (``gearbox-vsensor export-dbc``).

Input: the published component ids in their CAN order and, optionally, what each one is in a few words (the signal
comments). ``can_dbc`` does not read gearbox descriptions: the caller (tools/cli/export_dbc.py) passes plain data.

Frame layout for N published components (docs/can.md, "A DBC per gearbox"): 16-bit values four to a frame, 2-bit
warning levels 32 to a frame, all J1939 Proprietary B PGNs allotted in this order from 0xFF40 upwards:
GBX_TEMP_1..k, GBX_WARN (GBX_WARN_1..w when N > 32), GBX_TTL_1..k, GBX_STATUS, RIG_TC_1..k, with k = ceil(N / 4)
and w = ceil(N / 32); DM1 keeps its standard PGN 0xFECA. For the GRS905's 28 components this is the shipped
gearbox_vsensor.dbc, byte for byte (0xFF40-0xFF4F and 0xFF50-0xFF56). The PGNs end at 0xFFFF, so at most
:data:`MAX_COMPONENTS` components fit.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from typing import NamedTuple

from can_dbc import dbc_parts
from can_dbc.errors import CanDbcError
from can_dbc.j1939 import DEFAULT_PRIORITY

#: the first and last PGN of the sensor's own frames (Proprietary B, PDU2: broadcast)
PGN_FIRST = 0xFF40
PGN_LAST = 0xFFFF
#: DM1 (J1939-73), the sensor's default source address and the rig logger's
DM1_PGN = 0xFECA
SENSOR_SOURCE = 0xE5
RIG_SOURCE = 0xF0
#: 16-bit signals per 8-byte frame, 2-bit warning levels per frame
PER_FRAME = 4
LEVELS_PER_FRAME = 32
#: SPN of the first published component (proprietary SPN range 520192..524287), the others follow in order
SPN_FIRST = 520192
#: the longest DBC name most tools accept (Vector CANdb++: 32 characters); the longest prefix is "TTL_"
NAME_MAX = 32
#: a component id a DBC string attribute can hold (no quote, no whitespace)
_ID = re.compile(r"[^\s\"\\]+")


class GenerateError(CanDbcError):
    """The published components cannot be laid out as a DBC (too many, a bad id, two ids with one signal name)."""


class Frame(NamedTuple):
    """One generated message: its name, PGN and the component ids of its signals in payload order."""

    name: str
    pgn: int
    components: tuple[str, ...]


class Layout(NamedTuple):
    """The per-component frames of a DBC and GBX_STATUS's PGN."""

    temp: tuple[Frame, ...]
    warn: tuple[Frame, ...]
    ttl: tuple[Frame, ...]
    status_pgn: int
    rig: tuple[Frame, ...]


def frames_needed(n: int) -> int:
    """How many Proprietary B PGNs the layout of ``n`` components takes."""
    return 3 * math.ceil(n / PER_FRAME) + math.ceil(n / LEVELS_PER_FRAME) + 1


#: the most published components whose frames fit in PGN_FIRST..PGN_LAST (244)
MAX_COMPONENTS = max(
    n for n in range(1, PER_FRAME * (PGN_LAST - PGN_FIRST)) if frames_needed(n) <= PGN_LAST - PGN_FIRST + 1
)


def _chunks(ids: tuple[str, ...], size: int) -> list[tuple[str, ...]]:
    return [ids[i : i + size] for i in range(0, len(ids), size)]


def frame_layout(components: Sequence[str]) -> Layout:
    """The frames and PGNs of ``components`` (the published ids in order); GenerateError when they do not fit."""
    ids = tuple(components)
    if not ids:
        raise GenerateError("no published components: a DBC needs at least one")
    if len(ids) > MAX_COMPONENTS:
        raise GenerateError(
            f"{len(ids)} published components need {frames_needed(len(ids))} PGNs; the sensor's Proprietary B range "
            f"0x{PGN_FIRST:04X}-0x{PGN_LAST:04X} holds {PGN_LAST - PGN_FIRST + 1}, so at most {MAX_COMPONENTS} fit"
        )
    pgn = iter(range(PGN_FIRST, PGN_LAST + 1))
    quads, levels = _chunks(ids, PER_FRAME), _chunks(ids, LEVELS_PER_FRAME)
    temp = tuple(Frame(f"GBX_TEMP_{i + 1}", next(pgn), c) for i, c in enumerate(quads))
    if len(levels) == 1:
        warn = (Frame("GBX_WARN", next(pgn), levels[0]),)
    else:
        warn = tuple(Frame(f"GBX_WARN_{i + 1}", next(pgn), c) for i, c in enumerate(levels))
    ttl = tuple(Frame(f"GBX_TTL_{i + 1}", next(pgn), c) for i, c in enumerate(quads))
    status_pgn = next(pgn)
    rig = tuple(Frame(f"RIG_TC_{i + 1}", next(pgn), c) for i, c in enumerate(quads))
    return Layout(temp, warn, ttl, status_pgn, rig)


def frame_id(pgn: int, source: int) -> int:
    """The DBC frame id (bit 31 set: extended) of a priority-6 PDU2 PGN sent by ``source``."""
    return 0x8000_0000 | DEFAULT_PRIORITY << 26 | pgn << 8 | source


def signal_names(components: Sequence[str]) -> dict[str, str]:
    """Component id -> the suffix of its signal names (``LI.teeth`` -> ``LI_teeth``: any character a DBC name cannot
    hold becomes ``_``); GenerateError for an id a DBC cannot carry or two ids with one suffix."""
    out: dict[str, str] = {}
    seen: dict[str, str] = {}
    for c in components:
        if not _ID.fullmatch(c):
            raise GenerateError(f"published component {c!r} cannot be a DBC attribute value (quote or white space)")
        name = re.sub(r"[^A-Za-z0-9_]", "_", c)
        if len("TTL_" + name) > NAME_MAX:
            raise GenerateError(
                f"published component {c!r} makes the signal name TTL_{name}, over {NAME_MAX} characters"
            )
        if name in seen:
            raise GenerateError(f"published components {seen[name]!r} and {c!r} both make the signal name T_{name}")
        seen[name] = c
        out[c] = name
    return out


def _pgn_text(pgn: int) -> str:
    return f"{pgn} (0x{pgn:04X})"


class _Writer:
    """The DBC's sections, filled frame by frame and joined in file order."""

    def __init__(self, components: Sequence[str], meanings: Mapping[str, str | None]) -> None:
        self.layout = frame_layout(components)
        self.names = signal_names(components)
        self.index = {c: i for i, c in enumerate(components)}
        self.meanings = meanings
        self.messages: list[str] = []
        self.comments: list[str] = []
        self.frame_attributes: list[str] = []
        self.spns: list[str] = []
        self.component_ids: list[str] = []
        self.values: list[str] = []

    def describe(self, component: str) -> str:
        words = self.meanings.get(component)
        return f"{component} ({words.replace(chr(34), chr(39))})" if words else component

    def frame(self, frame: Frame, source: int, cycle_ms: int, comment: str) -> int:
        can_id = frame_id(frame.pgn, source)
        sender = "RigLogger" if source == RIG_SOURCE else "GearboxVSensor"
        self.messages.append(f"BO_ {can_id} {frame.name}: 8 {sender}")
        self.comments.append(f'CM_ BO_ {can_id} "{comment}";')
        self.frame_attributes += [
            f'BA_ "VFrameFormat" BO_ {can_id} 3;',
            f'BA_ "GenMsgCycleTime" BO_ {can_id} {cycle_ms};',
        ]
        return can_id

    def signals(self, frame: Frame, can_id: int, kind: str, comment: str, values: str) -> None:
        """One signal per component of ``frame``; ``kind``: T, TC (16-bit degC), TTL (16-bit s) or W (2-bit)."""
        bits = 2 if kind == "W" else 16
        scaling = {
            "W": '(1,0) [0|3] ""',
            "TTL": '(1,0) [0|64255] "s"',
        }.get(kind, '(0.03125,-273) [-273|1734.96875] "degC"')
        receiver = "GearboxVSensor" if kind == "TC" else "Vector__XXX"
        for k, c in enumerate(frame.components):
            name = f"{kind}_{self.names[c]}"
            self.messages.append(f" SG_ {name} : {k * bits}|{bits}@1+ {scaling} {receiver}")
            self.comments.append(f'CM_ SG_ {can_id} {name} "{comment.format(self.describe(c))}";')
            if kind == "T":
                self.spns.append(f'BA_ "SPN" SG_ {can_id} {name} {SPN_FIRST + self.index[c]};')
            self.component_ids.append(f'BA_ "ComponentId" SG_ {can_id} {name} "{c}";')
            self.values.append(f"VAL_ {can_id} {name} {values} ;")
        self.messages.append("")


_NA = '65535 "not available"'


def _temperatures(w: _Writer) -> None:
    for f in w.layout.temp:
        can_id = w.frame(
            f,
            SENSOR_SOURCE,
            100,
            f"Estimated component temperatures {', '.join(f.components)}; J1939 Proprietary B PGN {_pgn_text(f.pgn)}, "
            f"priority 6, default source address 0xE5 (configurable), 100 ms.",
        )
        w.signals(f, can_id, "T", "Estimated temperature of {}; 0xFFFF not available (no valid estimate).", _NA)


def _warnings(w: _Writer) -> None:
    start = 0
    for f in w.layout.warn:
        part = "" if len(w.layout.warn) == 1 else f" (published components {start + 1}-{start + len(f.components)})"
        start += len(f.components)
        used = 2 * len(f.components)
        fill = f" Bits {used + 1}-64 are sent as 1." if used < 64 else ""
        can_id = w.frame(
            f,
            SENSOR_SOURCE,
            100,
            f"Warning level per published component, 2 bits each in published order{part}; J1939 Proprietary B PGN "
            f"{_pgn_text(f.pgn)}, priority 6, default source address 0xE5, 100 ms.{fill}",
        )
        w.signals(
            f,
            can_id,
            "W",
            "Warning level of {}: 0 normal, 1 warning, 2 critical, 3 not available.",
            '0 "normal" 1 "warning" 2 "critical" 3 "not available"',
        )


def _times_to_limit(w: _Writer) -> None:
    for f in w.layout.ttl:
        can_id = w.frame(
            f,
            SENSOR_SOURCE,
            100,
            f"Time until the warning limit is reached, {', '.join(f.components)}; J1939 Proprietary B PGN "
            f"{_pgn_text(f.pgn)}, priority 6, default source address 0xE5, 100 ms. 0..64254 s data, 64255 (0xFAFF) "
            f"never reached within the prediction horizon, 65535 (0xFFFF) not available.",
        )
        w.signals(
            f,
            can_id,
            "TTL",
            "Time until {} reaches its warning limit; 0 = at or above it now; 64255 never; 65535 not available.",
            '64255 "never" 65535 "not available"',
        )


def _status_and_dm1(w: _Writer) -> None:
    status_id = frame_id(w.layout.status_pgn, SENSOR_SOURCE)
    dm1_id = frame_id(DM1_PGN, SENSOR_SOURCE)
    fill = {"status_id": status_id, "status_pgn": _pgn_text(w.layout.status_pgn)}
    w.messages += [line.format(**fill) for line in dbc_parts.STATUS_MESSAGES]
    w.comments += [line.format(**fill) for line in dbc_parts.STATUS_COMMENTS]
    w.values += [line.format(**fill) for line in dbc_parts.STATUS_VALUES]
    for can_id, cycle_ms in ((status_id, 100), (dm1_id, 1000)):
        w.frame_attributes += [f'BA_ "VFrameFormat" BO_ {can_id} 3;', f'BA_ "GenMsgCycleTime" BO_ {can_id} {cycle_ms};']


def _rig(w: _Writer) -> None:
    for f in w.layout.rig:
        can_id = w.frame(
            f,
            RIG_SOURCE,
            100,
            f"Test-rig thermocouples (true component temperatures) {', '.join(f.components)}; J1939 Proprietary B PGN "
            f"{_pgn_text(f.pgn)}, priority 6, source address 0xF0 rig logger, 100 ms.",
        )
        w.signals(f, can_id, "TC", "Measured temperature of {}; 0xFFFF not available (no thermocouple or broken).", _NA)


def _database_comment(layout: Layout) -> str:
    rig = (
        f"0x{layout.rig[0].pgn:04X}-0x{layout.rig[-1].pgn:04X}" if len(layout.rig) > 1 else f"0x{layout.rig[0].pgn:04X}"
    )
    return (
        'CM_ "Gearbox virtual temperature sensor: J1939 inputs it decodes, its own outputs (Proprietary B PGNs '
        f"0x{PGN_FIRST:04X}-0x{layout.status_pgn:04X} and DM1), and test-rig thermocouple frames ({rig}). "
        'See docs/can.md.";'
    )


def generate_dbc(components: Sequence[str], meanings: Mapping[str, str | None] | None = None) -> str:
    """The DBC text for the published ``components`` (ids in CAN order); ``meanings``: component id -> what it is in a
    few words, shown in the signal comments (``LI.teeth (teeth of the low-split wheel, input shaft)``), a missing or
    empty one leaves the id alone. GenerateError when the components cannot be laid out (:func:`frame_layout`,
    :func:`signal_names`)."""
    w = _Writer(components, meanings or {})
    _temperatures(w)
    _warnings(w)
    _times_to_limit(w)
    _status_and_dm1(w)
    _rig(w)
    lines = [*dbc_parts.HEAD, *w.messages, "", _database_comment(w.layout), *dbc_parts.INPUT_COMMENTS, *w.comments]
    lines += [*dbc_parts.DEFINITIONS, *w.frame_attributes, *dbc_parts.INPUT_SPNS, *w.spns, *w.component_ids]
    lines += [*dbc_parts.INPUT_VALUES, *w.values, "", ""]  # the file ends in a blank line
    return "\n".join(lines)
