"""The CAN service: J1939 frames in, the virtual sensor stepped on frame time, GBX_* frames out.

:class:`SensorService` owns time and is pure of threads, clocks and I/O: ``feed(msg)`` takes one received frame and
returns the frames to send. Live (``gearbox-vsensor run``, :func:`serve`), the replay of a log (tools/replay/log.py)
and the tests all call the same ``feed``, so the same traffic gives bit-identical outputs at any replay speed.

Timing model (docs/can.md "Service"):

- **Time is frame time.** The first frame that drives time anchors the step grid: boundaries at ``t0 + k x 0.1 s``.
  Only frames the service listens to drive time (data frames of the PGNs of :func:`wanted_pgns`, the same set the
  live receive filters pass); every other frame is still decoded and counted but never moves time, so a replay
  without filters steps exactly like a live run with them.
- **A step is due** when a frame's timestamp reaches the next boundary; the step runs *before* that frame is used,
  on the latest values of the frames before the boundary. Missing boundaries (a silent bus) are stepped one by one
  up to ``max_catchup_steps`` (default 50 = 5 s); only the last of a burst of catch-up steps is sent (the older ones
  would be stale on the bus), every step is recorded.
- **Time jumps**: a frame more than ``max_catchup_steps`` steps ahead, or more than ``backward_tolerance_s``
  behind the last step, restarts the grid at that frame: values are dropped, the sensor resumes from its state
  (it sees the gap in the frame time of its next step) and the event is counted (``time_jumps``) and logged.
- **Staleness**: a value older than ``stale_factor`` (default 3) x its message's nominal period
  (:data:`NOMINAL_PERIOD_S`) at a step boundary is given to the sensor as NaN ("not available"); it recovers with
  the next valid frame. A J1939 "not available" or "error" value is not a value: the signal goes stale the same way.
- **Outputs** every step (100 ms): the 16 GBX frames with the step's frame time as timestamp; GBX_DM1 every
  second and whenever its content changes. Before the sensor is initialised (it waits up to ``init_wait_s`` for a
  measured oil temperature) the frames say "not initialised" (DegradedMode 3), every value not available.

Counters (:attr:`SensorService.counters`, logged every ``counter_log_period_s`` of frame time): the decoder's
(frames seen = used + rejected per reason; values rejected per signal; TP.BAM) plus the service's (steps, steps
sent, catch-up steps, time jumps, frames that did not drive time, steps with each input stale, frames sent).

Trust (``trust``, docs/can.md "Trust findings"): a time base that runs several times too fast or too slow (the
input messages' arrival rates in frame time; GBX_STATUS TimeBaseSuspect), inputs from unexpected source
addresses and a large degraded share are logged as findings with their likely cause (:meth:`SensorService.findings`).

Modules: ``options`` (settings, the signal wiring, receive filters), ``records`` (the typed records of a step),
``protocol`` (the sensor the service expects), ``core`` (:class:`SensorService`), ``recorder`` (run-table rows),
``trust`` (the findings), ``live`` (:func:`serve`), ``build`` (:func:`build_service` from a config). Only the standard
library, numpy and
the CAN edge (``can_dbc``: python-can, cantools) are imported by the service itself (docs/CONVENTIONS.md).
"""

from __future__ import annotations

import importlib

#: the public names and the submodule each lives in; imported on first use (PEP 562), so that a run-table replay,
#: which needs only ``options``, does not import python-can (whose MF4 support alone imports asammdf: ~0.5 s)
_WHERE = {
    "build_service": "build",
    "DM1_PERIOD_STEPS": "core",
    "SensorService": "core",
    "LatencyFigures": "live",
    "QueueListener": "live",
    "ServeResult": "live",
    "serve": "live",
    "GEAR_RANGE": "options",
    "INPUT_COLUMNS": "options",
    "INPUT_SIGNALS": "records",
    "NOMINAL_PERIOD_S": "options",
    "SENSOR_INPUTS": "records",
    "ServiceOptions": "options",
    "can_filters": "options",
    "parse_gear_map": "options",
    "rig_pgns": "options",
    "wanted_pgns": "options",
    "StepSensor": "protocol",
    "check_sensor": "protocol",
    "GbxStatus": "records",
    "OutputRow": "records",
    "RecordedOutputs": "records",
    "StepInputs": "records",
    "StepKind": "records",
    "StepRequest": "records",
}

__all__ = list(_WHERE)


def __getattr__(name: str):
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{where}"), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(list(globals()) + __all__)
