"""Warning limits and the warning-level state machine of the onboard sensor.

* :func:`load_limits` reads ``params/limits.toml`` (per component group, optional per-component overrides) into a
  frozen :class:`Limits` record with one value per published component (firmware_model.limits, imported here: the
  description's checks use the same loader).
* :func:`update_levels` is the warning state machine: two levels (warning, critical) with hysteresis and a debounce
  time, plus level 3 "not available" (the ``LEVEL_*`` codes of firmware_model.components); vectorised over vehicles.
"""

from __future__ import annotations

import numpy as np

from firmware_model.components import LEVEL_CRITICAL, LEVEL_NA, LEVEL_NORMAL, LEVEL_WARNING
from firmware_model.limits import GROUPS, LIMIT_RANGE_C, LIMITS_PATH, Limits, load_limits

#: the limits' names, imported by the sensor, the exports and the tests from here
__all__ = ["GROUPS", "LIMIT_RANGE_C", "LIMITS_PATH", "Limits", "load_limits", "update_levels"]


def update_levels(level, pending_s, T_c, available, limits: Limits, dt_s: float, ttl_s=None):
    """One step of the warning state machine, vectorised: returns (level, pending_s).

    Target level: critical while T >= critical (or, once critical, while T > critical - hysteresis); else warning
    while T >= warning or the time to the warning limit is at most ``lead_s`` (or, once at warning or above, while
    T > warning - hysteresis or the time to limit is at most 2 lead_s); else normal. A change to the target is
    taken when it has been pending for ``debounce`` seconds, to the nearest step (the timer restarts whenever the
    target equals the current level). Level 3 (not available) is entered and left at once: it reports the sensor,
    not the part.
    """
    T = np.asarray(T_c)
    lv = np.asarray(level)
    crit = (T >= limits.critical_c) | ((lv == LEVEL_CRITICAL) & (T > limits.critical_c - limits.hysteresis_k))
    held = (lv >= LEVEL_WARNING) & (lv <= LEVEL_CRITICAL)
    warn = (T >= limits.warning_c) | (held & (T > limits.warning_c - limits.hysteresis_k))
    if ttl_s is not None and limits.lead_s > 0:
        ttl = np.asarray(ttl_s, dtype=float)  # NaN (not available) compares False, like inf
        warn = warn | (ttl <= limits.lead_s) | (held & (ttl <= 2.0 * limits.lead_s))
    target = np.where(crit, LEVEL_CRITICAL, np.where(warn, LEVEL_WARNING, LEVEL_NORMAL))
    avail = np.asarray(available)[..., None] if np.ndim(available) == np.ndim(T) - 1 else np.asarray(available)
    target = np.where(avail, target, LEVEL_NA)
    change = target != lv
    pend = np.where(change, pending_s + dt_s, 0.0)
    immediate = (target == LEVEL_NA) | (lv == LEVEL_NA)
    # the pending time is a sum of steps: half a step of slack makes a debounce that is a whole number of steps
    # exact in float as in double (600 float steps of 0.1 s sum to less than 60 s), and rounds any other to the
    # nearest step
    take = change & (immediate | (pend >= limits.debounce_s - 0.5 * dt_s))
    new = np.where(take, target, lv).astype(np.int8)
    return new, np.where(take, 0.0, pend)
