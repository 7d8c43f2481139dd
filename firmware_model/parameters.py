"""Load, convert to SI and validate a gearbox parameter file (one TOML file per variant).

Each entry in the file is `name = { v = value, u = "unit", src = "seed|derived|assumed", ref/note = ... }`.
The loader converts every value to SI (temperatures stay in degC), checks the unit is one the entry may have and the
value lies in its allowed range (ranges live here, in code, so a file cannot widen its own), and keeps the provenance
of every value. A variant file may `inherit` another and override entries.

A file may only hold keys its parent has (a file that inherits nothing: keys of the shipped variants), each in a unit
of the same dimension as there and a number where the parent has a number (text where it has text, cooler.kind): a
misspelt key or section, ``u = "-"`` for an angle or ``v = "4200"`` is a ParameterError naming the file and the key.
Values must be greater than zero unless their dimension takes any sign or the key may be zero or negative
(SIGN_FREE_DIMS, ZERO_ALLOWED, NOT_POSITIVE); range messages give the value and the range in the unit the file used.

The ``[topology]`` section (the gearbox description, firmware_model.description) is passed by: its keys are no
parameters, and firmware_model.description checks them against what a description may hold.

Renamed keys (RENAMED_KEYS) are migrated in the shipped files; a file that still uses an old name
(``oil_system.flow_per_ls_rpm``, ``engine.max_speed``, ``heat.N_nom``) loads with a FutureWarning naming the new key
(``oil_system.flow_m3_per_rad``, ``engine.max_speed_rad_s``, ``heat.omega_nom_rad_s``), its value converted by its unit
as before; so does ``Parameters.with_overrides`` with an old name.

    >>> p = load_parameters("GRS905")
    >>> round(p["gear.3.width1"], 3)          # SI: metres
    0.04
    >>> p.provenance("heat.h_nom")
    'seed'
"""

from __future__ import annotations

import difflib
import fnmatch
import functools
import math
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

from firmware_model.errors import InputError, ParameterError
from firmware_model.physics.kinematics import KinematicTable, Teeth, build_table
from firmware_model.physics.oil import GRADE_KEYS, oil_of
from firmware_model.units import L_PER_M3, RAD_S_PER_RPM, S_PER_MIN

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

PARAM_DIR = Path(__file__).resolve().parent / "params"
VARIANTS = ("GRS905", "GRSO905")
#: the shipped gearboxes with a description of their own (a NAME.toml in firmware_model/params/, standalone files): they
#: load by name like the variants but are no reference for the keys of other files
STANDALONE = ("R1", "HR225", "MM82")
#: where a value comes from: "fitted" is what `calibrate` writes (OUT.toml); "calibrated" a value fitted to measured
#: data of the real machine and shipped in its description (the data, the held-out figure: in its note)
PROVENANCES = ("seed", "derived", "assumed", "fitted", "calibrated")
#: the fields an entry may have: its value, unit and provenance, where the seed states it, why (an assumed value),
#: calibration bounds, or a parameter it takes its value from (a topology entry); a misspelt field (nte) would be
#: silently ignored
ENTRY_FIELDS = ("v", "u", "src", "ref", "note", "lo", "hi", "from")
#: a field written out in full, for the hint
_FIELDS_IN_FULL = {"value": "v", "unit": "u", "source": "src", "provenance": "src"}

#: unit string in a file -> (SI dimension, factor to SI)
UNITS = {
    "-": ("1", 1.0),
    "m": ("m", 1.0),
    "mm": ("m", 1e-3),
    "m2": ("m2", 1.0),
    "L": ("m3", 1.0 / L_PER_M3),
    "m3": ("m3", 1.0),
    "deg": ("rad", math.pi / 180.0),
    "rad": ("rad", 1.0),
    "kg": ("kg", 1.0),
    "kg/m3": ("kg/m3", 1.0),
    "W/(m K)": ("W/(m K)", 1.0),
    "J/(kg K)": ("J/(kg K)", 1.0),
    "W/(m2 K)": ("W/(m2 K)", 1.0),
    "W/K": ("W/K", 1.0),
    "W": ("W", 1.0),
    "kW": ("W", 1e3),
    "Pa": ("Pa", 1.0),
    "N": ("N", 1.0),
    "Nm": ("N m", 1.0),
    "N m": ("N m", 1.0),  # as the SCADA column maps write it
    "s": ("s", 1.0),
    "degC": ("degC", 1.0),
    "rpm": ("rad/s", RAD_S_PER_RPM),
    "rad/s": ("rad/s", 1.0),
    "Nm/rpm": ("N m s/rad", 1.0 / RAD_S_PER_RPM),  # torque per speed
    "L/min/rpm": ("m3/rad", 1.0 / L_PER_M3 / S_PER_MIN / RAD_S_PER_RPM),  # volume flow per speed
    "m3/rad": ("m3/rad", 1.0),
    "mm2/s": ("m2/s", 1e-6),  # a kinematic viscosity (cSt)
    "cSt": ("m2/s", 1e-6),
    "m2/s": ("m2/s", 1.0),
    "1/GPa": ("1/Pa", 1e-9),  # a piezo-viscosity coefficient
    "1/Pa": ("1/Pa", 1.0),
}
#: what a quantity of each SI dimension is, for messages
DIM_NAMES = {
    "1": "a plain number",
    "m": "a length",
    "m2": "an area",
    "m3": "a volume",
    "rad": "an angle",
    "kg": "a mass",
    "kg/m3": "a density",
    "W/(m K)": "a thermal conductivity",
    "J/(kg K)": "a specific heat capacity",
    "W/(m2 K)": "a heat transfer coefficient",
    "W/K": "a thermal conductance",
    "W": "a power",
    "Pa": "a pressure or elastic modulus",
    "N": "a force",
    "N m": "a torque",
    "s": "a time",
    "m2/s": "a kinematic viscosity",
    "1/Pa": "a piezo-viscosity coefficient",
    "degC": "a temperature",
    "rad/s": "a speed",
    "N m s/rad": "a torque per speed",
    "m3/rad": "a volume flow per speed",
}
#: renamed keys (old -> new): a file that still uses an old key is read with a deprecation warning
RENAMED_KEYS = {
    "oil_system.flow_per_ls_rpm": "oil_system.flow_m3_per_rad",
    "engine.max_speed": "engine.max_speed_rad_s",
    "heat.N_nom": "heat.omega_nom_rad_s",
}

#: allowed SI range per dimension (inclusive); specific keys are narrowed below
DIM_RANGE = {
    "1": (0.0, 1e6),
    "m": (0.0, 3.0),
    "m2": (0.0, 50.0),
    "m3": (0.0, 0.1),
    "rad": (0.0, math.radians(45)),
    "kg": (0.0, 1000.0),
    "kg/m3": (500.0, 20000.0),
    "W/(m K)": (0.01, 500.0),
    "J/(kg K)": (100.0, 5000.0),
    "W/(m2 K)": (0.0, 1e7),
    "W/K": (0.0, 1e5),
    "W": (0.0, 1e6),
    "Pa": (1e6, 1e13),
    "N": (0.0, 1e7),
    "N m": (-1e5, 1e5),
    "s": (0.0, 1e5),
    "degC": (-60.0, 250.0),
    "rad/s": (0.0, 1000.0),
    "N m s/rad": (0.0, 1.0),
    "m3/rad": (0.0, 1e-4),
}
#: (glob pattern, low, high, integer?) checked after the dimension range, first match wins
KEY_RULES = [
    ("gear.*.z*", 8, 200, True),
    ("planetary.z_*", 8, 250, True),
    ("planetary.n_planets", 2, 8, True),
    ("*.n_rollers*", 4, 100, True),
    ("sync.n_ring_*", 0, 6, True),
    ("meta.split_inverted", 0, 1, True),
    ("wheel.covered_sides", 0, 1, True),
    ("*frac*", 0.0, 1.0, False),
    ("housing.internal_split_*", 0.0, 1.0, False),
    ("*.immersion", 0.0, 1.0, False),
    ("housing.emissivity", 0.0, 1.0, False),
    ("material.*.poisson", 0.0, 0.5, False),
    ("scale.*_to_heat", 0.1, 3.0, False),
    ("bearing.sf_*", 0.0, 1.0, False),
    ("*.sf_*", 0.0, 1.0, False),
    ("oil.volume", 4e-3, 20e-3, False),
    ("heat.h_nom", 10.0, 5000.0, False),
    ("heat.TCC", 1e3, 1e6, False),
    ("heat.splash_exponent", 0.0, 2.0, False),
    ("planetary.h_oil", 10.0, 1e4, False),
    ("housing.h_oil", 10.0, 5000.0, False),
    ("housing.h_air", 1.0, 200.0, False),
    ("gear.alpha_n", math.radians(14), math.radians(30), False),
    ("bearing.f0_*", 0.5, 10.0, False),
    ("wheel_bearing.f0_*", 0.5, 10.0, False),
    ("bearing.f1_*", 0.0, 0.01, False),
    ("bearing.R1_*", 0.0, 1e-5, False),
    ("wheel.hub_mass_factor", 1.0, 3.0, False),
    ("engine.max_speed_rad_s", 100.0, 1000.0, False),
]
#: sign rule: a value of any dimension but these must be greater than zero (plain numbers and angles are kept
#: non-negative by DIM_RANGE and KEY_RULES, temperatures in degC take either sign)
SIGN_FREE_DIMS = ("1", "rad", "degC")
#: ... except these keys, which may also be zero: positions, bores (0: a solid shaft), overhangs, the bearing preload,
#: the oil surface at the layshaft axis, an idler not dipping, the heat lag (0: no lag)
ZERO_ALLOWED = (
    "*.x",
    "*.x_*",
    "*.d_bore",
    "*.overhang_*",
    "bearing.P0",
    "oil.level_below_ls_axis",
    "gear.R.idler_immersion",
    "scale.heat_lag_tau",
)
#: ... and these, which must be zero or negative (the engine's braking torque)
NOT_POSITIVE = ("engine.min_torque",)


@dataclass
class Parameters:
    """A validated parameter set: SI values and provenance by dotted key, plus the kinematics."""

    variant: str
    values: dict
    sources: dict
    units: dict
    strings: dict = field(default_factory=dict)
    origin: str = ""
    #: plausible (low, high) bounds in SI of the keys whose entry declares ``lo`` and ``hi`` (what calibrate may fit)
    bounds: dict = field(default_factory=dict)
    #: the file it was loaded from (its description: firmware_model.description.description_of); "" for a set
    #: made in code (its variant's shipped file then)
    path: str = ""

    def __getitem__(self, key: str) -> float:
        try:
            return self.values[key]
        except KeyError:
            raise ParameterError(f"parameter {key!r} is missing from parameter set {self.variant}") from None

    def get(self, key, default=None):
        return self.values.get(key, default)

    def provenance(self, key: str) -> str:
        return self.sources[key]

    def string(self, key: str) -> str:
        return self.strings[key]

    @property
    def split_inverted(self) -> bool:
        """Whether the GRS905's split is inverted (meta.split_inverted); a gearbox without that key has no split."""
        return bool(self.values.get("meta.split_inverted", 0.0))

    @property
    def teeth(self) -> Teeth:
        z = self.values
        idle = {
            "LI": int(z["gear.L.z1"]),
            "3M": int(z["gear.3.z1"]),
            "2M": int(z["gear.2.z1"]),
            "1M": int(z["gear.1.z1"]),
            "CM": int(z["gear.C.z1"]),
            "RM": int(z["gear.R.z1"]),
        }
        lay = {
            "LL": int(z["gear.L.z2"]),
            "3L": int(z["gear.3.z2"]),
            "2L": int(z["gear.2.z2"]),
            "1L": int(z["gear.1.z2"]),
            "CL": int(z["gear.C.z2"]),
            "RL": int(z["gear.R.z2"]),
        }
        return Teeth(
            idle,
            lay,
            int(z["gear.R.z_idler"]),
            int(z["planetary.z_sun"]),
            int(z["planetary.z_planet"]),
            int(z["planetary.z_ring"]),
            int(z["planetary.n_planets"]),
        )

    @property
    def kinematics(self) -> KinematicTable:
        """The range-splitter's Table 1 kinematics in closed form from the tooth parameters (the check of the
        description's solve; the plant and the onboard model take the gearbox's own description's:
        firmware_model.physics.drivetrain.kinematics_of)."""
        kin = self.__dict__.get("_kin")
        if kin is None:
            kin = build_table(self.teeth, self.split_inverted)
            self.__dict__["_kin"] = kin
        return kin

    def with_overrides(self, overrides: dict) -> Parameters:
        """A copy with SI values replaced (keys must exist); used by effects and parameter studies."""
        vals = dict(self.values)
        for k, v in overrides.items():
            if k in RENAMED_KEYS:
                warnings.warn(f"parameter {k} is deprecated, use {RENAMED_KEYS[k]}", FutureWarning, stacklevel=2)
                k = RENAMED_KEYS[k]
            if k not in vals:
                raise ParameterError(f"cannot override unknown parameter {k!r}")
            vals[k] = float(v)
        new = replace(
            self,
            values=vals,
            sources=dict(self.sources),
            units=dict(self.units),
            strings=dict(self.strings),
            bounds=dict(self.bounds),
        )
        _check_values(new)
        _keep_description(self, new, overrides)
        return new

    def with_cooler_kind(self, kind: str) -> Parameters:
        """A copy whose cooler is of another kind (``cooler.kind``: "none" runs the gearbox without its cooler)."""
        strings = dict(self.strings)
        strings["cooler.kind"] = kind
        return replace(
            self,
            values=dict(self.values),
            sources=dict(self.sources),
            units=dict(self.units),
            strings=strings,
            bounds=dict(self.bounds),
        )

    def table(self):
        """Rows (key, SI value, SI unit, provenance) for documentation."""
        return [(k, self.values[k], self.units[k], self.sources[k]) for k in sorted(self.values)]


#: the section of a parameter file that holds the gearbox's topology (firmware_model.description reads and checks it;
#: the parameter loader passes it by)
TOPOLOGY = "topology"


def is_topology(key: str) -> bool:
    """Whether a dotted key belongs to the topology section (read by firmware_model.description, not here)."""
    return key.startswith(TOPOLOGY + ".")


#: pairs of keys whose values keep an order, the first below the second by at least the gap (the description's
#: check: the thermostat is fully open above where it starts to open), which calibrate's box bounds cannot say
ORDERED_KEYS = (("cooler.thermostat_open", "cooler.thermostat_full", 0.1),)


def with_fit_bounds(p: Parameters, keys) -> Parameters:
    """A copy whose bounds of the ``keys`` to fit keep ORDERED_KEYS' order for every value within them: a key fitted
    without its partner stays on its side of the partner's value; two fitted together split the range their bounds
    share at its middle (moved, if need be, to lie between their values). The values are unchanged."""
    keys, bounds = set(keys), dict(p.bounds)
    for a, b, gap in ORDERED_KEYS:
        fit_a, fit_b = a in keys and a in bounds, b in keys and b in bounds
        if fit_a and fit_b:
            lo, hi = max(bounds[a][0], bounds[b][0]), min(bounds[a][1], bounds[b][1])
            if lo < hi:
                m = min(max(0.5 * (lo + hi), p[a] + 0.5 * gap), p[b] - 0.5 * gap)
                bounds[a] = (bounds[a][0], min(bounds[a][1], m - 0.5 * gap))
                bounds[b] = (max(bounds[b][0], m + 0.5 * gap), bounds[b][1])
        elif fit_a and b in p.values:
            bounds[a] = (bounds[a][0], min(bounds[a][1], p[b] - gap))
        elif fit_b and a in p.values:
            bounds[b] = (max(bounds[b][0], p[a] + gap), bounds[b][1])
    return replace(p, bounds=bounds)


def _keep_description(parent: Parameters, new: Parameters, overrides: dict) -> None:
    """A copy that overrides no parameter its gearbox description takes (``{ from }``) describes the same gearbox:
    it keeps its parent's description (firmware_model.description.description_of) instead of deriving it again."""
    d = parent.__dict__.get("_description")
    if d is None:
        return
    keys = {RENAMED_KEYS.get(k, k) for k in overrides}
    if keys.isdisjoint(d.taken):
        new.__dict__["_description"] = d


def _flatten(d: dict, prefix: str = ""):
    """(dotted key, entry) of every entry: a table with a value ``v``, or a topology entry ``{ from = "key" }``
    that takes a parameter's value."""
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and "v" not in v and "from" not in v:
            yield from _flatten(v, key + ".")
        else:
            yield key, v


#: parsed documents by their bytes: a command reads the shipped files many times (the key checks, inheritance),
#: and parsing each once shortens every start-up. Keyed by content, not by path and time stamp, so a file rewritten
#: within a time stamp's resolution is read afresh.
_PARSED: dict[bytes, dict] = {}
_PARSED_MAX = 64


def _copy_document(x):
    """A deep copy of a parsed TOML document (dicts, lists and immutable scalars): callers may change what they get."""
    if isinstance(x, dict):
        return {k: _copy_document(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_copy_document(v) for v in x]
    return x


def read_toml(path: str | Path, label: str, label_invalid: str | None = None) -> dict:
    """The TOML document at ``path``; a missing file or invalid TOML is a ParameterError that starts with ``label``
    (e.g. "parameter file GRS905.toml"; ``label_invalid`` for the second case if it differs)."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read()
        doc = _PARSED.get(raw)
        if doc is None:
            # a byte-order mark (Windows editors write one) is not TOML, but it is no reason to refuse the file
            doc = tomllib.loads(raw.removeprefix(b"\xef\xbb\xbf").decode("utf-8"))
            if len(_PARSED) >= _PARSED_MAX:
                _PARSED.clear()
            _PARSED[raw] = doc
        return _copy_document(doc)
    except FileNotFoundError:
        raise ParameterError(f"{label} does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"{label_invalid or label} is not valid TOML: {exc}") from None
    except UnicodeDecodeError:
        raise ParameterError(f"{label_invalid or label} is not valid TOML: not UTF-8 text") from None
    except IsADirectoryError:
        raise ParameterError(f"{label} is a directory, not a file") from None


def _renamed(entries: dict, path: Path) -> dict:
    """Entries with old key names (RENAMED_KEYS) moved to their new names, each with a deprecation warning."""
    out = {}
    for key, e in entries.items():
        new = RENAMED_KEYS.get(key)
        if new is not None:
            warnings.warn(
                f"{path.name}: parameter {key} is deprecated, use {new} (it is read as {new})",
                FutureWarning,
                stacklevel=4,
            )
            if new in entries:
                raise ParameterError(f"{path.name}: {key} and {new} are the same parameter; keep only {new}")
            key = new
        out[key] = e
    return out


def _read(path: Path, seen=()) -> dict:
    """The entries of a parameter file with its parent's (``meta.inherit``) underneath. The file's own keys are
    checked against its parent's, or, for a file that inherits nothing, against the shipped variants'
    (`_check_keys`)."""
    doc = read_toml(path, f"parameter file {path.name}")
    entries = _renamed(dict(_flatten(doc)), path)
    for key, e in entries.items():
        _check_entry_fields(path, key, e)
    meta = doc.get("meta")
    parent = meta.get("inherit") if isinstance(meta, dict) else None
    if parent:
        if parent in seen:
            raise ParameterError(f"parameter file {path.name} inherits in a cycle through {parent}")
        base = _read(PARAM_DIR / f"{parent}.toml", seen + (parent,))
        _check_keys(path, entries, base, f"{parent}.toml")
        base.update({k: v for k, v in entries.items() if k != "meta.inherit"})
        return base
    if not _is_shipped(path):
        if any(is_topology(k) for k in entries):
            _check_own_keys(path, entries)
        else:
            _check_keys(path, entries, _reference_entries(), f"the shipped parameter files ({', '.join(VARIANTS)})")
    return entries


#: the physics parameters a file with its own [topology] may hold whatever its gearbox (the rest of its geometry is
#: in its [topology]); these sections' keys of the shipped files, but those the GRS905's description takes
GENERIC_SECTIONS = (
    "meta",
    "material",
    "oil",
    "gear",
    "wheel",
    "bearing",
    "wheel_bearing",
    "sync",
    "pump",
    "planetary",
    "housing",
    "heat",
    "scale",
    "oil_system",
    "cooler",
    "boundary",
    "engine",
)
#: sections whose keys stay parameters even where the GRS905's description takes them (defaults, the cooler, limits)
ALWAYS_GENERIC = ("boundary", "cooler", "engine")
#: parameters of a kind a gearbox may have the GRS905 lacks: (pattern, the shipped key whose unit it takes)
PER_KIND = (
    ("material.*.rho", "material.steel.rho"),
    ("material.*.k", "material.steel.k"),
    ("material.*.cp", "material.steel.cp"),
    ("bearing.sf_radial_*", "bearing.sf_radial_tapered"),
    ("bearing.f0_*", "bearing.f0_tapered"),  # Palmgren's coefficients and Eq 40's load factors of a bearing kind
    ("bearing.f1_*", "bearing.f1_tapered"),
    ("bearing.e_*", "bearing.e_tapered"),
    ("bearing.X1_*", "bearing.X1_tapered"),
    ("bearing.Y1_*", "bearing.Y1_tapered"),
    ("bearing.X2_*", "bearing.X2_tapered"),
    ("bearing.Y2_*", "bearing.Y2_tapered"),
    ("wheel_bearing.sf_radial_*", "wheel_bearing.sf_radial_needle"),
)
#: optional parameters of a kind, which any file may add, its base having them or not: (pattern, the shipped key whose
#: unit it takes). SKF's rolling term of a bearing kind (physics.losses.skf_rolling_coef): none where absent
OPTIONAL_PER_KIND = (("bearing.R1_*", "bearing.f2"),)
#: optional parameters no shipped reference file has, with the unit their dimension is checked against: an oil's
#: grade (physics.oil.oil_of; absent: the seed's oil)
OPTIONAL_KEYS = dict(zip(GRADE_KEYS, ("mm2/s", "mm2/s", "kg/m3", "1/GPa")))
#: what a file with its own [topology] must hold: the physics every network needs (the per-kind ones its
#: description implies are named by the network when missing)
REQUIRED_GENERIC = (
    "material.steel.rho",
    "material.steel.k",
    "material.steel.cp",
    "oil.capacity_temp",
    "gear.alpha_n",
    "gear.teeth_shell_modules",
    "wheel.hub_mass_factor",
    "wheel_bearing.cage_depth_frac",
    "housing.k_joint",
    "housing.h_oil",
    "housing.h_air",
    "housing.emissivity",
    "housing.external_frac",
    "housing.oil_covered_frac",
    "heat.h_nom",
    "heat.omega_nom_rad_s",
    "heat.splash_exponent",
    "heat.TCC",
    "heat.w_Hz",
    "heat.contact_length_frac",
    "heat.sf_teeth_bulk",
    "heat.sf_layshaft_wheel",
    "heat.cut_wheel_inner_frac",
    "heat.shaft_inner_diameter_frac",
    "heat.seat_outer_diameter_factor",
    "scale.gear_contact_to_heat",
    "scale.planet_to_heat",
    "scale.churn_to_heat",
    "scale.heat_lag_tau",
    "boundary.initial",
)
#: ... and with a planetary set in its description
REQUIRED_PLANETARY = (
    "planetary.planet_bore_frac",
    "planetary.sf_planet_carrier",
    "planetary.sf_sun_spline",
    "planetary.h_oil",
)


def _check_entry_fields(path: Path, key: str, e) -> None:
    """Every field of an entry is one of ENTRY_FIELDS, with the closest one named for a typo."""
    if not isinstance(e, dict):
        return
    for name in e:
        if name not in ENTRY_FIELDS:
            close = difflib.get_close_matches(name, ENTRY_FIELDS, n=1)
            close = [_FIELDS_IN_FULL[name]] if name in _FIELDS_IN_FULL else close
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise ParameterError(
                f"{path.name}: {key} has an unknown field {name}{hint}; an entry's fields: {', '.join(ENTRY_FIELDS)}"
            )


def _generic_entries() -> dict:
    """The shipped keys a file with its own [topology] may hold (GENERIC_SECTIONS, ALWAYS_GENERIC)."""
    ref = _reference_entries()
    taken = {e["from"] for k, e in ref.items() if is_topology(k) and isinstance(e, dict) and "from" in e}
    return {
        k: e
        for k, e in ref.items()
        if k.split(".")[0] in GENERIC_SECTIONS and (k not in taken or k.split(".")[0] in ALWAYS_GENERIC)
    }


def _check_own_keys(path: Path, entries: dict) -> None:
    """A file with its own [topology] holds the generic physics parameters (`_generic_entries`), parameters of a
    kind the shipped files lack (PER_KIND, in the unit of their pattern's shipped key) and its own parameters that
    its [topology] takes (``{ from = ... }``; their units are checked by the description keys that take them), and
    the OPTIONAL_KEYS (an oil's grade)."""
    base = _generic_entries()
    own = {e["from"] for k, e in entries.items() if is_topology(k) and isinstance(e, dict) and "from" in e}
    reference = None  # the shipped files' entries, read once (not once per key)
    for key, e in entries.items():
        if key == "meta.inherit" or is_topology(key) or (key.startswith("meta.") and isinstance(e, str)):
            continue
        if key in base or key in OPTIONAL_KEYS:
            _check_entry_kind(path, key, e, base.get(key) or {"v": 0.0, "u": OPTIONAL_KEYS[key]})
            continue
        kind = next((ref for pat, ref in PER_KIND + OPTIONAL_PER_KIND if fnmatch.fnmatchcase(key, pat)), None)
        if kind is not None:
            reference = _reference_entries() if reference is None else reference
            _check_entry_kind(path, key, e, reference[kind])
        elif key not in own:
            known = {**base, **dict.fromkeys(own)}
            raise ParameterError(_unknown_key(path, key, known, "a file with its own [topology]"))


def _is_shipped(path: Path) -> bool:
    """Whether ``path`` is one of the shipped variant files (the reference the other files are checked against)."""
    return path.resolve() in {(PARAM_DIR / f"{v}.toml").resolve() for v in VARIANTS}


def _reference_entries() -> dict:
    """The entries of the shipped variants by key (the union; the first variant's entry where they share a key):
    what a parameter file that inherits nothing may contain. Read-only for callers: built once per state of the
    shipped files (a command checks several files against it)."""
    stamps = []
    for v in VARIANTS:
        try:
            st = (PARAM_DIR / f"{v}.toml").stat()
            stamps.append((st.st_mtime_ns, st.st_size))
        except OSError:
            stamps.append(None)
    return _reference_entries_of(tuple(stamps))


@functools.lru_cache(maxsize=2)
def _reference_entries_of(stamps: tuple) -> dict:
    """`_reference_entries` for the shipped files' (time stamp, size) ``stamps``."""
    ref = {}
    for v in VARIANTS:
        for key, e in _read(PARAM_DIR / f"{v}.toml").items():
            ref.setdefault(key, e)
    return ref


def _check_keys(path: Path, entries: dict, base: dict, base_name: str) -> None:
    """ParameterError for a key of ``entries`` that ``base`` does not have (a typo would be silently ignored), a
    number written as text (or text as a number) and a unit of another dimension than the base entry's."""
    for key, e in entries.items():
        if key == "meta.inherit" or (key.startswith("meta.") and isinstance(e, str)):
            continue  # a file's own description (meta.description ...): text, no physics
        if is_topology(key):
            continue  # checked by firmware_model.description against what a topology may hold
        if key not in base:
            if key in OPTIONAL_KEYS:
                _check_entry_kind(path, key, e, {"v": 0.0, "u": OPTIONAL_KEYS[key]})
                continue
            optional = next((ref for pat, ref in OPTIONAL_PER_KIND if fnmatch.fnmatchcase(key, pat)), None)
            if optional is None:
                raise ParameterError(_unknown_key(path, key, base, base_name))
            _check_entry_kind(path, key, e, _reference_entries()[optional])
            continue
        _check_entry_kind(path, key, e, base[key])


def _unknown_key(path: Path, key: str, base: dict, base_name: str) -> str:
    """The message for a key that the base file does not have, with the closest known key."""
    table = next((k for k in base if key.startswith(k + ".")), None)
    if table is not None:
        return f"{path.name}: entry {table!r} must be a table {{ v = ..., u = ..., src = ... }} with a value v"
    section, _, name = key.rpartition(".")
    siblings = [k.rpartition(".")[2] for k in base if k.rpartition(".")[0] == section]
    has = "have" if base_name.startswith("the ") else "has"
    if siblings:  # a known section: the closest key name in it
        close = [f"{section}.{k}" for k in difflib.get_close_matches(name, siblings, n=1)]
        what = "no such key"
    else:  # an unknown section: the closest dotted key anywhere
        close = difflib.get_close_matches(key, list(base), n=1)
        what = f"no section [{section}]" if section else "no such key"
    hint = f"; did you mean {close[0]}?" if close else ""
    return f"{path.name}: unknown parameter {key}: {base_name} {has} {what}{hint}"


def _check_entry_kind(path: Path, key: str, e, ref) -> None:
    """An entry must hold text where the base entry does (cooler.kind) and a number elsewhere, in a unit of the
    base entry's dimension (mm for m is fine, "-" for an angle is not)."""
    if not (isinstance(e, dict) and "v" in e and isinstance(ref, dict) and "v" in ref):
        return
    text, ref_text = isinstance(e["v"], str), isinstance(ref["v"], str)
    if text and not ref_text:
        raise ParameterError(f'{path.name}: {key} = "{e["v"]}" is text, not a number: write the value without quotes')
    if ref_text:
        if not text:
            raise ParameterError(f'{path.name}: {key} = {e["v"]!r} must be text in quotes, such as "{ref["v"]}"')
        return
    u, ref_u = e.get("u"), ref.get("u")
    if u not in UNITS or ref_u not in UNITS or UNITS[u][0] == UNITS[ref_u][0]:
        return  # an unknown unit is reported by load_parameters
    dim, ref_dim = UNITS[u][0], UNITS[ref_u][0]
    allowed = " or ".join(f'u = "{x}"' for x, (d, _) in UNITS.items() if d == ref_dim)
    raise ParameterError(
        f"{path.name}: {key} has unit {u!r} ({DIM_NAMES.get(dim, dim)}) but the key is "
        f"{DIM_NAMES.get(ref_dim, ref_dim)}: write it with {allowed}"
    )


def parameter_path(variant_or_path: str | Path) -> Path:
    """The TOML file of a variant name (GRS905, GRSO905) or a path."""
    p = Path(variant_or_path)
    if p.suffix.lower() == ".toml":
        return p
    if str(variant_or_path) in VARIANTS + STANDALONE:
        return PARAM_DIR / f"{variant_or_path}.toml"
    raise ParameterError(
        f"unknown gearbox variant {variant_or_path!r}: use one of {', '.join(VARIANTS + STANDALONE)} "
        f"or the path of a .toml parameter file"
    )


def read_entries(variant_or_path: str | Path) -> dict:
    """The raw entries of a parameter file by dotted key (inheritance resolved): {v, u, src, ...} tables, as written."""
    return _read(parameter_path(variant_or_path))


def _bounds(path: Path, key: str, e: dict, fac: float, v: float):
    """(lo, hi) in SI of an entry that declares them (both or neither), with lo <= v <= hi."""
    if "lo" not in e and "hi" not in e:
        return None
    try:
        lo, hi = float(e["lo"]) * fac, float(e["hi"]) * fac
    except KeyError:
        raise ParameterError(f"{path.name}: {key} declares only one of lo and hi; give both or neither") from None
    except (TypeError, ValueError):
        raise ParameterError(
            f"{path.name}: {key} has bounds lo = {e.get('lo')!r}, hi = {e.get('hi')!r}, which are not numbers"
        ) from None
    if not lo < hi:
        raise ParameterError(
            f"{path.name}: {key} has bounds lo = {e['lo']} .. hi = {e['hi']}: lo must be below hi "
            f"(reversed or equal bounds)"
        )
    if not lo <= v <= hi:
        raise ParameterError(
            f"{path.name}: {key} = {e['v']} must lie within its bounds lo = {e['lo']} .. hi = {e['hi']}"
        )
    return lo, hi


def load_parameters(variant_or_path: str | Path = "GRS905") -> Parameters:
    """Load a shipped gearbox by name (GRS905, GRSO905, R1, HR225, MM82) or a TOML file by path."""
    path = parameter_path(variant_or_path)
    entries = _read(path)
    values, sources, units, strings, bounds = {}, {}, {}, {}, {}
    written = {}  # key -> (unit, factor to SI) as in the file, for messages
    for key, e in entries.items():
        if is_topology(key):
            continue  # the gearbox description (firmware_model.description), no parameter
        if key in ("meta.variant", "meta.inherit") or (key.startswith("meta.") and isinstance(e, str)):
            strings[key] = str(e)  # a description of the file (meta.description ...): text, no physics
            continue
        if not isinstance(e, dict) or "v" not in e:
            raise ParameterError(f"{path.name}: entry {key!r} must be a table {{ v = ..., u = ..., src = ... }}")
        u = e.get("u")
        src = e.get("src")
        if src not in PROVENANCES:
            raise ParameterError(f"{path.name}: {key} has provenance {src!r}; it must be one of {PROVENANCES}")
        if isinstance(e["v"], str):
            strings[key] = e["v"]
            sources[key] = src
            continue
        if u not in UNITS:
            raise ParameterError(f"{path.name}: {key} has unit {u!r}, {_unit_hint(key)}")
        if isinstance(e["v"], bool):  # TOML's true / false: float() would read them as 1 and 0
            raise ParameterError(f"{path.name}: {key} = {str(e['v']).lower()} is true or false, not a number")
        dim, fac = UNITS[u]
        try:
            v = float(e["v"]) * fac
        except (TypeError, ValueError):
            raise ParameterError(f"{path.name}: {key} = {e['v']!r} is not a number") from None
        values[key] = v
        sources[key] = src
        units[key] = dim
        written[key] = (u, fac)
        b = _bounds(path, key, e, fac, v)
        if b is not None:
            bounds[key] = b
    params = Parameters(
        strings.get("meta.variant", path.stem), values, sources, units, strings, path.name, bounds, str(path.resolve())
    )
    _check_values(params, written)
    if _standalone(path, entries):
        _check_required_generic(params, entries)
    else:
        _check_required(params)
    kind = params.strings.get("cooler.kind", "liquid")
    if kind not in COOLER_KINDS:
        raise ParameterError(f"cooler.kind = {kind!r} must be one of {', '.join(COOLER_KINDS)}")
    try:
        oil_of(params)  # the [oil]'s grade, where it gives one: both viscosities, values an oil can have
    except InputError as exc:
        raise ParameterError(f"{path.name}: {exc}") from None
    return params


COOLER_KINDS = ("none", "liquid", "air", "hold", "measured")

REQUIRED = [
    "gear.center_distance",
    "gear.alpha_n",
    "oil.volume",
    "heat.h_nom",
    "heat.TCC",
    "planetary.z_sun",
    "scale.gear_contact_to_heat",
    "scale.planet_to_heat",
    "scale.churn_to_heat",
    "housing.h_oil",
    "cooler.liquid_hA_ref",
    "boundary.ambient",
    "engine.max_torque",
    "engine.max_speed_rad_s",
] + [f"gear.{p}.{k}" for p in ("L", "3", "2", "1", "C", "R") for k in ("z1", "z2", "m_n", "beta", "width1", "width2")]


def _standalone(path: Path, entries: dict) -> bool:
    """Whether a file describes its own gearbox: a [topology] of its own, inheriting no shipped file."""
    if _is_shipped(path) or not any(is_topology(k) for k in entries):
        return False
    meta = read_toml(path, f"parameter file {path.name}").get("meta")
    return not (isinstance(meta, dict) and meta.get("inherit"))


def _check_required_generic(p: Parameters, entries: dict) -> None:
    """A file with its own [topology] holds the physics parameters every network needs (REQUIRED_GENERIC; with a
    planetary set REQUIRED_PLANETARY) and the materials of its housings."""
    need = list(REQUIRED_GENERIC)
    if any(k.startswith(f"{TOPOLOGY}.planetary.") for k in entries):
        need += REQUIRED_PLANETARY
    for k, e in entries.items():
        if fnmatch.fnmatchcase(k, f"{TOPOLOGY}.housing.*.material") and isinstance(e, dict):
            name = e.get("v") if "v" in e else p.strings.get(e.get("from", ""))
            need += [f"material.{name}.k", f"material.{name}.cp"]
    for k in need:
        if k not in p.values:
            raise ParameterError(f"{p.origin}: parameter {k} is missing (every gearbox's network needs it)")


def _check_required(p: Parameters):
    for k in REQUIRED:
        if k not in p.values:
            raise ParameterError(f"parameter {k!r} is missing from {p.origin}")
    ratio = 1.0 + p["planetary.z_ring"] / p["planetary.z_sun"]
    if abs((p["planetary.z_ring"] - p["planetary.z_sun"]) / 2.0 - p["planetary.z_planet"]) > 0.5:
        raise ParameterError(
            f"planetary.z_planet = {p['planetary.z_planet']:.0f} does not fit between sun and ring "
            f"(must be (z_ring - z_sun) / 2)"
        )
    if not 2.0 < ratio < 6.0:
        raise ParameterError(f"planetary range ratio 1 + z_ring/z_sun = {ratio:.2f} is outside 2..6")


def _shown(x: float, key: str, dim: str, written: dict | None) -> tuple:
    """(number, unit suffix) of an SI value in the unit the file wrote the key in (SI when not from a file)."""
    if written and key in written:
        u, fac = written[key]
        return x / fac, "" if u == "-" else f" {u}"
    return x, "" if dim == "1" else f" {dim}"


def _sign_rule(key: str, v: float, dim: str) -> str | None:
    """What is wrong with the sign of ``v`` (None if nothing): values are greater than zero unless their dimension
    is sign-free (SIGN_FREE_DIMS) or the key is listed in ZERO_ALLOWED or NOT_POSITIVE."""
    if dim in SIGN_FREE_DIMS:
        return None
    if any(fnmatch.fnmatchcase(key, pat) for pat in NOT_POSITIVE):
        return None if v <= 0 else "must be zero or negative"
    if v > 0:
        return None
    if any(fnmatch.fnmatchcase(key, pat) for pat in ZERO_ALLOWED):
        return None if v == 0 else "must not be negative"
    return "must be greater than zero"


def _unit_hint(key: str) -> str:
    """The end of the sentence refusing an unknown unit of ``key``: the units of its dimension where the key is
    known (a shipped file's or an optional one), else every unit."""
    ref = OPTIONAL_KEYS.get(key) or (_reference_entries().get(key) or {}).get("u")
    if ref not in UNITS:
        return f"which is not one of {sorted(UNITS)}"
    dim = UNITS[ref][0]
    same = " or ".join(f'u = "{x}"' for x, (d, _) in UNITS.items() if d == dim)
    return f"which is not a unit this program knows: the key is {DIM_NAMES.get(dim, dim)}, write it with {same}"


def _check_values(p: Parameters, written: dict | None = None):
    """Every value finite, of the right sign and within its dimension's and its key's range. ``written`` (key ->
    (unit, factor) as in the file) makes the messages name the file and use its units; without it they are in SI."""
    where = f"{p.origin}: " if written else ""
    for key, v in p.values.items():
        dim = p.units.get(key, "1")
        x, unit = _shown(v, key, dim, written)
        if not math.isfinite(v):
            raise ParameterError(f"{where}{key} = {v} is not a finite number")
        bad_sign = _sign_rule(key, v, dim)
        if bad_sign:
            raise ParameterError(f"{where}{key} = {x:g}{unit} {bad_sign} (the key is {DIM_NAMES.get(dim, dim)})")
        if not _ranged(key):
            continue  # a file's own parameter (its [topology] takes it): the description checks what it may be
        lo, hi = DIM_RANGE.get(dim, (-math.inf, math.inf))
        rule = _key_rule(key)
        if rule is not None:
            klo, khi, integer = rule
            lo, hi = max(lo, klo), min(hi, khi)
            if integer and v != int(v):
                raise ParameterError(f"{where}{key} = {x:g}{unit} must be an integer")
        if not lo <= v <= hi:
            (slo, _), (shi, _) = _shown(lo, key, dim, written), _shown(hi, key, dim, written)
            raise ParameterError(f"{where}{key} = {x:g}{unit} is outside its allowed range {slo:g}..{shi:g}{unit}")
        _check_bounds(p, key, dim, lo, hi, where, written)


@functools.lru_cache(maxsize=4096)
def _key_rule(key: str):
    """(low, high, integer?) of the first KEY_RULES pattern a key matches, None if none does."""
    return next(((lo, hi, i) for pat, lo, hi, i in KEY_RULES if fnmatch.fnmatchcase(key, pat)), None)


@functools.lru_cache(maxsize=4096)
def _ranged(key: str) -> bool:
    """Whether a key's value is held to the ranges here: the shipped files' keys and the per-kind ones (PER_KIND,
    OPTIONAL_PER_KIND)."""
    return key in _reference_keys() or any(fnmatch.fnmatchcase(key, pat) for pat, _ in PER_KIND + OPTIONAL_PER_KIND)


@functools.lru_cache(maxsize=1)
def _reference_keys() -> frozenset:
    return frozenset(_reference_entries())


def _check_bounds(p: Parameters, key: str, dim: str, lo: float, hi: float, where: str, written: dict | None):
    """A key's calibration bounds lie within its allowed range and sign: calibrate would otherwise stop half-way
    through a fit on a start point the user never wrote."""
    b = p.bounds.get(key)
    if b is None:
        return
    (blo, _), (bhi, unit) = _shown(b[0], key, dim, written), _shown(b[1], key, dim, written)
    bad = next((x for x in b if _sign_rule(key, x, dim)), None)
    if not (lo <= b[0] and b[1] <= hi) or bad is not None:
        (slo, _), (shi, _) = _shown(lo, key, dim, written), _shown(hi, key, dim, written)
        why = (
            f"{_sign_rule(key, bad, dim)} (the key is {DIM_NAMES.get(dim, dim)})"
            if bad is not None
            else f"reach outside its allowed range {slo:g}..{shi:g}{unit}"
        )
        raise ParameterError(
            f"{where}{key}'s bounds lo = {blo:g} .. hi = {bhi:g}{unit} {why}; calibrate would try values there"
        )
