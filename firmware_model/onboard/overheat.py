"""Overheat warnings and time to limit of the onboard sensor.

* :func:`load_limits` reads ``params/limits.toml`` (per component group, optional per-component overrides) into a
  frozen :class:`Limits` record with one value per published component.
* :func:`update_levels` is the warning state machine: two levels (warning, critical) with hysteresis and a debounce
  time, plus level 3 "not available"; vectorised over vehicles.
* :class:`HeldInputSolver` answers "what happens if the current inputs are held": with the inputs frozen the onboard
  network is linear, ``C dT/dt = -K T + b``. ``K`` is symmetric (a weighted Laplacian plus boundary and cooler terms
  on its diagonal), so ``C^-1/2 K C^-1/2 = V diag(lambda) V^T`` with real ``lambda > 0`` and
  ``T(t) = T_inf + C^-1/2 V exp(-lambda t) V^T C^1/2 (T(0) - T_inf)`` exactly. With the sump modelled, the oil-system
  inlet follows the sump through a column ``u`` (``K - u e_sump^T``, not symmetric): then ``V diag(lambda) V^-1``
  from a general eigen-decomposition, possibly with a complex pair (temperatures are the real parts). The
  decomposition depends only on the operating point (gear, speed, oil temperature, oil measured or not, the cooler
  slope) and is cached per quantised operating point (a bounded LRU); ``T_inf`` and the modal coefficients are
  recomputed from the current temperatures and heat every time. Time to limit is the first crossing of the warning
  limit, found on a geometric time grid and refined by a safeguarded Newton search on multiples of 2^-7 s; the same
  solution propagates the state over a time jump (held inputs) and cools a snapshot down (engine off) on restart.
"""
from __future__ import annotations

import math
import tomllib
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from firmware_model.components import GROUP, PUBLISHED
from firmware_model.errors import ParameterError

LIMITS_PATH = Path(__file__).resolve().parents[1] / "params" / "limits.toml"
GROUPS = ("gear", "sun", "planetary", "bearing", "oil")
LEVEL_NORMAL, LEVEL_WARNING, LEVEL_CRITICAL, LEVEL_NA = 0, 1, 2, 3
_KEYS = {"warning": "degC", "critical": "degC", "hysteresis": "K"}


@dataclass(frozen=True)
class Limits:
    """Per published component (PUBLISHED order): warning and critical limits [degC], hysteresis [K]; debounce [s]."""
    warning_c: np.ndarray
    critical_c: np.ndarray
    hysteresis_k: np.ndarray
    debounce_s: float
    provenance: dict
    origin: str = "default"
    #: a warning also fires when the component will reach its warning limit within lead_s at the current load
    #: (and clears only when that is more than 2 lead_s away); 0 switches the early warning off
    lead_s: float = 0.0

    def of(self, component: str) -> tuple:
        i = PUBLISHED.index(component)
        return float(self.warning_c[i]), float(self.critical_c[i]), float(self.hysteresis_k[i])


def _value(entry, where: str, unit: str) -> tuple:
    if not isinstance(entry, dict) or "v" not in entry:
        raise ParameterError(f"{where} must be a table {{ v = ..., u = \"{unit}\", src = ... }}")
    if entry.get("u") != unit:
        raise ParameterError(f"{where} has unit {entry.get('u')!r}; it must be {unit!r}")
    if entry.get("src") not in ("seed", "derived", "assumed"):
        raise ParameterError(f"{where} has provenance {entry.get('src')!r}; it must be seed, derived or assumed")
    v = entry["v"]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ParameterError(f"{where} = {v!r} is not a finite number")
    return float(v), entry["src"]


def load_limits(path: str | Path | None = None, debounce_s: float | None = None,
                hysteresis_k: float | None = None, lead_s: float | None = None) -> Limits:
    """Limits from a TOML file (default params/limits.toml); ``debounce_s`` / ``hysteresis_k`` override the file
    (config [sensor] debounce_s, hysteresis_c)."""
    path = Path(path) if path is not None else LIMITS_PATH
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError:
        raise ParameterError(f"limits file {path} does not exist") from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"limits file {path.name} is not valid TOML: {exc}") from None
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
    deb, prov["timing.debounce"] = _value(timing.get("debounce", {"v": 1.0, "u": "s", "src": "assumed"}),
                                          f"{path.name}: timing.debounce", "s")
    lead, prov["timing.lead"] = _value(timing.get("lead", {"v": 0.0, "u": "s", "src": "assumed"}),
                                       f"{path.name}: timing.lead", "s")
    for k in timing:
        if k not in ("debounce", "lead"):
            raise ParameterError(f"{path.name}: unknown key timing.{k}; known: debounce, lead")
    n = len(PUBLISHED)
    arr = {key: np.array([per[(GROUP[c], key)] for c in PUBLISHED]) for key in _KEYS}
    for comp, sec in (doc.get("component") or {}).items():
        if comp not in PUBLISHED:
            raise ParameterError(f"{path.name}: [component.{comp!r}] is not a published component")
        i = PUBLISHED.index(comp)
        for key, entry in sec.items():
            if key not in _KEYS:
                raise ParameterError(f"{path.name}: unknown key component.{comp}.{key}")
            arr[key][i], prov[f"component.{comp}.{key}"] = _value(entry, f"{path.name}: component.{comp}.{key}",
                                                                   _KEYS[key])
    if debounce_s is not None:
        deb = float(debounce_s)
    if hysteresis_k is not None:
        arr["hysteresis"] = np.full(n, float(hysteresis_k))
    w, c, hy = arr["warning"], arr["critical"], arr["hysteresis"]
    for i, comp in enumerate(PUBLISHED):
        if not -40.0 <= w[i] < c[i] <= 250.0:
            raise ParameterError(f"limits of {comp}: warning {w[i]:g} degC must be below critical {c[i]:g} degC, "
                                 f"both in -40..250 degC")
        if not 0.0 <= hy[i] < c[i] - w[i]:
            raise ParameterError(f"limits of {comp}: hysteresis {hy[i]:g} K must be in 0..(critical - warning) = "
                                 f"{c[i] - w[i]:g} K")
    if not 0.0 <= deb <= 60.0:
        raise ParameterError(f"debounce = {deb:g} s must be in 0..60 s")
    if lead_s is not None:
        lead = float(lead_s)
    if not 0.0 <= lead <= 3600.0:
        raise ParameterError(f"lead = {lead:g} s must be in 0..3600 s")
    for a in (w, c, hy):
        a.setflags(write=False)
    return Limits(w, c, hy, deb, prov, str(path.name), lead)


def update_levels(level, pending_s, T_c, available, limits: Limits, dt_s: float, ttl_s=None):
    """One step of the warning state machine, vectorised: returns (level, pending_s).

    Target level: critical while T >= critical (or, once critical, while T > critical - hysteresis); else warning
    while T >= warning or the time to the warning limit is at most ``lead_s`` (or, once at warning or above, while
    T > warning - hysteresis or the time to limit is at most 2 lead_s); else normal. A change to the target is
    taken when it has been pending for ``debounce`` seconds (the timer restarts whenever the target equals the
    current level). Level 3 (not available) is entered and left at once: it reports the sensor, not the part.
    """
    T = np.asarray(T_c)
    lv = np.asarray(level)
    crit = (T >= limits.critical_c) | ((lv == LEVEL_CRITICAL) & (T > limits.critical_c - limits.hysteresis_k))
    held = (lv >= LEVEL_WARNING) & (lv <= LEVEL_CRITICAL)
    warn = (T >= limits.warning_c) | (held & (T > limits.warning_c - limits.hysteresis_k))
    if ttl_s is not None and limits.lead_s > 0:
        ttl = np.asarray(ttl_s, dtype=float)          # NaN (not available) compares False, like inf
        warn = warn | (ttl <= limits.lead_s) | (held & (ttl <= 2.0 * limits.lead_s))
    target = np.where(crit, LEVEL_CRITICAL, np.where(warn, LEVEL_WARNING, LEVEL_NORMAL))
    avail = np.asarray(available)[..., None] if np.ndim(available) == np.ndim(T) - 1 else np.asarray(available)
    target = np.where(avail, target, LEVEL_NA)
    change = target != lv
    pend = np.where(change, pending_s + dt_s, 0.0)
    immediate = (target == LEVEL_NA) | (lv == LEVEL_NA)
    take = change & (immediate | (pend >= limits.debounce_s - 1e-9))
    new = np.where(take, target, lv).astype(np.int8)
    return new, np.where(take, 0.0, pend)


# ---------------------------------------------------------------------------------------------------------------
# held inputs: the linear network and its modal solution

#: geometric time grid of the first-crossing search [s]
TTL_GRID_S = np.concatenate([[0.0], np.geomspace(0.5, 2.0e6, 72)])
#: safeguarded Newton steps of the first-crossing search (from regula falsi on the grid bracket; the bracket halves
#: whenever Newton would leave it)
NEWTON_STEPS = 8
#: the search works on multiples of this [s] and returns the first multiple at or after the crossing: its result
#: rests on comparisons (T >= limit at a multiple), not on the last bits of exp(), so machines whose exp() differs
#: in the last bit (numpy's AVX-512 and AVX2 paths: the vcan VM and its host) give the same time to limit
TTL_QUANTUM_S = 2.0 ** -7
#: time to limit beyond this is reported as never (inf) [s]
TTL_HORIZON_S = float(TTL_GRID_S[-1])


def _re(x):
    """Real part of a modal sum (the modes of a coupled system may include a complex pair); real input as is."""
    return x.real if np.iscomplexobj(x) else x


class HeldInputSolver:
    """Modal solution of the onboard network with held inputs; one per (ReducedParams, cache size)."""

    def __init__(self, n_nodes: int, C_j_per_k: np.ndarray, cache_size: int = 64):
        self.n = n_nodes
        self.C = np.asarray(C_j_per_k, dtype=float)
        self.sqrtC = np.sqrt(self.C)
        self.cache: OrderedDict = OrderedDict()
        self.cache_size = cache_size
        self.hits = 0
        self.misses = 0

    def modes(self, key, K: np.ndarray, free: np.ndarray, coupling=None):
        """Eigen-decomposition of C^-1/2 K C^-1/2 over the free nodes (cached under ``key``).

        ``coupling = (u, j)``: the system is ``C dT/dt = -(K - u e_j^T) T + b``, a node j (the modelled sump) that
        drives the others through the column u (the oil-system inlet follows the sump through the cooler). That
        matrix is not symmetric: its modes come from a general eigen-decomposition, ``V^-1`` is kept with them, and
        the item says ``coupled`` (and keeps u as its item[6]). Its modes may include a complex pair: the
        temperatures are then the real parts of the modal sums. When an eigenvalue has no positive real part or the
        eigenvectors are ill-conditioned (V^-1 does not reproduce the matrix to 1e-9), the coupling is dropped (the
        symmetric modes of K) and the item says so (``coupled`` False), so that the caller can freeze the inlet
        instead."""
        item = self.cache.get(key) if key is not None else None
        if item is not None:
            self.cache.move_to_end(key)
            self.hits += 1
            return item
        self.misses += 1
        s = self.sqrtC[free]
        Kf = K[np.ix_(free, free)]
        M = Kf / s[:, None] / s[None, :]
        item = None
        if coupling is not None:
            u, j = coupling
            jf = int(np.searchsorted(free, j))
            Mc = M.copy()
            Mc[:, jf] -= np.asarray(u, dtype=float)[free] / (s * s[jf])
            try:
                lam, V = np.linalg.eig(Mc)
            except (np.linalg.LinAlgError, ValueError):      # no convergence (or not finite): symmetric modes
                lam, V = np.array([-1.0]), None
            if np.all(lam.imag == 0.0) and V is not None:
                lam, V = lam.real.copy(), np.ascontiguousarray(V.real)
            # a complex pair (the sump-stream loop can make one) is kept: temperatures are the real parts
            if V is not None and np.all(lam.real > 0.0):
                try:
                    Vinv = np.linalg.inv(V)
                except np.linalg.LinAlgError:
                    Vinv = None
                if Vinv is not None and np.abs((V * lam) @ Vinv - Mc).max() <= 1e-9 * np.abs(Mc).max():
                    item = (lam, V, s, free, np.exp(-np.outer(lam, TTL_GRID_S)), Vinv, np.asarray(u, dtype=float))
        if item is None:
            lam, V = np.linalg.eigh(0.5 * (M + M.T))
            lam = np.maximum(lam, 1e-12)
            item = (lam, V, s, free, np.exp(-np.outer(lam, TTL_GRID_S)), None)
        if key is not None:
            self.cache[key] = item
            if len(self.cache) > self.cache_size:
                self.cache.popitem(last=False)
        return item

    @staticmethod
    def coupled(item) -> bool:
        """True when the item's modes include the coupling asked for (see :meth:`modes`)."""
        return len(item) > 5 and item[5] is not None

    @staticmethod
    def _to_modes(item, x):
        """Modal coordinates of x (scaled by C^1/2): V^T x for the symmetric modes, V^-1 x for the coupled ones."""
        return item[5] @ x if len(item) > 5 and item[5] is not None else item[1].T @ x

    @staticmethod
    def steady(item, b_free):
        """T_inf over the free nodes: K_ff^-1 b_f = C^-1/2 V lambda^-1 V^-1 C^-1/2 b_f (V^-1 = V^T when symmetric)."""
        lam, V, s = item[:3]
        return _re(V @ (HeldInputSolver._to_modes(item, b_free / s) / lam)) / s

    @staticmethod
    def propagate(item, T0_free, Tinf_free, t_s):
        """Free-node temperatures after t_s seconds of held inputs."""
        lam, V, s = item[:3]
        c = HeldInputSolver._to_modes(item, s * (T0_free - Tinf_free))
        return Tinf_free + _re(V @ (c * np.exp(-lam * t_s))) / s

    @staticmethod
    def time_to_limit(item, T0_free, Tinf_free, rows, limit_c):
        """First time [s] each free node ``rows`` reaches ``limit_c`` (0 if already there, inf if never within the
        horizon), for held inputs."""
        lam, V, s = item[:3]
        c = HeldInputSolver._to_modes(item, s * (T0_free - Tinf_free))
        W = V[rows] / s[rows, None]                       # (r, m)
        Wc = W * c                                        # modal contributions
        T0 = T0_free[rows]
        out = np.full(len(rows), np.inf)
        out[T0 >= limit_c] = 0.0
        # bound: T(t) <= T_inf + sum |W c| for all t >= 0
        reach = (T0 < limit_c) & (Tinf_free[rows] + np.abs(Wc).sum(axis=1) >= limit_c)
        idx = np.flatnonzero(reach)
        if idx.size == 0:
            return out
        E = item[4] if len(item) > 4 else np.exp(-np.outer(lam, TTL_GRID_S))   # (m, g), cached with the modes
        F = Tinf_free[rows[idx], None] + _re(Wc[idx] @ E)  # (k, g)
        L = limit_c[idx, None]
        above = F >= L
        first = np.where(above.any(axis=1), above.argmax(axis=1), -1)
        sel = first > 0
        if sel.any():
            j = idx[sel]
            g = first[sel]
            lo, hi = TTL_GRID_S[g - 1], TTL_GRID_S[g]
            wcl = np.stack([Wc[j], Wc[j] * lam], axis=1)  # (k, 2, m): T(t) - T_inf and -dT/dt from e
            f0 = Tinf_free[rows[j]] - limit_c[j]
            f_lo = F[sel, g - 1] - limit_c[j]              # < 0
            f_hi = F[sel, g] - limit_c[j]                  # >= 0
            q = TTL_QUANTUM_S
            t = np.round((lo + (hi - lo) * (-f_lo / (f_hi - f_lo))) / q) * q   # regula falsi start in the bracket
            inside = (t > lo) & (t < hi)
            with np.errstate(divide="ignore", invalid="ignore"):
                for _ in range(NEWTON_STEPS):              # safeguarded Newton on multiples of q (all at once)
                    sums = _re((wcl * np.exp(np.multiply.outer(t, -lam))[:, None, :]).sum(axis=2))
                    f = f0 + sums[:, 0]
                    up = f >= 0.0
                    hi = np.where(inside & up, t, hi)
                    lo = np.where(inside & ~up, t, lo)
                    t_new = np.round((t + f / sums[:, 1]) / q) * q  # t - f / (dT/dt)
                    # Newton settled on t: test its neighbour on the open side of the crossing
                    t = np.where(t_new == t, np.where(up, t - q, t + q), t_new)
                    inside = (t > lo) & (t < hi)
                    if not inside.all():                   # else bisect the bracket
                        t = np.where(inside, t, np.round(0.5 * (lo + hi) / q) * q)
                        inside = (t > lo) & (t < hi)       # False once the bracket is one quantum wide
                        if not inside.any():
                            break
            out[j] = hi
        return out
