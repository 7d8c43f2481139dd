"""Catalog of candidate unmodelled effects, and the one record of effect values the models apply.

Each effect is a physically parameterised term with one bounded parameter. All are off by default; a model switches
one on with its parameter (`retarder_heat:fraction=0.05`). The reference plant implements every effect; the onboard
model implements those that change its network (see firmware_model.onboard.reduce), which is what the gap diagnosis
fits.
Both read the values through :class:`EffectScales` (:func:`effect_scales` from an ``{effect id: value}`` dict).
"""

from __future__ import annotations

from dataclasses import dataclass

from firmware_model.errors import InputError
from firmware_model.units import L_PER_M3


@dataclass(frozen=True)
class Effect:
    id: str
    param: str
    unit: str
    low: float
    high: float
    neutral: float  # the value at which the effect does nothing
    description: str


class _Catalog(dict):
    """The catalog by id. A channel effect (CHANNEL_EFFECTS) is one effect per measured channel, ``ID:CHANNEL``
    (``thermocouple_offset:PS``): looked up as the family's record under that id."""

    def __missing__(self, key):
        fam, sep, cid = str(key).partition(":")
        if sep and cid and fam in CHANNEL_EFFECTS and dict.__contains__(self, fam):
            from dataclasses import replace

            e = dict.__getitem__(self, fam)
            return replace(e, id=key, description=f"{e.description} ({cid})")
        raise KeyError(key)

    def __contains__(self, key):
        if dict.__contains__(self, key):
            return True
        fam, sep, cid = str(key).partition(":")
        return bool(sep and cid) and fam in CHANNEL_EFFECTS and dict.__contains__(self, fam)

    def get(self, key, default=None):
        return self[key] if key in self else default


#: effects that exist once per measured channel: ``thermocouple_offset:PS``
CHANNEL_EFFECTS = ("thermocouple_offset",)

CATALOG = _Catalog(
    {
        e.id: e
        for e in (
            Effect(
                "retarder_heat",
                "fraction",
                "-",
                0.0,
                0.1,
                0.0,
                "part of the retarder's braking power (retarder torque x output shaft speed) reaching the oil "
                "(80 %) and "
                "the rear bearing housing H3 (20 %)",
            ),
            Effect(
                "synchronizer_shift_heat",
                "energy_j",
                "J",
                0.0,
                5000.0,
                0.0,
                "friction work released in the engaging synchronizer at every gear change (into the engaged wheel)",
            ),
            Effect("churning_scale", "factor", "-", 0.5, 2.0, 1.0, "churning losses differ from the correlations"),
            Effect(
                "gear_friction_scale",
                "factor",
                "-",
                0.5,
                1.5,
                1.0,
                "gear-contact heat differs from the 0.75-scaled correlation",
            ),
            Effect(
                "planetary_loss_scale",
                "factor",
                "-",
                0.5,
                1.5,
                1.0,
                "planetary heat differs from the 0.80-scaled correlation",
            ),
            Effect(
                "bearing_loss_scale",
                "factor",
                "-",
                0.5,
                3.0,
                1.0,
                "bearing losses differ (e.g. preload from thermal expansion)",
            ),
            Effect(
                "teeth_oil_h_scale",
                "factor",
                "-",
                0.5,
                1.5,
                1.0,
                "splash convection of input/main-shaft wheels differs from h_nom",
            ),
            Effect(
                "planet_oil_h_scale",
                "factor",
                "-",
                0.5,
                1.5,
                1.0,
                "oil-system convection in the planetary differs from 750 W/(m2 K)",
            ),
            Effect(
                "housing_air_h_scale",
                "factor",
                "-",
                0.3,
                3.0,
                1.0,
                "external housing convection differs from 10 W/(m2 K)",
            ),
            Effect(
                "cooler_effectiveness_scale",
                "factor",
                "-",
                0.2,
                1.2,
                1.0,
                "cooler hA lower or higher than its data sheet",
            ),
            Effect(
                "thermostat_offset",
                "offset_c",
                "degC",
                -10.0,
                10.0,
                0.0,
                "the air cooler's thermostat opens at other temperatures",
            ),
            Effect("hot_surroundings_offset", "offset_c", "degC", 0.0, 40.0, 0.0, "the hot surroundings are hotter"),
            Effect(
                "oil_sensor_lag", "tau_s", "s", 0.0, 300.0, 0.0, "the oil sensor lags the sump (placement, filtering)"
            ),
            Effect(
                "oil_level_low",
                "volume_l",
                "L",
                8.0,
                13.5,
                13.5,
                "less oil than nominal (less immersion, less thermal mass)",
            ),
            Effect(
                "oil_sensor_offset",
                "offset_c",
                "degC",
                -5.0,
                5.0,
                0.0,
                "the oil sensor reads a constant offset from the sump (calibration, or placed in a warmer "
                "or colder spot)",
            ),
            Effect(
                "oil_sensor_gain",
                "factor",
                "-",
                0.9,
                1.1,
                1.0,
                "the oil sensor's gain is off: it reads gain x the sump temperature in degC (scaling or calibration)",
            ),
            Effect(
                "thermocouple_offset",
                "offset_c",
                "degC",
                -5.0,
                5.0,
                0.0,
                "a rig thermocouple reads a constant offset (calibration, or placed off the component's mean)",
            ),
        )
    }
)

#: the effects a model can switch on by id (channel effects are instances, ``thermocouple_offset:PS``)
EFFECT_IDS = tuple(e for e in CATALOG if e not in CHANNEL_EFFECTS)


class IdFamilies(tuple):
    """A tuple of effect ids that also contains every channel instance (``thermocouple_offset:PS``) of its channel
    families."""

    def __contains__(self, key):
        return (
            tuple.__contains__(self, key)
            or str(key).partition(":")[0] in CHANNEL_EFFECTS
            and tuple.__contains__(self, str(key).partition(":")[0])
        )


#: effects on the measurement, not on the gearbox: the models' temperatures are unchanged, the sensor reads them
#: differently (the gap diagnosis applies them to its predictions without re-simulating); thermocouple_offset:<id>
#: per rig thermocouple
MEASUREMENT_EFFECTS = IdFamilies(("oil_sensor_offset", "oil_sensor_gain", "thermocouple_offset"))


def channel_effect(family: str, cid: str) -> str:
    """The id of a channel effect on one channel: ``thermocouple_offset:PS``."""
    return f"{family}:{cid}"


def effect_channel(eid: str) -> str | None:
    """The channel of a channel effect's id (None for other effects)."""
    fam, sep, cid = str(eid).partition(":")
    return cid if sep and fam in CHANNEL_EFFECTS else None


#: the effects that change the gearbox's physics (the single-effect benchmark plants these)
PHYSICAL_EFFECT_IDS = tuple(e for e in EFFECT_IDS if e not in MEASUREMENT_EFFECTS)
#: where the retarder_heat effect deposits its heat (node -> share; the catalog's description)
RETARDER_HEAT_SPLIT = {"oil": 0.8, "H3": 0.2}


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
    if eid in CHANNEL_EFFECTS:
        if pname is None or ":" not in pname:
            raise InputError(
                f"effect {spec!r}: {eid} acts on one measured channel: {eid}:CHANNEL:PARAM=VALUE, e.g. "
                f"{eid}:PS:{CATALOG[eid].param}=1.5"
            )
        cid, pname = pname.split(":", 1)
        from firmware_model.components import HOUSINGS, PUBLISHED

        if cid.strip() not in PUBLISHED + tuple(HOUSINGS) + ("oil@rig",):
            raise InputError(
                f"effect {spec!r}: {cid.strip()!r} is not a component id (docs/interfaces.md section 5) or oil@rig"
            )
        eid = channel_effect(eid, cid.strip())
    if eid not in CATALOG:
        raise InputError(f"unknown effect id {eid!r}; known effects: {', '.join(EFFECT_IDS + CHANNEL_EFFECTS)}")
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
        unit = "" if e.unit in ("", "-") else f" {e.unit}"
        raise InputError(
            f"effect {eid}: {e.param} = {value:g}{unit} is outside its plausible range {e.low:g}..{e.high:g}{unit}"
        )


def fraction_of_range(eid: str, value: float) -> float:
    """How far `value` sits from the effect's neutral value towards the bound on its side (0..1)."""
    e = CATALOG[eid]
    bound = e.high if value >= e.neutral else e.low
    return (value - e.neutral) / (bound - e.neutral) if bound != e.neutral else 0.0


def effect_value(effects: dict | None, eid: str) -> float:
    """The effect's parameter, or its neutral value when the effect is off."""
    if effects and eid in effects:
        return float(effects[eid])
    return CATALOG[eid].neutral


#: effect id -> field of EffectScales that carries its value
FIELD_OF_EFFECT = {
    "retarder_heat": "retarder_frac",
    "synchronizer_shift_heat": "shift_energy_j",
    "churning_scale": "churn_scale",
    "gear_friction_scale": "gear_friction_scale",
    "planetary_loss_scale": "planetary_scale",
    "bearing_loss_scale": "bearing_scale",
    "teeth_oil_h_scale": "teeth_oil_h",
    "planet_oil_h_scale": "planet_oil_h",
    "housing_air_h_scale": "housing_air_h",
    "cooler_effectiveness_scale": "cooler_scale",
    "thermostat_offset": "thermostat_offset_c",
    "hot_surroundings_offset": "hot_offset_c",
    "oil_sensor_lag": "oil_sensor_tau_s",
    "oil_level_low": "oil_volume_l",
    "oil_sensor_offset": "oil_sensor_offset_c",
    "oil_sensor_gain": "oil_sensor_gain",
}


@dataclass(frozen=True)
class EffectScales:
    """The effect values as the models apply them: multipliers (1.0 = as the seed's model), offsets and amounts,
    neutral by default. Each is a float, or in the onboard model an array of per-vehicle values (V,).

    Losses (heat of each family): gear contacts, planetary meshes, churning, bearings (shaft and needle). Heat
    transfer: splash h of the idle-wheel teeth, oil-system h in the planetary, external housing h. Cooler: its hA
    and its thermostat. Boundaries: the hot surroundings. Sources: retarder heat (fraction of its braking power),
    synchronizer heat per shift. The oil sensor's lag, offset and gain, and the sump volume. ``src_scale`` is the
    onboard model's
    multiplier per loss-source column (firmware_model.onboard.reduce.make_effects fills it; None elsewhere).
    """

    gear_friction_scale: object = 1.0
    planetary_scale: object = 1.0
    churn_scale: object = 1.0
    bearing_scale: object = 1.0
    teeth_oil_h: object = 1.0
    planet_oil_h: object = 1.0
    housing_air_h: object = 1.0
    cooler_scale: object = 1.0
    thermostat_offset_c: object = 0.0
    hot_offset_c: object = 0.0
    retarder_frac: object = 0.0
    shift_energy_j: object = 0.0
    oil_sensor_tau_s: object = 0.0
    oil_volume_l: object = CATALOG["oil_level_low"].neutral
    oil_sensor_offset_c: object = 0.0
    oil_sensor_gain: object = 1.0
    src_scale: object = None

    @property
    def needle_scale(self):
        """Multiplier on the needle (idle-wheel) bearing heat: the bearing-loss scale."""
        return self.bearing_scale


def effect_scales(effects: dict | None = None) -> EffectScales:
    """EffectScales of an {effect id: value} dict (ids not given take their neutral value). A channel effect
    (thermocouple_offset:ID) is refused: it acts on a rig's reading, and a model writes the true temperatures."""
    bad = [e for e in (effects or {}) if effect_channel(e) is not None]
    if bad:
        raise InputError(
            f"effect {bad[0]} acts on a rig thermocouple's reading, not on the gearbox: a model writes "
            f"the true temperatures, so there is nothing to offset (the gap diagnosis fits it; "
            f"bench-diagnosis plants it)"
        )
    return EffectScales(**{FIELD_OF_EFFECT[eid]: effect_value(effects, eid) for eid in EFFECT_IDS})


def oil_level_refusal(params) -> str | None:
    """Why effect oil_level_low cannot act on ``params``' gearbox, or None when it can: its range (8..13.5 L, neutral
    13.5) is the GRS905 family's sump (the ``oil.volume`` parameter); another gearbox's oil volume is its
    description's ``topology.oil.volume``, which the effect's litres do not describe (for an 11 L sump, 12 L would
    be more oil, not less)."""
    if "oil.volume" in params.values:
        return None
    return (
        f"effect oil_level_low's range {CATALOG['oil_level_low'].low:g}..{CATALOG['oil_level_low'].high:g} L is the "
        "GRS905 family's sump, and this gearbox's oil volume is its description's topology.oil.volume"
    )


def with_oil_volume(params, volume_l: float):
    """The parameter set with the sump holding ``volume_l`` litres when that is below nominal (effect
    oil_level_low: less immersion, less thermal mass); the set itself otherwise. InputError for a gearbox the
    effect does not describe (:func:`oil_level_refusal`)."""
    if volume_l < CATALOG["oil_level_low"].neutral:
        why = oil_level_refusal(params)
        if why is not None:
            raise InputError(f"{why}: give a lower volume there (a copy of the description) to run it with less oil")
        return params.with_overrides({"oil.volume": volume_l * (1.0 / L_PER_M3)})
    return params
