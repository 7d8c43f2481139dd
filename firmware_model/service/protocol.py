"""The sensor the CAN service steps: :class:`StepSensor`, what ``firmware_model.onboard.sensor.VirtualSensor``
offers (and the tests' stand-in, tests/firmware_model/sensor_standin.py). The service reads these attributes and
nothing else; :func:`check_sensor` checks them once when a service is built."""

from __future__ import annotations

import inspect
import math
from typing import Any, Protocol

from firmware_model.components import STEP_S
from firmware_model.errors import ParameterError
from firmware_model.service.records import StepInputs

#: what the service needs of a sensor's status record (``Outputs.status``)
STATUS_FIELDS = (
    "degraded_mode",
    "speed_valid",
    "torque_valid",
    "gear_valid",
    "oil_valid",
    "oil_innovation_c",
    "model_oil_temp_c",
    "rejects",
)


class StepSensor(Protocol):
    """A sensor with a pure fixed step that the service can drive.

    - ``Inputs``: the inputs record type, fields ``input_fields`` (NaN = not available) and ``t_s`` (the step's
      frame time on the run-table clock);
    - ``Status``: its status record type, with at least :data:`STATUS_FIELDS` (``rejects``: the cumulative reject
      counters in ``reject_reasons`` order);
    - ``Outputs``: its outputs record type: ``T_c``, ``level``, ``ttl_s`` (per published component) and ``status``;
    - ``reject_reasons``: names of the reject counters; ``input_fields``: :class:`StepInputs` fields, same order;
      ``dt_s``: the step, ``firmware_model.components.STEP_S``; ``published``: the published components' ids,
      the order of the outputs' last axis (the gearbox description's published.order);
    - ``initial_state(T_oil_c=...)``, optionally with ``ambient_c=...`` (no oil reading: start at the ambient one;
      :func:`start_state` passes it to a sensor whose ``initial_state`` takes it),
      ``step_deferred(state, inputs) -> (state, outputs, job)`` (the step without its slow time-to-limit refresh)
      and ``refresh_ttl(state, job) -> state`` (that refresh; ``job`` None: none due). ``step_deferred`` then
      ``refresh_ttl`` must equal the plain ``step``.
    """

    Inputs: type
    Status: type
    Outputs: type
    reject_reasons: tuple[str, ...]
    input_fields: tuple[str, ...]
    dt_s: float
    published: tuple[str, ...]

    def initial_state(self, T_oil_c: float | None = None) -> Any: ...

    def step_deferred(self, state: Any, inputs: Any) -> tuple[Any, Any, Any]: ...

    def refresh_ttl(self, state: Any, job: Any) -> Any: ...


def check_sensor(sensor: StepSensor) -> None:
    """ParameterError unless ``sensor`` has the inputs, status and step the service feeds and reads."""
    if tuple(sensor.input_fields) != StepInputs._fields:
        raise ParameterError(
            f"the sensor's input_fields {tuple(sensor.input_fields)} are not the service's {StepInputs._fields}"
        )
    missing = [f for f in (*StepInputs._fields, "t_s") if f not in sensor.Inputs._fields]
    missing += [f for f in STATUS_FIELDS if f not in sensor.Status._fields]
    if missing:
        raise ParameterError(f"the sensor's Inputs/Status records lack the fields {missing}")
    if not tuple(getattr(sensor, "published", ())):
        raise ParameterError("the sensor names no published components (its published ids)")
    if sensor.dt_s != STEP_S:
        raise ParameterError(f"the sensor steps every {sensor.dt_s} s; the CAN service every {STEP_S} s")


def start_state(sensor: StepSensor, T_oil_c, ambient_c=None, **kw):
    """``sensor.initial_state`` from the first oil reading, with the first ambient reading too when the sensor's
    ``initial_state`` takes ``ambient_c`` (VirtualSensor: no oil reading, start at the ambient one); a sensor
    written to the older protocol (``T_oil_c`` only) is called as before."""
    try:
        params = inspect.signature(sensor.initial_state).parameters
    except (TypeError, ValueError):
        params = {}
    takes = "ambient_c" in params or any(p.kind is p.VAR_KEYWORD for p in params.values())
    oil = None if T_oil_c is None or not math.isfinite(T_oil_c) else float(T_oil_c)
    if takes and ambient_c is not None:
        kw["ambient_c"] = ambient_c
    return sensor.initial_state(T_oil_c=oil, **kw)
