"""What the live service keeps across ignition cycles and shows a technician (docs/gateway.md).

* :class:`StateStore`: the sensor state saved to a file every ``period_s`` of wall time and on shutdown (atomic:
  a temporary file in the same directory, fsync, rename; never a half-written file; at most one write per period
  for flash wear), and restored at start: cooled for the wall time the gateway was off, reconciled with the first
  valid oil reading (``VirtualSensor.initial_state(snapshot=..., elapsed_s=..., T_oil_c=...)``). A missing,
  corrupt, truncated or foreign file (another variant or network) means a cold start from the oil, logged and
  counted (``counters["state"]``).
* :class:`HealthFile`: a small JSON the service rewrites every second (uptime, last step, degraded state, counters,
  age of the last state save) that ``gearbox-vsensor status`` reads.
* :func:`sd_notify`: the systemd notification protocol (``READY=1``, ``WATCHDOG=1``) over the standard library's
  socket, a no-op when not run by systemd.
"""
from __future__ import annotations

import json
import logging
import os
import socket
import time
from pathlib import Path

STATE_SCHEMA = "vsensor-state/1"
HEALTH_SCHEMA = "vsensor-health/1"
#: default period of the state saves [s] (flash wear: about 1500 writes a day)
STATE_PERIOD_S = 60.0
#: the health file is rewritten this often [s]
HEALTH_PERIOD_S = 1.0

log = logging.getLogger("gearbox_vsensor.state")


def atomic_write(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so that a reader (or a power cut) sees the old file or the new one, never half."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


class StateStore:
    """The sensor state in a file across restarts: :meth:`load` at start, :meth:`maybe_save` from the loop,
    :meth:`save` at shutdown. ``clock``: wall time [s] (injectable for tests)."""

    def __init__(self, path, period_s: float = STATE_PERIOD_S, clock=time.time):
        self.path = Path(path)
        self.period_s = float(period_s)
        self.clock = clock
        self.last_save_s: float | None = None
        self.counters = {"restored": 0, "cold_starts": 0, "saves": 0, "save_errors": 0, "reason": None}

    def load(self, sensor) -> tuple | None:
        """``(snapshot, elapsed_s)`` of a usable saved state for ``sensor``, or None (a cold start: the reason is
        logged and counted). A state is usable when the file parses, has this schema and was taken with the same
        thermal network (the sensor's own snapshot check)."""
        reason = None
        try:
            doc = json.loads(self.path.read_bytes())
            if not isinstance(doc, dict) or doc.get("schema") != STATE_SCHEMA:
                reason = "not a saved sensor state (schema)"
            elif doc.get("nodes") != list(sensor.reduced.nodes) or doc.get("variant") != sensor.reduced.variant:
                reason = f"saved by another gearbox or network ({doc.get('variant')!r})"
        except FileNotFoundError:
            reason = "no saved state"
        except (OSError, ValueError, UnicodeDecodeError) as exc:
            reason = f"unreadable or truncated ({exc.__class__.__name__})"
        if reason is None:
            elapsed_s = max(self.clock() - float(doc.get("saved_wall_s", 0.0)), 0.0)
            return doc["snapshot"], elapsed_s
        self.cold_start(reason)
        return None

    def cold_start(self, reason: str) -> None:
        self.counters["cold_starts"] += 1
        self.counters["reason"] = reason
        log.warning("state %s: %s; cold start from the oil temperature", self.path, reason)

    def maybe_save(self, service) -> bool:
        """Save when ``period_s`` of wall time has passed since the last save (and the sensor is initialised)."""
        now = self.clock()
        if self.last_save_s is not None and now - self.last_save_s < self.period_s:
            return False
        return self.save(service)

    def save(self, service) -> bool:
        if service.state is None:
            return False
        sensor = service.sensor
        doc = {"schema": STATE_SCHEMA, "saved_wall_s": self.clock(), "frame_time_s": service.frame_time_s,
               "variant": sensor.reduced.variant, "nodes": list(sensor.reduced.nodes),
               "snapshot": json.loads(sensor.snapshot(service.state))}
        try:
            atomic_write(self.path, json.dumps(doc, separators=(",", ":")).encode("utf-8"))
        except OSError as exc:
            self.counters["save_errors"] += 1
            if self.counters["save_errors"] == 1:
                log.warning("cannot save the state to %s: %s (further errors counted, not logged)", self.path, exc)
            return False
        self.last_save_s = self.clock()
        self.counters["saves"] += 1
        return True

    def age_s(self) -> float | None:
        return None if self.last_save_s is None else self.clock() - self.last_save_s


class HealthFile:
    """The service's health for ``gearbox-vsensor status``: rewritten every ``period_s`` of wall time."""

    def __init__(self, path, period_s: float = HEALTH_PERIOD_S, clock=time.time):
        self.path = Path(path)
        self.period_s = float(period_s)
        self.clock = clock
        self.started_s = clock()
        self.last_write_s: float | None = None
        self.errors = 0                       # writes that failed (the first is logged)

    def maybe_write(self, service, store: StateStore | None = None, bus_events: dict | None = None) -> bool:
        now = self.clock()
        if self.last_write_s is not None and now - self.last_write_s < self.period_s:
            return False
        c = service.counters
        doc = {"schema": HEALTH_SCHEMA, "pid": os.getpid(), "written_wall_s": now,
               "uptime_s": now - self.started_s, "last_step_frame_time_s": service.frame_time_s,
               "steps": c.get("steps", 0), "initialised": service.state is not None,
               "degraded_mode_steps": dict(c.get("mode_steps", {})), "time_jumps": c.get("time_jumps", 0),
               "frames_sent": c.get("frames_sent", 0),
               "decoder": {k: v for k, v in service.decoder.counters.items() if k in ("frames_seen", "frames_used",
                                                                                     "rejected")},
               "state": None if store is None else {**store.counters, "path": str(store.path),
                                                    "last_save_age_s": store.age_s()},
               "bus": bus_events or {}, "health_write_errors": self.errors}
        try:
            atomic_write(self.path, json.dumps(doc, default=str).encode("utf-8"))
        except OSError as exc:
            # not fatal to the sensor, but said: `status` would otherwise report a service that is not running
            self.errors += 1
            if self.errors == 1:
                log.warning("cannot write the health file %s: %s (further errors counted, not logged; `status` "
                            "will not see this service)", self.path, exc)
            self.last_write_s = now           # retried after a period, not at every step
            return False
        self.last_write_s = now
        return True


def read_health(path) -> dict:
    """The health document a running service wrote (ValueError when the file is not one)."""
    doc = json.loads(Path(path).read_bytes())
    if not isinstance(doc, dict) or doc.get("schema") != HEALTH_SCHEMA:
        raise ValueError("not a gearbox-vsensor health file")
    return doc


def sd_notify(message: str) -> bool:
    """Send ``message`` (``READY=1``, ``WATCHDOG=1``, ``STOPPING=1``) to systemd when it started us with
    ``NOTIFY_SOCKET`` (Type=notify, WatchdogSec=); False when not under systemd or the socket is gone."""
    addr = os.environ.get("NOTIFY_SOCKET")
    if not addr:
        return False
    if addr.startswith("@"):
        addr = "\0" + addr[1:]           # abstract namespace
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM) as s:
            s.connect(addr)
            s.sendall(message.encode("ascii"))
        return True
    except OSError:
        return False


def watchdog_period_s() -> float | None:
    """Half the watchdog interval systemd asks for (WATCHDOG_USEC), or None without a watchdog."""
    usec = os.environ.get("WATCHDOG_USEC")
    try:
        return int(usec) / 2e6 if usec else None
    except ValueError:
        return None
