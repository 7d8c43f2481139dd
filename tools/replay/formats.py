"""Which files the replay reads, by suffix, without importing python-can (which takes a second to import: a CSV
replay should not pay it)."""

from __future__ import annotations

import contextlib
import gc
import os
import re
import sys
from collections.abc import Iterator
from pathlib import Path

from firmware_model.errors import InputError

#: CAN log formats python-can reads, by suffix
LOG_SUFFIXES = {
    ".log": "candump -L",
    ".asc": "Vector ASC",
    ".blf": "Vector BLF",
    ".mf4": "ASAM MDF 4",
    ".trc": "PEAK PCAN-View TRC",
}


def _a(name: str) -> str:
    """The name with its indefinite article ("an ASAM MDF 4", "a Vector BLF")."""
    return ("an " if name[:1] in "AEIOU" else "a ") + name


def is_can_log(path: str | os.PathLike) -> bool:
    """True for a path whose suffix is a CAN log format (not a CSV run table)."""
    return Path(path).suffix.lower() in LOG_SUFFIXES


def mixed_channels(path: Path, channels) -> str:
    """The sentence for a log that holds the frames of several CAN channels (one J1939 bus is replayed at a time).
    candump names its interfaces (can0); python-can numbers the channels of .asc and .blf files from 0, the files
    from 1: those are named as the file does (a .trc's it reads as the file numbers them: 1, 2)."""
    text = path.suffix.lower() == ".log"
    zero_based = path.suffix.lower() in (".asc", ".blf")
    names = [str(c + 1) if zero_based and isinstance(c, int) else str(c) for c in channels]
    how = f"grep ' {names[0]} ' {path.name} > {names[0]}.log" if text else "export one channel with the logger's tool"
    return (
        f"{path}: holds the frames of {len(names)} CAN channels ({', '.join(names[:4])}); the sensor listens to "
        f"one bus: keep one channel ({how})"
    )


def _gzipped(path: Path) -> bool:
    """Whether the file starts with gzip's magic bytes (a compressed log under a log's name)."""
    try:
        with open(path, "rb") as fh:
            return fh.read(2) == b"\x1f\x8b"
    except OSError:
        return False


def check_log(path: str | os.PathLike) -> Path:
    """The log's path, checked: a known suffix, an existing file, asammdf installed for .mf4; else InputError."""
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".gz" or (p.is_file() and _gzipped(p)):
        from tools.runtable import scada_hint

        if scada_hint(p):
            raise InputError(f"{p}: {scada_hint(p)[2:-1]}")
        inner = Path(p.stem).suffix if suffix == ".gz" else suffix  # short.log.gz holds a .log
        raise InputError(
            f"{p}: the file is gzip-compressed; decompress it first (zcat {p.name} > "
            f"{Path(p.stem).stem if suffix == '.gz' else p.stem}-plain{inner or '.log'})"
        )
    if suffix not in LOG_SUFFIXES:
        raise InputError(
            f"{p}: unknown log suffix {suffix!r}; CAN logs are "
            + ", ".join(f"{s} ({n})" for s, n in LOG_SUFFIXES.items())
            + ", run tables .csv"
        )
    if p.is_dir():
        raise InputError(f"{p}: is a directory, not a log file")
    if not p.is_file():
        raise InputError(f"{p}: the log file does not exist")
    if suffix == ".mf4":
        try:
            import asammdf  # noqa: F401
        except ImportError:
            raise InputError(
                f"{p}: reading .mf4 needs the optional package asammdf; install it with "
                f"pip install 'gearbox-vsensor[mf4]'"
            ) from None
    return p


@contextlib.contextmanager
def quiet_reader_teardown():
    """Silence the teardown of a log reader whose constructor failed: asammdf's ``MDF4.__del__`` raises on a
    half-built object (a truncated .mf4), which Python prints as "Exception ignored" with a traceback around the
    one-sentence error. Only exceptions raised by asammdf's finalisers are dropped; a caller whose reader failed
    collects the half-built objects (gc.collect) inside the block. No collection otherwise: a full collection
    delays the first frame of a real-time replay by tens of milliseconds."""
    previous = sys.unraisablehook

    def hook(unraisable) -> None:
        if not str(getattr(unraisable.object, "__module__", "") or "").startswith("asammdf"):
            previous(unraisable)

    sys.unraisablehook = hook
    try:
        yield
    finally:
        sys.unraisablehook = previous


def read_log(path: str | os.PathLike, damage=None) -> Iterator:
    """The frames of a CAN log in file order (``can.Message``); problems raise InputError naming the file, a
    malformed line or a cut log among them. ``damage`` (tools.replay.lines.LogDamage, from
    ``tools.replay.columns.scan_log``): the log without its malformed lines instead, a BLF log up to its cut."""
    import can

    p = check_log(path)
    strict = damage is None
    if strict:
        cut = truncation(p)
        if cut:
            raise InputError(f"{p}: {cut}")
    failure = None
    with quiet_reader_teardown():
        try:
            reader = can.LogReader(p) if strict or damage.clean is None else damage.text_reader(p.suffix.lower())
        except Exception as exc:  # python-can raises a variety of errors for a broken file
            failure = f"{p}: cannot open it as {_a(LOG_SUFFIXES[p.suffix.lower()])} log: {exc}"
            if p.suffix.lower() == ".mf4" and "seek out of range" in str(exc):
                failure = f"{p}: the MDF 4 log ends before the blocks it refers to (truncated, or still being written)"
        if failure is not None:
            gc.collect()  # the half-built reader's finaliser runs here, silenced
    if failure is not None:  # raised here, not in the handler: the error keeps no half-built reader alive
        raise InputError(failure)
    n = 0
    try:
        with reader:
            first_channel = None
            for msg in reader:
                n += 1
                if msg.channel is not None:
                    if first_channel is None:
                        first_channel = msg.channel
                    elif msg.channel != first_channel:
                        raise InputError(mixed_channels(p, [first_channel, msg.channel]))
                yield msg
    except InputError:
        raise
    except Exception as exc:
        if strict and ends_mid_line(p):
            raise InputError(
                f"{p}: the log ends in the middle of a line at frame {n + 1} (truncated, or still being written)"
            ) from None
        bad = first_bad_candump_line(p) if p.suffix.lower() == ".log" else None
        if bad is not None and bad[1].startswith("\ufeff"):
            raise InputError(
                f"{p}: starts with a UTF-8 byte-order mark, which candump never writes (an editor added it); remove it"
            ) from None
        if bad is not None and any((ord(ch) < 32 and ch not in "\t\r") or ch == "\ufffd" for ch in bad[1]):
            raise InputError(f"{p}: line {bad[0]} holds binary data; this is not a candump -L text log") from None
        if bad is not None:
            raise InputError(
                f"{p}: line {bad[0]} is not a candump -L frame '(time) interface ID#DATA': {bad[1]!r}"
            ) from None
        raise InputError(
            f"{p}: frame {n + 1} cannot be read as {_a(LOG_SUFFIXES[p.suffix.lower()])} log: {exc}"
        ) from None


#: a candump -L frame line as python-can reads it: (time) interface ID#DATA (ID##FLAGS DATA for CAN FD, #R remote)
CANDUMP_LINE = re.compile(r"\s*\(\s*[-+0-9.eE]+\s*\)\s+\S+\s+[0-9A-Fa-f]{1,8}#")


#: what a log's first bytes say it is, and the name it should end with
CONTENT_KINDS = (("a BLF log", ".blf"), ("a candump -L log", ".log"), ("an ASC log", ".asc"))


def content_kind(path: Path) -> tuple[str, str] | None:
    """(what the file's first bytes look like, the suffix that reads it), or None when they look like none of
    CONTENT_KINDS: a log named for another format says what it is instead of 'no CAN frame'."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return None
    if head[:4] == b"LOGG":
        return CONTENT_KINDS[0]
    lines = [ln for ln in head.decode("utf-8", "replace").splitlines()[:20] if ln.strip()]
    if lines and sum(bool(CANDUMP_LINE.match(ln)) for ln in lines) >= max(1, len(lines) // 2):
        return CONTENT_KINDS[1]
    if lines and (lines[0].lower().startswith("date ") or any(ln.lower().startswith("base hex") for ln in lines)):
        return CONTENT_KINDS[2]
    return None


def first_bad_candump_line(path: Path, max_lines: int = 10_000_000) -> tuple[int, str] | None:
    """(line number, text cut to 60 characters) of the first non-empty line of a candump -L log that is not a frame
    line, or None (the error path of read_log: names the line instead of python-can's unpacking error)."""
    with open(path, encoding="utf-8", errors="replace") as fh:
        for i, line in enumerate(fh, start=1):
            if i > max_lines:
                break
            if line.strip() and not CANDUMP_LINE.match(line):
                return i, line.rstrip("\n")[:60]
    return None


def truncation(path: Path) -> str | None:
    """Why ``path`` looks cut short (a truncated copy, a log still being written), or None: a text log whose last
    line is cut, a BLF file shorter than the size its header records (python-can reads both without a word)."""
    if ends_mid_line(path):
        return "the log ends in the middle of a line (truncated, or still being written)"
    if path.suffix.lower() == ".blf" and path.is_file():
        with open(path, "rb") as fh:
            head = fh.read(24)
        if len(head) == 24 and head[:4] == b"LOGG":
            recorded = int.from_bytes(head[16:24], "little")
            size = path.stat().st_size
            if 0 < size < recorded:
                return (
                    f"the BLF log is shorter than its header records ({size} of {recorded} bytes: truncated, or "
                    f"still being written)"
                )
    return None


def ends_mid_line(path: Path) -> bool:
    """Is ``path`` a text log (.log, .asc, .trc) whose last line is cut (a truncated copy, a log still being
    written)?"""
    if path.suffix.lower() not in (".log", ".asc", ".trc") or not path.is_file() or path.stat().st_size == 0:
        return False
    with open(path, "rb") as fh:
        text = b"\0" not in fh.read(4096)  # a binary file is the reader's to refuse
        fh.seek(-1, os.SEEK_END)
        return text and fh.read(1) not in (b"\n", b"\r")
