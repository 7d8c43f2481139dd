"""Where the tests find the real J1939 truck captures.

They are public captures that this project did not record and does not redistribute. The tests look for them in
``$GVS_REAL_J1939`` (a directory holding the ``*.candump.log`` files), else in the project's development layout
(``shared/data/real-j1939`` beside the checkout). Without them the tests that need them skip and say this.
"""

from __future__ import annotations

import os
from pathlib import Path

#: the captures the tests read, in the directory $GVS_REAL_J1939
CAPTURE_FILES = (
    "normal.candump.log",
    "tsc1.candump.log",
    "fuzz_1ms_ID_and_Data.candump.log",
    "utulsa_logger2_drive.candump.log",
)
SKIP_REASON = (
    "real J1939 captures not found: the repository does not ship these public truck captures (what they "
    "are: docs/can.md, 'Real truck captures'); put " + ", ".join(CAPTURE_FILES) + " in a directory and "
    "run the tests with GVS_REAL_J1939=<that directory>"
)


def real_capture_dir() -> Path | None:
    env = os.environ.get("GVS_REAL_J1939")
    cands = [Path(env)] if env else []
    cands.append(Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real-j1939")
    for c in cands:
        if (c / "normal.candump.log").is_file():
            return c
    return None


#: the real measured gearbox temperatures (ENGIE's La Haute Borne SCADA) are read only from $GVS_REAL_SCADA
SCADA_SKIP_REASON = (
    "real SCADA records not found: the repository does not ship ENGIE's La Haute Borne open data (what it is: "
    "docs/real-data.md, 'Real measured temperatures'); put its turbine_<ID>_<period>_<k>.csv.gz files in a "
    "directory and run the tests with GVS_REAL_SCADA=<that directory>"
)


def real_scada_dir() -> Path | None:
    """$GVS_REAL_SCADA when it names a directory holding SCADA files, else None (no other place is searched: the
    records are read only where they are pointed to)."""
    env = os.environ.get("GVS_REAL_SCADA")
    if env and any(Path(env).glob("*.csv*")):
        return Path(env)
    return None
