"""Which files the replay reads, by suffix, without importing python-can (which takes a second to import: a CSV
replay should not pay it)."""
from __future__ import annotations

import os
from pathlib import Path

#: CAN log formats python-can reads, by suffix
LOG_SUFFIXES = {".log": "candump -L", ".asc": "Vector ASC", ".blf": "Vector BLF", ".mf4": "ASAM MDF 4"}


def is_can_log(path: str | os.PathLike) -> bool:
    """True for a path whose suffix is a CAN log format (not a CSV run table)."""
    return Path(path).suffix.lower() in LOG_SUFFIXES
