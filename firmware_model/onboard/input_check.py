"""The first part of the onboard step: every input checked and repaired (docs/sensor.md, "Bad input").

Hold the last good value, clamp, or degrade; every rejection counted (REJECT_REASONS). Vectorised over any batch
shape (one vehicle: shape ()).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from firmware_model.onboard.kernel_interface import OIL_DRIFT_K_PER_S
from firmware_model.onboard.params import SensorParams
from firmware_model.onboard.records import (
    I_AMB,
    I_GEAR,
    I_OIL,
    I_RET,
    I_SPEED,
    I_TORQUE,
    MAIN,
    N_INPUTS,
    REJECT_INDEX,
    REJECT_REASONS,
    TWIN,
    SensorState,
)
from firmware_model.physics.kinematics import GEAR_MIN

#: reject counters of the input checks, in REJECT_REASONS order (the time checks come after them)
_INPUT_REASONS = REJECT_REASONS[: REJECT_INDEX["aux_missing"] + 1]
assert tuple(REJECT_INDEX[r] for r in _INPUT_REASONS) == tuple(range(len(_INPUT_REASONS)))
_MISSING_COLUMNS = [REJECT_INDEX[r] for r in ("speed_missing", "torque_missing", "gear_missing", "oil_missing")]
_CLAMPED_COLUMNS = [REJECT_INDEX[r] for r in ("speed_clamped", "torque_clamped")]
_GEAR_UNKNOWN, _OIL_IMPLAUSIBLE, _OIL_FROZEN, _DRIVE_FROZEN, _AUX_MISSING = (
    REJECT_INDEX[r] for r in ("gear_unknown", "oil_implausible", "oil_frozen", "drive_frozen", "aux_missing")
)


class InputCheck(NamedTuple):
    """What the checks decided this step (arrays of the batch shape B, or B + (8,) per input field)."""

    ok: np.ndarray  # B + (8,): the raw input is good
    used: np.ndarray  # B + (8,): the value the step uses (good, clamped, held or the auxiliary default)
    age_s: np.ndarray  # B + (8,): time since each input was last good [s]
    same_s: np.ndarray  # B + (8,): time each raw input has been bit-identical [s]
    oil_ref_c: np.ndarray  # B: twin sump when the measured oil last changed [degC]
    measured: np.ndarray  # B: the measured oil is the main copy's sump this step
    drive_ok: np.ndarray  # B: speed, torque and gear all good
    drive_age_s: np.ndarray  # B: age of the oldest of them [s]
    drive_frozen: np.ndarray  # B: speed and torque bit-identical too long while turning
    oil_frozen: np.ndarray  # B: the measured oil bit-identical too long while the twin's sump moved
    counts: np.ndarray  # B + (11,): rejections this step, REJECT_REASONS order up to aux_missing


def check_inputs(state: SensorState, raw: np.ndarray, sp: SensorParams) -> InputCheck:
    """Check the raw inputs (B + (8,), NaN missing) against the state's holds: a good speed or torque is clamped to
    the engine's range, a gear must be an integer in range and a gear of the description, the measured oil
    plausible, steady (with the sump measured within ``oil_step_c`` + OIL_DRIFT_K_PER_S x the time since the last good
    reading came of that reading or of the main copy's sump, else no step above ``oil_step_c`` from a good value
    under 1 s old) and not frozen, the auxiliary inputs
    in range (a missing one takes its default, it is not held; counted only if the drive has it)."""
    opt, dt = sp.options, sp.dt_s
    finite = np.isfinite(raw)
    in_range = finite & (raw >= sp.input_lo) & (raw <= sp.input_hi)
    fixed = np.minimum(np.maximum(raw, sp.clamp_lo), sp.clamp_hi)
    fixed[..., I_RET] = np.abs(raw[..., I_RET])
    clamped = in_range & (fixed != raw)  # beyond the plausible range a speed or torque is missing, not clamped
    gear = raw[..., I_GEAR]
    gear_ok = in_range[..., I_GEAR] & (gear == np.rint(gear))
    # and a gear of the description (a table lookup, as the kernel's): another gearbox's number is unknown too
    gear_ok &= sp.reduced.gear_defined[np.where(gear_ok, gear, GEAR_MIN).astype(np.int64) - GEAR_MIN]
    # oil: plausible range, no implausible step, not frozen while the twin's sump moves
    oil = raw[..., I_OIL]
    oil_in_range = in_range[..., I_OIL]
    age_oil_s = state.age_s[..., I_OIL]
    if opt.oil_mode == "measured":
        # off both the last good reading and the main copy's sump (that reading carried by the model since) by more
        # than oil_step_c and a drift over the time since it came (its age and the period one reading stands for):
        # a reading that jumps and stays is not taken
        allow_k = opt.oil_step_c + OIL_DRIFT_K_PER_S * (age_oil_s + opt.oil_period_s)
        off_carried = np.abs(oil - state.T_c[..., MAIN, sp.reduced.i_oil]) > allow_k
        jumpy = oil_in_range & off_carried & (np.abs(oil - state.hold[..., I_OIL]) > allow_k)
    else:  # the reading is not used: a step from a good value less than 1 s old
        jumpy = oil_in_range & (age_oil_s <= 1.0) & (np.abs(oil - state.hold[..., I_OIL]) > opt.oil_step_c)
    same = np.where(finite & (raw == state.raw_prev), state.same_s + dt, 0.0)
    twin_oil = state.T_c[..., TWIN, sp.reduced.i_oil]
    oil_ref = np.where(same[..., I_OIL] > 0, state.oil_ref_c, twin_oil)
    oil_frozen = (
        oil_in_range & (same[..., I_OIL] >= opt.oil_frozen_s) & (np.abs(twin_oil - oil_ref) >= opt.oil_frozen_drift_c)
    )
    oil_ok = oil_in_range & ~jumpy & ~oil_frozen
    drive_frozen = (
        (same[..., I_SPEED] >= opt.drive_frozen_s)
        & (same[..., I_TORQUE] >= opt.drive_frozen_s)
        & (fixed[..., I_SPEED] > 0)
    )
    ok = in_range.copy()
    ok[..., I_GEAR] = gear_ok
    ok[..., I_OIL] = oil_ok
    fallback = np.array(state.hold, dtype=float)
    fallback[..., I_AMB:] = sp.aux_default  # auxiliary inputs are not held: a missing one takes its default
    used = np.where(ok, fixed, fallback)
    age = np.where(ok, 0.0, state.age_s + dt)
    counts = np.zeros(ok.shape[:-1] + (len(_INPUT_REASONS),), dtype=np.int64)
    counts[..., _MISSING_COLUMNS] = ~finite[..., :I_AMB]  # speed, torque, gear, oil missing
    counts[..., _MISSING_COLUMNS[:2]] = ~in_range[..., :I_GEAR]  # speed, torque: also a value no frame can carry
    counts[..., _CLAMPED_COLUMNS] = clamped[..., :I_GEAR]  # speed, torque clamped
    counts[..., _GEAR_UNKNOWN] = finite[..., I_GEAR] & ~gear_ok
    counts[..., _OIL_IMPLAUSIBLE] = (finite[..., I_OIL] & ~oil_in_range) | jumpy
    counts[..., _OIL_FROZEN] = oil_frozen
    counts[..., _DRIVE_FROZEN] = drive_frozen
    # an auxiliary input the drive has not (a wind turbine's coolant) is not applicable: its default, not counted
    counts[..., _AUX_MISSING] = np.add.reduce(~ok[..., I_AMB:] & np.array(sp.reduced.aux_expected), axis=-1)
    measured = oil_ok if opt.oil_mode == "measured" else np.zeros(oil_ok.shape, dtype=bool)
    drive_ok = ok[..., I_SPEED] & ok[..., I_TORQUE] & ok[..., I_GEAR]
    drive_age = np.maximum(np.maximum(age[..., I_SPEED], age[..., I_TORQUE]), age[..., I_GEAR])
    return InputCheck(ok, used, age, same, oil_ref, measured, drive_ok, drive_age, drive_frozen, oil_frozen, counts)


#: the bit of each input field in SensorStatus.valid_flags / frozen_flags
INPUT_BITS = (1 << np.arange(N_INPUTS)).astype(np.int64)
#: frozen_flags of frozen drive inputs (speed and torque) and of a frozen oil reading
DRIVE_FROZEN_BITS = (1 << I_SPEED) | (1 << I_TORQUE)
OIL_FROZEN_BITS = 1 << I_OIL
