"""The frozen record of everything the pure onboard step reads (:class:`SensorParams`), built once per sensor.

Nothing in it changes after :meth:`SensorParams.build`; what the step memoises lives in a separate
:class:`~firmware_model.onboard.step_cache.StepCache` that the sensor owns and passes to the step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from firmware_model.errors import ParameterError
from firmware_model.onboard import evaluate as E
from firmware_model.onboard import reduce as R
from firmware_model.onboard.records import SensorOptions
from firmware_model.onboard.warning_levels import Limits
from firmware_model.physics.kinematics import GEAR_MAX, GEAR_MIN


@dataclass(frozen=True, eq=False)
class SensorParams:
    """Parameters of the pure step: the onboard network, limits, effects, options and what is derived from them.

    Effects may be per vehicle (arrays over the batch): then ``T_bc_default_c``, ``cooler_scale`` and
    ``thermostat_offset_c`` carry the batch axis and ``scalar_effects`` is False."""

    reduced: E.ReducedParams
    limits: Limits
    effects: R.Effects
    options: SensorOptions
    helpers: E.Helpers  # index splits and scatter matrices of the network (ReducedParams.helpers)
    dt_over_C_s_k_per_j: np.ndarray  # (n,) dt / C of every node
    sqrt_C: np.ndarray  # (n,) C^1/2 (held-input modes)
    T_bc_default_c: np.ndarray  # (nb,) or (V, nb): boundary temperatures, hot-side offset applied
    aux_default: np.ndarray  # (4,) defaults of ambient, coolant [degC], vehicle speed [km/h], retarder
    cooler_scale: float | np.ndarray  # cooler effectiveness scale (per vehicle: (V, 1))
    thermostat_offset_c: float | np.ndarray
    warning_rest_c: np.ndarray  # (28,) warning limit minus hysteresis: below it with every level normal,
    #                                      the warning state machine rests
    input_lo: np.ndarray  # (8,) plausible range of every input (INPUT_FIELDS order) ...
    input_hi: np.ndarray
    clamp_lo: np.ndarray  # (8,) ... and the clamp of the value used (speed, torque: engine range)
    clamp_hi: np.ndarray
    ttl_every: int  # steps between time-to-limit refreshes
    scalar_effects: bool  # every effect one value for the whole batch (the caches apply)

    @property
    def dt_s(self) -> float:
        """The step [s], from the onboard build (components.STEP_S)."""
        return self.reduced.dt_s

    @classmethod
    def build(
        cls, reduced: E.ReducedParams, limits: Limits, effects: R.Effects, options: SensorOptions
    ) -> SensorParams:
        """Derive the step's constants once."""
        rp, eff = reduced, effects
        if tuple(limits.components) != tuple(rp.published):
            raise ParameterError(
                f"the limits ({limits.origin}) are for the components {', '.join(limits.components)}; this gearbox "
                f"publishes {', '.join(rp.published)}"
            )
        dt_s = rp.dt_s
        hot = eff.hot_offset_c
        if np.ndim(hot) == 0:
            bc = np.array(rp.bc_default_c, dtype=float)
            bc[rp.i_hot] = bc[rp.i_hot] + np.asarray(hot).reshape(-1)[0]
        else:
            n_bc = len(rp.bc_default_c)
            bc = (
                np.broadcast_to(rp.bc_default_c, np.shape(hot) + (n_bc,))
                + np.eye(n_bc)[rp.i_hot] * np.asarray(hot)[..., None]
            )
        scalar_effects = (
            all(
                np.ndim(v) == 0
                for v in (
                    eff.teeth_oil_h,
                    eff.planet_oil_h,
                    eff.housing_air_h,
                    eff.cooler_scale,
                    eff.thermostat_offset_c,
                    eff.hot_offset_c,
                    eff.retarder_frac,
                    eff.churn_scale,
                    eff.needle_scale,
                )
            )
            and np.ndim(eff.src_scale) <= 1
        )
        sp = cls(
            reduced=rp,
            limits=limits,
            effects=eff,
            options=options,
            helpers=rp.helpers,
            dt_over_C_s_k_per_j=dt_s / np.asarray(rp.C_j_per_k, dtype=float),
            sqrt_C=np.sqrt(np.asarray(rp.C_j_per_k, dtype=float)),
            T_bc_default_c=bc,
            aux_default=np.array(
                [rp.bc_default_c[rp.i_ambient], rp.bc_default_c[rp.i_coolant], options.default_vehicle_speed_kmh, 0.0]
            ),
            cooler_scale=_per_vehicle(eff.cooler_scale),
            thermostat_offset_c=_per_vehicle(eff.thermostat_offset_c),
            warning_rest_c=np.asarray(limits.warning_c - limits.hysteresis_k),
            **_input_bounds(rp, options),
            ttl_every=max(int(round(options.ttl_period_s / dt_s)), 1),
            scalar_effects=scalar_effects,
        )
        for f in fields(sp):
            value = getattr(sp, f.name)
            if isinstance(value, np.ndarray) and value.flags.writeable:
                value.setflags(write=False)  # derived once; nothing writes to them
        return sp


#: plausible retarder torque magnitude [N m]: the data range of the J1939 retarder reference torque (SPN 1085,
#: 0..64255 N m), so that a percent of it can never exceed it; beyond it the input is not plausible (aux_missing)
RETARDER_TORQUE_MAX_NM = 64255.0
#: the largest engine speed a J1939 frame can carry [rpm] (SPN 190: 0..8031.875 rpm): a value beyond it in either sign
#: is no reading (garbage such as 1e308 was clamped to 4000 rpm and used as full speed); it is not available (held)
ENGINE_SPEED_DATA_MAX_RPM = 8031.875
#: the largest engine torque magnitude a J1939 frame can carry [N m] (SPN 513, -125..125 %, of the reference torque
#: SPN 544, at most 64255 N m): beyond it no reading (1e308 was clamped to the engine's maximum and raised warnings)
ENGINE_TORQUE_DATA_MAX_NM = 1.25 * 64255.0
#: a drive whose torque exceeds what a J1939 frame can carry (the MM82's rotor, 2.5 MN m, read from SCADA): its input
#: is plausible up to this multiple of its largest torque (assumed: J1939's 125 % of the reference torque)
TORQUE_DATA_REL = 1.25


def _input_bounds(rp: E.ReducedParams, opt: SensorOptions) -> dict:
    """Plausible range and clamp of every input field (docs/sensor.md "Bad input")."""
    inf = math.inf
    aux_lo, aux_hi = opt.aux_range_c
    ret = RETARDER_TORQUE_MAX_NM
    torque_max_nm = max(ENGINE_TORQUE_DATA_MAX_NM, TORQUE_DATA_REL * max(rp.max_torque_nm, -rp.min_torque_nm))
    return dict(
        input_lo=np.array(
            [
                -ENGINE_SPEED_DATA_MAX_RPM,
                -torque_max_nm,
                GEAR_MIN,
                opt.oil_range_c[0],
                aux_lo,
                aux_lo,
                0.0,
                -ret,
            ]
        ),
        input_hi=np.array(
            [
                ENGINE_SPEED_DATA_MAX_RPM,
                torque_max_nm,
                GEAR_MAX,
                opt.oil_range_c[1],
                aux_hi,
                aux_hi,
                opt.max_vehicle_speed_kmh,
                ret,
            ]
        ),
        clamp_lo=np.array([0.0, rp.min_torque_nm, -inf, -inf, -inf, -inf, -inf, -inf]),
        clamp_hi=np.array([rp.max_speed_rpm, rp.max_torque_nm, inf, inf, inf, inf, inf, inf]),
    )


def first_value(value) -> float:
    """One value of an effect that may be per vehicle (the first vehicle's)."""
    a = np.asarray(value, dtype=float)
    return float(a) if a.ndim == 0 else float(a.reshape(-1)[0])


def vehicle_value(value, vehicle=None) -> float:
    """One vehicle's value of an effect that may be per vehicle (``vehicle``: its batch index; None: the first)."""
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        return float(a)
    return float(a[vehicle]) if vehicle is not None and len(vehicle) == a.ndim else float(a.reshape(-1)[0])


def first_row(value) -> np.ndarray:
    """One row of a per-source effect that may be per vehicle (the first vehicle's)."""
    a = np.asarray(value, dtype=float)
    return a if a.ndim <= 1 else a.reshape(-1, a.shape[-1])[0]


def _per_vehicle(value):
    """An effect value as the cooler arithmetic broadcasts it: a float, or (V, 1) for one value per vehicle."""
    return np.asarray(value)[..., None] if np.ndim(value) else float(value)


def boundary_change_steps(bc_shift_k: np.ndarray) -> set:
    """The steps at which a per-step shift of the boundary temperatures (n, nb) takes a new value: step 0 and every
    step whose row differs from the row before (a 1 Hz table held on the 0.1 s grid changes every tenth step)."""
    moved = np.any(np.diff(np.asarray(bc_shift_k, dtype=float), axis=0) != 0.0, axis=1)
    return {0, *(int(k) + 1 for k in np.flatnonzero(moved))}
