"""Warning limits of the published components: the limits file (``params/limits.toml`` or a description's own,
``[topology.published] limits``) read and checked into a frozen :class:`Limits` record, one value per published
component. One loader for every command: `describe` (firmware_model.description) checks a description's limits file
with it, the onboard sensor (replay, simulate) runs on what it returns; the warning state machine that uses the
limits is firmware_model.onboard.warning_levels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from firmware_model.components import GROUP, PUBLISHED
from firmware_model.errors import ParameterError
from firmware_model.parameters import PARAM_DIR, read_toml

LIMITS_PATH = PARAM_DIR / "limits.toml"
GROUPS = ("gear", "sun", "planetary", "bearing", "oil")
_KEYS = {"warning": "degC", "critical": "degC", "hysteresis": "K"}
#: every warning and critical limit lies in this range [degC] (the limits file, a configuration, the FMU's parameters)
LIMIT_RANGE_C = (-40.0, 250.0)


@dataclass(frozen=True)
class Limits:
    """Per published component (``components`` order, the description's published.order): warning and critical
    limits [degC], hysteresis [K]; debounce [s]."""

    warning_c: np.ndarray
    critical_c: np.ndarray
    hysteresis_k: np.ndarray
    debounce_s: float
    provenance: dict
    origin: str = "default"
    #: a warning also fires when the component will reach its warning limit within lead_s at the current load
    #: (and clears only when that is more than 2 lead_s away); 0 switches the early warning off
    lead_s: float = 0.0
    #: the published components' ids, in the order of the arrays (default: the GRS905's)
    components: tuple = PUBLISHED

    def of(self, component: str) -> tuple:
        i = self.components.index(component)
        return float(self.warning_c[i]), float(self.critical_c[i]), float(self.hysteresis_k[i])


def _value(entry, where: str, unit: str) -> tuple:
    if not isinstance(entry, dict) or "v" not in entry:
        raise ParameterError(f'{where} must be a table {{ v = ..., u = "{unit}", src = ... }}')
    if entry.get("u") != unit:
        raise ParameterError(f"{where} has unit {entry.get('u')!r}; it must be {unit!r}")
    if entry.get("src") not in ("seed", "derived", "assumed"):
        raise ParameterError(f"{where} has provenance {entry.get('src')!r}; it must be seed, derived or assumed")
    v = entry["v"]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ParameterError(f"{where} = {v!r} is not a finite number")
    return float(v), entry["src"]


def _limits_path(path: str | Path | None) -> Path:
    """The limits file: the default, a path, or a shipped file by its name (limits.toml, limits_wind.toml)."""
    path = Path(path) if path is not None else LIMITS_PATH
    if not path.exists() and path.name == str(path) and (LIMITS_PATH.parent / path.name).exists():
        return LIMITS_PATH.parent / path.name
    return path


def load_limits(
    path: str | Path | None = None,
    debounce_s: float | None = None,
    hysteresis_k: float | None = None,
    lead_s: float | None = None,
    published: tuple | None = None,
) -> Limits:
    """Limits from a TOML file (default params/limits.toml); ``debounce_s`` / ``hysteresis_k`` override the file
    (config [sensor] debounce_s, hysteresis_c). ``published``: the components, each with an ``id`` and a limit
    ``group`` (a description's published, firmware_model.description), in their order; None: the GRS905's."""
    ids = PUBLISHED if published is None else tuple(c.id for c in published)
    group = GROUP if published is None else {c.id: c.group for c in published}
    path = _limits_path(path)
    doc = read_toml(path, f"limits file {path}", f"limits file {path.name}")
    known = set(GROUPS) | {"meta", "timing", "component"}
    for k in doc:
        if k not in known:
            raise ParameterError(f"{path.name}: unknown section [{k}]; known: {', '.join(sorted(known))}")
    prov = {}
    per = {}
    for g in GROUPS:
        sec = doc.get(g)
        if not isinstance(sec, dict):
            raise ParameterError(f"{path.name}: section [{g}] is missing")
        for key, unit in _KEYS.items():
            if key not in sec:
                raise ParameterError(f"{path.name}: {g}.{key} is missing")
            per[(g, key)], prov[f"{g}.{key}"] = _value(sec[key], f"{path.name}: {g}.{key}", unit)
        for key in sec:
            if key not in _KEYS:
                raise ParameterError(f"{path.name}: unknown key {g}.{key}; known: {', '.join(_KEYS)}")
    timing = doc.get("timing", {})
    deb, prov["timing.debounce"] = _value(
        timing.get("debounce", {"v": 1.0, "u": "s", "src": "assumed"}), f"{path.name}: timing.debounce", "s"
    )
    lead, prov["timing.lead"] = _value(
        timing.get("lead", {"v": 0.0, "u": "s", "src": "assumed"}), f"{path.name}: timing.lead", "s"
    )
    for k in timing:
        if k not in ("debounce", "lead"):
            raise ParameterError(f"{path.name}: unknown key timing.{k}; known: debounce, lead")
    n = len(ids)
    for c in ids:
        if group[c] not in GROUPS:
            raise ParameterError(f"published component {c}: limit group {group[c]!r} has no section in {path.name}")
    arr = {key: np.array([per[(group[c], key)] for c in ids]) for key in _KEYS}
    for comp, sec in (doc.get("component") or {}).items():
        if comp not in ids:
            raise ParameterError(f"{path.name}: [component.{comp!r}] is not a published component")
        i = ids.index(comp)
        for key, entry in sec.items():
            if key not in _KEYS:
                raise ParameterError(f"{path.name}: unknown key component.{comp}.{key}")
            arr[key][i], prov[f"component.{comp}.{key}"] = _value(
                entry, f"{path.name}: component.{comp}.{key}", _KEYS[key]
            )
    if debounce_s is not None:
        deb = float(debounce_s)
    if hysteresis_k is not None:
        arr["hysteresis"] = np.full(n, float(hysteresis_k))
    w, c, hy = arr["warning"], arr["critical"], arr["hysteresis"]
    for i, comp in enumerate(ids):
        if not LIMIT_RANGE_C[0] <= w[i] < c[i] <= LIMIT_RANGE_C[1]:
            raise ParameterError(
                f"limits of {comp}: warning {w[i]:g} degC must be below critical {c[i]:g} degC, "
                f"both in {LIMIT_RANGE_C[0]:g}..{LIMIT_RANGE_C[1]:g} degC"
            )
        if not 0.0 <= hy[i] < c[i] - w[i]:
            raise ParameterError(
                f"limits of {comp}: hysteresis {hy[i]:g} K must be in 0..(critical - warning) = {c[i] - w[i]:g} K"
            )
    if not 0.0 <= deb <= 60.0:
        raise ParameterError(f"debounce = {deb:g} s must be in 0..60 s")
    if lead_s is not None:
        lead = float(lead_s)
    if not 0.0 <= lead <= 3600.0:
        raise ParameterError(f"lead = {lead:g} s must be in 0..3600 s")
    for a in (w, c, hy):
        a.setflags(write=False)
    return Limits(w, c, hy, deb, prov, str(path.name), lead, ids)
