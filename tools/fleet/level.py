"""The measured oil level of a log: J1939 SPN 124 (TRF1 byte 2), when the truck sends it.

The oil temperature alone does not identify a low oil level (docs/fleet.md, "Fleet health": a 4 L leak moves the
oil by a few tenths of a kelvin, less than the onboard model's own error). Many transmissions have a level sensor
and send its reading in TRF1 (PGN 65272), byte 2: SPN 124, "transmission oil level", the sump's oil volume as a share
of its nominal (maximum required) volume, 0.4 %/bit, 0-100 %. The fleet health (``fleet --diagnose``) reads it beside
the oil temperature: per log the median of the valid readings, which a sloshing sump (driving, braking, grades)
scatters by a few percent frame to frame but barely moves.

What counts as a reading: a 29-bit data frame with a finite time and 8 data bytes (DLC 8) of PGN 65272 from the
configured TRF1 source address (``[can.source_address] TRF1``, else ``[can] transmission_source_address``, as for the
oil temperature), byte 2 at most 250 (0xFA), and the level's measurement status (SPN 3026, byte 8 bits 5-8) 0
"conditions valid" or 15 "not available" (a sender without it). J1939 "error" (0xFE), "not available" (0xFF) and the
reserved 0xFB-0xFD are not readings, nor is a level whose status says the conditions were not valid. A log without a
reading has a NaN level and 0 readings: the level is then not known, which is not the same as low.
"""

from __future__ import annotations

import math
import os
from typing import NamedTuple

import numpy as np

from can_dbc import dbc
from can_dbc.columnar import FrameColumns, frame_reasons, pgn_keys
from can_dbc.j1939 import RAW8_DATA_MAX

#: the DBC's TRF1 level signal (SPN 124) and its measurement status (SPN 3026)
LEVEL_MESSAGE, LEVEL_SIGNAL, STATUS_SIGNAL = "TRF1", "TransOilLevel", "TransOilLevelMeasStatus"
#: the measurement status values under which a level is a reading: 0 conditions valid, 15 not available (a sender
#: without the status); 1-13 (conditions not valid: settling, in gear, oil too cold or hot, moving ...) and 14 (error)
#: are not
STATUS_ACCEPTED = (0, 15)
#: a log's level counts only with at least this many readings (TRF1 is sent every second)
MIN_READINGS = 30


class LogLevel(NamedTuple):
    """The median of a log's valid SPN 124 readings [%] (NaN without readings) and how many there were."""

    level_pct: float
    readings: int


def level_readings(cols: FrameColumns, source_address: int | None) -> np.ndarray:
    """Every valid SPN 124 reading of the frames [%], in file order; ``source_address`` None accepts any source."""
    level = dbc.signal_layout(LEVEL_MESSAGE, LEVEL_SIGNAL, 8)
    status = dbc.signal_layout(LEVEL_MESSAGE, STATUS_SIGNAL, 4)
    ok = frame_reasons(cols) == 0  # the decoder's frame checks, as for the oil temperature
    ok &= (cols.dlc == 8) & (cols.length == 8)
    ok &= pgn_keys(np.where(ok, cols.can_id, 0)) == dbc.message_pgn(LEVEL_MESSAGE)
    if source_address is not None:
        ok &= (cols.can_id & 0xFF) == source_address
    raw = cols.data[:, level.start_bit // 8].astype(np.int64)
    ok &= raw <= RAW8_DATA_MAX
    st = (cols.data[:, status.start_bit // 8].astype(np.int64) >> (status.start_bit % 8)) & 0xF
    ok &= np.isin(st, STATUS_ACCEPTED)
    return raw[ok] * level.scale + level.offset


def log_level(cols: FrameColumns, source_address: int | None) -> LogLevel:
    """The log's level: the median of its readings when it has at least :data:`MIN_READINGS`."""
    x = level_readings(cols, source_address)
    if x.size < MIN_READINGS:
        return LogLevel(math.nan, int(x.size))
    return LogLevel(float(np.median(x)), int(x.size))


def read_log_level(path: str | os.PathLike, source_address: int | None) -> LogLevel:
    """:func:`log_level` of a CAN log file (any format ``replay`` reads)."""
    from tools.replay.columns import read_columns

    return log_level(read_columns(path, strict=False).columns, source_address)  # as the replay read it


__all__ = [
    "LEVEL_MESSAGE",
    "LEVEL_SIGNAL",
    "MIN_READINGS",
    "STATUS_ACCEPTED",
    "STATUS_SIGNAL",
    "LogLevel",
    "level_readings",
    "log_level",
    "read_log_level",
]
