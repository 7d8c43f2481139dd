"""A tiny stand-in for firmware_model.onboard.sensor.VirtualSensor (agreed API), used by the CAN tests only while the real
sensor is not importable. Deterministic, cheap, and it reacts to every input so that wrong inputs show."""
from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from firmware_model.components import PUBLISHED


class SensorInputs(NamedTuple):
    speed_rpm: float
    torque_nm: float
    gear: float
    oil_temp_c: float
    ambient_temp_c: float
    coolant_temp_c: float
    vehicle_speed_kmh: float
    retarder_torque_nm: float


class Outputs(NamedTuple):
    T_c: np.ndarray
    level: np.ndarray
    ttl_s: np.ndarray
    status: dict


class VirtualSensor:
    dt_s = 0.1

    def __init__(self, params=None, limits=None, config=None):
        self.warn_c = 95.0 if limits is None else limits
        self.rise = np.linspace(0.1, 0.5, len(PUBLISHED))

    def initial_state(self, T_oil_c=None, snapshot=None, elapsed_s=0.0):
        if snapshot is not None:
            return snapshot
        return (25.0 if T_oil_c is None or not math.isfinite(T_oil_c) else float(T_oil_c), 0.0)

    def step(self, state, inputs):
        oil, load = state
        p_kw = 0.0
        if math.isfinite(inputs.speed_rpm) and math.isfinite(inputs.torque_nm):
            p_kw = abs(inputs.speed_rpm * inputs.torque_nm) * 2 * math.pi / 60 / 1000
        load += (p_kw / 100.0 - load) * 0.01
        if math.isfinite(inputs.oil_temp_c):
            innov = inputs.oil_temp_c - oil
            oil += 0.05 * innov
            mode = 0
        else:
            innov = math.nan
            oil += 0.001 * load
            mode = 1
        if not (math.isfinite(inputs.speed_rpm) and math.isfinite(inputs.torque_nm) and math.isfinite(inputs.gear)):
            mode = 2
        T = oil + self.rise * load * 10.0
        T[-1] = oil
        level = np.where(T > self.warn_c + 10, 2, np.where(T > self.warn_c, 1, 0))
        ttl = np.where(T > self.warn_c, 0.0, np.where(load > 0.5, (self.warn_c - T) * 60.0, np.inf))
        status = {"degraded_mode": mode, "oil_innovation_c": innov, "model_oil_temp_c": oil}
        return (oil, load), Outputs(T, level, ttl, status)


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
