"""Calibration of the model's assumed parameters to measured runs (``gearbox-vsensor calibrate``).

The seed censors most geometry, so every real gearbox differs from the parameter file in its assumed values. This
fits chosen parameters (each must declare plausible bounds ``lo``/``hi`` in the parameter file) to the training
files with the reference plant, after an identifiability analysis, and checks the result on held-out test files:

1. **Sensitivities**: every parameter moved by a small step from its file value; the change of each measured channel
   (on the analysis grid) over half its plausible range is its *signature*. A parameter whose signature stays below
   ``ident_min_c`` on every channel cannot be fitted from these files; two parameters whose sensitivity columns are
   nearly parallel (|cos| >= ``collinear_cos``) cannot be separated (the weaker one is left out).
2. **Fit**: bounded nonlinear least squares (scipy ``least_squares``, trust-region reflective) of the cell residual
   (measured - model) of every channel, each channel weighted equally per file; parameters scaled to their bounds.
3. **Uncertainty**: one standard deviation from the Jacobian at the optimum, ``s^2 (J^T J)^-1`` inflated by
   ``N / N_eff`` (the residual's lag-1 autocorrelation: a thermal residual drifts, its samples are not independent).
4. **Held-out**: the test files simulated with the file's values and with the fitted ones; RMS per channel.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import signal
import textwrap
import warnings
from dataclasses import dataclass, field

import numpy as np

from firmware_model.errors import InputError
from firmware_model.parameters import Parameters, with_fit_bounds
from tools.diagnosis.measurement import model_at_cells
from tools.diagnosis.options import HOUSING_PERTURB_C, Options, how_much_more, n_eff_needed
from tools.diagnosis.prepare import prepare_runs

#: a parameter is identifiable when moving it over half its plausible range moves some channel by at least this [K]
IDENT_MIN_C = 0.2
#: two parameters whose sensitivity columns have |cos| at least this cannot be separated
COLLINEAR_COS = 0.98
#: the step of the finite-difference sensitivities, as a share of the plausible range
SENS_STEP = 0.1
#: starting points of the fit per parameter (Latin hypercube over the bounds, besides the file's values) and the
#: number of local searches from the best of them
START_POINTS_PER_KEY = 3
LOCAL_SEARCHES = 2


def latin_hypercube(k: int, n: int, seed: int = 20261125) -> np.ndarray:
    """n points in [0, 1]^k, one per stratum in every dimension (deterministic)."""
    rng = np.random.default_rng(seed)
    u = (np.arange(n)[:, None] + rng.random((n, k))) / n
    for j in range(k):
        u[:, j] = u[rng.permutation(n), j]
    return u


@dataclass
class Identifiability:
    key: str
    signature_c: dict  # channel -> RMS change over half the plausible range [K]
    identifiable: bool
    reason: str  # why not ('' when identifiable)
    max_cos: float = 0.0  # largest |cos| with another parameter's sensitivity
    with_key: str = ""  # ... that parameter


@dataclass
class Calibration:
    keys: list  # fitted keys
    start: dict  # key -> SI value in the file
    fitted: dict  # key -> fitted SI value
    sigma: dict  # key -> one standard deviation [SI]
    at_bound: dict  # key -> bool
    ident: list  # Identifiability of every requested key
    train_rms_c: tuple  # (before, after) pooled
    test_rms_c: tuple  # (before, after) pooled
    test_by_channel: dict  # channel -> (before, after)
    n_sims: int
    train: list = field(default_factory=list)
    test: list = field(default_factory=list)
    plot: dict = field(default_factory=dict)  # held-out residuals for the report's figure
    starts: tuple = ()  # start.StartOf per file (rest, or running with --start running)
    n_eff: float = math.inf  # effective samples of the training residual after the fit
    n_eff_needed: int = 0  # ... needed to decide the fitted values (options.n_eff_needed)
    notes: list = field(default_factory=list)  # what the records' screening left out (SCADA: a channel far off)
    n_cells: int = 0  # cells of the training residual
    train_s: float = 0.0  # training time scored [s]
    rivals: list = field(default_factory=list)  # SCADA: channels a reading offset explains as well as the fit

    def thin_evidence(self) -> str:
        """One sentence when the fitted values rest on too few effective samples ('' otherwise), with the advice."""
        if not self.n_eff < self.n_eff_needed:
            return ""
        b, a = self.test_rms_c
        return (
            f"thin evidence: the training residual after the fit holds n_eff = {self.n_eff:.0f} effective samples "
            f"of {self.n_cells} cells and fitting {len(self.keys)} value{'s' if len(self.keys) > 1 else ''} needs "
            f"at least {self.n_eff_needed}; the fit {'cuts' if a < b else 'does not cut'} the held-out RMS "
            f"{b:.2f} -> {a:.2f} K {'but' if a < b else 'and'} rests on too little to trust: add more training "
            f"files, or longer ones ({how_much_more(self.n_eff_needed, self.n_eff, self.train_s)}), and calibrate "
            "again"
        )


# ----------------------------------------------------------------------------------------------------------------
# simulation with changed parameters (the reference plant, a process pool)

_W = {}


def _init(params, cooler, dt_s):
    _W.update(params=params, cooler=cooler, dt_s=dt_s)
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    # Ctrl-C is the parent's to handle (it terminates the pool): a worker's own KeyboardInterrupt printed
    # "Process ForkPoolWorker-2:" and a traceback before the one-sentence "interrupted"
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _job(job):
    from tools.plant.reference import ReferencePlant
    from tools.published import housings

    overrides, table, columns, housing_offset_c = job
    params = _W["params"].with_overrides(overrides) if overrides else _W["params"]
    res = ReferencePlant(params, {}, cooler=_W["cooler"], dt_s=_W["dt_s"]).run(
        table,
        initial_temp_c=table.meta.get("initial_temp_c"),
        out_dt_s=1.0,
        progress=False,
        initial_offsets_c={h: housing_offset_c for h in housings(params)} if housing_offset_c else None,
    )
    return {c: res.table[c] for c in ("time_s",) + tuple(columns)}


class PlantRuns:
    """Runs of the reference plant with parameter overrides over the prepared files (counted)."""

    def __init__(self, params: Parameters, cooler: str, dt_s: float, workers: int | None):
        self.params, self.cooler, self.dt_s = params, cooler, dt_s
        self.workers = max(1, int(workers if workers is not None else min(2, os.cpu_count() or 1)))
        self.n_sims = 0
        self._pool = None

    def run(self, datasets: list, overrides: list, housing_offset_c: float = 0.0) -> list:
        """Per override dict, per dataset: the plant outputs of the channels' columns (`housing_offset_c`: the
        housings start that far from the others)."""
        cols = tuple(sorted({ch.model_column for ds in datasets for ch in ds.channels.values()}))
        jobs = [(ov, ds.inputs, cols, float(housing_offset_c)) for ov in overrides for ds in datasets]
        self.n_sims += len(jobs)
        if self.workers > 1 and len(jobs) > 1:
            if self._pool is None:
                ctx = mp.get_context("fork") if "fork" in mp.get_all_start_methods() else mp.get_context()
                self._pool = ctx.Pool(self.workers, initializer=_init, initargs=(self.params, self.cooler, self.dt_s))
            outs = self._pool.map(_job, jobs)
        else:
            _init(self.params, self.cooler, self.dt_s)
            outs = [_job(j) for j in jobs]
        n = len(datasets)
        return [outs[i * n : (i + 1) * n] for i in range(len(overrides))]

    def close(self):
        if self._pool is not None:
            self._pool.terminate()
            self._pool = None


# ----------------------------------------------------------------------------------------------------------------
# residuals


def residual_parts(datasets: list, outs: list, sens_h: list | None = None, opts: Options | None = None) -> list:
    """Measured - model on every (file, channel)'s cells; a file that starts running (tools/diagnosis/start.py) with
    its housings' start as a nuisance: `sens_h`, per file the sensitivity of each channel to it (None: at rest),
    the offset fitted per file (each channel's cells weighted alike, as the fit weighs them)."""
    from tools.diagnosis.scoring import box_lsq

    opts = opts or Options()
    out = []
    for f, (ds, o) in enumerate(zip(datasets, outs)):
        rs = [ch.cell_y_c - model_at_cells(o, ch, 0.0) for ch in ds.channels.values()]
        sh = sens_h[f] if sens_h is not None else None
        if sh is not None and rs:
            w = np.concatenate([np.full(r.size, 1.0 / max(r.size, 1)) for r in rs])
            (beta,), _ = box_lsq(
                np.concatenate(rs),
                w,
                np.concatenate(sh)[:, None],
                np.array([opts.housing_offset_lo_c]),
                np.array([opts.housing_offset_hi_c]),
            )
            rs = [r - beta * s for r, s in zip(rs, sh)]
        out.append(rs)
    return out


def housing_sensitivity(runs, datasets: list, base: list, overrides: dict | None = None) -> list:
    """Per file (None for one at rest) and channel: the model's response to its housings' start [K/K]."""
    if not any(ds.start == "running" for ds in datasets):
        return [None] * len(datasets)
    house = runs.run(datasets, [overrides or {}], housing_offset_c=HOUSING_PERTURB_C)[0]
    return [
        [(model_at_cells(h, ch, 0.0) - model_at_cells(b, ch, 0.0)) / HOUSING_PERTURB_C for ch in ds.channels.values()]
        if ds.start == "running"
        else None
        for ds, b, h in zip(datasets, base, house)
    ]


def residual_vector(datasets: list, outs: list, sens_h: list | None = None) -> np.ndarray:
    """Measured - model on every channel's cells, each (file, channel) weighted by 1/sqrt(its cell count)."""
    parts = [r / math.sqrt(max(r.size, 1)) for rs in residual_parts(datasets, outs, sens_h) for r in rs]
    return np.concatenate(parts) if parts else np.zeros(0)


def channel_rms(datasets: list, outs: list, sens_h: list | None = None) -> dict:
    acc = {}
    for ds, rs in zip(datasets, residual_parts(datasets, outs, sens_h)):
        for cid, r in zip(ds.channels, rs):
            a = acc.setdefault(cid, [0.0, 0])
            a[0] += float(np.sum(r * r))
            a[1] += r.size
    return {c: math.sqrt(a[0] / max(a[1], 1)) for c, a in acc.items()}


def pooled_rms(datasets: list, outs: list, sens_h: list | None = None) -> float:
    rs = [r for parts in residual_parts(datasets, outs, sens_h) for r in parts]
    n = sum(r.size for r in rs)
    return math.sqrt(sum(float(np.sum(r * r)) for r in rs) / max(n, 1))


# ----------------------------------------------------------------------------------------------------------------
# requested keys and identifiability


def check_keys(params: Parameters, keys: list) -> list:
    """The requested keys, or an InputError (one sentence) for an unknown key or one without bounds."""
    if not keys:
        raise InputError("give the parameters to calibrate (--params KEY,KEY,...) or --auto")
    with_bounds = sorted(params.bounds)
    for k in keys:
        if k not in params.values:
            raise InputError(
                f"--params: {k!r} is not a parameter of {params.variant} (parameters with plausible "
                f"bounds, which calibrate can fit: {', '.join(with_bounds) or 'none'})"
            )
        if k not in params.bounds:
            raise InputError(
                f"--params: {k} declares no plausible bounds (lo, hi) in {params.origin}; only keys "
                f"with bounds can be calibrated: {', '.join(with_bounds) or 'none'}"
            )
    if len(set(keys)) != len(keys):
        raise InputError("--params names a parameter twice")
    return list(keys)


def _columns(datasets: list) -> list:
    return [(i, cid) for i, ds in enumerate(datasets) for cid in ds.channels]


def sensitivities(
    runs: PlantRuns, params: Parameters, datasets: list, keys: list, base: list, sens_h: list | None = None
) -> tuple:
    """(J, per key its per-channel signature over half its plausible range): J[:, j] = d residual / d (x_j), x scaled
    to 0..1 over the bounds (with the housings' start of running files as a nuisance, `sens_h`)."""
    steps = []
    for k in keys:
        lo, hi = params.bounds[k]
        v = params[k]
        h = SENS_STEP * (hi - lo)
        steps.append(h if v + h <= hi else -h)
    outs = runs.run(datasets, [{k: params[k] + h} for k, h in zip(keys, steps)])
    r0 = residual_vector(datasets, base, sens_h)
    J = np.empty((r0.size, len(keys)))
    sig = {}
    for j, (k, h, out) in enumerate(zip(keys, steps, outs)):
        lo, hi = params.bounds[k]
        J[:, j] = (residual_vector(datasets, out, sens_h) - r0) / (h / (hi - lo))
        d = {}
        for i, ds in enumerate(datasets):
            for cid, ch in ds.channels.items():
                dm = (model_at_cells(out[i], ch, 0.0) - model_at_cells(base[i], ch, 0.0)) * (0.5 * (hi - lo) / abs(h))
                d.setdefault(cid, []).append(dm)
        sig[k] = {c: float(np.sqrt(np.mean(np.concatenate(v) ** 2))) for c, v in d.items()}
    return J, sig


def identifiability(
    keys: list, J: np.ndarray, sig: dict, ident_min_c: float = IDENT_MIN_C, collinear_cos: float = COLLINEAR_COS
) -> list:
    """Which keys the measured channels can fit: a signature above ident_min_c on some channel, and a sensitivity not
    parallel to a stronger key's."""
    norms = np.linalg.norm(J, axis=0)
    out = []
    strength = {k: max(sig[k].values()) for k in keys}
    for j, k in enumerate(keys):
        best_cos, with_k = 0.0, ""
        for i, o in enumerate(keys):
            if i != j and norms[i] > 0 and norms[j] > 0:
                c = abs(float(J[:, i] @ J[:, j]) / (norms[i] * norms[j]))
                if c > best_cos:
                    best_cos, with_k = c, o
        if strength[k] < ident_min_c:
            ch, v = max(sig[k].items(), key=lambda kv: kv[1])
            out.append(
                Identifiability(
                    k,
                    sig[k],
                    False,
                    f"over half its plausible range it moves no measured channel "
                    f"by more than {v:.2f} K ({ch}), below {ident_min_c:g} K",
                    best_cos,
                    with_k,
                )
            )
        elif best_cos >= collinear_cos and strength[with_k] >= strength[k]:
            out.append(
                Identifiability(
                    k,
                    sig[k],
                    False,
                    f"its effect on the measured channels is parallel to that of "
                    f"{with_k} (|cos| = {best_cos:.3f}): the data cannot separate them",
                    best_cos,
                    with_k,
                )
            )
        else:
            out.append(Identifiability(k, sig[k], True, "", best_cos, with_k))
    return out


# ----------------------------------------------------------------------------------------------------------------
# the fit


def _effective_n(r: np.ndarray) -> float:
    x = r - r.mean()
    den = float(x @ x)
    rho = float(x[1:] @ x[:-1]) / den if den > 0 and x.size > 2 else 0.0
    rho = min(max(rho, 0.0), 0.999)
    return max(x.size * (1 - rho) / (1 + rho), 2.0)


def fit(
    runs: PlantRuns, params: Parameters, datasets: list, keys: list, progress=None, sens_h: list | None = None
) -> tuple:
    """(fitted SI values, one-sigma SI, at-bound flags): bounded least squares over the keys scaled to 0..1 (the
    housings' start of a running file a nuisance, fitted per file: `sens_h`, residual_parts)."""
    from scipy.optimize import least_squares

    lo = np.array([params.bounds[k][0] for k in keys])
    hi = np.array([params.bounds[k][1] for k in keys])
    x0 = (np.array([params[k] for k in keys]) - lo) / (hi - lo)

    def fun(x):
        out = runs.run(datasets, [dict(zip(keys, lo + np.clip(x, 0, 1) * (hi - lo)))])[0]
        if progress:
            progress()
        return residual_vector(datasets, out, sens_h)

    # starts: the file's values and a Latin hypercube over the bounds (one batch of simulations); the thermal
    # responses are far from linear (the oil-system flow against the sun wheel), a local search from the file's
    # values alone can stop in the wrong valley
    starts = [x0] + list(latin_hypercube(len(keys), START_POINTS_PER_KEY * len(keys)))
    outs = runs.run(datasets, [dict(zip(keys, lo + x * (hi - lo))) for x in starts])
    costs = [float(np.sum(residual_vector(datasets, o, sens_h) ** 2)) for o in outs]
    best = None
    for i in np.argsort(costs)[:LOCAL_SEARCHES]:
        r_ = least_squares(
            fun,
            starts[i],
            bounds=(0.0, 1.0),
            x_scale=1.0,
            diff_step=0.02,
            xtol=1e-3,
            ftol=1e-4,
            max_nfev=10 * (len(keys) + 1),
        )
        if best is None or r_.cost < best.cost:
            best = r_
    res = best
    x = np.clip(res.x, 0, 1)
    r = res.fun
    n, p = r.size, len(keys)
    s2 = float(r @ r) / max(n - p, 1)
    try:
        cov = np.linalg.pinv(res.jac.T @ res.jac) * s2 * (n / _effective_n(r))
        sd = np.sqrt(np.clip(np.diag(cov), 0, None)) * (hi - lo)
    except np.linalg.LinAlgError:
        sd = np.full(p, np.nan)
    vals = lo + x * (hi - lo)
    at_bound = {k: bool(xi < 0.01 or xi > 0.99) for k, xi in zip(keys, x)}
    return dict(zip(keys, map(float, vals))), dict(zip(keys, map(float, sd))), at_bound


#: the plant's step for calibration [s]: as good as 1 s for these slow thermal fits (held-out RMS 0.127 vs 0.137 degC
#: on the docs' example) at 60 % of the time
CAL_DT_S = 2.0


def _identifiable_keys(ident: list, auto: bool) -> list[str]:
    """The keys the training files identify; one sentence when a key asked for by name (not ``auto``) is not, or
    when none is."""
    bad = [x for x in ident if not x.identifiable]
    if bad and not auto:
        x = bad[0]
        raise InputError(f"--params: {x.key} cannot be calibrated from these files: {x.reason}")
    keys_ok = [x.key for x in ident if x.identifiable]
    if not keys_ok:
        raise InputError(
            "none of the parameters with plausible bounds can be identified from these files: "
            + "; ".join(f"{x.key}: {x.reason}" for x in ident)
        )
    return keys_ok


def calibrate(
    train_tables,
    test_tables,
    params: Parameters,
    keys: list | None,
    auto: bool = False,
    cooler: str | None = None,
    opts: Options | None = None,
    progress=None,
    train_names=None,
    test_names=None,
    config_path=None,
    dt_s: float = CAL_DT_S,
) -> Calibration:
    """Calibrate `keys` (or, with `auto`, every key with bounds that the data can identify) to the training files,
    with the plant at `dt_s`."""
    opts = opts or Options()
    cooler = cooler or params.strings.get("cooler.kind", "liquid")
    wanted = sorted(params.bounds) if auto else check_keys(params, list(keys or []))
    params = with_fit_bounds(params, wanted)  # the thermostat's open below its full, whatever the trial
    if auto and not wanted:
        raise InputError(f"{params.origin} declares no parameter with plausible bounds (lo, hi): nothing to calibrate")
    runs_ = prepare_runs(
        train_tables, test_tables, opts, cooler in ("measured", "hold"), train_names, test_names, config_path, params
    )
    from tools.diagnosis.start import decide_starts

    starts = decide_starts(opts, runs_.train, runs_.test)  # rest, or every file running (--start running)
    train, test = starts.train, starts.test
    tick = progress or (lambda: None)
    runs = PlantRuns(params, cooler, dt_s, opts.workers)
    try:
        base_tr = runs.run(train, [{}])[0]
        sh_tr = housing_sensitivity(runs, train, base_tr)
        J, sig = sensitivities(runs, params, train, wanted, base_tr, sh_tr)
        ident = identifiability(wanted, J, sig)
        keys_ok = _identifiable_keys(ident, auto)
        fitted, sd, at_bound = fit(runs, params, train, keys_ok, tick, sh_tr)
        after_tr, base_te, after_te = runs.run(train, [fitted])[0], *runs.run(test, [{}, fitted])
        sh_te = housing_sensitivity(runs, test, base_te)
        before_c, after_c = channel_rms(test, base_te, sh_te), channel_rms(test, after_te, sh_te)
        rb, ra = residual_parts(test, base_te, sh_te), residual_parts(test, after_te, sh_te)
        plot = {
            "test": [
                (ds.name, cid, ch.cell_t_s, b, a)
                for ds, bs, as_ in zip(test, rb, ra)
                for (cid, ch), b, a in zip(ds.channels.items(), bs, as_)
            ]
        }
        r_tr = residual_vector(train, after_tr, sh_tr)
        train_s = sum(ds.t_end_s - (ds.scored_from_s if ds.scored_from_s is not None else ds.t_start_s) for ds in train)
        return Calibration(
            keys_ok,
            {k: params[k] for k in keys_ok},
            fitted,
            sd,
            at_bound,
            ident,
            (pooled_rms(train, base_tr, sh_tr), pooled_rms(train, after_tr, sh_tr)),
            (pooled_rms(test, base_te, sh_te), pooled_rms(test, after_te, sh_te)),
            {c: (before_c[c], after_c[c]) for c in before_c},
            runs.n_sims,
            [ds.name for ds in train],
            [ds.name for ds in test],
            plot,
            starts.records,
            _effective_n(r_tr),
            n_eff_needed(opts, len(keys_ok)),
            # by name: ``notes`` lies between (positional, the cells landed in it, the training seconds in n_cells)
            n_cells=int(r_tr.size),
            train_s=train_s,
        )
    finally:
        runs.close()


# ----------------------------------------------------------------------------------------------------------------
# output: the calibrated parameter file and the report


def _toml_key(key: str) -> str:
    import re

    return ".".join(
        p if re.fullmatch(r"[A-Za-z0-9_-]+", p) else '"' + p.replace('"', '\\"') + '"' for p in key.split(".")
    )


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items()) + " }"
    if isinstance(v, list):  # a topology entry's list (shaft segments, a gear's power path)
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    return '"' + str(v).replace("\\", "\\\\").replace('"', '\\"') + '"'


def calibrated_toml(base_file, params: Parameters, cal: Calibration, stamp: str) -> str:
    """The parameter file with the fitted values: every entry of `base_file` (inheritance resolved), the fitted ones
    with provenance ``fitted`` and a note of the data they came from, their one-sigma and the value they replace."""
    from firmware_model.parameters import UNITS, read_entries

    entries = read_entries(base_file)
    lines = [
        f"# {params.variant} calibrated by gearbox-vsensor calibrate ({stamp}) to {', '.join(cal.train)};",
        f"# held-out {', '.join(cal.test)}: RMS {cal.test_rms_c[0]:.3f} -> {cal.test_rms_c[1]:.3f} degC.",
        '# Fitted entries have src = "fitted"; every other entry is as in ' + str(params.origin) + ".",
    ]
    if cal.thin_evidence():
        lines.append("# " + cal.thin_evidence() + ".")
    for rival in getattr(cal, "rivals", ()):  # (SCADA: a channel a reading offset explains as well: said in the file)
        lines += ["# warning: " + part for part in textwrap.wrap(rival, 110)]
    lines.append("")
    for key, e in entries.items():
        if key in cal.fitted:
            fac = UNITS[e["u"]][1]
            was = e["v"]
            e = dict(e)
            e["v"] = float(f"{cal.fitted[key] / fac:.6g}")
            e["src"] = "fitted"
            e["note"] = (
                f"calibrated to {', '.join(cal.train)}: {e['v']:.6g} +- {cal.sigma[key] / fac:.2g} "
                f"{e['u']} (1 sigma, statistical); was {was} ({entries[key].get('src')})"
                + ("; at a bound of its plausible range" if cal.at_bound[key] else "")
            )
            e.pop("ref", None)
        lines.append(f"{_toml_key(key)} = {_toml_value(e)}")
    return "\n".join(lines) + "\n"


def _first_up(text: str) -> str:
    return text[:1].upper() + text[1:]


def report_markdown(cal: Calibration, params: Parameters, figure: str | None) -> str:
    """The calibration report: identifiability, fitted values, training and held-out RMS."""
    chans = sorted({c for x in cal.ident for c in x.signature_c})
    out = [
        "# Calibration report",
        "",
        f"Parameter file {params.origin}; training files {', '.join(cal.train)}; held-out {', '.join(cal.test)}; "
        f"{cal.n_sims} plant simulations.",
        "",
    ]
    running = [st.name for st in cal.starts if st.start == "running"]
    if running:
        out += [
            f"Runs that start running (scored after their first minutes, each with its housings' start fitted): "
            f"{', '.join(running)}.",
            "",
        ]
    out += [
        "## Identifiability",
        "",
        "Signature: the RMS change of each measured channel when the parameter moves over half its plausible "
        f"range [K]; identifiable when some channel moves by at least {IDENT_MIN_C:g} K and its sensitivity is "
        f"not parallel (|cos| >= {COLLINEAR_COS:g}) to a stronger parameter's.",
        "",
        "| parameter | " + " | ".join(chans) + " | max abs(cos), with | fitted |",
        "|---|" + "---|" * len(chans) + "---|---|",
    ]
    for x in cal.ident:
        sig = " | ".join(f"{x.signature_c.get(c, float('nan')):.2f}" for c in chans)
        out.append(
            f"| `{x.key}` | {sig} | {x.max_cos:.3f} {x.with_key} | {'yes' if x.identifiable else 'no: ' + x.reason} |"
        )
    out += [
        "",
        "## Fitted values",
        "",
        "| parameter | file value | fitted | 1 sigma (statistical) | SI unit |",
        "|---|---|---|---|---|",
    ]
    for k in cal.keys:
        unit = params.units.get(k, "")
        out.append(
            f"| `{k}` | {cal.start[k]:.6g} | {cal.fitted[k]:.6g} | {cal.sigma[k]:.2g} | {unit}"
            + ("; at a bound" if cal.at_bound[k] else "")
            + " |"
        )
    if cal.thin_evidence():
        out += ["", f"**Thin evidence.** {_first_up(cal.thin_evidence()[len('thin evidence: ') :])}."]
    out += [
        "",
        "The one-sigma figures are statistical (the residual's autocorrelation accounted for); they do not "
        "include the model's own form error, which is usually larger: judge the fit by the held-out files.",
        "",
        "## Residual RMS [degC]",
        "",
        "| | before (file values) | after (fitted) |",
        "|---|---|---|",
        f"| training files, pooled | {cal.train_rms_c[0]:.3f} | {cal.train_rms_c[1]:.3f} |",
        f"| held-out files, pooled | {cal.test_rms_c[0]:.3f} | {cal.test_rms_c[1]:.3f} |",
    ]
    for c, (b, a) in sorted(cal.test_by_channel.items()):
        out.append(f"| held-out, {c} | {b:.3f} | {a:.3f} |")
    if figure:
        out += ["", f"![held-out residual before and after]({figure})"]
    return "\n".join(out) + "\n"


def plot_held_out(cal: Calibration, path) -> bool:
    """The held-out residual per channel before and after (PNG); False when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    items = cal.plot["test"]
    fig, axes = plt.subplots(len(items), 1, figsize=(9, 2.2 * len(items) + 0.6), sharex=True, squeeze=False)
    for ax, (name, cid, t, before, after) in zip(axes[:, 0], items):
        ax.plot(t / 60.0, before, color="tab:red", lw=1.0, label="file values")
        ax.plot(t / 60.0, after, color="tab:blue", lw=1.0, label="calibrated")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_ylabel(f"{cid}\nmeasured - model [K]")
        ax.set_title(
            f"{name}: RMS {np.sqrt(np.mean(before**2)):.2f} -> {np.sqrt(np.mean(after**2)):.2f} K",
            fontsize=9,
            loc="left",
        )
        ax.grid(alpha=0.3)
    axes[0, 0].legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("time [min]")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return True
