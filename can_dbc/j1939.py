"""SAE J1939 rules that a DBC cannot hold, written once: identifier arithmetic, value ranges, transport protocol.

- Identifiers (J1939-21): a 29-bit CAN identifier is priority (bits 26-28), PGN (bits 8-25: EDP, DP, PF, PS) and
  source address (bits 0-7). For PDU1 PGNs (PF < 240) the PS byte is a destination address and not part of the PGN;
  PDU2 PGNs (PF >= 240) are broadcast and PS belongs to the PGN. :func:`pgn_of`, :func:`source_address`,
  :func:`priority`, :func:`destination_address` take an identifier apart, :func:`can_id_of` builds one,
  :func:`with_source` puts another source address into a DBC frame id, :func:`receive_filter` is a python-can
  filter that matches a PGN only.
- Value ranges (J1939-71): 8-bit data 0..0xFA, 16-bit data 0..0xFAFF, then indicator/reserved, error (0xFE, 0xFExx)
  and not available (0xFF, 0xFFxx): :func:`raw_reason`.
- Transport protocol (J1939-21 TP.BAM), EC1 (J1939-71 PGN 65251) and RC (PGN 65249), reassembled from it: the
  constants the decoder and the log synthesis share. The TP.CM and TP.DT PGNs themselves are read from the DBC
  (``can_dbc.dbc``).
"""

from __future__ import annotations

from can_dbc.errors import ConfigError, DecodeError

#: largest 29-bit identifier and 18-bit PGN
ID_MAX = 0x1FFFFFFF
PGN_MAX = 0x3FFFF
#: PDU format at and above which a PGN is PDU2 (broadcast; its PS byte belongs to the PGN)
PDU2_MIN_PF = 240
#: the global destination address (BAM transfers are sent to it) and the null address
GLOBAL_ADDRESS = 0xFF
NULL_ADDRESS = 0xFE
#: highest priority value (0 is the most urgent)
PRIORITY_MAX = 7
DEFAULT_PRIORITY = 6

#: J1939-71 8-bit ranges: data 0x00-0xFA, then indicator/reserved, error 0xFE, not available 0xFF
RAW8_DATA_MAX = 0xFA
RAW8_ERROR = 0xFE
RAW8_NOT_AVAILABLE = 0xFF
#: J1939-71 16-bit ranges: data 0x0000-0xFAFF, then indicator/reserved, error 0xFExx, not available 0xFFxx
RAW16_DATA_MAX = 0xFAFF
RAW16_ERROR_MIN = 0xFE00
RAW16_NOT_AVAILABLE_MIN = 0xFF00
RAW16_NOT_AVAILABLE = 0xFFFF

#: J1939-21 TP: BAM control byte, receive timeout T1, largest transfer, data bytes per TP.DT packet
TP_BAM_CONTROL = 32
TP_TIMEOUT_S = 0.750
TP_MAX_SIZE_BYTES = 1785
TP_DT_DATA_BYTES = 7
#: EC1 Engine Configuration 1 (J1939-71, longer than 8 bytes: arrives by TP.BAM); SPN 544 engine reference torque
#: in bytes 20-21 (1-based), 1 Nm/bit
EC1_PGN = 65251
EC1_REF_TORQUE_BYTE0 = 19  # 0-based index of byte 20
EC1_MIN_SIZE_BYTES = 21
#: RC Retarder Configuration (J1939-71, 19 bytes: by TP.BAM, about every 5 s, from the retarder); SPN 556 reference
#: retarder torque in bytes 17-18 (1-based), 1 Nm/bit: the torque ERC1's actual retarder percent torque refers to
RC_PGN = 65249
RC_REF_TORQUE_BYTE0 = 16  # 0-based index of byte 17
RC_MIN_SIZE_BYTES = 18


def check_id(can_id: int) -> None:
    """DecodeError unless ``can_id`` is a 29-bit identifier."""
    if not 0 <= can_id <= ID_MAX:
        raise DecodeError(f"can_id = {can_id:#x} is outside the 29-bit range 0..0x1FFFFFFF")


def is_pdu1(pgn: int) -> bool:
    """True for a PDU1 PGN (PF < 240): its PS byte is a destination address."""
    return (pgn >> 8) & 0xFF < PDU2_MIN_PF


def source_key(can_id: int) -> int:
    """The source address of an identifier already known to be 29-bit (no check): :func:`source_address` for the
    per-frame paths."""
    return can_id & 0xFF


def pdu_specific(can_id: int) -> int:
    """The PS byte of an identifier already known to be 29-bit (no check): a PDU1 destination, a PDU2 group
    extension."""
    return (can_id >> 8) & 0xFF


def pgn_key(can_id: int) -> int:
    """The PGN of an identifier already known to be 29-bit (no check): :func:`pgn_of` for the per-frame paths."""
    pgn = (can_id >> 8) & PGN_MAX
    if (pgn >> 8) & 0xFF < PDU2_MIN_PF:
        pgn &= 0x3FF00
    return pgn


def pgn_of(can_id: int) -> int:
    """PGN of a 29-bit J1939 identifier: EDP, DP, PF and, for PDU2 (PF >= 240), PS; a PDU1 PS is a destination."""
    check_id(can_id)
    return pgn_key(can_id)


def source_address(can_id: int) -> int:
    """Source address: the last byte of the identifier."""
    check_id(can_id)
    return source_key(can_id)


def priority(can_id: int) -> int:
    """Priority 0 (highest) .. 7: identifier bits 26-28."""
    check_id(can_id)
    return (can_id >> 26) & PRIORITY_MAX


def destination_address(can_id: int) -> int:
    """Destination of a PDU1 identifier (its PS byte); 0xFF (global) for PDU2."""
    check_id(can_id)
    return pdu_specific(can_id) if is_pdu1((can_id >> 8) & PGN_MAX) else GLOBAL_ADDRESS


def can_id_of(pgn: int, source: int, prio: int = DEFAULT_PRIORITY, destination: int = GLOBAL_ADDRESS) -> int:
    """29-bit identifier of a PGN sent by ``source``; ``destination`` goes into PS for PDU1 PGNs."""
    if not 0 <= pgn <= PGN_MAX:
        raise DecodeError(f"pgn = {pgn} is outside 0..0x3FFFF")
    for field, value in (("source", source), ("destination", destination)):
        if not 0 <= value <= 0xFF:
            raise DecodeError(f"{field} = {value} is outside the address range 0..255")
    if not 0 <= prio <= PRIORITY_MAX:
        raise DecodeError(f"prio = {prio} is outside the J1939 priority range 0..7")
    if is_pdu1(pgn):
        if pgn & 0xFF:
            raise DecodeError(f"pgn = {pgn:#x} is PDU1 (PF < 240) and must have PS = 0")
        pgn |= destination
    return (prio << 26) | (pgn << 8) | source


def with_source(can_id: int, source: int) -> int:
    """``can_id`` (e.g. a DBC frame id) sent by ``source`` instead: its last byte replaced."""
    check_id(can_id)
    if not 0 <= source <= 0xFF:
        raise DecodeError(f"source = {source} is outside the address range 0..255")
    return (can_id & ~0xFF) | source


def receive_filter(pgn: int) -> dict:
    """A python-can receive filter that passes every frame of ``pgn``: the mask covers the PGN bits only (no
    priority, no source address; for a PDU1 PGN no destination either)."""
    return {"can_id": pgn << 8, "can_mask": 0x3FF0000 if is_pdu1(pgn) else 0x3FFFF00, "extended": True}


def check_source_address(field: str, value: object) -> int:
    """A configurable source address: 0..253 (254 is the null address, 255 the global address); else ConfigError."""
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < NULL_ADDRESS:
        raise ConfigError(f"{field} = {value!r} is not a J1939 source address 0..253")
    return value


def raw_reason(raw: int, nbytes: int) -> str | None:
    """J1939-71 classification of a raw value: None (data), 'out_of_range', 'error_value' or 'not_available'."""
    if nbytes == 1:
        if raw <= RAW8_DATA_MAX:
            return None
        if raw == RAW8_ERROR:
            return "error_value"
        if raw == RAW8_NOT_AVAILABLE:
            return "not_available"
        return "out_of_range"  # 0xFB indicator (gear: park), 0xFC-0xFD reserved
    if raw <= RAW16_DATA_MAX:
        return None
    if raw >= RAW16_NOT_AVAILABLE_MIN:
        return "not_available"
    if raw >= RAW16_ERROR_MIN:
        return "error_value"
    return "out_of_range"  # 0xFB00-0xFBFF indicator, 0xFC00-0xFDFF reserved
