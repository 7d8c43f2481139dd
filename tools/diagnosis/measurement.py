"""The measurement model of the diagnosis: what a sensor makes of the model's temperature, and its noise.

A first-order sensor lag (a nuisance of 0..sensor_lag_max_s per channel, never an effect), the averaging onto the
analysis grid, and the noise per sample from the high-frequency content of the residual (floored at the J1939
quantisation).
"""

from __future__ import annotations

import math

import numpy as np

from tools.diagnosis.options import J1939_RES_C, Options
from tools.diagnosis.prepare import Channel


def lag_filter(x: np.ndarray, tau_s: float, dt_s: float) -> np.ndarray:
    """First-order lag starting at the input's first value; exact when x[n] holds over (t[n-1], t[n]] (the plant's
    own oil-sensor lag uses the same convention)."""
    if tau_s <= 0 or x.size < 2:
        return x
    from scipy.signal import lfilter

    a = math.exp(-dt_s / tau_s)
    y, _ = lfilter([1 - a], [1, -a], x, zi=[a * x[0]])
    return y


def lag_filter_many(x: np.ndarray, taus: np.ndarray, dt_s: float) -> np.ndarray:
    """lag_filter for many time constants at once: (n_tau, n)."""
    out = np.empty((taus.size, x.size))
    for i, tau in enumerate(taus):
        out[i] = lag_filter(x, float(tau), dt_s)
    return out


def model_at_cells(out: dict, ch: Channel, tau_s: float, source: str | None = None) -> np.ndarray:
    """The model's prediction of channel `ch` on its grid cells, through a sensor lag `tau_s` (`source`: another
    model column than the channel's own)."""
    tm = out["time_s"]
    x = np.asarray(out[source or ch.model_column], dtype=float)
    dt = float(np.median(np.diff(tm))) if tm.size > 1 else 1.0
    if tau_s > 0:
        x = lag_filter(x, tau_s, dt)
    return np.interp(ch.cell_t_s, tm, x)


def raw_noise(ch: Channel, out: dict) -> float:
    """Per-sample noise from the high-frequency content of the residual (robust, floored at quantisation)."""
    r = ch.y_c - np.interp(ch.t_s, out["time_s"], out[ch.model_column])
    d = np.diff(r)
    dtt = np.diff(ch.t_s)
    d = d[dtt <= 3 * np.median(dtt)]
    q = J1939_RES_C / math.sqrt(12)
    if d.size < 5:
        return q
    s = 1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2)
    return float(max(s, q))


def highpass(x, n):
    """x minus its centred moving average over n cells."""
    if n < 3 or x.size < n:
        return x - x.mean()
    k = np.ones(n) / n
    pad = n // 2
    xp = np.pad(x, pad, mode="edge")
    return x - np.convolve(xp, k, mode="valid")[: x.size]


def noise_per_channel(datasets: list, outs: list) -> dict:
    """Per channel: the median per-sample noise over the files that measure it."""
    sigma = {}
    for cid in sorted({c for ds in datasets for c in ds.channels}):
        vals = [raw_noise(ds.channels[cid], out) for ds, out in zip(datasets, outs) if cid in ds.channels]
        sigma[cid] = float(np.median(vals))
    return sigma


def fit_nuisance_lags(train: list, base_tr: list, opts: Options) -> dict:
    """Per channel, the sensor lag (0..sensor_lag_max_s) that best matches the high-pass part of the training
    residual (slow model errors cannot pull it)."""
    from scipy.optimize import minimize_scalar

    n = max(int(60 / opts.grid_dt_s), 3)
    lag = {}
    for cid in sorted({c for ds in train for c in ds.channels}):
        items = []
        for ds, out in zip(train, base_tr):
            ch = ds.channels.get(cid)
            if ch is not None:
                tm = out["time_s"]
                items.append(
                    (
                        highpass(ch.cell_y_c, n),
                        ch.cell_t_s,
                        tm,
                        np.asarray(out[ch.model_column], float),
                        float(np.median(np.diff(tm))),
                    )
                )

        def cost(tau):
            return sum(
                float(np.sum((y - highpass(np.interp(ct, tm, lag_filter(x, tau, dt)), n)) ** 2))
                for y, ct, tm, x, dt in items  # noqa: B023 (called in this iteration)
            )

        taus = np.arange(0.0, opts.sensor_lag_max_s + 1e-9, 0.5)
        c = [cost(t) for t in taus]
        i = int(np.argmin(c))
        lo, hi = taus[max(i - 1, 0)], taus[min(i + 1, taus.size - 1)]
        best = float(taus[i])
        if hi > lo:
            r = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 0.02})
            if r.fun < c[i]:
                best = float(r.x)
        lag[cid] = round(best, 3)
    return lag
