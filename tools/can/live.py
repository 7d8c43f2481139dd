"""The onboard sensor live on a CAN bus: the library behind `gearbox-vsensor run`.

J1939 frames in (receive filters on the needed PGNs), the sensor stepped every 100 ms of frame time, GBX_* frames
and DM1 out (``firmware_model.service``, docs/can.md). SIGINT and SIGTERM stop it cleanly: the loop drains the
frames already received, stops the notifier, shuts the bus down and returns. The signals are taken by a thread of
their own (:class:`SignalWatcher`), never inside the loop's wait for frames, which could then hang on a silent bus.
"""
from __future__ import annotations

import logging
import signal
import threading
from dataclasses import dataclass

from firmware_model.errors import InputError
from tools.can.bus import STOP_SIGNALS, check_bitrate, open_bus, stop_on_signals

log = logging.getLogger("gearbox_vsensor.run")
#: real-time priorities SCHED_FIFO takes
RT_PRIORITY_RANGE = (1, 99)


class SignalWatcher:
    """While active, SIGINT and SIGTERM are taken by a thread of their own (``signal.sigwait``) that sets ``stop``;
    they are blocked in the calling thread and in the threads it starts meanwhile (the notifier's).

    Why: CPython 3.11's ``queue.SimpleQueue.get(timeout)``, where the live loop waits for frames, waits *forever* when
    a signal handler that runs inside it (the signal interrupted its wait) outlasts the timeout: it recomputes the
    timeout, gets a negative one and a negative timeout means no timeout; only the next frame would wake it, and a
    silent bus sends none. Seen on a slow (emulated) CPU as `run` hanging after SIGTERM. A signal that still reaches
    another thread runs the Python handler (``on_signal``) between bytecodes, never inside that wait. Without
    ``pthread_sigmask``/``sigwait`` (Windows) this does nothing and the handlers alone stop the loop.
    """

    def __init__(self, stop: threading.Event, signals=STOP_SIGNALS):
        self.stop = stop
        self.signals = set(signals)
        self.available = hasattr(signal, "pthread_sigmask") and hasattr(signal, "sigwait")
        self._old_mask = None
        self._thread: threading.Thread | None = None
        self._done = False

    def _watch(self) -> None:
        while True:
            signal.sigwait(self.signals)
            if self._done:
                return
            self.stop.set()

    def __enter__(self) -> "SignalWatcher":
        if self.available:
            self._old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, self.signals)
            self._thread = threading.Thread(target=self._watch, name="signal-watcher", daemon=True)
            self._thread.start()  # inherits the blocked mask, as sigwait needs
        return self

    def __exit__(self, *exc) -> None:
        if self._thread is not None:
            self._done = True
            signal.pthread_kill(self._thread.ident, signal.SIGTERM)  # to that thread only: its sigwait takes it
            self._thread.join(timeout=1.0)
            self._thread = None
        if self._old_mask is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, self._old_mask)
            self._old_mask = None


def set_realtime_priority(priority: int) -> None:
    """SCHED_FIFO for the calling thread and the threads it starts later (the notifier)."""
    import os
    low, high = RT_PRIORITY_RANGE
    if not low <= priority <= high:
        raise InputError(f"--rt-priority {priority} must be in {low}..{high}")
    if not hasattr(os, "sched_setscheduler"):
        raise InputError("--rt-priority needs Linux real-time scheduling (os.sched_setscheduler)")
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except PermissionError:
        raise InputError(f"--rt-priority {priority}: not permitted (needs root or CAP_SYS_NICE)") from None


@dataclass(frozen=True)
class LiveSettings:
    """What `gearbox-vsensor run` was asked for: the bus (``bitrate_bit_s`` None: the interface's), the project
    configuration (None: defaults), a wall-time limit (None: until a signal), receive filters on the wanted PGNs
    (False: every frame), the rig thermocouple frames, a SCHED_FIFO priority (None: normal scheduling)."""
    interface: str
    channel: str
    bitrate_bit_s: int | None = None
    config_path: str | None = None
    duration_s: float | None = None
    filters: bool = True
    rig: bool = False
    rt_priority: int | None = None

    def check(self) -> None:
        if self.duration_s is not None and not self.duration_s > 0:
            raise InputError(f"--duration {self.duration_s} must be a positive number of seconds")
        check_bitrate(self.bitrate_bit_s)


def run_live(settings: LiveSettings):
    """Run the service with the onboard sensor on the bus until SIGINT/SIGTERM or the duration; logs the counters,
    the trust findings (WARNING when the outputs should not be trusted) and a summary; returns the
    ``ServeResult``."""
    from firmware_model.service import build_service, can_filters, serve
    settings.check()
    service = build_service(settings.config_path)
    filters = can_filters(rig=settings.rig) if settings.filters else None
    if settings.rt_priority is not None:
        set_realtime_priority(settings.rt_priority)
    bus = open_bus(settings.interface, settings.channel, settings.bitrate_bit_s, filters)

    def ready():
        log.info("listening on %s %s (%s); sending as source address 0x%02X", settings.interface, settings.channel,
                 "no receive filters" if filters is None else f"{len(filters)} receive filters",
                 service.encoder.source_address)

    try:
        with stop_on_signals() as stop, SignalWatcher(stop):
            result = serve(bus, service, stop=stop, duration_s=settings.duration_s, on_ready=ready)
    finally:
        bus.shutdown()
    service.log_counters()
    service.log_findings()   # firmware_model.service.trust: time base, source addresses, degraded share
    log.info("stopped (%s): %d frames in, %d frames out, %d send errors, %.1f s, CPU %.1f %% of one core",
             {"stop": "signal", "duration": "--duration"}.get(result.reason, result.reason), result.frames_in,
             result.frames_out, result.send_errors, result.wall_s, 100.0 * result.cpu_share)
    latency = result.latency()
    if latency is not None:
        log.info("step latency (completing frame received -> its outputs sent): median %.2f ms, p99 %.2f ms, "
                 "max %.2f ms over %d steps", latency.median_ms, latency.p99_ms, latency.max_ms, latency.steps)
    return result
