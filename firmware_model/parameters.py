"""Load, convert to SI and validate a gearbox parameter file (one TOML file per variant).

Each entry in the file is `name = { v = value, u = "unit", src = "seed|derived|assumed", ref/note = ... }`.
The loader converts every value to SI (temperatures stay in degC), checks the unit is one the entry may have and the
value lies in its allowed range (ranges live here, in code, so a file cannot widen its own), and keeps the provenance
of every value. A variant file may `inherit` another and override entries.

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

import fnmatch
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from firmware_model.errors import ParameterError
from firmware_model.physics.kinematics import KinematicTable, Teeth, build_table
from firmware_model.units import L_PER_M3, RAD_S_PER_RPM, S_PER_MIN

try:
    import tomllib
except ModuleNotFoundError:          # Python 3.10
    import tomli as tomllib

PARAM_DIR = Path(__file__).resolve().parent / "params"
VARIANTS = ("GRS905", "GRSO905")
PROVENANCES = ("seed", "derived", "assumed", "fitted")

#: unit string in a file -> (SI dimension, factor to SI)
UNITS = {
    "-": ("1", 1.0),
    "m": ("m", 1.0), "mm": ("m", 1e-3),
    "m2": ("m2", 1.0),
    "L": ("m3", 1.0 / L_PER_M3), "m3": ("m3", 1.0),
    "deg": ("rad", math.pi / 180.0), "rad": ("rad", 1.0),
    "kg": ("kg", 1.0), "kg/m3": ("kg/m3", 1.0),
    "W/(m K)": ("W/(m K)", 1.0), "J/(kg K)": ("J/(kg K)", 1.0), "W/(m2 K)": ("W/(m2 K)", 1.0),
    "W/K": ("W/K", 1.0), "W": ("W", 1.0), "kW": ("W", 1e3),
    "Pa": ("Pa", 1.0), "N": ("N", 1.0), "Nm": ("N m", 1.0),
    "s": ("s", 1.0), "degC": ("degC", 1.0),
    "rpm": ("rad/s", RAD_S_PER_RPM), "rad/s": ("rad/s", 1.0),
    "Nm/rpm": ("N m s/rad", 1.0 / RAD_S_PER_RPM),           # torque per speed
    "L/min/rpm": ("m3/rad", 1.0 / L_PER_M3 / S_PER_MIN / RAD_S_PER_RPM),   # volume flow per speed
    "m3/rad": ("m3/rad", 1.0),
}
#: renamed keys (old -> new): a file that still uses an old key is read with a deprecation warning
RENAMED_KEYS = {
    "oil_system.flow_per_ls_rpm": "oil_system.flow_m3_per_rad",
    "engine.max_speed": "engine.max_speed_rad_s",
    "heat.N_nom": "heat.omega_nom_rad_s",
}

#: allowed SI range per dimension (inclusive); specific keys are narrowed below
DIM_RANGE = {
    "1": (0.0, 1e6), "m": (0.0, 3.0), "m2": (0.0, 50.0), "m3": (0.0, 0.1), "rad": (0.0, math.radians(45)),
    "kg": (0.0, 1000.0), "kg/m3": (500.0, 20000.0), "W/(m K)": (0.01, 500.0), "J/(kg K)": (100.0, 5000.0),
    "W/(m2 K)": (0.0, 1e7), "W/K": (0.0, 1e5), "W": (0.0, 1e6), "Pa": (1e6, 1e13), "N": (0.0, 1e7),
    "N m": (-1e5, 1e5), "s": (0.0, 1e5), "degC": (-60.0, 250.0), "rad/s": (0.0, 1000.0),
    "N m s/rad": (0.0, 1.0), "m3/rad": (0.0, 1e-4),
}
#: (glob pattern, low, high, integer?) checked after the dimension range, first match wins
KEY_RULES = [
    ("gear.*.z*", 8, 200, True), ("planetary.z_*", 8, 250, True), ("planetary.n_planets", 2, 8, True),
    ("*.n_rollers*", 4, 100, True), ("sync.n_ring_*", 0, 6, True), ("meta.split_inverted", 0, 1, True),
    ("wheel.covered_sides", 0, 1, True),
    ("*frac*", 0.0, 1.0, False), ("housing.internal_split_*", 0.0, 1.0, False), ("*.immersion", 0.0, 1.0, False),
    ("housing.emissivity", 0.0, 1.0, False), ("material.*.poisson", 0.0, 0.5, False),
    ("scale.*_to_heat", 0.1, 3.0, False), ("bearing.sf_*", 0.0, 1.0, False), ("*.sf_*", 0.0, 1.0, False),
    ("oil.volume", 4e-3, 20e-3, False), ("heat.h_nom", 10.0, 5000.0, False), ("heat.TCC", 1e3, 1e6, False),
    ("heat.splash_exponent", 0.0, 2.0, False), ("planetary.h_oil", 10.0, 1e4, False),
    ("housing.h_oil", 10.0, 5000.0, False), ("housing.h_air", 1.0, 200.0, False),
    ("gear.alpha_n", math.radians(14), math.radians(30), False),
    ("bearing.f0_*", 0.5, 10.0, False), ("wheel_bearing.f0_*", 0.5, 10.0, False),
    ("bearing.f1_*", 0.0, 0.01, False), ("wheel.hub_mass_factor", 1.0, 3.0, False),
    ("engine.max_speed_rad_s", 100.0, 1000.0, False),
]


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
        return bool(self["meta.split_inverted"])

    @property
    def teeth(self) -> Teeth:
        z = self.values
        idle = {"LI": int(z["gear.L.z1"]), "3M": int(z["gear.3.z1"]), "2M": int(z["gear.2.z1"]),
                "1M": int(z["gear.1.z1"]), "CM": int(z["gear.C.z1"]), "RM": int(z["gear.R.z1"])}
        lay = {"LL": int(z["gear.L.z2"]), "3L": int(z["gear.3.z2"]), "2L": int(z["gear.2.z2"]),
               "1L": int(z["gear.1.z2"]), "CL": int(z["gear.C.z2"]), "RL": int(z["gear.R.z2"])}
        return Teeth(idle, lay, int(z["gear.R.z_idler"]), int(z["planetary.z_sun"]), int(z["planetary.z_planet"]),
                     int(z["planetary.z_ring"]), int(z["planetary.n_planets"]))

    @property
    def kinematics(self) -> KinematicTable:
        kin = self.__dict__.get("_kin")
        if kin is None:
            kin = build_table(self.teeth, self.split_inverted)
            self.__dict__["_kin"] = kin
        return kin

    def with_overrides(self, overrides: dict) -> "Parameters":
        """A copy with SI values replaced (keys must exist); used by effects and parameter studies."""
        vals = dict(self.values)
        for k, v in overrides.items():
            if k in RENAMED_KEYS:
                warnings.warn(f"parameter {k} is deprecated, use {RENAMED_KEYS[k]}", FutureWarning, stacklevel=2)
                k = RENAMED_KEYS[k]
            if k not in vals:
                raise ParameterError(f"cannot override unknown parameter {k!r}")
            vals[k] = float(v)
        new = Parameters(self.variant, vals, dict(self.sources), dict(self.units), dict(self.strings), self.origin,
                         dict(self.bounds))
        _check_values(new)
        return new

    def table(self):
        """Rows (key, SI value, SI unit, provenance) for documentation."""
        return [(k, self.values[k], self.units[k], self.sources[k]) for k in sorted(self.values)]


def _flatten(d: dict, prefix: str = ""):
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict) and "v" not in v:
            yield from _flatten(v, key + ".")
        else:
            yield key, v


def read_toml(path: str | Path, label: str, label_invalid: str | None = None) -> dict:
    """The TOML document at ``path``; a missing file or invalid TOML is a ParameterError that starts with ``label``
    (e.g. "parameter file GRS905.toml"; ``label_invalid`` for the second case if it differs)."""
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
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
            warnings.warn(f"{path.name}: parameter {key} is deprecated, use {new} (it is read as {new})",
                          FutureWarning, stacklevel=4)
            if new in entries:
                raise ParameterError(f"{path.name}: {key} and {new} are the same parameter; keep only {new}")
            key = new
        out[key] = e
    return out


def _read(path: Path, seen=()) -> dict:
    doc = read_toml(path, f"parameter file {path.name}")
    entries = _renamed(dict(_flatten(doc)), path)
    parent = doc.get("meta", {}).get("inherit")
    if parent:
        if parent in seen:
            raise ParameterError(f"parameter file {path.name} inherits in a cycle through {parent}")
        base = _read(PARAM_DIR / f"{parent}.toml", seen + (parent,))
        base.update({k: v for k, v in entries.items() if k != "meta.inherit"})
        entries = base
    return entries


def parameter_path(variant_or_path: str | Path) -> Path:
    """The TOML file of a variant name (GRS905, GRSO905) or a path."""
    p = Path(variant_or_path)
    if p.suffix.lower() == ".toml":
        return p
    if str(variant_or_path) in VARIANTS:
        return PARAM_DIR / f"{variant_or_path}.toml"
    raise ParameterError(f"unknown gearbox variant {variant_or_path!r}: use one of {', '.join(VARIANTS)} "
                         f"or the path of a .toml parameter file")


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
        raise ParameterError(f"{path.name}: {key} has bounds lo = {e.get('lo')!r}, hi = {e.get('hi')!r}, which are "
                             f"not numbers") from None
    if not lo <= v <= hi or not lo < hi:
        raise ParameterError(f"{path.name}: {key} = {e['v']} must lie within its bounds lo = {e['lo']} .. hi = "
                             f"{e['hi']}")
    return lo, hi


def load_parameters(variant_or_path: str | Path = "GRS905") -> Parameters:
    """Load a variant by name (GRS905, GRSO905) or a TOML file by path."""
    path = parameter_path(variant_or_path)
    entries = _read(path)
    values, sources, units, strings, bounds = {}, {}, {}, {}, {}
    for key, e in entries.items():
        if key in ("meta.variant", "meta.inherit"):
            strings[key] = str(e)
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
            raise ParameterError(f"{path.name}: {key} has unit {u!r}, which is not one of {sorted(UNITS)}")
        dim, fac = UNITS[u]
        try:
            v = float(e["v"]) * fac
        except (TypeError, ValueError):
            raise ParameterError(f"{path.name}: {key} = {e['v']!r} is not a number") from None
        values[key] = v
        sources[key] = src
        units[key] = dim
        b = _bounds(path, key, e, fac, v)
        if b is not None:
            bounds[key] = b
    params = Parameters(strings.get("meta.variant", path.stem), values, sources, units, strings, path.name, bounds)
    _check_values(params)
    _check_required(params)
    kind = params.strings.get("cooler.kind", "liquid")
    if kind not in COOLER_KINDS:
        raise ParameterError(f"cooler.kind = {kind!r} must be one of {', '.join(COOLER_KINDS)}")
    return params


COOLER_KINDS = ("none", "liquid", "air", "hold", "measured")

REQUIRED = [
    "gear.center_distance", "gear.alpha_n", "oil.volume", "heat.h_nom", "heat.TCC", "planetary.z_sun",
    "scale.gear_contact_to_heat", "scale.planet_to_heat", "scale.churn_to_heat", "housing.h_oil",
    "cooler.liquid_hA_ref", "boundary.ambient", "engine.max_torque", "engine.max_speed_rad_s",
] + [f"gear.{p}.{k}" for p in ("L", "3", "2", "1", "C", "R") for k in ("z1", "z2", "m_n", "beta", "width1", "width2")]


def _check_required(p: Parameters):
    for k in REQUIRED:
        if k not in p.values:
            raise ParameterError(f"parameter {k!r} is missing from {p.origin}")
    ratio = 1.0 + p["planetary.z_ring"] / p["planetary.z_sun"]
    if abs((p["planetary.z_ring"] - p["planetary.z_sun"]) / 2.0 - p["planetary.z_planet"]) > 0.5:
        raise ParameterError(f"planetary.z_planet = {p['planetary.z_planet']:.0f} does not fit between sun and ring "
                             f"(must be (z_ring - z_sun) / 2)")
    if not 2.0 < ratio < 6.0:
        raise ParameterError(f"planetary range ratio 1 + z_ring/z_sun = {ratio:.2f} is outside 2..6")


def _check_values(p: Parameters):
    for key, v in p.values.items():
        if not math.isfinite(v):
            raise ParameterError(f"{key} = {v} is not a finite number")
        dim = p.units.get(key, "1")
        lo, hi = DIM_RANGE.get(dim, (-math.inf, math.inf))
        if not lo <= v <= hi:
            raise ParameterError(f"{key} = {v:g} {dim} is outside its allowed range {lo:g}..{hi:g} {dim}")
        for pat, klo, khi, integer in KEY_RULES:
            if fnmatch.fnmatchcase(key, pat):
                if not klo <= v <= khi:
                    raise ParameterError(f"{key} = {v:g} is outside its allowed range {klo:g}..{khi:g}")
                if integer and v != int(v):
                    raise ParameterError(f"{key} = {v:g} must be an integer")
                break
