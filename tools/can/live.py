"""The onboard sensor live on a CAN bus: the library behind `gearbox-vsensor run`.

J1939 frames in (receive filters on the needed PGNs), the sensor stepped every 100 ms of frame time, GBX_* frames
and DM1 out (``firmware_model.service``, docs/can.md). SIGINT and SIGTERM stop it cleanly: the loop drains the
frames already received, stops the notifier, shuts the bus down and returns. The signals are taken by a thread of
their own (:class:`SignalWatcher`), never inside the loop's wait for frames, which could then hang on a silent bus.
"""

from __future__ import annotations

import logging
import os
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

    def __enter__(self) -> SignalWatcher:
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
    state_file: str | None = None  # the sensor state across restarts (None: cold start every time)
    state_period_s: float = 60.0  # save the state this often [s] of wall time (and on shutdown)
    health_file: str | None = None  # the health `gearbox-vsensor status` reads (None: none written)

    def check(self) -> None:
        if self.duration_s is not None and not self.duration_s > 0:
            raise InputError(f"--duration {self.duration_s} must be a positive number of seconds")
        if not 1.0 <= self.state_period_s <= 86400.0:
            raise InputError(f"--state-period {self.state_period_s:g} must be within 1..86400 s")
        for opt, f in (("--state-file", self.state_file), ("--health-file", self.health_file)):
            if f is not None and not os.path.isdir(os.path.dirname(os.path.abspath(f))):
                raise InputError(f"{opt} {f}: its directory does not exist")
            if f is not None and os.path.isdir(f):
                raise InputError(f"{opt} {f} is a directory, not a file")
        if (
            self.state_file
            and self.health_file
            and os.path.abspath(self.state_file) == os.path.abspath(self.health_file)
        ):
            raise InputError(
                f"--state-file and --health-file are the same file {self.state_file}: one would overwrite the other"
            )
        check_bitrate(self.bitrate_bit_s)


class GatewayHooks:
    """What a gateway does besides the sensor, from the serve loop's ticks (firmware_model.service.persist): save
    the state every ``state_period_s`` and at the end, rewrite the health file every second, and keep systemd's
    watchdog fed (READY=1 once listening, WATCHDOG=1 at half its interval, STOPPING=1 at the end)."""

    def __init__(self, settings: LiveSettings, service):
        from firmware_model.service.persist import HealthFile, StateStore, watchdog_period_s

        self.service = service
        # the periodic saves in a writer thread: a slow fsync (SD card, eMMC) must not hold up the outputs
        self.store = (
            StateStore(settings.state_file, settings.state_period_s, background=True) if settings.state_file else None
        )
        self.health = (
            HealthFile(settings.health_file, interface=settings.interface, channel=settings.channel)
            if settings.health_file
            else None
        )
        self.watchdog_s = watchdog_period_s()
        self._last_watchdog = 0.0
        if self.store is not None:
            restore = self.store.load(service.sensor)
            if restore is not None:
                service.restore = restore

    def ready(self) -> None:
        from firmware_model.service.persist import sd_notify

        sd_notify("READY=1")

    def tick(self) -> None:
        import time

        from firmware_model.service.persist import Restore, sd_notify

        if self.store is not None:
            svc = self.service
            if svc.state is None and svc.restore is not None:  # not restored yet: cooled until now
                r = svc.restore
                svc.restore = Restore(r[0], self.store.elapsed_s(), getattr(r, "clean_stop", True))
            self.store.maybe_save(svc)
        if self.health is not None:
            self.health.maybe_write(self.service, self.store)
        if self.watchdog_s is not None:
            now = time.monotonic()
            if now - self._last_watchdog >= self.watchdog_s:
                self._last_watchdog = now
                sd_notify("WATCHDOG=1")

    def finish(self) -> None:
        from firmware_model.service.persist import sd_notify

        sd_notify("STOPPING=1")
        if self.store is not None and self.store.save(self.service, final=True):
            log.info("sensor state saved to %s", self.store.path)
        if self.health is not None:
            self.health.maybe_write(self.service, self.store, stopped=True)


def _log_summary(result) -> None:
    """Log what a finished run did: frames, bus outages and the step latency."""
    log.info(
        "stopped (%s): %d frames in, %d frames out, %d send errors, %.1f s, CPU %.1f %% of one core",
        {"stop": "signal", "duration": "--duration"}.get(result.reason, result.reason),
        result.frames_in,
        result.frames_out,
        result.send_errors,
        result.wall_s,
        100.0 * result.cpu_share,
    )
    if result.bus_events.get("read_errors"):
        log.warning(
            "bus: %d receive outages, %d receive errors, %d resumes, %d reopens, %d failed reopen attempts",
            result.bus_events["outages"],
            result.bus_events["read_errors"],
            result.bus_events["resumes"],
            result.bus_events["reopens"],
            result.bus_events["reopen_failures"],
        )
    latency = result.latency()
    if latency is not None:
        log.info(
            "step latency (completing frame received -> its outputs sent): median %.2f ms, p99 %.2f ms, "
            "max %.2f ms over %d steps",
            latency.median_ms,
            latency.p99_ms,
            latency.max_ms,
            latency.steps,
        )


def run_live(settings: LiveSettings):
    """Run the service with the onboard sensor on the bus until SIGINT/SIGTERM or the duration; logs the counters,
    the trust findings (WARNING when the outputs should not be trusted) and a summary; returns the
    ``ServeResult``."""
    from firmware_model.service import build_service, can_filters, serve

    settings.check()
    service = build_service(settings.config_path, address_claim=True)  # a node on the bus: J1939-81
    if hasattr(service.sensor, "warm_up"):
        service.sensor.warm_up()  # the first time jump after an outage does not pay for first use on the bus
    filters = can_filters(rig=settings.rig) if settings.filters else None
    if settings.rt_priority is not None:
        set_realtime_priority(settings.rt_priority)
    bus = open_bus(settings.interface, settings.channel, settings.bitrate_bit_s, filters)

    hooks = GatewayHooks(settings, service)
    # frames stamped with the system clock: its steps (NTP, GNSS) are no time without frames
    from firmware_model.service.live import FrameClock
    from tools.can.bus import SENDER_TIMESTAMP_INTERFACES

    frame_clock = None if settings.interface in SENDER_TIMESTAMP_INTERFACES else FrameClock(service.log)

    def ready():
        log.info(
            "listening on %s %s (%s); sending as source address 0x%02X",
            settings.interface,
            settings.channel,
            "no receive filters" if filters is None else f"{len(filters)} receive filters",
            service.encoder.source_address,
        )
        hooks.ready()

    # the final save runs while the signals still only set `stop`: a second SIGTERM (systemd's, a user's) during
    # it would otherwise kill the process with the last state unsaved
    with stop_on_signals() as stop, SignalWatcher(stop):
        try:
            result = serve(
                bus,
                service,
                stop=stop,
                duration_s=settings.duration_s,
                on_ready=ready,
                on_tick=hooks.tick,
                reopen=lambda: open_bus(settings.interface, settings.channel, settings.bitrate_bit_s, filters),
                frame_clock=frame_clock,
            )
        finally:
            try:
                bus.shutdown()
            except (OSError, RuntimeError, ValueError):
                pass  # already shut down after a receive error
            hooks.finish()
    service.log_counters()
    service.log_findings()  # firmware_model.service.trust: time base, source addresses, degraded share
    _log_summary(result)
    return result
