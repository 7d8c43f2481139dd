"""Models the gap diagnosis can put under diagnosis: one small interface, two backends.

`DiagnosisModel.simulate(datasets, runs)` re-simulates every prepared data set once per run (a run = a set of
effect values, see :class:`Run`) and returns, per run and per data set, the model's output columns on its own output
grid (``time_s`` plus ``oil_temp_c``, ``T_oil_c``, ``T_<id>_c`` ...).

* :class:`PlantModel`: the reference plant (tools.plant.reference), every catalog effect, runs farmed out to a process
pool
  (the machine has two cores; a 25-minute cycle takes about 0.4 s at the default 1 s step).
* :class:`OnboardModel`: the onboard reduced model (firmware_model.onboard.sensor), run with ``oil_temp_c = NaN`` so
that it
  predicts the oil itself; effect values are batched as "vehicles" of one vectorised pass. Effects the onboard model
  cannot represent are delegated to a fallback plant (reported per effect).

Both predict the oil with their own cooler model ("closed loop"): the plant's planetary and input-shaft wheels are fed
by the oil-system flow that left the cooler, several kelvin below the sump, so driving the components with the
measured sump and no cooler state is a larger model error (up to 20 K on the sun wheel in the uphill cycle) than
most of the effects sought.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import multiprocessing as mp
import os
import warnings
from dataclasses import dataclass, replace

import numpy as np

from firmware_model.errors import InputError
from tools.published import housings

#: columns every run returns besides the measured channels' model columns
ALWAYS = ("oil_temp_c", "T_oil_c", "Q_out_cooler_w")
#: heat-flow columns summed into the heat to the outside (for the effective conductance of the oil)
Q_OUT = (
    "Q_out_cooler_w",
    "Q_out_housing_convection_w",
    "Q_out_housing_radiation_w",
    "Q_out_supports_conduction_w",
    "Q_out_shafts_conduction_w",
)


def initial_shift_c(effect: str | None, value: float | None, T0_meas_c: float) -> float:
    """The model's initial temperature moves with a measurement effect: it starts from the oil sensor's first reading,
    and a sensor reading sump + offset (or gain x sump in degC) started it off the true sump by this much [K]."""
    if value is None:
        return 0.0
    if effect == "oil_sensor_offset":
        return -float(value)
    if effect == "oil_sensor_gain" and value > 0:
        return T0_meas_c / float(value) - T0_meas_c
    return 0.0


@dataclass(frozen=True)
class Run:
    """One re-simulation: effect values (id -> parameter), an offset on the initial temperature, and whether to
    return every node (decimated to `full_dt_s`) for the measurement suggestions. `start` = (effect, value) of an
    oil-sensor offset or gain: every file starts from the sump that its first reading implies through that sensor
    (:func:`initial_shift_c`), exactly rather than to first order."""

    effects: tuple = ()  # ((id, value), ...) so that runs hash
    initial_offset_c: float = 0.0
    full: bool = False
    coarse: bool = False  # a cheaper, coarser step where the backend has one (surrogate grids)
    fine: bool = False  # half the step (the model's own numerical error), where it has one
    start: tuple = ()  # (oil-sensor effect, value) the files start from; () the reading itself
    housing_offset_c: float = 0.0  # the housings start this far from the others (tools/diagnosis/start.py)
    thinned: bool = False  # every second row's drive inputs from its neighbours (the inputs' sampling error)

    @staticmethod
    def of(
        effects: dict | None = None,
        initial_offset_c: float = 0.0,
        full: bool = False,
        coarse: bool = False,
        fine: bool = False,
        start: tuple | None = None,
        housing_offset_c: float = 0.0,
        thinned: bool = False,
    ) -> Run:
        return Run(
            tuple(sorted((effects or {}).items())),
            float(initial_offset_c),
            bool(full),
            bool(coarse),
            bool(fine),
            tuple(start or ()),
            float(housing_offset_c),
            bool(thinned),
        )

    def initial_offsets_c(self, housings: tuple) -> dict | None:
        """{node: K} added to the start of the ``housings`` (the gearbox's housing ids; None: no offset)."""
        return {h: self.housing_offset_c for h in housings} if self.housing_offset_c else None

    def initial_c(self, T0_meas_c: float) -> float:
        """The initial temperature of a file whose first oil reading (or initial temperature) is `T0_meas_c`."""
        return T0_meas_c + self.initial_offset_c + (initial_shift_c(*self.start, T0_meas_c) if self.start else 0.0)

    @property
    def effect_dict(self) -> dict:
        return dict(self.effects)


class DiagnosisModel:
    """Interface of a model under diagnosis."""

    name = "abstract"
    #: effect ids this backend represents itself (others are delegated or unsupported)
    native_effects: tuple = ()
    notes: list

    def simulate(self, datasets, runs, columns) -> list:
        """Per run, per data set: dict column -> array on the model's output grid (with ``time_s``)."""
        raise NotImplementedError

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def describe(self) -> dict:
        return {"model": self.name}


# ----------------------------------------------------------------------------------------------------------------
# reference plant

_WORKER = {}


def _init_worker(params, cooler, dt_s, out_dt_s, full_dt_s, coarse_dt_s):
    _WORKER.update(
        params=params, cooler=cooler, dt_s=dt_s, out_dt_s=out_dt_s, full_dt_s=full_dt_s, coarse_dt_s=coarse_dt_s
    )
    warnings.filterwarnings("ignore", category=RuntimeWarning)


#: the drive inputs a thinned run takes from every second row's neighbours: linearly for these, held for the gear
THIN_LINEAR, THIN_HELD = ("engine_speed_rpm", "engine_torque_nm", "retarder_torque_nm"), ("gear",)


def thinned_inputs(table):
    """``table`` with every odd row's drive inputs taken from its neighbours (the mean of the two rows around it;
    the gear of the row before): inputs that move smoothly between rows are almost unchanged, inputs that vary
    faster than the rows are sampled (a 10 Hz drive written every 1 s) differ by about their sampling error, which
    the diagnosis's error floor then covers (tools.diagnosis.baseline.model_error_floor)."""
    out = table.copy()
    n = table.n
    odd = np.arange(1, n - 1, 2)
    for c in THIN_LINEAR + THIN_HELD:
        if not out.has(c) or odd.size == 0:
            continue
        v = np.array(table[c], dtype=float)
        v[odd] = 0.5 * (v[odd - 1] + v[odd + 1]) if c in THIN_LINEAR else v[odd - 1]
        out[c] = v
    return out


def _plant_job(job):
    table, run, columns = job
    if run.thinned:
        table = thinned_inputs(table)
    from tools.plant.reference import ReferencePlant

    w = _WORKER
    plant = ReferencePlant(
        w["params"],
        run.effect_dict,
        cooler=w["cooler"],
        dt_s=w["coarse_dt_s"] if run.coarse else (0.5 * w["dt_s"] if run.fine else w["dt_s"]),
    )
    t0 = table.meta.get("initial_temp_c")
    res = plant.run(
        table,
        initial_temp_c=run.initial_c(t0) if t0 is not None else None,
        out_dt_s=w["out_dt_s"],
        progress=False,
        initial_offsets_c=run.initial_offsets_c(housings(w["params"])),
    )
    tb = res.table
    out = {"time_s": tb["time_s"]}
    for c in set(columns) | set(ALWAYS):
        if tb.has(c):
            out[c] = tb[c]
    if not run.effects:
        for c in Q_OUT:
            if tb.has(c):
                out[c] = tb[c]
    if run.full:
        t = tb["time_s"]
        k = max(int(round(w["full_dt_s"] / max(w["out_dt_s"], 1e-9))), 1)
        sel = slice(None, None, k)
        out["full"] = {c: tb[c][sel] for c in tb.columns if (c.startswith("T_") or c in Q_OUT)}
        out["full"]["time_s"] = t[sel]
    return out


def _copy_outputs(out: dict, keep: set | None = None) -> dict:
    """A copy of one plant job's outputs (``keep``: only those columns), its "full" node table too."""
    return {
        k: ({c: v.copy() for c, v in a.items()} if k == "full" else a.copy())
        for k, a in out.items()
        if keep is None or k in keep
    }


class PlantModel(DiagnosisModel):
    """The reference plant under diagnosis (``--model plant``)."""

    name = "plant"

    def __init__(
        self,
        params,
        cooler: str | None = None,
        dt_s: float = 1.0,
        out_dt_s: float = 1.0,
        workers: int | None = None,
        full_dt_s: float = 10.0,
        coarse_dt_s: float = 2.0,
    ):
        from firmware_model.effects import EFFECT_IDS

        self.params = params
        self.cooler = cooler or params.strings.get("cooler.kind", "liquid")
        self.dt_s, self.out_dt_s, self.full_dt_s = float(dt_s), float(out_dt_s), float(full_dt_s)
        self.coarse_dt_s = max(float(coarse_dt_s), self.dt_s)
        self.workers = max(1, int(workers if workers is not None else min(2, os.cpu_count() or 1)))
        self.native_effects = tuple(EFFECT_IDS)
        self.notes = []
        self._pool = None
        self._memo = {}

    def _get_pool(self):
        if self.workers <= 1:
            return None
        if self._pool is None:
            ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else mp.get_context()
            self._pool = ctx.Pool(
                self.workers,
                initializer=_init_worker,
                initargs=(self.params, self.cooler, self.dt_s, self.out_dt_s, self.full_dt_s, self.coarse_dt_s),
            )
        return self._pool

    def simulate(self, datasets, runs, columns):
        jobs = [(ds.inputs, run, tuple(columns)) for run in runs for ds in datasets]
        outs = [self._remembered(j) for j in jobs]
        todo = [i for i, o in enumerate(outs) if o is None]
        pool = self._get_pool() if len(todo) > 1 else None
        if pool is None:
            _init_worker(self.params, self.cooler, self.dt_s, self.out_dt_s, self.full_dt_s, self.coarse_dt_s)
            for i in todo:
                outs[i] = _plant_job(jobs[i])
        else:
            # longest jobs first keeps both cores busy to the end
            order = sorted(todo, key=lambda i: -jobs[i][0].n)
            for i, r in zip(order, pool.map(_plant_job, [jobs[i] for i in order], chunksize=1)):
                outs[i] = r
        for i in todo:
            self._remember(jobs[i], outs[i])
        nd = len(datasets)
        return [outs[i * nd : (i + 1) * nd] for i in range(len(runs))]

    #: plant runs kept per diagnosis: the same run of the same table asked twice runs once
    REMEMBER_MAX = 16

    def _remembered(self, job) -> dict | None:
        """What an identical earlier job (the same table object, the same run, asking for these columns or more)
        returned, with only the columns this one gets (copies); else None."""
        table, run, columns = job
        hit = self._memo.get((id(table), run))
        if hit is None or hit[0] is not table or not set(columns) <= hit[2]:  # (an id can be reused: table kept)
            return None
        return _copy_outputs(hit[1], {"time_s", "full", *columns, *ALWAYS, *(() if run.effects else Q_OUT)})

    def _remember(self, job, out: dict) -> None:
        table, run, columns = job
        if len(self._memo) >= self.REMEMBER_MAX:
            self._memo.clear()
        self._memo[(id(table), run)] = (table, _copy_outputs(out), set(columns) | set(ALWAYS))

    def close(self):
        if self._pool is not None:
            self._pool.close()
            self._pool.join()
            self._pool = None

    def describe(self) -> dict:
        return {"model": "plant", "plant_dt_s": self.dt_s, "cooler": self.cooler}


# ----------------------------------------------------------------------------------------------------------------
# onboard model


def onboard_available() -> bool:
    return importlib.util.find_spec("firmware_model.onboard.sensor") is not None


class OnboardModel(DiagnosisModel):
    """The onboard reduced model under diagnosis (the default: it is what runs in the truck).

    Runs the sensor's pure step over each file at its own 10 Hz with the oil input absent (NaN), so the sensor
    integrates the sump with its cooler model. The runs of one call are the vehicles of one vectorised pass per
    file (the onboard model's per-vehicle effect hooks, firmware_model.onboard.reduce.EFFECT_HOOKS); ``oil_level_low``
    is
    one build per volume, ``oil_sensor_lag`` a filter on the sump output. A file's bc_<boundary>_c columns are its
    runs' boundary temperatures, as they are the plant's (run_onboard_pass). Other effects are delegated to
    `fallback` (a PlantModel) and listed in `delegated`. Passes are spread over a process pool (one file per
    process).
    """

    name = "onboard"

    def __init__(
        self,
        params,
        cooler: str | None = None,
        fallback: PlantModel | None = None,
        out_dt_s: float = 1.0,
        config=None,
        workers: int | None = None,
    ):
        if not onboard_available():
            raise InputError(
                "the onboard model (firmware_model.onboard.sensor) is not available in this installation; "
                "use --model plant"
            )
        self.params = params
        self.cooler = cooler
        self.out_dt_s = float(out_dt_s)
        self.config = config
        self.fallback = fallback
        self.workers = max(1, int(workers if workers is not None else min(2, os.cpu_count() or 1)))
        self._pool = None
        red = importlib.import_module("firmware_model.onboard.reduce")
        self.native_effects = (
            tuple(getattr(red, "EFFECT_HOOKS", ())) + tuple(getattr(red, "BUILD_EFFECTS", ())) + ("oil_sensor_lag",)
        )
        self.delegated = []
        self.notes = []

    def simulate(self, datasets, runs, columns):
        native = [r for r in runs if all(e in self.native_effects for e, _ in r.effects) and not r.full]
        other = [r for r in runs if r not in native]
        results = {}
        if native:
            jobs, where = [], []
            for j, ds in enumerate(datasets):
                groups = {}
                for i, r in enumerate(native):
                    groups.setdefault(r.effect_dict.get("oil_level_low", 13.5), []).append(i)
                for vol, idx in groups.items():
                    jobs.append((_DS(ds.inputs, ds.initial_temp_c), [native[i] for i in idx], tuple(columns), vol))
                    where.append((j, idx))
            pool = self._get_pool()
            if pool is None:
                outs = [_onboard_job(x) for x in jobs]
            else:
                order = sorted(range(len(jobs)), key=lambda i: -jobs[i][0].inputs.n)
                res = pool.map(_onboard_job, [jobs[i] for i in order], chunksize=1)
                outs = [None] * len(jobs)
                for i, r in zip(order, res):
                    outs[i] = r
            per = [[None] * len(native) for _ in datasets]
            for (j, idx), res in zip(where, outs):
                for i, o in zip(idx, res):
                    per[j][i] = o
            for i, r in enumerate(native):
                results[r] = [per[j][i] for j in range(len(datasets))]
        if other:
            if self.fallback is None:
                bad = sorted({e for r in other for e, _ in r.effects if e not in self.native_effects})
                raise InputError(
                    f"the onboard model cannot represent effect(s) {', '.join(bad)} and no fallback plant is configured"
                )
            # runs of every node (the measurement suggestions) always come from the plant: not a delegated effect
            for e, _ in (x for r in other if not r.full for x in r.effects):
                if e not in self.native_effects and e not in self.delegated:
                    self.delegated.append(e)
            for r, out in zip(other, self.fallback.simulate(datasets, other, columns)):
                results[r] = out
        return [results[r] for r in runs]

    def _get_pool(self):
        if self.workers <= 1:
            _init_onboard(self.params, self.cooler, self.config, self.out_dt_s)
            return None
        if self._pool is None:
            ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else mp.get_context()
            self._pool = ctx.Pool(
                self.workers, initializer=_init_onboard, initargs=(self.params, self.cooler, self.config, self.out_dt_s)
            )
        return self._pool

    def close(self):
        if self._pool is not None:
            self._pool.close()
            self._pool.join()
            self._pool = None
        if self.fallback is not None:
            self.fallback.close()

    def describe(self) -> dict:
        d = {"model": "onboard", "step_s": 0.1}
        if self.delegated:
            d["delegated_to_plant"] = sorted(self.delegated)
        return d


@dataclass
class _DS:
    inputs: object
    initial_temp_c: float


_ONB = {"builds": {}, "boundary_names": {}}


def _init_onboard(params, cooler, config, out_dt_s):
    key = (id(params), cooler, out_dt_s)
    if _ONB.get("key") != key:
        _ONB.update(
            params=params, cooler=cooler, config=config, out_dt_s=out_dt_s, builds={}, boundary_names={}, key=key
        )
    warnings.filterwarnings("ignore", category=RuntimeWarning)


def _onboard_job(job):
    ds, runs, columns, volume = job
    return run_onboard_pass(ds, runs, columns, volume)


def _onboard_build(volume_l: float):
    """The onboard sensor built once per oil volume and process (the expensive part: the reduced network)."""
    from firmware_model.effects import CATALOG

    vs = _ONB["builds"].get(volume_l)
    if vs is None:
        from firmware_model.config import Config
        from firmware_model.onboard.sensor import VirtualSensor

        eff = {} if volume_l == CATALOG["oil_level_low"].neutral else {"oil_level_low": volume_l}
        params = _ONB["params"]
        if _ONB["cooler"]:
            params = params.with_cooler_kind(_ONB["cooler"])
        vs = VirtualSensor(params, config=_ONB["config"] or Config(), effects=eff, oil_mode="model", ttl_period_s=1e12)
        _ONB["builds"][volume_l] = vs
    return vs


def _onboard_steps(vs, sp, state, raw: np.ndarray, keep: np.ndarray, wi: np.ndarray, bc_shift_k=None) -> np.ndarray:
    """The main copy's temperatures of nodes ``wi`` at the steps ``keep`` (V vehicles, the same inputs ``raw``
    (n, 8) for all): the compiled kernel when the sensor has it (one call per step for the whole batch), else the
    numpy step. ``bc_shift_k`` (n, nb): the boundaries' shift from their defaults at each step (None: none)."""
    from firmware_model.onboard import sensor as S
    from firmware_model.onboard.params import boundary_change_steps

    V = state.T_c.shape[0]
    rec = np.empty((keep.size, V, len(wi)))
    rec[0] = state.T_c[:, S.MAIN, :][:, wi]
    if getattr(vs, "compiled", None) is not None:
        from firmware_model.onboard.compiled import CompiledCore

        return CompiledCore(sp).run_batch(state, raw, keep, wi, rec, bc_shift_k)
    bc_at = boundary_change_steps(bc_shift_k) if bc_shift_k is not None else set()
    sp_k, j = sp, 1
    for k in range(raw.shape[0] - 1):
        if k in bc_at:
            sp_k = replace(sp, T_bc_default_c=np.asarray(sp.T_bc_default_c, dtype=float) + bc_shift_k[k])
        state, _ = S.step(state, S.SensorInputs(*raw[k].tolist()), sp_k)
        if j < keep.size and k + 1 == keep[j]:
            rec[j] = state.T_c[:, S.MAIN, :][:, wi]
            j += 1
    return rec


#: the boundaries the onboard step takes from its drive inputs (ambient_temp_c, coolant_temp_c), not from bc_ columns
INPUT_BOUNDARIES = ("ambient", "coolant")


def _boundary_shift_k(vs, table, idx: np.ndarray):
    """The shift of the onboard model's boundaries from their defaults [K] at each 0.1 s step (n, nb; ``idx``: the
    table's row held at each step), from the table's bc_<boundary>_c columns (a rig's measured boundaries, a named
    cycle's), their empty cells bridged linearly as the plant bridges them, each row's value held over its row (the
    plant interpolates within a row); None without such a column. A truck
    sends the ambient and the coolant only, but offline the diagnosis knows the boundaries the plant takes, and a
    run's effects must act on them as in the plant: a cooler at 0.6 lets the same boundaries lift the oil 1.5 K
    where the nominal cooler lets them lift it 1.0 K (docs/diagnosis.md, "Boundary columns")."""
    from firmware_model.network import build_network
    from firmware_model.onboard.reduce import onboard_boundaries

    names = _ONB["boundary_names"].get(id(vs))
    if names is None:  # (per build: the builds are kept, so an id is not reused)
        names = _ONB["boundary_names"][id(vs)] = onboard_boundaries(build_network(vs.params))
    t = np.asarray(table["time_s"], dtype=float)
    default_c = np.asarray(vs.reduced.bc_default_c, dtype=float)
    shift_k = np.zeros((idx.size, default_c.size))
    found = False
    for i, b in enumerate(names):
        v = np.asarray(table[f"bc_{b}_c"], dtype=float) if table.has(f"bc_{b}_c") else np.full(t.size, np.nan)
        ok = np.isfinite(v)
        if b in INPUT_BOUNDARIES or not ok.any():
            continue
        shift_k[:, i] = np.interp(t, t[ok], v[ok])[idx] - default_c[i]
        found = True
    return shift_k if found else None


def run_onboard_pass(ds, runs, columns, volume_l: float) -> list:
    """Run the onboard step over `ds` once, one vehicle per run (effect values as per-vehicle arrays, the oil input
    absent so that the sensor integrates its sump), and return each run's output columns every `out_dt_s`."""
    from firmware_model.effects import CATALOG
    from firmware_model.onboard import reduce as R
    from firmware_model.onboard import sensor as S

    vs = _onboard_build(volume_l)
    out_dt_s = _ONB["out_dt_s"]
    V = len(runs)
    eff = {}
    for eid in R.EFFECT_HOOKS:
        vals = np.array([r.effect_dict.get(eid, CATALOG[eid].neutral) for r in runs], dtype=float)
        if np.any(vals != CATALOG[eid].neutral):
            eff[eid] = vals
    sp = S.SensorParams.build(vs.reduced, vs.limits, R.make_effects(eff, vs.reduced), vs.options)
    dt = vs.dt_s
    tin = np.asarray(ds.inputs["time_s"], dtype=float)
    n = int(np.floor((tin[-1] - tin[0]) / dt + 1e-9)) + 1
    ts = tin[0] + dt * np.arange(n)
    idx = np.clip(np.searchsorted(tin, ts + 1e-9, side="right") - 1, 0, tin.size - 1)

    def col(name):
        return np.asarray(ds.inputs[name], dtype=float)[idx] if ds.inputs.has(name) else np.full(n, np.nan)

    spd, tq, gear = col("engine_speed_rpm"), col("engine_torque_nm"), col("gear")
    amb, cool, vk = col("ambient_temp_c"), col("coolant_temp_c"), col("vehicle_speed_kmh")
    ret = np.nan_to_num(col("retarder_torque_nm"), nan=0.0)
    T0 = np.array([r.initial_c(ds.initial_temp_c) for r in runs], dtype=float)
    state = vs.initial_state(T_oil_c=T0, n_vehicles=V)
    dh = np.array([r.housing_offset_c for r in runs], dtype=float)
    if np.any(dh != 0.0):
        T_c = np.array(state.T_c, copy=True)
        hi = [list(vs.nodes).index(h) for h in housings(vs)]
        T_c[:, :, hi] += dh[:, None, None]  # both copies
        state = state._replace(T_c=T_c)
    every = max(int(round(out_dt_s / dt)), 1)
    keep = np.arange(0, n, every)
    nodes = list(vs.nodes)
    want = sorted({c[2:-2] for c in columns if c.startswith("T_") and c.endswith("_c") and c[2:-2] in nodes} | {"oil"})
    wi = np.array([nodes.index(w) for w in want])
    raw = np.stack([spd, tq, gear, np.full(n, math.nan), amb, cool, vk, ret], axis=-1)
    rec = _onboard_steps(vs, sp, state, raw, keep, wi, _boundary_shift_k(vs, ds.inputs, idx))
    t_out = ts[keep]
    outs = []
    for v, r in enumerate(runs):
        o = {"time_s": t_out}
        for m, w in enumerate(want):
            o[f"T_{w}_c"] = rec[:, v, m]
        sump = o["T_oil_c"]
        tau = r.effect_dict.get("oil_sensor_lag", 0.0)
        if tau > 0:
            from scipy.signal import lfilter

            a = math.exp(-out_dt_s / tau)
            o["oil_temp_c"] = lfilter([1 - a], [1, -a], sump, zi=[a * sump[0]])[0]
        else:
            o["oil_temp_c"] = sump
        outs.append(o)
    return outs
