"""The sensor the CAN service steps: :class:`StepSensor`, what ``firmware_model.onboard.sensor.VirtualSensor``
offers (and the tests' stand-in, tests/firmware_model/sensor_standin.py). The service reads these attributes and
nothing else; :func:`check_sensor` checks them once when a service is built."""
from __future__ import annotations

from typing import Any, Protocol

from firmware_model.components import STEP_S
from firmware_model.errors import ParameterError
from firmware_model.service.records import StepInputs

#: what the service needs of a sensor's status record (``Outputs.status``)
STATUS_FIELDS = ("degraded_mode", "speed_valid", "torque_valid", "gear_valid", "oil_valid", "oil_innovation_c",
                 "model_oil_temp_c", "rejects")


class StepSensor(Protocol):
    """A sensor with a pure fixed step that the service can drive.

    - ``Inputs``: the inputs record type, fields ``input_fields`` (NaN = not available) and ``t_s`` (the step's
      frame time on the run-table clock);
    - ``Status``: its status record type, with at least :data:`STATUS_FIELDS` (``rejects``: the cumulative reject
      counters in ``reject_reasons`` order);
    - ``Outputs``: its outputs record type: ``T_c``, ``level``, ``ttl_s`` (per published component) and ``status``;
    - ``reject_reasons``: names of the reject counters; ``input_fields``: :class:`StepInputs` fields, same order;
      ``dt_s``: the step, ``firmware_model.components.STEP_S``;
    - ``initial_state(T_oil_c=...)``, ``step_deferred(state, inputs) -> (state, outputs, job)`` (the step without
      its slow time-to-limit refresh) and ``refresh_ttl(state, job) -> state`` (that refresh; ``job`` None: none
      due). ``step_deferred`` then ``refresh_ttl`` must equal the plain ``step``.
    """
    Inputs: type
    Status: type
    Outputs: type
    reject_reasons: tuple[str, ...]
    input_fields: tuple[str, ...]
    dt_s: float

    def initial_state(self, T_oil_c: float | None = None) -> Any: ...

    def step_deferred(self, state: Any, inputs: Any) -> tuple[Any, Any, Any]: ...

    def refresh_ttl(self, state: Any, job: Any) -> Any: ...


def check_sensor(sensor: StepSensor) -> None:
    """ParameterError unless ``sensor`` has the inputs, status and step the service feeds and reads."""
    if tuple(sensor.input_fields) != StepInputs._fields:
        raise ParameterError(f"the sensor's input_fields {tuple(sensor.input_fields)} are not the service's "
                             f"{StepInputs._fields}")
    missing = [f for f in (*StepInputs._fields, "t_s") if f not in sensor.Inputs._fields]
    missing += [f for f in STATUS_FIELDS if f not in sensor.Status._fields]
    if missing:
        raise ParameterError(f"the sensor's Inputs/Status records lack the fields {missing}")
    if sensor.dt_s != STEP_S:
        raise ParameterError(f"the sensor steps every {sensor.dt_s} s; the CAN service every {STEP_S} s")
