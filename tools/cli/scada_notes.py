"""The note each command reading SCADA files (replay, fleet, diagnose and calibrate with --columns) prints on the
files' damaged lines: one per file, naming its first lines and why (tools.scada.reader.BadLines), whatever their
share, so a record fitted or replayed without a cut line is never so in silence."""

from __future__ import annotations

import sys


def say_damaged_lines(records, rest: str, quiet: bool = False) -> None:
    """On stderr, a note per file of ``records`` with damaged lines, in the records' order (left out with
    ``quiet``, as the other notes); ``rest`` says what became of the file's other rows (replayed, read)."""
    if quiet:
        return
    for record in records:
        for bad in record.bad_lines:
            print(f"note: {bad.sentence(rest)}", file=sys.stderr)
