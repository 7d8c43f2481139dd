"""Catalog of candidate unmodelled effects (CONTRACTS.md section 6).

Each effect is a physically parameterised term with one bounded parameter. All are off by default; a model switches
one on with its parameter (`retarder_heat:fraction=0.05`). The reference plant implements every effect; the onboard
model implements those that change its network (see firmware_model.onboard.reduce), which is what the gap diagnosis fits.
"""
from __future__ import annotations

from dataclasses import dataclass

from firmware_model.errors import InputError


@dataclass(frozen=True)
class Effect:
    id: str
    param: str
    unit: str
    low: float
    high: float
    neutral: float          # the value at which the effect does nothing
    description: str


CATALOG = {e.id: e for e in (
    Effect("retarder_heat", "fraction", "-", 0.0, 0.1, 0.0,
           "part of the retarder's braking power (retarder torque x output shaft speed) reaching the oil (80 %) and "
           "the rear bearing housing H3 (20 %)"),
    Effect("synchronizer_shift_heat", "energy_j", "J", 0.0, 5000.0, 0.0,
           "friction work released in the engaging synchronizer at every gear change (into the engaged wheel)"),
    Effect("churning_scale", "factor", "-", 0.5, 2.0, 1.0, "churning losses differ from the correlations"),
    Effect("gear_friction_scale", "factor", "-", 0.5, 1.5, 1.0, "gear-contact heat differs from the 0.75-scaled correlation"),
    Effect("planetary_loss_scale", "factor", "-", 0.5, 1.5, 1.0, "planetary heat differs from the 0.80-scaled correlation"),
    Effect("bearing_loss_scale", "factor", "-", 0.5, 3.0, 1.0, "bearing losses differ (e.g. preload from thermal expansion)"),
    Effect("teeth_oil_h_scale", "factor", "-", 0.5, 1.5, 1.0, "splash convection of input/main-shaft wheels differs from h_nom"),
    Effect("planet_oil_h_scale", "factor", "-", 0.5, 1.5, 1.0, "oil-system convection in the planetary differs from 750 W/(m2 K)"),
    Effect("housing_air_h_scale", "factor", "-", 0.3, 3.0, 1.0, "external housing convection differs from 10 W/(m2 K)"),
    Effect("cooler_effectiveness_scale", "factor", "-", 0.2, 1.2, 1.0, "cooler hA lower or higher than its data sheet"),
    Effect("thermostat_offset", "offset_c", "degC", -10.0, 10.0, 0.0, "the air cooler's thermostat opens at other temperatures"),
    Effect("hot_surroundings_offset", "offset_c", "degC", 0.0, 40.0, 0.0, "the hot surroundings are hotter"),
    Effect("oil_sensor_lag", "tau_s", "s", 0.0, 300.0, 0.0, "the oil sensor lags the sump (placement, filtering)"),
    Effect("oil_level_low", "volume_l", "L", 8.0, 13.5, 13.5, "less oil than nominal (less immersion, less thermal mass)"),
)}

EFFECT_IDS = tuple(CATALOG)


def parse_effect(spec: str) -> tuple[str, float]:
    """Parse `ID:PARAM=VALUE` (or `ID=VALUE`) into (id, value), checking id, parameter name and range."""
    s = spec.strip()
    if ":" in s:
        eid, rest = s.split(":", 1)
        if "=" not in rest:
            raise InputError(f"effect {spec!r} must look like ID:PARAM=VALUE, e.g. retarder_heat:fraction=0.05")
        pname, val = rest.split("=", 1)
    elif "=" in s:
        eid, val = s.split("=", 1)
        pname = None
    else:
        raise InputError(f"effect {spec!r} must look like ID:PARAM=VALUE, e.g. retarder_heat:fraction=0.05")
    eid = eid.strip()
    if eid not in CATALOG:
        raise InputError(f"unknown effect id {eid!r}; known effects: {', '.join(EFFECT_IDS)}")
    e = CATALOG[eid]
    if pname is not None and pname.strip() != e.param:
        raise InputError(f"effect {eid} has parameter {e.param!r}, not {pname.strip()!r}")
    try:
        v = float(val)
    except ValueError:
        raise InputError(f"effect {eid}: {e.param} = {val!r} is not a number") from None
    check_effect(eid, v)
    return eid, v


def check_effect(eid: str, value: float) -> None:
    e = CATALOG.get(eid)
    if e is None:
        raise InputError(f"unknown effect id {eid!r}; known effects: {', '.join(EFFECT_IDS)}")
    if not (e.low <= value <= e.high):
        raise InputError(f"effect {eid}: {e.param} = {value:g} {e.unit} is outside its plausible range "
                         f"{e.low:g}..{e.high:g} {e.unit}")


def effect_value(effects: dict | None, eid: str) -> float:
    """The effect's parameter, or its neutral value when the effect is off."""
    if effects and eid in effects:
        return float(effects[eid])
    return CATALOG[eid].neutral
