"""The reference plant: the thesis's full gearbox thermal network, integrated fast and stiff-safe.

Inputs are a run table (any sample rate, irregular allowed; values are held until the next sample). Mechanical
losses are evaluated for every input sample (vectorised, oil properties at the sump temperature of the current
chunk) and averaged exactly over each thermal step, so 100 Hz noisy signals cost no solver steps (the thesis's
commercial tool crawled on them, seed chapter 7). The network is integrated with BDF2 (A-stable, second order;
implicit Euler on the first step and after a step-size change) with conductances evaluated once per step from the
step's mean shaft speeds, its dominant gear and the sump temperature; radiation and the cooler are linearised
around the current temperatures. Every joule is booked: generated heat = stored + rejected (+ what a held or
measured sump absorbs), checked by `SimResult.energy_balance()`. `ReferencePlant.run` is the driver (chunks of
steps: losses of every input sample, averaged over each step); `ReferencePlant._step` is one thermal step.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from firmware_model.description import OIL_INLET, description_of
from firmware_model.effects import effect_scales, with_oil_volume
from firmware_model.errors import InputError
from firmware_model.network import (
    BOUNDARIES,
    K_EXT_CONV,
    K_EXT_RAD,
    K_STREAM,
    ConductanceEvaluator,
    Network,
    build_network,
)
from firmware_model.parameters import COOLER_KINDS, Parameters
from firmware_model.physics import oil as oilprops
from firmware_model.physics.conductance_matrix import (
    boundary_heat_w,
    conductance_matrix,
    internal_laplacian_w_per_k,
    link_topology,
)
from firmware_model.physics.cooler import (
    AIR_RECIRC_V_KMH,
    DEFAULT_VEHICLE_SPEED_KMH,
    cooler_params,
    cooler_values,
    heater_heat_w,
    inlet_drop_k,
    oil_cooler_heat,
)
from firmware_model.physics.gearbox_losses import GearboxLosses
from firmware_model.physics.heat_lag import HeatLag, first_order_lag_step, heat_lag, heat_lag_step
from firmware_model.physics.kinematics import GEAR_MAX, GEAR_MIN, gear_state
from firmware_model.units import RAD_S_PER_RPM
from tools.drive_table import FIXED_RATIO_NAMES
from tools.plant.held import N_OUT, HeldIntegrator, takes_held_path
from tools.progress import progress as progress_bar
from tools.runtable import RunTable, row_namer


def bc_columns(boundaries) -> dict:
    """Run-table column -> boundary name of a gearbox's boundaries (its description's, in their order): a bc_<name>_c
    column each, plus the contract's ambient_temp_c and coolant_temp_c where it has those boundaries."""
    cols = {f"bc_{b}_c": b for b in boundaries}
    cols.update({f"{b}_temp_c": b for b in ("ambient", "coolant") if b in boundaries})
    return cols


#: run-table column -> boundary name of the GRS905 (network.BOUNDARIES); a plant takes its gearbox's (bc_columns)
BC_COLUMNS = bc_columns(BOUNDARIES)
#: step of the forward difference that linearises the cooler around the sump temperature [K]
COOLER_SLOPE_DT_K = 0.05

HEAT_OUT_NAMES = (
    "cooler",
    "housing_convection",
    "housing_radiation",
    "supports_conduction",
    "shafts_conduction",
    "oil_boundary",
)
assert len(HEAT_OUT_NAMES) == N_OUT  # the held path's books (tools/plant/held.py)


#: a run notes the churning correlations' validity only when they left their range for less than this share of it
CHURN_NOTE_SHARE = 0.99
#: the losses of a chunk of steps are evaluated at its starting sump temperature; a chunk ends early when the sump
#: has moved this far [K] (the oil's viscosity, and with it the losses, changes 2-10 %/K; on a loaded cold start the
#: sump moves a kelvin a second, and a whole 20-s chunk at its starting viscosity overstated the losses many times)
CHUNK_OIL_MOVE_K = 0.25


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


class RunInputs(NamedTuple):
    """A run table as the integrator reads it (SI; boundary and oil signals interpolated onto the input times)."""

    t_s: np.ndarray
    omega_in_rad_s: np.ndarray
    torque_nm: np.ndarray
    gear: np.ndarray  # int64
    v_kmh: np.ndarray | None
    retarder_nm: np.ndarray | None  # NaN taken as 0
    bc_c: dict  # boundary index -> its temperature at every input time
    oil_meas_c: np.ndarray | None  # measured sump (cooler 'measured')
    kind: str  # none | liquid | air | hold | measured
    hold_oil_c: float | None
    initial_temp_c: float


class ChunkSources(NamedTuple):
    """The sources of a chunk of thermal steps: exact averages over each step of the held input samples."""

    edges_s: np.ndarray  # (k + 1,) step edges
    P_src_w: np.ndarray  # (n_src, k) heat of every source
    P_mech_w: np.ndarray  # (k,) mechanical loss
    omega_rad_s: np.ndarray  # (n_speeds, k) |shaft speeds|
    churn_invalid: np.ndarray  # (k,) share of the step outside the churning correlations' range
    gear: np.ndarray  # (k,) the gear in force at each step's middle
    T_bc_c: np.ndarray  # (k, n_boundaries) boundary temperatures at each step's end
    v_kmh: np.ndarray | None  # (k,) vehicle speed at each step's middle (None: no column)
    oil_meas_c: np.ndarray | None  # (k,) the measured sump at each step's end (None: not measured)


@dataclass
class StepState:
    """The integrator's state between thermal steps."""

    T_c: np.ndarray
    T_prev_c: np.ndarray
    dt_prev_s: float | None
    lag_w: np.ndarray  # heat-lag state of every source
    gear_prev: int  # gear of the last step (synchronizer shift heat)


class StepResult(NamedTuple):
    T_new_c: np.ndarray
    generated_w: float  # heat delivered by all sources
    stored_w: float  # d(stored energy)/dt over the step
    out_w: np.ndarray  # (len(HEAT_OUT_NAMES),) heat leaving by each path


@dataclass
class Ledger:
    """Histories and the energy books of a run."""

    T_c: np.ndarray  # (n_steps + 1, n)
    Q_w: np.ndarray  # (n_steps + 1, n_q) the Q_ columns of the output
    out_j: np.ndarray  # (len(HEAT_OUT_NAMES),) heat out by each path
    generated_j: float = 0.0
    stored_j: float = 0.0
    mechanical_j: float = 0.0
    churn_invalid_s: float = 0.0
    n_sources: int = 0  # the loss sources of the gearbox (GearboxLosses.sources)

    def book(self, step: int, res: StepResult, cs: ChunkSources, k: int, h_s: float, i_retarder: int) -> None:
        """Books thermal step ``step`` (the k-th of its chunk, length h_s)."""
        self.generated_j += res.generated_w * h_s
        self.stored_j += res.stored_w * h_s
        self.out_j += res.out_w * h_s
        self.mechanical_j += cs.P_mech_w[k] * h_s
        self.churn_invalid_s += cs.churn_invalid[k] * h_s
        ns, no = self.n_sources, len(HEAT_OUT_NAMES)
        q = self.Q_w[step + 1]
        q[:ns] = cs.P_src_w[:ns, k]
        q[ns] = cs.P_mech_w[k]
        q[ns + 1] = res.generated_w
        q[ns + 2 : ns + 2 + no] = res.out_w
        q[-2] = cs.P_src_w[i_retarder, k]
        q[-1] = res.stored_w
        self.T_c[step + 1] = res.T_new_c

    def energy(self) -> dict:
        return {
            "generated_j": self.generated_j,
            "stored_j": self.stored_j,
            "rejected_j": float(self.out_j.sum()),
            "mechanical_loss_j": self.mechanical_j,
            **{f"{nm}_j": float(v) for nm, v in zip(HEAT_OUT_NAMES, self.out_j)},
        }


class ReferencePlant:
    """Build once per parameter set and effect set, then `run()` any number of run tables."""

    def __init__(self, params: Parameters, effects: dict | None = None, cooler: str | None = None, dt_s: float = 0.5):
        self.effects = dict(effects or {})
        self.scales = effect_scales(self.effects)
        self.p = params = with_oil_volume(params, self.scales.oil_volume_l)
        self.kind = cooler or params.strings.get("cooler.kind", "liquid")
        if self.kind not in COOLER_KINDS:
            raise InputError(f"cooler {self.kind!r} must be one of {', '.join(COOLER_KINDS)}")
        if not 0.01 <= dt_s <= 5.0:
            raise InputError(f"plant time step {dt_s} s is outside 0.01..5 s")
        self.dt = float(dt_s)
        self.net: Network = build_network(params)
        self.losses = GearboxLosses(params, self.net.geometry)
        self.sources = self.losses.sources  # the gearbox's loss sources (the GRS905's: gearbox_losses.SOURCES)
        d = self.net.geometry.description
        names = self.losses.kin.speed_names
        # the speeds the cooler and the retarder read: the oil pump's shaft (a motor pump: none), the input shaft
        # (the engine of a vehicle: the liquid cooler's coolant flow) and the output shaft (the retarder)
        self.i_pump = None if d.oil.pump_shaft is None else names.index(d.oil.pump_shaft)
        self.i_input, self.i_output = names.index(d.drive.input_shaft), names.index(d.drive.output_shaft)
        # a stationary machine (no vehicle) without a vehicle-speed column: its air cooler sees its fan's air and no
        # recirculated air (the recirculation table's end); a vehicle without one: the cooler model's default speed
        self.v_default_kmh = DEFAULT_VEHICLE_SPEED_KMH if d.drive.kind == "vehicle" else float(AIR_RECIRC_V_KMH[-1])
        self.drive = d.drive
        self.ev = ConductanceEvaluator(self.net, params, self.scales)
        self.n = n = self.net.n
        self.i_oil = self.net.index("oil")
        self.topo = link_topology(self.net.link_a, self.net.link_b, n)
        # classify boundary links for the heat budget
        kinds = self.net.link_kind[self.topo.ext_idx]
        self.boundaries = self.net.boundaries
        self.bc_columns = bc_columns(self.boundaries)
        # conduction to a boundary: through the supports (a housing touches it: the GRS905's flywheel cover and
        # support beam) or along the shafts (its engine shaft and end yoke)
        housings = [self.net.index(h.id) for h in d.housings]
        at_housing = np.isin(self.net.link_a[self.topo.ext_idx], housings)
        self.ext_group = np.where(kinds == K_EXT_CONV, 1, np.where(kinds == K_EXT_RAD, 2, np.where(at_housing, 3, 4)))
        self.ext_group_links = [np.flatnonzero(self.ext_group == grp) for grp in (1, 2, 3, 4)]
        # source distribution matrix: node heat = S @ source heat
        # the synchronizers' shift heat: one source per wheel a shift heats, as the network's description has them
        shifts = [s for s in self.net.sources if s.startswith("shift:")]
        self.src_names = list(self.sources) + ["retarder", *shifts]
        self.S = np.zeros((n, len(self.src_names)))
        for j, s in enumerate(self.src_names):
            for node, frac in self.net.sources[s]:
                self.S[node, j] += frac
        self.stream_idx = self.net.links_of_kind(K_STREAM)
        self.stream_nodes = self.net.link_a[self.stream_idx]
        ia, ib = self.topo.ia, self.topo.ib
        self.oil_links = np.flatnonzero((ia == self.i_oil) | (ib == self.i_oil))  # internal links at the sump
        self.oil_other = np.where(ia[self.oil_links] == self.i_oil, ib[self.oil_links], ia[self.oil_links])
        self.tau_lag = params["scale.heat_lag_tau"]
        self.bc_default = np.array([bd.temperature_c for bd in self.net.geometry.description.boundaries])
        if "hot_surroundings" in self.boundaries:
            self.bc_default[self.boundaries.index("hot_surroundings")] += self.scales.hot_offset_c
        self.cooler = cooler_params(cooler_values(params))
        self._laplacian, self._laplacian_key = None, None

    # ------------------------------------------------------------------ cooler (seed 3.4, Eq 82-83)
    def _pump_speed(self, omega: np.ndarray) -> float:
        """|speed| of the oil pump's shaft (the GRS905's layshaft); a motor-driven pump's flow is fixed, but it may
        stop with the machine (oil.pump_stops_below): the input shaft's speed, which its flow reads
        (network.ConductanceEvaluator.oil_mass_flow_kg_s)."""
        return omega[self.i_input] if self.i_pump is None else omega[self.i_pump]

    def _bc_or_nan(self, T_bc, name: str) -> float:
        """A boundary's temperature; NaN for one the gearbox lacks (the coolant of a gearbox without a liquid
        cooler: the coolers read only their own)."""
        return T_bc[self.boundaries.index(name)] if name in self.boundaries else math.nan

    def cooler_heat(self, T_oil, w_ls, w_eng, T_cool, T_amb, v_kmh, slope: bool = True):
        """Heat from the sump to the cooler [W] (physics.cooler.oil_cooler_heat, the onboard model's cooler), net of
        the sump heater's (physics.cooler.heater_heat_w), and its derivative with respect to the sump temperature
        (forward difference over COOLER_SLOPE_DT_K; 0 without ``slope``)."""
        q_w, g_w_per_k = self._cooler_alone(T_oil, w_ls, w_eng, T_cool, T_amb, v_kmh, slope)
        if not self.cooler.heater_w > 0.0 or self.kind in ("hold", "measured"):
            return q_w, g_w_per_k
        h0_w = heater_heat_w(self.cooler, T_oil)
        if slope:
            g_w_per_k += (h0_w - heater_heat_w(self.cooler, T_oil + COOLER_SLOPE_DT_K)) / COOLER_SLOPE_DT_K
        return q_w - h0_w, g_w_per_k

    def _cooler_alone(self, T_oil, w_ls, w_eng, T_cool, T_amb, v_kmh, slope: bool):
        """The cooler's heat and slope of :meth:`cooler_heat`, without the heater."""
        if self.kind not in ("liquid", "air"):
            return 0.0, 0.0
        op = self.ev.oil.properties(T_oil)
        mdot_kg_s = self.ev.oil_mass_flow_kg_s(w_ls, op.rho_kg_m3)
        if mdot_kg_s <= 0:
            return 0.0, 0.0
        # the oil flow over the data sheet's: a shaft pump's at the reference speed, a motor pump's is its own
        flow_ratio = (
            1.0
            if self.i_pump is None
            else mdot_kg_s / self.ev.oil_mass_flow_kg_s(self.cooler.ref_ls_speed_rad_s, op.rho_kg_m3)
        )
        mcp_w_per_k = mdot_kg_s * op.cp_j_per_kgk
        sc = self.scales

        # the sump and the slope's second point in one call: the cooler's law is element-wise, so each value is
        # the one a scalar call gives
        T_eval = T_oil if not slope else np.array([T_oil, T_oil + COOLER_SLOPE_DT_K])
        q = oil_cooler_heat(
            self.cooler,
            self.kind,
            T_eval,
            flow_ratio,
            w_eng,
            T_cool,
            T_amb,
            v_kmh,
            mcp_w_per_k,
            sc.cooler_scale,
            sc.thermostat_offset_c,
        )
        if q.hA_w_per_k <= 0:
            return 0.0, 0.0
        if not slope:
            return float(q.Q_w), 0.0
        q0_w, q1_w = q.Q_w.tolist()
        return q0_w, max((q1_w - q0_w) / COOLER_SLOPE_DT_K, 0.0)

    # ------------------------------------------------------------------ driver
    def run(
        self,
        table: RunTable,
        initial_temp_c: float | None = None,
        hold_oil_c: float | None = None,
        out_dt_s: float = 1.0,
        progress: bool | None = None,
        chunk_s: float = 20.0,
        initial_offsets_c: dict | None = None,
        held: bool | None = None,
    ) -> SimResult:
        """Integrate the network over the run table; node temperatures and heat flows every ``out_dt_s``.
        ``initial_temp_c``/``hold_oil_c`` given: within the oil model's range (InputError otherwise).
        ``initial_offsets_c``: {node: K} added to those nodes' start (a gearbox that ran before the table began:
        its housings lag the oil; the diagnosis fits that offset, tools/diagnosis/start.py). ``held``: integrate
        row interval by row interval in long exact steps (tools/plant/held.py; None: when the table is a fixed-ratio
        drive's whose rows are slower than the step, held.takes_held_path)."""
        wall0 = time.perf_counter()
        for label, value_c in (("initial_temp_c", initial_temp_c), ("hold_oil_c", hold_oil_c)):
            if value_c is not None:
                oilprops.check_temperature_c(label, value_c)
        inp = self._inputs(table, initial_temp_c, hold_oil_c)
        t = inp.t_s
        dt = self.dt
        t0, t_end = float(t[0]), float(t[-1])
        n_steps = int(math.ceil((t_end - t0) / dt - 1e-9))
        step_t = np.minimum(t0 + dt * np.arange(n_steps + 1), t_end)
        dts = np.diff(t, append=t[-1])  # sample durations (zero-order hold; the last has none)
        T = np.full(self.n, float(inp.initial_temp_c))
        for name, dT in (initial_offsets_c or {}).items():
            if name not in self.net.nodes or name == "oil" or not math.isfinite(float(dT)):
                raise InputError(
                    f"initial_offsets_c: {name!r} is not a node of the network other than the sump, "
                    f"or its offset {dT!r} is not a finite number"
                )
            T[self.net.nodes.index(name)] += float(dT)
        if inp.kind == "hold":
            T[self.i_oil] = inp.hold_oil_c
        elif inp.kind == "measured":
            T[self.i_oil] = inp.oil_meas_c[0]
        if held or (held is None and takes_held_path(table, inp.kind, dt, self.scales)):
            return self._run_held(table, inp, T, out_dt_s, wall0)
        state = StepState(T, T.copy(), None, np.zeros(len(self.src_names)), int(inp.gear[0]))
        ledger = self._ledger(n_steps, T)
        lag_dt = heat_lag(self.tau_lag, dt)
        i_ret = self.src_names.index("retarder")
        k_chunk = max(1, int(round(chunk_s / dt)))
        with progress_bar(n_steps, "plant", progress, unit="step") as bar:
            s0 = 0
            while s0 < n_steps:
                s1 = min(s0 + k_chunk, n_steps)
                T_chunk_c = float(state.T_c[self.i_oil])
                cs = self._chunk_sources(inp, dts, step_t[s0 : s1 + 1], T_chunk_c)
                done = s1 - s0
                for k in range(s1 - s0):
                    h = cs.edges_s[k + 1] - cs.edges_s[k]
                    if h <= 0:
                        ledger.T_c[s0 + k + 1] = state.T_c
                        continue
                    res = self._step(state, inp, cs, k, lag_dt if abs(h - dt) < 1e-12 else heat_lag(self.tau_lag, h))
                    ledger.book(s0 + k, res, cs, k, h, i_ret)
                    if not np.all(np.isfinite(res.T_new_c)):
                        raise InputError(
                            f"the plant diverged at t = {cs.edges_s[k + 1]:.1f} s (non-finite "
                            f"temperature); check the inputs and parameters"
                        )
                    if abs(state.T_c[self.i_oil] - T_chunk_c) > CHUNK_OIL_MOVE_K:
                        done = k + 1  # the losses again at the sump's new temperature
                        break
                bar.update(done)
                s0 += done
        res = self._output(table, inp, step_t, ledger.T_c, ledger.Q_w, out_dt_s)
        warnings = _churn_note(ledger.churn_invalid_s, t_end - t0) + self._range_notes(ledger.T_c, step_t)
        return SimResult(res, self.net.nodes, ledger.energy(), warnings, time.perf_counter() - wall0)

    def _run_held(self, table: RunTable, inp: RunInputs, T0_c: np.ndarray, out_dt_s: float, wall0: float):
        """The held path of :meth:`run` (tools/plant/held.py): the state at every row time, the books."""
        if inp.kind not in ("none", "liquid", "air"):
            raise InputError(f"the held path integrates a modelled sump (cooler none, liquid or air), not {inp.kind}")
        ledger = self._ledger(inp.t_s.size - 1, T0_c)
        rows = HeldIntegrator(self, inp).run(T0_c, ledger.Q_w.shape[1])
        ledger.T_c, ledger.Q_w, ledger.out_j = rows.T_c, rows.Q_w, rows.out_j
        ledger.generated_j, ledger.stored_j, ledger.mechanical_j = rows.generated_j, rows.stored_j, rows.mechanical_j
        ledger.churn_invalid_s = rows.churn_invalid_s
        t = inp.t_s
        res = self._output(table, inp, t, ledger.T_c, ledger.Q_w, out_dt_s)
        res.meta.update(held_sub_intervals=rows.sub_intervals)
        warnings = _churn_note(ledger.churn_invalid_s, float(t[-1] - t[0])) + self._range_notes(ledger.T_c, t)
        return SimResult(res, self.net.nodes, ledger.energy(), warnings, time.perf_counter() - wall0)

    def _range_notes(self, T_c: np.ndarray, t_s: np.ndarray) -> list:
        """The run's notes where it left the oil model (docs/physics.md, "Oil properties"): a part hotter than the
        T_MAX_C its properties are defined to (clipped there), a sump thicker than SAE J306's coldest use."""
        notes = []
        hot = T_c > oilprops.T_MAX_C
        if hot.any():
            names = [self.net.nodes[j] for j in np.flatnonzero(hot.any(axis=0))]
            notes.append(
                f"{', '.join(names[:4])}{' and more' if len(names) > 4 else ''} reached {float(T_c.max()):.0f} degC "
                f"(from t = {float(t_s[np.argmax(hot.any(axis=1))]):.0f} s), above the {oilprops.T_MAX_C:g} degC the "
                "oil's properties are defined to: the run has left the model there (a loaded start in oil too thick "
                'for its loss laws: docs/physics.md, "Oil properties")'
            )
        cold_c = self.ev.oil.temperature_at_mu_c(oilprops.COLDEST_USE_MU_PA_S)
        if cold_c > oilprops.T_MIN_C and (T_c[:, self.i_oil] < cold_c).any():
            notes.append(
                f"the sump was below {cold_c:.0f} degC, where its oil is thicker than {oilprops.COLDEST_USE_MU_PA_S:g} "
                "Pa s (SAE J306's coldest use of a gear oil): the loss model is extrapolated there"
            )
        return notes

    def _ledger(self, n_steps: int, T0_c: np.ndarray) -> Ledger:
        """Empty books for a run of ``n_steps`` thermal steps starting at node temperatures ``T0_c``."""
        n_q = len(self.sources) + 4 + len(HEAT_OUT_NAMES)
        ledger = Ledger(
            np.empty((n_steps + 1, self.n)),
            np.zeros((n_steps + 1, n_q)),
            np.zeros(len(HEAT_OUT_NAMES)),
            n_sources=len(self.sources),
        )
        ledger.T_c[0] = T0_c
        return ledger

    def _inputs(self, table: RunTable, initial_temp_c, hold_oil_c) -> RunInputs:
        """The run table checked and read (columns of the run-table contract; bc_ columns override the defaults)."""
        t = np.asarray(table["time_s"], dtype=float)
        if t.size < 2:
            raise InputError("the run table needs at least two samples")
        spd = np.asarray(table["engine_speed_rpm"], dtype=float)
        trq = np.asarray(table["engine_torque_nm"], dtype=float)
        gear = np.asarray(table["gear"], dtype=float)
        _validate_inputs(t, spd, trq, gear, self.p, row_namer(table))
        meta = getattr(table, "meta", {}) or {}
        if initial_temp_c is None:
            initial_temp_c = meta.get("initial_temp_c")
        if initial_temp_c is not None:
            oilprops.check_temperature_c("the run table's initial_temp_c", initial_temp_c)
        if initial_temp_c is None and table.has("oil_temp_c") and np.isfinite(table["oil_temp_c"][0]):
            # the start: every node at the first oil reading (the oil model's range, as --initial-temp)
            initial_temp_c = oilprops.check_temperature_c(
                "column oil_temp_c row 1 (the start temperature):", float(table["oil_temp_c"][0])
            )
        if hold_oil_c is None:
            hold_oil_c = meta.get("hold_oil_c")
        kind = self.kind
        if hold_oil_c is not None and kind not in ("measured",):
            kind = "hold"
        if kind == "hold" and hold_oil_c is None:
            hold_oil_c = self.p["cooler.hold_temp"]
        if initial_temp_c is None:  # a held sump: every node starts there (as the named cycles do), else the default
            initial_temp_c = float(hold_oil_c) if kind == "hold" else self.p["boundary.initial"]
        oil_meas = None
        if kind == "measured":
            if not table.has("oil_temp_c"):
                raise InputError("cooler 'measured' needs an oil_temp_c column in the run table")
            oil_meas = np.asarray(table["oil_temp_c"], dtype=float)
            ok = np.isfinite(oil_meas)
            if ok.sum() < 2:
                raise InputError("cooler 'measured': column oil_temp_c has fewer than two valid values")
            _check_range("oil_temp_c", oil_meas, ok, oilprops.T_MIN_C, oilprops.T_MAX_C)
            oil_meas = np.interp(t, t[ok], oil_meas[ok])
        bc_c = {}
        for col, b in self.bc_columns.items():
            if table.has(col):
                v = np.asarray(table[col], dtype=float)
                ok = np.isfinite(v)
                _check_range(col, v, ok, *BC_RANGE_C)
                if ok.any():
                    bc_c[self.boundaries.index(b)] = np.interp(t, t[ok], v[ok]) + (
                        self.scales.hot_offset_c if b == "hot_surroundings" else 0.0
                    )
        v_kmh = None
        if table.has("vehicle_speed_kmh"):  # empty cells interpolated as the bc_ columns (a NaN speed would
            v = np.asarray(table["vehicle_speed_kmh"], dtype=float)  # switch the air cooler off); none: default
            ok = np.isfinite(v)
            v_kmh = np.interp(t, t[ok], v[ok]) if ok.any() else None
        ret_nm = np.asarray(table["retarder_torque_nm"], dtype=float) if table.has("retarder_torque_nm") else None
        if ret_nm is not None:
            ret_nm = np.nan_to_num(ret_nm, nan=0.0)
        return RunInputs(
            t,
            spd * RAD_S_PER_RPM,
            trq,
            gear.astype(np.int64),
            v_kmh,
            ret_nm,
            bc_c,
            oil_meas,
            kind,
            hold_oil_c,
            initial_temp_c,
        )

    def _chunk_sources(self, inp: RunInputs, dts: np.ndarray, edges: np.ndarray, T_oil_c: float) -> ChunkSources:
        """Losses of every input sample of a chunk of steps (oil properties at the chunk's start sump temperature),
        their heat, and their exact averages over each step."""
        t, n_s = inp.t_s, inp.t_s.size
        i0 = max(int(np.searchsorted(t, edges[0], side="right")) - 1, 0)
        i1 = min(int(np.searchsorted(t, edges[-1], side="left")) + 1, n_s)
        sl = slice(i0, i1)
        w_in, gear = inp.omega_in_rad_s[sl], inp.gear[sl]
        loss = self.losses.evaluate(w_in, inp.torque_nm[sl], gear, T_oil_c, churn_validity=True)
        churn_ok = loss.pop("churning_valid")
        heat = self.losses.heat(loss, self.scales)
        P_src = np.zeros((i1 - i0, len(self.src_names)))
        for j, nm in enumerate(self.sources):
            P_src[:, j] = heat[nm]
        P_mech = np.sum([loss[k] for k in self.sources], axis=0)
        sp = self.losses.kin.speed[gear - GEAR_MIN] * w_in[:, None]
        if inp.retarder_nm is not None and self.scales.retarder_frac > 0:
            # the braking torque's magnitude, as the onboard sensor and the CAN encoder take it (J1939 sends braking
            # negative; a table in that sign would give the plant no heat and its own CAN log 3 kNm)
            P_src[:, self.src_names.index("retarder")] = (
                self.scales.retarder_frac * np.abs(inp.retarder_nm[sl]) * np.abs(sp[:, self.i_output])
            )
        avg = _StepAverager(t[sl], dts[sl], edges)
        # the step's gear, boundaries and vehicle speed, for every step of the chunk at once (np.interp element by
        # element: the same values as one call per step)
        t_b, t_mid = edges[1:], 0.5 * (edges[:-1] + edges[1:])
        im = np.clip(np.searchsorted(t, t_mid, side="right") - 1, 0, t.size - 1)
        T_bc = np.tile(self.bc_default, (t_b.size, 1))
        for j, arr in inp.bc_c.items():
            T_bc[:, j] = np.interp(t_b, t, arr)
        v_kmh = np.interp(t_mid, t, inp.v_kmh) if inp.v_kmh is not None else None
        oil_meas_c = np.interp(t_b, t, inp.oil_meas_c) if inp.kind == "measured" else None
        return ChunkSources(
            edges,
            avg(P_src),
            avg(P_mech)[0],
            avg(np.abs(sp)),
            avg((~churn_ok).astype(float))[0],
            inp.gear[im],
            T_bc,
            v_kmh,
            oil_meas_c,
        )

    # ------------------------------------------------------------------ one thermal step
    def _step(self, state: StepState, inp: RunInputs, cs: ChunkSources, k: int, lag: HeatLag) -> StepResult:
        """One BDF2 step (implicit Euler on the first step and after a change of step size) of
        (a0 C / h + K) T_new = C (history) / h + sources, with the cooler linearised around the sump temperature;
        updates ``state``."""
        h = cs.edges_s[k + 1] - cs.edges_s[k]
        gear = int(cs.gear[k])
        row = gear - GEAR_MIN
        omega = cs.omega_rad_s[:, k]
        T, i_oil = state.T_c, self.i_oil
        T_bc = cs.T_bc_c[k]  # boundary temperatures at the step end
        delivered = self._delivered_heat(state, cs.P_src_w[:, k].copy(), gear, h, lag)
        kin = self.losses.kin
        G = self.ev.evaluate_cached(T[i_oil], omega, row, kin.mesh_torque[row], bool(kin.low_range[row]), T, T_bc)
        v_kmh = float(cs.v_kmh[k]) if cs.v_kmh is not None else self.v_default_kmh
        q0, gc = self.cooler_heat(
            T[i_oil],
            self._pump_speed(omega),
            omega[self.i_input],
            self._bc_or_nan(T_bc, "coolant"),
            self._bc_or_nan(T_bc, "ambient"),
            v_kmh,
        )
        q_nodes = self._stream_transfer(self.S @ delivered, G, q0, omega, T[i_oil], inp.kind)
        bdf2 = state.dt_prev_s is not None and abs(state.dt_prev_s - h) < 1e-12
        C = self.net.C_j_per_k
        if bdf2:
            a0 = 1.5
            hist_term = C * (2.0 * T - 0.5 * state.T_prev_c) / h
        else:
            a0 = 1.0
            hist_term = C * T / h
        if self._laplacian_key != (id(G), self.ev.generation):  # node-node links changed: their part of K again
            self._laplacian = internal_laplacian_w_per_k(G, self.topo)
            self._laplacian_key = (id(G), self.ev.generation)
        A, Ge = conductance_matrix(G, self.topo, a0 * C / h, self._laplacian)
        rhs = hist_term + q_nodes + boundary_heat_w(Ge, self.topo, T_bc)
        A[i_oil, i_oil] += gc  # cooler linearised: Q = q0 + gc (T_oil_new - T_oil)
        rhs[i_oil] += gc * T[i_oil] - q0
        prescribed = None
        if inp.kind == "hold":
            prescribed = inp.hold_oil_c
        elif inp.kind == "measured":
            prescribed = float(cs.oil_meas_c[k])
        if prescribed is not None:
            A[i_oil, :] = 0.0
            A[i_oil, i_oil] = 1.0
            rhs[i_oil] = prescribed
        T_new = _solve(A, rhs)
        if bdf2:
            dstore = C * (1.5 * T_new - 2.0 * T + 0.5 * state.T_prev_c) / h
        else:
            dstore = C * (T_new - T) / h
        out = self._heat_out(G, Ge, T, T_new, T_bc, q0, gc, q_nodes, dstore, inp.kind, prescribed)
        state.T_prev_c, state.T_c, state.dt_prev_s = T, T_new, h
        return StepResult(T_new, delivered.sum(), dstore.sum(), out)

    def _delivered_heat(self, state: StepState, u_w: np.ndarray, gear: int, h: float, lag: HeatLag) -> np.ndarray:
        """The sources' heat through the heat lag (exact for an input held over the step), with the synchronizer's
        shift heat (effect synchronizer_shift_heat) released over the step of a gear change; updates ``state``."""
        shift_energy = self.scales.shift_energy_j
        if gear != state.gear_prev:
            # the GRS905's shifts (seed Table 1): a gearbox without its synchronized wheels has no shift heat
            if shift_energy > 0 and self.src_names[-1].startswith("shift:"):
                target = _shift_target(state.gear_prev, gear, self.p.split_inverted)
                if target in self.src_names:
                    u_w[self.src_names.index(target)] += shift_energy / h
            state.gear_prev = gear
        state.lag_w, delivered = heat_lag_step(state.lag_w, u_w, lag)
        return delivered

    def _stream_transfer(
        self, q_nodes: np.ndarray, G: np.ndarray, q0: float, omega: np.ndarray, T_oil_c: float, kind: str
    ) -> np.ndarray:
        """The oil-system inlet lies below the sump by the cooler's drop (Eq 82 idea): a stream component loses
        G (T_i - T_in) = G (T_i - T_s) + G dT, which the returning oil brings to the sump (zero-sum)."""
        xfer_w = G[self.stream_idx] * self._inlet_drop_k(q0, omega, T_oil_c, kind)
        q_nodes = q_nodes.copy()
        np.subtract.at(q_nodes, self.stream_nodes, xfer_w)
        q_nodes[self.i_oil] += xfer_w.sum()
        return q_nodes

    def _inlet_drop_k(self, q0: float, omega: np.ndarray, T_oil_c: float, kind: str) -> float:
        """The cooler's inlet drop Q / (mdot cp) [K] (physics.cooler.inlet_drop_k): the oil-system inlet lies this
        far below the sump at ``T_oil_c``; 0 without a modelled cooler, its heat or an oil flow."""
        if kind not in ("liquid", "air") or q0 == 0.0:
            return 0.0
        op = self.ev.oil.properties(T_oil_c)
        mdot = self.ev.oil_mass_flow_kg_s(self._pump_speed(omega), op.rho_kg_m3)
        return float(inlet_drop_k(q0, mdot * op.cp_j_per_kgk)) if mdot > 0 else 0.0

    def _inlet_c(self, inp: RunInputs, t_out: np.ndarray, T_oil_c: np.ndarray) -> np.ndarray:
        """A forced oil system's inlet at the output times (the description's derived oil.inlet): the sump there minus
        the cooler's drop at that sump, with the inputs in force over the step that ends there (the row before
        ``t_out``: a held row's over its interval) and the boundaries at ``t_out``."""
        t, kin = inp.t_s, self.losses.kin
        rows = np.clip(np.searchsorted(t, t_out, side="left") - 1, 0, t.size - 1)
        T_in_c = np.empty(t_out.size)
        for k, (tk, i, T_oil) in enumerate(zip(t_out.tolist(), rows.tolist(), np.asarray(T_oil_c).tolist())):
            omega = np.abs(kin.speed[int(inp.gear[i]) - GEAR_MIN] * inp.omega_in_rad_s[i])
            T_bc = self.bc_default.copy()
            for j, arr in inp.bc_c.items():
                T_bc[j] = float(np.interp(tk, t, arr))
            v_kmh = float(np.interp(tk, t, inp.v_kmh)) if inp.v_kmh is not None else self.v_default_kmh
            cool, amb = self._bc_or_nan(T_bc, "coolant"), self._bc_or_nan(T_bc, "ambient")
            q0, _ = self.cooler_heat(T_oil, self._pump_speed(omega), omega[self.i_input], cool, amb, v_kmh, slope=False)
            T_in_c[k] = T_oil - self._inlet_drop_k(q0, omega, T_oil, inp.kind)
        return T_in_c

    def _heat_out(self, G, Ge, T, T_new, T_bc, q0, gc, q_nodes, dstore, kind, prescribed) -> np.ndarray:
        """Heat leaving by each path of HEAT_OUT_NAMES over the step [W]; a held or measured sump's absorption is
        its net inflow minus its own storage change."""
        out = np.zeros(len(HEAT_OUT_NAMES))
        out[0] = q0 + gc * (T_new[self.i_oil] - T[self.i_oil]) if kind in ("liquid", "air") else 0.0
        q_bc = Ge * (T_new[self.topo.ea] - T_bc[self.topo.eb])
        for grp, links in enumerate(self.ext_group_links, start=1):
            out[grp] = q_bc[links].sum()
        if prescribed is not None:
            Gi = G[self.topo.int_idx]
            inflow = q_nodes[self.i_oil] + float(np.dot(Gi[self.oil_links], T_new[self.oil_other] - T_new[self.i_oil]))
            out[5] = inflow - dstore[self.i_oil]
        return out

    # ------------------------------------------------------------------ output
    def _output(self, table, inp: RunInputs, step_t, hist_T, hist_Q, out_dt_s) -> RunTable:
        t, kind = inp.t_s, inp.kind
        t_out = np.arange(step_t[0], step_t[-1] + 1e-9, out_dt_s) if out_dt_s > 0 else step_t
        if t_out[-1] < step_t[-1] - 1e-9:
            t_out = np.append(t_out, step_t[-1])
        cols = {"time_s": t_out}
        idx = np.clip(np.searchsorted(t, t_out, side="right") - 1, 0, t.size - 1)
        for c in (
            "engine_speed_rpm",
            "engine_torque_nm",
            "gear",
            "vehicle_speed_kmh",
            "ambient_temp_c",
            "coolant_temp_c",
            "retarder_torque_nm",
            *(c for c in table.columns if c.startswith("bc_")),
        ):
            if table.has(c):  # the inputs as the plant read them (bc_*: so that the output reproduces the run)
                cols[c] = np.asarray(table[c], dtype=float)[idx]
        # node temperatures, linear between thermal steps
        T_out = np.empty((t_out.size, self.n))
        for j in range(self.n):
            T_out[:, j] = np.interp(t_out, step_t, hist_T[:, j])
        if kind == "measured" and table.has("oil_temp_c"):
            cols["oil_temp_c"] = np.interp(t_out, t, np.asarray(table["oil_temp_c"], dtype=float))
        else:
            cols["oil_temp_c"] = self._oil_sensor(t_out, step_t, hist_T[:, self.i_oil], T_out[:, self.i_oil])
        for j, nm in enumerate(self.net.nodes):
            cols[f"T_{nm}_c"] = T_out[:, j]
        if OIL_INLET in self.net.geometry.description.derived:  # a forced oil system: its inlet, derived
            cols[f"T_{OIL_INLET}_c"] = self._inlet_c(inp, t_out, T_out[:, self.i_oil])
        # heat flows: step averages, each output sample shows the step that ends at or after it
        qi = np.clip(np.searchsorted(step_t, t_out, side="left"), 1, step_t.size - 1)
        names = (
            [f"Q_heat_{s.replace(':', '_')}_w" for s in self.sources]
            + ["Q_loss_mechanical_total_w", "Q_heat_total_w"]
            + [f"Q_out_{nm}_w" for nm in HEAT_OUT_NAMES]
            + ["Q_heat_retarder_w", "Q_stored_w"]
        )
        for j, nm in enumerate(names):
            cols[nm] = hist_Q[qi, j]
        return RunTable(cols)

    def _oil_sensor(self, t_out, step_t, T_oil_steps, T_oil_out):
        """The vehicle's oil sensor: the sump, or the sump through a first-order lag (effect oil_sensor_lag), read
        with a gain in degC and an offset (effects oil_sensor_gain, oil_sensor_offset)."""
        tau = self.scales.oil_sensor_tau_s
        gain, offset_c = float(self.scales.oil_sensor_gain), float(self.scales.oil_sensor_offset_c)
        if not tau > 0:
            y_out = T_oil_out
        else:
            oil_s = np.interp(step_t, step_t, T_oil_steps)
            y = np.empty_like(oil_s)
            y[0] = oil_s[0]
            for i in range(1, oil_s.size):
                y[i] = first_order_lag_step(y[i - 1], oil_s[i], step_t[i] - step_t[i - 1], tau)
            y_out = np.interp(t_out, step_t, y)
        if gain == 1.0 and offset_c == 0.0:
            return y_out
        return gain * np.asarray(y_out) + offset_c


def _churn_note(churn_invalid_s: float, span_s: float) -> list:
    """The run's note on the churning correlations' range, when they left it for part of the run only: the seed's
    geometry is outside their range on most drives (docs/validation.md, "Churning correlations outside their
    range"), which the docs say once; a run notes it only when it is partial, i.e. tells something about this drive."""
    if 0 < churn_invalid_s < CHURN_NOTE_SHARE * span_s:
        return [
            f"churning correlations (Eq 28-34) outside their validity range (Eq 33-34) for "
            f"{churn_invalid_s:.0f} s of {span_s:.0f} s (see docs/validation.md)"
        ]
    return []


def _solve(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A x = b by LAPACK's dgesv without numpy.linalg's per-call overhead (the plant's one solve per step)."""
    from scipy.linalg.lapack import dgesv  # imported at the first step, not with the plant (0.2 s)

    _, _, x, info = dgesv(A, b)
    if info != 0:
        raise np.linalg.LinAlgError(f"the plant's step matrix is singular (LAPACK dgesv info {info})")
    return x


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


#: a boundary temperature column's plausible range [degC] (as the [boundary] keys of a configuration)
BC_RANGE_C = (-60.0, 250.0)


def _check_range(col: str, v: np.ndarray, ok: np.ndarray, lo: float, hi: float) -> None:
    """InputError naming the first row of column ``col`` whose finite value lies outside lo..hi."""
    bad = ok & ((v < lo) | (v > hi))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(f"column {col} row {i + 1}: {v[i]:g} degC is outside {lo:g}..{hi:g} degC")


def validate_drive(table: RunTable, p: Parameters) -> None:
    """InputError (column and row) for a run table's drive values that no engine or gearbox of ``p`` produces:
    engine speed and torque outside the engine's range, a gear not in seed Table 1 or not of the description
    (missing values are left to the caller: a measured file may have gaps)."""
    _check_drive_ranges(
        {
            c: np.asarray(table[c], dtype=float)
            for c in ("engine_speed_rpm", "engine_torque_nm", "gear", "time_s")
            if table.has(c)
        },
        p,
        row_namer(table),
    )


def _check_drive_ranges(cols: dict, p: Parameters, row_of=None) -> None:
    """The range rules of the drive columns, on their finite values (validate_drive, _validate_inputs): the
    description's drive (the GRS905's: its engine; a fixed-ratio gearbox's: its input shaft). ``row_of``: names a
    0-based row (tools.runtable.row_namer: with its file's line)."""
    row_of = row_of or row_namer(None)
    drive = description_of(p).drive
    vmax = drive.max_speed_rad_s / RAD_S_PER_RPM
    lo, hi = drive.min_torque_nm, drive.max_torque_nm
    who = "the engine's" if drive.kind == "vehicle" else "the input shaft's"
    rules = (
        (
            "engine_speed_rpm",
            lambda v: (v < 0) | (v > vmax),
            lambda x: "rpm is a negative speed" if x < 0 else f"rpm exceeds {vmax:.0f} rpm",
        ),
        (
            "engine_torque_nm",
            lambda v: (v > hi) | (v < lo),
            f"Nm is outside {who} range {lo:g}..{hi:g} Nm",
        ),
        (
            "gear",
            lambda v: (v != np.round(v)) | (v < GEAR_MIN) | (v > GEAR_MAX),
            f"is not a gear in {GEAR_MIN}..{GEAR_MAX} (seed Table 1)",
        ),
    )
    # a fixed-ratio drive's table names its columns input_speed_rpm, input_torque_nm (tools.drive_table)
    shown = FIXED_RATIO_NAMES if drive.kind != "vehicle" else {}
    for col, bad_of, what in rules:
        if col in cols:
            v = cols[col]
            bad = np.isfinite(v) & bad_of(np.where(np.isfinite(v), v, 0.0))
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise InputError(
                    f"column {shown.get(col, col)} {row_of(i)}: {v[i]:g} {what(v[i]) if callable(what) else what}"
                )
    if "gear" in cols:
        _check_gears_defined(cols["gear"], description_of(p), cols.get("time_s"))


def _check_gears_defined(gear: np.ndarray, d, t_s: np.ndarray | None = None) -> None:
    """InputError (row, time, the description's gears) for a gear number the description has no gear for: its
    kinematic row is neutral's, so the engine's power would vanish without a loss (a GRS905 cycle's gear 7 on a
    6-speed gearbox)."""
    numbers = sorted(g.number for g in d.gears)
    bad = np.isfinite(gear) & ~np.isin(gear, numbers)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        at = f" (time_s {t_s[i]:g} s)" if t_s is not None else ""
        raise InputError(
            f"column gear row {i + 1}{at}: gear {gear[i]:g} is no gear of {d.name} (its gears: "
            f"{', '.join(map(str, numbers))})"
        )


def _validate_inputs(t, spd, trq, gear, p: Parameters, row_of=None):
    def first_bad(mask):
        return int(np.flatnonzero(mask)[0])

    row_of = row_of or row_namer(None)
    shown = FIXED_RATIO_NAMES if description_of(p).drive.kind != "vehicle" else {}
    for name, arr in (("time_s", t), ("engine_speed_rpm", spd), ("engine_torque_nm", trq), ("gear", gear)):
        bad = ~np.isfinite(arr)
        if bad.any():
            raise InputError(
                f"column {shown.get(name, name)} {row_of(first_bad(bad))}: value is missing or not a number"
            )
    if np.any(np.diff(t) <= 0):
        raise InputError(
            f"column time_s {row_of(first_bad(np.append(np.diff(t) <= 0, False)) + 1)}: time must increase"
        )
    _check_drive_ranges({"engine_speed_rpm": spd, "engine_torque_nm": trq, "gear": gear, "time_s": t}, p, row_of)
