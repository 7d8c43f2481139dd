"""The fleet's output folder: Parquet tables written by one process only, each file complete or absent.

``DIR/summary/vehicle=<V>/date=<YYYY-MM-DD>/part-<batch>.parquet``: one row per log (tools/fleet/summary.py), Hive
partitions by vehicle and date (any Parquet reader: ``pyarrow.dataset.dataset(DIR/"summary",
partitioning="hive")``, ``dask.dataframe.read_parquet``, pandas). ``DIR/errors/part-<batch>.parquet``: one row per
log that could not be read, with the reason. ``DIR/estimates/vehicle=<V>/date=<D>/<log>-<key>.parquet`` (with
``--estimates``): the 10 Hz sensor output of each log. Every file is written under a temporary name and renamed:
``DIR/fits/...`` (with ``--diagnose``): each log's health fit (tools/fleet/health.py). A run killed at any moment
leaves whole files only. A re-run skips the logs that have a summary row of the same log file and settings
(:meth:`FleetStore.done_rows`, tools/fleet/run.py) and tries
the logs of the errors table again (a log finished or repaired since); at the end of a run the errors table is
rewritten with one row per log that still fails (:meth:`FleetStore.compact_errors`), and :func:`read_table` drops
error rows of logs that have a summary, so no log ever has two rows, even after a run killed in between.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path
from typing import NamedTuple
from urllib.parse import quote, unquote

from firmware_model.errors import InputError

SUMMARY, ERRORS, ESTIMATES, HEALTH, FITS = "summary", "errors", "estimates", "health", "fits"
ERROR_COLUMNS = ("vehicle", "log", "log_key", "stage", "reason")
#: a summary row's record of the log file it came from (a re-run replays a log whose size or time changed) and when
#: it was written (a log replayed again: the newest row wins)
LOG_BYTES, LOG_MTIME, REPLAYED = "log_bytes", "log_mtime_ns", "replayed_at_s"
#: a summary row's record of the settings it was made with besides the log file (tools/fleet/run.py, settings_of):
#: a re-run replays a log whose settings changed
SETTINGS = "settings"


class DoneRow(NamedTuple):
    """What a re-run compares of a log's newest summary row: the log file's (size, modification time) and the
    settings hash (None: a row of an earlier version, which did not record them), its vehicle and gearbox."""

    stamp: tuple | None
    settings: str | None
    vehicle: str
    variant: str | None


def log_stamp(path) -> tuple[int, int] | None:
    """(size in bytes, modification time in ns) of a log file; None when it cannot be read."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return int(st.st_size), int(st.st_mtime_ns)


def _pa():
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise InputError("the fleet's Parquet output needs pyarrow: pip install 'gearbox-vsensor[fleet]'") from None
    return pa, pq


def write_atomic(table, path: Path) -> Path:
    """Write a pyarrow table as Parquet under a temporary name in the same folder, then rename it."""
    _, pq = _pa()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.tmp")
    pq.write_table(table, tmp)
    os.replace(tmp, path)
    return path


def partition_dir(root: Path, vehicle: str, date: str) -> Path:
    return root / f"vehicle={quote(vehicle, safe='')}" / f"date={quote(date, safe='')}"


def _keep_rows(path: Path, table, keep: list[int]) -> None:
    """Rewrite the Parquet file ``path`` (holding ``table``) with only the rows ``keep``; remove it when none is
    kept; leave it alone when all are."""
    pa, _ = _pa()
    if len(keep) == table.num_rows:
        return
    if keep:
        write_atomic(table.take(pa.array(keep)), path)
    else:
        path.unlink()


class FleetStore:
    """The output folder ``out``."""

    def __init__(self, out: str | os.PathLike) -> None:
        self.out = Path(out)

    def prepare(self) -> None:
        if self.out.exists() and not self.out.is_dir():
            raise InputError(f"--out {self.out} is a file, not a folder")
        self.out.mkdir(parents=True, exist_ok=True)

    def done_keys(self) -> dict:
        """The keys of the logs that have a summary row (done; the errors table's logs are tried again), each with
        the (size, modification time) of the log it was made from (None: a row of an earlier version, which did not
        record them)."""
        return {k: r.stamp for k, r in self.done_rows().items()}

    def done_rows(self) -> dict:
        """{log key: :class:`DoneRow`} of the logs that have a summary row, from the newest row of each."""
        _, pq = _pa()
        rows: dict = {}
        wanted = ("log_key", LOG_BYTES, LOG_MTIME, REPLAYED, SETTINGS, "variant")
        for f in (self.out / SUMMARY).rglob("*.parquet") if (self.out / SUMMARY).is_dir() else ():
            names = pq.read_schema(f).names  # only the columns needed (a row has ~300)
            t = pq.read_table(f, columns=[c for c in wanted if c in names])
            n = t.num_rows
            col = {c: t.column(c).to_pylist() if c in names else [None] * n for c in wanted}
            vehicle = unquote(f.parent.parent.name.removeprefix("vehicle="))  # the partition
            for key, nb, mt, at, st, var in zip(*(col[c] for c in wanted)):
                if key not in rows or (at or 0.0) >= rows[key][1]:
                    stamp = None if nb is None or mt is None else (int(nb), int(mt))
                    rows[key] = (DoneRow(stamp, st, vehicle, var), at or 0.0)
        return {k: v[0] for k, v in rows.items()}

    def estimate_files(self) -> dict:
        """{log key: [its estimates files]} (``<log>-<key>.parquet`` under DIR/estimates)."""
        root = self.out / ESTIMATES
        found: dict = {}
        for f in root.rglob("*.parquet") if root.is_dir() else ():
            found.setdefault(f.stem.rsplit("-", 1)[-1], []).append(f)
        return found

    def vehicle_variants(self) -> dict:
        """{vehicle: the gearbox variant its rows were replayed with}, from the rows that record it."""
        table = read_table(self.out)
        if table is None or "variant" not in table.column_names:
            return {}
        out: dict = {}
        for v, var in zip(table.column("vehicle").to_pylist(), table.column("variant").to_pylist()):
            if var:
                out.setdefault(v, set()).add(var)
        return out

    def prune(self, exists=os.path.exists) -> list[str]:
        """Remove the summary, fit and estimate rows of logs that are no longer at their path (moved, renamed,
        deleted), file by file (each rewritten under a temporary name, or removed when it empties); returns their
        paths."""
        pa, pq = _pa()
        gone: set[str] = set()
        keys: set[str] = set()
        root = self.out / SUMMARY
        for f in sorted(root.rglob("*.parquet")) if root.is_dir() else ():
            t = pq.read_table(f)
            logs, file_keys = t.column("log").to_pylist(), t.column("log_key").to_pylist()
            drop = [i for i, p in enumerate(logs) if not exists(p)]
            gone.update(logs[i] for i in drop)
            keys.update(file_keys[i] for i in drop)
            _keep_rows(f, t, [i for i in range(len(logs)) if i not in set(drop)])
        fits = self.out / FITS
        for f in sorted(fits.rglob("*.parquet")) if fits.is_dir() and keys else ():
            t = pq.read_table(f)
            _keep_rows(f, t, [i for i, k in enumerate(t.column("log_key").to_pylist()) if k not in keys])
        est = self.out / ESTIMATES
        for f in sorted(est.rglob("*.parquet")) if est.is_dir() and keys else ():
            if any(f.stem.endswith(f"-{k}") for k in keys):
                f.unlink()
        return sorted(gone)

    def compact_errors(self) -> int:
        """Rewrite the errors table as one file: the latest row of each log that has no summary row (the one new
        file first, then the old ones removed: a kill in between leaves rows that :func:`read_table` drops).
        Returns the rows kept."""
        root = self.out / ERRORS
        old = list(root.glob("*.parquet")) if root.is_dir() else []
        if not old:
            return 0
        table = read_table(self.out, ERRORS)
        if table is not None:
            write_atomic(table, root / f"part-{uuid.uuid4().hex[:12]}.parquet")
        for f in old:
            f.unlink(missing_ok=True)
        return 0 if table is None else table.num_rows

    def write_batch(self, batch_id: str, rows: list[dict], errors: list[dict]) -> None:
        """One batch's summary rows (a file per vehicle and date) and error rows."""
        pa, _ = _pa()
        groups: dict[tuple[str, str], list[dict]] = {}
        fits: dict[tuple[str, str], list[dict]] = {}
        for r in rows:
            fit = r.pop("_fit", None)
            if fit is not None:
                fits.setdefault((r["vehicle"], r["date"]), []).append(
                    {"log_key": r["log_key"], **fit, REPLAYED: r.get(REPLAYED)}
                )
            groups.setdefault((r["vehicle"], r["date"]), []).append(r)
        # fits first: the summary row is what marks a log done
        for (vehicle, date), part in fits.items():
            write_atomic(
                pa.Table.from_pylist(part), partition_dir(self.out / FITS, vehicle, date) / f"part-{batch_id}.parquet"
            )
        for (vehicle, date), part in groups.items():
            body = [{k: v for k, v in r.items() if k not in ("vehicle", "date")} for r in part]
            write_atomic(
                pa.Table.from_pylist(body),
                partition_dir(self.out / SUMMARY, vehicle, date) / f"part-{batch_id}.parquet",
            )
        if errors:
            table = pa.table({c: [str(e.get(c, "")) for e in errors] for c in ERROR_COLUMNS})
            write_atomic(table, self.out / ERRORS / f"part-{batch_id}.parquet")


def read_table(out: str | os.PathLike, which: str = SUMMARY):
    """A table of a fleet folder as one pyarrow table (vehicle and date from the partitions, as strings); None when
    it has no file."""
    pa, _ = _pa()
    import pyarrow.dataset as ds

    root = Path(out) / which
    if not root.is_dir() or not any(root.rglob("*.parquet")):
        return None
    if which == ERRORS:
        # a log tried again: its latest row only, none once it has a summary row
        done = FleetStore(out).done_keys()
        latest: dict = {}
        for f in sorted(root.glob("*.parquet"), key=lambda f: f.stat().st_mtime_ns):
            for r in ds.dataset(f, format="parquet").to_table().to_pylist():
                if r["log_key"] not in done:
                    latest.pop(r["log_key"], None)
                    latest[r["log_key"]] = r
        if not latest:
            return None
        return pa.table({c: [str(r.get(c, "")) for r in latest.values()] for c in ERROR_COLUMNS})
    part = ds.partitioning(pa.schema([("vehicle", pa.string()), ("date", pa.string())]), flavor="hive")
    data = ds.dataset(root, format="parquet", partitioning=part)
    if which in (FITS, SUMMARY):
        # files written by an earlier version lack the newer columns (the measured level, the trust verdict): every
        # file's columns, not only the first file's, and the missing ones as nulls
        schema = pa.unify_schemas(
            [data.schema, *(f.physical_schema for f in data.get_fragments())], promote_options="permissive"
        )
        data = ds.dataset(root, format="parquet", partitioning=part, schema=schema)
        return newest_rows(data.to_table())
    return data.to_table()


def newest_rows(table):
    """One row per log_key: the newest (by replayed_at_s; a log replayed again after it changed, or a run killed
    between two files); rows of an earlier version, without the time, count as the oldest."""
    import numpy as np

    pa, _ = _pa()
    keys = table.column("log_key").to_pylist()
    if len(set(keys)) == len(keys):
        return table
    at = table.column(REPLAYED).to_pylist() if REPLAYED in table.column_names else [None] * len(keys)
    best: dict = {}
    for i, (k, a) in enumerate(zip(keys, at)):
        a = -np.inf if a is None else float(a)
        if k not in best or a >= best[k][0]:
            best[k] = (a, i)
    return table.take(pa.array(sorted(i for _, i in best.values())))


__all__ = [
    "ERRORS",
    "ERROR_COLUMNS",
    "ESTIMATES",
    "FITS",
    "HEALTH",
    "LOG_BYTES",
    "LOG_MTIME",
    "REPLAYED",
    "SETTINGS",
    "SUMMARY",
    "DoneRow",
    "FleetStore",
    "log_stamp",
    "newest_rows",
    "partition_dir",
    "read_table",
    "write_atomic",
]
