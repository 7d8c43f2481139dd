"""The live loop survives a failing bus (issue: in-vehicle gateway): a receive error closes the bus and reopens it
with back-off, each outage counted and logged once, the sensor resumes when frames return; without a way to reopen,
the error ends the loop as before."""
from __future__ import annotations

import logging
import threading

import can
import pytest

from firmware_model.service import SensorService, ServiceOptions, serve
from tests.firmware_model.sensor_standin import VirtualSensor as StandIn
from tests.firmware_model.test_can_service import traffic


class FaultyBus(can.BusABC):
    """Replays ``frames`` and then raises a receive error once (``fail``), or just goes silent."""

    def __init__(self, frames, fail: bool, **kw):
        self.frames, self.fail = list(frames), fail
        self.sent = []
        super().__init__(channel="faulty", **kw)

    def _recv_internal(self, timeout):
        if self.frames:
            return self.frames.pop(0), False
        if self.fail:
            self.fail = False
            raise can.CanOperationError("Network is down [Error Code 100]")
        threading.Event().wait(min(timeout or 0.01, 0.01))
        return None, False

    def send(self, msg, timeout=None):
        self.sent.append(msg)


def _service():
    return SensorService(StandIn(), ServiceOptions(configured_ref_torque_nm=2000.0))


def test_a_receive_error_reopens_the_bus_and_the_sensor_resumes(caplog):
    caplog.set_level(logging.INFO)
    frames = traffic(0.0, 4.0)
    first = FaultyBus(frames[:len(frames) // 2], fail=True)
    later = []
    attempts = {"n": 0}

    def reopen():
        attempts["n"] += 1
        if attempts["n"] == 1:
            raise can.CanInitializationError("No such device")     # the interface is still down once
        bus = FaultyBus(frames[len(frames) // 2:], fail=False)
        later.append(bus)
        return bus

    svc = _service()
    stop = threading.Event()
    timer = threading.Timer(3.0, stop.set)
    timer.start()
    result = serve(first, svc, stop=stop, reopen=reopen, poll_s=0.02)
    timer.cancel()
    # the error, a resume on the same (now silent) bus, the silent outage's reopen: failing once, then working
    assert result.bus_events == {"read_errors": 1, "outages": 1, "resumes": 1, "reopens": 1, "reopen_failures": 1}
    assert result.frames_in == len(frames)                            # every frame, before and after the outage
    assert svc.counters["steps"] >= 38 and later and later[0].sent   # stepping and sending on the new bus
    assert caplog.text.count("CAN receive error") == 1 and caplog.text.count("CAN bus back after") == 1


def test_without_reopen_a_receive_error_still_ends_the_loop():
    bus = FaultyBus(traffic(0.0, 1.0), fail=True)
    with pytest.raises(can.CanOperationError):
        serve(bus, _service(), poll_s=0.02, duration_s=5.0)
    bus.shutdown()
