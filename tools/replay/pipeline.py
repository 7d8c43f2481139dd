"""A CAN log replay in two processes: this process reads and decodes the log and gathers each step's request (the
service's frame half), a forked process steps the sensor on the requests (the sensor half) and sends the recorded
outputs back at the end. Outputs are the same bit for bit as one process (the frame half never reads what the
sensor half computed); the wall time is the larger half, not the sum."""
from __future__ import annotations

import threading
from typing import Any, Iterable, NamedTuple

from firmware_model.service import RecordedOutputs, SensorService, StepRequest

#: logs at least this big are replayed in two processes by default (smaller ones: the fork is not worth it)
PIPELINE_MIN_BYTES = 2_000_000
#: steps per message from the frame process to the sensor process
BATCH_STEPS = 256


class SensorHalfResult(NamedTuple):
    """What the sensor process sends back: its recorded outputs and final state, or the traceback of what failed
    (then ``outputs`` and ``state`` are None)."""
    error: str | None
    outputs: RecordedOutputs | None
    state: Any


def pipeline_available(service: SensorService, on_frames=None) -> str | None:
    """None when ``service`` can replay in two processes, else why not."""
    import multiprocessing
    if on_frames is not None or service.emit_frames:
        return "the sensor's output frames are written (--frames-out), which needs them in order in one process"
    if "fork" not in multiprocessing.get_all_start_methods():
        return "this platform cannot fork"
    if threading.active_count() > 1:
        return "this process runs other threads (forking it is not safe)"
    if service.counters["steps"] > 0:
        return "the service has already stepped"
    return None


def _sensor_process(service: SensorService, conn) -> None:
    """The sensor half: apply every step request, then send back a :class:`SensorHalfResult`."""
    try:
        apply = service.apply_request
        while True:
            batch: list[StepRequest] | None = conn.recv()
            if batch is None:
                break
            for req in batch:
                apply(req)
        service.finish_pending()
        conn.send(SensorHalfResult(None, service.recorded_outputs(), service.state))
    except BaseException:  # anything: the parent re-raises it with this traceback
        import traceback
        try:
            conn.send(SensorHalfResult(traceback.format_exc(), None, None))
        except Exception:
            pass
    finally:
        conn.close()


class _Batcher:
    """Collects the frame half's step requests and sends them to the sensor process BATCH_STEPS at a time."""

    def __init__(self, conn) -> None:
        self.conn = conn
        self.batch: list[StepRequest] = []

    def __call__(self, req: StepRequest) -> None:
        self.batch.append(req)
        if len(self.batch) >= BATCH_STEPS:
            self.conn.send(self.batch.copy())
            self.batch.clear()

    def close(self) -> None:
        """Send what is left and the end mark."""
        if self.batch:
            self.conn.send(self.batch)
        self.conn.send(None)


def _failure(conn, proc) -> RuntimeError:
    try:
        detail = conn.recv().error
    except (EOFError, OSError):
        detail = f"the sensor process ended (exit code {proc.exitcode})"
    return RuntimeError(f"replay: the sensor process failed:\n{detail}")


def feed_pipelined(frames: Iterable, service: SensorService) -> None:
    """Feed ``frames`` to ``service`` here and step its sensor in a forked process; the service then holds the
    recorded outputs and the final state as if it had stepped itself (see :func:`pipeline_available`)."""
    import multiprocessing
    ctx = multiprocessing.get_context("fork")
    here, there = ctx.Pipe(duplex=True)
    proc = ctx.Process(target=_sensor_process, args=(service, there), daemon=True,
                       name="gearbox-vsensor replay: sensor")
    proc.start()
    there.close()
    batcher = _Batcher(here)
    service.split_steps(batcher)
    ok = False
    try:
        feed = service.feed
        try:
            for msg in frames:
                feed(msg)
            batcher.close()
        except (BrokenPipeError, ConnectionResetError):
            raise _failure(here, proc) from None
        try:
            result: SensorHalfResult = here.recv()
        except (EOFError, OSError):
            raise _failure(here, proc) from None
        if result.error is not None:
            raise RuntimeError(f"replay: the sensor process failed:\n{result.error}")
        service.adopt_outputs(result.outputs, result.state)
        ok = True
    finally:
        service.split_steps(None)
        here.close()
        if ok:
            proc.join(timeout=30.0)
        if proc.is_alive():
            proc.terminate()
            proc.join(timeout=5.0)
