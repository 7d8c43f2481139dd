"""How a model run is scored against the measurements: predictions on the grid cells with the nuisance sensor lags,
the initial-temperature nuisance solved per file, and the weighted misfit S."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from firmware_model.effects import effect_channel
from tools.diagnosis.measurement import lag_filter, model_at_cells
from tools.diagnosis.models import initial_shift_c
from tools.diagnosis.options import OIL, Options


def predictions(
    datasets: list,
    outs: list,
    lags: dict,
    effect: str | None = None,
    value: float | None = None,
    sens: list | None = None,
    start: tuple = (),
) -> list:
    """Predictions on cells per (dataset, channel) with the nuisance lags (the lag candidate replaces the oil
    nuisance by its own lag on the sump; the offset and gain candidates read the oil channel through them and, with
    `sens` (each entry's sensitivity to the initial temperature), start the model from the sump their reading implies,
    to first order; `start`: the (effect, value) the runs `outs` already started from, Run.start, so that only the
    difference is taken to first order)."""
    res, k = [], 0
    for i, ds in enumerate(datasets):
        shift_c = 0.0
        if sens is not None and OIL in ds.channels:
            shift_c = initial_shift_c(effect, value, ds.initial_temp_c) - (
                initial_shift_c(*start, ds.initial_temp_c) if start else 0.0
            )
        for cid, ch in ds.channels.items():
            if cid == OIL and effect == "oil_sensor_lag" and value:
                p = model_at_cells(outs[i], ch, value, source="T_oil_c")
            else:
                p = model_at_cells(outs[i], ch, lags.get(cid, 0.0))
            if shift_c:
                p = p + shift_c * sens[k]
            if cid == OIL and effect == "oil_sensor_offset" and value is not None:
                p = p + value  # the sensor reads the (lagged) sump plus an offset
            elif cid == OIL and effect == "oil_sensor_gain" and value is not None:
                p = p * value  # ... or gain x the sump in degC
            elif value is not None and effect_channel(effect) == cid:
                p = p + value  # a rig thermocouple reading its component plus an offset
            res.append(p)
            k += 1
    return res


def box_lsq(r: np.ndarray, w: np.ndarray, A: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple:
    """min_x sum w (r - A x)^2 with lo <= x <= hi (columns of A: at most two): (x, S). The unconstrained solution,
    else the best over each face with the other variable free (then clipped) and the corners."""
    k = A.shape[1]
    sw = np.sqrt(w)
    Aw, rw = A * sw[:, None], r * sw

    def S(x):
        return float(np.sum((rw - Aw @ x) ** 2))

    def ok(x):
        return bool(np.all(x >= lo - 1e-12) and np.all(x <= hi + 1e-12))

    cands = []
    x, *_ = np.linalg.lstsq(Aw, rw, rcond=None)
    if ok(x):
        return x, S(x)
    for j in range(k):  # one variable at a bound, the others free (then clipped)
        for b in (lo[j], hi[j]):
            free = [i for i in range(k) if i != j]
            xx = np.zeros(k)
            xx[j] = b
            if free:
                sub, *_ = np.linalg.lstsq(Aw[:, free], rw - Aw[:, j] * b, rcond=None)
                xx[free] = np.clip(sub, lo[free], hi[free])
            cands.append(xx)
    best = min(cands, key=S)
    return best, S(best)


def start_design(rd, idx: list, opts) -> tuple:
    """One file that starts running (tools/diagnosis/start.py), entries `idx` of role data `rd`: (its observations,
    weights, the sensitivities to both start nuisances (uniform, housings) as the columns of A, their box lo, hi),
    for :func:`box_lsq`."""
    y = np.concatenate([rd.obs[k] for k in idx])
    w = np.concatenate([np.broadcast_to(rd.w[k], rd.obs[k].shape) for k in idx])
    A = np.stack([np.concatenate([rd.sens[k] for k in idx]), np.concatenate([rd.sens_h[k] for k in idx])], 1)
    return (
        y,
        w,
        A,
        np.array([-opts.initial_offset_max_c, opts.housing_offset_lo_c]),
        np.array([opts.initial_offset_max_c, opts.housing_offset_hi_c]),
    )


def observations(datasets: list) -> list:
    """The measured cell values per (dataset, channel)."""
    return [ch.cell_y_c for ds in datasets for ch in ds.channels.values()]


def weights(datasets: list, sigma: dict, floor: dict, opts: Options) -> list:
    """Per (dataset, channel) cell: 1 / (noise of the cell mean + model error)."""
    w = []
    for ds in datasets:
        for cid, ch in ds.channels.items():
            s = sigma.get(cid, 0.1)
            f = floor.get(cid, opts.model_floor_c)
            w.append(1.0 / (s * s / ch.cell_n + f * f))
    return w


def misfit(preds: list, obs: list, w: list) -> float:
    """S: the weighted sum of squared residuals."""
    return float(sum(np.sum(wi * (yi - pi) ** 2) for pi, yi, wi in zip(preds, obs, w)))


def file_groups(datasets: list) -> list:
    """Per file: the indices of its (dataset, channel) entries."""
    grp, k = [], 0
    for ds in datasets:
        grp.append(list(range(k, k + len(ds.channels))))
        k += len(ds.channels)
    return grp


@dataclass(frozen=True)
class RoleData:
    """The measurements of the training or the test files, per (dataset, channel), and what scoring needs."""

    datasets: list
    obs: list  # measured cell values
    w: list  # weights
    sens: list  # sensitivity of each prediction to a uniform initial offset [K/K]
    files: list  # per file, the indices of its entries
    sens_h: list | None = None  # ... to the housings' start [K/K] (None: no file of this role starts running)


@dataclass(frozen=True)
class Scorer:
    """Scores model runs: predictions with the nuisance lags, the initial-temperature nuisance, the misfit."""

    train: RoleData
    test: RoleData
    lag: dict  # the nuisance sensor lag per channel (high-pass fit on the baseline)
    opts: Options

    def role(self, role: str) -> RoleData:
        return self.train if role == "train" else self.test

    def preds(
        self,
        datasets: list,
        outs: list,
        effect: str | None = None,
        value: float | None = None,
        lags: dict | None = None,
        start: tuple = (),
    ) -> list:
        rd = next((r for r in (self.train, self.test) if r.datasets is datasets), None)
        return predictions(
            datasets,
            outs,
            self.lag if lags is None else lags,
            effect,
            value,
            rd.sens if rd is not None else None,
            start,
        )

    def adjust(self, preds: list, role: str) -> list:
        """The initial temperature of every file is a nuisance (state, not model): shift each file's predictions by
        delta x (sensitivity to a uniform initial offset), delta by weighted least squares within
        +-initial_offset_max_c of the first reading; a file that starts running (tools/diagnosis/start.py) also by
        beta x (sensitivity to the housings' start), beta within housing_offset_lo_c..hi_c, jointly."""
        rd = self.role(role)
        sens, obs, w = rd.sens, rd.obs, rd.w
        out = list(preds)
        dmax = self.opts.initial_offset_max_c
        for f, idx in enumerate(rd.files):
            if rd.sens_h is not None and rd.datasets[f].start == "running":
                d, b = self._start_pair(preds, rd, idx)
                for k in idx:
                    out[k] = preds[k] + d * sens[k] + b * rd.sens_h[k]
                continue
            num = sum(float(np.sum(w[k] * (obs[k] - preds[k]) * sens[k])) for k in idx)
            den = sum(float(np.sum(w[k] * sens[k] ** 2)) for k in idx)
            d = min(max(num / den, -dmax), dmax) if den > 0 else 0.0
            for k in idx:
                out[k] = preds[k] + d * sens[k]
        return out

    def _start_pair(self, preds: list, rd: RoleData, idx: list) -> tuple:
        """(delta, beta) of one running file: the weighted least squares of both start nuisances in their box."""
        y, w, A, lo, hi = start_design(rd, idx, self.opts)
        x, _ = box_lsq(y - np.concatenate([preds[k] for k in idx]), w, A, lo, hi)
        return float(x[0]), float(x[1])

    def S(self, preds: list, role: str = "train") -> float:
        rd = self.role(role)
        return misfit(preds, rd.obs, rd.w)

    def S_adj(self, preds: list, role: str = "train") -> float:
        return self.S(self.adjust(preds, role), role)

    def refit_lags(self, outs: list, effect: str | None = None) -> dict:
        """The nuisance lags (0..sensor_lag_max_s) that minimise the full weighted misfit of a given model run on
        the training files, per channel (every model, the baseline included, is scored with its best nuisance
        lags)."""
        from scipy.optimize import minimize_scalar

        datasets, obs, w = self.train.datasets, self.train.obs, self.train.w
        lags = {}
        for cid in sorted({c for ds in datasets for c in ds.channels}):
            if cid == OIL and effect == "oil_sensor_lag":
                continue
            items = []
            k = 0
            for i, ds in enumerate(datasets):
                for c, ch in ds.channels.items():
                    if c == cid:
                        tm = outs[i]["time_s"]
                        items.append(
                            (
                                obs[k],
                                w[k],
                                ch.cell_t_s,
                                tm,
                                np.asarray(outs[i][ch.model_column], float),
                                float(np.median(np.diff(tm))),
                            )
                        )
                    k += 1

            def cost(tau):
                return sum(
                    float(np.sum(wk * (y - np.interp(ct, tm, lag_filter(x, tau, dt))) ** 2))
                    for y, wk, ct, tm, x, dt in items  # noqa: B023 (called in this iteration)
                )

            t0 = self.lag.get(cid, 0.0)
            lo, hi = max(t0 - 2.0, 0.0), min(t0 + 2.0, self.opts.sensor_lag_max_s)
            r = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 0.02})
            best = float(r.x) if r.fun <= cost(t0) else t0
            lags[cid] = round(best, 3)
        return lags
