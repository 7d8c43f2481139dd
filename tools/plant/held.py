"""The reference plant over a table slower than its step (a SCADA system's 10-minute rows, tools/drive_table.py):
each row's inputs are held over its interval, and the network is integrated over the interval in long exponential
steps instead of 0.5 s BDF2 steps (issue 45: a month of 10-minute rows is 5 million plant steps, 25 min).

Over a sub-interval the network is linear with every input held: ``C dT/dt = -A T + b`` (A: the conductance matrix
with the cooler's slope on the sump, b: the sources, the boundaries' heat and the cooler linearised), solved exactly
with the modes of the symmetric ``C^-1/2 A C^-1/2`` (the onboard model's held solution, held_modes, on the full
network). The plant is nonlinear only through temperature: the losses and conductances follow the oil (viscosity),
radiation the surfaces, the cooler the sump (thermostat). So each sub-interval is first predicted with everything at
its start (one implicit Euler step), then solved exactly with the conductances and cooler at the mean temperatures the
prediction gives over it and the losses linear in time from those at its start to those at its predicted end (second
order in the sump's move). A sub-interval is halved while the sump moves more
than OIL_MOVE_K in it or the cooler's linearisation is off by more than COOLER_TOL_K of sump temperature over it (a
thermostat opening or closing inside it: sub-stepping down to the plant's step). Boundaries are held at their value
at a sub-interval's middle (the step path interpolates them between rows as well).

The energy ledger is booked from the same linear solution (the heat out of each path from the exact time integral of
the temperatures), so generated = stored + rejected holds to round-off, as on the step path.

The losses of every row are evaluated (vectorised over a block of rows) on a grid of sump temperatures LOSS_GRID_K
apart and interpolated linearly in the sump (they follow the oil's viscosity, smooth but for a churning regime change).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware_model.physics import oil as oilprops
from firmware_model.physics.conductance_matrix import boundary_heat_w, conductance_matrix
from firmware_model.physics.heat_lag import heat_lag, heat_lag_step
from firmware_model.physics.kinematics import GEAR_MIN

#: the paths heat leaves by (tools.plant.reference.HEAT_OUT_NAMES: cooler, housing convection, radiation, supports,
#: shafts, held sump); the held path books the first five
N_OUT = 6

#: a table takes the held path when its rows lie at least this many plant steps apart (the median spacing) [-]
HELD_MIN_ROW_STEPS = 20
#: the sump moves at most this much over a sub-interval [K] (assumed: with the losses, conductances and cooler taken
#: at the sub-interval's mean temperatures the error is second order in this move; measured 0.03 K on the MM82)
OIL_MOVE_K = 0.5
#: the cooler's linearisation error over a sub-interval, as sump temperature, at most [K] (assumed; measured on
#: test_plant_held's 6 MM82 hours: 0.0005 let the planets err 0.095 K in the valve's band, where the jets' oil
#: moves ~9 K a kelvin of sump; 0.0001: 0.05 K, for 6 % more sub-intervals)
COOLER_TOL_K = 0.0001
#: the spacing of the sump-temperature grid the losses are interpolated on [K] (assumed; measured: smooth but where a
#: churning correlation changes regime, whose jump the interpolation spreads over one spacing: up to 1 % of the total
#: loss there, -10..110 degC, MM82 and HR225; the node errors of bench_held_month.py include it)
LOSS_GRID_K = 1.0
#: rows of a block whose losses are evaluated in one vectorised call
LOSS_BLOCK_ROWS = 144


def takes_held_path(table, kind: str, dt_s: float, scales) -> bool:
    """True when the plant integrates ``table`` row interval by row interval: a fixed-ratio drive's table (its
    inputs are held between rows, tools/drive_table.py) whose rows lie at least HELD_MIN_ROW_STEPS steps apart, with
    a cooler the held path models (none, liquid, air: a held or measured sump takes the step path) and no lagged oil
    sensor (effect oil_sensor_lag: its lag is marched over the plant's steps, here the rows)."""
    meta = getattr(table, "meta", None) or {}
    return (
        meta.get("drive") == "fixed_ratio"
        and float(meta.get("row_period_s") or 0.0) >= HELD_MIN_ROW_STEPS * dt_s
        and kind in ("none", "liquid", "air")
        and not scales.oil_sensor_tau_s > 0
    )


class HeldRows(NamedTuple):
    """What the held path gives the plant's output and ledger: the state at every row time and the interval
    averages of the Q_ columns (row k + 1: the interval that ends there), the energy books."""

    T_c: np.ndarray  # (N, n) node temperatures at the row times
    Q_w: np.ndarray  # (N, n_q)
    generated_j: float
    stored_j: float
    out_j: np.ndarray  # (len(HEAT_OUT_NAMES),)
    mechanical_j: float
    churn_invalid_s: float
    sub_intervals: int  # exponential solves accepted (a figure for the benchmark)


class _Sub(NamedTuple):
    """One exactly solved sub-interval."""

    T_end_c: np.ndarray
    T_mean_c: np.ndarray  # the time average over it
    lag_w: np.ndarray
    delivered_w: np.ndarray  # (n_src,) heat through the lag, average
    out_w: np.ndarray  # heat out by each path, average
    src_w: np.ndarray  # (n_src + 2,) source heat, mechanical loss, churn-invalid share (interpolated)
    cooler: tuple  # (heat at the linearisation point, slope, the sump there, the cooler's other arguments)


class _LossGrid:
    """The losses of every row at sump temperatures on a LOSS_GRID_K grid, evaluated a block of rows at a time when
    first needed; :meth:`at` interpolates linearly. Columns: the heat of every source of ``plant.src_names`` (the
    retarder's from its torque, no shift heat), the mechanical loss, the share outside the churning correlations."""

    def __init__(self, plant, inp):
        self.plant, self.inp = plant, inp
        self.cache: dict = {}

    def _block(self, b: int, k: int) -> np.ndarray:
        key = (b, k)
        got = self.cache.get(key)
        if got is None:
            p, inp = self.plant, self.inp
            sl = slice(b * LOSS_BLOCK_ROWS, (b + 1) * LOSS_BLOCK_ROWS)
            T_c = min(max(k * LOSS_GRID_K, oilprops.T_MIN_C), oilprops.T_MAX_C)
            w_in, gear = inp.omega_in_rad_s[sl], inp.gear[sl]
            loss = p.losses.evaluate(w_in, inp.torque_nm[sl], gear, T_c, churn_validity=True)
            churn_ok = loss.pop("churning_valid")
            heat = p.losses.heat(loss, p.scales)
            got = np.zeros((w_in.size, len(p.src_names) + 2))
            for j, nm in enumerate(p.sources):
                got[:, j] = heat[nm]
            if inp.retarder_nm is not None and p.scales.retarder_frac > 0:
                sp = p.losses.kin.speed[gear - GEAR_MIN] * w_in[:, None]
                got[:, p.src_names.index("retarder")] = (
                    p.scales.retarder_frac * np.abs(inp.retarder_nm[sl]) * np.abs(sp[:, p.i_output])
                )
            got[:, -2] = np.sum([loss[s] for s in p.sources], axis=0)
            got[:, -1] = ~np.asarray(churn_ok, dtype=bool)
            self.cache[key] = got
        return got

    def at(self, i: int, T_oil_c: float) -> np.ndarray:
        """The columns of row ``i`` at sump temperature ``T_oil_c``, linear between the grid's temperatures."""
        x = T_oil_c / LOSS_GRID_K
        k = math.floor(x)
        b, r = divmod(i, LOSS_BLOCK_ROWS)
        lo, hi = self._block(b, k)[r], self._block(b, k + 1)[r]
        return lo + (x - k) * (hi - lo)


class HeldIntegrator:
    """The held path of one run: ``plant`` (a ReferencePlant) over ``inp`` (its RunInputs)."""

    def __init__(self, plant, inp):
        self.p, self.inp = plant, inp
        self.losses = _LossGrid(plant, inp)
        C = plant.net.C_j_per_k
        self.s = 1.0 / np.sqrt(C)
        self.C = C
        self.n_src = len(plant.src_names)
        # every boundary at every row time (the defaults where the table gives none)
        self.bc_rows = np.tile(plant.bc_default, (inp.t_s.size, 1))
        for j, arr in inp.bc_c.items():
            self.bc_rows[:, j] = arr

    def run(self, T0_c: np.ndarray, n_q: int) -> HeldRows:
        """Every row interval in turn from the node temperatures ``T0_c``."""
        p, t = self.p, self.inp.t_s
        N = t.size
        T_rows = np.empty((N, p.n))
        Q = np.zeros((N, n_q))
        T_rows[0] = T = np.array(T0_c, dtype=float)
        lag = np.zeros(self.n_src)
        books = np.zeros(4 + N_OUT)  # generated, stored, mechanical, churn-invalid s, heat out by path
        subs = 0
        for i in range(N - 1):
            T, lag, avg, n_sub = self._interval(i, T, lag, books)
            subs += n_sub
            T_rows[i + 1] = T
            Q[i + 1] = avg
        return HeldRows(T_rows, Q, books[0], books[1], books[4:], books[2], books[3], subs)

    def _interval(self, i: int, T, lag, books):
        """Row ``i`` over its interval in sub-intervals; returns (T, lag, the interval's Q_ row, sub-intervals)."""
        p = self.p
        ta, tb = float(self.inp.t_s[i]), float(self.inp.t_s[i + 1])
        acc = np.zeros(self.n_src + 3 + N_OUT)  # integrals: heat by source, mechanical, generated, out, stored
        t, h, n_sub = ta, tb - ta, 0
        while t < tb - 1e-9:
            h = min(h, tb - t)
            pred = self._solve(i, T, lag, t, h, T, T, predict=True)
            if abs(pred.T_end_c[p.i_oil] - T[p.i_oil]) > OIL_MOVE_K and h > 2.0 * p.dt:
                h *= 0.5
                continue
            sub = self._solve(i, T, lag, t, h, pred.T_mean_c, pred.T_end_c, slope_w_per_k=pred.cooler[1])
            if h > 2.0 * p.dt and self._cooler_err_k(sub, h) > COOLER_TOL_K:
                h *= 0.5
                continue
            stored_w = float(np.dot(self.C, sub.T_end_c - T)) / h
            gen_w = float(sub.delivered_w.sum())
            books[:4] += h * np.array([gen_w, stored_w, sub.src_w[-2], sub.src_w[-1]])
            books[4:] += h * sub.out_w
            acc += h * np.concatenate([sub.src_w[:-1], [gen_w], sub.out_w, [stored_w]])
            T, lag, t, n_sub = sub.T_end_c, sub.lag_w, t + h, n_sub + 1
            h *= 2.0
        return T, lag, self._q_row(acc / (tb - ta)), n_sub

    def _q_row(self, a: np.ndarray) -> np.ndarray:
        """The Q_ columns (Ledger.book's order) from the interval's averages ``a``: the sources' heat, the mechanical
        loss, the generated heat, the heat out by path, the stored heat."""
        p = self.p
        ns = len(p.sources)
        i_ret = p.src_names.index("retarder")
        out = a[self.n_src + 2 : -1]
        return np.concatenate([a[:ns], [a[self.n_src], a[self.n_src + 1]], out, [a[i_ret], a[-1]]])

    def _boundaries_c(self, i: int, t: float) -> np.ndarray:
        """The boundary temperatures at time ``t`` within row ``i``'s interval (linear between rows, as the step path
        reads them)."""
        t_s = self.inp.t_s
        return self.bc_rows[i] + (self.bc_rows[i + 1] - self.bc_rows[i]) * ((t - t_s[i]) / (t_s[i + 1] - t_s[i]))

    def _solve(self, i, T0, lag0, t: float, h: float, T_mean, T_end, predict: bool = False, slope_w_per_k=None) -> _Sub:
        """Sub-interval [t, t + h] of row ``i`` from ``T0`` solved exactly: the conductances, radiation and cooler
        taken at the temperatures ``T_mean`` (the sub-interval's mean), the sources' heat and the boundaries linear
        in time from their values at the start (the losses at the sump of ``T0``) to those at the end (the losses at
        the sump of ``T_end``): the end state of the fast nodes (a bearing) follows the losses at the end.
        ``predict``: one implicit Euler step instead (L-stable: the fast nodes at their end state, the slow ones within
        a few per cent of their move), the mean temperatures halfway; the point the exact solution is then taken at.
        ``slope_w_per_k``: the cooler's slope to take (the prediction's, at the start: the error check at the end
        catches a thermostat between), else evaluated."""
        p, inp = self.p, self.inp
        row = int(inp.gear[i]) - GEAR_MIN
        kin = p.losses.kin
        omega = np.abs(kin.speed[row] * inp.omega_in_rad_s[i])
        T_oil = float(T_mean[p.i_oil])
        bc0, bc1 = self._boundaries_c(i, t), self._boundaries_c(i, t + h)
        T_bc = 0.5 * (bc0 + bc1)
        src0 = self.losses.at(i, float(T0[p.i_oil]))
        src1 = src0 if T_end is T0 else self.losses.at(i, float(T_end[p.i_oil]))
        src = 0.5 * (src0 + src1)
        lag = heat_lag_step(lag0, src[: self.n_src], heat_lag(p.tau_lag, h))
        G = p.ev.evaluate_cached(T_oil, omega, row, kin.mesh_torque[row], bool(kin.low_range[row]), T_mean, T_bc)
        v_kmh = float(np.interp(t + 0.5 * h, inp.t_s, inp.v_kmh)) if inp.v_kmh is not None else p.v_default_kmh
        cooler_args = (p._pump_speed(omega), omega[p.i_input], p._bc_or_nan(T_bc, "coolant"))
        cooler_args += (p._bc_or_nan(T_bc, "ambient"), v_kmh)
        q0, gc = p.cooler_heat(T_oil, *cooler_args, slope=slope_w_per_k is None)
        gc = gc if slope_w_per_k is None or q0 == 0.0 else slope_w_per_k
        q_nodes = p._stream_transfer(p.S @ lag.delivered_w, G, q0, omega, T_oil, inp.kind)
        A, Ge = conductance_matrix(G, p.topo)
        A[p.i_oil, p.i_oil] += gc  # the cooler linearised at the mean sump: Q = q0 + gc (T_oil - T_oil_mean)
        b = q_nodes + boundary_heat_w(Ge, p.topo, T_bc)
        b[p.i_oil] += gc * T_oil - q0
        # the ramp: b(t) = b + db (t / h - 1/2), its mean b (the books stay exact)
        db = p.S @ (src1 - src0)[: self.n_src] + boundary_heat_w(Ge, p.topo, bc1 - bc0)
        if predict:
            T_end_c = np.linalg.solve(A + np.diag(self.C / h), self.C / h * T0 + b + 0.5 * db)
            T_mean_c = 0.5 * (T0 + T_end_c)
        else:
            T_end_c, T_mean_c = self._exact(A, b - 0.5 * db, db, T0, h)
        q_bc = Ge * (T_mean_c[p.topo.ea] - T_bc[p.topo.eb])
        out = np.zeros(N_OUT)  # HEAT_OUT_NAMES (no held sump here: oil_boundary stays 0)
        out[0] = q0 + gc * (T_mean_c[p.i_oil] - T_oil) if inp.kind in ("liquid", "air") else 0.0
        for grp in (1, 2, 3, 4):
            out[grp] = q_bc[p.ext_group == grp].sum()
        return _Sub(T_end_c, T_mean_c, lag.state_w, lag.delivered_w, out, src, (q0, gc, T_oil, cooler_args))

    def _cooler_err_k(self, sub: _Sub, h: float) -> float:
        """The cooler's linearisation error at the sub-interval's end (a thermostat opening or closing inside it), as
        the sump temperature it would move over the sub-interval [K]."""
        q0, gc, T_oil, cooler_args = sub.cooler
        # a valve closed at the linearisation point (no heat, no slope) may open before the end: evaluated there too
        T_end = float(sub.T_end_c[self.p.i_oil])
        q_end, _ = self.p.cooler_heat(T_end, *cooler_args, slope=False)
        return 0.5 * abs(q_end - (q0 + gc * (T_end - T_oil))) * h / float(self.C[self.p.i_oil])

    def _exact(self, A: np.ndarray, b0: np.ndarray, db: np.ndarray, T0: np.ndarray, h: float):
        """``C dT/dt = -A T + b0 + db t / h`` from T0 over h: the end temperatures and their time average. Modal
        solution of the symmetric system in y = C^1/2 T (dy/dt = -M y + s b, M = s A s, s = C^-1/2): per mode, with
        x = lambda h, z(h) = z0 e^-x + c0 h phi1 + c1 h^2 phi2 and its mean z0 phi1 + c0 h phi2 + c1 h^2 phi3."""
        s = self.s
        lam, V = np.linalg.eigh(A * s[:, None] * s[None, :])
        z0 = V.T @ (T0 / s)
        c0 = V.T @ (s * b0)
        c1h = V.T @ (s * db)  # c1 h
        phi1, phi2, phi3 = _phis(lam * h)
        z_end = z0 * np.exp(-lam * h) + h * (c0 * phi1 + c1h * phi2)
        z_mean = z0 * phi1 + h * (c0 * phi2 + c1h * phi3)
        return s * (V @ z_end), s * (V @ z_mean)


def _phis(x: np.ndarray):
    """phi1 = (1 - e^-x) / x, phi2 = (1 - phi1) / x, phi3 = (1/2 - phi2) / x (x >= 0), by their series below 1e-3
    (where the differences would cancel)."""
    x = np.asarray(x, dtype=float)
    small = x < 1e-3
    if not small.any():
        phi1 = -np.expm1(-x) / x
        phi2 = (1.0 - phi1) / x
        return phi1, phi2, (0.5 - phi2) / x
    xs = np.where(small, 1.0, x)
    phi1 = np.where(small, 1.0 - x / 2.0 + x * x / 6.0, -np.expm1(-xs) / xs)
    phi2 = np.where(small, 0.5 - x / 6.0 + x * x / 24.0, (1.0 - phi1) / xs)
    phi3 = np.where(small, 1.0 / 6.0 - x / 24.0 + x * x / 120.0, (0.5 - phi2) / xs)
    return phi1, phi2, phi3
