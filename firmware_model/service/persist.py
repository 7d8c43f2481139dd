"""What the live service keeps across ignition cycles and shows a technician (docs/gateway.md).

* :class:`StateStore`: the sensor state saved to a file every ``period_s`` of wall time and on shutdown (atomic:
  a temporary file in the same directory, fsync, rename; never a half-written file; at most one write per period
  for flash wear; with ``background=True`` the periodic writes run in a writer thread, so a slow fsync on an SD card
  or eMMC does not hold up the outputs, and the shutdown save waits for it), and restored at start: cooled for the wall
  time the gateway was off, reconciled with the first
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
import math
import os
import socket
import threading
import time
from pathlib import Path
from typing import NamedTuple

STATE_SCHEMA = "vsensor-state/1"
HEALTH_SCHEMA = "vsensor-health/1"
#: default period of the state saves [s] (flash wear: about 1500 writes a day)
STATE_PERIOD_S = 60.0
#: the health file is rewritten this often [s]
HEALTH_PERIOD_S = 1.0
#: the shutdown save waits this long for a periodic save still being written [s]
SAVE_WAIT_S = 20.0

log = logging.getLogger("gearbox_vsensor.state")


def atomic_write(path: Path, data: bytes, durable: bool = True) -> None:
    """Write ``data`` to ``path`` so that a reader (or, ``durable``: with fsync, a power cut) sees the old file or
    the new one, never half."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            if durable:
                os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


#: a state saved more than this far in the future of the wall clock at start [s]: the clock is wrong (set back, or
#: not yet set at boot on a gateway without a real-time clock), so the time off is unknown: a cold start
FUTURE_TOLERANCE_S = 300.0


class Restore(NamedTuple):
    """A saved state to start from (:meth:`StateStore.load`): the snapshot, the wall time since its last step [s],
    and whether it was saved at a clean stop (False: by a periodic save while stepping, so the service died while
    the truck drove and the engine is taken to have run on; files from before this field count as clean)."""

    snapshot: object
    elapsed_s: float
    clean_stop: bool = True


class StateStore:
    """The sensor state in a file across restarts: :meth:`load` at start, :meth:`maybe_save` from the loop,
    :meth:`save` at shutdown. ``clock``: wall time [s] (stored: the time off between runs); ``timer``: the clock of
    the save period (monotonic: a wall clock set back must not stop the saves); both injectable for tests."""

    def __init__(
        self, path, period_s: float = STATE_PERIOD_S, clock=time.time, timer=time.monotonic, background: bool = False
    ):
        self.path = Path(path)
        self.period_s = float(period_s)
        self.clock, self.timer = clock, timer
        #: the periodic saves write in a thread (the live gateway); :meth:`save` itself always writes now
        self.background = background
        self._writing: threading.Thread | None = None
        self.last_save_s: float | None = None  # timer: the last attempt
        self.last_ok_s: float | None = None  # timer: the last save that was written
        self.stepped_wall_s: float | None = None  # wall time when the state last changed (a step)
        self._steps_seen: int | None = None
        self.loaded_saved_wall_s = math.nan  # the time of the state :meth:`load` returned
        self._saved_steps: int | None = None
        self.counters = {"restored": 0, "cold_starts": 0, "saves": 0, "save_errors": 0, "reason": None}

    def load(self, sensor) -> tuple | None:
        """The :class:`Restore` of a usable saved state for ``sensor``, or None (a cold start: the reason is
        logged and counted). A state is usable when the file parses, has this schema, was taken with the same
        thermal network (the sensor's own snapshot check) and saved at a wall time that is not in the future."""
        reason = None
        try:
            doc = json.loads(self.path.read_bytes())
            if not isinstance(doc, dict) or doc.get("schema") != STATE_SCHEMA:
                reason = "not a saved sensor state (schema)"
            elif doc.get("nodes") != list(sensor.reduced.nodes) or doc.get("variant") != sensor.reduced.variant:
                reason = f"saved by another gearbox or network ({doc.get('variant')!r})"
            elif not isinstance(doc.get("snapshot"), (dict, str)):
                reason = "not a saved sensor state (no snapshot)"
            elif not (isinstance(doc.get("saved_wall_s"), (int, float)) and math.isfinite(doc["saved_wall_s"])):
                reason = "not a saved sensor state (no time of saving)"
            elif doc["saved_wall_s"] > self.clock() + FUTURE_TOLERANCE_S:
                reason = (
                    f"saved {doc['saved_wall_s'] - self.clock():.0f} s in the future of this clock (the "
                    f"system clock was set back, or is not yet set): the time off is unknown"
                )
        except FileNotFoundError:
            reason = "no saved state"
        except (OSError, ValueError, UnicodeDecodeError) as exc:
            reason = f"unreadable or truncated ({exc.__class__.__name__})"
        if reason is None:
            self.loaded_saved_wall_s = float(doc["saved_wall_s"])
            return Restore(doc["snapshot"], self.elapsed_s(), doc.get("clean_stop") is not False)
        self.cold_start(reason)
        return None

    def elapsed_s(self) -> float:
        """Wall time since the loaded state was taken, now (the restore happens at the first frame, which may come
        long after the start: :class:`GatewayHooks` refreshes it until then)."""
        return max(self.clock() - self.loaded_saved_wall_s, 0.0)

    def cold_start(self, reason: str) -> None:
        self.counters["cold_starts"] += 1
        self.counters["reason"] = reason
        log.warning("state %s: %s; cold start from the oil temperature", self.path, reason)

    def _note_steps(self, service) -> int:
        """The service's step count; the wall time of the call where it last changed is when the state was taken
        (a bus that fell silent leaves the state as it was: its time is that of the last step, not of a save)."""
        steps = int(service.counters.get("steps", 0))
        if steps != self._steps_seen:
            self._steps_seen = steps
            self.stepped_wall_s = self.clock()
        return steps

    def maybe_save(self, service) -> bool:
        """Save when ``period_s`` has passed since the last save attempt (``timer``), the sensor is initialised and
        it stepped since the last save (an unchanged state is not written again: flash wear)."""
        steps = self._note_steps(service)
        now = self.timer()
        if self.last_save_s is not None and now - self.last_save_s < self.period_s:
            return False
        if steps == self._saved_steps:
            return False
        if not self.background:
            return self.save(service)
        if self.writing:  # the last write is still in its fsync: not a second one behind it
            return False
        job = self._job(service)
        if job is None:
            return False
        self._writing = threading.Thread(target=self._write, args=job, name="state-save", daemon=True)
        try:
            self._writing.start()
        except RuntimeError as exc:  # no thread to be had: write now rather than not at all
            self._writing = None
            log.warning("cannot start the state writer thread (%s): saving in the loop", exc)
            return self._write(*job)
        return True

    @property
    def writing(self) -> bool:
        """True while a background save is being written."""
        return self._writing is not None and self._writing.is_alive()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Wait for a background save to finish; False if it is still writing after ``timeout_s``."""
        if self._writing is not None:
            self._writing.join(timeout_s)
        return not self.writing

    def save(self, service, final: bool = False) -> bool:
        """Write the state now (``final``: at shutdown, a failure is logged whatever came before), after a
        background save still being written (waited for up to SAVE_WAIT_S: a write hung in its fsync does not
        hold the shutdown for ever). A failed write is counted and tried again a period later, not at every tick."""
        if not self.wait(SAVE_WAIT_S):
            log.warning(
                "a state save has been writing %s for %.0f s (a hung storage?): writing the state now beside it",
                self.path,
                SAVE_WAIT_S,
            )
        job = self._job(service, clean_stop=final)
        return False if job is None else self._write(*job, final=final)

    def _job(self, service, clean_stop: bool = False) -> tuple | None:
        """(file content, step count, timer) of the state now, taken in the loop's thread; None before the first
        step. ``clean_stop``: the shutdown save (a periodic one is made while stepping: if the service dies, the
        truck was driving; Restore)."""
        if service.state is None:
            return None
        steps = self._note_steps(service)
        sensor = service.sensor
        doc = {
            "schema": STATE_SCHEMA,
            "saved_wall_s": self.stepped_wall_s,
            "frame_time_s": service.frame_time_s,
            "variant": sensor.reduced.variant,
            "nodes": list(sensor.reduced.nodes),
            "clean_stop": bool(clean_stop),
            "snapshot": json.loads(sensor.snapshot(service.state)),
        }
        self.last_save_s = self.timer()
        return json.dumps(doc, separators=(",", ":")).encode("utf-8"), steps, self.last_save_s

    def _write(self, data: bytes, steps: int, taken_s: float, final: bool = False) -> bool:
        try:
            atomic_write(self.path, data)
        except OSError as exc:
            self.counters["save_errors"] += 1
            if self.counters["save_errors"] == 1 or final:
                log.warning(
                    "cannot save the state to %s%s: %s (%s)",
                    self.path,
                    " at shutdown" if final else "",
                    exc,
                    "the next start is a cold start"
                    if final
                    else f"tried again every {self.period_s:g} s; further errors counted, not logged",
                )
            return False
        self._saved_steps = steps
        self.last_ok_s = taken_s
        self.counters["saves"] += 1
        return True

    def age_s(self) -> float | None:
        """Seconds since the last save that was written (None: none yet)."""
        return None if self.last_ok_s is None else self.timer() - self.last_ok_s


def boot_clock() -> float:
    """Seconds since boot, counting time suspended (Linux CLOCK_BOOTTIME; elsewhere the monotonic clock): the
    clock against which a step of the wall clock is told from time that passed (a suspended gateway's time
    passes)."""
    return time.clock_gettime(time.CLOCK_BOOTTIME) if hasattr(time, "CLOCK_BOOTTIME") else time.monotonic()


def boot_id() -> str | None:
    """This boot's id (Linux): two processes comparing monotonic clocks must be on the same boot."""
    try:
        return Path("/proc/sys/kernel/random/boot_id").read_text().strip()
    except OSError:
        return None


class HealthFile:
    """The service's health for ``gearbox-vsensor status``: rewritten every ``period_s`` (``timer``: monotonic, so
    a wall clock set back does not stop it). It carries the time since boot of writing (:func:`boot_clock`) with the
    boot id, so that `status` judges its age without the wall clock."""

    def __init__(
        self,
        path,
        period_s: float = HEALTH_PERIOD_S,
        clock=time.time,
        timer=time.monotonic,
        interface: str | None = None,
        channel: str | None = None,
    ):
        self.path = Path(path)
        # the bus it listens on, for `status` to name when no input frame arrives (None: not known)
        self.interface, self.channel = interface, channel
        self.period_s = float(period_s)
        self.clock, self.timer = clock, timer
        self.started_s = timer()
        self.last_write_s: float | None = None
        self.errors = 0  # writes that failed (the first is logged)
        self.boot_id = boot_id()
        self._steps_seen: int | None = None  # the service's step count at the last write ...
        self._stepped_s: float | None = None  # ... and the timer when it last changed (None: never stepped)

    def maybe_write(
        self, service, store: StateStore | None = None, bus_events: dict | None = None, stopped: bool = False
    ) -> bool:
        """Rewrite the file when a period has passed (``stopped``: the last write of a clean stop, now)."""
        now = self.timer()
        if not stopped and self.last_write_s is not None and now - self.last_write_s < self.period_s:
            return False
        c = service.counters
        restored = c.get("state_restored") is True
        steps = c.get("steps", 0)
        if steps != self._steps_seen:
            self._steps_seen = steps
            self._stepped_s = now if steps else None
        doc = {
            "schema": HEALTH_SCHEMA,
            "pid": os.getpid(),
            "written_wall_s": self.clock(),
            "written_boottime_s": boot_clock(),
            "boot_id": self.boot_id,
            "stopped": stopped,
            "interface": self.interface,
            "channel": self.channel,
            "uptime_s": now - self.started_s,
            "last_step_frame_time_s": service.frame_time_s,
            "steps": steps,
            "initialised": service.state is not None,
            # how long since the step count last moved (a service whose inputs stopped steps no more)
            "last_step_age_s": None if self._stepped_s is None else now - self._stepped_s,
            "degraded_mode_now": c.get("mode_now"),
            "degraded_mode_steps": dict(c.get("mode_steps", {})),
            "time_jumps": c.get("time_jumps", 0),
            "clock_steps": c.get("clock_steps", 0),
            "bus_off": c.get("bus_off", 0),
            "frames_sent": c.get("frames_sent", 0),
            "frames_held_no_address": c.get("frames_held_no_address", 0),
            "decoder": {
                k: v for k, v in service.decoder.counters.items() if k in ("frames_seen", "frames_used", "rejected")
            },
            "state": None
            if store is None
            else {
                **store.counters,
                "restored": int(restored),
                "path": str(store.path),
                "last_save_age_s": store.age_s(),
                # a saved state the sensor could not use is a cold start decided at the first step
                "cold_starts": store.counters["cold_starts"] + int("state_cold_start" in c),
                "reason": c.get("state_cold_start") or store.counters["reason"],
            },
            "j1939": None
            if getattr(service, "netmgmt", None) is None
            else {"address": service.netmgmt.address, **service.netmgmt.counters},
            "bus": dict(bus_events or getattr(service, "bus_events", None) or {}),
            # the whole-record findings (firmware_model.service.plausibility), judged after the first minute
            "findings": list(c.get("record_findings", [])),
            # the live time-base check (firmware_model.service.trust): suspect now, and its first sentence
            "time_base": time_base_health(c.get("time_base") or {}),
            "health_write_errors": self.errors,
        }
        try:
            # no fsync: rewritten every second (a power cut loses nothing it needs); the rename stays atomic
            atomic_write(self.path, json.dumps(doc, default=str).encode("utf-8"), durable=False)
        except OSError as exc:
            # not fatal to the sensor, but said: `status` would otherwise report a service that is not running
            self.errors += 1
            if self.errors == 1:
                log.warning(
                    "cannot write the health file %s: %s (further errors counted, not logged; `status` "
                    "will not see this service)",
                    self.path,
                    exc,
                )
            self.last_write_s = now  # retried after a period, not at every step
            return False
        self.last_write_s = now
        return True


def time_base_health(tb: dict) -> dict:
    """The health file's ``time_base``: suspect now (the frames' time stamps against their J1939 periods), the
    windows checked and suspect, and the sentence of the first suspect window (None: none yet)."""
    return {
        "suspect": bool(tb.get("suspect", False)),
        "windows_checked": int(tb.get("windows_checked", 0)),
        "windows_suspect": int(tb.get("windows_suspect", 0)),
        "sentence": tb.get("sentence"),
    }


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
        addr = "\0" + addr[1:]  # abstract namespace
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
