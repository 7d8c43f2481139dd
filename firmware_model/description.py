"""The gearbox description as data: what a gearbox is made of and how its power flows (docs/description.md).

A description is the ``[topology]`` section of a parameter file (firmware_model/params/*.toml, or a user's own file):
shafts with their segments and positions, wheels, meshes, planetary sets, couplings, bearings, housings, the oil
system, the gears with their power paths and stated ratios, what drives the gearbox, its boundaries and the
components it publishes. Every value is written as in the rest of the file (``{ v, u, src }``) or taken from a
parameter of the file with its unit and provenance (``{ from = "gear.L.z1" }``), so a variant that overrides a
parameter (GRSO905 inherits GRS905) changes its description with it.

:func:`load_description` reads a description by name or path and checks that it holds together before anything
runs: a description that does not is a ParameterError of one sentence naming the file, the key and why (the CLI
turns it into exit status 2). SI units throughout; temperatures in degC.

    >>> d = load_description("GRS905")
    >>> len(d.published), d.gear("4L").number, round(d.gear("4L").ratio, 4)
    (28, 9, 3.0336)
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

from firmware_model.errors import ParameterError
from firmware_model.limits import GROUPS as LIMIT_GROUPS
from firmware_model.limits import load_limits
from firmware_model.parameters import (
    DIM_NAMES,
    PARAM_DIR,
    PROVENANCES,
    TOPOLOGY,
    UNITS,
    VARIANTS,
    Parameters,
    is_topology,
    read_entries,
    read_toml,
)
from firmware_model.physics.losses import ADDENDUM_COEF, DEDENDUM_COEF
from firmware_model.physics.oil import T_MAX_C, T_MIN_C
from firmware_model.units import RAD_S_PER_RPM

#: units a description may use: the parameter files' and volume flows (a motor-driven pump)
DESC_UNITS = {**UNITS, "L/min": ("m3/s", 1e-3 / 60.0), "m3/s": ("m3/s", 1.0), "K": ("K", 1.0)}
DESC_DIM_NAMES = {**DIM_NAMES, "m3/s": "a volume flow", "K": "a temperature difference"}
#: the unit of each SI dimension whose factor is 1 (a parameter set's SI value written as an entry, unchanged)
SI_UNIT = {}
for _u, (_dim, _fac) in DESC_UNITS.items():
    if _fac == 1.0:
        SI_UNIT.setdefault(_dim, _u)

#: how a wheel sits: turning on its shaft until a coupling engages it, fixed to it, cut into it, on a stationary pin
MOUNTS = ("idle", "fixed", "cut", "pin")
SIDES = ("covered", "free")
BEARING_KINDS = ("tapered", "ball", "needle", "cylindrical", "spherical")
COUPLING_KINDS = ("sync", "dog", "clutch")
LUBRICATIONS = ("splash", "forced")
COOLERS = ("none", "liquid", "air")
DRIVES = ("vehicle", "fixed_ratio")
#: what a planetary step of a power path may hold (``range/ring``); ``locked`` turns the set as one body
HELD = ("sun", "ring", "carrier", "locked")
#: a coupling member that is no part: the gearbox casing (a brake holding a ring gear)
CASING = "housing"
#: the node of the pumped oil on its way to the jets (after the pump, filter and cooler) of a forced oil system
OIL_INLET = "oil.inlet"
#: a boundary's temperature: the range the oil model describes [degC] (physics.oil.check_temperature_c); beyond it
#: the convection to the housing is thousands of W (-300 degC lies below absolute zero)
BOUNDARY_RANGE_C = (T_MIN_C, T_MAX_C)
#: where a thermostatic bypass may plausibly open: the oil's working range [degC]
THERMOSTAT_RANGE_C = (40.0, 150.0)
#: how far a shaft may step down to a bearing seat: the shaft's diameter over the bearing's bore at most (a shoulder
#: of common shaft design practice, D/d 1.1..1.5; the GRS905's layshaft journals are 50 mm on 62 mm, 1.24); a pilot
#: bearing (seated inside another shaft) sits on a spigot at the shaft's end and is not held to it
SHOULDER_MAX = 1.5
#: a shaft's length (its segments' span and both ends) over the square root of its housings' total area, at most:
#: a shaft lies mostly inside its housing (the shipped shafts: 0.06-0.26; positions in mm written u = "m" make it
#: about 1000 times too long, and every wheel and bearing still lies on its shaft)
SHAFT_LENGTH_PER_HOUSING = 2.0
#: a bearing's mass over what its rings' annulus pi/4 (D^2 - d^2) B of solid bearing steel would weigh: a bearing is
#: lighter than that solid ring (the shipped bearings: 0.60-0.87), a mass in grams or tonnes is 1000 times off
BEARING_MASS_PER_ANNULUS = (0.1, 2.0)
BEARING_STEEL_KG_M3 = 7850.0
#: a wheel's (a planetary set's) face width over its (the sun's) pitch diameter, at most (the shipped: up to 1.26;
#: practice for pinions, b/d 0.5-1.5): a width in mm written u = "m" is 1000 times too wide
FACE_WIDTH_PER_PITCH = 3.0
#: the helix angles of helical and spur gears [deg] (the shipped: 0-20 deg); 10 written u = "rad" is 573 deg
HELIX_RANGE_DEG = (0.0, 45.0)
#: the boundaries a cooler reaches without touching a part: a liquid cooler's coolant, an air cooler's ambient
COOLER_BOUNDARIES = ("coolant", "ambient")
#: where the thermostat reads the oil: "return" the oil leaving the cooler and bypass, T_sump - Q / (mdot cp) (seed
#: Eq 82, the default); "sump" the oil the pump draws, before the cooler (a valve upstream of the cooler)
THERMOSTAT_SENSES = ("return", "sump")
#: what the cooler takes while the sump is measured: "thermostat" its law at the measured sump (the default, as
#: with the sump modelled); "balance" the heat the sump's balance leaves at its reading (an air cooler's, bounded by
#: its fully open valve): a thermostat's band is too narrow a guide once a real sump sits a few kelvin off it
MEASURED_COOLER = ("thermostat", "balance")

# field specifications: name -> (kind, required, dimension, sign); kind text | list | number | int | table;
# sign "+" (> 0), "0+" (>= 0), "-0" (<= 0), "share" (> 0 and <= 1: a share of a whole) or "any"
_T, _L = ("text", True, None, None), ("list", True, None, None)
_t, _l = ("text", False, None, None), ("list", False, None, None)


def _n(dim: str, required: bool = True, sign: str = "+") -> tuple:
    return ("number", required, dim, sign)


def _i(required: bool = True, sign: str = "+") -> tuple:
    return ("int", required, "1", sign)


SPECS = {
    "shaft": {
        "name": _t,
        "d_out": _n("m"),
        "d_bore": _n("m", sign="0+"),
        "x_front": _n("m", False, "any"),
        "x_rear": _n("m", False, "any"),
        "overhang_front": _n("m", False, "0+"),
        "overhang_rear": _n("m", False, "0+"),
        "segments": _L,
        "x": ("table", True, "m", "any"),
        "wetted_length": _n("m", False),
    },
    "wheel": {
        "name": _t,
        "shaft": _t,
        "segment": _t,
        "mount": _T,
        "teeth": _i(),
        "module": _n("m"),
        "helix": _n("rad", sign="0+"),
        "width": _n("m"),
        "x": _n("m", sign="any"),
        "bore": _n("m", False),
        "sides": _t,
        "immersion": _n("1", False, "share"),
    },
    "planetary": {
        "sun": _T,
        "planet": _T,
        "ring": _T,
        "sun_shaft": _T,
        "sun_segment": _t,
        "carrier_shaft": _T,
        "carrier_segment": _t,
        "z_sun": _i(),
        "z_planet": _i(),
        "z_ring": _i(),
        "n_planets": _i(),
        "module": _n("m"),
        "helix": _n("rad", sign="0+"),
        "width": _n("m"),
        "x": _n("m", sign="any"),
        "mass_sun": _n("kg", False),
        "mass_planets": _n("kg", False),
        "mass_ring": _n("kg", False),
        "carrier_mass": _n("kg", False),
        "ring_area": _n("m2", False),
    },
    "mesh": {"wheels": _L, "centre_distance": _n("m", False)},
    "coupling": {"kind": _T, "joins": _L},
    "bearing": {
        "name": _t,
        "kind": _T,
        "shaft": _t,
        "segment": _t,
        "housing": _t,
        "inside": _t,
        "wheel": _t,
        "bore": _n("m", False),
        "outer": _n("m", False),
        "width": _n("m"),
        "roller": _n("m", False),
        "x": _n("m", False, "any"),
        "rollers": _i(False),
        "mass": _n("kg", False),
        "immersion": _n("1", False, "share"),
    },
    "housing": {
        "name": _t,
        "material": _T,
        "mass": _n("kg"),
        "area": _n("m2"),
        "internal_split": _n("1", sign="0+"),
        "faces": _L,
        "x": _n("m", False, "any"),
        "joined_to": _t,
        "joint_area": _n("m2", False),
        "share": ("table", False, "1", "0+"),
    },
    "gear": {"number": _i(sign="any"), "path": _L, "ratio": _n("1", False, "any")},
    "boundary": {"temperature": _n("degC", sign="any"), "touches": _L, "conductance": _n("W/K", False)},
}
#: the sections that hold one table, not one table per id
SINGLE_SPECS = {
    "oil": {
        "lubrication": _T,
        "volume": _n("m3"),
        "pump_shaft": _t,
        "pump_flow": ("number", False, ("m3/rad", "m3/s"), "+"),
        "pump_stops_below": _n("rad/s", False),
        "jets": _l,
        "dipping": _l,
        "splashed": _l,
        "filter": _t,
        "cooler": _T,
        "thermostat_open": _n("degC", False, "any"),
        "thermostat_full": _n("degC", False, "any"),
        "thermostat_senses": _t,
        "measured_cooler": _t,
        "heater": _n("W", False, "0+"),
        "heater_set": _n("degC", False, "any"),
        "heater_band": _n("K", False),
        "inside_area": _n("m2", False),
        "flow_share": ("table", False, "1", "0+"),
    },
    "check": {"ratio_rel_tol": _n("1", False), "profile_shift_max": _n("1", False)},
    "drive": {
        "kind": _T,
        "input_shaft": _T,
        "output_shaft": _T,
        "max_speed": _n("rad/s"),
        "max_torque": _n("N m"),
        "min_torque": _n("N m", False, "-0"),
    },
}
#: the published section: the order, the limits file, and one list of ids per limit group (any other key)
PUBLISHED_KEYS = ("order", "limits")
SECTIONS = tuple(SPECS) + tuple(SINGLE_SPECS) + ("published",)
REQUIRED_SECTIONS = ("shaft", "mesh", "housing", "oil", "gear", "drive", "boundary", "published")
DEFAULT_CHECK = {"ratio_rel_tol": 0.005, "profile_shift_max": 1.0}


@dataclass(frozen=True)
class Segment:
    """A piece of a shaft with one node: its id (``MS@2M``) and axial position [m]."""

    id: str
    x_m: float


@dataclass(frozen=True)
class Shaft:
    id: str
    name: str
    d_out_m: float
    d_bore_m: float
    segments: tuple
    front_m: float  # the shaft's front end [m]
    rear_m: float  # its rear end [m]
    wetted_length_m: float | None = None  # the length of its splashed segments the thrown oil wets (Eq 62)


@dataclass(frozen=True)
class Wheel:
    id: str
    mount: str  # MOUNTS
    teeth: int
    module_m: float
    helix_rad: float
    width_m: float
    x_m: float
    shaft: str | None  # None: on a pin
    segment: str | None
    bore_m: float | None  # diameter of the bore (idle and pin wheels)
    sides: str | None = None  # SIDES: the web sides covered by neighbouring wheels or free (splash area)
    name: str | None = None  # what it is, in a few words
    immersion: float | None = None  # the share of its tip diameter dipping into the sump (a dipping wheel)


@dataclass(frozen=True)
class PlanetarySet:
    id: str
    sun: str
    planet: str
    ring: str
    sun_shaft: str
    sun_segment: str | None
    carrier_shaft: str
    carrier_segment: str | None
    z_sun: int
    z_planet: int
    z_ring: int
    n_planets: int
    module_m: float
    helix_rad: float
    width_m: float
    x_m: float
    mass_sun_kg: float | None = None
    mass_planets_kg: float | None = None  # all planets with their bearings
    mass_ring_kg: float | None = None
    carrier_mass_kg: float | None = None  # the carrier segment's mass (left out: the segment's own)
    ring_area_m2: float | None = None  # the ring gear's outer area the oil reaches

    def teeth(self, member: str) -> int:
        return {self.sun: self.z_sun, self.planet: self.z_planet, self.ring: self.z_ring}[member]


@dataclass(frozen=True)
class Mesh:
    id: str
    wheels: tuple  # (wheel 1, wheel 2)
    centre_distance_m: float  # stated by the shafts' axes, else the standard one
    standard_m: float  # m_n (z1 +- z2) / (2 cos beta)
    internal: bool  # wheel 2 is a ring gear


@dataclass(frozen=True)
class Coupling:
    id: str
    kind: str
    joins: tuple  # the engaged member first, then what it can be engaged to


@dataclass(frozen=True)
class Bearing:
    id: str
    kind: str
    shaft: str
    segment: str
    housing: str | None  # seated in a housing ...
    inside: str | None  # ... or inside another shaft's segment (a pilot bearing)
    wheel: str | None  # under an idle wheel
    bore_m: float | None
    outer_m: float | None
    width_m: float
    roller_m: float | None
    x_m: float | None
    name: str | None = None  # what it is, in a few words
    rollers: int | None = None  # the number of rolling elements
    mass_kg: float | None = None
    immersion: float | None = None  # the immersed share of its height, dipping into the sump (Eq 53)


@dataclass(frozen=True)
class Housing:
    id: str
    name: str
    material: str
    mass_kg: float
    area_m2: float
    internal_split: float
    faces: tuple
    x_m: float | None = None  # position of its node (for the conduction across a joint)
    joined_to: str | None = None  # the housing it is bolted to
    joint_area_m2: float | None = None  # the flange's cross-section
    shares: dict = field(default_factory=dict)  # boundary -> share of its outside facing it (faces by convection)


@dataclass(frozen=True)
class OilSystem:
    lubrication: str
    volume_m3: float
    pump_shaft: str | None
    pump_flow: float | None  # m3/rad for a shaft-driven pump, m3/s for a motor-driven one
    jets: tuple
    filter: str
    cooler: str
    thermostat_open_c: float | None
    thermostat_full_c: float | None
    heater_w: float
    dipping: tuple = ()  # the parts that dip into the sump
    splashed: tuple = ()  # the parts the thrown oil splashes
    inside_area_m2: float | None = None  # the housings' inside area, shared by their internal_split
    flow_share: dict = field(default_factory=dict)  # shaft (its bore), bearing or planetary set -> share of the flow
    thermostat_senses: str = "return"  # where the thermostat reads the oil (THERMOSTAT_SENSES)
    heater_set_c: float | None = None  # the sump heater is off above it [degC]
    heater_band_k: float | None = None  # ... and at full power below heater_set - heater_band [K]
    pump_stops_below_rad_s: float | None = None  # a motor pump runs only while the input shaft turns faster
    measured_cooler: str = "thermostat"  # the cooler's heat while the sump is measured (MEASURED_COOLER)


@dataclass(frozen=True)
class Gear:
    name: str
    number: int
    path: tuple
    stated_ratio: float | None
    ratio: float  # input speed / output speed from the teeth along the path (inf: neutral)
    meshes: tuple = ()  # the meshes that carry the power, in the path's order (none in neutral)
    engaged: tuple = ()  # the couplings the path engages
    held: tuple = ()  # (planetary set, held member or "locked") of each set the path passes


@dataclass(frozen=True)
class Drive:
    kind: str
    input_shaft: str
    output_shaft: str
    max_speed_rad_s: float
    max_torque_nm: float
    min_torque_nm: float


@dataclass(frozen=True)
class Boundary:
    id: str
    temperature_c: float
    touches: tuple
    conductance_w_per_k: float | None = None  # of each touch by conduction (None: through a cooler or the housing)


@dataclass(frozen=True)
class Published:
    id: str
    group: str
    warning_c: float | None
    critical_c: float | None


@dataclass(frozen=True)
class Description:
    """A checked gearbox description; every collection in the file's order."""

    name: str
    origin: str
    shafts: tuple
    wheels: tuple
    planetary: tuple
    meshes: tuple
    couplings: tuple
    bearings: tuple
    housings: tuple
    oil: OilSystem
    gears: tuple
    drive: Drive
    boundaries: tuple
    published: tuple
    provenance: dict = field(default_factory=dict)  # dotted key -> seed | derived | assumed | fitted
    #: the parameters its { from } entries take (a copy of a parameter set overriding none describes the same gearbox)
    taken: frozenset = frozenset()
    #: the warning-limits file its published.limits names (resolved: beside the description, else a shipped one)
    limits_path: str | None = None
    #: whether published.limits names the limits file (else the default, limits.toml: the GRS905 truck's)
    limits_stated: bool = True

    def _one(self, items, key: str):
        return next((x for x in items if getattr(x, "id", getattr(x, "name", None)) == key), None)

    def shaft(self, id_: str) -> Shaft | None:
        return self._one(self.shafts, id_)

    def wheel(self, id_: str) -> Wheel | None:
        return self._one(self.wheels, id_)

    def gear(self, name: str) -> Gear | None:
        return self._one(self.gears, name)

    @property
    def names(self) -> dict:
        """What each part is, in a few words (printed output, legends): shafts, wheels, planetary members (sun
        wheel, planet wheels, ring gear), bearings and housings by id, and the sump; a part without a name is left
        out."""
        out = {s.id: s.name for s in self.shafts}
        out.update({w.id: w.name for w in self.wheels if w.name})
        for ps in self.planetary:
            out.update({ps.sun: "sun wheel", ps.planet: "planet wheels", ps.ring: "ring gear"})
        out.update({b.id: b.name for b in self.bearings if b.name})
        out.update({h.id: h.name for h in self.housings})
        out["oil"] = "oil sump"
        if self.oil is not None and self.oil.lubrication == "forced":
            out[OIL_INLET] = "oil inlet (to the jets)"
        return out

    @property
    def nodes(self) -> tuple:
        """The thermal nodes the description implies, in the network's order: shaft segments, idle wheels (teeth
        and bulk), the other wheels, planetary members, bearings, housings and the sump (a forced oil system's inlet
        is no node: it is `derived`)."""
        out = [s.id for sh in self.shafts for s in sh.segments]
        out += [f"{w.id}.{part}" for w in self.wheels if w.mount == "idle" for part in ("teeth", "bulk")]
        out += [w.id for w in self.wheels if w.mount != "idle"]
        out += [m for ps in self.planetary for m in (ps.sun, ps.planet, ps.ring)]
        out += [b.id for b in self.bearings] + [h.id for h in self.housings] + ["oil"]
        return tuple(out)

    @property
    def derived(self) -> tuple:
        """The temperatures computed from the nodes rather than held by one: for forced lubrication the oil inlet
        (the pumped oil after the pump, filter and cooler, before the jets), the sump minus the cooler's drop
        Q / (mdot cp) (physics.cooler.inlet_drop_k: the temperature the jets' streams take)."""
        return (OIL_INLET,) if self.oil is not None and self.oil.lubrication == "forced" else ()


# ---------------------------------------------------------------------------------------------------------------
# reading


class _Reader:
    """The file's entries and the messages that name it."""

    def __init__(self, path: Path, entries: dict, params: Parameters | None = None):
        self.path, self.entries, self.params = path, entries, params
        self.provenance: dict = {}
        self.taken: set = set()

    def fail(self, key: str, why: str):
        raise ParameterError(f"{self.path.name}: {key} {why}")

    def resolve(self, key: str, raw) -> dict:
        """The entry ``{ v, u, src }`` of a key, following ``{ from = "parameter" }``."""
        if isinstance(raw, dict) and "from" in raw and "v" not in raw:
            src_key = raw["from"]
            if not isinstance(src_key, str) or is_topology(src_key) or src_key not in self.entries:
                self.fail(key, f"takes its value from {src_key!r}, which is no parameter of this file")
            raw = self._parameter(src_key, self.entries[src_key])
            self.taken.add(src_key)
        if not isinstance(raw, dict) or "v" not in raw:
            self.fail(key, 'must be a table { v = ..., u = ..., src = ... } or { from = "parameter" }')
        if raw.get("src") not in PROVENANCES:
            self.fail(key, f"has provenance {raw.get('src')!r}; it must be one of {', '.join(PROVENANCES)}")
        self.provenance[key] = raw["src"]
        return raw

    def _parameter(self, src_key: str, raw):
        """The file's entry of a parameter, or, describing a parameter set, the set's SI value (an overridden or
        fitted value follows; the file's value converted to SI is the same float)."""
        p = self.params
        if p is None or src_key not in p.values or not isinstance(raw, dict) or p.units.get(src_key) not in SI_UNIT:
            return raw
        return {**raw, "v": p.values[src_key], "u": SI_UNIT[p.units[src_key]], "src": p.sources[src_key]}

    def value(self, key: str, raw, spec: tuple):
        kind, _, dim, sign = spec
        e = self.resolve(key, raw)
        v = e["v"]
        if kind == "text":
            if not isinstance(v, str) or not v:
                self.fail(key, f"= {v!r} must be text in quotes")
            return v
        if kind == "list":
            if not isinstance(v, list) or not all(isinstance(x, str) and x for x in v):
                self.fail(key, f"= {v!r} must be a list of ids in quotes")
            return tuple(v)
        return self.number(key, e, kind, dim, sign)

    def number(self, key: str, e: dict, kind: str, dim, sign: str):
        v, u = e["v"], e.get("u")
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(key, f"= {v!r} is not a number")
        dims = dim if isinstance(dim, tuple) else (dim,)
        if u not in DESC_UNITS or DESC_UNITS[u][0] not in dims:
            allowed = " or ".join(f'"{x}"' for x, (d, _) in DESC_UNITS.items() if d in dims)
            what = " or ".join(DESC_DIM_NAMES.get(d, d) for d in dims)
            known = u in DESC_UNITS
            given = f"{u!r} ({DESC_DIM_NAMES.get(DESC_UNITS[u][0], DESC_UNITS[u][0])})" if known else f"{u!r}"
            if u == "K" and "degC" in DESC_UNITS and DESC_UNITS["degC"][0] in dims:
                given = "'K' (a temperature difference, or kelvin)"
            self.fail(key, f"has unit {given}, but it is {what}: write it with u = {allowed}")
        x = float(v) * DESC_UNITS[u][1]
        if not math.isfinite(x):
            self.fail(key, f"= {v} is not a finite number")
        if kind == "int" and x != int(x):
            self.fail(key, f"= {v:g} must be a whole number")
        bad = {"+": x <= 0, "0+": x < 0, "-0": x > 0, "share": not 0 < x <= 1}.get(sign, False)
        if bad:
            rule = {
                "+": "greater than zero",
                "0+": "zero or more",
                "-0": "zero or less",
                "share": "greater than zero and at most 1 (a share of the whole: 0..1)",
            }[sign]
            self.fail(key, f"= {v:g}{'' if u == '-' else ' ' + u} must be {rule}")
        return int(x) if kind == "int" else x

    def fields(self, key: str, table, spec: dict) -> dict:
        """The values of one table by field name, every field known and every required one present."""
        if not isinstance(table, dict) or "v" in table or "from" in table:
            self.fail(key, "must be a section of fields, such as [" + key + "]")
        for name in table:
            if name not in spec:
                close = difflib.get_close_matches(name, list(spec), n=1)
                hint = f" (did you mean {close[0]}?)" if close else ""
                self.fail(f"{key}.{name}", f"is an unknown key{hint}; known: {', '.join(spec)}")
        out = {}
        for name, fs in spec.items():
            if name not in table:
                if fs[1]:
                    self.fail(key, f"has no {name}; required: {', '.join(n for n, s in spec.items() if s[1])}")
                out[name] = None
            elif fs[0] == "table":
                sub = table[name]
                if not isinstance(sub, dict) or "v" in sub or "from" in sub:
                    self.fail(f"{key}.{name}", "must be a section of one entry per id")
                out[name] = {
                    k: self.value(f"{key}.{name}.{k}", r, ("number", True, fs[2], fs[3])) for k, r in sub.items()
                }
            else:
                out[name] = self.value(f"{key}.{name}", table[name], fs)
        return out


def _nest(entries: dict) -> dict:
    """The topology entries (dotted keys below ``topology.``) as nested sections."""
    root: dict = {}
    for key, e in entries.items():
        if not is_topology(key):
            continue
        parts = key.split(".")[1:]
        d = root
        for p in parts[:-1]:
            d = d.setdefault(p, {})
        d[parts[-1]] = e
    return root


def _sections(r: _Reader, topo: dict) -> None:
    """Every section of the topology known, every required one present."""
    if not topo:
        r.fail(f"[{TOPOLOGY}]", "is missing: the file describes no gearbox (docs/description.md)")
    for name in topo:
        if name not in SECTIONS:
            close = difflib.get_close_matches(name, SECTIONS, n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            r.fail(f"{TOPOLOGY}.{name}", f"is an unknown section{hint}; known: {', '.join(SECTIONS)}")
    for name in REQUIRED_SECTIONS:
        if not topo.get(name):
            r.fail(f"{TOPOLOGY}.{name}", f"is missing; a description needs {', '.join(REQUIRED_SECTIONS)}")


def _per_id(r: _Reader, topo: dict, section: str) -> list:
    """(id, dotted key, field values) of every table of a per-id section, in the file's order."""
    spec = SPECS[section]
    tables = topo.get(section) or {}
    return [(i, f"{TOPOLOGY}.{section}.{i}", r.fields(f"{TOPOLOGY}.{section}.{i}", t, spec)) for i, t in tables.items()]


def _shafts(r: _Reader, topo: dict) -> tuple:
    out = []
    for sid, key, f in _per_id(r, topo, "shaft"):
        segs, xs = f["segments"], f["x"]
        if not segs:
            r.fail(f"{key}.segments", "is empty; a shaft has at least one segment")
        for s in segs:
            if s not in xs:
                r.fail(f"{key}.x", f"has no position for segment {s}")
        for s in xs:
            if s not in segs:
                r.fail(f"{key}.x.{s}", f"is no segment of the shaft; its segments: {', '.join(segs)}")
        pos = [xs[s] for s in segs]
        for a, b, xa, xb in zip(segs, segs[1:], pos, pos[1:]):
            if xb < xa:
                r.fail(f"{key}.x.{b}", f"= {xb:g} m lies in front of {a} ({xa:g} m): list segments front to rear")
        if f["d_bore"] >= f["d_out"]:
            r.fail(f"{key}.d_bore", f"= {f['d_bore']:g} m must be smaller than d_out = {f['d_out']:g} m")
        ends = _shaft_ends(r, key, f, pos)
        segments = tuple(Segment(s, x) for s, x in zip(segs, pos))
        out.append(Shaft(sid, f["name"] or sid, f["d_out"], f["d_bore"], segments, *ends, f["wetted_length"]))
    return tuple(out)


def _shaft_ends(r: _Reader, key: str, f: dict, pos: list) -> tuple:
    """(front, rear) of a shaft: stated (x_front, x_rear) or its outer segments plus their overhangs."""
    stated = f["x_front"] is not None or f["x_rear"] is not None
    overhang = f["overhang_front"] is not None or f["overhang_rear"] is not None
    if stated == overhang or (stated and None in (f["x_front"], f["x_rear"])):
        r.fail(key, "needs its ends: x_front and x_rear, or overhang_front and overhang_rear (not both pairs)")
    if stated:
        if not (f["x_front"] <= pos[0] and pos[-1] <= f["x_rear"]):
            r.fail(f"{key}.x_front", "and x_rear must enclose the shaft's segments")
        return f["x_front"], f["x_rear"]
    if None in (f["overhang_front"], f["overhang_rear"]):
        r.fail(key, "needs both overhang_front and overhang_rear")
    return pos[0] - f["overhang_front"], pos[-1] + f["overhang_rear"]


def _wheels(r: _Reader, topo: dict, shafts: dict) -> tuple:
    out = []
    for wid, key, f in _per_id(r, topo, "wheel"):
        mount, shaft, seg = f["mount"], f["shaft"], f["segment"]
        if mount not in MOUNTS:
            r.fail(f"{key}.mount", f"= {mount!r} must be one of {', '.join(MOUNTS)}")
        if mount == "pin":
            if shaft is not None:
                r.fail(f"{key}.shaft", "must be left out: a wheel on a pin sits on no shaft")
        elif shaft not in shafts:
            known = ", ".join(shafts)
            r.fail(f"{key}.shaft", f"= {shaft!r} is no shaft of the description (mount {mount}); shafts: {known}")
        elif seg not in [s.id for s in shafts[shaft].segments]:
            r.fail(f"{key}.segment", f"= {seg!r} is no segment of shaft {shaft}")
        if mount in ("idle", "pin") and f["bore"] is None:
            r.fail(key, f"has no bore: a wheel that turns on its {'pin' if mount == 'pin' else 'shaft'} needs one")
        if f["sides"] is not None and f["sides"] not in SIDES:
            r.fail(f"{key}.sides", f"= {f['sides']!r} must be one of {', '.join(SIDES)}")
        _check_gear_size(r, key, f["teeth"], f["module"], f["helix"], f["width"])
        w = Wheel(wid, mount, f["teeth"], f["module"], f["helix"], f["width"], f["x"], shaft, seg, f["bore"])
        _check_wheel_fits(r, key, w, shafts)
        if mount != "pin" and shaft in shafts:
            _check_on_shaft(r, key, f["x"], shafts[shaft], seg, "wheel")
        out.append(replace(w, sides=f["sides"], name=f["name"], immersion=f["immersion"]))
    return tuple(out)


def _check_on_shaft(r: _Reader, key: str, x_m: float, shaft: Shaft, seg: str, what: str) -> None:
    """A wheel or a bearing lies between its shaft's ends and nearer its own segment's node than any other's: the
    bearings' share of the mesh forces and the conduction along the shaft come from these positions (a wheel's x
    in metres for millimetres put a 110 kW reducer's bearing at 6600 degC, exit 0)."""
    xs = {g.id: g.x_m for g in shaft.segments}
    if not shaft.front_m <= x_m <= shaft.rear_m:
        r.fail(
            f"{key}.x",
            f"= {x_m:g} m lies outside shaft {shaft.id}, {shaft.front_m:g}..{shaft.rear_m:g} m (another unit? "
            'millimetres are written u = "mm")',
        )
    elif seg in xs:
        near = min(xs, key=lambda k: abs(xs[k] - x_m))
        if abs(xs[near] - x_m) < abs(xs[seg] - x_m) - 1e-9:
            r.fail(
                f"{key}.x",
                f"= {x_m:g} m is nearer segment {near} ({xs[near]:g} m) than its own segment {seg} ({xs[seg]:g} m): a "
                f"{what} sits on its segment's piece of the shaft; correct its x or its segment",
            )


def _as_written(r: _Reader, key: str, si: float, si_unit: str) -> str:
    """A value as the file writes it (``10 rad``), or in SI when it is taken from a parameter."""
    e = r.entries.get(key)
    if isinstance(e, dict) and isinstance(e.get("v"), (int, float)) and isinstance(e.get("u"), str):
        return f"{e['v']:g} {e['u']}"
    return f"{si:g} {si_unit}"


def _check_gear_size(r: _Reader, key: str, teeth: int, module_m: float, helix_rad: float, width_m: float) -> None:
    """A helix angle within HELIX_RANGE_DEG, checked before anything is derived from it (10 written u = "rad", 573
    deg, was said as a tip diameter of -103 mm), and a face width at most FACE_WIDTH_PER_PITCH times the pitch
    diameter (50 mm written u = "m" was said as a node's explicit step: merge the node with a neighbour)."""
    lo, hi = HELIX_RANGE_DEG
    deg = math.degrees(helix_rad)
    if not lo <= deg <= hi:
        written = _as_written(r, f"{key}.helix", deg, "deg")
        shown = written if written.endswith(" deg") else f"{written} ({deg:.3g} deg)"
        r.fail(
            f"{key}.helix",
            f"= {shown} lies outside {lo:g}..{hi:g} deg, the helix angles of spur and helical gears (another unit? "
            'degrees are written u = "deg")',
        )
    d_pitch = module_m * teeth / math.cos(helix_rad)
    if width_m > FACE_WIDTH_PER_PITCH * d_pitch:
        r.fail(
            f"{key}.width",
            f"= {_as_written(r, f'{key}.width', width_m, 'm')} is {width_m / d_pitch:.3g} times its pitch diameter "
            f"{d_pitch * 1e3:.3g} mm (z {teeth}, module {module_m * 1e3:g} mm): a face width is at most "
            f'{FACE_WIDTH_PER_PITCH:g} times it (another unit? millimetres are written u = "mm")',
        )


def _check_wheel_fits(r: _Reader, key: str, w: Wheel, shafts: dict) -> None:
    """A wheel is larger than what it sits on: an idle wheel's bore than its shaft, the root circle of a wheel than
    its bore (idle, pin) or its shaft (fixed), a cut wheel's tip circle than its shaft (its teeth stand out of it);
    else its body has a negative mass (ISO 53 basic rack, as physics.geometry builds it)."""
    d_pitch = w.module_m * w.teeth / math.cos(w.helix_rad)
    d_root, d_tip = d_pitch - 2 * DEDENDUM_COEF * w.module_m, d_pitch + 2 * ADDENDUM_COEF * w.module_m
    size = f"(z {w.teeth}, module {w.module_m * 1e3:g} mm)"
    d_shaft = shafts[w.shaft].d_out_m if w.shaft is not None else None
    if w.mount == "idle" and w.bore_m <= d_shaft:
        r.fail(
            f"{key}.bore",
            f"= {w.bore_m * 1e3:g} mm is not larger than its shaft {w.shaft} (d_out = {d_shaft * 1e3:g} mm): an idle "
            "wheel turns on a bearing around its shaft",
        )
    inner, what = (w.bore_m, "its bore") if w.mount in ("idle", "pin") else (d_shaft, f"its shaft {w.shaft}'s d_out")
    outer, circle = (d_tip, "tip") if w.mount == "cut" else (d_root, "root")
    if outer <= inner:
        r.fail(
            key,
            f"{size} has a {circle} diameter of {outer * 1e3:.4g} mm, not larger than {what} {inner * 1e3:g} mm: "
            f"the wheel is smaller than what it sits on",
        )


def _planetary(r: _Reader, topo: dict, shafts: dict) -> tuple:
    out = []
    for pid, key, f in _per_id(r, topo, "planetary"):
        for k, seg_k in (("sun_shaft", "sun_segment"), ("carrier_shaft", "carrier_segment")):
            if f[k] not in shafts:
                r.fail(f"{key}.{k}", f"= {f[k]!r} is no shaft of the description; shafts: {', '.join(shafts)}")
            if f[seg_k] is not None and f[seg_k] not in [s.id for s in shafts[f[k]].segments]:
                r.fail(f"{key}.{seg_k}", f"= {f[seg_k]!r} is no segment of shaft {f[k]}")
        zs, zp, zr, n = f["z_sun"], f["z_planet"], f["z_ring"], f["n_planets"]
        _check_gear_size(r, key, zs, f["module"], f["helix"], f["width"])  # the sun: the smallest member
        if abs((zr - zs) / 2 - zp) > 0.5:
            r.fail(f"{key}.z_planet", f"= {zp} does not fit between sun and ring: it must be (z_ring - z_sun) / 2")
        if (zs + zr) % n:
            r.fail(
                f"{key}.n_planets",
                f"= {n}: (z_sun + z_ring) / n_planets = {(zs + zr) / n:g} is not whole, so "
                "the planets cannot be spaced evenly",
            )
        members = (f["sun"], f["planet"], f["ring"])
        if len(set(members)) < 3:
            r.fail(key, f"names a member twice ({', '.join(members)}): sun, planet and ring are three parts")
        out.append(
            PlanetarySet(
                pid,
                *members,
                f["sun_shaft"],
                f["sun_segment"],
                f["carrier_shaft"],
                f["carrier_segment"],
                zs,
                zp,
                zr,
                n,
                f["module"],
                f["helix"],
                f["width"],
                f["x"],
                f["mass_sun"],
                f["mass_planets"],
                f["mass_ring"],
                f["carrier_mass"],
                f["ring_area"],
            )
        )
    return tuple(out)


def _gear_of(wheels: dict, planetary: tuple, member: str):
    """(teeth, module, helix, shaft or None, ring?) of a wheel or planetary member; None if there is none."""
    if member in wheels:
        w = wheels[member]
        return w.teeth, w.module_m, w.helix_rad, w.shaft if w.mount in ("fixed", "cut") else None, False
    for ps in planetary:
        if member in (ps.sun, ps.planet, ps.ring):
            shaft = ps.sun_shaft if member == ps.sun else None
            return ps.teeth(member), ps.module_m, ps.helix_rad, shaft, member == ps.ring
    return None


def _meshes(r: _Reader, topo: dict, wheels: dict, planetary: tuple, check: dict) -> tuple:
    out = []
    for mid, key, f in _per_id(r, topo, "mesh"):
        pair = f["wheels"]
        if len(pair) != 2 or pair[0] == pair[1]:
            r.fail(f"{key}.wheels", f"= {list(pair)} must name two different wheels")
        g = [_gear_of(wheels, planetary, w) for w in pair]
        for w, gw in zip(pair, g):
            if gw is None:
                r.fail(f"{key}.wheels", f"names {w}, which is no wheel or planetary member of the description")
        (z1, m1, b1, _, _), (z2, m2, b2, _, ring) = g
        s1, s2 = (wheels[w].shaft if w in wheels else g_[3] for w, g_ in zip(pair, g))
        if g[0][4]:
            r.fail(f"{key}.wheels", f"= {list(pair)}: put the ring gear {pair[0]} second")
        if not math.isclose(m1, m2, rel_tol=1e-9):
            r.fail(f"{key}.wheels", f"= {list(pair)}: their modules disagree ({m1 * 1e3:g} mm and {m2 * 1e3:g} mm)")
        if not math.isclose(b1, b2, rel_tol=1e-9, abs_tol=1e-12):
            r.fail(
                f"{key}.wheels",
                f"= {list(pair)}: their helix angles disagree ({math.degrees(b1):g} deg and {math.degrees(b2):g} deg)",
            )
        if s1 is not None and s1 == s2:
            r.fail(f"{key}.wheels", f"= {list(pair)} sit on one shaft ({s1}) and cannot mesh")
        std = m1 * (z2 - z1 if ring else z1 + z2) / (2 * math.cos(b1))
        a = std if f["centre_distance"] is None else f["centre_distance"]
        shift = abs(a - std) / m1
        if shift > check["profile_shift_max"] + 1e-12:
            r.fail(
                f"{key}.centre_distance",
                f"= {a * 1e3:g} mm disagrees with the wheels' standard centre distance "
                f"{std * 1e3:.4g} mm by {shift:.2g} modules; a profile shift covers at most "
                f"{check['profile_shift_max']:g} (topology.check.profile_shift_max)",
            )
        out.append(Mesh(mid, tuple(pair), a, std, ring))
    return tuple(out)


def _couplings(r: _Reader, topo: dict, members: set) -> tuple:
    out = []
    for cid, key, f in _per_id(r, topo, "coupling"):
        if f["kind"] not in COUPLING_KINDS:
            r.fail(f"{key}.kind", f"= {f['kind']!r} must be one of {', '.join(COUPLING_KINDS)}")
        joins = f["joins"]
        if not 2 <= len(joins) <= 3 or len(set(joins)) < len(joins):
            r.fail(f"{key}.joins", f"= {list(joins)} must name a member and one or two others it engages to")
        for m in joins:
            if m not in members and m != CASING:
                r.fail(f"{key}.joins", f"names {m}, which is no shaft, wheel or planetary member (or {CASING!r})")
        out.append(Coupling(cid, f["kind"], joins))
    return tuple(out)


def _bearings(r: _Reader, topo: dict, shafts: dict, wheels: dict, housings: set) -> tuple:
    out = []
    segments = {s.id for sh in shafts.values() for s in sh.segments}
    for bid, key, f in _per_id(r, topo, "bearing"):
        if f["kind"] not in BEARING_KINDS:
            r.fail(f"{key}.kind", f"= {f['kind']!r} must be one of {', '.join(BEARING_KINDS)}")
        if f["wheel"] is not None:  # under an idle wheel: on the wheel's shaft and segment
            w = wheels.get(f["wheel"])
            if w is None or w.mount != "idle":
                r.fail(f"{key}.wheel", f"= {f['wheel']!r} is no idle wheel of the description")
            for k in ("shaft", "segment", "housing", "inside"):
                if f[k] is not None:
                    r.fail(f"{key}.{k}", "must be left out: a wheel bearing sits under its wheel")
            shaft, seg = w.shaft, w.segment
        else:
            shaft, seg = f["shaft"], f["segment"]
            if shaft not in shafts:
                r.fail(f"{key}.shaft", f"= {shaft!r} is no shaft of the description; shafts: {', '.join(shafts)}")
            if seg not in [s.id for s in shafts[shaft].segments]:
                r.fail(f"{key}.segment", f"= {seg!r} is no segment of shaft {shaft}")
            if (f["housing"] is None) == (f["inside"] is None):
                r.fail(key, "needs one seat: housing (a housing id) or inside (another shaft's segment)")
            if f["housing"] is not None and f["housing"] not in housings:
                r.fail(f"{key}.housing", f"= {f['housing']!r} is no housing; housings: {', '.join(housings)}")
            if f["inside"] is not None and (f["inside"] not in segments or f["inside"] == seg):
                r.fail(f"{key}.inside", f"= {f['inside']!r} is no segment of another shaft")
            if f["bore"] is None or f["outer"] is None:
                r.fail(key, "needs bore and outer (diameters of a shaft bearing)")
            if f["bore"] >= f["outer"]:
                r.fail(f"{key}.bore", f"= {f['bore'] * 1e3:g} mm must be smaller than outer = {f['outer'] * 1e3:g} mm")
            _check_seat(r, key, f, shafts[shaft])
        if shaft in shafts and f["x"] is not None:
            _check_on_shaft(r, key, f["x"], shafts[shaft], seg, "bearing")
        _check_bearing_mass(r, key, f)
        out.append(
            Bearing(
                bid,
                f["kind"],
                shaft,
                seg,
                f["housing"],
                f["inside"],
                f["wheel"],
                f["bore"],
                f["outer"],
                f["width"],
                f["roller"],
                f["x"],
                f["name"],
                f["rollers"],
                f["mass"],
                f["immersion"],
            )
        )
    return tuple(out)


def _check_bearing_mass(r: _Reader, key: str, f: dict) -> None:
    """A bearing's mass (when given, with its bore and outer diameter) within BEARING_MASS_PER_ANNULUS of what its
    rings' annulus of solid steel would weigh: 6100 kg for a 120 x 215 mm bearing (grams written kg) passed and made
    its node a heat sink that never warmed."""
    m, d, D, B = f["mass"], f["bore"], f["outer"], f["width"]
    if m is None or d is None or D is None or not D > d:
        return
    solid_kg = math.pi / 4 * (D * D - d * d) * B * BEARING_STEEL_KG_M3
    lo, hi = BEARING_MASS_PER_ANNULUS
    if not lo <= m / solid_kg <= hi:
        r.fail(
            f"{key}.mass",
            f"= {_as_written(r, f'{key}.mass', m, 'kg')} is {m / solid_kg:.3g} times what its rings would weigh as "
            f"solid steel ({solid_kg:.3g} kg: pi/4 (D^2 - d^2) B x {BEARING_STEEL_KG_M3:g} kg/m3 for "
            f"{d * 1e3:g} x {D * 1e3:g} x {B * 1e3:g} mm); a bearing weighs {lo:g}-{hi:g} times that (another unit? "
            'kilograms are written u = "kg")',
        )


def _check_seat(r: _Reader, key: str, f: dict, shaft: Shaft) -> None:
    """A shaft bearing seated in a housing sits on a journal of its shaft, stepped down at most SHOULDER_MAX."""
    if f["inside"] is None and shaft.d_out_m > SHOULDER_MAX * f["bore"]:
        r.fail(
            f"{key}.bore",
            f"= {f['bore'] * 1e3:g} mm is too small for its shaft {shaft.id} (d_out = {shaft.d_out_m * 1e3:g} mm, "
            f"{shaft.d_out_m / f['bore']:.2f} times the bore): a bearing seat is a journal of the shaft, stepped down "
            f"by a shoulder of at most {SHOULDER_MAX:g}:1 (a bore of {shaft.d_out_m / SHOULDER_MAX * 1e3:.3g} mm or "
            "more); a bearing on a spigot at the shaft's end is a pilot bearing (inside)",
        )


def _check_joint(r: _Reader, key: str, f: dict, topo: dict) -> None:
    """A housing bolted to another names a housing that is not itself, with the flange's area and both positions."""
    j = f["joined_to"]
    if j is None:
        if f["joint_area"] is not None:
            r.fail(f"{key}.joint_area", "is given, but the housing is joined to no other (joined_to)")
        return
    others = topo.get("housing") or {}
    if j not in others or f"{TOPOLOGY}.housing.{j}" == key:
        r.fail(f"{key}.joined_to", f"= {j!r} is no other housing; housings: {', '.join(others)}")
    if f["joint_area"] is None or f["x"] is None or not isinstance(others[j], dict) or "x" not in others[j]:
        r.fail(key, f"is joined to {j} but lacks joint_area, or x (here or in {j}): the joint's conduction needs both")


def _check_shares(r: _Reader, key: str, shares: dict, faces: tuple) -> None:
    """Each share of a housing's outside names a boundary it faces; together they are at most all of it."""
    for b, x in shares.items():
        if b not in faces:
            r.fail(f"{key}.share.{b}", f"names no boundary the housing faces; faces: {', '.join(faces)}")
        if x > 1:
            r.fail(f"{key}.share.{b}", f"= {x:g} is more than the whole outside (1)")
    total = sum(shares.values())
    if total > 1 + 1e-9:
        r.fail(f"{key}.share", f"adds up to {total:g}; the shares of the outside add up to 1 at most")


def _housings(r: _Reader, topo: dict, boundaries: set) -> tuple:
    out = []
    materials = sorted({k.split(".")[1] for k in r.entries if k.startswith("material.")})
    for hid, key, f in _per_id(r, topo, "housing"):
        if materials and f["material"] not in materials:
            r.fail(
                f"{key}.material",
                f"= {f['material']!r} has no [material.{f['material']}] in the file; materials: {', '.join(materials)}",
            )
        if not f["faces"]:  # its outside would exchange nothing: the sump read what the shafts' ends gave it
            r.fail(
                f"{key}.faces",
                "is empty: the housing's outside (housing.external_frac of its area) would exchange heat with nothing; "
                "name the boundaries around it (as ambient)",
            )
        for b in f["faces"]:
            if b not in boundaries:
                r.fail(f"{key}.faces", f"names {b}, which is no boundary; boundaries: {', '.join(boundaries)}")
        _check_joint(r, key, f, topo)
        shares = f["share"] or {}
        _check_shares(r, key, shares, f["faces"])
        h = Housing(hid, f["name"] or hid, f["material"], f["mass"], f["area"], f["internal_split"], f["faces"])
        _check_wall(r, key, h)
        out.append(replace(h, x_m=f["x"], joined_to=f["joined_to"], joint_area_m2=f["joint_area"], shares=shares))
    split = sum(h.internal_split for h in out)
    if out and abs(split - 1.0) > 1e-6:
        r.fail(f"{TOPOLOGY}.housing.*.internal_split", f"add up to {split:g}; the housings share the inside: 1")
    return tuple(out)


#: a housing's mass over its material's density and its outside area: the wall it makes [mm], plausible between
#: these (the shipped housings: 6-62 mm); outside, the mass or the area is in another unit (tonnes as kg, mm2 as m2)
WALL_MM = (1.0, 300.0)


def _check_wall(r: _Reader, key: str, h) -> None:
    """The wall a housing's mass, material and area make lies within WALL_MM (a housing of 700 m2 and 550 kg, a
    0.1 mm wall, read its sump at the air's temperature while a bearing ran 58 K over it, exit 0)."""
    rho = r.entries.get(f"material.{h.material}.rho")
    if not isinstance(rho, dict) or rho.get("u") != "kg/m3" or not isinstance(rho.get("v"), (int, float)):
        return  # (a density in another unit or from elsewhere: its own checks)
    if not (rho["v"] > 0 and h.mass_kg > 0 and h.area_m2 > 0):
        return
    wall_mm = h.mass_kg / (float(rho["v"]) * h.area_m2) * 1e3
    if not WALL_MM[0] <= wall_mm <= WALL_MM[1]:
        r.fail(
            key,
            f"has a mass of {h.mass_kg:g} kg over {h.area_m2:g} m2 of {h.material} ({rho['v']:g} kg/m3): a wall "
            f"{wall_mm:.3g} mm thick, where a housing's walls are {WALL_MM[0]:g}-{WALL_MM[1]:g} mm; is the mass or "
            "the area in another unit?",
        )


def _single(r: _Reader, topo: dict, section: str) -> dict:
    return r.fields(f"{TOPOLOGY}.{section}", topo.get(section) or {}, SINGLE_SPECS[section])


def cooler_flow_refusal(kind: str, pump_flow) -> str | None:
    """Why an oil cooler of ``kind`` cannot work in an oil system with this pump flow (None: no pump), or None: a
    liquid or air cooler takes its heat from the oil the pump drives through it (Eq 82-83, its conductance scaled
    by that flow), so without a pump it takes none, in silence (178 degC with an 'air' cooler that removed 0 W)."""
    if kind in ("liquid", "air") and not pump_flow:
        return (
            "an oil cooler takes its heat from the oil a pump drives through it, and this oil system has no pump "
            '(pump_flow): give the pump\'s flow, or cooler = "none" (a housing cooled by the air around it: its '
            "area and h_air)"
        )
    return None


def _oil(r: _Reader, topo: dict, shafts: dict, nodes: set) -> OilSystem:
    key = f"{TOPOLOGY}.oil"
    f = _single(r, topo, "oil")
    if f["lubrication"] not in LUBRICATIONS:
        r.fail(f"{key}.lubrication", f"= {f['lubrication']!r} must be one of {', '.join(LUBRICATIONS)}")
    if f["lubrication"] == "forced" and (f["pump_flow"] is None or not f["jets"]):
        r.fail(key, "has forced lubrication but no pump_flow or no jets (what the pumped oil reaches)")
    if f["pump_shaft"] is not None and f["pump_shaft"] not in shafts:
        r.fail(
            f"{key}.pump_shaft", f"= {f['pump_shaft']!r} is no shaft of the description; shafts: {', '.join(shafts)}"
        )
    for k in ("jets", "dipping", "splashed"):
        for j in f[k] or ():
            if j not in nodes:
                r.fail(f"{key}.{k}", f"names {j}, which is no part of the description")
    _check_splash_reaches(r, key, f)
    if f["cooler"] not in COOLERS:
        r.fail(f"{key}.cooler", f"= {f['cooler']!r} must be one of {', '.join(COOLERS)}")
    t_open, t_full = f["thermostat_open"], f["thermostat_full"]
    if (t_open is None) != (t_full is None):
        r.fail(key, "needs both thermostat_open and thermostat_full (a bypass opens between them), or neither")
    if t_open is not None:
        lo, hi = THERMOSTAT_RANGE_C
        if not lo <= t_open <= hi:
            r.fail(
                f"{key}.thermostat_open",
                f"= {t_open:g} degC lies outside the oil's plausible working range "
                f"{lo:g}..{hi:g} degC: the bypass would never (or always) be open",
            )
        if t_full <= t_open:
            r.fail(f"{key}.thermostat_full", f"= {t_full:g} degC must lie above thermostat_open = {t_open:g} degC")
        if f["cooler"] == "none":
            r.fail(f"{key}.thermostat_open", 'is given, but there is no cooler (cooler = "none") to bypass')
    why = cooler_flow_refusal(f["cooler"], f["pump_flow"])
    if why:
        r.fail(f"{key}.cooler", f"= {f['cooler']!r}: {why}")
    # a run's cooler kind (the file's [cooler] kind, or a configuration's) may leave the cooler out or hold the sump,
    # but not ask for a cooler the description does not have
    raw = r.entries.get(f"{key}.cooler")
    linked = isinstance(raw, dict) and raw.get("from") == "cooler.kind"  # the run's kind is the description's
    kind = r.params.strings.get("cooler.kind") if r.params is not None else None
    if linked and kind is not None:
        why = cooler_flow_refusal(kind, f["pump_flow"])
        if why:
            r.fail(f"{key}.cooler", f"= {kind!r} (the run's cooler kind): {why}")
    elif kind in ("liquid", "air") and kind != f["cooler"]:
        r.fail(
            f"{key}.cooler",
            f"= {f['cooler']!r} but the run's cooler kind is {kind!r} (the file's [cooler] kind, or a "
            "configuration's): say it once (cooler = { from = \"cooler.kind\" } takes the [cooler] section's)",
        )
    senses = f["thermostat_senses"] or "return"
    if senses not in THERMOSTAT_SENSES:
        r.fail(f"{key}.thermostat_senses", f"= {senses!r} must be one of {', '.join(THERMOSTAT_SENSES)}")
    elif f["thermostat_senses"] is not None and t_open is None:
        r.fail(f"{key}.thermostat_senses", "is given, but there is no thermostat (thermostat_open, thermostat_full)")
    measured_cooler = _measured_cooler(r, key, f, t_open)
    _check_heater_and_pump(r, key, f)
    return OilSystem(
        f["lubrication"],
        f["volume"],
        f["pump_shaft"],
        f["pump_flow"],
        f["jets"] or (),
        f["filter"] or "none",
        f["cooler"],
        t_open,
        t_full,
        f["heater"] or 0.0,
        f["dipping"] or (),
        f["splashed"] or (),
        f["inside_area"],
        f["flow_share"] or {},
        senses,
        f["heater_set"],
        f["heater_band"],
        f["pump_stops_below"],
        measured_cooler,
    )


def _check_splash_reaches(r: _Reader, key: str, f: dict) -> None:
    """A splash-lubricated oil system names something in the oil: what dips (dipping) or what is splashed (the R1
    names only what its wheel throws over); with neither, the wheels and bearings exchanged heat with the oil through
    nothing and a pinion ran at 257 degC, exit 0."""
    if f["lubrication"] == "splash" and not f["dipping"] and not f["splashed"]:
        r.fail(
            f"{key}.dipping",
            "and splashed are empty: a splash-lubricated gearbox's oil reaches its wheels and bearings by a part "
            "dipping into the sump that throws it over the others; name what dips (dipping) and what it splashes "
            "(splashed)",
        )


def _measured_cooler(r: _Reader, key: str, f: dict, t_open) -> str:
    """``measured_cooler`` (MEASURED_COOLER, default "thermostat"); "balance" only for an air cooler behind a
    thermostat."""
    measured_cooler = f["measured_cooler"] or "thermostat"
    if measured_cooler not in MEASURED_COOLER:
        r.fail(f"{key}.measured_cooler", f"= {measured_cooler!r} must be one of {', '.join(MEASURED_COOLER)}")
    elif measured_cooler == "balance" and (f["cooler"] != "air" or t_open is None):
        r.fail(
            f"{key}.measured_cooler",
            '= "balance" needs an air cooler behind a thermostat (cooler = "air", thermostat_open, thermostat_full)',
        )
    return measured_cooler


def _check_heater_and_pump(r: _Reader, key: str, f: dict) -> None:
    """A heater (power above 0) says the sump temperature it holds and its band; neither without one. A pump that
    stops with the machine is a motor-driven one (a shaft's pump stops with its shaft)."""
    if f["pump_stops_below"] is not None and (f["pump_shaft"] is not None or f["pump_flow"] is None):
        r.fail(
            f"{key}.pump_stops_below",
            "is given, but there is no motor-driven pump (pump_flow without pump_shaft): a shaft's pump stops with it",
        )
    if (f["heater"] or 0.0) > 0.0:
        for k, what in (("heater_set", "the sump temperature it holds"), ("heater_band", "its band below it")):
            if f[k] is None:
                r.fail(f"{key}.{k}", f"is needed: the heater (heater = {f['heater'] / 1e3:g} kW) needs {what}")
    else:
        for k in ("heater_set", "heater_band"):
            if f[k] is not None:
                r.fail(f"{key}.{k}", "is given, but there is no heater (heater = 0 or left out)")


def _check_oil_fits(r: _Reader, oil: OilSystem, housings: tuple) -> None:
    """The oil volume fits in its housings: no more than a sphere of their outside surface holds (half their total
    area, which counts both faces; the sphere encloses the most for its surface), a loose bound that still catches a
    volume in the wrong unit (6 m3 for the MM82's 300 L)."""
    outside_m2 = 0.5 * sum(h.area_m2 for h in housings)
    most_m3 = outside_m2**1.5 / (6.0 * math.sqrt(math.pi))
    if oil.volume_m3 > most_m3:
        r.fail(
            f"{TOPOLOGY}.oil.volume",
            f"= {oil.volume_m3 * 1e3:g} L does not fit in the housings: a sphere of their outside surface (half their "
            f"total area, {outside_m2:.3g} m2) holds {most_m3 * 1e3:.3g} L; is the volume in another unit?",
        )


def _check_oil_covers_the_dipping(r: _Reader, oil: OilSystem, wheels: tuple) -> None:
    """The sump holds at least what its dipping wheels' immersed parts displace (the circular segment of each tip
    circle under its immersion, over its face width): a volume in the wrong unit (0.04 L for 40 L) passed and cut
    the churning sevenfold."""
    displaced_m3 = 0.0
    for w in wheels:
        if w.immersion is None or w.id not in oil.dipping:
            continue
        R = (w.module_m * w.teeth / math.cos(w.helix_rad) + 2 * ADDENDUM_COEF * w.module_m) / 2
        h = min(w.immersion, 1.0) * 2 * R
        segment_m2 = R * R * math.acos((R - h) / R) - (R - h) * math.sqrt(max(2 * R * h - h * h, 0.0))
        displaced_m3 += segment_m2 * w.width_m
    if displaced_m3 > oil.volume_m3:
        r.fail(
            f"{TOPOLOGY}.oil.volume",
            f"= {oil.volume_m3 * 1e3:g} L is less than the dipping wheels' immersed parts displace "
            f"({displaced_m3 * 1e3:.3g} L, from their tip circles, immersion and face widths); is the volume in "
            "another unit, or an immersion too deep?",
        )


def _check_oil_controls(r: _Reader, oil: OilSystem, drive) -> None:
    """A heater's set point within the oil model's range, a pump that stops below a speed the drive reaches (else it
    would heat or stand always: a unit or a digit wrong, no model)."""
    lo, hi = BOUNDARY_RANGE_C
    if oil.heater_set_c is not None and not lo <= oil.heater_set_c <= hi:
        r.fail(
            f"{TOPOLOGY}.oil.heater_set",
            f"= {oil.heater_set_c:g} degC lies outside the oil model's range {lo:g}..{hi:g} degC",
        )
    stop = oil.pump_stops_below_rad_s
    if stop is not None and drive is not None and not stop < drive.max_speed_rad_s:
        r.fail(
            f"{TOPOLOGY}.oil.pump_stops_below",
            f"= {stop / RAD_S_PER_RPM:g} rpm is not below the drive's top input speed "
            f"({drive.max_speed_rad_s / RAD_S_PER_RPM:g} rpm): the pump would never run",
        )


def _boundaries(r: _Reader, topo: dict) -> tuple:
    out = []
    for b, key, f in _per_id(r, topo, "boundary"):
        if f["conductance"] is not None and not f["touches"]:
            r.fail(f"{key}.conductance", "is given, but the boundary touches nothing")
        lo, hi = BOUNDARY_RANGE_C
        if not lo <= f["temperature"] <= hi:
            r.fail(
                f"{key}.temperature",
                f"= {f['temperature']:g} degC lies outside the plausible range {lo:g}..{hi:g} degC (the oil model's; "
                "no gearbox in use is surrounded by a colder or hotter boundary)",
            )
        out.append(Boundary(b, f["temperature"], f["touches"], f["conductance"]))
    return tuple(out)


def _check_touches(r: _Reader, boundaries: tuple, nodes: set) -> None:
    for b in boundaries:
        for n in b.touches:
            if n not in nodes:
                r.fail(f"{TOPOLOGY}.boundary.{b.id}.touches", f"names {n}, which is no part of the description")


def _check_boundaries_used(r: _Reader, boundaries: tuple, housings: tuple, oil: OilSystem) -> None:
    """Every boundary takes heat from something: a part it touches by conduction (touches with a conductance), a
    housing facing it (faces), or a cooler reaching it (COOLER_BOUNDARIES, while there is a cooler)."""
    faced = {f for h in housings for f in h.faces}
    for b in boundaries:
        if b.id in faced or (b.touches and b.conductance_w_per_k is not None):
            continue
        if oil.cooler != "none" and b.id in COOLER_BOUNDARIES:
            continue
        r.fail(
            f"{TOPOLOGY}.boundary.{b.id}",
            "touches no part and no housing faces it: it would exchange heat with nothing; name the parts it touches "
            "by conduction (touches, with a conductance) or face it from a housing (faces)",
        )


def _check_shaft_lengths(r: _Reader, shafts: tuple, housings: tuple) -> None:
    """A shaft at most SHAFT_LENGTH_PER_HOUSING times the square root of its housings' total area long: positions
    in mm written u = "m" throughout (shafts, wheels, bearings alike) made 300 m shafts whose wheels and bearings all
    lay on them, and the sump read 31 degC for 55; an overhang of 210 m did the same."""
    area_m2 = sum(h.area_m2 for h in housings)
    if area_m2 <= 0:
        return
    most_m = SHAFT_LENGTH_PER_HOUSING * math.sqrt(area_m2)
    for sh in shafts:
        length = sh.rear_m - sh.front_m
        if length <= most_m:
            continue
        first, last = sh.segments[0].x_m, sh.segments[-1].x_m
        r.fail(
            f"{TOPOLOGY}.shaft.{sh.id}",
            f"is {length:.4g} m long (its segments over {last - first:.4g} m, ends {first - sh.front_m:.4g} m and "
            f"{sh.rear_m - last:.4g} m beyond them), more than {SHAFT_LENGTH_PER_HOUSING:g} times the square root of "
            f"its housings' total area ({math.sqrt(area_m2):.3g} m, of {area_m2:g} m2): a shaft lies mostly inside "
            'its housing (another unit? millimetres are written u = "mm")',
        )


def conduction_links(d: Description) -> tuple:
    """The pairs (node, node or boundary id) the thermal network joins by a conductance, as network.build_network
    links them from the description (the test holds them to the network's): conduction along the shafts, wheels,
    bearings and planetary members to their seats, the meshes' contact, what dips, is splashed or jetted to the
    sump, the housings to the sump, to each other and to the boundaries they face, the boundaries' conduction."""
    out = [(a.id, b.id) for sh in d.shafts for a, b in zip(sh.segments, sh.segments[1:])]
    idle = {w.id for w in d.wheels if w.mount == "idle"}
    whole = {w.id for w in d.wheels if w.mount != "idle"}
    for w in d.wheels:
        if w.mount == "idle":
            out.append((f"{w.id}.teeth", f"{w.id}.bulk"))
        elif w.shaft is not None:
            out.append((w.id, w.segment))
    shaft_brgs = {b.id for b in d.bearings if b.wheel is None}
    for b in d.bearings:
        seat = f"{b.wheel}.bulk" if b.wheel is not None else b.inside or b.housing
        out += [(b.id, b.segment), (b.id, seat)]
    for ps in d.planetary:
        out += [(ps.planet, ps.carrier_segment), (ps.sun, ps.sun_segment)]
    out += [tuple(f"{w}.teeth" if w in idle else w for w in m.wheels) for m in d.meshes]
    oil = d.oil
    jets = set(oil.jets)  # (a splash gearbox's pump may feed jets too: the GRS905's)
    forced = jets if oil.lubrication == "forced" else set()
    segments = {g.id for sh in d.shafts for g in sh.segments}
    rings = {ps.ring for ps in d.planetary}
    out += [(x, "oil") for x in oil.dipping if x in whole or x in shaft_brgs]
    splashed = [x for x in oil.splashed if x.endswith(".teeth") or x in segments | rings | shaft_brgs]
    out += [(x, "oil") for x in splashed + [w for w in whole if w in set(oil.splashed) | forced]]
    out += [(x, "oil") for x in _jetted(d, jets)]
    for h in d.housings:
        out.append((h.id, "oil"))
        out += [(h.id, f) for f in h.faces] + ([(h.id, h.joined_to)] if h.joined_to else [])
    out += [(n, b.id) for b in d.boundaries if b.conductance_w_per_k is not None for n in b.touches]
    return tuple(dict.fromkeys(x for x in out if None not in x))


def _jetted(d: Description, jets: set) -> list:
    """The parts a forced oil system's streams join to the sump: segments of a shaft with a bore, bearings and
    planetary members in its jets."""
    out = [g.id for sh in d.shafts if sh.d_bore_m > 0 for g in sh.segments if g.id in jets]
    out += [b.id for b in d.bearings if b.id in jets]
    return out + [m for ps in d.planetary for m in (ps.sun, ps.planet, ps.ring) if m in jets]


def _part_of(d: Description, node: str) -> tuple:
    """(section, id) of the part a node belongs to: a segment's shaft, an idle wheel's teeth or bulk, a planetary
    member's set, or the part itself."""
    for sh in d.shafts:
        if node in {g.id for g in sh.segments}:
            return "shaft", sh.id
    for ps in d.planetary:
        if node in (ps.sun, ps.planet, ps.ring):
            return "planetary", ps.id
    base = node.rsplit(".", 1)[0] if node.endswith((".teeth", ".bulk")) else node
    kinds = [("wheel", d.wheels), ("bearing", d.bearings), ("housing", d.housings)]
    return next(((k, base) for k, parts in kinds if any(x.id == base for x in parts)), ("oil", None))


def _check_connected(r: _Reader, d: Description) -> None:
    """Every node reaches a boundary through the network's conductances (conduction_links): a shaft with no bearing,
    wheel or boundary passed, the sensor's step divided by zero and the node stayed at its start temperature."""
    near: dict = {}
    for a, b in conduction_links(d):
        near.setdefault(a, set()).add(b)
        near.setdefault(b, set()).add(a)
    reached, todo = set(), [b.id for b in d.boundaries]
    while todo:
        x = todo.pop()
        if x not in reached:
            reached.add(x)
            todo += near.get(x, ())
    cut = [n for n in d.nodes if n not in reached]
    if not cut:
        return
    group, todo = set(), [cut[0]]
    while todo:
        x = todo.pop()
        if x not in group:
            group.add(x)
            todo += near.get(x, ())
    parts = list(dict.fromkeys(_part_of(d, n) for n in d.nodes if n in group))
    (kind, pid), others = parts[0], parts[1:]
    key = f"{TOPOLOGY}.{kind}" + (f".{pid}" if pid else "")
    nodes = ", ".join(n for n in d.nodes if n in group)
    if not others:
        why = "is connected to nothing (no bearing, wheel, mesh, boundary or oil joins it to the rest)"
    else:
        names = " and ".join(", ".join(f"{k} {i}" for k, i in others).rsplit(", ", 1))
        why = f"and {names} are joined to one another but to no boundary"
    r.fail(
        key,
        f"{why}: no path of conductances leads from its nodes ({nodes}) to a boundary, so they would stay at their "
        "start temperature (and the sensor's step divide by zero); seat it in bearings, or take it out",
    )


def _drive(r: _Reader, topo: dict, shafts: dict) -> Drive:
    key = f"{TOPOLOGY}.drive"
    f = _single(r, topo, "drive")
    if f["kind"] not in DRIVES:
        r.fail(f"{key}.kind", f"= {f['kind']!r} must be one of {', '.join(DRIVES)}")
    for k in ("input_shaft", "output_shaft"):
        if f[k] not in shafts:
            r.fail(f"{key}.{k}", f"= {f[k]!r} is no shaft of the description; shafts: {', '.join(shafts)}")
    if f["input_shaft"] == f["output_shaft"]:
        r.fail(f"{key}.output_shaft", "is the input shaft: the power must go somewhere")
    min_t = 0.0 if f["min_torque"] is None else f["min_torque"]
    return Drive(f["kind"], f["input_shaft"], f["output_shaft"], f["max_speed"], f["max_torque"], min_t)


class _Walk:
    """Follows a gear's power path from the input shaft: the member carrying the power and its speed per unit
    input speed."""

    def __init__(self, r, key, wheels, planetary, meshes, couplings, start):
        self.r, self.key = r, key
        self.wheels, self.planetary = wheels, planetary
        self.meshes, self.couplings = meshes, couplings
        self.at, self.speed = start, 1.0
        self.loaded, self.engaged, self.held = [], [], []

    def fail(self, step: str, why: str):
        self.r.fail(self.key, f"does not close at step {step!r}: {why}")

    def carried(self, wheel: str) -> bool:
        """Whether the power, now on ``self.at``, reaches ``wheel``: it is the wheel, or fixed to that shaft."""
        g = _gear_of(self.wheels, self.planetary, wheel)
        return self.at == wheel or (g is not None and g[3] == self.at)

    def step(self, s: str) -> None:
        if s in self.couplings:
            joins = self.couplings[s].joins
            others = [j for j in joins if j != self.at]
            if self.at not in joins or len(others) != 1:
                self.fail(s, f"the power is on {self.at}, which the coupling {s} ({', '.join(joins)}) does not join")
            self.at = others[0]
            self.engaged.append(s)
        elif s in self.meshes:
            self.mesh(s, self.meshes[s])
        elif s.partition("/")[0] in {p.id for p in self.planetary}:
            self.planet_step(s)
        else:
            self.fail(s, "it is no mesh, coupling or planetary set/held member of the description")

    def mesh(self, s: str, m: Mesh) -> None:
        a, b = m.wheels
        if not self.carried(a) and not self.carried(b):
            self.fail(
                s,
                f"the power is on {self.at}, which drives neither {a} nor {b} (an idle wheel needs its coupling first)",
            )
        w_in, w_out = (a, b) if self.carried(a) else (b, a)
        z_in, _, _, _, _ = _gear_of(self.wheels, self.planetary, w_in)
        z_out, _, _, shaft_out, _ = _gear_of(self.wheels, self.planetary, w_out)
        self.speed *= (z_in / z_out) * (1.0 if m.internal else -1.0)
        self.loaded.append(s)
        self.at = shaft_out if shaft_out is not None else w_out

    def planet_step(self, s: str) -> None:
        pid, _, held = s.partition("/")
        ps = next(p for p in self.planetary if p.id == pid)
        if held not in HELD:
            self.fail(s, f"{held!r} must be one of {', '.join(HELD)}")
        where = {ps.sun_shaft: "sun", ps.sun: "sun", ps.carrier_shaft: "carrier", ps.ring: "ring"}
        if self.at not in where:
            self.fail(s, f"the power is on {self.at}, which is no member of planetary set {pid}")
        into = where[self.at]
        if into == held:
            self.fail(s, f"the power enters through the held member ({held})")
        out = next(m for m in ("carrier", "sun", "ring") if m not in (into, held))
        zs, zr = ps.z_sun, ps.z_ring
        # speeds of (sun, carrier, ring) with one member held (Willis: w_s - w_c = -(z_r/z_s)(w_r - w_c))
        rel = {
            "ring": {"sun": 1 + zr / zs, "carrier": 1.0, "ring": 0.0},
            "sun": {"sun": 0.0, "carrier": 1.0, "ring": 1 + zs / zr},
            "carrier": {"sun": -zr / zs, "carrier": 0.0, "ring": 1.0},
            "locked": {"sun": 1.0, "carrier": 1.0, "ring": 1.0},
        }[held]
        self.speed *= rel[out] / rel[into]
        self.at = {"sun": ps.sun_shaft, "carrier": ps.carrier_shaft, "ring": ps.ring}[out]
        self.held.append((pid, held))
        if held != "locked":  # the set's own meshes carry the power unless it turns as one body
            members = {ps.sun, ps.planet, ps.ring}
            self.loaded += [m.id for m in self.meshes.values() if set(m.wheels) <= members]


def _gears(r: _Reader, topo: dict, parts: dict, drive: Drive, check: dict) -> tuple:
    """Every gear's power path followed from the input shaft to the output shaft, its ratio against the stated one."""
    out, numbers = [], {}
    for name, key, f in _per_id(r, topo, "gear"):
        if f["number"] in numbers:
            r.fail(f"{key}.number", f"= {f['number']} is also gear {numbers[f['number']]}'s number")
        numbers[f["number"]] = name
        walk = _Walk(r, f"{key}.path", *parts, drive.input_shaft)
        for s in f["path"]:
            walk.step(s)
        neutral = f["number"] == 0
        if neutral:
            if walk.at == drive.output_shaft:
                r.fail(f"{key}.path", f"reaches the output shaft {drive.output_shaft}, but gear 0 is neutral")
            if f["ratio"] is not None:
                r.fail(f"{key}.ratio", "must be left out: neutral transmits no power")
            out.append(Gear(name, 0, f["path"], None, math.inf, (), tuple(walk.engaged), tuple(walk.held)))
            continue
        if walk.at != drive.output_shaft:
            r.fail(f"{key}.path", f"does not close: it ends on {walk.at}, not on the output shaft {drive.output_shaft}")
        ratio = 1.0 / walk.speed
        stated, tol = f["ratio"], check["ratio_rel_tol"]
        if stated is None:
            r.fail(key, "has no ratio: state the ratio input/output speed (it is checked against the teeth)")
        if stated == 0:  # checked relative to the stated ratio below: a division by zero without this
            r.fail(
                f"{key}.ratio",
                f"= 0 is no ratio of a gear that transmits power: state input/output speed, {ratio:.6g} by the "
                f"teeth along its path (neutral is gear number 0, without a ratio)",
            )
        if stated != 0 and ratio != 0 and (ratio > 0) != (stated > 0):
            r.fail(
                f"{key}.ratio",
                f"= {stated:g} has the wrong sign: the teeth along its path turn the output "
                f"{'the same way as' if ratio > 0 else 'against'} the input (ratio {ratio:.6g}; a reverse gear's "
                "ratio is negative, an idler in its path turns it back)",
            )
        if abs(ratio - stated) > tol * abs(stated):
            r.fail(
                f"{key}.ratio",
                f"= {stated:g} is off the ratio of the teeth along its path, {ratio:.6g} (by "
                f"{abs(ratio / stated - 1):.2%}; topology.check.ratio_rel_tol = {tol:g})",
            )
        out.append(
            Gear(name, f["number"], f["path"], stated, ratio, tuple(walk.loaded), tuple(walk.engaged), tuple(walk.held))
        )
    if drive.kind == "fixed_ratio" and sum(g.number != 0 for g in out) != 1:
        r.fail(f"{TOPOLOGY}.gear", "must hold exactly one gear (besides neutral) for a fixed-ratio drive")
    return tuple(out)


def limits_file(r: _Reader, name: str) -> Path:
    """The limits file ``name`` of a description: beside it, else a shipped one."""
    path = r.path.parent / name
    if not path.is_file():
        path = PARAM_DIR / name
    if not path.is_file():
        r.fail(f"{TOPOLOGY}.published.limits", f"= {name!r} is no file beside the description or shipped with it")
    return path


def _limits(r: _Reader, name: str, published: tuple) -> tuple:
    """The published components with their warning and critical limits [degC], read by the one loader every command
    uses (firmware_model.limits.load_limits: its sections, keys, units, warning below critical, the hysteresis): what
    replay and simulate refuse, describe refuses too, naming the description's key."""
    try:
        lim = load_limits(limits_file(r, name), published=published)
    except ParameterError as exc:
        r.fail(f"{TOPOLOGY}.published.limits", f"= {name!r} is refused: {exc}")
    return tuple(replace(c, warning_c=lim.of(c.id)[0], critical_c=lim.of(c.id)[1]) for c in published)


def _limits_name(r: _Reader, topo: dict) -> str:
    """The limits file the description's published.limits names (default limits.toml)."""
    table = topo.get("published") or {}
    return r.value(f"{TOPOLOGY}.published.limits", table["limits"], _T) if "limits" in table else "limits.toml"


def _published(r: _Reader, topo: dict, nodes: set) -> tuple:
    key = f"{TOPOLOGY}.published"
    table = topo.get("published") or {}
    if "order" not in table:
        r.fail(key, "has no order (the published components, in their CAN and column order)")
    order = r.value(f"{key}.order", table["order"], _L)
    limits_name = _limits_name(r, topo)
    group_of = {}
    for g, raw in table.items():
        if g in PUBLISHED_KEYS:
            continue
        if g not in LIMIT_GROUPS:
            r.fail(
                f"{key}.{g}",
                f"is no limit group of {limits_name}; known keys: {', '.join(PUBLISHED_KEYS + LIMIT_GROUPS)}",
            )
        for c in r.value(f"{key}.{g}", raw, _L):
            if c in group_of:
                r.fail(f"{key}.{g}", f"lists {c}, which is already in group {group_of[c]}")
            group_of[c] = g
    seen = set()
    for c in order:
        if c in seen:
            r.fail(f"{key}.order", f"lists {c} twice")
        seen.add(c)
        if c not in nodes:
            r.fail(f"{key}.order", f"lists {c}, which is no node of the description (no part has that id)")
        if c not in group_of:
            r.fail(f"{key}.order", f"lists {c}, which is in no limit group ({', '.join(LIMIT_GROUPS)})")
    for c, g in group_of.items():
        if c not in seen:
            r.fail(f"{key}.{g}", f"lists {c}, which is not published (not in order)")
    return _limits(r, limits_name, tuple(Published(c, group_of[c], None, None) for c in order))


def default_limits_note(d: Description) -> str | None:
    """A sentence when the description names no limits file (published.limits): its components take the default,
    limits.toml, which holds the GRS905 truck's limits (a user's reducer warned at the truck's 120 degC oil limit in
    silence). None when it names one (the shipped GRS905 and MM82 do)."""
    if d.limits_stated or d.limits_path is None or Path(d.limits_path) != PARAM_DIR / "limits.toml":
        return None  # (a limits.toml beside the description is its own)
    shown = {}
    for c in d.published:
        if c.warning_c is not None:
            shown.setdefault(c.group, c.warning_c)
    warnings = ", ".join(f"{g} {w:g} degC" for g, w in shown.items())
    return (
        f"{d.origin}: {TOPOLOGY}.published.limits is not given, so its components take {Path(d.limits_path).name}, "
        f"the GRS905 truck's warning limits ({warnings}), not this gearbox's: write its own limits file beside it "
        'and name it (published.limits = { v = "my_limits.toml", u = "-", src = "assumed" }; docs/description.md)'
    )


def limit_notes(d: Description) -> tuple:
    """Sentences on limits a part cannot stay below: a warning limit at or below every boundary's default
    temperature (without losses the parts settle between the boundaries' temperatures, so such a part warns, or is
    critical, from the start). Notes, not errors: a run table's ambient may be colder than the default."""
    if not d.boundaries:
        return ()
    cold = min(d.boundaries, key=lambda b: b.temperature_c)
    limits = Path(d.limits_path).name if d.limits_path else "the limits file"
    out = []
    for c in d.published:
        if c.warning_c is None or c.warning_c > cold.temperature_c:
            continue
        level = "critical" if c.critical_c is not None and c.critical_c <= cold.temperature_c else "at warning"
        out.append(
            f"{d.origin}: {c.id}'s warning limit {c.warning_c:g} degC ({limits}, group {c.group}) lies at or below "
            f"every boundary's temperature (the coldest, {cold.id}, is {cold.temperature_c:g} degC): {c.id} cannot "
            f"cool below it and is {level} from the start"
        )
    return tuple(out)


def _unique_ids(r: _Reader, named: list) -> None:
    """No id names two parts: (kind, id) of every shaft, segment, wheel, planetary member, bearing, housing."""
    seen: dict = {"oil": "the sump", OIL_INLET: "the oil inlet"}
    for kind, i in named:
        if i in seen:
            r.fail(f"{TOPOLOGY}.{kind}.{i}", f"reuses the id {i} of {seen[i]}: every part needs its own id")
        seen[i] = f"{kind} {i}"


def shipped_descriptions() -> tuple:
    """The names of the descriptions shipped in firmware_model/params/ (the parameter files with a topology)."""
    names = []
    for p in sorted(PARAM_DIR.glob("*.toml")):
        try:
            if _has_topology(p):
                names.append(p.stem)
        except ParameterError:
            continue
    return tuple(names)


_TOPOLOGY_HEADER = re.compile(rb"^[ \t]*\[[ \t]*topology[ \t]*[.\]]", re.MULTILINE)


def _has_topology(path: Path, depth: int = 0) -> bool:
    """Whether a shipped file has a [topology] of its own or through ``meta.inherit``: read without the key checks
    of `read_entries` (every command's --help names the descriptions; the checks run when one is loaded). A
    ``[topology...]`` table header answers without parsing the file."""
    if _TOPOLOGY_HEADER.search(path.read_bytes()):
        return True
    doc = read_toml(path, f"parameter file {path.name}")
    if TOPOLOGY in doc:
        return True
    meta = doc.get("meta")
    parent = meta.get("inherit") if isinstance(meta, dict) else None
    if not isinstance(parent, str) or depth > len(VARIANTS):
        return False
    return (PARAM_DIR / f"{parent}.toml").is_file() and _has_topology(PARAM_DIR / f"{parent}.toml", depth + 1)


def description_path(name_or_path: str | Path) -> Path:
    """The file of a description: NAME (shipped in firmware_model/params/) or the path of a .toml FILE."""
    p = Path(name_or_path)
    if p.suffix.lower() == ".toml":
        return p
    if (PARAM_DIR / f"{p.name}.toml").is_file() and str(name_or_path) == p.name and p.name != "limits":
        return PARAM_DIR / f"{p.name}.toml"
    raise ParameterError(
        f"unknown gearbox {str(name_or_path)!r}: use one of {', '.join(shipped_descriptions())} "
        f"or the path of a .toml description file"
    )


def load_description(name_or_path: str | Path = "GRS905") -> Description:
    """The checked description of a shipped gearbox (NAME) or of a user's file (FILE): one sentence naming the
    file, the key and why for anything that does not hold together."""
    path = description_path(name_or_path)
    return _describe(path, read_entries(path))


def description_of(p: Parameters) -> Description:
    """The description of the gearbox a parameter set describes, kept with the set: the ``[topology]`` of the file
    it came from (its variant's shipped file for a set made in code), every numeric ``{ from = "parameter" }`` entry
    taking the set's value (a set made with ``with_overrides`` or fitted by calibrate describes its own gearbox).
    A parameter file without a ``[topology]`` has the first shipped variant's, with its own values (as before
    descriptions)."""
    d = p.__dict__.get("_description")
    if d is None:
        path = description_path(p.path or p.variant)
        entries = _entries_of(path)
        if not any(is_topology(k) for k in entries):
            ref = _entries_of(PARAM_DIR / f"{VARIANTS[0]}.toml")
            entries = {**entries, **{k: e for k, e in ref.items() if is_topology(k)}}
        d = _describe(path, entries, p)
        p.__dict__["_description"] = d
    return d


#: the entries of the files parameter sets were described from, by (path, modification time, size): a set copied
#: with ``with_overrides`` (effects, calibrate) is described again without reading and parsing its file again
_ENTRIES: dict = {}
_ENTRIES_MAX = 16


def _entries_of(path: Path) -> dict:
    """The file's entries (as read_entries), read once per version of the file; never modified by the reader."""
    try:
        st = path.stat()
    except OSError:
        return read_entries(path)  # a missing file: its ParameterError
    key = (str(path.resolve()), st.st_mtime_ns, st.st_size)
    if key not in _ENTRIES:
        if len(_ENTRIES) >= _ENTRIES_MAX:
            _ENTRIES.clear()
        _ENTRIES[key] = read_entries(path)
    return dict(_ENTRIES[key])


def _describe(path: Path, entries: dict, params: Parameters | None = None) -> Description:
    """The checked description in a file's entries (the values of ``params`` for its parameters, when given)."""
    r = _Reader(path, entries, params)
    topo = _nest(entries)
    _sections(r, topo)
    check = {**DEFAULT_CHECK, **{k: v for k, v in _single(r, topo, "check").items() if v is not None}}
    shafts = _shafts(r, topo)
    by_shaft = {s.id: s for s in shafts}
    wheels = _wheels(r, topo, by_shaft)
    planetary = _planetary(r, topo, by_shaft)
    housing_ids = tuple((topo.get("housing") or {}).keys())
    named = [("shaft", s.id) for s in shafts] + [("shaft", g.id) for s in shafts for g in s.segments]
    named += [("wheel", w.id) for w in wheels]
    named += [("planetary", m) for ps in planetary for m in (ps.sun, ps.planet, ps.ring)]
    named += [("bearing", b) for b in topo.get("bearing") or {}] + [("housing", h) for h in housing_ids]
    _unique_ids(r, named)
    by_wheel = {w.id: w for w in wheels}
    meshes = _meshes(r, topo, by_wheel, planetary, check)
    members = {i for _, i in named}
    couplings = _couplings(r, topo, members)
    boundaries = _boundaries(r, topo)
    housings = _housings(r, topo, {b.id for b in boundaries})
    bearings = _bearings(r, topo, by_shaft, by_wheel, set(housing_ids))
    drive = _drive(r, topo, by_shaft)
    parts = (by_wheel, planetary, {m.id: m for m in meshes}, {c.id: c for c in couplings})
    gears = _gears(r, topo, parts, drive, check)
    desc = Description(
        str(entries.get("meta.variant", path.stem)),
        path.name,
        shafts,
        wheels,
        planetary,
        meshes,
        couplings,
        bearings,
        housings,
        None,
        gears,
        drive,
        boundaries,
        (),
        r.provenance,
    )
    nodes = set(desc.nodes)
    _check_touches(r, boundaries, nodes)
    _check_shaft_lengths(r, shafts, housings)
    oil = _oil(r, topo, by_shaft, nodes)
    _check_boundaries_used(r, boundaries, housings, oil)
    _check_oil_fits(r, oil, housings)
    _check_oil_covers_the_dipping(r, oil, wheels)
    _check_oil_controls(r, oil, drive)
    with_oil = replace(desc, oil=oil)
    _check_connected(r, with_oil)
    published = _published(r, topo, set(with_oil.nodes) | set(with_oil.derived))  # a forced system's oil inlet too
    return Description(
        desc.name,
        desc.origin,
        shafts,
        wheels,
        planetary,
        meshes,
        couplings,
        bearings,
        housings,
        oil,
        gears,
        drive,
        boundaries,
        published,
        r.provenance,
        frozenset(r.taken),
        str(limits_file(r, _limits_name(r, topo))),
        "limits" in (topo.get("published") or {}),
    )
