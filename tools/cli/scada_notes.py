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


def stuck_sentences(record) -> list[str]:
    """One sentence per channel of ``record`` with readings stuck at one value (tools.scada.clean.STUCK_MIN_S): its
    longest run, when it began, how many more."""
    from datetime import datetime, timezone

    out = []
    t = record.time_s
    for name, runs in record.stuck.items():
        a, b, value = max(runs, key=lambda r: r[1] - r[0])
        ch = record.cmap.channels[name]
        cols = "" if list(ch.columns) == [name] else f" ({', '.join(ch.columns)})"
        since = datetime.fromtimestamp(float(t[a]), tz=timezone.utc).strftime("%Y-%m-%d %H:%M")
        longest = f"{value:g} degC for {(t[b - 1] - t[a]) / 86400.0:.1f} days from {since} UTC"
        if len(runs) > 1:
            days = sum(t[e - 1] - t[s] for s, e, _ in runs) / 86400.0
            what = f"in {len(runs)} runs, {days:.1f} days in all, the longest {longest}"
        else:
            what = longest
        out.append(
            f"{record.unit}: {name}{cols} reads one value to the bit for a day or more {what}: a "
            "stuck sensor or logger, not the gearbox; its readings after each run's first are left out (NaN) of the "
            "estimates' comparison and of every fit"
        )
    return out


def say_stuck_channels(records) -> None:
    """On stderr, a warning per stuck channel of ``records`` (:func:`stuck_sentences`; said even with --quiet: a
    sensor fault, not a note)."""
    for record in records:
        for sentence in stuck_sentences(record):
            print(f"warning: {sentence}", file=sys.stderr)


def say_conflicting_rows(records) -> list[str]:
    """On stderr, a warning per record of ``records`` with rows dropped because they repeat a time stamp with other
    values (tools.scada.reader.ScadaRecord.conflict_sentence; said even with --quiet, as replay says it); returns
    the sentences."""
    said = [s for s in (r.conflict_sentence() for r in records) if s]
    for sentence in said:
        print(f"warning: {sentence}", file=sys.stderr)
    return said
