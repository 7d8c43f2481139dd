"""The CAN service live: a python-can bus, a listener that only queues frames (:class:`QueueListener`, run by the
``can.Notifier`` thread) and one loop, :func:`serve`, that owns time: it takes the frames in order, feeds the
:class:`~firmware_model.service.core.SensorService` and sends what it returns."""

from __future__ import annotations

import math
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import can
import numpy as np

from firmware_model.service.core import SensorService
from firmware_model.service.persist import boot_clock

#: a step's latency figures keep the last this many steps (then the older half is dropped)
LATENCY_KEEP_STEPS = 100_000
#: send errors are logged at most once per this many seconds of wall time
SEND_ERROR_LOG_PERIOD_S = 10.0
#: back-off between attempts to reopen a bus that cannot be opened [s]: doubling from the first to the last
REOPEN_BACKOFF_S = (0.5, 30.0)
#: after a receive error the loop first resumes reading the same bus after this delay [s], doubling while errors
#: follow each other without a frame (at most twice: 0.1, 0.2 s, so that frames wait at most that long once the bus
#: is back); after RESUME_LIMIT such errors it closes and reopens the bus ...
RESUME_DELAY_S = 0.1
RESUME_LIMIT = 3
#: ... but within one outage reopens after errors come at least this far apart [s], doubling from the first to the
#: second: a bus whose reads fail at once (a dead adapter) was reopened every 0.3 s
ERROR_REOPEN_GAP_S = (0.5, 30.0)
#: the notifier's thread waits this long after reporting a receive error, unless the loop takes it first [s]:
#: python-can's Notifier goes on reading after an error a listener handled, so without the pause a bus whose reads
#: fail at once reports ~40 000 errors a second at ~45 % CPU
ERROR_PAUSE_S = 0.1
#: an outage that stays silent (no frame, no error) is treated as a dead handle: the bus is reopened after the
#: first of these [s], then with the delay doubling up to the second
SILENT_REOPEN_S = (1.0, 30.0)
#: the wall clock set by more than this is a step of the clock that stamps the frames (FrameClock) [s]; a step the
#: frames do not show for CLOCK_ADOPT_S of reception time is not theirs (their clock is another)
CLOCK_STEP_S = 2.0
CLOCK_ADOPT_S = 10.0
#: linux/can/error.h: the error class bit of an error frame that reports the controller in bus-off
CAN_ERR_BUSOFF = 0x40
#: a bus-off error frame this long [s] after the previous one is the same episode (logged once)
BUS_OFF_EPISODE_S = 10.0


class FrameClock:
    """Frame times on one continuous base. Most interfaces stamp frames with the system's wall clock (SocketCAN's
    kernel, udp_multicast), which steps when it is set (NTP, GNSS, an RTC read at boot): an hour's step read as an
    hour without frames would cool a driving gearbox for an hour. The wall clock's own offset from the time since
    boot (:func:`~firmware_model.service.persist.boot_clock`, which counts a suspend: a suspended gateway's time
    passes) changes only when the clock is set; when it has moved by more than ``step_s`` and the frames' spacing
    departs from their reception times' by the same amount, the frames stepped with it: the step is taken out of
    every later frame time (counted, logged). A pause of the bus, a suspend, a backlog of frames received late, or
    timestamps that are not the wall clock (an adapter's hardware clock, zeros) are left as they are; when the wall
    clock moved but the frames do not show it for ``adopt_s``, they do not follow it and the new offset is adopted.
    Not for frames that carry their sender's time (python-can's virtual bus replaying a log)."""

    def __init__(
        self,
        log=None,
        step_s: float = CLOCK_STEP_S,
        adopt_s: float = CLOCK_ADOPT_S,
        wall: Callable[[], float] = time.time,
        boot: Callable[[], float] = boot_clock,
    ):
        self.log, self.step_s, self.adopt_s, self.wall, self.boot = log, step_s, adopt_s, wall, boot
        self.ref_offset_s: float | None = None  # wall - boot for the frames' base so far
        self.prev: tuple[float, float] | None = None  # (frame time, reception time) of the last frame
        self.unseen_since_s: float | None = None  # reception time since the wall clock moved unseen by the frames
        self.correction_s = 0.0  # taken out of every frame time so far
        self.steps = 0

    def __call__(self, t_frame_s: float, t_received_s: float) -> float:
        if not math.isfinite(t_frame_s):
            return t_frame_s
        offset_s = self.wall() - self.boot()
        if self.ref_offset_s is None:
            self.ref_offset_s = offset_s
        moved_s = offset_s - self.ref_offset_s
        if abs(moved_s) <= self.step_s:
            self.ref_offset_s = offset_s  # a slew (NTP's slow corrections) is no step
            self.unseen_since_s = None
        elif self.prev is not None:
            mismatch_s = (t_frame_s - self.prev[0]) - (t_received_s - self.prev[1])
            if abs(mismatch_s - moved_s) < self.step_s:  # the frames stepped with the wall clock
                self._step(moved_s, offset_s)
            elif self.unseen_since_s is None:
                self.unseen_since_s = t_received_s
            elif t_received_s - self.unseen_since_s > self.adopt_s:
                self.ref_offset_s, self.unseen_since_s = offset_s, None  # these frames do not follow it
        self.prev = (t_frame_s, t_received_s)
        return t_frame_s - self.correction_s

    def _step(self, step_s: float, offset_s: float) -> None:
        self.correction_s += step_s
        self.ref_offset_s, self.unseen_since_s = offset_s, None
        self.steps += 1
        if self.log is not None:
            self.log.warning(
                "the system clock that stamps the frames was set by %+.1f s (NTP, GNSS, RTC); the "
                "sensor's time continues without the step (%d clock steps so far)",
                step_s,
                self.steps,
            )


class QueueListener:
    """A python-can listener that only queues frames (the Notifier's thread calls it)."""

    def __init__(self) -> None:
        # queue.Queue, not SimpleQueue: CPython 3.11's SimpleQueue.get(timeout) waits forever when a signal handler
        # that runs inside the wait outlasts the timeout (seen as `run` hanging after SIGTERM on a silent bus in the
        # QEMU VM); Queue waits on a lock whose timed acquire keeps its deadline. ~2 us more per frame.
        self.queue: queue.Queue = queue.Queue()
        self.errors: list[BaseException] = []
        #: frames received so far (only the Notifier's thread writes it)
        self.received = 0
        self._released = threading.Event()

    def __call__(self, msg) -> None:
        self.on_message_received(msg)

    def on_message_received(self, msg) -> None:
        self.received += 1
        self.queue.put((msg, boot_clock()))  # with the time of reception since boot (FrameClock)

    def on_error(self, exc: BaseException) -> None:
        """Keep the error for the loop, and hold the notifier's thread until the loop takes it (at most
        ERROR_PAUSE_S): no storm of reads that fail at once."""
        self.errors.append(exc)
        self._released.wait(ERROR_PAUSE_S)

    def release(self) -> None:
        """Let a notifier's thread held in :meth:`on_error` go (its notifier is being stopped)."""
        self._released.set()

    def rearm(self) -> None:
        """Hold the next notifier's thread after an error again."""
        self._released.clear()

    def stop(self) -> None:
        pass


@dataclass
class Outage:
    """A receive outage of :class:`BusLink`: from the first receive error to the first frame after it."""

    start_s: float  # monotonic clock
    frames_at_start: int
    next_reopen_s: float  # when a silent outage reopens the bus next
    reopen_delay_s: float
    consecutive: int = 0  # receive errors since the last frame or reopen
    next_error_reopen_s: float = 0.0  # the earliest time of the next reopen after errors (monotonic)
    error_reopen_gap_s: float = ERROR_REOPEN_GAP_S[0]
    errors: int = 0
    reopen_failed: bool = False  # a reopen failed in this outage (logged once per outage)


class BusLink:
    """The bus and the notifier that feeds the listener, and what the loop does when receiving fails (the interface
    went down, the controller went bus-off, a read failed): it is an *outage* until the next frame arrives, logged
    once when it starts (warning) and once when it ends (info), and counted (``events``). Within an outage:

    - after a receive error the loop resumes reading the same bus after RESUME_DELAY_S, doubling once while errors
      follow each other without a frame (SocketCAN reports an interface going down once per socket: the socket then
      waits and receives again as soon as the interface is up, with no frame lost to a reopen);
    - after RESUME_LIMIT such errors, or when the outage stays silent for SILENT_REOPEN_S (doubling to 30 s: a dead
      handle), the bus is closed and reopened with ``reopen`` (a factory), with a doubling back-off while it cannot
      be opened.

    Never a busy loop, never a crash; without ``reopen`` the first error is raised as before."""

    def __init__(
        self,
        bus,
        listener: QueueListener,
        reopen: Callable | None = None,
        log=None,
        on_wait: Callable[[], None] | None = None,
    ):
        self.bus, self.listener, self.reopen, self.log, self.on_wait = bus, listener, reopen, log, on_wait
        self.events = {"read_errors": 0, "outages": 0, "resumes": 0, "reopens": 0, "reopen_failures": 0}
        self.opened_here = False
        self.outage: Outage | None = None
        self.notifier = self._start_notifier()

    def _start_notifier(self) -> can.Notifier:
        self.listener.rearm()
        return can.Notifier(self.bus, [self.listener], timeout=0.1)

    def check(self, stop: threading.Event) -> None:
        """Raise, or recover from, a receive error the notifier reported; end or escalate an outage."""
        if self.listener.errors:
            self._on_error(stop)
        elif self.outage is not None:
            self._watch_outage(stop)

    def _wait(self, stop: threading.Event, seconds: float) -> None:
        """Wait (until ``stop``) while calling ``on_wait`` at least every second: the watchdog, the health file
        and the state saves go on while the bus is being reopened."""
        end = time.monotonic() + seconds
        while not stop.is_set():
            left = end - time.monotonic()
            if left <= 0:
                return
            stop.wait(min(left, 1.0))
            if self.on_wait is not None:
                self.on_wait()

    def _on_error(self, stop: threading.Event) -> None:
        exc = self.listener.errors[0]
        n_errors = len(self.listener.errors)
        self.listener.errors.clear()
        if self.reopen is None:
            raise exc
        self.events["read_errors"] += n_errors
        now = time.monotonic()
        o = self.outage
        if o is None:
            o = self.outage = Outage(now, self.listener.received, now + SILENT_REOPEN_S[0], SILENT_REOPEN_S[0])
            self.events["outages"] += 1
            if self.log is not None:
                self.log.warning(
                    "CAN receive error (%s): the sensor is blind until frames return; resuming, and "
                    "reopening the bus with back-off if it keeps failing",
                    exc,
                )
        o.errors += 1
        o.consecutive += 1
        self._stop_notifier()
        if o.consecutive >= RESUME_LIMIT and now >= o.next_error_reopen_s:
            self._reopen(stop)
            o.next_error_reopen_s = time.monotonic() + o.error_reopen_gap_s
            o.error_reopen_gap_s = min(2.0 * o.error_reopen_gap_s, ERROR_REOPEN_GAP_S[1])
        else:
            self._wait(stop, RESUME_DELAY_S * 2 ** (min(o.consecutive, RESUME_LIMIT - 1) - 1))
            self.events["resumes"] += 1
        if not stop.is_set():
            self.notifier = self._start_notifier()

    def _watch_outage(self, stop: threading.Event) -> None:
        o = self.outage
        now = time.monotonic()
        if self.listener.received > o.frames_at_start:
            self.outage = None
            if self.log is not None:
                self.log.info(
                    "CAN bus back after %.1f s (%d receive errors, %d reopens so far)",
                    now - o.start_s,
                    o.errors,
                    self.events["reopens"],
                )
        elif now >= o.next_reopen_s:
            self._stop_notifier()
            self._reopen(stop)
            self.notifier = self._start_notifier()
            o.reopen_delay_s = min(2.0 * o.reopen_delay_s, SILENT_REOPEN_S[1])
            o.next_reopen_s = time.monotonic() + o.reopen_delay_s

    def _stop_notifier(self) -> None:
        self.listener.release()
        try:
            self.notifier.stop(timeout=1.0)
        except (can.CanError, OSError, RuntimeError):
            pass

    def _reopen(self, stop: threading.Event) -> None:
        """Close the bus and open a new one, with a doubling back-off while that fails (or until ``stop``)."""
        if self.outage is not None:
            self.outage.consecutive = 0
        try:
            self.bus.shutdown()  # the failed bus, whoever opened it (a second shutdown is harmless)
        except (can.CanError, OSError, RuntimeError, ValueError):
            pass
        delay_s = REOPEN_BACKOFF_S[0]
        while not stop.is_set():
            try:
                self.bus = self.reopen()
            except (can.CanError, OSError, ValueError) as err:
                self.events["reopen_failures"] += 1
                first = self.outage is None or not self.outage.reopen_failed
                if self.outage is not None:
                    self.outage.reopen_failed = True
                if first and self.log is not None:  # once per outage
                    self.log.warning(
                        "cannot reopen the bus yet (%s); retrying with back-off up to %.0f s (failures counted)",
                        err,
                        REOPEN_BACKOFF_S[1],
                    )
                self._wait(stop, delay_s)
                delay_s = min(2.0 * delay_s, REOPEN_BACKOFF_S[1])
                continue
            self.opened_here = True
            self.events["reopens"] += 1
            if self.log is not None:
                self.log.debug("bus reopened (%d reopens so far)", self.events["reopens"])
            return

    def close(self) -> None:
        """Stop the notifier and shut down a bus this link opened itself (the caller shuts its own down)."""
        self._stop_notifier()
        if self.opened_here:
            try:
                self.bus.shutdown()
            except (can.CanError, OSError, RuntimeError):
                pass


@dataclass
class ServeResult:
    """What :func:`serve` did. ``step_latency_s``: per sent step, wall time from the receive timestamp of the frame
    that completed the step to the end of sending its frames (meaningful when the bus stamps frames with the wall
    clock, as socketcan, udp_multicast and virtual do; the last LATENCY_KEEP_STEPS steps)."""

    frames_in: int = 0
    frames_out: int = 0
    send_errors: int = 0
    wall_s: float = 0.0
    cpu_s: float = 0.0
    reason: str = ""
    step_latency_s: list = field(default_factory=list)
    bus_events: dict = field(default_factory=dict)

    @property
    def cpu_share(self) -> float:
        return self.cpu_s / self.wall_s if self.wall_s > 0 else 0.0

    def latency(self) -> LatencyFigures | None:
        """Median, p99 and max of ``step_latency_s`` (None without steps)."""
        if not self.step_latency_s:
            return None
        a = np.sort(np.asarray(self.step_latency_s)) * 1e3
        return LatencyFigures(float(np.median(a)), float(np.percentile(a, 99)), float(a[-1]), a.size)


class LatencyFigures(NamedTuple):
    """Step latency of a live run [ms] over ``steps`` sent steps."""

    median_ms: float
    p99_ms: float
    max_ms: float
    steps: int


class _FrameHandler:
    """What :func:`serve` does with one received frame: a bus-off error frame counted and logged once per episode,
    the frame time put on the :class:`FrameClock`'s base, the service fed, its frames sent (send errors counted,
    logged once per 10 s), the step's latency kept and the deferred part of the step run."""

    def __init__(self, service: SensorService, link: BusLink, result: ServeResult, on_sent, frame_clock):
        self.service, self.link, self.result, self.on_sent, self.frame_clock = (
            service,
            link,
            result,
            on_sent,
            frame_clock,
        )
        self.last_err_log_s = -math.inf
        self.last_bus_off_s = -math.inf

    def bus_off(self, t_received_s: float) -> None:
        """A SocketCAN error frame of the bus-off class: counted, logged once per episode (the frames stop coming;
        the sensor holds its inputs and its levels become 'not available' after 10 s, as for any silence)."""
        c = self.service.counters
        c["bus_off"] = c.get("bus_off", 0) + 1
        if t_received_s - self.last_bus_off_s > BUS_OFF_EPISODE_S:
            self.service.log.warning(
                "CAN controller bus-off (error frame; %d so far): no frames until it restarts "
                "(set the interface's restart-ms); the sensor holds its inputs",
                c["bus_off"],
            )
        self.last_bus_off_s = t_received_s

    def send(self, frame) -> None:
        result = self.result
        try:
            self.link.bus.send(frame)
            result.frames_out += 1
            if self.on_sent is not None:
                self.on_sent(frame)
        except can.CanError as exc:
            result.send_errors += 1
            now_s = time.perf_counter()
            if now_s - self.last_err_log_s > SEND_ERROR_LOG_PERIOD_S:
                self.last_err_log_s = now_s
                self.service.log.warning(
                    "cannot send %08X: %s (%d send errors so far)", frame.arbitration_id, exc, result.send_errors
                )

    def __call__(self, item) -> None:
        msg, t_received_s = item
        service, fc = self.service, self.frame_clock
        self.result.frames_in += 1
        if msg.is_error_frame and msg.arbitration_id & CAN_ERR_BUSOFF:
            self.bus_off(t_received_s)
        received_s = msg.timestamp
        if fc is not None:
            msg.timestamp = fc(received_s, t_received_s)
            if fc.steps:
                service.counters["clock_steps"] = fc.steps
        frames = service.feed(msg)
        if not frames:
            return
        for frame in frames:
            self.send(frame)
        latencies = self.result.step_latency_s
        if len(latencies) >= LATENCY_KEEP_STEPS:
            del latencies[: LATENCY_KEEP_STEPS // 2]
        latencies.append(time.time() - received_s)
        service.finish_pending()  # the slow part of the step, now that its frames are out


def serve(
    bus,
    service: SensorService,
    *,
    stop: threading.Event | None = None,
    duration_s: float | None = None,
    poll_s: float = 0.05,
    on_sent: Callable | None = None,
    on_ready: Callable[[], None] | None = None,
    on_tick: Callable[[], None] | None = None,
    reopen: Callable | None = None,
    frame_clock: FrameClock | None = None,
) -> ServeResult:
    """Run ``service`` on ``bus`` until ``stop`` is set or ``duration_s`` of wall time passed.

    A ``can.Notifier`` thread receives and queues frames (:class:`QueueListener`); this loop, in the calling thread,
    takes them in order, feeds the service and sends what it returns. On stop it drains the queue, stops the
    notifier and returns (the caller shuts the bus down). Send errors (a full transmit queue) are counted and logged
    once per 10 s, never fatal. The wall clock is only used for ``duration_s`` and the CPU figure.
    ``on_tick``: called after every frame and every empty wait (at least every ``poll_s``): the periodic state save,
    the health file and the systemd watchdog (firmware_model.service.persist), which check the time themselves.
    ``reopen``: a bus factory; with it a receive error is an outage that :class:`BusLink` rides out.
    ``frame_clock``: a :class:`FrameClock` for a bus that stamps frames with the system clock (steps taken out).
    """
    stop = stop or threading.Event()
    listener = QueueListener()
    result = ServeResult()
    wall0_s, cpu0_s = time.perf_counter(), time.process_time()
    deadline_s = None if duration_s is None else wall0_s + duration_s
    link = BusLink(bus, listener, reopen, service.log, on_wait=on_tick)
    service.bus_events = link.events  # the outage counters, live, for the health file
    if on_ready is not None:
        on_ready()
    q = listener.queue
    handle = _FrameHandler(service, link, result, on_sent, frame_clock)

    try:
        while not stop.is_set():
            if deadline_s is not None and time.perf_counter() >= deadline_s:
                result.reason = "duration"
                break
            try:
                msg = q.get(timeout=poll_s)
            except queue.Empty:
                link.check(stop)
                if on_tick is not None:
                    on_tick()
                continue
            handle(msg)
            link.check(stop) if link.outage is not None else None  # frames again: the outage ends
            if on_tick is not None:
                on_tick()
        else:
            result.reason = "stop"
    finally:
        link.close()
        result.bus_events = dict(link.events)
        while True:  # drain what was received before the notifier stopped
            try:
                handle(q.get_nowait())
            except queue.Empty:
                break
        result.wall_s = time.perf_counter() - wall0_s
        result.cpu_s = time.process_time() - cpu0_s
    return result
