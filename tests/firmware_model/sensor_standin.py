"""A tiny stand-in for firmware_model.onboard.sensor.VirtualSensor with the API the CAN service expects
(firmware_model.service.protocol.StepSensor), used by the CAN tests. Deterministic, cheap, and it reacts to every
input so that wrong inputs show."""

from __future__ import annotations

import collections
import functools
import math
from typing import NamedTuple

import numpy as np

from firmware_model.components import MODE_HOLDING, MODE_NORMAL, MODE_OIL_MODEL, PUBLISHED, STEP_S
from firmware_model.service import StepInputs
from firmware_model.units import RAD_S_PER_RPM

#: the stand-in's inputs: the service's input fields (NaN = not available), then the step's frame time
SensorInputs = collections.namedtuple(
    "SensorInputs", (*StepInputs._fields, "t_s"), defaults=(math.nan,) * (len(StepInputs._fields) + 1)
)


class Status(NamedTuple):
    degraded_mode: int
    speed_valid: bool
    torque_valid: bool
    gear_valid: bool
    oil_valid: bool
    oil_innovation_c: float
    model_oil_temp_c: float
    rejects: np.ndarray


class Outputs(NamedTuple):
    T_c: np.ndarray
    level: np.ndarray
    ttl_s: np.ndarray
    status: Status


class VirtualSensor:
    Inputs = SensorInputs
    Status = Status
    Outputs = Outputs
    reject_reasons: tuple[str, ...] = ()
    input_fields = SensorInputs._fields[:-1]
    dt_s = STEP_S
    published = PUBLISHED

    def __init__(self, params=None, limits=None, config=None):
        self.warn_c = 95.0 if limits is None else limits
        self.rise = np.linspace(0.1, 0.5, len(PUBLISHED))

    def initial_state(self, T_oil_c=None, snapshot=None, elapsed_s=0.0):
        if snapshot is not None:
            return snapshot
        return (25.0 if T_oil_c is None or not math.isfinite(T_oil_c) else float(T_oil_c), 0.0)

    def step(self, state, inputs):
        oil_c, load = state
        power_kw = 0.0
        speed_ok, torque_ok = math.isfinite(inputs.speed_rpm), math.isfinite(inputs.torque_nm)
        if speed_ok and torque_ok:
            power_kw = abs(inputs.speed_rpm * inputs.torque_nm) * RAD_S_PER_RPM / 1000
        load += (power_kw / 100.0 - load) * 0.01
        oil_ok = math.isfinite(inputs.oil_temp_c)
        if oil_ok:
            innovation_c = inputs.oil_temp_c - oil_c
            oil_c += 0.05 * innovation_c
            mode = MODE_NORMAL
        else:
            innovation_c = math.nan
            oil_c += 0.001 * load
            mode = MODE_OIL_MODEL
        gear_ok = math.isfinite(inputs.gear)
        if not (speed_ok and torque_ok and gear_ok):
            mode = MODE_HOLDING
        T_c = oil_c + self.rise * load * 10.0
        T_c[-1] = oil_c
        level = np.where(T_c > self.warn_c + 10, 2, np.where(T_c > self.warn_c, 1, 0))
        ttl_s = np.where(T_c > self.warn_c, 0.0, np.where(load > 0.5, (self.warn_c - T_c) * 60.0, np.inf))
        status = Status(mode, speed_ok, torque_ok, gear_ok, oil_ok, innovation_c, oil_c, np.zeros(0))
        return (oil_c, load), Outputs(T_c, level, ttl_s, status)

    def step_deferred(self, state, inputs):
        state, outputs = self.step(state, inputs)
        return state, outputs, None

    @staticmethod
    def refresh_ttl(state, job):
        return state


def real_sensor_available() -> bool:
    try:
        import firmware_model.onboard.sensor  # noqa: F401
    except ImportError:
        return False
    return True


@functools.cache
def make_sensor():
    """The real VirtualSensor with the default parameters when it exists, else this stand-in. Shared: the sensor
    keeps no state of its own (its step is pure), so one instance serves every test."""
    if real_sensor_available():
        from firmware_model.config import load_config
        from firmware_model.onboard.sensor import VirtualSensor as Real

        cfg = load_config(None)
        return Real(cfg.load_params(), config=cfg)
    return VirtualSensor()
