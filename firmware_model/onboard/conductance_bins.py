"""Conductances of the onboard network at a quantised operating point (docs/sensor.md).

The step evaluates every link's conductance at the centre of the operating point's bin: 1 % in input speed, 0.5 K
in oil temperature, radiation linearised at the bin's oil temperature. The conductances are then a pure function of
(gear row, speed bin centre, oil bin centre): :func:`bin_conductances` evaluates them for any batch shape through
firmware_model.onboard.evaluate, and a :class:`BinCache` (part of the sensor's step cache) memoises them for one
vehicle at a time, keyed by the bin centre itself, so that a cached value is the value the batch computes.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware_model.onboard import evaluate as E
from firmware_model.onboard.evaluate import SPEED_BIN_MIN_RAD_S
from firmware_model.onboard.params import SensorParams

#: operating-point quantisation of the conductances: 1 % in speed, 0.5 K in oil temperature
SPEED_BIN_REL = 0.01
OIL_BIN_C = 0.5
LN_SPEED_BIN = math.log1p(SPEED_BIN_REL)
#: bins a BinCache keeps (a bounded memo; the oldest entry goes first)
BIN_CACHE_SIZE = 256


def quantise(omega_in_rad_s, T_oil_c, speed_min_rad_s: float = SPEED_BIN_MIN_RAD_S):
    """(speed bin centre [rad/s], oil bin centre [degC], speed bin index) of the operating point, any shape: the
    conductances are evaluated at the bin centres; below ``speed_min_rad_s`` (ReducedParams.speed_bin_min_rad_s) at
    standstill."""
    omega = np.asarray(omega_in_rad_s, dtype=float)
    b = np.round(np.log(np.maximum(omega, speed_min_rad_s)) / LN_SPEED_BIN)
    omega_q = np.where(omega >= speed_min_rad_s, np.exp(b * LN_SPEED_BIN), 0.0)
    T_q = np.round(np.asarray(T_oil_c, dtype=float) / OIL_BIN_C) * OIL_BIN_C
    return omega_q, T_q, b


def bin_centre(
    omega_in_rad_s: float, T_oil_c: float, speed_min_rad_s: float = SPEED_BIN_MIN_RAD_S
) -> tuple[float, float]:
    """:func:`quantise` for one vehicle in scalars, the same numbers: (speed bin centre, oil bin centre)."""
    if omega_in_rad_s >= speed_min_rad_s:
        omega_q = float(np.exp(np.round(np.log(omega_in_rad_s) / LN_SPEED_BIN) * LN_SPEED_BIN))
    else:
        omega_q = 0.0
    return omega_q, round(T_oil_c / OIL_BIN_C) * OIL_BIN_C


class BinConductances(NamedTuple):
    """Conductances at one bin centre [W/K]."""

    G_w_per_k: np.ndarray  # (nl,) every link
    G_streams_w_per_k: np.ndarray  # (nst,) the oil-system stream terms
    G_int_w_per_k: np.ndarray  # (n_int,) the node-node links (helpers.int_idx)
    G_ext_w_per_k: np.ndarray  # (n_ext,) the node-boundary links (helpers.ext_idx)


def bin_conductances(sp: SensorParams, row, omega_q_rad_s, T_q_c):
    """(G, stream G) at bin centres of any batch shape: the compact laws of firmware_model.onboard.evaluate at the
    speed and oil temperature of the centre, radiation (Eq 81) with the housings at the bin's oil temperature (they
    sit within a few kelvin of the sump: ~1 % on h_rad) and the boundaries at their defaults."""
    rp, h = sp.reduced, sp.helpers
    T_q = np.asarray(T_q_c, dtype=float)
    T_grid_x, prop, phi = E.oil_row(rp, T_q, h)
    T_nodes = np.broadcast_to(T_q[..., None], T_q.shape + (rp.n,))
    return E.conductances(rp, row, omega_q_rad_s, T_grid_x, prop, phi, T_nodes, sp.T_bc_default_c, sp.effects, h)


class BinCache:
    """Conductances per bin for one vehicle (scalar effects): a bounded memo of :func:`bin_conductances` keyed by
    (gear row, speed bin centre, oil bin centre)."""

    def __init__(self, size: int = BIN_CACHE_SIZE):
        self.size = size
        self.items: dict = {}

    def get(self, sp: SensorParams, row: int, omega_q_rad_s: float, T_q_c: float) -> BinConductances:
        key = (row, omega_q_rad_s, T_q_c)
        item = self.items.get(key)
        if item is None:
            G, Gs = bin_conductances(sp, row, omega_q_rad_s, T_q_c)
            h = sp.helpers
            item = BinConductances(G, Gs, G[h.int_idx], G[h.ext_idx])
            for a in item:
                a.setflags(write=False)
            self.items[key] = item
            if len(self.items) > self.size:
                self.items.pop(next(iter(self.items)))
        return item


def conductance_matrix(G_w_per_k, h: E.Helpers, n: int):
    """(K, G_ext): the network's conductance matrix [W/K] (weighted Laplacian plus the boundary links on the
    diagonal) of one vehicle's link conductances, and the boundary links' conductances."""
    # TODO(merge): one conductance assembly (the plant and firmware_model.onboard.evaluate assemble the same matrix)
    Gi = G_w_per_k[h.int_idx]
    K = np.zeros((n, n))
    np.add.at(K, (h.ia, h.ia), Gi)
    np.add.at(K, (h.ib, h.ib), Gi)
    np.add.at(K, (h.ia, h.ib), -Gi)
    np.add.at(K, (h.ib, h.ia), -Gi)
    G_ext = G_w_per_k[h.ext_idx]
    np.add.at(K, (h.ea, h.ea), G_ext)
    return K, G_ext
