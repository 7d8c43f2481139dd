"""The reference plant: the thesis's full gearbox thermal network, integrated fast and stiff-safe.

Inputs are a run table (any sample rate, irregular allowed; values are held until the next sample). Mechanical
losses are evaluated for every input sample (vectorised, oil properties at the sump temperature of the current
chunk) and averaged exactly over each thermal step, so 100 Hz noisy signals cost no solver steps (the thesis's
commercial tool crawled on them, seed chapter 7). The network is integrated with BDF2 (A-stable, second order;
implicit Euler on the first step and after a step-size change) with conductances evaluated once per step from the
step's mean shaft speeds, its dominant gear and the sump temperature; radiation and the cooler are linearised
around the current temperatures. Every joule is booked: generated heat = stored + rejected (+ what a held or
measured sump absorbs), checked by `SimResult.energy_balance()`.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from firmware_model.physics import oil as oilprops
from firmware_model.components import IDLE_WHEELS
from firmware_model.effects import effect_scales, effect_value, with_oil_volume
from firmware_model.errors import InputError
from firmware_model.physics.cooler import cooler_params, cooler_values, inlet_drop_k, oil_cooler_heat
from firmware_model.physics.gearbox_losses import SOURCES, GearboxLosses
from firmware_model.physics.kinematics import GEAR_MAX, GEAR_MIN, SPEED_NAMES, gear_state
from firmware_model.network import (BOUNDARIES, K_EXT_CONV, K_EXT_RAD, K_STREAM, ConductanceEvaluator,
                                    Network, build_network)
from firmware_model.parameters import Parameters

from tools.runtable import RunTable

RPM = 2.0 * math.pi / 60.0
#: run-table column -> boundary name (bc_<name>_c columns, plus the contract's ambient and coolant columns)
BC_COLUMNS = {**{f"bc_{b}_c": b for b in BOUNDARIES}, "ambient_temp_c": "ambient", "coolant_temp_c": "coolant"}
#: step of the forward difference that linearises the cooler around the sump temperature [K]
COOLER_SLOPE_DT_K = 0.05

HEAT_OUT_NAMES = ("cooler", "housing_convection", "housing_radiation", "supports_conduction", "shafts_conduction",
                  "oil_boundary")


@dataclass
class SimResult:
    table: RunTable
    nodes: tuple
    energy: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    wall_s: float = 0.0

    def energy_balance(self) -> dict:
        e = self.energy
        gen = e["generated_j"]
        closure = gen - e["stored_j"] - e["rejected_j"]
        return {**e, "closure_j": closure, "closure_rel": abs(closure) / max(abs(gen), 1e-9)}


class ReferencePlant:
    """Build once per parameter set and effect set, then `run()` any number of run tables."""

    def __init__(self, params: Parameters, effects: dict | None = None, cooler: str | None = None,
                 dt_s: float = 0.5):
        self.effects = dict(effects or {})
        self.p = params = with_oil_volume(params, effect_value(self.effects, "oil_level_low"))
        self.kind = cooler or params.strings.get("cooler.kind", "liquid")
        if self.kind not in ("none", "liquid", "air", "hold", "measured"):
            raise InputError(f"cooler {self.kind!r} must be one of none, liquid, air, hold, measured")
        if not 0.01 <= dt_s <= 5.0:
            raise InputError(f"plant time step {dt_s} s is outside 0.01..5 s")
        self.dt = float(dt_s)
        self.net: Network = build_network(params)
        self.losses = GearboxLosses(params, self.net.geometry)
        self.scales = effect_scales(self.effects)
        self.ev = ConductanceEvaluator(self.net, params, self.scales)
        n = self.net.n
        self.n = n
        self.i_oil = self.net.index("oil")
        a, b = self.net.link_a, self.net.link_b
        self.internal = b < n
        self.ia, self.ib = a[self.internal], b[self.internal]
        self.ea, self.eb = a[~self.internal], b[~self.internal] - n
        self.lap_idx = np.concatenate([self.ia * n + self.ia, self.ib * n + self.ib, self.ia * n + self.ib,
                                       self.ib * n + self.ia])
        # classify boundary links for the heat budget
        kinds = self.net.link_kind[~self.internal]
        bname = np.array(BOUNDARIES)[self.eb]
        self.ext_group = np.where(kinds == K_EXT_CONV, 1, np.where(kinds == K_EXT_RAD, 2, np.where(
            np.isin(bname, ["flywheel_cover", "support_beam"]), 3, 4)))
        # source distribution matrix: node heat = S @ source heat
        self.src_names = list(SOURCES) + ["retarder", *[f"shift:{w}" for w in IDLE_WHEELS], "shift:PR"]
        self.S = np.zeros((n, len(self.src_names)))
        for j, s in enumerate(self.src_names):
            for node, frac in self.net.sources[s]:
                self.S[node, j] += frac
        self.stream_idx = self.net.links_of_kind(K_STREAM)
        self.stream_nodes = self.net.link_a[self.stream_idx]
        self.tau_lag = params["scale.heat_lag_tau"]
        self.bc_default = np.array([params[f"boundary.{b}"] for b in BOUNDARIES])
        self.bc_default[BOUNDARIES.index("hot_surroundings")] += effect_value(self.effects, "hot_surroundings_offset")
        self.cooler = cooler_params(cooler_values(params))
        self.retarder_frac = effect_value(self.effects, "retarder_heat")
        self.shift_energy = effect_value(self.effects, "synchronizer_shift_heat")
        self.sensor_tau = effect_value(self.effects, "oil_sensor_lag")
        self.rho_cp_oil_flow = None

    # ------------------------------------------------------------------ cooler (seed 3.4, Eq 82-83)
    def cooler_heat(self, T_oil, w_ls, w_eng, T_cool, T_amb, v_kmh):
        """Heat from the sump to the cooler [W] (physics.cooler.oil_cooler_heat, the onboard model's cooler) and its
        derivative with respect to the sump temperature (forward difference over COOLER_SLOPE_DT_K)."""
        if self.kind not in ("liquid", "air"):
            return 0.0, 0.0
        op = oilprops.oil_properties(T_oil)
        mdot_kg_s = self.ev.oil_mass_flow_kg_s(w_ls, op.rho_kg_m3)
        if mdot_kg_s <= 0:
            return 0.0, 0.0
        flow_ratio = mdot_kg_s / self.ev.oil_mass_flow_kg_s(self.cooler.ref_ls_speed_rad_s, op.rho_kg_m3)
        mcp_w_per_k = mdot_kg_s * op.cp_j_per_kgk
        sc = self.scales

        def q(T):
            return oil_cooler_heat(self.cooler, self.kind, T, flow_ratio, w_eng, T_cool, T_amb, v_kmh, mcp_w_per_k,
                                   sc.cooler_scale, sc.thermostat_offset_c)
        q0 = q(T_oil)
        if q0.hA_w_per_k <= 0:
            return 0.0, 0.0
        slope = (float(q(T_oil + COOLER_SLOPE_DT_K).Q_w) - float(q0.Q_w)) / COOLER_SLOPE_DT_K
        return float(q0.Q_w), max(slope, 0.0)

    # ------------------------------------------------------------------ main loop
    def run(self, table: RunTable, initial_temp_c: float | None = None, hold_oil_c: float | None = None,
            out_dt_s: float = 1.0, progress: bool | None = None, chunk_s: float = 20.0) -> SimResult:
        wall0 = time.perf_counter()
        t = np.asarray(table["time_s"], dtype=float)
        if t.size < 2:
            raise InputError("the run table needs at least two samples")
        spd = np.asarray(table["engine_speed_rpm"], dtype=float)
        trq = np.asarray(table["engine_torque_nm"], dtype=float)
        gear = np.asarray(table["gear"], dtype=float)
        _validate_inputs(t, spd, trq, gear, self.p)
        gear = gear.astype(np.int64)
        w_in = spd * RPM
        n_s = t.size
        meta = getattr(table, "meta", {}) or {}
        if initial_temp_c is None:
            initial_temp_c = meta.get("initial_temp_c")
        if initial_temp_c is None and table.has("oil_temp_c") and np.isfinite(table["oil_temp_c"][0]):
            initial_temp_c = float(table["oil_temp_c"][0])
        if initial_temp_c is None:
            initial_temp_c = self.p["boundary.initial"]
        if hold_oil_c is None:
            hold_oil_c = meta.get("hold_oil_c")
        kind = self.kind
        if hold_oil_c is not None and kind not in ("measured",):
            kind = "hold"
        if kind == "hold" and hold_oil_c is None:
            hold_oil_c = self.p["cooler.hold_temp"]
        if kind == "measured":
            if not table.has("oil_temp_c"):
                raise InputError("cooler 'measured' needs an oil_temp_c column in the run table")
            oil_meas = np.asarray(table["oil_temp_c"], dtype=float)
            ok = np.isfinite(oil_meas)
            if ok.sum() < 2:
                raise InputError("cooler 'measured': column oil_temp_c has fewer than two valid values")
            oil_meas = np.interp(t, t[ok], oil_meas[ok])
        # boundary temperature signals (constant defaults unless the table carries them)
        bc_cols = {}
        for col, b in BC_COLUMNS.items():
            if table.has(col):
                v = np.asarray(table[col], dtype=float)
                ok = np.isfinite(v)
                if ok.any():
                    bc_cols[BOUNDARIES.index(b)] = np.interp(t, t[ok], v[ok]) + (
                        effect_value(self.effects, "hot_surroundings_offset") if b == "hot_surroundings" else 0.0)
        v_kmh = np.asarray(table["vehicle_speed_kmh"], dtype=float) if table.has("vehicle_speed_kmh") else None
        ret_nm = np.asarray(table["retarder_torque_nm"], dtype=float) if table.has("retarder_torque_nm") else None
        if ret_nm is not None:
            ret_nm = np.nan_to_num(ret_nm, nan=0.0)

        n, dt = self.n, self.dt
        t0, t_end = float(t[0]), float(t[-1])
        n_steps = int(math.ceil((t_end - t0) / dt - 1e-9))
        step_t = np.minimum(t0 + dt * np.arange(n_steps + 1), t_end)
        # sample durations (zero-order hold; the last sample has no duration)
        dts = np.diff(t, append=t[-1])

        C = self.net.C_j_per_k
        T = np.full(n, float(initial_temp_c))
        if kind == "hold":
            T[self.i_oil] = hold_oil_c
        elif kind == "measured":
            T[self.i_oil] = oil_meas[0]
        T_prev = T.copy()
        dt_prev = None
        lag_y = np.zeros(len(self.src_names))
        lag_a = 1.0 - math.exp(-dt / self.tau_lag) if self.tau_lag > 0 else 1.0
        kin = self.losses.kin

        hist_T = np.empty((n_steps + 1, n))
        hist_T[0] = T
        n_out_q = len(SOURCES) + 2 + len(HEAT_OUT_NAMES) + 2
        hist_Q = np.zeros((n_steps + 1, n_out_q))
        E_gen = E_stored = 0.0
        E_out = np.zeros(len(HEAT_OUT_NAMES))
        E_mech = 0.0
        churn_invalid_s = 0.0
        dT_cool_oil = 0.0     # oil-system inlet below the sump by the cooler's drop (Eq 82 idea)
        prog = _Progress(n_steps, progress)

        step = 0
        k_chunk = max(1, int(round(chunk_s / dt)))
        shift_gear_prev = int(gear[0])
        while step < n_steps:
            s0, s1 = step, min(step + k_chunk, n_steps)
            ta, tb = step_t[s0], step_t[s1]
            i0 = max(int(np.searchsorted(t, ta, side="right")) - 1, 0)
            i1 = min(int(np.searchsorted(t, tb, side="left")) + 1, n_s)
            sl = slice(i0, i1)
            T_oil_losses = T[self.i_oil]
            loss = self.losses.evaluate(w_in[sl], trq[sl], gear[sl], T_oil_losses, churn_validity=True)
            churn_ok = loss.pop("churning_valid")
            heat = self.losses.heat(loss, self.scales)
            P_src = np.zeros((i1 - i0, len(self.src_names)))
            for j, nm in enumerate(SOURCES):
                P_src[:, j] = heat[nm]
            P_mech = np.sum([loss[k] for k in SOURCES], axis=0)
            sp = kin.speed[gear[sl] - GEAR_MIN] * w_in[sl, None]
            if ret_nm is not None and self.retarder_frac > 0:
                P_src[:, self.src_names.index("retarder")] = self.retarder_frac * np.maximum(ret_nm[sl], 0) * np.abs(
                    sp[:, SPEED_NAMES.index("OS")])
            # exact averages over each step of the held samples (cumulative integrals at the step edges)
            seg_t = step_t[s0:s1 + 1]
            dur = np.diff(seg_t)
            avg = _StepAverager(t[sl], dts[sl], seg_t)
            Psrc_avg = avg(P_src)          # (n_src, k)
            Pmech_avg = avg(P_mech)[0]
            sp_avg = avg(np.abs(sp))       # (n_speeds, k)
            churn_bad_avg = avg((~churn_ok).astype(float))[0]
            for k in range(s1 - s0):
                st = s0 + k
                h = dur[k]
                if h <= 0:
                    hist_T[st + 1] = T
                    continue
                tm = 0.5 * (seg_t[k] + seg_t[k + 1])
                im = min(max(int(np.searchsorted(t, tm, side="right")) - 1, 0), n_s - 1)
                g = int(gear[im])
                row = g - GEAR_MIN
                speeds = sp_avg[:, k]
                # boundary temperatures at the step end
                T_bc = self.bc_default.copy()
                for j, arr in bc_cols.items():
                    T_bc[j] = float(np.interp(seg_t[k + 1], t, arr))
                # sources (with the heat lag, exact for a held input over the step)
                u = Psrc_avg[:, k].copy()
                if self.shift_energy > 0 and g != shift_gear_prev:
                    tgt = _shift_target(shift_gear_prev, g, self.p.split_inverted)
                    if tgt is not None:
                        u[self.src_names.index(tgt)] += self.shift_energy / h
                    shift_gear_prev = g
                elif g != shift_gear_prev:
                    shift_gear_prev = g
                a_lag = lag_a if abs(h - dt) < 1e-12 else (1.0 - math.exp(-h / self.tau_lag) if self.tau_lag > 0 else 1.0)
                y_new = lag_y + (u - lag_y) * a_lag
                delivered = u - (self.tau_lag * (y_new - lag_y) / h if self.tau_lag > 0 else 0.0)
                lag_y = y_new
                q_nodes = self.S @ delivered
                # conductances at the current state
                G = self.ev.evaluate_cached(T[self.i_oil], speeds, row, kin.mesh_torque[row],
                                            bool(kin.low_range[row]), T, T_bc)
                # cooler
                w_eng = speeds[SPEED_NAMES.index("IS")]
                vk = float(np.interp(tm, t, v_kmh)) if v_kmh is not None else 50.0
                q0, gc = self.cooler_heat(T[self.i_oil], speeds[SPEED_NAMES.index("LS")], w_eng,
                                          T_bc[BOUNDARIES.index("coolant")], T_bc[BOUNDARIES.index("ambient")], vk)
                # oil-system inlet temperature below the sump by the cooler's drop: zero-sum transfer stream->sump
                if kind in ("liquid", "air") and q0 != 0.0:
                    op = oilprops.oil_properties(T[self.i_oil])
                    mdot = self.ev.oil_mass_flow_kg_s(speeds[SPEED_NAMES.index("LS")], op.rho_kg_m3)
                    dT_cool_oil = float(inlet_drop_k(q0, mdot * op.cp_j_per_kgk)) if mdot > 0 else 0.0
                else:
                    dT_cool_oil = 0.0
                Gs = G[self.stream_idx]
                xfer = Gs * dT_cool_oil
                q_nodes = q_nodes.copy()
                np.subtract.at(q_nodes, self.stream_nodes, xfer)    # component loses G (T_i - T_in) = G (T_i - T_s) + G dT
                q_nodes[self.i_oil] += xfer.sum()                   # ... which the returning oil brings to the sump
                # assemble (a0 C / h + L) T_new = rhs  (BDF2, implicit Euler when the step size changed)
                bdf2 = dt_prev is not None and abs(dt_prev - h) < 1e-12
                Gi = G[self.internal]
                Ge = G[~self.internal]
                Lflat = np.bincount(self.lap_idx, np.concatenate([Gi, Gi, -Gi, -Gi]), minlength=n * n)
                A = Lflat.reshape(n, n)
                diag_bc = np.bincount(self.ea, Ge, minlength=n)
                if bdf2:
                    a0 = 1.5
                    hist_term = C * (2.0 * T - 0.5 * T_prev) / h
                else:
                    a0 = 1.0
                    hist_term = C * T / h
                A[np.diag_indices(n)] += a0 * C / h + diag_bc
                rhs = hist_term + q_nodes + np.bincount(self.ea, Ge * T_bc[self.eb], minlength=n)
                # cooler linearised: Q = q0 + gc (T_oil_new - T_oil)
                A[self.i_oil, self.i_oil] += gc
                rhs[self.i_oil] += gc * T[self.i_oil] - q0
                prescribed = None
                if kind == "hold":
                    prescribed = hold_oil_c
                elif kind == "measured":
                    prescribed = float(np.interp(seg_t[k + 1], t, oil_meas))
                if prescribed is not None:
                    A[self.i_oil, :] = 0.0
                    A[self.i_oil, self.i_oil] = 1.0
                    rhs[self.i_oil] = prescribed
                T_new = np.linalg.solve(A, rhs)
                # ---- energy ledger (powers over this step)
                if bdf2:
                    dstore = C * (1.5 * T_new - 2.0 * T + 0.5 * T_prev) / h
                else:
                    dstore = C * (T_new - T) / h
                q_bc = Ge * (T_new[self.ea] - T_bc[self.eb])
                Q_cool = q0 + gc * (T_new[self.i_oil] - T[self.i_oil]) if kind in ("liquid", "air") else 0.0
                outs = np.zeros(len(HEAT_OUT_NAMES))
                outs[0] = Q_cool
                for grp in (1, 2, 3, 4):
                    outs[grp] = q_bc[self.ext_group == grp].sum()
                gen = delivered.sum()
                if prescribed is not None:
                    # what the held/measured sump absorbs = its net inflow minus its own storage change
                    om, other = self._oil_links()
                    inflow = q_nodes[self.i_oil] + float(np.dot(Gi[om], T_new[other] - T_new[self.i_oil]))
                    outs[5] = inflow - dstore[self.i_oil]
                    dstore_sum = dstore.sum()
                else:
                    dstore_sum = dstore.sum()
                E_gen += gen * h
                E_stored += dstore_sum * h
                E_out += outs * h
                E_mech += Pmech_avg[k] * h
                churn_invalid_s += churn_bad_avg[k] * h
                hist_Q[st + 1, :len(SOURCES)] = Psrc_avg[:len(SOURCES), k]
                hist_Q[st + 1, len(SOURCES)] = Pmech_avg[k]
                hist_Q[st + 1, len(SOURCES) + 1] = gen
                hist_Q[st + 1, len(SOURCES) + 2:len(SOURCES) + 2 + len(HEAT_OUT_NAMES)] = outs
                hist_Q[st + 1, -2] = Psrc_avg[self.src_names.index("retarder"), k]
                hist_Q[st + 1, -1] = dstore_sum
                T_prev, T = T, T_new
                dt_prev = h
                hist_T[st + 1] = T
                if not np.all(np.isfinite(T)):
                    raise InputError(f"the plant diverged at t = {seg_t[k + 1]:.1f} s (non-finite temperature); "
                                     f"check the inputs and parameters")
            step = s1
            prog.update(step)
        prog.close()
        warnings = []
        if churn_invalid_s > 0:
            warnings.append(f"churning correlations (Eq 28-34) used outside their validity range (Eq 33-34) for "
                            f"{churn_invalid_s:.0f} s of {t_end - t0:.0f} s (the seed's model shares this)")
        res = self._output(table, t, step_t, hist_T, hist_Q, out_dt_s, kind)
        energy = {"generated_j": E_gen, "stored_j": E_stored, "rejected_j": float(E_out.sum()),
                  "mechanical_loss_j": E_mech,
                  **{f"{nm}_j": float(v) for nm, v in zip(HEAT_OUT_NAMES, E_out)}}
        return SimResult(res, self.net.nodes, energy, warnings, time.perf_counter() - wall0)

    def _oil_links(self):
        cache = getattr(self, "_oil_link_cache", None)
        if cache is None:
            om = np.flatnonzero((self.ia == self.i_oil) | (self.ib == self.i_oil))
            other = np.where(self.ia[om] == self.i_oil, self.ib[om], self.ia[om])
            cache = self._oil_link_cache = (om, other)
        return cache

    def _output(self, table, t, step_t, hist_T, hist_Q, out_dt_s, kind) -> RunTable:
        t_out = np.arange(step_t[0], step_t[-1] + 1e-9, out_dt_s) if out_dt_s > 0 else step_t
        if t_out[-1] < step_t[-1] - 1e-9:
            t_out = np.append(t_out, step_t[-1])
        cols = {"time_s": t_out}
        idx = np.clip(np.searchsorted(t, t_out, side="right") - 1, 0, t.size - 1)
        for c in ("engine_speed_rpm", "engine_torque_nm", "gear", "vehicle_speed_kmh", "ambient_temp_c",
                  "coolant_temp_c", "retarder_torque_nm"):
            if table.has(c):
                cols[c] = np.asarray(table[c], dtype=float)[idx]
        # node temperatures, linear between thermal steps
        T_out = np.empty((t_out.size, self.n))
        for j in range(self.n):
            T_out[:, j] = np.interp(t_out, step_t, hist_T[:, j])
        oil = T_out[:, self.i_oil]
        if self.sensor_tau > 0:
            # the vehicle's oil sensor lags the sump (effect oil_sensor_lag)
            oil_s = np.interp(step_t, step_t, hist_T[:, self.i_oil])
            y = np.empty_like(oil_s)
            y[0] = oil_s[0]
            for i in range(1, oil_s.size):
                a = 1.0 - math.exp(-(step_t[i] - step_t[i - 1]) / self.sensor_tau)
                y[i] = y[i - 1] + (oil_s[i] - y[i - 1]) * a
            oil = np.interp(t_out, step_t, y)
        if kind == "measured" and table.has("oil_temp_c"):
            cols["oil_temp_c"] = np.interp(t_out, t, np.asarray(table["oil_temp_c"], dtype=float))
        else:
            cols["oil_temp_c"] = oil
        for j, nm in enumerate(self.net.nodes):
            cols[f"T_{nm}_c"] = T_out[:, j]
        # heat flows: step averages, each output sample shows the step that ends at or after it
        qi = np.clip(np.searchsorted(step_t, t_out, side="left"), 1, step_t.size - 1)
        names = [f"Q_heat_{s.replace(':', '_')}_w" for s in SOURCES] + ["Q_loss_mechanical_total_w",
                                                                          "Q_heat_total_w"] + \
                [f"Q_out_{nm}_w" for nm in HEAT_OUT_NAMES] + ["Q_heat_retarder_w", "Q_stored_w"]
        for j, nm in enumerate(names):
            cols[nm] = hist_Q[qi, j]
        out = RunTable(cols)
        return out


class _StepAverager:
    """Exact averages of zero-order-held samples over the intervals between consecutive edges."""

    def __init__(self, tt, dts, edges):
        knots = np.append(tt, tt[-1] + dts[-1])
        self.dts = dts
        idx = np.clip(np.searchsorted(knots, edges, side="right") - 1, 0, knots.size - 2)
        span = knots[idx + 1] - knots[idx]
        self.idx = idx
        self.frac = np.where(span > 0, (edges - knots[idx]) / np.where(span > 0, span, 1.0), 0.0)[:, None]
        dur = np.diff(edges)
        self.inv = (1.0 / np.where(dur > 0, dur, 1.0))[:, None]

    def __call__(self, x):
        X = np.asarray(x, dtype=float).reshape(self.dts.size, -1)
        cum = np.vstack([np.zeros((1, X.shape[1])), np.cumsum(X * self.dts[:, None], axis=0)])
        F = cum[self.idx] + self.frac * (cum[self.idx + 1] - cum[self.idx])
        return (np.diff(F, axis=0) * self.inv).T


def _shift_target(g_from: int, g_to: int, inverted: bool):
    if g_to == 0:
        return None
    a, b = gear_state(g_from, inverted), gear_state(g_to, inverted)
    if b.main_pair is not None and b.main_pair != a.main_pair and b.main_pair in ("3", "2", "1"):
        return f"shift:{dict(zip('321', ('3M', '2M', '1M')))[b.main_pair]}"
    if b.split_pair != a.split_pair:
        return "shift:LI" if b.split_pair == "L" else "shift:3M"
    if b.range != a.range and a.range is not None:
        return "shift:PR"
    return None


def _validate_inputs(t, spd, trq, gear, p: Parameters):
    def first_bad(mask):
        return int(np.flatnonzero(mask)[0]) + 1
    for name, arr in (("time_s", t), ("engine_speed_rpm", spd), ("engine_torque_nm", trq), ("gear", gear)):
        bad = ~np.isfinite(arr)
        if bad.any():
            raise InputError(f"column {name} row {first_bad(bad)}: value is missing or not a number")
    if np.any(np.diff(t) <= 0):
        raise InputError(f"column time_s row {first_bad(np.append(np.diff(t) <= 0, False)) + 1}: time must increase")
    if np.any(spd < 0):
        raise InputError(f"column engine_speed_rpm row {first_bad(spd < 0)}: negative speed {spd[spd < 0][0]:g} rpm")
    vmax = p["engine.max_speed_rad_s"] / RPM
    if np.any(spd > vmax):
        raise InputError(f"column engine_speed_rpm row {first_bad(spd > vmax)}: {spd[spd > vmax][0]:g} rpm exceeds "
                         f"{vmax:.0f} rpm")
    tmax, tmin = p["engine.max_torque"], p["engine.min_torque"]
    bad = (trq > tmax) | (trq < tmin)
    if bad.any():
        raise InputError(f"column engine_torque_nm row {first_bad(bad)}: {trq[bad][0]:g} Nm is outside the engine's "
                         f"range {tmin:g}..{tmax:g} Nm")
    bad = (gear != np.round(gear)) | (gear < GEAR_MIN) | (gear > GEAR_MAX)
    if bad.any():
        raise InputError(f"column gear row {first_bad(bad)}: {gear[bad][0]:g} is not a gear in {GEAR_MIN}..{GEAR_MAX} "
                         f"(seed Table 1)")


class _Progress:
    """A plain progress bar on stderr for long runs (only when attached to a terminal, or forced)."""

    def __init__(self, total: int, enabled: bool | None):
        self.total = max(total, 1)
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.t0 = time.perf_counter()
        self.last = 0.0

    def update(self, done: int):
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self.last < 0.2 and done < self.total:
            return
        self.last = now
        frac = done / self.total
        bar = "#" * int(30 * frac)
        el = now - self.t0
        eta = el / frac - el if frac > 0 else 0.0
        sys.stderr.write(f"\r  plant [{bar:<30}] {100 * frac:5.1f} %  {el:5.1f} s elapsed, {eta:5.1f} s left")
        sys.stderr.flush()

    def close(self):
        if self.enabled:
            sys.stderr.write("\n")
            sys.stderr.flush()
