"""The first-order lag between a mechanical loss and the heat it deposits (seed section 3.2, Fig 4).

The seed low-passes the loss-to-heat signals with a first-order lag ``tau dy/dt = u - y`` to keep gear-change loss
spikes out of the thermal network. For an input held over a step of length dt the lag is exact:
``y_new = y + (u - y) (1 - exp(-dt / tau))``, and the heat the lag delivers on average over the step is what enters
minus what it stores, ``u - tau (y_new - y) / dt``, so no joule is lost or created. The reference plant and the
onboard step both use :func:`heat_lag_step` (the onboard step with its fixed dt through precomputed
:func:`heat_lag` coefficients). tau <= 0 means no lag: the heat is the loss.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


class HeatLag(NamedTuple):
    """Coefficients of one step of the lag."""

    gain: float  # 1 - exp(-dt / tau): share of the gap to the input closed in one step
    tau_over_dt: float  # tau / dt (0: no lag)


class LagStep(NamedTuple):
    state_w: np.ndarray | float  # the lag's output at the end of the step
    delivered_w: np.ndarray | float  # heat delivered on average over the step


def heat_lag(tau_s: float, dt_s: float) -> HeatLag:
    """The coefficients of a step of ``dt_s`` for a lag of time constant ``tau_s`` (no lag when tau_s <= 0)."""
    if tau_s > 0:
        return HeatLag(-math.expm1(-dt_s / tau_s), tau_s / dt_s)
    return HeatLag(1.0, 0.0)


def heat_lag_step(y_w, u_w, lag: HeatLag) -> LagStep:
    """One exact step of the lag for an input ``u_w`` held over the step, from the state ``y_w`` (vectorised)."""
    y_new = y_w + (u_w - y_w) * lag.gain
    return LagStep(y_new, u_w - lag.tau_over_dt * (y_new - y_w))


def first_order_lag_step(y, u, dt_s, tau_s):
    """One exact (zero-order-hold) step of ``tau dy/dt = u - y``: ``u + (y - u) exp(-dt/tau)`` (the reference form
    of the lag's state; tau <= 0 means no lag: y follows u). Vectorised, also over tau."""
    y = np.asarray(y, dtype=float)
    u = np.asarray(u, dtype=float)
    tau = np.asarray(tau_s, dtype=float)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        a = np.where(tau > 0.0, np.exp(-dt_s / np.where(tau > 0.0, tau, 1.0)), 0.0)
    return u + (y - u) * a
