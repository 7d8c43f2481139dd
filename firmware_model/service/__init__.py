"""The CAN service: J1939 frames in, the virtual sensor stepped on frame time, GBX_* frames out.

:class:`SensorService` owns time and is pure of threads, clocks and I/O: ``feed(msg)`` takes one received frame and
returns the frames to send. Live (``gearbox-vsensor run``, :func:`serve`), the replay of a log (tools/replay/log.py)
and the tests all call the same ``feed``, so the same traffic gives bit-identical outputs at any replay speed.

Modules: ``options`` (settings, the signal wiring, receive filters), ``records`` (the typed records of a step),
``protocol`` (the sensor the service expects), ``core`` (:class:`SensorService`), ``recorder`` (run-table rows),
``trust`` (the findings), ``live`` (:func:`serve`), ``build`` (:func:`build_service` from a config). The timing model
(time is frame time, catch-up, time jumps, staleness, outputs), the counters and the trust findings are in
docs/can.md, "The live service".
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
