"""The fleet run: every log through the onboard sensor on a Dask cluster, one summary row each (docs/fleet.md).

:func:`run_fleet` connects to a Dask scheduler (``scheduler``: ``tcp://HOST:PORT``) or starts a ``LocalCluster`` on
this machine (``workers`` processes, one thread each), sends the logs in batches (a few per worker for a small fleet,
at most :data:`BATCH_MAX_LOGS` per task for a big one, so that 100 000 logs are ~1600 tasks), and writes each batch's
rows as it completes (tools/fleet/store.py). Workers only compute: they read, replay and summarise
(:func:`process_batch`, the whole-log path of ``tools.replay.log``) and return rows; this process alone writes. A
worker that dies mid-run (its tasks go to another worker: Dask) costs time, never a row twice; a log that cannot be
read becomes an error row with its reason; a re-run skips the logs already written, unless the log file or its
settings (:func:`settings_of`) changed since.
"""

from __future__ import annotations

import functools
import hashlib
import json
import logging
import math
import os
import time
from pathlib import Path
from typing import NamedTuple

from firmware_model.errors import InputError
from tools.fleet.manifest import LogEntry, vehicle_config
from tools.fleet.store import (
    ESTIMATES,
    LOG_BYTES,
    LOG_MTIME,
    REPLAYED,
    SETTINGS,
    FleetStore,
    log_stamp,
    partition_dir,
)

#: logs per task at most; a small fleet gets about TASKS_PER_WORKER tasks per worker
BATCH_MAX_LOGS = 64
TASKS_PER_WORKER = 4
#: how long to wait for a scheduler given by address [s]
CONNECT_TIMEOUT_S = 10.0
#: how long to wait for the first worker of a scheduler given by address [s]
WORKER_WAIT_S = 30.0

_SENSORS: dict = {}


class FleetRun(NamedTuple):
    """What a run did: logs given, skipped (done before), summarised, failed; the tasks; the workers; of the logs
    summarised before, those replayed again because their settings changed or estimates were asked (``resettled``),
    and those kept whose row does not record its settings (``unrecorded``: a row of an earlier version)."""

    logs: int
    skipped: int
    summarised: int
    failed: int
    tasks: int
    workers: int
    resettled: int = 0
    unrecorded: int = 0


def _sensor(variant: str | None, config: str | None):
    """The onboard sensor and service options of a (variant, config), built once per worker process."""
    key = (variant, config)
    if key not in _SENSORS:
        from firmware_model.onboard.sensor import VirtualSensor
        from firmware_model.service import ServiceOptions

        cfg = vehicle_config(variant, config)
        _SENSORS[key] = (
            VirtualSensor(cfg.load_params(), config=cfg),
            ServiceOptions.from_config(cfg, log_findings=False),
        )
    return _SENSORS[key]


#: the logger of the workers' sensor services: errors only (a log's jumps and findings are in its row)
_QUIET = logging.getLogger("gearbox_vsensor.fleet_worker")
_QUIET.setLevel(logging.ERROR)


def _estimates(table, entry: LogEntry, out: Path, date: str) -> None:
    import pyarrow as pa

    from tools.fleet.store import write_atomic

    cols = {c: table[c] for c in table.columns}
    write_atomic(
        pa.table(cols), partition_dir(out / ESTIMATES, entry.vehicle, date) / f"{entry.log.stem}-{entry.key}.parquet"
    )


def _oil_level(path: Path, options) -> dict:
    """The log's measured oil level (SPN 124; tools/fleet/level.py) for its health fit: NaN and 0 readings when the
    truck does not send it (or, exceptionally, when the second read of the log fails)."""
    from can_dbc import dbc
    from tools.fleet.level import read_log_level

    sa = options.expected_sa.get("TRF1", dbc.message("TRF1").frame_id & 0xFF)
    try:
        level = read_log_level(path, sa)
    except (InputError, OSError, ValueError):  # the log was read once already: its summary is not lost for this
        return {"level_pct": math.nan, "level_readings": 0}
    return {"level_pct": level.level_pct, "level_readings": level.readings}


def _check_complete(path: Path) -> None:
    """InputError for an empty log. A text log whose last line is cut (a logger unplugged, a log still being
    written: a re-run replays it again once it changed) is summarised without that line, counted in its row."""
    if not path.is_file():
        return
    size = path.stat().st_size
    if size == 0:
        raise InputError(f"{path}: the log file is empty")


def process_log(
    entry: LogEntry, out: str | None = None, estimates: bool = False, diagnose: bool = False
) -> tuple[str, dict]:
    """One log: ("ok", summary row) or ("error", error row); never raises for a bad log. ``diagnose``: the row
    carries the log's health fit under "_fit" (tools/fleet/health.py; None when the log cannot be fitted)."""
    from firmware_model.service import SensorService
    from firmware_model.service.degraded import Severity, untrusted
    from tools.fleet.summary import asc_date, summarize
    from tools.replay.log import log_findings, replay_log, with_malformed

    base = {"vehicle": entry.vehicle, "log": os.fspath(entry.log), "log_key": entry.key}
    stage = "sensor"
    stamp = log_stamp(entry.log)  # before reading: a log that grows while it is read is replayed again
    try:
        sensor, options = _sensor(entry.variant, entry.config)
        stage = "replay"
        _check_complete(entry.log)
        service = SensorService(sensor, options, record=True, emit_frames=False, logger=_QUIET)
        table = replay_log(entry.log, service)
        stage = "summary"
        date = entry.date or (asc_date(entry.log) if Path(entry.log).suffix.lower() == ".asc" else None)
        row = summarize(
            table,
            table.meta["counters"],
            vehicle=entry.vehicle,
            log=os.fspath(entry.log),
            key=entry.key,
            date=date,
            oil_model=getattr(sensor.options, "oil_mode", "measured") == "model",
            gearbox=sensor,
        )
        # the verdict `replay` gives this log (exit status 3): its warnings, and whether they make it untrusted
        malformed = table.meta.get("malformed")
        findings = with_malformed(log_findings(service, table), malformed)
        row.update(malformed_columns(malformed))
        row["variant"] = gearbox_of(entry.variant, entry.config)
        row[SETTINGS] = settings_of(entry)
        row[LOG_BYTES], row[LOG_MTIME] = stamp if stamp is not None else (None, None)
        row[REPLAYED] = time.time()
        row["trusted"] = not untrusted(findings)
        row["trust_warnings"] = " | ".join(f.sentence for f in findings if f.severity >= Severity.WARNING)
        if estimates and out is not None:
            stage = "estimates"
            _estimates(table, entry, Path(out), row["date"])
        if diagnose:
            from tools.fleet.health import fit_log

            stage = "health fit"
            fit = fit_log(table, entry.variant, entry.config)
            if fit is not None:
                stage = "oil level"
                fit.update(_oil_level(entry.log, options))
            row["_fit"] = fit
        return "ok", row
    except (InputError, OSError, ValueError) as exc:
        return "error", {**base, "stage": stage, "reason": str(exc)}
    except Exception as exc:  # a bug must not stop a fleet: the reason names it
        return "error", {**base, "stage": stage, "reason": f"{type(exc).__name__}: {exc}"}


def malformed_columns(malformed) -> dict:
    """A summary row's record of the malformed lines skipped in its log (tools/replay/lines.py): how many, the
    first line numbers ("1045, 20871"), and the sentence."""
    if malformed is None:
        return {"malformed_lines": 0, "malformed_first_lines": "", "malformed": ""}
    return {
        "malformed_lines": malformed.skipped,
        "malformed_first_lines": ", ".join(map(str, malformed.first)),
        "malformed": malformed.summary,
    }


def process_batch(
    entries: list[LogEntry], out: str | None = None, estimates: bool = False, diagnose: bool = False
) -> list:
    """The logs of one task, in order (a Dask task runs this on a worker). The sensor service's own warnings (a
    frame time jump, a bus finding) are not logged on the worker: each log's row counts them (``time_jumps``) and
    carries its findings (``trust_warnings``); logged, they would flood the fleet's console without a log's
    name."""
    return [process_log(e, out, estimates, diagnose) for e in entries]


def batches(entries: list[LogEntry], workers: int, max_logs: int = BATCH_MAX_LOGS) -> list[list[LogEntry]]:
    """Tasks of whole logs, by vehicle: about TASKS_PER_WORKER per worker, at most ``max_logs`` logs each."""
    if not entries:
        return []
    size = max(1, min(max_logs, math.ceil(len(entries) / (TASKS_PER_WORKER * max(workers, 1)))))
    ordered = sorted(entries, key=lambda e: (e.vehicle, os.fspath(e.log)))
    return [ordered[i : i + size] for i in range(0, len(ordered), size)]


def batch_id(batch: list[LogEntry]) -> str:
    return hashlib.sha1(",".join(e.key for e in batch).encode()).hexdigest()[:16]


def _probe_scheduler(address: str) -> str | None:
    """Why ``address`` (``tcp://HOST:PORT``) is not a Dask scheduler that answers, or None. A scheduler sends its
    handshake as soon as a connection opens (8-byte frame length, frame count, msgpack); a port of something else
    (the scheduler's dashboard, a web server) sends nothing, and Dask's client would then wait for ever. Other
    protocols (tls://, ucx://) are not probed."""
    import socket
    import struct
    from urllib.parse import urlsplit

    if not address.startswith("tcp://"):
        return None
    try:
        u = urlsplit(address)
        host, port = u.hostname, u.port
    except ValueError:
        return f"{address} is not tcp://HOST:PORT"
    if not host or port is None:
        return f"{address} is not tcp://HOST:PORT"
    try:
        with socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S) as sock:
            sock.settimeout(CONNECT_TIMEOUT_S)
            head = b""
            while len(head) < 16:
                chunk = sock.recv(16 - len(head))
                if not chunk:
                    break
                head += chunk
    except TimeoutError:
        return (
            f"nothing at {address} answered as a Dask scheduler within {CONNECT_TIMEOUT_S:.0f} s (the "
            f"dashboard's port, or another service?)"
        )
    except OSError as exc:
        return f"the Dask scheduler at {address} does not answer ({exc.strerror or type(exc).__name__})"
    if len(head) < 16:
        return f"{address} closed the connection without a Dask handshake"
    total, frames = struct.unpack("<QQ", head)
    if not (0 < total < 1 << 24 and 0 < frames < 64):
        return f"{address} is not a Dask scheduler (it does not speak Dask's protocol)"
    return None


def _client_within(address: str, timeout_s: float):
    """A Dask client of ``address``, or InputError when it is not connected within ``timeout_s`` (Dask's own
    timeout does not bound every handshake: the connection runs in a daemon thread given up after it)."""
    import threading

    from dask.distributed import Client

    box: dict = {}

    def connect_():
        try:
            box["client"] = Client(address, timeout=f"{CONNECT_TIMEOUT_S}s")
        except BaseException as exc:  # handed to the caller
            box["error"] = exc

    t = threading.Thread(target=connect_, daemon=True, name="gvs-fleet-connect")
    t.start()
    t.join(timeout_s)
    if "client" in box:
        return box["client"]
    exc = box.get("error")
    raise InputError(
        f"the Dask scheduler at {address} does not answer within {timeout_s:.0f} s"
        + (f" ({type(exc).__name__})" if exc is not None else "")
    ) from None


def connect(scheduler: str | None, workers: int | None):
    """(client, cluster or None): a Dask client of the scheduler at ``scheduler`` (probed first, then waited for up
    to WORKER_WAIT_S for a worker), or of a new LocalCluster."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise InputError("the fleet command needs dask.distributed: pip install 'gearbox-vsensor[fleet]'") from None
    if workers is not None and workers < 1:
        raise InputError(f"--workers {workers} must be at least 1")
    if scheduler:
        if workers is not None:
            raise InputError("--workers starts a local cluster; with --scheduler the cluster's own workers run")
        why = _probe_scheduler(scheduler)
        if why is not None:
            raise InputError(why)
        client = _client_within(scheduler, 3 * CONNECT_TIMEOUT_S)
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT_S)
        except (TimeoutError, OSError):
            client.close()
            raise InputError(
                f"the Dask scheduler at {scheduler} has no worker (none connected within "
                f"{WORKER_WAIT_S:.0f} s: start `dask worker {scheduler}`)"
            ) from None
        return client, None
    n = workers or max(1, os.cpu_count() or 1)
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=40)
    return Client(cluster), cluster


@functools.lru_cache(maxsize=256)
def gearbox_of(variant: str | None, config: str | None) -> str:
    """The gearbox a log is replayed as: its variant, or the parameter file its configuration names."""
    cfg = vehicle_config(variant, config)
    return os.fspath(cfg.params_path) if cfg.params_path else cfg.variant


@functools.lru_cache(maxsize=256)
def _model_settings(variant: str | None, config: str | None) -> str:
    """What of a (variant, configuration) changes a log's replay, as canonical text: the gearbox, the [cooler],
    [boundary], [can] and [sensor] sections (not [fleet] or the commands' settings)."""
    cfg = vehicle_config(variant, config)
    sections = {"gearbox": gearbox_of(variant, config), "cooler": cfg.cooler, "boundary": cfg.boundary}
    return json.dumps({**sections, "can": cfg.can, "sensor": cfg.sensor}, sort_keys=True, default=str)


def settings_of(entry: LogEntry) -> str:
    """A hash of what a log's summary row depends on besides the log file: its gearbox and configuration
    (:func:`_model_settings`), its vehicle name and its manifest date. A re-run replays a log whose row has another
    (a --config that sets the source address, a manifest that renames a vehicle), else it would keep the old row."""
    text = "\n".join((_model_settings(entry.variant, entry.config), entry.vehicle, entry.date or ""))
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def _stale(entry: LogEntry, done, estimates: bool, with_estimates: set) -> str | None:
    """Why the summary row ``done`` (a DoneRow; None: no row) of a log is not kept: "new", "changed" (the log file),
    "settings" (they differ, or estimates are asked and it has none), "unrecorded" (kept: an earlier version's
    row, which does not record its settings; its vehicle and gearbox match); None: kept."""
    if done is None:
        return "new"
    if done.stamp is not None and done.stamp != log_stamp(entry.log):
        return "changed"
    if done.vehicle != entry.vehicle or (done.variant and done.variant != gearbox_of(entry.variant, entry.config)):
        return "settings"
    if estimates and entry.key not in with_estimates:
        return "settings"
    if done.settings is None:
        return "unrecorded"
    return None if done.settings == settings_of(entry) else "settings"


def _todo(store: FleetStore, entries: list[LogEntry], estimates: bool) -> tuple[list[LogEntry], dict]:
    """(the logs to replay, {log key: why (:func:`_stale`)}): a log not done yet, changed since its row was written
    (a log still being written then: its size and time moved, and its partial summary must not be kept for good), or
    whose settings changed since (else the row of the old settings is kept for good); rows of an earlier version
    have no stamp and no settings. A log replayed again loses its old estimates (of the old log, settings or
    vehicle)."""
    done = store.done_rows()
    old_estimates = store.estimate_files()
    has_estimates = set(old_estimates)
    why = {e.key: _stale(e, done.get(e.key), estimates, has_estimates) for e in entries}
    todo = [e for e in entries if why[e.key] not in (None, "unrecorded")]
    for e in todo:
        for f in old_estimates.get(e.key, ()) if e.key in done else ():
            f.unlink(missing_ok=True)
    return todo, why


def _check_variants(store: FleetStore, entries: list[LogEntry]) -> None:
    """InputError when a vehicle of ``entries`` already has rows in the output replayed as another gearbox variant
    (a vehicle is one gearbox: otherwise a corrected manifest would keep the rows of the wrong variant)."""
    known = store.vehicle_variants()
    if not known:
        return
    for e in entries:
        have = known.get(e.vehicle)
        if not have:
            continue
        want = gearbox_of(e.variant, e.config)
        if want not in have:
            raise InputError(
                f"vehicle {e.vehicle} has rows in {store.out} replayed as {', '.join(sorted(have))}, "
                f"and this run gives it {want}: a vehicle is one gearbox (use another --out, or remove "
                f"{store.out / 'summary' / ('vehicle=' + e.vehicle)} to replay it as {want})"
            )


def _worker_count(client) -> int:
    return max(1, len(client.scheduler_info().get("workers", {})))


def _worker_failure(batch: list[LogEntry], exc: BaseException, killed: bool) -> list[tuple]:
    """The error rows of a batch whose task failed on its worker (``killed``: its worker processes died)."""
    why = (
        f"the worker processes running this log died ({type(exc).__name__}: {exc})"
        if killed
        else f"the task failed on its worker ({type(exc).__name__}: {exc})"
    )
    return [
        ("error", {"vehicle": e.vehicle, "log": os.fspath(e.log), "log_key": e.key, "stage": "worker", "reason": why})
        for e in batch
    ]


def run_fleet(
    entries: list[LogEntry],
    out: str | os.PathLike,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    estimates: bool = False,
    diagnose: bool = False,
    show_progress: bool | None = None,
    max_logs: int = BATCH_MAX_LOGS,
    on_batch=None,
) -> FleetRun:
    """Summarise every log of ``entries`` into ``out`` (tools/fleet/store.py); see the module doc. ``on_batch(n)``
    is called after each batch is written (tests kill a worker from it)."""
    from tools.progress import progress

    client, cluster = connect(scheduler, workers)  # first: without dask it says what to install
    from dask.distributed import as_completed

    try:
        store = FleetStore(out)
        store.prepare()
        _check_variants(store, entries)
        todo, why = _todo(store, entries, estimates)
        n_workers = _worker_count(client)
        tasks = batches(todo, n_workers, max_logs)

        def submit(b):
            return client.submit(
                process_batch, b, os.fspath(out), estimates, diagnose, pure=False, key=f"gvs-fleet-{batch_id(b)}"
            )

        futures = {submit(b): b for b in tasks}
        ok = failed = written = 0
        queue = as_completed(futures)
        with progress(len(todo), "fleet", show_progress, unit="log") as bar:
            for fut in queue:
                batch = futures.pop(fut)
                try:
                    results = fut.result()
                except Exception as exc:  # e.g. KilledWorker: the task's logs killed every worker that ran them
                    killed = type(exc).__name__ == "KilledWorker"
                    if killed and len(batch) > 1:  # one log of the batch, or none: each alone, only the guilty fails
                        for e in batch:
                            f1 = submit([e])
                            futures[f1] = [e]
                            queue.add(f1)
                        continue
                    results = _worker_failure(batch, exc, killed)
                rows = [r for kind, r in results if kind == "ok"]
                errors = [r for kind, r in results if kind == "error"]
                store.write_batch(batch_id(batch), rows, errors)
                ok, failed, written = ok + len(rows), failed + len(errors), written + 1
                bar.update(len(batch))
                if on_batch is not None:
                    on_batch(written)
        store.compact_errors()
        counts = list(why.values())
        return FleetRun(
            len(entries),
            len(entries) - len(todo),
            ok,
            failed,
            written,
            n_workers,
            counts.count("settings"),
            counts.count("unrecorded"),
        )
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


__all__ = [
    "BATCH_MAX_LOGS",
    "FleetRun",
    "batch_id",
    "batches",
    "connect",
    "process_batch",
    "process_log",
    "run_fleet",
    "settings_of",
]
