"""Stage 3 of the diagnosis: fit every catalog effect on the training files and rank them by the information
criterion.

Per effect: re-simulation at its bound(s) and midpoint(s) (the grid, run with the baseline), a quadratic spline in the
parameter with the initial-temperature nuisance solved in closed form, a dense search, and a check of the minimum by
re-simulation (refined where the surrogate was off). The best re-simulated values compete with the neutral value,
each with its own refitted nuisance lags. Ranked by ``score = -dBIC`` with an effective sample size from the
residual's lag-1 autocorrelation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from firmware_model.effects import CATALOG, MEASUREMENT_EFFECTS
from tools.diagnosis.baseline import Baseline, GridPlan
from tools.diagnosis.context import Context
from tools.diagnosis.models import Run
from tools.diagnosis.options import ANALYTIC
from tools.diagnosis.scoring import box_lsq, start_design


@dataclass(frozen=True, eq=False)
class Fit:
    """One effect fitted on the training files."""

    effect: str
    value: float
    S: float  # misfit at the fitted value (with its own nuisance lags, initial temperature solved)
    preds_train: list  # per (dataset, channel) arrays on cells (with nuisance)
    out_train: list  # per dataset model outputs at the fitted value (re-simulated)
    at_bound: bool
    surrogate_S: float = float("nan")
    grid: dict = field(default_factory=dict)  # value -> per-(ds,ch) predictions
    lags: dict = field(default_factory=dict)  # the nuisance sensor lags refitted for this model


@dataclass(frozen=True, eq=False)
class Candidate:
    """A fitted effect scored on the criterion, with its predictions on the test files."""

    fit: Fit
    score: float  # -dBIC
    explained: float  # share of the excess squared residual it explains
    p_te: list  # predictions on the test files (re-simulated at the fitted value)
    tout: list  # the test re-simulation


@dataclass(frozen=True)
class Criterion:
    """The ranking: candidates best first, the sample sizes and the signatures for confusability."""

    candidates: list
    n: int
    n_eff: float
    rho: dict  # lag-1 autocorrelation of the best candidate's residual, per channel
    signatures: dict  # effect -> weighted change of the predictions, pooled over channels


# ----------------------------------------------------------------------------------------------------------------
# the grid


def grid_values(eid: str) -> list:
    """The neutral value, the bound(s) and the midpoint(s) towards them."""
    e = CATALOG[eid]
    vals = [e.neutral]
    for bound in (e.low, e.high):
        if bound == e.neutral:
            continue
        # the bound and the midpoint: responses can be far from linear (at 8 L the oil level changes which
        # wheels dip; the thermostat acts only above its opening temperature)
        vals += [bound, e.neutral + 0.5 * (bound - e.neutral)]
    return sorted(set(vals))


def use_coarse_grid(ctx: Context) -> bool:
    return bool(ctx.opts.coarse_grid) and ctx.is_plant


def grid_plan(ctx: Context) -> GridPlan:
    """The grid runs of every candidate: its bound(s) and the midpoint(s) towards them; the coarse plant baseline
    first."""
    coarse = use_coarse_grid(ctx)
    runs, keys = ([Run.of(coarse=True)], [None]) if coarse else ([], [])
    for eid in ctx.candidates:
        if eid in ANALYTIC:
            continue
        e = CATALOG[eid]
        for v in grid_values(eid):
            if v != e.neutral:
                runs.append(Run.of({eid: v}, coarse=coarse))
                keys.append((eid, v))
    return GridPlan(runs, keys)


def grid_predictions(ctx: Context, base: Baseline, grid: GridPlan) -> dict:
    """Effect -> {value: predictions} from the grid runs (coarse runs as differences to the coarse baseline)."""
    train, p0 = base.train.datasets, base.p0_hp
    grids = {eid: {CATALOG[eid].neutral: p0} for eid in ctx.candidates}
    outs, keys = list(base.grid_outs), list(grid.keys)
    ref = None
    if use_coarse_grid(ctx) and outs:
        ref = base.scorer.preds(train, outs[0])
        outs, keys = outs[1:], keys[1:]
    for (eid, v), out in zip(keys, outs):
        pr = base.scorer.preds(train, out, eid, v)
        if ref is not None:
            pr = [a + (p - r0) for a, p, r0 in zip(p0, pr, ref)]
        grids[eid][v] = pr
    return grids


# ----------------------------------------------------------------------------------------------------------------
# the surrogate


def _surrogate_min_analytic(ctx: Context, base: Baseline, eid: str) -> tuple:
    """The oil sensor's lag (an exact filter of the model's sump temperature), offset or gain (exact transforms of
    its prediction): the oil channel only, other channels unaffected."""
    from scipy.optimize import minimize_scalar

    e = CATALOG[eid]
    sc, train = base.scorer, base.train.datasets
    base_p = sc.preds(train, base.base_tr)

    def cost(v):
        return sc.S_adj(sc.preds(train, base.base_tr, eid, v) if v != e.neutral else base_p)

    fine = [np.linspace(0, min(20.0, e.high), 41)] if eid == "oil_sensor_lag" else []  # short lags, finely
    dense = np.unique(np.concatenate(fine + [np.linspace(e.low, e.high, ctx.opts.dense)]))
    c = np.array([cost(t) for t in dense])
    i = int(np.argmin(c))
    lo, hi = dense[max(i - 1, 0)], dense[min(i + 1, dense.size - 1)]
    best, bS = float(dense[i]), float(c[i])
    if hi > lo:
        r = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": 0.02})
        if r.fun < bS:
            best, bS = float(r.x), float(r.fun)
    return round(best, 3), bS


def _surrogate_min_spline(ctx: Context, base: Baseline, eid: str, grid: dict) -> tuple:
    """A quadratic spline through the grid's predictions, S on a dense parameter grid with the initial-temperature
    nuisance solved in closed form per file; the minimum snapped to a simulated value within one dense step."""
    from scipy.interpolate import make_interp_spline

    e = CATALOG[eid]
    dense = np.linspace(e.low, e.high, ctx.opts.dense)
    rd = base.train
    xs = np.array(sorted(grid))
    kk = min(2, xs.size - 1)
    S = np.zeros(dense.size)
    dmax = ctx.opts.initial_offset_max_c
    for f, idx in enumerate(rd.files):
        if rd.sens_h is not None and rd.datasets[f].start == "running":
            S += _running_file_S(ctx, rd, idx, xs, kk, dense, grid)
            continue
        # per file: S(theta) with the initial-temperature nuisance solved in closed form
        raw = np.zeros(dense.size)
        num = np.zeros(dense.size)
        den = 0.0
        for k in idx:
            Y = np.array([grid[x][k] for x in xs])
            P = make_interp_spline(xs, Y, k=kk, axis=0)(dense)
            R = rd.obs[k] - P
            raw += np.sum(rd.w[k] * R**2, axis=1)
            num += np.sum(rd.w[k] * R * rd.sens[k], axis=1)
            den += float(np.sum(rd.w[k] * rd.sens[k] ** 2))
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


def _running_file_S(ctx: Context, rd, idx: list, xs: np.ndarray, kk: int, dense: np.ndarray, grid: dict) -> np.ndarray:
    """S(theta) on the dense grid of one file that starts running: both start nuisances (uniform, housings) fitted
    per value in their box, as Scorer.adjust fits them (tools/diagnosis/start.py)."""
    from scipy.interpolate import make_interp_spline

    P = np.concatenate(
        [make_interp_spline(xs, np.array([grid[x][k] for x in xs]), k=kk, axis=0)(dense) for k in idx], axis=1
    )
    y, w, A, lo, hi = start_design(rd, idx, ctx.opts)
    return np.array([box_lsq(y - P[j], w, A, lo, hi)[1] for j in range(dense.size)])


def surrogate_min(ctx: Context, base: Baseline, eid: str, grid: dict) -> tuple:
    """(value, predicted S) at the surrogate's minimum."""
    if eid in ANALYTIC:
        return _surrogate_min_analytic(ctx, base, eid)
    return _surrogate_min_spline(ctx, base, eid, grid)


# ----------------------------------------------------------------------------------------------------------------
# the search


@dataclass
class Search:
    """The search for one effect's value (mutable: refined in rounds)."""

    value: float | None = None
    surrogate_S: float = float("nan")
    checked: dict = field(default_factory=dict)  # value -> Checked
    done: bool = False


@dataclass(frozen=True, eq=False)
class Checked:
    """A re-simulated value: its misfit, its predictions, the model outputs."""

    S: float | None
    preds: list | None
    out: list


def _drop_uncompetitive(ctx: Context, base: Baseline, state: dict) -> None:
    """After the first round only the 4 best candidates (by their best checked misfit) are refined further."""
    S0h = base.scorer.S_adj(base.p0_hp)
    ranked = sorted(ctx.candidates, key=lambda e: min([s.S for s in state[e].checked.values()] + [S0h]))
    for eid in ranked[4:]:
        state[eid].done = True


def _search_round(ctx: Context, base: Baseline, grids: dict, state: dict) -> bool:
    """One round: the surrogate's minimum of every open search, re-simulated; False when nothing was left to
    check."""
    sc, train = base.scorer, base.train.datasets
    runs, keys = [], []
    for eid in ctx.candidates:
        st = state[eid]
        if st.done:
            continue
        st.value, st.surrogate_S = surrogate_min(ctx, base, eid, grids[eid])
        if st.value in st.checked or st.value == CATALOG[eid].neutral:
            st.done = True  # the neutral value is the baseline: nothing to check
            continue
        runs.append(Run.of({eid: st.value}))
        keys.append(eid)
    if not runs:
        return False
    # the measurement effects read the baseline run differently: nothing to simulate
    to_sim = [r for r, k in zip(runs, keys) if k not in MEASUREMENT_EFFECTS]
    sims = iter(ctx.sim.run(train, to_sim) if to_sim else [])
    outs = [base.base_tr if k in MEASUREMENT_EFFECTS else next(sims) for k in keys]
    for eid, out in zip(keys, outs):
        st = state[eid]
        v = st.value
        pr = sc.preds(train, out, eid, v)
        S = sc.S_adj(pr)
        st.checked[v] = Checked(S, pr, out)
        if eid not in ANALYTIC:
            grids[eid][v] = pr
        # converged when the surrogate predicted the re-simulated misfit within 2 % (+ noise level)
        tol = 0.02 * S + 1.0
        if abs(S - st.surrogate_S) <= tol or eid in ANALYTIC:
            st.done = True
    return True


def _best_checked(ctx: Context, base: Baseline, eid: str, st: Search, grid: dict) -> Fit:
    """The best re-simulated value, each scored with its own best nuisance lags; the neutral value (the baseline)
    competes too, so that a candidate never scores below the unmodified model."""
    sc, train = base.scorer, base.train.datasets
    e = CATALOG[eid]
    best = None
    pool = dict(st.checked)
    pool.setdefault(e.neutral, Checked(None, None, base.base_tr))
    for v_, chk in sorted(pool.items(), key=lambda kv: kv[1].S if kv[1].S is not None else -1)[:2]:
        eff = eid if v_ != e.neutral else None
        lags_ = sc.refit_lags(chk.out, eff)
        pr_ = sc.adjust(sc.preds(train, chk.out, eff, v_, lags=lags_), "train")
        S_ = sc.S(pr_)
        if best is None or S_ < best.S:
            best = Fit(eid, float(v_), S_, pr_, chk.out, False, st.surrogate_S, grid, lags_)
    span = e.high - e.low
    v = best.value
    near = [b for b in (e.low, e.high) if b != e.neutral and abs(v - b) < 0.02 * span]
    at_bound = bool(near)
    if near and eid in ANALYTIC and v != near[0]:
        # an exact effect can be scored at the bound itself: a minimum inside the range is not pinned there
        S_b = sc.S(sc.adjust(sc.preds(train, base.base_tr, eid, near[0], lags=best.lags), "train"))
        at_bound = not S_b > best.S
    return Fit(eid, v, best.S, best.preds_train, best.out_train, bool(at_bound), st.surrogate_S, grid, best.lags)


def fit_all(ctx: Context, base: Baseline, grid: GridPlan) -> list:
    """Every candidate fitted: the grid, the surrogate, refinement rounds, the best re-simulated value."""
    grids = grid_predictions(ctx, base, grid)
    # surrogate optimum per effect, then re-simulate; refine the competitive ones where surrogate and
    # re-simulation disagree
    state = {eid: Search() for eid in ctx.candidates}
    for it in range(ctx.opts.refine + 1):
        if it > 0:
            _drop_uncompetitive(ctx, base, state)
        if not _search_round(ctx, base, grids, state):
            break
    return [_best_checked(ctx, base, eid, state[eid], grids[eid]) for eid in ctx.candidates]


# ----------------------------------------------------------------------------------------------------------------
# the criterion


def lag1_rho(resid: np.ndarray) -> float:
    """The lag-1 autocorrelation of a residual (its mean removed), in 0..0.999."""
    r = resid - resid.mean()
    den = float(np.dot(r, r))
    rho = float(np.dot(r[1:], r[:-1]) / den) if den > 0 and r.size > 2 else 0.0
    return min(max(rho, 0.0), 0.999)


def effective_n(datasets: list, resid: list) -> tuple:
    """(n_eff, lag-1 autocorrelation per channel): the sample size shrunk by each residual's autocorrelation."""
    rho_ch = {}
    n_eff = 0.0
    k = 0
    for ds in datasets:
        for cid, _ch in ds.channels.items():
            rho = lag1_rho(resid[k])
            n_eff += resid[k].size * (1 - rho) / (1 + rho)
            k += 1
            rho_ch.setdefault(cid, []).append(rho)
    return max(n_eff, 2.0), {c: float(np.mean(v)) for c, v in rho_ch.items()}


def simulate_test_files(ctx: Context, base: Baseline, fits: list) -> list:
    """Per fit, the test files re-simulated at its fitted value (the baseline where it fitted neutral)."""
    moved = [f for f in fits if f.value != CATALOG[f.effect].neutral and f.effect not in MEASUREMENT_EFFECTS]
    touts_m = dict(
        zip(
            [f.effect for f in moved],
            ctx.sim.run(base.test.datasets, [Run.of({f.effect: f.value}) for f in moved]) if moved else [],
        )
    )
    return [touts_m.get(f.effect, base.base_te) for f in fits]


def rank(base: Baseline, fits: list, touts: list) -> Criterion:
    """score = -dBIC = -(n_eff ln(S_effect / S_baseline) + k ln n_eff), k = 1; best first."""
    sc, rd = base.scorer, base.train
    S0 = base.S0
    N = sum(p.size for p in base.p0_tr)
    best = min(fits, key=lambda f: f.S)
    n_eff, rho = effective_n(rd.datasets, [y - p for y, p in zip(rd.obs, best.preds_train)])
    cands = []
    for f, tout in zip(fits, touts):
        dbic = n_eff * math.log(max(f.S, 1e-12) / max(S0, 1e-12)) + 1.0 * math.log(max(n_eff, 2.0))
        p_te = sc.adjust(sc.preds(base.test.datasets, tout, f.effect, f.value, lags=f.lags), "test")
        explained = (S0 - f.S) / max(S0 - base.S_noise, 0.02 * S0, 1e-12)
        cands.append(Candidate(f, -dbic, float(explained), p_te, tout))
    cands.sort(key=lambda c: -c.score)
    # signatures for confusability (weighted, pooled over channels)
    sigs = {
        c.fit.effect: np.concatenate(
            [np.sqrt(wi) * (pf - p0) for pf, p0, wi in zip(c.fit.preds_train, base.p0_tr, rd.w)]
        )
        for c in cands
    }
    return Criterion(cands, int(N), n_eff, rho, sigs)
