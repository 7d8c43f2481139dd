"""Which logs belong to which vehicle: a manifest CSV (``log,vehicle`` and optional ``variant,config,date``) or the
logs' paths (the vehicle from a regular expression on the file name or the path; by default the name of the folder
that holds the log inside a folder given, else the log's own file name: one vehicle per log of a flat folder).

Every problem with the list itself (a manifest naming missing files, a vehicle with two variants or configurations,
a log listed twice, no log at all) is an :class:`~firmware_model.errors.InputError` before anything runs; a log that
exists but cannot be read is not: it lands in the fleet's errors table.
"""

from __future__ import annotations

import csv
import datetime as dt
import hashlib
import os
import re
from pathlib import Path
from typing import NamedTuple

from firmware_model.errors import InputError
from tools.replay.formats import LOG_SUFFIXES

#: the manifest's columns: required, then optional
MANIFEST_REQUIRED = ("log", "vehicle")
MANIFEST_OPTIONAL = ("variant", "config", "date")
#: the vehicle of a log in a vehicle's folder (logs/<vehicle>/*.log): the name of the folder holding it
DEFAULT_VEHICLE_PATTERN = r"(?P<vehicle>[^/]+)/[^/]+$"


class LogEntry(NamedTuple):
    """One log of the fleet: its path, vehicle, gearbox variant and configuration (None: the defaults), a date
    (YYYY-MM-DD; None: from the log's first frame time) and its key (what a re-run recognises it by)."""

    log: Path
    vehicle: str
    variant: str | None
    config: str | None
    date: str | None
    key: str


def vehicle_config(variant: str | None, config: str | None):
    """The project configuration of a vehicle: its ``config`` file (None: the defaults) with its ``variant`` (a
    parameter file name) in place of the file's, when given."""
    import dataclasses

    from firmware_model.config import load_config

    cfg = load_config(config)
    return cfg if variant is None else dataclasses.replace(cfg, variant=variant, params_path=None)


def log_key(path: Path) -> str:
    """A log's key: a hash of its absolute path (a re-run skips a log whose key is in the output)."""
    return hashlib.sha1(os.fspath(path.resolve()).encode()).hexdigest()[:16]


def _entry(path: Path, vehicle: str, variant=None, config=None, date=None) -> LogEntry:
    if not vehicle or not vehicle.strip():
        raise InputError(f"{path}: no vehicle name")
    given = date
    if date is not None and re.fullmatch(r"\d{8}", date):  # a file name's compact date (truck7_20260106.log)
        date = f"{date[:4]}-{date[4:6]}-{date[6:]}"
    if date is not None and not re.fullmatch(r"\d{4}-\d{2}-\d{2}", date):
        raise InputError(f"{path}: date {date!r} is not YYYY-MM-DD (nor YYYYMMDD)")
    if date:
        try:
            dt.date.fromisoformat(date)
        except ValueError:
            raise InputError(f"{path}: date {given!r} is not a day of the calendar") from None
    return LogEntry(path, vehicle.strip(), variant or None, config or None, date or None, log_key(path))


def read_manifest(manifest: str | os.PathLike) -> list[LogEntry]:
    """The logs a manifest CSV lists; paths relative to the manifest's folder."""
    m = Path(manifest)
    if not m.is_file():
        raise InputError(f"manifest {m} does not exist")
    try:
        return _read_manifest(m)
    except (UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"manifest {m} is not a UTF-8 CSV file ({exc})") from None


def _read_manifest(m: Path) -> list[LogEntry]:
    with open(m, newline="", encoding="utf-8-sig") as fh:  # -sig: a byte-order mark is not part of "log"
        first = fh.readline()
        fh.seek(0)
        # a spreadsheet's export: ';' separated (a European locale), names capitalised ('Log;Vehicle')
        reader = csv.DictReader(fh, delimiter=";" if ";" in first and "," not in first else ",")
        if reader.fieldnames:
            reader.fieldnames = [h.strip().lower() for h in reader.fieldnames]
        header = list(reader.fieldnames or [])
        missing = [c for c in MANIFEST_REQUIRED if c not in header]
        if missing:
            raise InputError(
                f"manifest {m} has no column {' or '.join(missing)}; it needs columns log,vehicle "
                f"(optional: {','.join(MANIFEST_OPTIONAL)})"
            )
        unknown = [c for c in header if c not in MANIFEST_REQUIRED + MANIFEST_OPTIONAL]
        if unknown:
            raise InputError(
                f"manifest {m} has unknown column(s) {', '.join(unknown)}; use log,vehicle and "
                f"optionally {','.join(MANIFEST_OPTIONAL)}"
            )
        rows = []
        for r in reader:
            extra = [v for v in (r.get(None) or []) if v and v.strip()]
            if extra:
                raise InputError(
                    f"manifest {m} line {reader.line_num} has {len(extra)} field(s) more than its header "
                    f"({', '.join(map(repr, extra[:3]))}): a comma in a path must be quoted"
                )
            rows.append((reader.line_num, {k.strip(): (v or "").strip() for k, v in r.items() if k}))
    entries, lines = [], {}
    for line, r in rows:
        p = Path(r["log"])
        if not r["log"]:
            raise InputError(f"manifest {m} line {line}: no log file named")
        if not p.is_absolute():
            p = m.parent / p
        config = r.get("config") or None
        if config and not Path(config).is_absolute():  # relative to the manifest, as the logs
            config = str(m.parent / config)
        try:
            # an empty optional field is the default (a blank date: from the log), as a column left out
            entries.append(_entry(p, r["vehicle"], r.get("variant") or None, config, r.get("date") or None))
        except InputError as exc:
            raise InputError(f"manifest {m} line {line}: {exc}") from None
        lines[id(entries[-1])] = line
    folders = [e for e in entries if e.log.is_dir()]
    if folders:
        raise InputError(
            f"manifest {m} line {lines[id(folders[0])]} names a folder where a log file belongs: {folders[0].log}"
        )
    absent = [e for e in entries if not e.log.is_file()]
    if absent:
        more = f" and {len(absent) - 3} more" if len(absent) > 3 else ""
        raise InputError(
            f"manifest {m} names {len(absent)} log file(s) that do not exist: "
            f"{', '.join(f'{e.log} (line {lines[id(e)]})' for e in absent[:3])}{more}"
        )
    return check_entries(entries, f"manifest {m}", lambda e: str(lines[id(e)]))


def entries_from_paths(paths, pattern: str | None = None, vehicle_from: str | None = None) -> list[LogEntry]:
    """The logs among ``paths`` (files, and folders searched for CAN log suffixes) with their vehicles
    (:func:`entries_and_rule`)."""
    return entries_and_rule(paths, pattern, vehicle_from)[0]


def _log_files(paths) -> list[tuple[Path, str | None]]:
    """(log file, the name of the folder directly inside a folder given that holds it, at any depth: its vehicle
    by default; None for a log directly in a folder given or given itself) for every log among ``paths``. A truck's
    folder with month folders in it (logs/truck1/2026-01/*.log) is still truck1's (the folder holding the log, the
    month, made every truck's January one vehicle)."""
    files: list[tuple[Path, str | None]] = []
    for given in paths:
        p = Path(given)
        if p.is_dir():
            # a compressed log (drive.log.gz) is taken too: it lands in the errors table saying so, not skipped
            found = sorted(
                f
                for f in p.rglob("*")
                if f.is_file()
                and (
                    f.suffix.lower() in LOG_SUFFIXES
                    or (f.suffix.lower() == ".gz" and Path(f.stem).suffix.lower() in LOG_SUFFIXES)
                )
            )
            files.extend((f, f.relative_to(p).parts[0] if f.parent != p else None) for f in found)
        elif p.exists():
            files.append((p, None))
        else:
            raise InputError(f"{p} does not exist")
    return files


def _stem(f: Path) -> str:
    """A log's name without its log suffix (and .gz): truck7_2026-01-05.log.gz -> truck7_2026-01-05."""
    name = f.name[:-3] if f.name.lower().endswith(".gz") else f.name
    return name[: -len(Path(name).suffix)] if Path(name).suffix else name


def _vehicle_from(files: list[Path], vehicle_from: str, option: str = "--vehicle-from") -> tuple[list[tuple], bool]:
    """((file, vehicle, variant, date) per file, whether any was read from a path rather than a file name) from
    ``vehicle_from``, a regular expression searched in each file name, else in its whole path (a pattern with a
    folder in it): the vehicle is its group ``vehicle``, else its first group, else what it matches; optional groups
    ``variant`` and ``date`` (YYYY-MM-DD)."""
    try:
        rx = re.compile(vehicle_from)
    except re.error as exc:
        raise InputError(f"{option} {vehicle_from!r} is not a regular expression: {exc}") from None
    out, unmatched, on_path = [], [], False
    for f in files:
        m = rx.search(f.name)
        if m is None:
            m = rx.search(f.resolve().as_posix())
            on_path = on_path or m is not None
        vehicle = (
            None
            if m is None
            else (m.group("vehicle") if "vehicle" in rx.groupindex else m.group(1) if rx.groups else m.group(0))
        )
        if not vehicle:
            unmatched.append(f)
            continue
        out.append((f, vehicle, m.groupdict().get("variant"), m.groupdict().get("date")))
    if unmatched:
        more = (
            f" ({len(unmatched)} of {len(files)} logs: {', '.join(u.name for u in unmatched[:3])}"
            f"{' ...' if len(unmatched) > 3 else ''})"
            if len(unmatched) > 1
            else ""
        )
        raise InputError(
            f"{unmatched[0]}: {option} '{vehicle_from}' finds no vehicle in its file name "
            f"{unmatched[0].name} or its path{more}; fix the pattern (the vehicle is its group (?P<vehicle>...) "
            f"or its first group), or name each log's vehicle in a --manifest"
        )
    return out, on_path


def entries_and_rule(paths, pattern: str | None = None, vehicle_from: str | None = None) -> tuple[list[LogEntry], str]:
    """The logs among ``paths`` with their vehicles, and one sentence saying how the vehicles were read. The
    vehicle: what ``vehicle_from`` finds in the file name, else in the path (:func:`_vehicle_from`; ``pattern`` is
    the same, the former --vehicle-pattern); else the name of the folder directly inside a folder given that holds
    the log, at any depth (logs/<vehicle>/*.log, logs/<vehicle>/<month>/*.log), and otherwise the log itself, its
    file name without the suffix: a flat folder of logs is one vehicle per log (it was one vehicle, the folder's)."""
    if pattern and vehicle_from:
        raise InputError("give either --vehicle-pattern (on the path) or --vehicle-from (on the file name), not both")
    listed = _log_files(paths)
    files = [f for f, _ in listed]
    regex = vehicle_from or pattern
    if regex:
        option = "--vehicle-from" if vehicle_from else "--vehicle-pattern"
        found, on_path = _vehicle_from(files, regex, option)
        entries = [_entry(f, v, variant, None, d) for f, v, variant, d in found]
        n = len({v for _, v, _, _ in found})
        where = "paths" if on_path else "file names"
        return check_entries(entries, "the logs given"), f"vehicles: {n} read from the {where} by {option} '{regex}'"
    if not listed:
        _no_logs_but_scada(paths)
    entries = [_entry(f, folder if folder is not None else _stem(f)) for f, folder in listed]
    check_entries(entries, "the logs given")
    n_nested = sum(folder is not None for _, folder in listed)
    loose = len(listed) - n_nested
    parts = []
    if n_nested:
        parts.append(
            f"{len({e.vehicle for e, (_, n) in zip(entries, listed) if n is not None})} from the folders holding "
            f"{n_nested} logs"
        )
    if loose:
        names = [e.vehicle for e, (_, n) in zip(entries, listed) if n is None]
        parts.append(
            f"one per log for the {loose} logs not in a vehicle's folder (the file name without its suffix: "
            f"{', '.join(names[:3])}{' ...' if loose > 3 else ''}; --vehicle-from REGEX reads a vehicle "
            f"from the file names, --vehicle-from '(?P<vehicle>[^/]+)/[^/]+$' makes the folder holding "
            f"them one vehicle, a --manifest names each)"
        )
    return entries, f"vehicles: {len({e.vehicle for e in entries})}: " + "; ".join(parts) + _others_words(paths)


def _others_words(paths) -> str:
    """The rest of the vehicles' sentence on the files in the folders given that are no CAN log by their suffix
    (a candump log saved as .candump or .txt was dropped without a word): how many, the first three."""
    others = sorted(
        f
        for given in paths
        if Path(given).is_dir()
        for f in Path(given).rglob("*")
        if f.is_file()
        and not f.name.startswith(".")
        and f.suffix.lower() not in LOG_SUFFIXES
        and not (f.suffix.lower() == ".gz" and Path(f.stem).suffix.lower() in LOG_SUFFIXES)
    )
    if not others:
        return ""
    names = ", ".join(str(f.name) for f in others[:3]) + (" ..." if len(others) > 3 else "")
    csv_ = any(f.suffix.lower() == ".csv" for f in others)
    return (
        f"; {len(others)} other file(s) not taken, no CAN log by their suffix ({names}): a candump log among them "
        f"runs renamed to one of {', '.join(LOG_SUFFIXES)}"
        + (
            "; a python-can CSV log runs converted (python -m can.logconvert IN.csv OUT.log), a run table with "
            "`replay`, a SCADA record with --columns"
            if csv_
            else ""
        )
    )


def _no_logs_but_scada(paths) -> None:
    """InputError when the folders given hold no CAN log but SCADA files: the user forgot --columns (the fleet
    without it said only that there was no CAN log to run)."""
    scada = sorted(
        f
        for given in paths
        if Path(given).is_dir()
        for f in Path(given).rglob("*")
        if f.is_file() and f.name.lower().endswith((".csv", ".csv.gz"))
    )
    if scada:
        raise InputError(
            f"the logs given: no CAN log ({', '.join(LOG_SUFFIXES)}) to run, but {len(scada)} SCADA file(s) (.csv, "
            f".csv.gz, e.g. {scada[0].name}): read them through a column map with --columns NAME|FILE (--columns "
            "engie for ENGIE's La Haute Borne format; docs/real-data.md)"
        )


def check_entries(entries: list[LogEntry], where: str, at=None) -> list[LogEntry]:
    """InputError for no log, a log twice, a vehicle with two variants or two configurations; ``at(entry)``: the
    manifest line an entry was given on, named in those errors."""
    at = at or (lambda e: "")
    if not entries:
        raise InputError(f"{where}: no CAN log ({', '.join(LOG_SUFFIXES)}) to run")
    seen: dict[str, LogEntry] = {}
    per_vehicle: dict[str, LogEntry] = {}
    for e in entries:
        if e.key in seen:
            lines = f" (lines {at(seen[e.key])} and {at(e)})" if at(e) else ""
            raise InputError(f"{where}: the log {e.log} is listed twice{lines}")
        seen[e.key] = e
        first = per_vehicle.setdefault(e.vehicle, e)
        for field in ("variant", "config"):
            if getattr(first, field) != getattr(e, field):
                a, b = (
                    f"{getattr(x, field) or f'the default {field} (none given)'}{f' (line {at(x)})' if at(x) else ''}"
                    for x in (first, e)
                )
                raise InputError(
                    f"{where}: vehicle {e.vehicle} has two {field}s, {a} and {b}; a vehicle is one "
                    f"gearbox (give the other a new vehicle name)"
                )
    _check_gearboxes(per_vehicle.values(), where)
    return entries


def _check_gearboxes(firsts, where: str) -> None:
    """InputError for a variant or configuration that does not load (an unknown variant, a missing or invalid
    configuration file): before anything runs, not as every log of the vehicle in the errors table."""
    from firmware_model.errors import ParameterError

    done = set()
    for e in firsts:
        if (e.variant, e.config) in done:
            continue
        done.add((e.variant, e.config))
        try:
            from firmware_model.service.options import ServiceOptions

            cfg = vehicle_config(e.variant, e.config)
            cfg.load_params()
            ServiceOptions.from_config(cfg)  # the [can] section
            if cfg.sensor.get("oil_mode", "measured") not in ("measured", "model"):
                raise ParameterError(f"sensor.oil_mode = {cfg.sensor['oil_mode']!r} must be 'measured' or 'model'")
        except (ParameterError, InputError) as exc:
            raise InputError(f"{where}: vehicle {e.vehicle}: {exc}") from None


__all__ = [
    "DEFAULT_VEHICLE_PATTERN",
    "LogEntry",
    "check_entries",
    "entries_and_rule",
    "entries_from_paths",
    "log_key",
    "read_manifest",
    "vehicle_config",
]
