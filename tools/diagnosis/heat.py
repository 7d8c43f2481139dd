"""The oil residual as a heat flow: Q = C_eff d(r)/dt + G_eff r, the heat entering the oil that the model does not
have (r smoothed over 120 s)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from tools.diagnosis.baseline import HeatPair
from tools.diagnosis.models import Q_OUT
from tools.diagnosis.options import OIL, json_number

#: the smoothing window of the residual [s]
SMOOTHING_S = 120.0


class HeatSeries(NamedTuple):
    """The unexplained heat flow of one file's oil channel on the analysis grid."""

    dataset: object  # prepare.Dataset
    t_s: np.ndarray
    Q_w: np.ndarray
    r_smooth_c: np.ndarray


class UnexplainedHeat(NamedTuple):
    json: dict  # the JSON's "unexplained_heat"
    series: list  # HeatSeries per file with an oil channel


def effective_conductance_w_per_k(pair: HeatPair) -> float:
    """G_eff from the warmer-start re-simulation: d(heat to the outside) / d(T_oil); NaN without one."""
    ratios = []
    for out0, out1 in zip(pair.base, pair.warmer):
        q0 = sum(np.asarray(out0.get(c, 0.0)) for c in Q_OUT)
        q1 = sum(np.asarray(out1.get(c, 0.0)) for c in Q_OUT)
        dT = np.asarray(out1["T_oil_c"]) - np.asarray(out0["T_oil_c"])
        m = dT > 0.2
        if np.any(m):
            ratios.append(np.median((q1 - q0)[m] / dT[m]))
    return float(np.median(ratios)) if ratios else float("nan")


def oil_heat_capacity_j_per_k(params) -> float:
    """The oil and the housings (the description's), which follow it."""
    from firmware_model.network import build_network
    from tools.published import housings

    net = build_network(params)
    C = dict(zip(net.nodes, net.C_j_per_k))
    total = C["oil"]
    for h in housings(params):
        total += C[h]
    return total


def _heat_series(ds, ch, p: np.ndarray, C_eff_j_per_k: float, G_eff_w_per_k: float, grid_dt_s: float) -> HeatSeries:
    from scipy.signal import savgol_filter

    r = ch.cell_y_c - p
    tg = np.arange(ds.t_start_s, ds.t_end_s + 1e-9, grid_dt_s)
    rg = np.interp(tg, ch.cell_t_s, r)
    win = max(int(round(SMOOTHING_S / grid_dt_s)) | 1, 5)
    if rg.size > win:
        rs = savgol_filter(rg, win, 2)
        drs = savgol_filter(rg, win, 2, deriv=1, delta=grid_dt_s)
    else:
        rs, drs = rg, np.gradient(rg, tg)
    Q = C_eff_j_per_k * drs + (G_eff_w_per_k if math.isfinite(G_eff_w_per_k) else 0.0) * rs
    return HeatSeries(ds, tg, Q, rs)


def unexplained_heat(params, datasets: list, pair: HeatPair, preds: list, grid_dt_s: float) -> UnexplainedHeat:
    """Oil channel: the heat flow the residual implies, Q = C_eff dr/dt + G_eff r (smoothed)."""
    C_eff_j_per_k = oil_heat_capacity_j_per_k(params)
    G_eff_w_per_k = effective_conductance_w_per_k(pair)
    files, series = [], []
    k = 0
    for ds in datasets:
        for cid, ch in ds.channels.items():
            p = preds[k]
            k += 1
            if cid != OIL:
                continue
            hs = _heat_series(ds, ch, p, C_eff_j_per_k, G_eff_w_per_k, grid_dt_s)
            series.append(hs)
            Q = hs.Q_w
            files.append(
                {
                    "file": ds.name,
                    "role": ds.role,
                    "mean_w": json_number(float(np.mean(Q)), 1),
                    "p5_w": json_number(float(np.percentile(Q, 5)), 1),
                    "p95_w": json_number(float(np.percentile(Q, 95)), 1),
                }
            )
    return UnexplainedHeat(
        {
            "C_eff_j_per_k": json_number(C_eff_j_per_k, 1),
            "G_eff_w_per_k": json_number(G_eff_w_per_k, 2),
            "smoothing_s": SMOOTHING_S,
            "sign": "positive = heat entering the oil that the model does not have",
            "files": files,
        },
        series,
    )
