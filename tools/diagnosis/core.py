"""Sim-to-real gap diagnosis: where the model misses, which unmodelled effect explains it, how far it shrinks.

Input: measured run tables (CONTRACTS section 3) or CAN logs with the oil sensor ``oil_temp_c`` and/or rig
thermocouples ``meas_T_<id>_c``, split into TRAINING and TEST files. Output: the gap-diagnosis JSON of CONTRACTS
section 4 (plus extra fields), see :func:`diagnose`. The method and the reasons behind each choice are in
docs/diagnosis.md; in short:

1. **Measurement model.** Each channel is averaged onto an analysis grid (`grid_dt_s`, default 2 s). The model
   predicts the node temperature, with three nuisances that are state or sensor, never an effect: a first-order
   sensor lag of 0..10 s per channel, the initial temperature of every file (+-0.25 K around the first reading,
   least squares on its sensitivity), and the model's own numerical error (the plant re-simulated with half the
   step), which floors the weights and the thresholds. Noise per sample comes from the high-frequency content of
   the residual, floored at the J1939 quantisation.
2. **Where.** Residual = measured - model, its square apportioned to operating regimes and episodes; for the oil it
   is inverted into the unexplained heat flow ``Q = C_eff d(r)/dt + G_eff r``.
3. **Which.** Every catalog effect is fitted on the training files: re-simulation at its bound(s) and midpoint(s),
   a quadratic spline in the parameter, a dense search, and a check of the minimum by re-simulation (refined where
   the surrogate was off). Ranked by ``score = -dBIC`` with an effective sample size from the residual's lag-1
   autocorrelation; confusable candidates and the measurement that separates them; identifiability per channel.
4. **Verdict.** "none", the best candidate, or "unexplained" (see :meth:`Diagnosis.run` and docs/diagnosis.md).
5. **Shrink.** RMS and max residual before/after on the TEST files only.
"""
from __future__ import annotations

import hashlib
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from firmware_model.effects import CATALOG, EFFECT_IDS
from firmware_model.errors import InputError

from tools.diagnosis.models import Q_OUT, Run
from tools.runtable import REQUIRED, RunTable, read_run_table, validate_run_table

SCHEMA = "gap-diagnosis/1"
J1939_RES_C = 0.03125
OIL = "oil"
INPUT_COLUMNS = ("time_s", "engine_speed_rpm", "engine_torque_nm", "gear", "ambient_temp_c", "coolant_temp_c",
                 "vehicle_speed_kmh", "retarder_torque_nm")
#: effects whose prediction is exact from the baseline (no simulation needed before the check)
ANALYTIC = ("oil_sensor_lag",)
LOG_SUFFIXES = (".log", ".asc", ".blf", ".mf4")


@dataclass
class Options:
    grid_dt_s: float = 2.0            # analysis grid
    plant_dt_s: float = 1.0           # re-simulation step of the plant
    out_dt_s: float = 1.0             # model output interval (before the nuisance lag and the grid)
    sensor_lag_max_s: float = 10.0    # normal sensor dynamics: a nuisance, never an effect
    model_floor_c: float = 0.05       # model error floor added to the noise in the weights
    initial_offset_max_c: float = 0.25  # the initial temperature nuisance: within this of the first reading
    none_k: float = 0.3               # "none" at once: systematic residual <= none_k x noise (per sample) ...
    none_floor_c: float = 0.03        # ... or this, on every channel
    gap_k: float = 1.0                # a real gap: systematic residual > gap_k x noise ...
    gap_floor_c: float = 0.1          # ... and this, on some channel
    ident_k: float = 0.5              # identifiable: the effect can move a channel by ident_k x noise (RMS)
    min_frac: float = 0.1             # a verdict's effect must sit >= 10 % of the way from neutral to its bound
    evidence_min: float = 10.0        # score (-dBIC) for strong evidence
    explain_min: float = 0.5          # share of the excess squared residual the verdict must explain
    confusable_corr: float = 0.95
    confusable_share: float = 0.1     # explained shares within this of the best
    refine: int = 2                   # refinement re-simulations per candidate
    coarse_grid: bool = True          # surrogate grid at the plant's coarse step (2 s), differences only
    dense: int = 161                  # dense parameter grid of the surrogate
    workers: int | None = None
    cold_c: float = 60.0
    max_time_gap_s: float = 60.0
    max_channel_gap_frac: float = 0.25


# ----------------------------------------------------------------------------------------------------------------
# input preparation

@dataclass
class Channel:
    id: str                 # 'oil' or component id
    column: str             # measured column
    model_column: str       # model column predicting it
    t: np.ndarray           # raw valid sample times
    y: np.ndarray           # raw valid values
    cell_t: np.ndarray = None
    cell_y: np.ndarray = None
    cell_n: np.ndarray = None


@dataclass
class Dataset:
    name: str
    role: str
    inputs: RunTable
    channels: dict
    initial_temp_c: float
    t_start: float
    t_end: float
    warnings: list = field(default_factory=list)


def channel_columns(table: RunTable) -> dict:
    out = {}
    if table.has("oil_temp_c"):
        out[OIL] = ("oil_temp_c", "oil_temp_c")
    for c in table.columns:
        if c.startswith("meas_T_") and c.endswith("_c"):
            cid = c[len("meas_T_"):-2]
            # a rig thermocouple in the sump is not the vehicle's oil sensor (no sensor lag effect on it)
            out[cid if cid != OIL else "oil@rig"] = (c, f"T_{cid}_c")
    return out


def load_table(path, config_path=None) -> RunTable:
    """A measured run table from a CSV file, or from a CAN log (candump -L .log, .asc, .blf, .mf4) decoded through
    the sensor's own CAN service (tools.can.replay_log): the decoded inputs, the oil sensor (TRF1) and the rig
    thermocouple frames (meas_T_<id>_c); the sensor's own estimates are dropped."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"{path}: no such file")
    if p.suffix.lower() in LOG_SUFFIXES:
        try:
            from firmware_model.service import build_service
            from tools.replay.log import is_can_log, replay_log
        except ImportError:
            raise InputError(f"{path}: CAN logs need the log decoder (tools/can/replay_log.py), which is not installed; "
                             f"convert the log to a CSV run table first") from None
        if not is_can_log(p):
            raise InputError(f"{path}: {p.suffix} logs are not supported; use .log, .asc, .blf or .mf4")
        rec = replay_log(p, build_service(config_path, record=True, emit_frames=False))
        keep = [c for c in INPUT_COLUMNS + ("oil_temp_c",) if rec.has(c)] + [
            c for c in rec.columns if c.startswith("meas_T_") and c.endswith("_c")]
        cols = {c: np.asarray(rec[c], dtype=float) for c in keep}
        # the first steps before every drive signal has arrived carry no input: drop them
        ok = np.ones(rec.n, dtype=bool)
        for c in REQUIRED:
            if c not in cols:
                raise InputError(f"{path}: the log never carries {c} (its J1939 message is missing or from another "
                                 f"source address); check the [can] section of the configuration")
            ok &= np.isfinite(cols[c])
        if not ok.any():
            raise InputError(f"{path}: no step of the log has engine speed, torque and gear together")
        first = int(np.argmax(ok))
        t = RunTable({c: v[first:] for c, v in cols.items()}, source=os.fspath(path))
        # a drive signal that drops out later is held (the sensor does the same)
        for c in REQUIRED[1:]:
            v = t[c]
            bad = ~np.isfinite(v)
            if bad.any():
                idx = np.maximum.accumulate(np.where(bad, 0, np.arange(v.size)))
                t[c] = v[idx]
        return t
    t = read_run_table(p)
    t.source = os.fspath(path)
    return t


def _fingerprint(table: RunTable) -> str:
    h = hashlib.sha1()
    for c in ("time_s", "engine_speed_rpm", "engine_torque_nm", "gear"):
        h.update(np.ascontiguousarray(table[c]).tobytes())
    for c, _ in channel_columns(table).values():
        h.update(np.ascontiguousarray(table[c]).tobytes())
    return h.hexdigest()


def _longest_nan_run(t, valid):
    """Longest time span [s] without a valid sample (start, length)."""
    tv = t[valid]
    if tv.size == 0:
        return t[0], t[-1] - t[0]
    edges = np.concatenate([[t[0]], tv, [t[-1]]])
    d = np.diff(edges)
    k = int(np.argmax(d))
    return float(edges[k]), float(d[k])


def prepare(table: RunTable, name: str, role: str, opts: Options, oil_is_input: bool = False) -> Dataset:
    """Validate a measured run table and put its channels on the analysis grid. Raises InputError (one sentence)."""
    validate_run_table(table, REQUIRED, name)
    t = np.asarray(table["time_s"], dtype=float)
    if t.size < 10:
        raise InputError(f"{name}: has only {t.size} rows; the diagnosis needs at least 10 samples")
    dt = np.diff(t)
    med = float(np.median(dt))
    gap_lim = max(opts.max_time_gap_s, 50 * med)
    k = int(np.argmax(dt))
    if dt[k] > gap_lim:
        raise InputError(f"{name}: column time_s jumps from {t[k]:.10g} s to {t[k + 1]:.10g} s (a gap of "
                         f"{dt[k]:.0f} s, more than {gap_lim:.0f} s); split the file at the gap")
    cols = channel_columns(table)
    if oil_is_input:
        cols.pop(OIL, None)
    if not cols:
        raise InputError(f"{name}: has no measured channel; the diagnosis needs oil_temp_c or a meas_T_<id>_c column "
                         f"to compare with the model")
    dur = t[-1] - t[0]
    channels = {}
    warn = []
    from firmware_model.components import PUBLISHED
    for cid, (col, mcol) in cols.items():
        if cid not in (OIL, "oil@rig") and cid not in PUBLISHED and cid not in ("H1", "H2", "H3"):
            raise InputError(f'{name}: column "{col}" names component "{cid}", which is not a component id of '
                             f"CONTRACTS section 5")
        y = np.asarray(table[col], dtype=float)
        if np.any(np.isinf(y)):
            raise InputError(f'{name}: column "{col}" row {int(np.flatnonzero(np.isinf(y))[0]) + 1}: infinite value')
        ok = np.isfinite(y)
        if not ok.any():
            raise InputError(f'{name}: column "{col}" has no valid value (a dead sensor); remove the column or fix '
                             f"the logging")
        if ok.sum() < max(10, 0.2 * y.size):
            raise InputError(f'{name}: column "{col}" has only {int(ok.sum())} valid values of {y.size} (a dead '
                             f"sensor); remove the column or fix the logging")
        yv = y[ok]
        if np.ptp(yv) <= J1939_RES_C * 1.01 and dur > 60:
            raise InputError(f'{name}: column "{col}" stays at {yv[0]:.5g} degC for the whole {dur:.0f} s (a stuck '
                             f"sensor); remove the column or the file")
        if np.any((yv < -60) | (yv > 300)):
            bad = yv[(yv < -60) | (yv > 300)][0]
            raise InputError(f'{name}: column "{col}" holds {bad:.5g} degC, outside -60..300 degC (not a plausible '
                             f"temperature)")
        g0, glen = _longest_nan_run(t, ok)
        if glen > max(opts.max_channel_gap_frac * dur, 300.0):
            raise InputError(f'{name}: column "{col}" has no valid value for {glen:.0f} s from t = {g0:.10g} s '
                             f"(more than a quarter of the run); cut the file or drop the column")
        # a sensor frozen for a long stretch while the rest of the run varies
        same = np.flatnonzero(np.diff(yv) != 0)
        tv = t[ok]
        if same.size:
            bounds = np.concatenate([[0], same + 1, [yv.size]])
            lens = tv[np.minimum(bounds[1:], yv.size) - 1] - tv[bounds[:-1]]
            j = int(np.argmax(lens))
            if lens[j] > max(600.0, 0.3 * dur):
                warn.append(f'column "{col}" is frozen at {yv[bounds[j]]:.5g} degC for {lens[j]:.0f} s from '
                            f"t = {tv[bounds[j]]:.0f} s")
        channels[cid] = Channel(cid, col, mcol, tv, yv)
    # initial temperature: the oil (or the mean of the measured channels) extrapolated to the start
    src = channels.get(OIL)
    if oil_is_input and table.has("oil_temp_c"):
        y = np.asarray(table["oil_temp_c"], dtype=float)
        ok = np.isfinite(y)
        src = Channel(OIL, "oil_temp_c", "oil_temp_c", t[ok], y[ok]) if ok.any() else None
    if src is None:
        src = min(channels.values(), key=lambda c: c.t[0])
    # the mean of the first 5 s (a first-order sensor starts at the sump's value); the remaining error is a
    # nuisance fitted per file (Diagnosis._adjust)
    sel = src.t <= src.t[0] + 5.0
    T0 = float(np.mean(src.y[sel])) if sel.any() else float(src.y[0])
    inputs = RunTable({c: table[c] for c in INPUT_COLUMNS if table.has(c)} |
                      ({"oil_temp_c": table["oil_temp_c"]} if oil_is_input and table.has("oil_temp_c") else {}) |
                      {c: table[c] for c in table.columns if c.startswith("bc_")},
                      meta={"initial_temp_c": T0})
    ds = Dataset(name, role, inputs, channels, T0, float(t[0]), float(t[-1]), warn)
    _grid(ds, opts.grid_dt_s)
    return ds


def _grid(ds: Dataset, grid_dt: float):
    for ch in ds.channels.values():
        k = np.floor((ch.t - ds.t_start) / grid_dt + 0.5).astype(np.int64)
        uk, inv, cnt = np.unique(k, return_inverse=True, return_counts=True)
        ch.cell_n = cnt.astype(float)
        ch.cell_t = np.bincount(inv, ch.t) / cnt
        ch.cell_y = np.bincount(inv, ch.y) / cnt


# ----------------------------------------------------------------------------------------------------------------
# prediction helpers

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


def _model_at_cells(out: dict, ch: Channel, tau_s: float, source: str | None = None) -> np.ndarray:
    tm = out["time_s"]
    x = np.asarray(out[source or ch.model_column], dtype=float)
    dt = float(np.median(np.diff(tm))) if tm.size > 1 else 1.0
    if tau_s > 0:
        x = lag_filter(x, tau_s, dt)
    return np.interp(ch.cell_t, tm, x)


def _raw_noise(ch: Channel, out: dict) -> float:
    """Per-sample noise from the high-frequency content of the residual (robust, floored at quantisation)."""
    r = ch.y - np.interp(ch.t, out["time_s"], out[ch.model_column])
    d = np.diff(r)
    dtt = np.diff(ch.t)
    d = d[dtt <= 3 * np.median(dtt)]
    q = J1939_RES_C / math.sqrt(12)
    if d.size < 5:
        return q
    s = 1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2)
    return float(max(s, q))


def _hp(x, n):
    """x minus its centred moving average over n cells."""
    if n < 3 or x.size < n:
        return x - x.mean()
    k = np.ones(n) / n
    pad = n // 2
    xp = np.pad(x, pad, mode="edge")
    return x - np.convolve(xp, k, mode="valid")[:x.size]


# ----------------------------------------------------------------------------------------------------------------
# regimes

PRIMARY = "range x torque"


def _gear_group(g):
    g = np.asarray(g)
    return np.where(g == 0, "neutral", np.where(g < 0, "reverse", np.where(g <= 8, "low range", "high range")))


def _torque_bin(tq):
    return np.where(tq < 0, "engine braking (torque < 0)", np.where(
        tq < 800, "torque 0-800 Nm", np.where(tq < 1500, "torque 800-1500 Nm", "torque > 1500 Nm")))


def _speed_bin(rpm):
    return np.where(rpm < 1000, "speed < 1000 rpm", np.where(rpm < 1400, "speed 1000-1400 rpm", np.where(
        rpm < 1800, "speed 1400-1800 rpm", "speed > 1800 rpm")))


def regime_labels(ds: Dataset, ch: Channel, base_out: dict, params, cooler: str, opts: Options) -> dict:
    """Partition name -> label per cell of channel `ch`."""
    from firmware_model.physics.kinematics import GEAR_NAMES
    tin = ds.inputs["time_s"]
    ct = ch.cell_t
    idx = np.clip(np.searchsorted(tin, ct, side="right") - 1, 0, tin.size - 1)
    gear = ds.inputs["gear"][idx].astype(int)
    tq = np.interp(ct, tin, ds.inputs["engine_torque_nm"])
    rpm = np.interp(ct, tin, ds.inputs["engine_speed_rpm"])
    lab = {PRIMARY: np.char.add(np.char.add(_gear_group(gear).astype(str), ", "), _torque_bin(tq).astype(str))}
    lab[PRIMARY] = np.where(gear == 0, "neutral", lab[PRIMARY])
    lab["gear"] = np.array([f"gear {GEAR_NAMES[int(g)]}" for g in gear])
    lab["engine speed"] = _speed_bin(rpm)
    lab["speed x torque"] = np.char.add(np.char.add(_speed_bin(rpm).astype(str), ", "), _torque_bin(tq).astype(str))
    # transient: a gear change or a torque step > 400 Nm in the last 60 s
    gi = ds.inputs["gear"]
    tqi = ds.inputs["engine_torque_nm"]
    change_t = tin[1:][np.diff(gi) != 0]
    last_change = np.full(ct.size, -np.inf)
    if change_t.size:
        j = np.searchsorted(change_t, ct, side="right") - 1
        last_change = np.where(j >= 0, change_t[np.maximum(j, 0)], -np.inf)
    # torque moving average over 60 s
    dtin = float(np.median(np.diff(tin))) if tin.size > 1 else 1.0
    n60 = max(int(60 / dtin), 1)
    tq_ma = np.convolve(np.pad(tqi, (n60 - 1, 0), mode="edge"), np.ones(n60) / n60, mode="valid")
    step = np.abs(tqi - tq_ma) > 400
    step_t = tin[step]
    last_step = np.full(ct.size, -np.inf)
    if step_t.size:
        j = np.searchsorted(step_t, ct, side="right") - 1
        last_step = np.where(j >= 0, step_t[np.maximum(j, 0)], -np.inf)
    trans = (ct - np.maximum(last_change, last_step)) < 60
    lab["transient / steady"] = np.where(trans, "transient (gear change or torque step in the last 60 s)", "steady")
    oil = np.interp(ct, base_out["time_s"], base_out["oil_temp_c"])
    if OIL in ds.channels:
        o = ds.channels[OIL]
        oil = np.interp(ct, o.t, o.y)
    lab["cold / warm"] = np.where(oil < opts.cold_c, f"cold (oil < {opts.cold_c:g} degC)", "warm")
    if ds.inputs.has("retarder_torque_nm"):
        ret = np.interp(ct, tin, np.nan_to_num(ds.inputs["retarder_torque_nm"]))
        lab["retarder"] = np.where(ret > 100, "retarder active", "retarder off")
    qc = np.interp(ct, base_out["time_s"], base_out.get("Q_out_cooler_w", np.zeros(base_out["time_s"].size)))
    if cooler == "air":
        to, tf = params["cooler.thermostat_open"], params["cooler.thermostat_full"]
        moil = np.interp(ct, base_out["time_s"], base_out["T_oil_c"])
        lab["cooler"] = np.where(moil < to, "thermostat closed", np.where(moil < tf, "thermostat opening",
                                                                           "thermostat open"))
    elif cooler == "liquid":
        lab["cooler"] = np.where(qc > 300, "cooler cooling", np.where(qc < -300, "cooler heating the oil",
                                                                      "cooler near balance"))
    return lab


# ----------------------------------------------------------------------------------------------------------------
# the engine

@dataclass
class _Fit:
    effect: str
    value: float
    S: float
    preds_train: list          # per (dataset, channel) arrays on cells (with nuisance)
    out_train: list            # per dataset model outputs at the fitted value (re-simulated)
    at_bound: bool
    surrogate_S: float = float("nan")
    grid: dict = field(default_factory=dict)   # value -> per-(ds,ch) predictions
    lags: dict = field(default_factory=dict)   # the nuisance sensor lags refitted for this model


class Diagnosis:
    """One diagnosis run. `run()` returns the JSON-ready dict."""

    def __init__(self, train, test, model, params, opts: Options | None = None, cooler: str | None = None,
                 progress=None, candidates=None):
        self.train, self.test = train, test
        self.model = model
        self.p = params
        self.o = opts or Options()
        self.cooler = cooler or params.strings.get("cooler.kind", "liquid")
        self.progress = progress or (lambda msg: None)
        self.candidates = list(candidates or EFFECT_IDS)
        self.timings = {}
        self.n_sims = 0

    # -- helpers ---------------------------------------------------------------------------------------------
    def _sim(self, datasets, runs):
        cols = sorted({ch.model_column for ds in datasets for ch in ds.channels.values()})
        t0 = time.perf_counter()
        out = self.model.simulate(datasets, runs, cols)
        self.n_sims += len(runs) * len(datasets)
        self.timings["simulate_s"] = self.timings.get("simulate_s", 0.0) + time.perf_counter() - t0
        return out

    def _pairs(self, datasets):
        return [(i, cid) for i, ds in enumerate(datasets) for cid in ds.channels]

    def _preds(self, datasets, outs, effect=None, value=None, lags=None):
        """Predictions on cells per (dataset, channel) with the nuisance lags (the lag candidate replaces the oil
        nuisance by its own lag on the sump)."""
        lags = self.lag if lags is None else lags
        res = []
        for i, ds in enumerate(datasets):
            for cid, ch in ds.channels.items():
                if cid == OIL and effect == "oil_sensor_lag" and value:
                    res.append(_model_at_cells(outs[i], ch, value, source="T_oil_c"))
                else:
                    res.append(_model_at_cells(outs[i], ch, lags.get(cid, 0.0)))
        return res

    def _refit_lags(self, datasets, outs, obs, w, effect=None):
        """The nuisance lags (0..sensor_lag_max_s) that minimise the full weighted misfit of a given model run, per
        channel (every model, the baseline included, is scored with its best nuisance lags)."""
        from scipy.optimize import minimize_scalar
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
                        items.append((obs[k], w[k], ch.cell_t, tm, np.asarray(outs[i][ch.model_column], float),
                                      float(np.median(np.diff(tm)))))
                    k += 1

            def cost(tau):
                return sum(float(np.sum(wk * (y - np.interp(ct, tm, lag_filter(x, tau, dt))) ** 2))
                           for y, wk, ct, tm, x, dt in items)
            t0 = self.lag.get(cid, 0.0)
            lo, hi = max(t0 - 2.0, 0.0), min(t0 + 2.0, self.o.sensor_lag_max_s)
            r = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 0.02})
            best = float(r.x) if r.fun <= cost(t0) else t0
            lags[cid] = round(best, 3)
        return lags

    def _weights(self, datasets):
        w = []
        for ds in datasets:
            for cid, ch in ds.channels.items():
                s = self.sigma.get(cid, 0.1)
                f = self.floor.get(cid, self.o.model_floor_c)
                w.append(1.0 / (s * s / ch.cell_n + f * f))
        return w

    @staticmethod
    def _obs(datasets):
        return [ch.cell_y for ds in datasets for ch in ds.channels.values()]

    def _S(self, preds, obs, w):
        return float(sum(np.sum(wi * (yi - pi) ** 2) for pi, yi, wi in zip(preds, obs, w)))

    def _adjust(self, preds, role):
        """The initial temperature of every file is a nuisance (state, not model): shift each file's predictions by
        delta x (sensitivity to a uniform initial offset), delta by weighted least squares within
        +-initial_offset_max_c of the first reading."""
        sens, grp = self._sens[role]
        obs, w = self._obs_w[role]
        out = list(preds)
        dmax = self.o.initial_offset_max_c
        for idx in grp:
            num = sum(float(np.sum(w[k] * (obs[k] - preds[k]) * sens[k])) for k in idx)
            den = sum(float(np.sum(w[k] * sens[k] ** 2)) for k in idx)
            d = min(max(num / den, -dmax), dmax) if den > 0 else 0.0
            for k in idx:
                out[k] = preds[k] + d * sens[k]
        return out

    def _S_adj(self, preds, role="train"):
        obs, w = self._obs_w[role]
        return self._S(self._adjust(preds, role), obs, w)

    # -- main ------------------------------------------------------------------------------------------------
    def run(self) -> dict:
        T = time.perf_counter()
        o = self.o
        train, test = self.train, self.test
        self.progress("baseline and candidate grid")
        # one batch per file: the baseline, a 2 K warmer start (initial-temperature sensitivity; the oil's effective
        # conductance to the outside), the baseline at half the step (the model's own numerical error, plant only)
        # and the candidates' grid (bounds, at the coarse step where the backend has one)
        is_plant = self.model.name == "plant"
        head = [Run.of(), Run.of(initial_offset_c=2.0)] + ([Run.of(fine=True)] if is_plant else [])
        self._grid_runs, self._grid_keys = self._grid_plan()
        out_tr = self._sim(train, head + self._grid_runs)
        out_te = self._sim(test, head[:2])
        base_tr, pert_tr = out_tr[0], out_tr[1]
        fine_tr = out_tr[2] if is_plant else None
        self._grid_outs = out_tr[len(head):]
        base_te, pert_te = out_te[0], out_te[1]
        pert = pert_tr + pert_te
        if is_plant:
            pert_pair = (base_tr, pert_tr)
        elif getattr(self.model, "fallback", None) is not None:
            pp = self.model.fallback.simulate(train[:1], [Run.of(), Run.of(initial_offset_c=2.0)], [])
            self.n_sims += 2
            pert_pair = (pp[0], pp[1])
        else:
            pert_pair = ([], [])
        # noise per channel (pooled median over the training files), nuisance lags
        self.sigma = {}
        for cid in sorted({c for ds in train + test for c in ds.channels}):
            vals = [_raw_noise(ds.channels[cid], out) for ds, out in zip(train + test, base_tr + base_te)
                    if cid in ds.channels]
            self.sigma[cid] = float(np.median(vals))
        self.lag = self._fit_nuisance_lags(train, base_tr)
        self._base_tr = base_tr
        # model error floor per channel: the numerical error of the step (BDF2: error ~ dt^2, so the full step's
        # error is about 4/3 of its difference to the half step), at least model_floor_c
        self.floor = {c: o.model_floor_c for c in self.sigma}
        if fine_tr is not None:
            pb, pf = self._preds(train, base_tr), self._preds(train, fine_tr)
            acc = {}
            for (cid, _), a, b in zip([(c, h) for ds in train for c, h in ds.channels.items()], pb, pf):
                x = acc.setdefault(cid, [0.0, 0])
                x[0] += float(np.sum((a - b) ** 2))
                x[1] += a.size
            for cid, (ss, n) in acc.items():
                self.floor[cid] = max(o.model_floor_c, 4.0 / 3.0 * math.sqrt(ss / max(n, 1)))
        obs_tr, w_tr = self._obs(train), self._weights(train)
        obs_te, w_te = self._obs(test), self._weights(test)
        # sensitivity of every prediction to the initial temperature (nuisance per file, see _adjust)
        self._sens = {}
        for role, dsets, b, pt in (("train", train, base_tr, pert[:len(train)]), ("test", test, base_te,
                                                                                  pert[len(train):])):
            sb, sp = self._preds(dsets, b), self._preds(dsets, pt)
            grp, k = [], 0
            for ds in dsets:
                grp.append(list(range(k, k + len(ds.channels))))
                k += len(ds.channels)
            self._sens[role] = ([(q - p) / 2.0 for p, q in zip(sb, sp)], grp)
        self._obs_w = {"train": (obs_tr, w_tr), "test": (obs_te, w_te)}
        self.lag0 = self._refit_lags(train, base_tr, obs_tr, w_tr)
        p0_tr = self._adjust(self._preds(train, base_tr, lags=self.lag0), "train")
        p0_te = self._adjust(self._preds(test, base_te, lags=self.lag0), "test")
        S0 = self._S(p0_tr, obs_tr, w_tr)
        # noise-expected part of S (for the explained share of the excess)
        S_noise = float(sum(np.sum(wi * (self.sigma[cid] ** 2 / ch.cell_n + self.floor[cid] ** 2))
                            for wi, (cid, ch) in zip(w_tr, [(c, h) for ds in train for c, h in ds.channels.items()])))
        # ---- where
        self.progress("where")
        where, where_by, episodes = self._where(train, base_tr, p0_tr, obs_tr)
        heat = self._unexplained_heat(train + test, pert_pair, p0_tr + p0_te)
        # ---- which
        self.progress("fit")
        self._p0_hp = self._preds(train, base_tr)
        fits = self._fit_all(train, base_tr, self._p0_hp, obs_tr, w_tr)
        # test re-simulation of every candidate at its fitted value
        self.progress("test")
        moved = [f for f in fits if f.value != CATALOG[f.effect].neutral]
        touts_m = dict(zip([f.effect for f in moved], self._sim(test, [Run.of({f.effect: f.value}) for f in moved])))
        touts = [touts_m.get(f.effect, base_te) for f in fits]
        # ---- criterion
        N = sum(p.size for p in p0_tr)
        best = min(fits, key=lambda f: f.S)
        resid_best = [y - p for y, p in zip(obs_tr, best.preds_train)]
        n_eff, rho = self._n_eff(train, resid_best)
        cands = []
        for f, tout in zip(fits, touts):
            dbic = n_eff * math.log(max(f.S, 1e-12) / max(S0, 1e-12)) + 1.0 * math.log(max(n_eff, 2.0))
            p_te = self._adjust(self._preds(test, tout, f.effect, f.value, lags=f.lags), "test")
            explained = (S0 - f.S) / max(S0 - S_noise, 0.02 * S0, 1e-12)
            cands.append({"fit": f, "score": -dbic, "explained": float(explained), "p_te": p_te, "tout": tout})
        cands.sort(key=lambda c: -c["score"])
        # signatures for confusability (weighted, pooled over channels)
        sigs = {}
        for c in cands:
            f = c["fit"]
            sigs[f.effect] = np.concatenate([np.sqrt(wi) * (pf - p0) for pf, p0, wi in zip(f.preds_train, p0_tr, w_tr)])
        # ---- identifiability
        ident = self._identifiability(train, fits, self._p0_hp)
        # ---- verdict
        self.progress("verdict")
        sys_rms, thr = self._systematic(train, obs_tr, p0_tr)
        gap_thr = {c: max(o.gap_k * self.sigma[c], o.gap_floor_c, 2.0 * self.floor[c]) for c in sys_rms}
        top = cands[0]
        f = top["fit"]
        e = CATALOG[f.effect]
        bound = e.high if f.value >= e.neutral else e.low
        frac = (f.value - e.neutral) / (bound - e.neutral) if bound != e.neutral else 0.0
        post = self._systematic(train, obs_tr, f.preds_train)[0]
        gap_left = any(post[c] > gap_thr[c] for c in post)
        real_gap = [c for c in sys_rms if sys_rms[c] > gap_thr[c]]
        conf_top = []
        why_not = ""
        if all(sys_rms[c] <= thr[c] for c in sys_rms):
            verdict = "none"
            reason = ("the model agrees with the measurement within its noise on every channel (systematic residual "
                      + ", ".join(f"{c} {sys_rms[c]:.3f} <= {thr[c]:.3f} degC" for c in sys_rms) + ")")
        else:
            if top["score"] < o.evidence_min:
                why_not = (f"no candidate has strong evidence (best {f.effect}: score {top['score']:.1f} < "
                           f"{o.evidence_min:g})")
            elif top["explained"] < o.explain_min:
                why_not = (f"the best candidate {f.effect} explains only {100 * top['explained']:.0f} % of the "
                           f"excess squared residual (< {100 * o.explain_min:.0f} %)")
            elif abs(frac) < o.min_frac:
                why_not = (f"the best candidate {f.effect} fits at {e.param} = {f.value:g} {e.unit}, only "
                           f"{100 * abs(frac):.0f} % of the way from neutral to its bound (< {100 * o.min_frac:.0f} %)")
            elif f.at_bound and gap_left:
                why_not = (f"the best candidate {f.effect} sits at the bound of its plausible range ({e.param} = "
                           f"{f.value:g} {e.unit}) and a gap remains")
            if not why_not:
                verdict = f.effect
                reason = (f"{f.effect} has the strongest evidence (score {top['score']:.0f}) and explains "
                          f"{100 * min(top['explained'], 1.0):.0f} % of the excess squared residual")
                if gap_left:
                    reason += ("; a gap remains after it (systematic residual " + ", ".join(
                        f"{c} {post[c]:.3f} > {gap_thr[c]:.3f} degC" for c in post if post[c] > gap_thr[c])
                        + "): a second effect, or one outside the catalog")
            elif real_gap:
                verdict = "unexplained"
                reason = (why_not + "; a real gap remains (systematic residual " + ", ".join(
                    f"{c} {sys_rms[c]:.3f} > {gap_thr[c]:.3f} degC" for c in real_gap) + ")")
            else:
                verdict = "none"
                reason = (why_not + "; the systematic residual stays below the measurement noise (" + ", ".join(
                    f"{c} {sys_rms[c]:.3f} <= {gap_thr[c]:.3f} degC" for c in sys_rms) + ")")
        # confusable with the top candidate (and pairwise for the others)
        for c in cands:
            c["confusable_with"] = []
        for i, a in enumerate(cands):
            for b in cands[i + 1:]:
                if self._confusable(a, b, sigs):
                    a["confusable_with"].append(b["fit"].effect)
                    b["confusable_with"].append(a["fit"].effect)
        # measurement suggestions for the verdict's confusable group
        suggestions = []
        if verdict not in ("none", "unexplained"):
            conf_top = list(cands[0]["confusable_with"])
            for other in conf_top:
                oc = next(c for c in cands if c["fit"].effect == other)
                suggestions.append(self._suggest(train, cands[0]["fit"], oc["fit"]))
        # ---- test shrink
        chan_ids = sorted({c for ds in train + test for c in ds.channels}, key=lambda c: (c != OIL, c))
        res_te0 = [y - p for y, p in zip(obs_te, p0_te)]
        if verdict in ("none", "unexplained"):
            res_te1 = res_te0
        else:
            res_te1 = [y - p for y, p in zip(obs_te, cands[0]["p_te"])]
        rms_b, rms_a = _pooled_rms(res_te0), _pooled_rms(res_te1)
        shrink = 1.0 - rms_a / rms_b if rms_b > 0 else 0.0
        # ---- assemble
        pairs_tr = [(ds, cid) for ds in train for cid in ds.channels]
        pairs_te = [(ds, cid) for ds in test for cid in ds.channels]
        res_tr0 = [y - p for y, p in zip(obs_tr, p0_tr)]
        res_tr1 = res_tr0 if verdict in ("none", "unexplained") else [y - p for y, p in zip(obs_tr, cands[0]["fit"].preds_train)]
        channels = {}
        for cid in chan_ids:
            def sel(res, pairs):
                return [r for r, (ds, c) in zip(res, pairs) if c == cid]
            a, b, c_, d = sel(res_tr0, pairs_tr), sel(res_te0, pairs_te), sel(res_tr1, pairs_tr), sel(res_te1, pairs_te)
            channels[cid] = {"train_rms_c": _r(_pooled_rms(a)), "train_max_c": _r(_max_abs(a)),
                             "test_rms_c": _r(_pooled_rms(b)), "test_max_c": _r(_max_abs(b)),
                             "train_rms_after_c": _r(_pooled_rms(c_)), "test_rms_after_c": _r(_pooled_rms(d)),
                             "test_max_after_c": _r(_max_abs(d)),
                             "noise_c": _r(self.sigma.get(cid, float("nan"))),
                             "model_error_c": _r(self.floor.get(cid, float("nan"))),
                             "systematic_train_c": _r(sys_rms.get(cid, float("nan"))),
                             "none_threshold_c": _r(thr.get(cid, float("nan"))),
                             "gap_threshold_c": _r(gap_thr.get(cid, float("nan"))),
                             "sensor_lag_s": _r(self.lag0.get(cid, 0.0)),
                             "column": "oil_temp_c" if cid == OIL else f"meas_T_{cid}_c"}
        cand_json = []
        for c in cands:
            f = c["fit"]
            e = CATALOG[f.effect]
            res_e_te = [y - p for y, p in zip(obs_te, c["p_te"])]
            res_e_tr = [y - p for y, p in zip(obs_tr, f.preds_train)]
            cand_json.append({
                "effect": f.effect, "parameters": {e.param: _r(f.value, 6)},
                "train_rms_before_c": _r(_pooled_rms(res_tr0)), "train_rms_after_c": _r(_pooled_rms(res_e_tr)),
                "test_rms_before_c": _r(rms_b), "test_rms_after_c": _r(_pooled_rms(res_e_te)),
                "score": _r(c["score"], 3), "confusable_with": list(c["confusable_with"]),
                "explained_share": _r(min(max(c["explained"], -1.0), 1.0), 4), "at_bound": bool(f.at_bound), "unit": e.unit,
                "range": [e.low, e.high], "identifiable": ident[f.effect]["identifiable"],
                "backend": self._backend_of(f.effect)})
        test_regimes = self._test_regimes(test, base_te, res_te0, res_te1)
        out = {
            "schema": SCHEMA,
            "train": [ds.name for ds in train], "test": [ds.name for ds in test],
            "channels": channels,
            "where": where,
            "candidates": cand_json,
            "verdict": {"effect": verdict, "test_rms_before_c": _r(rms_b), "test_rms_after_c": _r(rms_a),
                        "shrink": _r(shrink, 4), "reason": reason,
                        "test_max_before_c": _r(_max_abs(res_te0)), "test_max_after_c": _r(_max_abs(res_te1)),
                        **({"parameters": cand_json[0]["parameters"], "confusable_with": conf_top,
                            "remaining_gap_c": {c: _r(post[c]) for c in post if post[c] > gap_thr[c]}}
                           if verdict not in ("none", "unexplained") else {}),
                        **({"closest_candidate": cand_json[0]["effect"]} if verdict == "unexplained" else {})},
            "where_by": where_by,
            "episodes": episodes,
            "test_regimes": test_regimes,
            "unexplained_heat": heat,
            "identifiability": ident,
            "measurement_suggestions": suggestions,
            "criterion": {"name": "BIC with effective sample size", "n": int(N), "n_eff": _r(n_eff, 2),
                          "rho_lag1": {k: _r(v, 4) for k, v in rho.items()}, "grid_dt_s": o.grid_dt_s,
                          "S_baseline": _r(S0, 3), "S_expected_noise_and_model_error": _r(S_noise, 3),
                          "evidence_min": o.evidence_min, "explain_min": o.explain_min,
                          "score": "score = -dBIC = -(n_eff ln(S_effect/S_baseline) + k ln n_eff), k = 1"},
            "model": self.model.describe(),
            "cooler": self.cooler,
            "warnings": [f"{ds.name}: {w}" for ds in train + test for w in ds.warnings],
            "timing": {"total_s": _r(time.perf_counter() - T, 2), "simulate_s": _r(self.timings.get("simulate_s", 0), 2),
                       "simulations": self.n_sims},
        }
        self._plotdata = {"train": train, "test": test, "base_tr": base_tr, "base_te": base_te, "p0_tr": p0_tr,
                          "p0_te": p0_te, "obs_tr": obs_tr, "obs_te": obs_te, "cands": cands, "verdict": verdict,
                          "heat": heat, "where_by": where_by}
        return out

    # -- pieces -----------------------------------------------------------------------------------------------
    def _backend_of(self, eid):
        delegated = getattr(self.model, "delegated", [])
        if self.model.name == "onboard" and eid in delegated:
            return "plant (fallback)"
        return self.model.name

    def _fit_nuisance_lags(self, train, base_tr):
        """Per channel, the sensor lag (0..sensor_lag_max_s) that best matches the high-pass part of the training
        residual (slow model errors cannot pull it)."""
        from scipy.optimize import minimize_scalar
        n = max(int(60 / self.o.grid_dt_s), 3)
        lag = {}
        for cid in sorted({c for ds in train for c in ds.channels}):
            items = []
            for ds, out in zip(train, base_tr):
                ch = ds.channels.get(cid)
                if ch is not None:
                    tm = out["time_s"]
                    items.append((_hp(ch.cell_y, n), ch.cell_t, tm, np.asarray(out[ch.model_column], float),
                                  float(np.median(np.diff(tm)))))

            def cost(tau):
                return sum(float(np.sum((y - _hp(np.interp(ct, tm, lag_filter(x, tau, dt)), n)) ** 2))
                           for y, ct, tm, x, dt in items)
            taus = np.arange(0.0, self.o.sensor_lag_max_s + 1e-9, 0.5)
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

    def _n_eff(self, datasets, resid):
        rho_ch = {}
        n_eff = 0.0
        k = 0
        for ds in datasets:
            for cid, ch in ds.channels.items():
                r = resid[k] - resid[k].mean()
                k += 1
                den = float(np.dot(r, r))
                rho = float(np.dot(r[1:], r[:-1]) / den) if den > 0 and r.size > 2 else 0.0
                rho = min(max(rho, 0.0), 0.999)
                rho_ch.setdefault(cid, []).append(rho)
                n_eff += r.size * (1 - rho) / (1 + rho)
        return max(n_eff, 2.0), {c: float(np.mean(v)) for c, v in rho_ch.items()}

    def _systematic(self, datasets, obs, preds):
        """Per channel: RMS of the residual with the noise removed, and the 'none' threshold."""
        acc = {}
        k = 0
        for ds in datasets:
            for cid, ch in ds.channels.items():
                r = obs[k] - preds[k]
                k += 1
                a = acc.setdefault(cid, [0.0, 0.0, 0])
                a[0] += float(np.sum(r ** 2))
                a[1] += float(np.sum(self.sigma[cid] ** 2 / ch.cell_n))
                a[2] += r.size
        sys_rms = {c: math.sqrt(max(a[0] - a[1], 0.0) / max(a[2], 1)) for c, a in acc.items()}
        thr = {c: max(self.o.none_k * self.sigma[c], self.o.none_floor_c, self.floor[c]) for c in acc}
        return sys_rms, thr

    def _grid_plan(self):
        """The grid runs of every candidate: its bound(s) and the midpoint(s) towards them; the coarse plant baseline
        first."""
        coarse = bool(self.o.coarse_grid) and self.model.name == "plant"
        runs, keys = ([Run.of(coarse=True)], [None]) if coarse else ([], [])
        for eid in self.candidates:
            if eid in ANALYTIC:
                continue
            e = CATALOG[eid]
            for v in self._grid_values(eid):
                if v != e.neutral:
                    runs.append(Run.of({eid: v}, coarse=coarse))
                    keys.append((eid, v))
        return runs, keys

    def _grid_values(self, eid):
        e = CATALOG[eid]
        vals = [e.neutral]
        for bound in (e.low, e.high):
            if bound == e.neutral:
                continue
            # the bound and the midpoint: responses can be far from linear (at 8 L the oil level changes which
            # wheels dip; the thermostat acts only above its opening temperature)
            vals += [bound, e.neutral + 0.5 * (bound - e.neutral)]
        return sorted(set(vals))

    def _fit_all(self, train, base_tr, p0_tr, obs_tr, w_tr):
        o = self.o
        grids = {}
        # stage 1: the grid re-simulations (run with the baseline, see run() and _grid_plan)
        coarse = bool(o.coarse_grid) and self.model.name == "plant"
        for eid in self.candidates:
            grids[eid] = {CATALOG[eid].neutral: p0_tr}
        outs, keys = list(self._grid_outs), list(self._grid_keys)
        ref = None
        if coarse and outs:
            ref = self._preds(train, outs[0])
            outs, keys = outs[1:], keys[1:]
        for (eid, v), out in zip(keys, outs):
            pr = self._preds(train, out, eid, v)
            if ref is not None:
                pr = [p0 + (p - r0) for p0, p, r0 in zip(p0_tr, pr, ref)]
            grids[eid][v] = pr
        # surrogate optimum per effect, then re-simulate; refine the competitive ones where surrogate and
        # re-simulation disagree
        state = {eid: {"value": None, "checked": {}} for eid in self.candidates}
        for it in range(o.refine + 1):
            runs, keys = [], []
            if it > 0:
                S0h = self._S_adj(p0_tr)
                ranked = sorted(self.candidates, key=lambda e: min([s[0] for s in state[e]["checked"].values()]
                                                                   + [S0h]))
                for eid in ranked[4:]:
                    state[eid]["done"] = True
            for eid in self.candidates:
                st = state[eid]
                if st.get("done"):
                    continue
                v, s_pred = self._surrogate_min(eid, grids[eid], train, base_tr, obs_tr, w_tr)
                st["value"], st["surrogate_S"] = v, s_pred
                if v in st["checked"] or v == CATALOG[eid].neutral:
                    st["done"] = True       # the neutral value is the baseline: nothing to check
                    continue
                runs.append(Run.of({eid: v}))
                keys.append(eid)
            if not runs:
                break
            outs = self._sim(train, runs)
            for eid, out in zip(keys, outs):
                st = state[eid]
                v = st["value"]
                pr = self._preds(train, out, eid, v)
                S = self._S_adj(pr)
                st["checked"][v] = (S, pr, out)
                if eid not in ANALYTIC:
                    grids[eid][v] = pr
                # converged when the surrogate predicted the re-simulated misfit within 2 % (+ noise level)
                tol = 0.02 * S + 1.0
                if abs(S - st["surrogate_S"]) <= tol or eid in ANALYTIC:
                    st["done"] = True
        res = []
        for eid in self.candidates:
            st = state[eid]
            # the best re-simulated value, each scored with its own best nuisance lags; the neutral value (the
            # baseline) competes too, so that a candidate never scores below the unmodified model
            e = CATALOG[eid]
            best = None
            pool = dict(st["checked"])
            pool.setdefault(e.neutral, (None, None, base_tr))
            for v_, (_, _, out_) in sorted(pool.items(), key=lambda kv: kv[1][0] if kv[1][0] is not None else -1)[:2]:
                lags_ = self._refit_lags(train, out_, obs_tr, w_tr, eid if v_ != e.neutral else None)
                pr_ = self._adjust(self._preds(train, out_, eid if v_ != e.neutral else None, v_, lags=lags_),
                                   "train")
                S_ = self._S(pr_, obs_tr, w_tr)
                if best is None or S_ < best[0]:
                    best = (S_, v_, pr_, out_, lags_)
            S, v, pr, out, lags = best
            span = e.high - e.low
            at_bound = (abs(v - e.low) < 0.02 * span and e.low != e.neutral) or (
                abs(v - e.high) < 0.02 * span and e.high != e.neutral)
            f = _Fit(eid, float(v), S, pr, out, bool(at_bound), st.get("surrogate_S", float("nan")), grids[eid])
            f.lags = lags
            res.append(f)
        return res

    def _surrogate_min(self, eid, grid, train, base_tr, obs_tr, w_tr):
        e = CATALOG[eid]
        dense = np.linspace(e.low, e.high, self.o.dense)
        if eid in ANALYTIC:
            # oil_sensor_lag: exact filter of the model's sump temperature; other channels unaffected
            from scipy.optimize import minimize_scalar
            base_p = self._preds(train, base_tr)

            def cost(tau):
                return self._S_adj(self._preds(train, base_tr, eid, tau) if tau else base_p)
            dense = np.unique(np.concatenate([np.linspace(0, min(20.0, e.high), 41), dense]))
            c = np.array([cost(t) for t in dense])
            i = int(np.argmin(c))
            lo, hi = dense[max(i - 1, 0)], dense[min(i + 1, dense.size - 1)]
            best, bS = float(dense[i]), float(c[i])
            if hi > lo:
                r = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 0.02})
                if r.fun < bS:
                    best, bS = float(r.x), float(r.fun)
            return round(best, 3), bS
        from scipy.interpolate import make_interp_spline
        xs = np.array(sorted(grid))
        kk = min(2, xs.size - 1)
        S = np.zeros(dense.size)
        sens, grp = self._sens["train"]
        dmax = self.o.initial_offset_max_c
        for idx in grp:
            # per file: S(theta) with the initial-temperature nuisance solved in closed form
            raw = np.zeros(dense.size)
            num = np.zeros(dense.size)
            den = 0.0
            for k in idx:
                Y = np.array([grid[x][k] for x in xs])
                P = make_interp_spline(xs, Y, k=kk, axis=0)(dense)
                R = obs_tr[k] - P
                raw += np.sum(w_tr[k] * R ** 2, axis=1)
                num += np.sum(w_tr[k] * R * sens[k], axis=1)
                den += float(np.sum(w_tr[k] * sens[k] ** 2))
            d = np.clip(num / den, -dmax, dmax) if den > 0 else np.zeros(dense.size)
            S += raw - 2 * d * num + d * d * den
        i = int(np.argmin(S))
        v = float(dense[i])
        # snap to a simulated point when it is within one dense step
        step = dense[1] - dense[0]
        near = xs[np.argmin(np.abs(xs - v))]
        if abs(near - v) < 0.51 * step:
            v = float(near)
        return v, float(S[i])

    def _confusable(self, a, b, sigs):
        if a["score"] < self.o.evidence_min or b["score"] < self.o.evidence_min:
            return False
        sa, sb = sigs[a["fit"].effect], sigs[b["fit"].effect]
        na, nb = np.linalg.norm(sa), np.linalg.norm(sb)
        if na == 0 or nb == 0:
            return False
        corr = float(np.dot(sa, sb) / (na * nb))
        a["corr_" + b["fit"].effect] = corr
        return corr >= self.o.confusable_corr and abs(a["explained"] - b["explained"]) <= self.o.confusable_share

    def _identifiability(self, train, fits, p0_tr):
        """Per effect: the largest RMS change its parameter can make on each channel over its range (from the
        grid re-simulations) against the 'none' threshold; identifiable when some channel sees it, and from which
        magnitude on."""
        thr = {c: max(self.o.ident_k * self.sigma[c], self.o.none_floor_c, self.floor[c]) for c in self.sigma}
        pairs = [(cid, ch) for ds in train for cid, ch in ds.channels.items()]
        out = {}
        for f in fits:
            e = CATALOG[f.effect]
            grid = dict(f.grid)
            if f.effect in ANALYTIC:
                # the lag half-way and at its bound, exact on the baseline sump
                grid = {v: self._preds(train, self._base_tr, f.effect, v) for v in (0.5 * e.high, e.high)}
            per_ch = {}
            frac_min = None
            for v, preds in grid.items():
                if v == e.neutral:
                    continue
                span = (e.high if v > e.neutral else e.low) - e.neutral
                frac = (v - e.neutral) / span if span else 0.0
                acc = {}
                for (cid, ch), p, p0 in zip(pairs, preds, p0_tr):
                    a = acc.setdefault(cid, [0.0, 0])
                    a[0] += float(np.sum((p - p0) ** 2))
                    a[1] += p.size
                for cid, a in acc.items():
                    rms = math.sqrt(a[0] / max(a[1], 1))
                    per_ch[cid] = max(per_ch.get(cid, 0.0), rms)
                    if rms >= thr[cid] and (frac_min is None or frac < frac_min):
                        frac_min = frac
            seen = {c: (per_ch.get(c, 0.0) >= thr[c]) for c in thr if any(c == p[0] for p in pairs)}
            identifiable = any(seen.values())
            oil_only = per_ch.get(OIL, 0.0) >= thr.get(OIL, float("inf"))
            note = ""
            chans = sorted(seen)
            if not identifiable:
                if chans == [OIL]:
                    note = "not identifiable from oil alone"
                else:
                    note = "not identifiable with these channels"
                why = _why_invisible(f.effect, self.cooler, train, self._base_tr, self.p)
                if why:
                    note += f" ({why})"
            out[f.effect] = {"identifiable": bool(identifiable),
                             "identifiable_from_oil_alone": bool(oil_only) if OIL in thr else None,
                             "max_signature_c": {c: _r(v) for c, v in sorted(per_ch.items())},
                             "threshold_c": {c: _r(thr[c]) for c in sorted(per_ch)},
                             "detectable_from_fraction": _r(frac_min, 3) if frac_min is not None else None,
                             "note": note}
        return out

    def _where(self, train, base_tr, p0_tr, obs_tr):
        parts = {}
        ep = []
        k = 0
        for ds, out in zip(train, base_tr):
            for cid, ch in ds.channels.items():
                r = obs_tr[k] - p0_tr[k]
                k += 1
                labs = regime_labels(ds, ch, out, self.p, self.cooler, self.o)
                for part, lab in labs.items():
                    d = parts.setdefault(cid, {}).setdefault(part, {})
                    for L in np.unique(lab):
                        m = lab == L
                        a = d.setdefault(str(L), [0.0, 0, 0.0])
                        a[0] += float(np.sum(r[m] ** 2))
                        a[1] += int(m.sum())
                        a[2] += float(np.sum(r[m]))
                # episodes: 120-s windows
                w = 120.0
                kk = np.floor((ch.cell_t - ds.t_start) / w).astype(int)
                e2 = np.bincount(kk, r ** 2)
                for j in np.flatnonzero(e2):
                    ep.append((cid, ds.name, ds.t_start + j * w, min(ds.t_start + (j + 1) * w, ds.t_end), float(e2[j]),
                               float(np.sum(r[kk == j]) / max((kk == j).sum(), 1))))
        where, where_by = [], {}
        for cid, d in parts.items():
            where_by[cid] = {}
            for part, regs in d.items():
                tot = sum(a[0] for a in regs.values()) or 1.0
                ntot = sum(a[1] for a in regs.values()) or 1
                lst = [{"regime": L, "share": _r(a[0] / tot, 4), "time_share": _r(a[1] / ntot, 4),
                        "rms_c": _r(math.sqrt(a[0] / max(a[1], 1))), "mean_c": _r(a[2] / max(a[1], 1))}
                       for L, a in regs.items()]
                lst.sort(key=lambda x: -x["share"])
                where_by[cid][part] = lst
                if part == PRIMARY:
                    for x in lst:
                        where.append({"channel": cid, **x})
        where.sort(key=lambda x: (-x["share"], x["channel"], x["regime"]))
        tot_ch = {}
        for e in ep:
            tot_ch[e[0]] = tot_ch.get(e[0], 0.0) + e[4]
        ep.sort(key=lambda e: -e[4] / (tot_ch[e[0]] or 1.0))
        episodes = [{"channel": c, "file": f, "t_start_s": _r(a, 1), "t_end_s": _r(b, 1),
                     "share": _r(e2 / (tot_ch[c] or 1.0), 4), "mean_c": _r(m)} for c, f, a, b, e2, m in ep[:10]]
        return where, where_by, episodes

    def _unexplained_heat(self, datasets, pert_pair, preds):
        """Oil channel: the heat flow the residual implies, Q = C_eff dr/dt + G_eff r (smoothed)."""
        from firmware_model.network import build_network
        net = build_network(self.p)
        C = dict(zip(net.nodes, net.C_j_per_k))
        net_C = C["oil"] + C["H1"] + C["H2"] + C["H3"]
        # G_eff from the warmer-start re-simulation: d(heat to the outside) / d(T_oil)
        ratios = []
        for out0, out1 in zip(*pert_pair):
            q0 = sum(np.asarray(out0.get(c, 0.0)) for c in Q_OUT)
            q1 = sum(np.asarray(out1.get(c, 0.0)) for c in Q_OUT)
            dT = np.asarray(out1["T_oil_c"]) - np.asarray(out0["T_oil_c"])
            m = dT > 0.2
            if np.any(m):
                ratios.append(np.median((q1 - q0)[m] / dT[m]))
        G = float(np.median(ratios)) if ratios else float("nan")
        files = []
        self._heat_series = []
        k = 0
        for ds in datasets:
            for cid, ch in ds.channels.items():
                p = preds[k]
                k += 1
                if cid != OIL:
                    continue
                r = ch.cell_y - p
                tg = np.arange(ds.t_start, ds.t_end + 1e-9, self.o.grid_dt_s)
                rg = np.interp(tg, ch.cell_t, r)
                from scipy.signal import savgol_filter
                win = max(int(round(120.0 / self.o.grid_dt_s)) | 1, 5)
                if rg.size > win:
                    rs = savgol_filter(rg, win, 2)
                    drs = savgol_filter(rg, win, 2, deriv=1, delta=self.o.grid_dt_s)
                else:
                    rs, drs = rg, np.gradient(rg, tg)
                Q = net_C * drs + (G if math.isfinite(G) else 0.0) * rs
                self._heat_series.append((ds, tg, Q, rs))
                files.append({"file": ds.name, "role": ds.role, "mean_w": _r(float(np.mean(Q)), 1),
                              "p5_w": _r(float(np.percentile(Q, 5)), 1), "p95_w": _r(float(np.percentile(Q, 95)), 1)})
        return {"C_eff_j_per_k": _r(net_C, 1), "G_eff_w_per_k": _r(G, 2), "smoothing_s": 120.0,
                "sign": "positive = heat entering the oil that the model does not have", "files": files}

    def _suggest(self, train, fa: _Fit, fb: _Fit) -> dict:
        """Which extra measurement separates two confusable effects: simulate both at their fitted values with every
        node and rank the nodes (and the cooler heat) by the RMS difference."""
        outs = self._sim(train, [Run.of({fa.effect: fa.value}, full=True), Run.of({fb.effect: fb.value}, full=True)])
        measured = {cid for ds in train for cid in ds.channels}
        from firmware_model.components import PUBLISHED
        cand_nodes = [n for n in PUBLISHED if n != "oil"] + ["H1", "H2", "H3"]
        diffs = {}
        for oa, ob in zip(outs[0], outs[1]):
            fa_, fb_ = oa["full"], ob["full"]
            for n in cand_nodes + ["oil"]:
                c = f"T_{n}_c"
                if c in fa_ and c in fb_:
                    d = diffs.setdefault(n, [0.0, 0])
                    d[0] += float(np.sum((fa_[c] - fb_[c]) ** 2))
                    d[1] += fa_[c].size
            if "Q_out_cooler_w" in fa_:
                d = diffs.setdefault("__cooler", [0.0, 0])
                d[0] += float(np.sum((fa_["Q_out_cooler_w"] - fb_["Q_out_cooler_w"]) ** 2))
                d[1] += fa_["Q_out_cooler_w"].size
        ranked = []
        for n, (s, m) in diffs.items():
            rms = math.sqrt(s / max(m, 1))
            if n == "__cooler":
                continue
            if n in measured:
                continue
            label = ("a second, fast oil sensor in the sump" if n == "oil" else
                     f"a thermocouple on {n}" + (" (sun wheel)" if n == "PS" else ""))
            ranked.append({"measurement": label, "node": n, "difference_rms_c": _r(rms)})
        ranked.sort(key=lambda x: -x["difference_rms_c"])
        cool = diffs.get("__cooler")
        cool_rms = math.sqrt(cool[0] / max(cool[1], 1)) if cool else 0.0
        best = ranked[0] if ranked else None
        text = (f"{fa.effect} and {fb.effect} explain the data alike; " +
                (f"{best['measurement']} would separate them (predicted difference {best['difference_rms_c']:.2f} "
                 f"degC rms)" if best else "no single extra temperature separates them"))
        if cool_rms > 300:
            text += (f"; so would the cooler's heat (oil temperatures at the cooler inlet and outlet, or the coolant "
                     f"temperature): {cool_rms:.0f} W rms apart")
        return {"effects": [fa.effect, fb.effect], "best": ranked[:3], "cooler_heat_difference_rms_w": _r(cool_rms, 1),
                "text": text}

    def _test_regimes(self, test, base_te, res0, res1):
        acc = {}
        k = 0
        for ds, out in zip(test, base_te):
            for cid, ch in ds.channels.items():
                labs = regime_labels(ds, ch, out, self.p, self.cooler, self.o)
                r0, r1 = res0[k], res1[k]
                k += 1
                for part in (PRIMARY, "transient / steady", "cold / warm", "retarder", "cooler"):
                    if part not in labs:
                        continue
                    for L in np.unique(labs[part]):
                        m = labs[part] == L
                        a = acc.setdefault((cid, part, str(L)), [0.0, 0.0, 0, 0.0, 0.0])
                        a[0] += float(np.sum(r0[m] ** 2))
                        a[1] += float(np.sum(r1[m] ** 2))
                        a[2] += int(m.sum())
                        a[3] = max(a[3], float(np.max(np.abs(r0[m]))))
                        a[4] = max(a[4], float(np.max(np.abs(r1[m]))))
        out = [{"channel": c, "partition": p, "regime": L, "rms_before_c": _r(math.sqrt(a[0] / a[2])),
                "rms_after_c": _r(math.sqrt(a[1] / a[2])), "max_before_c": _r(a[3]), "max_after_c": _r(a[4]),
                "cells": a[2]} for (c, p, L), a in acc.items()]
        out.sort(key=lambda x: (x["channel"] != OIL, x["channel"], x["partition"], -x["rms_before_c"]))
        return out


def _why_invisible(eid, cooler, train, base_tr=None, params=None):
    if eid == "thermostat_offset" and cooler != "air":
        return f"the {cooler} cooler has no thermostat"
    if eid == "cooler_effectiveness_scale" and cooler not in ("liquid", "air"):
        return f"cooler kind '{cooler}' has no cooler model"
    if eid in ("thermostat_offset", "cooler_effectiveness_scale") and cooler == "air" and base_tr and params:
        top = max(float(np.max(o["T_oil_c"])) for o in base_tr)
        if top < params["cooler.thermostat_open"] + 10.0:
            return (f"the oil stays below {top:.0f} degC in the training files, near or under the air cooler's "
                    f"thermostat ({params['cooler.thermostat_open']:g}-{params['cooler.thermostat_full']:g} degC)")
    if eid == "retarder_heat":
        used = any(ds.inputs.has("retarder_torque_nm") and np.nanmax(ds.inputs["retarder_torque_nm"]) > 100
                   for ds in train)
        if not used:
            return "the retarder is never used in the training files"
    if eid == "synchronizer_shift_heat":
        shifts = sum(int(np.count_nonzero(np.diff(ds.inputs["gear"]))) for ds in train)
        return f"{shifts} gear changes in the training files"
    if eid in ("planet_oil_h_scale", "teeth_oil_h_scale"):
        return "it moves heat between components and the oil, barely changing the oil itself"
    return ""


def _pooled_rms(res):
    n = sum(r.size for r in res)
    return math.sqrt(sum(float(np.sum(r ** 2)) for r in res) / n) if n else float("nan")


def _max_abs(res):
    return max((float(np.max(np.abs(r))) for r in res if r.size), default=float("nan"))


def _r(x, nd=4):
    if x is None:
        return None
    x = float(x)
    if not math.isfinite(x):
        return None
    return round(x, nd)


# ----------------------------------------------------------------------------------------------------------------
# entry point

def make_model(kind: str, params, cooler: str | None, opts: Options):
    from tools.diagnosis.models import OnboardModel, PlantModel, onboard_available
    plant = PlantModel(params, cooler=cooler, dt_s=opts.plant_dt_s, out_dt_s=opts.out_dt_s, workers=opts.workers)
    note = None
    if kind == "plant":
        return plant, note
    if kind != "onboard":
        raise InputError(f"--model {kind!r} must be onboard or plant")
    if not onboard_available():
        note = ("the onboard model (firmware_model.onboard.sensor) is not available yet; the reference plant was diagnosed "
                "instead")
        return plant, note
    return OnboardModel(params, cooler=cooler, fallback=plant, out_dt_s=opts.out_dt_s, workers=opts.workers), note


def diagnose(train_tables, test_tables, params, model: str = "onboard", cooler: str | None = None,
             opts: Options | None = None, progress=None, train_names=None, test_names=None, candidates=None,
             keep=False, config_path=None):
    """Run the diagnosis on lists of RunTables (or paths). Returns the JSON dict (and the Diagnosis object when
    `keep`)."""
    opts = opts or Options()
    cooler = cooler or params.strings.get("cooler.kind", "liquid")
    oil_is_input = cooler in ("measured", "hold")
    if not train_tables:
        raise InputError("give at least one training file (--train)")
    if not test_tables:
        raise InputError("give at least one test file (--test)")

    def load(items, names, role):
        out = []
        for i, it in enumerate(items):
            if isinstance(it, RunTable):
                tb = it
                nm = (names[i] if names else None) or it.source or f"{role}{i + 1}"
            else:
                tb = load_table(it, config_path)
                nm = (names[i] if names else None) or os.fspath(it)
            out.append((nm, tb, it))
        return out

    tr = load(train_tables, train_names, "train")
    te = load(test_tables, test_names, "test")
    # train and test must be different files
    seen = {}
    for role, items in (("train", tr), ("test", te)):
        for nm, tb, src in items:
            keys = [("data", _fingerprint(tb))]
            if not isinstance(src, RunTable):
                keys.insert(0, ("path", os.path.realpath(src)))
            for k in keys:
                if k in seen:
                    other, orole = seen[k]
                    if orole != role:
                        raise InputError(f"{nm} is both a training and a test file (same data as {other}); the test "
                                         f"files must be different runs")
                    raise InputError(f"{nm} is given twice as a {role} file (same data as {other}); give each run once")
                seen[k] = (nm, role)
    train = [prepare(tb, nm, "train", opts, oil_is_input) for nm, tb, _ in tr]
    test = [prepare(tb, nm, "test", opts, oil_is_input) for nm, tb, _ in te]
    ch_tr = {c for ds in train for c in ds.channels}
    missing = sorted({c for ds in test for c in ds.channels} - ch_tr)
    if missing:
        raise InputError(f"channel(s) {', '.join(missing)} are measured in the test files but in no training file; "
                         f"the diagnosis can only test what it was trained on")
    m, note = make_model(model, params, cooler, opts)
    try:
        d = Diagnosis(train, test, m, params, opts, cooler, progress, candidates)
        res = d.run()
    finally:
        m.close()
    res["model"]["requested"] = model
    if note:
        res["model"]["note"] = note
    return (res, d) if keep else res
