"""SCADA files (``.csv``, ``.csv.gz``) -> one record per unit (turbine), its gaps kept (docs/real-data.md).

Each file is read with the csv module through its column map (:mod:`tools.scada.columns`); only the map's columns
are converted (numpy float64; an empty cell, or a marker such as ``NA``, ``-``, ``#N/A``, NaN). Time stamps with a
UTC offset become UTC seconds; a stamp without one, or one that does not parse, drops its row (``bad_time``), as
does a line with the wrong number of fields (``bad_line``); the first such lines of each file, and those with a
value that is no number, are kept by number and reason (:class:`BadLines`) for the note every command reading SCADA
prints (tools/cli/scada_notes.py). The files of one unit are joined in time order: a row earlier than one before it
in its file is counted (``out_of_order``) and sorted into place; the rows of a repeated time stamp that agree are
one row (``duplicate_time``), and those that differ are all dropped (``conflicting_time``): the record is the same
whatever order the files are given in. A step longer than 1.5 periods starts a new stretch (``gap``): the record
keeps the true times, no row is invented, and a model resets its state at each stretch's first row. The values'
rules (missing, implausible, spikes, standstill, negative power) are :mod:`tools.scada.clean`'s.

A file that is not such a SCADA file (binary, a damaged gzip, a header without the map's columns, no rows) raises an
:class:`~firmware_model.errors.InputError` with one sentence naming the file.
"""

from __future__ import annotations

import csv
import gzip
import io
import math
import zlib
from collections.abc import Iterable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from firmware_model.errors import InputError
from tools.scada.clean import REASONS, clean_values
from tools.scada.columns import ColumnMap, load_column_map

#: a step longer than this many periods is a gap
GAP_PERIODS = 1.5
#: the damaged lines of a file kept by number and reason (the rest only counted)
SHOWN_LINES = 5
#: time stamps of kind "seconds" whose median lies beyond this (the year 5138) are milliseconds
MS_STAMP_MIN_S = 1e11


@dataclass
class BadLines:
    """A file's damaged lines: ``total`` lines dropped or holding a value that is no number, the first SHOWN_LINES
    of them as (line number in the file, the header being line 1; what was wrong, in words)."""

    path: Path
    total: int = 0
    first: list = field(default_factory=list)

    def add(self, line: int, why: str) -> None:
        self.total += 1
        if len(self.first) < SHOWN_LINES:
            self.first.append((line, why))

    def sentence(self, rest: str = "replayed") -> str:
        """One sentence: the file, its first damaged lines and why, how many more, and what became of its other
        rows (``rest``: replayed, read)."""
        more = f", and {self.total - len(self.first)} more" if self.total > len(self.first) else ""
        lines = "; ".join(f"line {n} {why}" for n, why in self.first)
        return f"{self.path.name}: {lines}{more}; the rest is {rest}"


@dataclass
class FileRows:
    """One file's rows that have a time: UTC seconds, the unit of each row, the map's columns as float arrays."""

    path: Path
    time_s: np.ndarray
    unit: np.ndarray
    raw: dict[str, np.ndarray]
    counts: dict[str, int]
    bad: BadLines | None = None


@dataclass
class ScadaRecord:
    """One unit's rows in time order. ``stretch`` numbers the gap-free stretches (0, 1, ...) row by row; ``values``
        holds every input and measured channel of the map after the rules of :mod:`tools.scada.clean` (a rejected value
        is NaN); ``counts`` the rows or values each reason (REASONS) touched, ``by_channel`` the same per channel;
        ``bad_lines`` each file's damaged lines by number (files without any left out); ``stuck`` each channel's runs of
    readings stuck at one value (tools.scada.clean.STUCK_MIN_S)."""

    unit: str
    time_s: np.ndarray
    stretch: np.ndarray
    values: dict[str, np.ndarray]
    counts: dict[str, int]
    by_channel: dict[str, dict[str, int]]
    cmap: ColumnMap
    files: list[Path] = field(default_factory=list)
    bad_lines: list[BadLines] = field(default_factory=list)
    stuck: dict = field(default_factory=dict)  # channel -> its stuck runs: (start row, stop row, value)
    conflicts: dict = field(default_factory=dict)  # file -> its rows dropped as conflicting_time

    def conflict_sentence(self) -> str | None:
        """One sentence on the rows dropped because they repeat a time stamp with other values
        (``conflicting_time``): how many, the files, why; None when there are none."""
        n = self.counts.get("conflicting_time", 0)
        if not n:
            return None
        names = sorted(p.name for p in self.conflicts)
        where = "another file" if len(names) > 1 else "their file"
        return (
            f"{self.unit}: {n} rows repeat a time stamp of {where} with different values ({', '.join(names)}): none "
            "of them kept: two records of one unit disagree (another unit's rows under its name, or two exports that "
            "differ), and which holds its readings cannot be told"
        )

    @property
    def n(self) -> int:
        return int(self.time_s.size)

    @property
    def n_stretches(self) -> int:
        return int(self.stretch[-1]) + 1 if self.n else 0

    def stretch_bounds(self) -> list[tuple[int, int]]:
        """[start, stop) row indices of each gap-free stretch."""
        starts = np.flatnonzero(np.diff(self.stretch, prepend=-1) != 0)
        return list(zip(starts.tolist(), np.append(starts[1:], self.n).tolist()))

    def select(self, mask: np.ndarray) -> ScadaRecord:
        """The rows where ``mask`` holds (stretches renumbered; a removed row between two kept ones is a gap). The
        counters stay those of the whole record as read."""
        idx = np.flatnonzero(mask)
        brk = np.diff(idx, prepend=-2) != 1
        brk |= np.diff(self.stretch[idx], prepend=-1) != 0
        return ScadaRecord(
            unit=self.unit,
            time_s=self.time_s[idx],
            stretch=np.cumsum(brk) - 1,
            values={k: v[idx] for k, v in self.values.items()},
            counts=dict(self.counts),
            by_channel={k: dict(v) for k, v in self.by_channel.items()},
            cmap=self.cmap,
            files=list(self.files),
            bad_lines=list(self.bad_lines),
            conflicts=dict(self.conflicts),
            stuck={},  # (row numbers of the whole record; its values are NaN already)
        )


def open_text(path: Path, counts: dict | None = None, encoding: str = "utf-8-sig"):
    """The file as text: gzip by its magic bytes, else plain; a binary or damaged file raises InputError. Bytes that
    are not UTF-8 (a name or a unit in Latin-1, a logger's stray byte) become U+FFFD, their lines counted in
    ``counts["bad_bytes"]``: a cell with one does not parse and is dropped and counted like any bad cell."""
    if not path.is_file():
        raise InputError(f"{path}: no such file")
    data = path.read_bytes()
    cut = False
    if data[:2] == b"\x1f\x8b":
        data, cut = _gunzip(path, data)
    if b"\x00" in data[:4096]:
        raise InputError(f"{path.name}: not a SCADA CSV file (binary content)")
    if encoding != "utf-8-sig":
        return _Text(data.decode(encoding, errors="replace"), cut)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError:
        text = data.decode("utf-8-sig", errors="replace")
        if text.count("\ufffd") > 0.05 * len(text):  # text has a stray byte here and there, binary many more
            raise InputError(f"{path.name}: not a SCADA CSV file (binary content, not UTF-8 text)") from None
        if counts is not None:
            counts["bad_bytes"] += sum("\ufffd" in line for line in text.splitlines())
    return _Text(text, cut)


class _Text(io.StringIO):
    """A file's text; ``cut``: a gzip that ends mid-way, read up to its last whole line (the rest is lost)."""

    def __init__(self, text: str, cut: bool = False):
        super().__init__(text, newline="")
        self.cut = cut


#: the gzip chunk size read at a time: a damaged stream keeps what decompressed before the damage
GZIP_CHUNK = 1 << 16


def _gunzip(path: Path, data: bytes) -> tuple[bytes, bool]:
    """(the decompressed bytes, whether the stream ends mid-way). A gzip cut short (a copy interrupted, a logger
    stopped mid-write) or damaged after its start keeps its whole lines before the cut: they were dropped with the
    file before (a reviewer's trial), the one line cut in two would be a wrong number. InputError when nothing
    decompresses."""
    z = zlib.decompressobj(wbits=31)
    out, cut = [], False
    try:
        for i in range(0, len(data), GZIP_CHUNK):
            out.append(z.decompress(data[i : i + GZIP_CHUNK]))
            if z.eof:  # (a second member or trailing bytes: gzip.decompress reads on; this reads the first)
                break
        cut = not z.eof
    except zlib.error:
        cut = True
    text = b"".join(out)
    if z.eof and z.unused_data[:2] == b"\x1f\x8b":  # concatenated members: the whole file, as gzip reads it
        try:
            return gzip.decompress(data), False
        except (OSError, EOFError, zlib.error):
            cut = True
    if cut:
        text = text[: text.rfind(b"\n") + 1]  # the whole lines only
    if not text:
        raise InputError(f"{path.name}: a damaged gzip file (it does not decompress)")
    return text, cut


def parse_time(stamp: str, kind: str, fmt: str | None = None, zone=None, fold: int = 0) -> float | None:
    """UTC seconds of a time stamp, or None when it does not parse (or has no UTC offset where one is needed);
    ``fmt``: a strptime format (else ISO 8601); ``zone``: a tzinfo the stamps without an offset are local time of,
    ``fold`` 1 for the second of a repeated hour."""
    if kind in ("seconds", "milliseconds"):
        try:
            t = float(stamp)
        except ValueError:
            return None
        return (t / 1e3 if kind == "milliseconds" else t) if np.isfinite(t) else None
    try:
        text = stamp.strip()
        dt = datetime.strptime(text, fmt) if fmt else datetime.fromisoformat(text.replace("Z", "+00:00"))
    except ValueError:
        return None
    if dt.utcoffset() is None and kind == "iso8601_utc":  # the map says its stamps are UTC
        dt = dt.replace(tzinfo=timezone.utc)
    elif dt.utcoffset() is None and zone is not None:  # local time of the map's zone
        dt = dt.replace(tzinfo=zone, fold=fold)
    return dt.timestamp() if dt.utcoffset() is not None else None


class LocalClock:
    """A file's stamps, row after row, in UTC seconds: with a map's time.zone, an ambiguous local time (the repeated
    hour of the autumn change) is read as its second pass (fold 1) once the first pass has gone by (rows in time
    order, as loggers write them); with time.at = "start", a stamp is moved to its period's end."""

    def __init__(self, cmap: ColumnMap):
        from zoneinfo import ZoneInfo

        self.cmap = cmap
        self.zone = ZoneInfo(cmap.time_zone) if cmap.time_zone else None
        self.last = -math.inf  # the last stamp read [UTC s]

    def __call__(self, stamp: str) -> float | None:
        c = self.cmap
        t = parse_time(stamp, c.time_kind, c.time_format, self.zone)
        if t is not None and self.zone is not None and t <= self.last:
            second = parse_time(stamp, c.time_kind, c.time_format, self.zone, fold=1)
            t = second if second is not None and second > t else t
        if t is None:
            return None
        self.last = max(self.last, t)
        return t + c.period_s if c.time_at == "start" else t


#: cells that exports write for "no value" (lower case, stripped): read as an empty cell, missing
MISSING_MARKERS = frozenset({"na", "n/a", "#n/a", "-", "--", "null", "none", "nil", "?"})


def _number(cell: str) -> float:
    try:
        return float(cell) if cell.strip() else np.nan
    except ValueError:
        if cell.strip().lower() in MISSING_MARKERS:
            return np.nan
        return np.inf  # marked unparsable; clean_values counts it as implausible


def _decimal_comma(cell: str) -> float:
    """A number of a ';'-separated export: a decimal comma, and dots as thousands separators ('1.001.690,5' is
    1001690.5: read as 1.001690 it was an implausible power; a new user's review)."""
    if "," in cell:
        cell = cell.replace(".", "").replace(",", ".")
    elif cell.count(".") > 1:
        cell = cell.replace(".", "")
    return _number(cell)


def _text_of(path: Path, cmap: ColumnMap, counts: dict):
    """The file as text: UTF-8, or Windows-1252 when the header is not UTF-8 and only that reading holds the map's
    columns ('Au\xdfen [\xb0C]' written by Windows: the export's encoding throughout)."""
    text = open_text(path, counts)
    first = text.readline()
    text.seek(0)
    if "\ufffd" in first and not all(c in first for c in cmap.columns):
        latin = open_text(path, None, "cp1252")
        header = latin.readline()
        if all(c in header for c in cmap.columns):
            counts["bad_bytes"] = 0
            latin.seek(0)
            return latin
    return text


def _header_columns(path: Path, header: list | None, cmap: ColumnMap) -> list[str]:
    """The map's measured columns the header lacks (their readings are missing from this file: a sensor fitted
    later, an export of fewer columns); InputError when it lacks an input's or the time's (no file of the map)."""
    if not header:
        raise InputError(f"{path.name}: empty, not a SCADA file of the column map {cmap.name}")
    lacking = [c for c in cmap.columns if c not in header]
    inputs = {c for ch in cmap.inputs.values() for c in ch.columns} | {cmap.time_column, cmap.unit_column}
    needed = [c for c in lacking if c in inputs]
    if needed:
        # the columns all in one field: another separator (a tab-separated export), not other columns
        one = len(header) == 1 and "\t" in header[0] and any(c in header[0] for c in cmap.columns)
        raise InputError(
            f"{path.name}: not a SCADA file of the column map {cmap.name}: its header lacks the column(s) "
            f"{', '.join(needed[:4])}{' ...' if len(needed) > 4 else ''}"
            + (
                "; its header is one field holding tabs: give the file separated by ',' or ';' (the separators read)"
                if one
                else ""
            )
        )
    return [c for c in lacking if c not in inputs]


def read_file(path: str | Path, cmap: ColumnMap) -> FileRows:
    """One file's rows (see the module's docstring for what is dropped and counted)."""
    path = Path(path)
    counts = dict.fromkeys(REASONS, 0)
    text = _text_of(path, cmap, counts)
    # ENGIE's own export separates with ";" (and may write decimal commas): the same columns, read as they are; the
    # separator whose header fields hold more of the map's columns (a name may hold a comma: 'Aussen [degC, avg]')
    semicolon = _semicolon(text.readline(), cmap)
    text.seek(0)
    reader = csv.reader(text, delimiter=";" if semicolon else ",")
    number = _decimal_comma if semicolon else _number
    header = [h.strip() for h in next(reader, None) or []]
    optional = _header_columns(path, header, cmap)
    again = list(header)  # a repeated header line (files joined with their headers)
    width = len(header)
    header += optional  # read as empty cells
    idx = {c: header.index(c) for c in cmap.columns}
    value_cols = [c for c in cmap.columns if c not in (cmap.time_column, cmap.unit_column)]
    times, units, rows, bad = [], [], [], BadLines(path)
    clock = LocalClock(cmap)
    if optional:
        bad.add(1, f"(the header) lacks the measured column(s) {', '.join(optional)}: no reading of theirs here")
    for row in reader:
        if not row or (len(row) == 1 and not row[0].strip()):
            continue
        if len(row) != width:
            counts["bad_line"] += 1
            fault = "cut short or a field missing" if len(row) < width else "a separator too many"
            bad.add(reader.line_num, f"dropped ({len(row)} of the header's {width} fields: {fault})")
            continue
        if [c.strip() for c in row] == again:
            counts["bad_line"] += 1
            bad.add(reader.line_num, "dropped (the header again: files joined with their headers)")
            continue
        row += [""] * len(optional)
        stamp = row[idx[cmap.time_column]]
        t = clock(stamp)
        if t is None:
            counts["bad_time"] += 1
            bad.add(reader.line_num, f"dropped (time stamp {stamp.strip()[:30]!r}: {_stamp_fault(stamp, cmap)})")
            continue
        times.append(t)
        units.append(row[idx[cmap.unit_column]].strip() if cmap.unit_column else path.stem)
        rows.append([number(row[idx[c]]) for c in value_cols])
        if np.isinf(rows[-1]).any():  # a cell that is no number: its value left out (clean counts it implausible)
            c = next(c for c, v in zip(value_cols, rows[-1]) if np.isinf(v))
            bad.add(reader.line_num, f"kept without its {c} {row[idx[c]].strip()[:30]!r} (no number)")
    if getattr(text, "cut", False):
        bad.add(
            reader.line_num + 1,
            "and after: lost, the gzip ends mid-way there (a copy cut short or damaged)",
        )
    _check_times(
        path, cmap, times, lambda: next((r[idx[cmap.time_column]] for r in _rows_of(path, semicolon, width)), "")
    )
    arr = np.array(rows, dtype=float).reshape(len(rows), len(value_cols))
    return FileRows(
        path=path,
        time_s=np.array(times, dtype=float),
        unit=np.array(units, dtype=object),
        raw={c: arr[:, i] for i, c in enumerate(value_cols)},
        counts=counts,
        bad=bad if bad.total else None,
    )


def _check_times(path: Path, cmap: ColumnMap, times: list, example_of) -> None:
    """InputError when no row's stamp was read (without a UTC offset, or in another form: the map's keys that read
    them) or the stamps of kind "seconds" are milliseconds; ``example_of()``: a stamp of the file, for the sentence."""
    if not times:
        example = example_of()
        plain = cmap.time_kind == "iso8601_offset" and parse_time(example + "+00:00", cmap.time_kind) is not None
        raise InputError(
            f"{path.name}: its time stamps ({cmap.time_column}, e.g. {example!r}) have no UTC offset: give them with "
            'theirs (2017-01-01T00:10:00+01:00), or, if they are UTC, set time.kind = "iso8601_utc" in a copy of '
            'the column map, or, if they are local time, time.zone = "Europe/Paris" (the zone\'s IANA name)'
            if plain
            else f"{path.name}: no row with a readable time stamp ({cmap.time_column}, e.g. {example!r}), no SCADA "
            "data: ISO 8601 stamps (2017-01-01T00:10:00+01:00), or give their form as time.format in a copy of the "
            'column map (e.g. "%d.%m.%Y %H:%M")'
            if cmap.time_format is None and cmap.time_kind.startswith("iso")
            else f"{path.name}: no row with a readable time stamp ({cmap.time_column}, e.g. {example!r}), no SCADA data"
        )
    if cmap.time_kind == "seconds" and np.median(times) > MS_STAMP_MIN_S:
        mid = float(np.median(times))
        when = datetime.fromtimestamp(mid / 1e3, tz=timezone.utc).date().isoformat()
        raise InputError(
            f"{path.name}: its time stamps ({cmap.time_column}, e.g. {mid:.0f}) look like milliseconds ({when} in "
            f'milliseconds, the year {1970 + int(mid / 3.15576e7)} in seconds): set time.kind = "milliseconds" in a '
            "copy of the column map"
        )


def _semicolon(header: str, cmap: ColumnMap) -> bool:
    """Whether a header line is separated by ';' rather than ','."""
    if ";" not in header:
        return False
    found = {
        sep: sum(c in {f.strip() for f in next(csv.reader([header], delimiter=sep), [])} for c in cmap.columns)
        for sep in ";,"
    }
    return found[";"] > found[","] or (found[";"] == found[","] and "," not in header)


def _stamp_fault(stamp: str, cmap: ColumnMap) -> str:
    """Why a time stamp was not read, in words."""
    if cmap.time_kind == "iso8601_offset" and parse_time(stamp.strip() + "+00:00", cmap.time_kind) is not None:
        return "no UTC offset"
    return "does not parse"


def _rows_of(path: Path, semicolon: bool, width: int):
    """The data rows of a file with ``width`` fields (a second pass, for a sentence's example)."""
    reader = csv.reader(open_text(path), delimiter=";" if semicolon else ",")
    next(reader, None)
    return (r for r in reader if len(r) == width)


#: two rows of one time stamp agree when each value of the map's columns is within this share of the larger (or
#: of 1) of the other's, or missing in one of them: float noise, not two readings
SAME_VALUE_REL = 1e-9


def _order(parts: list[FileRows], counts: dict[str, int]) -> tuple[np.ndarray, dict[str, np.ndarray], dict]:
    """The files' rows joined in time order, duplicates removed (each counted): (time_s, raw columns, the rows of
    each file dropped as ``conflicting_time``). The rows of a repeated time stamp that agree (SAME_VALUE_REL; a value
    missing in one is taken from another) are one row (``duplicate_time``: the others); if any value differs, no
    row of that stamp is kept (``conflicting_time``: all of them): which of two records holds the unit's readings
    cannot be told, and keeping the first made the result depend on the order the files were given in."""
    parts = sorted(parts, key=lambda p: float(np.min(p.time_s)))
    for p in parts:
        counts["out_of_order"] += int(np.sum(p.time_s < np.maximum.accumulate(p.time_s)))
    t = np.concatenate([p.time_s for p in parts])
    src = np.concatenate([np.full(p.time_s.size, i) for i, p in enumerate(parts)])
    order = np.argsort(t, kind="stable")
    t, src = t[order], src[order]
    starts = np.flatnonzero(np.diff(t, prepend=-np.inf) > 0)
    size = np.diff(np.append(starts, t.size))
    agree = np.ones(starts.size, dtype=bool)
    raw = {}
    for c in parts[0].raw:
        x = np.concatenate([p.raw[c] for p in parts])[order]
        with np.errstate(invalid="ignore"):
            # agreement among the numbers read (a cell that is no number, read as inf, is judged like an empty one)
            xf = np.where(np.isfinite(x), x, np.nan)
            lo, hi = np.fmin.reduceat(xf, starts), np.fmax.reduceat(xf, starts)  # (NaN where none is read)
            noise = SAME_VALUE_REL * np.fmax(1.0, np.fmax(np.abs(lo), np.abs(hi)))
            agree &= (lo == hi) | np.isnan(lo) | (hi - lo <= noise)
        raw[c] = np.fmin.reduceat(x, starts)  # a stamp's one value, whatever the files' order
    conflict = np.repeat(~agree & (size > 1), size)
    counts["duplicate_time"] += int(np.sum(size[agree] - 1))
    counts["conflicting_time"] += int(np.sum(conflict))
    dropped = {parts[i].path: int(n) for i, n in enumerate(np.bincount(src[conflict], minlength=len(parts))) if n}
    return t[starts][agree], {c: v[agree] for c, v in raw.items()}, dropped


def _record(unit: str, parts: list[FileRows], cmap: ColumnMap) -> ScadaRecord:
    counts = dict.fromkeys(REASONS, 0)
    for p in parts:
        for k, v in p.counts.items():
            counts[k] += v
    t, raw, conflicts = _order(parts, counts)
    gap = np.diff(t, prepend=t[0]) > GAP_PERIODS * cmap.period_s
    counts["gap"] += int(np.sum(gap))
    stretch = np.cumsum(gap)
    values, by_channel, stuck = clean_values(raw, stretch, cmap, counts, t)
    return ScadaRecord(
        unit=unit,
        time_s=t,
        stretch=stretch,
        values=values,
        counts=counts,
        by_channel=by_channel,
        cmap=cmap,
        files=[p.path for p in parts],
        bad_lines=[p.bad for p in parts if p.bad is not None],
        stuck=stuck,
        conflicts=conflicts,
    )


def _split_units(f: FileRows) -> dict[str, FileRows]:
    out = {}
    for u in dict.fromkeys(f.unit.tolist()):
        m = f.unit == u
        first = not out  # the file's line counts (and damaged lines) go with its first unit
        counts = dict(f.counts) if first else dict.fromkeys(REASONS, 0)
        raw = {c: v[m] for c, v in f.raw.items()}
        out[u] = FileRows(f.path, f.time_s[m], f.unit[m], raw, counts, f.bad if first else None)
    return out


def read_units(
    paths: Iterable[str | Path], columns: str | Path | ColumnMap = "engie", skipped: list | None = None
) -> dict[str, ScadaRecord]:
    """Every unit's record in ``paths`` (the unit from the map's unit column), each unit's files joined in time;
    ``skipped``: a list that takes (path, sentence) of each file that cannot be read, which is then left out (a
    fleet's folder), instead of the InputError."""
    cmap = columns if isinstance(columns, ColumnMap) else load_column_map(columns)
    by_unit: dict[str, list[FileRows]] = {}
    for path in paths:
        try:
            rows = read_file(path, cmap)
        except InputError as exc:
            if skipped is None:
                raise
            skipped.append((Path(path), str(exc)))
            continue
        for unit, part in _split_units(rows).items():
            by_unit.setdefault(unit, []).append(part)
    if not by_unit:
        if skipped:
            raise InputError(f"none of the {len(skipped)} files could be read (the first: {skipped[0][1]})")
        raise InputError("no SCADA file given")
    return {u: _record(u, parts, cmap) for u, parts in sorted(by_unit.items())}


def rows_near(t_ref_s: np.ndarray, t_s: np.ndarray, within_s: float) -> int:
    """How many of the sorted times ``t_s`` lie closer than ``within_s`` to one of the sorted ``t_ref_s``."""
    if not (t_ref_s.size and t_s.size):
        return 0
    j = np.searchsorted(t_ref_s, t_s)
    before = np.abs(t_s - t_ref_s[np.maximum(j - 1, 0)])
    after = np.abs(t_ref_s[np.minimum(j, t_ref_s.size - 1)] - t_s)
    return int(np.sum(np.minimum(before, after) < within_s))


#: the fewest readings of a measured channel held-out records must hold to test a fit or a diagnosis (6 h of
#: 10-minute rows)
TEST_MIN_READINGS = 36


def held_readings(records: list[ScadaRecord]) -> dict[str, int]:
    """measured channel -> its readings (not NaN) over ``records``."""
    out: dict[str, int] = {}
    for r in records:
        for ch in r.cmap.measured:
            out[ch] = out.get(ch, 0) + int(np.sum(np.isfinite(r.values[ch])))
    return out


def same_readings(a: ScadaRecord, b: ScadaRecord) -> int:
    """How many rows of ``b`` repeat one of ``a``'s: the same time stamp and every measured channel's reading the
    same (and one at least read): one turbine's rows under two names."""
    t, ia, ib = np.intersect1d(a.time_s, b.time_s, assume_unique=False, return_indices=True)
    if not t.size:
        return 0
    same = np.ones(t.size, dtype=bool)
    read = np.zeros(t.size, dtype=bool)
    for ch in a.cmap.measured:
        if ch in b.values:
            x, y = a.values[ch][ia], b.values[ch][ib]
            same &= (x == y) | (np.isnan(x) & np.isnan(y))
            read |= np.isfinite(x)
    return int(np.sum(same & read))


def read_held_out(train_paths, test_paths, columns) -> tuple[list[ScadaRecord], list[ScadaRecord]]:
    """The training and the test records (each unit's files one record), refused with one sentence when a test
    record shares rows with a training one: its unit, and a time stamp within half the map's period of one of
    the training record's (the same stamps, or the same hours exported on a shifted grid), or another unit's name
    on TEST_MIN_READINGS or more of the training rows' time stamps and readings (a copy renamed): its error would not
    be held out."""
    train = list(read_units(train_paths, columns).values())
    test = list(read_units(test_paths, columns).values())
    for te in test:
        for tr in train:
            if te.unit == tr.unit:
                shared = rows_near(tr.time_s, te.time_s, 0.5 * te.cmap.period_s)
                if shared:
                    raise InputError(
                        f"the test records of {te.unit} share {shared} of their {te.n} rows with the training ones: "
                        "held-out figures need other rows (another unit, or other dates)"
                    )
            elif (copied := same_readings(tr, te)) >= TEST_MIN_READINGS:
                raise InputError(
                    f"{copied} of the {te.n} test rows of {te.unit} repeat training rows of {tr.unit} (the same time "
                    f"stamps and readings): one turbine under two names is not held out"
                )
    return train, test


def read_record(paths: Iterable[str | Path], columns: str | Path | ColumnMap = "engie") -> ScadaRecord:
    """The one unit's record in ``paths``; files of several units raise an InputError naming them. A map without a
    unit column (``unit_id``) takes the files given as one unit's, named after the first (a fleet takes each file
    for a unit: nothing in them says which files belong together)."""
    cmap = columns if isinstance(columns, ColumnMap) else load_column_map(columns)
    paths = list(paths)
    if cmap.unit_column is None and len(paths) > 1:
        return _record(Path(paths[0]).stem, [read_file(p, cmap) for p in paths], cmap)
    recs = read_units(paths, cmap)
    if len(recs) > 1:
        raise InputError(
            f"the files hold {len(recs)} units ({', '.join(repr(u) for u in recs)}), not one: give one unit's files "
            "(the fleet command reads several units)"
        )
    return next(iter(recs.values()))
