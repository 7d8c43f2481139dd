"""The onboard sensor's public records: its inputs, state, status, outputs and options, and the orders of the input
fields and reject reasons (docs/sensor.md "API"). Shared by the step (firmware_model.onboard.step), the snapshot
(firmware_model.onboard.snapshot) and the sensor object (firmware_model.onboard.sensor), which re-exports them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

#: input fields in the order of the state's hold / age arrays
INPUT_FIELDS = (
    "speed_rpm",
    "torque_nm",
    "gear",
    "oil_temp_c",
    "ambient_temp_c",
    "coolant_temp_c",
    "vehicle_speed_kmh",
    "retarder_torque_nm",
)
N_INPUTS = len(INPUT_FIELDS)
I_SPEED, I_TORQUE, I_GEAR, I_OIL, I_AMB, I_COOL, I_VKMH, I_RET = range(N_INPUTS)
#: why inputs were rejected or repaired (columns of the reject counters)
REJECT_REASONS = (
    "speed_missing",
    "speed_clamped",
    "torque_missing",
    "torque_clamped",
    "gear_missing",
    "gear_unknown",
    "oil_missing",
    "oil_implausible",
    "oil_frozen",
    "drive_frozen",
    "aux_missing",
    "time_jump",
    "time_backward",
)
N_REJECT = len(REJECT_REASONS)
#: reject reason -> its column in the counters
REJECT_INDEX = {k: i for i, k in enumerate(REJECT_REASONS)}
#: the two copies of the network in the state: the main copy (measured sump when available), the open-loop twin
MAIN, TWIN = 0, 1


class SensorInputs(NamedTuple):
    """One step's inputs; NaN means not available / stale. Fields may be arrays (one value per vehicle)."""

    speed_rpm: float = math.nan
    torque_nm: float = math.nan
    gear: float = math.nan
    oil_temp_c: float = math.nan
    ambient_temp_c: float = math.nan
    coolant_temp_c: float = math.nan
    vehicle_speed_kmh: float = math.nan
    retarder_torque_nm: float = math.nan
    #: optional frame time of this step [s] (time-jump detection); NaN: the caller keeps the 0.1 s grid
    t_s: float = math.nan


class SensorState(NamedTuple):
    """Everything the sensor remembers; fixed shapes (batch shape B = () or (V,))."""

    T_c: np.ndarray  # B + (2, n): node temperatures of the main copy and the open-loop twin [degC]
    lag_w: np.ndarray  # B + (ns,): heat-lag state of every loss source [W]
    hold: np.ndarray  # B + (8,): last good value of every input (INPUT_FIELDS)
    age_s: np.ndarray  # B + (8,): time since each input was last good [s]
    same_s: np.ndarray  # B + (8,): time each raw input has been bit-identical [s]
    raw_prev: np.ndarray  # B + (8,): previous raw input values
    oil_ref_c: np.ndarray  # B: twin sump temperature when the measured oil last changed [degC]
    level: np.ndarray  # B + (n_pub,): warning levels (int8), published order
    pending_s: np.ndarray  # B + (n_pub,): debounce timers [s]
    ttl_s: np.ndarray  # B + (n_pub,): last time to limit [s]
    t_last_s: np.ndarray  # B: frame time of the last step (NaN unknown)
    k: np.ndarray  # B: steps done (int64)
    rejects: np.ndarray  # B + (N_REJECT,): reject counters (int64)
    recover_s: np.ndarray  # B: the drive inputs' outage past the hold still to recover from [s] (levels 3 meanwhile)


class SensorStatus(NamedTuple):
    degraded_mode: np.ndarray  # components.MODE_*: 0 normal, 1 oil model only, 2 inputs missing - holding
    speed_valid: np.ndarray
    torque_valid: np.ndarray
    gear_valid: np.ndarray
    oil_valid: np.ndarray
    valid_flags: np.ndarray  # bit i: INPUT_FIELDS[i] was valid this step
    model_oil_temp_c: np.ndarray  # the open-loop twin's sump [degC]
    oil_innovation_c: np.ndarray  # measured - model oil (NaN without a valid measurement) [K]
    oil_source: np.ndarray  # 0 measured, 1 modelled (the main network's sump)
    frozen_flags: np.ndarray  # bit i: INPUT_FIELDS[i] frozen (bit-identical too long)
    rejects: np.ndarray  # cumulative counters, REJECT_REASONS order
    # a forced oil system's inlet [degC]: the sump the step took minus the cooler's drop Q / (mdot cp)
    # (physics.cooler.inlet_drop_k), the temperature the jets' streams take; NaN without forced lubrication
    oil_inlet_temp_c: np.ndarray = np.nan


class SensorOutputs(NamedTuple):
    # the last axis: the published components (n_pub), in the gearbox description's published.order
    T_c: np.ndarray  # (..., n_pub) published temperatures [degC]; always finite
    level: np.ndarray  # (..., n_pub) 0 normal, 1 warning, 2 critical, 3 not available (int8)
    ttl_s: np.ndarray  # (..., n_pub) time to the warning limit with held inputs [s]: inf never, NaN not available
    status: SensorStatus


@dataclass(frozen=True)
class SensorOptions:
    """Behaviour settings (docs/sensor.md, "Bad input"); all times in seconds."""

    oil_mode: str = "measured"  # measured: use a valid measurement; model: always the modelled sump
    hold_s: float = 10.0  # drive inputs missing longer than this: levels "not available"
    drive_frozen_s: float = 120.0  # speed and torque bit-identical this long while turning: flagged frozen
    oil_frozen_s: float = 300.0  # measured oil bit-identical this long ...
    oil_frozen_drift_c: float = 3.0  # ... while the twin's sump moved this much: measurement frozen
    oil_step_c: float = 5.0  # a measured oil off the last good one by more than this (+ a drift with its age)
    oil_period_s: float = 0.0  # how long one oil reading stands for: 0 a live one; a held table's row period
    oil_range_c: tuple = (-40.0, 200.0)  # plausible measured oil
    aux_range_c: tuple = (-60.0, 150.0)  # plausible ambient / coolant
    max_vehicle_speed_kmh: float = 250.0
    default_vehicle_speed_kmh: float = 50.0
    ttl_period_s: float = 1.0  # time to limit refreshed this often (0: every step)
    ttl_sump: str = "model"  # time to limit: the sump evolves with the cooler model ("model") or a
    #                                      measured reading is held like the other inputs ("held")
    ttl_method: str = "bound"  # time to limit: the losses and the cooler along their chords to the far sump
    #                                      ("bound", firmware_model.onboard.ttl_bound: never late by more than 10 %
    #                                      on bench_ttl) or the march alone ("march", late while the sump warms)
    time_jump_hold_s: float = 60.0  # forward jumps: held inputs this long, then engine off
    clock_reset_s: float = 10.0  # time back by more than this: a reset clock, stepped as one step
    initial_temp_c: float | None = None  # cold start without oil: default = ambient boundary
