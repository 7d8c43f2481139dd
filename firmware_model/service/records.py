"""The typed records of the CAN service: what one step's frame half hands its sensor half (:class:`StepRequest`),
what the sensor half gives back (:class:`OutputRow`, :class:`RecordedOutputs`), and the GBX_STATUS content of a
step (:class:`GbxStatus`). The whole-log replay (firmware_model.service.columnar) runs the halves apart: these
records are what passes between them."""

from __future__ import annotations

import enum
from typing import NamedTuple

import numpy as np


class StepKind(enum.IntEnum):
    """What the sensor half does with a step: nothing yet (waiting for an oil temperature), initialise the sensor
    and step it, or step it."""

    NOT_INITIALISED = 0
    INITIALISE = 1
    STEP = 2


class StepInputs(NamedTuple):
    """The inputs of one step as the frame half found them: the sensor's input fields (``VirtualSensor.input_fields``,
    same order) in SI/J1939 units; None = not available (never received, stale, or outside the model's range)."""

    speed_rpm: float | None
    torque_nm: float | None
    gear: float | None
    oil_temp_c: float | None
    ambient_temp_c: float | None
    coolant_temp_c: float | None
    vehicle_speed_kmh: float | None
    retarder_torque_nm: float | None


#: the decoder signal of each sensor input field (StepInputs order); it is also the input's run-table column
#: (the run-table column names, tools/runtable.py)
INPUT_SIGNALS = (
    "engine_speed_rpm",
    "engine_torque_nm",
    "gear",
    "oil_temp_c",
    "ambient_temp_c",
    "coolant_temp_c",
    "vehicle_speed_kmh",
    "retarder_torque_nm",
)
#: (sensor input field, decoder signal) pairs
SENSOR_INPUTS = tuple(zip(StepInputs._fields, INPUT_SIGNALS))


class StepRequest(NamedTuple):
    """One step from the frame half: what to do, the step's frame time (the outputs' timestamp), the inputs, the
    engine reference torque in use (None: none known), the step's run-table time (continuous across time jumps;
    the sensor's ``Inputs.t_s``) and whether the time base is suspect (GBX_STATUS TimeBaseSuspect)."""

    kind: StepKind
    t_step_s: float
    inputs: StepInputs
    ref_torque_nm: float | None
    t_s: float
    time_base_suspect: bool = False


class GbxStatus(NamedTuple):
    """The GBX_STATUS content of a step (``can_dbc.encoder.STATUS_KEYS``, the encoder's counter aside); None = not
    available. The field order is the order of the status columns of the run table."""

    degraded_mode: int | None
    speed_valid: bool | None
    torque_valid: bool | None
    gear_valid: bool | None
    oil_valid: bool | None
    ref_torque_valid: bool | None
    oil_innovation_c: float | None
    model_oil_temp_c: float | None


class OutputRow(NamedTuple):
    """The sensor half of one recorded step: published temperatures [degC], warning levels, time to limit [s] (in
    the published order) and the status tail (``degraded``, the :class:`GbxStatus` fields, the reject counters)."""

    T_c: np.ndarray
    level: np.ndarray
    ttl_s: np.ndarray
    tail: list


class RecordedOutputs(NamedTuple):
    """Every recorded step's sensor half as arrays: T_c, level, ttl_s (steps x published components) and tail
    (steps x status columns)."""

    T_c: np.ndarray
    level: np.ndarray
    ttl_s: np.ndarray
    tail: np.ndarray
