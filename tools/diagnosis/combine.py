"""Stage 4b of the diagnosis: several effects at once, by forward selection.

After the best single effect, the next one is sought on top of it: every other candidate's change (from its own
single-effect grid, or exactly for the oil sensor's lag, offset and gain) is added to the current set's run and its
parameter searched on a dense grid, then moved together with the set's members by coordinate passes on the same
surrogates; the two best are re-simulated together with the set; the best joins when the held-in evidence still pays
for one more parameter (the same criterion as for one effect: an increment of
``-dBIC = -(n_eff ln(S_new / S_set) + ln n_eff)`` of at least ``evidence_min``), it explains at least
``add_explain_min`` of what the set left unexplained, a real gap was left, and it has ``add_share_min`` of all the
set explains or closes a clear gap. Then all chosen parameters are refitted
jointly (a coordinate pass on the same surrogates, re-simulated and kept when it lowers the misfit). At most
``max_effects`` effects; at most one of the exact sensor effects (lag, offset, gain) in a set.

Each member's share of the explained residual: for a pair, the average of its two orders of entry (its share does not
depend on which was found first); for three, in the order found. The joint set is re-simulated on the test files:
its held-out shrink is the verdict's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from firmware_model.effects import CATALOG, fraction_of_range
from tools.diagnosis.baseline import Baseline
from tools.diagnosis.context import Context
from tools.diagnosis.decide import pooled_rms
from tools.diagnosis.fit import Criterion, Fit
from tools.diagnosis.models import Run
from tools.diagnosis.options import ANALYTIC, OIL


@dataclass(frozen=True, eq=False)
class Step:
    """One effect added to the set: its incremental evidence and the other effects nearly as good at that step."""

    effect: str
    score: float  # incremental -dBIC
    explained: float  # share of what the set before it left unexplained
    alternatives: tuple  # effects whose increment came within confusable_share of this one's


@dataclass(frozen=True, eq=False)
class Combination:
    """Effects fitted together on the training files and re-simulated together on the test files."""

    members: dict  # effect -> value, leading effect first
    S: float  # joint misfit (training files, own nuisance lags, initial temperature solved)
    preds_train: list
    p_te: list
    score: float  # -dBIC against the baseline, k = number of members
    explained: float  # share of the excess squared residual the set explains
    shares: dict  # effect -> share of the explained part
    steps: list = field(default_factory=list)  # the forward steps after the leading effect
    out_train: list | None = None  # the set's training run (model outputs per file)
    start: tuple = ()  # the (oil-sensor effect, value) that run started from (Run.start)


class SetState:
    """The set being grown: its members, its training run (started from `start`, Run.start) and its raw (unadjusted)
    predictions."""

    def __init__(self, base: Baseline, members: dict, out: list, start: tuple = ()):
        self.base, self.members, self.out, self.start = base, dict(members), out, tuple(start)
        self.raw = preds_of(base, base.train.datasets, out, members, start=self.start)
        self.S = base.scorer.S_adj(self.raw)


def preds_of(
    base: Baseline, datasets: list, outs: list, members: dict, lags: dict | None = None, start: tuple = ()
) -> list:
    """Predictions of a set's run (started from `start`): its (at most one) exact sensor effect applied to the model
    outputs."""
    exact = [(e, v) for e, v in members.items() if e in ANALYTIC]
    e, v = exact[0] if exact else (None, None)
    return base.scorer.preds(datasets, outs, e, v, lags=lags, start=start)


#: the exact sensor effects that move the initial temperature: a set's runs start from the sump their reading implies
START_EFFECTS = ("oil_sensor_offset", "oil_sensor_gain")


def start_of(members: dict) -> tuple:
    """(effect, value) of a set's oil-sensor offset or gain, () without one: the set's runs start every file from the
    sump that the first reading implies through it, exactly. To first order (the baseline's sensitivity to its
    initial temperature) a start several kelvin off is wrong where the model is not linear: an air cooler's
    thermostat at the first reading (a gain of x1.07 and a thermostat 7.7 K late left 1.45 K of systematic residual
    on a rig's PS thermocouple to first order, none started exactly)."""
    return next(((e, float(v)) for e, v in members.items() if e in START_EFFECTS and v != CATALOG[e].neutral), ())


def startable(datasets: list) -> bool:
    """Do all these files start from an oil reading (a file without the oil channel starts from a thermocouple's,
    which an oil-sensor effect does not move)?"""
    return all(OIL in ds.channels for ds in datasets)


def _physical(members: dict) -> dict:
    return {e: v for e, v in members.items() if e not in ANALYTIC}


#: coordinate passes over the set's members and a candidate on the surrogates (:func:`_surrogate_on_top`)
SURROGATE_PASSES = 2


def _dense(eid: str, n: int = 41) -> np.ndarray:
    e = CATALOG[eid]
    return np.linspace(e.low, e.high, n)


def delta_fn(base: Baseline, fit: Fit):
    """v -> per-entry change of the predictions from the effect's single-effect grid (quadratic spline)."""
    from scipy.interpolate import make_interp_spline

    xs = np.array(sorted(fit.grid))
    if xs.size < 2:
        return None
    kk = min(2, xs.size - 1)
    n = len(base.p0_hp)
    splines = [make_interp_spline(xs, np.array([fit.grid[x][k] for x in xs]), k=kk, axis=0) for k in range(n)]
    return lambda v: [s(v) - p for s, p in zip(splines, base.p0_hp)]


def _surrogate_on_top(ctx: Context, base: Baseline, st: SetState, eid: str, fit: Fit, deltas: dict) -> tuple:
    """((members, surrogate misfit) with the set as it is, (members, misfit) with the set moving): effect `eid`'s
    value searched on a dense grid on top of the set (exact for a sensor effect, else the set's run plus the
    effect's single-effect change); then :data:`SURROGATE_PASSES` coordinate passes over the set's members and `eid`
    on the same surrogates. The second matters when the set's members took up part of `eid`'s signature before it
    joined (gear friction fitted at x0.72 where the truth is x0.59 with teeth convection x0.7: on top of x0.72 teeth
    convection looks weak); the first is kept because the members' surrogates (changes around the baseline, not
    around the set's run) are rougher than the set's own run."""
    members = {**st.members, eid: CATALOG[eid].neutral}
    S_of = surrogate_misfit(base, st, deltas)
    best_S = S_of(members)
    order = [eid] + [m for m in st.members if m in ANALYTIC or deltas.get(m) is not None]
    fixed = None
    for k in range(1 + SURROGATE_PASSES):
        moved = False
        for m in order[:1] if k == 0 else order:
            for v in _dense(m):
                trial = {**members, m: float(v)}
                S = S_of(trial)
                if S < best_S:
                    members, best_S, moved = trial, S, True
        if k == 0:
            fixed = (members, best_S)
        elif not moved:
            break
    return fixed, (members, best_S)


def surrogate_misfit(base: Baseline, st: SetState, deltas: dict):
    """members -> the surrogate misfit of a set near `st`: the exact sensor effect applied to the set's run, plus the
    changes of the physical members from their values in `st` (their single-effect grids)."""
    sc, train = base.scorer, base.train.datasets
    exact0 = {e: v for e, v in st.members.items() if e in ANALYTIC}
    at_st: dict = {}  # a physical member's change at its value in `st`, computed once

    def S_of(members: dict) -> float:
        exact = {e: v for e, v in members.items() if e in ANALYTIC}
        raw = st.raw if exact == exact0 else preds_of(base, train, st.out, members, start=st.start)
        for m, v in members.items():
            v0 = st.members.get(m, CATALOG[m].neutral)
            if m in ANALYTIC or v == v0:
                continue
            if m not in at_st:
                at_st[m] = deltas[m](v0)
            raw = [a + d - d0 for a, d, d0 in zip(raw, deltas[m](v), at_st[m])]
        return sc.S_adj(raw)

    return S_of


def eligible(ctx: Context, st: SetState, fits: dict, deltas: dict) -> list:
    has_exact = any(e in ANALYTIC for e in st.members)
    out = []
    for eid, _f in fits.items():
        if eid in st.members or (eid in ANALYTIC and has_exact):
            continue
        if eid not in ANALYTIC and (deltas.get(eid) is None or ctx.backend_of(eid) != ctx.model.name):
            continue  # no grid, or fitted by the fallback plant (cannot be combined)
        out.append(eid)
    return out


def simulate_sets(ctx: Context, base: Baseline, sets: list, cur: SetState) -> list:
    """The SetStates of candidate sets, each run started from the sump its oil-sensor offset or gain implies
    (:func:`start_of`); the current run is reused where a set has the same physical effects and start."""
    ok = startable(base.train.datasets)
    keys = [(_physical(m), start_of(m) if ok else ()) for m in sets]
    need = [i for i, k in enumerate(keys) if k != (_physical(cur.members), cur.start)]
    sims = ctx.sim.run(base.train.datasets, [Run.of(keys[i][0], start=keys[i][1]) for i in need]) if need else []
    outs = [(cur.out, cur.start)] * len(sets)
    for i, o in zip(need, sims):
        outs[i] = (o, keys[i][1])
    return [SetState(base, m, out, start) for m, (out, start) in zip(sets, outs)]


def at_start(ctx: Context, base: Baseline, st: SetState) -> SetState:
    """`st` run from the sump its oil-sensor offset or gain implies (:func:`start_of`): re-simulated when it was not,
    else `st` itself."""
    return simulate_sets(ctx, base, [st.members], st)[0] if start_of(st.members) != st.start else st


def _refit_jointly(ctx: Context, base: Baseline, st: SetState, deltas: dict, passes: int = 3) -> SetState:
    """Coordinate passes over the members on the surrogates around the joint run, each re-simulated and kept while
    it lowers the misfit."""
    for _ in range(passes):
        new = _coordinate_pass(ctx, base, st, deltas)
        if new is st:
            break
        st = new
    return st


def _coordinate_pass(ctx: Context, base: Baseline, st: SetState, deltas: dict) -> SetState:
    """One coordinate pass over the members on the surrogates around the joint run, re-simulated; kept if better."""
    sc, train = base.scorer, base.train.datasets
    members = dict(st.members)
    raw = st.raw
    for eid in list(members):
        v0 = members[eid]
        best_v, best_S = v0, sc.S_adj(raw)
        d0 = None if eid in ANALYTIC else deltas[eid](v0)
        for v in _dense(eid):
            v = float(v)
            if eid in ANALYTIC:
                S = sc.S_adj(preds_of(base, train, st.out, {**members, eid: v}, start=st.start))
            else:
                S = sc.S_adj([a + d - d_0 for a, d, d_0 in zip(raw, deltas[eid](v), d0)])
            if S < best_S:
                best_v, best_S = v, S
        if best_v != v0:
            members[eid] = best_v
            if eid not in ANALYTIC:
                raw = [a + d - d_0 for a, d, d_0 in zip(raw, deltas[eid](best_v), d0)]
            else:
                raw = preds_of(base, train, st.out, members, start=st.start)
    if members == st.members:
        return st
    new = simulate_sets(ctx, base, [members], st)[0]
    return new if new.S < st.S else st


def _step(ctx: Context, base: Baseline, crit: Criterion, st: SetState, fits: dict, deltas: dict, gap_thr_c: dict):
    """(the set with one more effect, its Step), or None when nothing pays for one more parameter. A new effect with
    less than add_share_min of all the set explains joins only when it closes a clear gap (:func:`_closes_clear_gap`):
    a modest effect beside a large one (churning x0.55 beside teeth convection x0.6 on a rig) is a small share of the
    whole, yet the gap the large one leaves alone is the evidence for it."""
    o = ctx.opts
    cands, moving = [], []
    for eid in eligible(ctx, st, fits, deltas):
        (m, S), (m2, S2) = _surrogate_on_top(ctx, base, st, eid, fits[eid], deltas)
        if m[eid] != CATALOG[eid].neutral:
            cands.append((S, eid, m))
        if m2[eid] != CATALOG[eid].neutral:
            moving.append((S2, eid, m2))
    if not cands and not moving:
        return None
    cands.sort(key=lambda c: (c[0], c[1]))
    moving.sort(key=lambda c: (c[0], c[1]))
    checked = []
    # the best few with the set as it is, and the best with the set moving (when it is another set)
    sets = [m for _S, _eid, m in cands[: o.combine_check]]
    sets += [m for _S, _eid, m in moving[:1] if m not in sets]
    checked.extend(simulate_sets(ctx, base, sets, st))
    checked.sort(key=lambda s: s.S)
    best = _refit_jointly(ctx, base, checked[0], deltas)
    excess = max(st.S - base.S_noise, 0.02 * st.S, 1e-12)
    gain = (st.S - best.S) / excess
    score = -(crit.n_eff * math.log(max(best.S, 1e-12) / max(st.S, 1e-12)) + math.log(max(crit.n_eff, 2.0)))
    added = next(e for e in best.members if e not in st.members)
    # its share of all the set now explains, averaged over entering last and entering alone (its single fit)
    share = 0.5 * ((st.S - best.S) + max(base.S0 - fits[added].S, 0.0)) / max(base.S0 - best.S, 1e-12)
    if (
        score < o.evidence_min
        or gain < o.add_explain_min
        or abs(fraction_of_range(added, best.members[added])) < o.min_frac
    ):
        return None
    if share < o.add_share_min and not _closes_clear_gap(ctx, base, st, best, gap_thr_c):
        return None
    # alternatives: other effects whose surrogate increment came within confusable_share of the added one's (both
    # on the same surrogate footing; the checked increment of the added effect is higher after its joint refit)
    sur = {e: (st.S - S) / excess for S, e, _v in cands}
    alts = tuple(e for _S, e, _v in cands if e != added and sur[e] >= sur.get(added, gain) - o.confusable_share)
    return best, Step(added, float(score), float(gain), alts)


def _closes_clear_gap(ctx: Context, base: Baseline, before: SetState, after: SetState, gap_thr_c: dict) -> bool:
    """The set before left a clear gap (a systematic residual at least f = clear_gap_factor times its threshold on
    some channel: not the model's own error at the threshold), and the set after leaves none above the threshold, or
    no clear gap and less than 1 / clear_gap_cut of the one before (the largest ratio to the threshold over the
    channels). A rig's planetary losses x1.41 left 3.9 (900 s files) or 5.2 (1500 s) times the threshold on BLR, and
    bearing losses x0.55 beside them, 1.4 % of all the pair explains, take it to 1.2 or 1.03. A truck's cooler and
    oil-sensor gain, standing in for the planted cooler and sensor offset, would take a thermostat offset the truth
    does not have from 2.8 to 1.4 times: a cut by 2, which the cut factor 2.5 refuses."""
    sc = base.scorer
    o = ctx.opts
    r_before = gap_ratio(ctx, base, sc.adjust(before.raw, "train"), gap_thr_c)
    if r_before < o.clear_gap_factor:
        return False
    r_after = gap_ratio(ctx, base, sc.adjust(after.raw, "train"), gap_thr_c)
    return r_after <= 1.0 or r_after < min(o.clear_gap_factor, r_before / o.clear_gap_cut)


def _shares(base: Baseline, fits: dict, members: dict, chain: list) -> dict:
    """Each member's share of the explained misfit (pairs: averaged over both orders; else in the order found)."""
    S0 = base.S0
    total = max(S0 - chain[-1], 1e-12)
    ids = list(members)
    if len(ids) == 2:
        a, b = ids
        Sa, Sb, Sab = fits[a].S, fits[b].S, chain[-1]
        sa = 0.5 * ((S0 - Sa) + (Sb - Sab)) / total
        return {a: float(sa), b: float(1.0 - sa)}
    prev, out = S0, {}
    for eid, S in zip(ids, chain):
        out[eid] = float((prev - S) / total)
        prev = S
    return out


def gap_ratio(ctx: Context, base: Baseline, preds: list, gap_thr_c: dict) -> float:
    """The largest ratio, over the channels, of the systematic residual after predictions `preds` to its gap
    threshold (above 1: a real gap remains)."""
    from tools.diagnosis.decide import systematic

    post = systematic(base, preds, ctx.opts).rms_c
    return max((post[c] / gap_thr_c[c] for c in post), default=0.0)


def gap_left(ctx: Context, base: Baseline, preds: list, gap_thr_c: dict) -> bool:
    """Does a real gap remain after predictions `preds` (systematic residual above the gap threshold on some
    channel)?"""
    return gap_ratio(ctx, base, preds, gap_thr_c) > 1.0


def forward_select(ctx: Context, base: Baseline, crit: Criterion, fits: list, gap_thr_c: dict, start=None):
    """The set of effects found together, starting from the best single candidate (or the Fit `start`), grown while
    a real gap remains (above `gap_thr_c` on some channel) and the next effect pays for itself; None when no second
    effect joins (then the verdict stays one effect)."""
    o = ctx.opts
    top = start if start is not None else crit.candidates[0].fit
    if o.max_effects < 2 or top.value == CATALOG[top.effect].neutral:
        return None
    by_id = {f.effect: f for f in fits}
    deltas = {eid: (None if eid in ANALYTIC else delta_fn(base, f)) for eid, f in by_id.items()}
    # an offset or gain leader from the sump its reading implies, so that a partner's increment is not the start's
    st = at_start(ctx, base, SetState(base, {top.effect: top.value}, top.out_train))
    chain, steps = [st.S], []
    while len(st.members) < o.max_effects and gap_left(ctx, base, base.scorer.adjust(st.raw, "train"), gap_thr_c):
        nxt = _step(ctx, base, crit, st, by_id, deltas, gap_thr_c)
        if nxt is None:
            break
        st, step = nxt
        chain.append(st.S)
        steps.append(step)
    if len(st.members) < 2:
        return None
    return _finish(ctx, base, crit, by_id, st, chain, steps)


def _finish(
    ctx: Context, base: Baseline, crit: Criterion, fits: dict, st: SetState, chain: list, steps: list
) -> Combination:
    """The chosen set with its own nuisance lags, scored, and re-simulated on the test files."""
    sc = base.scorer
    exact = next((e for e in st.members if e in ANALYTIC), None)
    lags = sc.refit_lags(st.out, exact)
    pr = sc.adjust(preds_of(base, base.train.datasets, st.out, st.members, lags, start=st.start), "train")
    if sc.S(pr) > st.S:  # the refitted lags did not help: keep the scorer's
        lags = dict(sc.lag)
        pr = sc.adjust(st.raw, "train")
    S = sc.S(pr)
    chain[-1] = S
    k = len(st.members)
    score = -(crit.n_eff * math.log(max(S, 1e-12) / max(base.S0, 1e-12)) + k * math.log(max(crit.n_eff, 2.0)))
    explained = (base.S0 - S) / max(base.S0 - base.S_noise, 0.02 * base.S0, 1e-12)
    phys = _physical(st.members)
    t_start = start_of(st.members) if startable(base.test.datasets) else ()
    tout = ctx.sim.run(base.test.datasets, [Run.of(phys, start=t_start)])[0] if phys or t_start else base.base_te
    p_te = sc.adjust(preds_of(base, base.test.datasets, tout, st.members, lags, start=t_start), "test")
    return Combination(
        dict(st.members),
        S,
        pr,
        p_te,
        float(score),
        float(explained),
        _shares(base, fits, st.members, chain),
        steps,
        st.out,
        st.start,
    )


def _acceptable(ctx: Context, base: Baseline, combo: Combination, gap_thr_c: dict) -> bool:
    """A set stands as a verdict: strong evidence as a whole (score >= evidence_min with k = its size), it explains
    at least explain_min of the excess, every member sits at least min_frac from neutral, and none is pinned at a
    bound while a gap remains."""
    o = ctx.opts
    if combo.score < o.evidence_min or combo.explained < o.explain_min:
        return False
    if any(abs(fraction_of_range(e, v)) < o.min_frac for e, v in combo.members.items()):
        return False
    pinned = any(abs(fraction_of_range(e, v)) > 0.98 for e, v in combo.members.items())
    return not (pinned and gap_left(ctx, base, combo.preds_train, gap_thr_c))


def _alone_score(ctx: Context, base: Baseline, crit: Criterion, cand) -> float:
    """A candidate's score alone, counted as a set's is: an oil-sensor offset or gain from the sump its reading
    implies (:func:`start_of`), so that a set grown from another start, which starts so, is not preferred for the
    start alone (a rig's offset +3 K on an air cooler lost to a gain with a partner the truth does not have)."""
    members = {cand.fit.effect: cand.fit.value}
    if not start_of(members):
        return cand.score
    st = at_start(ctx, base, SetState(base, members, cand.fit.out_train))
    return -(crit.n_eff * math.log(max(st.S, 1e-12) / max(base.S0, 1e-12)) + math.log(max(crit.n_eff, 2.0)))


def _test_rms(base: Baseline, p_te: list) -> float:
    """Pooled RMS of the test files' residual under predictions ``p_te`` (as the verdict's test_rms_after_c)."""
    return pooled_rms([y - p for y, p in zip(base.test.obs, p_te)])


def select_set(ctx: Context, base: Baseline, crit: Criterion, fits: list, gap_thr_c: dict, confusable: dict) -> tuple:
    """Forward selection from the best single candidate, and also from each candidate confusable with it (alone the
    data cannot tell them apart, so either may be the set's first member: a sensor offset and hot surroundings both
    lift the oil, but only one of them leaves room for a load-dependent second effect). A set grown from another
    start replaces the best candidate's own result only when it is acceptable as a whole (see :func:`rescue`), its
    score beats that result (the set, or the best candidate alone) by at least evidence_min, and on the held-out
    files it does no worse than that result (RMS at most ``set_start_test_tol`` above): the held-out files guard
    the verdict, so a set that fits the training files better and them worse is an overfit, not the explanation
    (bearings x2.5 with a +2 K oil-sensor offset can be fitted as a gain, housing convection and retarder heat,
    none planted: 0.51 K held-out against 0.14 K for the offset alone). (set or None: one effect, note for the reason or
    "")."""
    o = ctx.opts
    top = crit.candidates[0]
    best = forward_select(ctx, base, crit, fits, gap_thr_c)
    best_score = best.score if best is not None else _alone_score(ctx, base, crit, top)
    own_test_rms = _test_rms(base, best.p_te if best is not None else top.p_te)
    alts = [c for c in crit.candidates[1:] if c.fit.effect in confusable.get(top.fit.effect, ())][: o.set_starts - 1]
    note = ""
    for cand in alts:
        if abs(fraction_of_range(cand.fit.effect, cand.fit.value)) < o.min_frac:
            continue
        combo = forward_select(ctx, base, crit, fits, gap_thr_c, start=cand.fit)
        if combo is None or not _acceptable(ctx, base, combo, gap_thr_c):
            continue
        if combo.score < best_score + o.evidence_min:
            continue
        combo_test_rms = _test_rms(base, combo.p_te)
        if combo_test_rms > own_test_rms * (1.0 + o.set_start_test_tol):
            note = (
                f"; a set grown from {cand.fit.effect} ({' + '.join(combo.members)}) scored higher on the "
                f"training files ({combo.score:.0f} against {best_score:.0f}) but left the held-out files worse "
                f"({combo_test_rms:.3f} against {own_test_rms:.3f} degC RMS): not taken, an overfit"
            )
            continue
        best, best_score, own_test_rms, note = combo, combo.score, combo_test_rms, ""
    return best, note


def rescue(ctx: Context, base: Baseline, crit: Criterion, fits: list, gap_thr_c: dict):
    """When no single effect passes (the best one pinned at a bound with a gap left, or too weak alone), several
    effects may explain the gap together: forward selection from each of the two strongest candidates; a set is
    accepted when, as a whole, it has strong evidence (score >= evidence_min with k = its size), explains at least
    explain_min of the excess, every member sits at least min_frac from neutral, and none is pinned at a bound while a
    gap remains. The best accepted set (by score), or None."""
    o = ctx.opts
    best = None
    for cand in crit.candidates[:2]:
        f = cand.fit
        if abs(fraction_of_range(f.effect, f.value)) < o.min_frac:
            continue
        combo = forward_select(ctx, base, crit, fits, gap_thr_c, start=f)
        if combo is None or not _acceptable(ctx, base, combo, gap_thr_c):
            continue
        if best is None or combo.score > best.score:
            best = combo
    return best
