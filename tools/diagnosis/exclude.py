"""Stage 4c of the diagnosis: what the data cannot rule out beside the verdict.

For every other catalog effect, over which values it **cannot be excluded** beside the verdict: a profile-likelihood
interval. The effect is held at tenths of the way from neutral to each bound, the verdict's members refitted on the
surrogates of :mod:`.combine`, and a value excluded only when ``-dBIC = n_eff ln(S(y) / S_best) - ln n_eff`` exceeds
``evidence_min``; an effect whose interval leaves out neutral is *indicated*. This changes no verdict. It is reported
as ``verdict.not_excluded`` and in the reason. docs/diagnosis.md, "What the data cannot rule out beside the
verdict", has the why of each rule and what it was measured to do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from firmware_model.effects import CATALOG, fraction_of_range
from tools.diagnosis.baseline import Baseline
from tools.diagnosis.combine import SetState, at_start, delta_fn, eligible, simulate_sets, surrogate_misfit
from tools.diagnosis.context import Context
from tools.diagnosis.fit import Criterion
from tools.diagnosis.options import ANALYTIC

#: fractions of the way from neutral to a bound that are tried
FRACTIONS = tuple(k / 10 for k in range(1, 11))
#: re-simulations tried per side before a side's interval is given up
CONFIRM_TRIES = 3


@dataclass(frozen=True)
class NotExcluded:
    """No strong evidence against effect `effect` anywhere in [low, high] beside the verdict (its members refitted);
    frac_low/frac_high: how far that reaches towards each bound (0..1)."""

    effect: str
    low: float
    high: float
    frac_low: float
    frac_high: float
    best: float  # the value that fits best beside the verdict
    indicated: bool  # neutral lies outside the interval: the data point to the effect (not claimed)
    evidence: float = 0.0  # -dBIC of adding it at `best` (n_eff ln(S_verdict / S_best) - ln n_eff)

    @property
    def reach(self) -> float:
        return max(self.frac_low, self.frac_high)

    def covers(self, value: float) -> bool:
        return self.low - 1e-12 <= value <= self.high + 1e-12


class _Profile:
    """S(members with Y held) on the surrogates around the verdict's own run (combine.surrogate_misfit), the members
    refitted. Each effect's change is kept for its last few values: the held effect's value is asked at every
    evaluation of a refit."""

    def __init__(self, base: Baseline, st: SetState, deltas: dict):
        from functools import lru_cache

        cached = {e: (lru_cache(maxsize=8)(fn) if fn is not None else None) for e, fn in deltas.items()}
        self._S_of = surrogate_misfit(base, st, cached)

    def S(self, members: dict) -> float:
        S = self._S_of(members)
        return S if math.isfinite(S) else math.inf  # a run that went bad is refused, never the best

    def refit(self, members: dict, held: str, passes: int = 2) -> tuple:
        """(members, S) with `held` fixed and every other member moved by bounded 1-D searches."""
        from scipy.optimize import minimize_scalar

        members = dict(members)
        S = self.S(members)
        for _ in range(passes):
            moved = False
            for m in [e for e in members if e != held]:
                e = CATALOG[m]
                r = minimize_scalar(
                    lambda x: self.S({**members, m: float(x)}),  # noqa: B023 (minimised in this iteration)
                    bounds=(e.low, e.high),
                    method="bounded",
                    options={"xatol": 1e-3 * (e.high - e.low)},
                )
                if r.fun < S - 1e-12 * max(S, 1.0):
                    members, S, moved = {**members, m: float(r.x)}, float(r.fun), True
            if not moved:
                break
        return members, S


def not_excluded(
    ctx: Context, base: Baseline, crit: Criterion, fits: list, members: dict, out: list, skip=(), start: tuple = ()
) -> list:
    """[NotExcluded] beside the verdict's effects `members` (effect -> value) whose training run is `out`, most
    reaching first; effects in `skip` (not identifiable with the channels) are left out."""
    o = ctx.opts
    by_id = {f.effect: f for f in fits}
    deltas = {eid: (None if eid in ANALYTIC else delta_fn(base, f)) for eid, f in by_id.items()}
    if any(m not in ANALYTIC and deltas.get(m) is None for m in members):
        return []  # a member without a grid cannot be moved on the surrogates
    # a single offset or gain verdict from the sump its reading implies, as every re-simulation below starts
    st = at_start(ctx, base, SetState(base, members, out, start))
    prof = _Profile(base, st, deltas)
    n_eff = max(crit.n_eff, 2.0)
    found = []
    for eid in eligible(ctx, st, by_id, deltas):
        if eid in skip:
            continue
        factor = _factor(ctx, n_eff)
        pts = (
            _walk(prof, st, eid, -1, factor)[::-1]
            + [(CATALOG[eid].neutral, dict(st.members), st.S)]
            + _walk(prof, st, eid, 1, factor)
        )
        if not _material(eid, pts, min(p[2] for p in pts) * _factor(ctx, n_eff), o):
            continue
        ne = _profile_interval(ctx, base, st, prof, eid, pts, n_eff)
        if ne is not None and ne.reach >= o.not_excluded_min_frac:
            found.append(ne)
    found.sort(key=lambda n: (-n.reach, n.effect))
    return found


#: a side's walk stops after this many successive values that are refused by a wide margin and rising
STOP_AFTER = 2
#: the wide margin: the misfit above the best so far times the exclusion factor times this
STOP_MARGIN = 1.05


def _walk(prof: _Profile, st: SetState, eid: str, side: int, factor: float) -> list:
    """[(y, members, S)] with `eid` held at tenths of the way from neutral to the bound on `side` (outwards), the
    members refitted from the previous value's. The walk stops early once STOP_AFTER successive values are refused
    with a margin (misfit above STOP_MARGIN x factor x the best so far) and rising: the profile has turned away (a
    strongly excluded effect costs two refits per side, not ten)."""
    e = CATALOG[eid]
    bound = e.high if side > 0 else e.low
    if bound == e.neutral:
        return []
    pts, members, best, prev, rising = [], dict(st.members), st.S, st.S, 0
    for f in FRACTIONS:
        y = bound if f == 1.0 else e.neutral + f * (bound - e.neutral)
        members, S = prof.refit({**members, eid: y}, eid)
        pts.append((y, dict(members), S))
        best = min(best, S)
        rising = rising + 1 if (S > STOP_MARGIN * factor * best and S > prev) else 0
        prev = S
        if rising >= STOP_AFTER:
            break
    return pts


def _factor(ctx: Context, n_eff: float) -> float:
    """A value is excluded when its misfit exceeds the best one by this factor: evidence against it counted as a
    verdict counts evidence for an effect, -dBIC = n_eff ln(S / S_best) - ln n_eff >= evidence_min."""
    return math.exp((ctx.opts.evidence_min + math.log(n_eff)) / n_eff)


def _material(eid: str, pts: list, thr: float, o) -> bool:
    """Does any value passing `thr` on the surrogates reach not_excluded_min_frac of the way to a bound?"""
    return any(S <= thr and abs(fraction_of_range(eid, y)) >= o.not_excluded_min_frac for y, _m, S in pts)


def _profile_interval(ctx: Context, base: Baseline, st: SetState, prof, eid: str, pts: list, n_eff: float):
    """The profile interval of `eid` from the walked points `pts` (ascending values, neutral among them): the
    surrogate's best value re-simulated (when it is not neutral) to set the reference misfit, the values around it
    that pass, each end refined by bisection and confirmed by re-simulation (inwards, CONFIRM_TRIES at most, else the
    best
    value)."""
    factor = _factor(ctx, n_eff)
    i_n = next(i for i, p in enumerate(pts) if p[0] == CATALOG[eid].neutral)
    i_best = min(range(len(pts)), key=lambda i: (pts[i][2], i != i_n))  # ties: neutral
    S_best, bias = st.S, 0.0
    if i_best != i_n:
        S_sim = _simulated_S(ctx, base, st, pts[i_best][1])
        if S_sim <= min(st.S, pts[i_best][2] * factor):
            # the surrogates' misfit near the best value is off the simulated one by `bias`: judged with it
            S_best, bias = S_sim, pts[i_best][2] - S_sim
        else:
            i_best = i_n  # the surrogate's better fit does not hold when simulated
    thr = S_best * factor
    thr_sur = thr + bias
    pts = list(pts)
    pts[i_n] = (pts[i_n][0], pts[i_n][1], st.S + bias)  # neutral is exact: on the surrogates' scale here
    a = b = i_best
    while a > 0 and pts[a - 1][2] <= thr_sur:
        a -= 1
    while b < len(pts) - 1 and pts[b + 1][2] <= thr_sur:
        b += 1
    lo = _confirm_end(
        ctx,
        base,
        st,
        prof,
        eid,
        (_bisect(prof, eid, pts[a - 1], pts[a], thr_sur) if a > 0 else []) + [pts[i] for i in range(a, i_best)],
        pts[i_best],
        thr,
    )
    hi = _confirm_end(
        ctx,
        base,
        st,
        prof,
        eid,
        (_bisect(prof, eid, pts[b + 1], pts[b], thr_sur) if b < len(pts) - 1 else [])
        + [pts[i] for i in range(b, i_best, -1)],
        pts[i_best],
        thr,
    )
    best = pts[i_best][0]
    ylo = lo if lo is not None else best
    yhi = hi if hi is not None else best
    evidence = n_eff * math.log(max(st.S, 1e-12) / max(S_best, 1e-12)) - math.log(n_eff)
    return NotExcluded(
        eid,
        float(ylo),
        float(yhi),
        _frac_toward(eid, ylo, -1),
        _frac_toward(eid, yhi, 1),
        float(best),
        not (ylo <= CATALOG[eid].neutral <= yhi),
        float(evidence),
    )


#: bisections of an interval's end between the last value passed and the first refused
BISECTIONS = 4


def _bisect(prof, eid: str, out_pt: tuple, in_pt: tuple, thr: float) -> list:
    """[the end of the interval] between a refused value and a passed one, by bisection on the surrogates; [] when
    no value between them passes (the passed one is the end)."""
    y_out, y_in, pt = out_pt[0], in_pt[0], None
    for _ in range(BISECTIONS):
        y = 0.5 * (y_out + y_in)
        members, S = prof.refit({**(pt or in_pt)[1], eid: y}, eid)
        if S <= thr:
            y_in, pt = y, (y, members, S)
        else:
            y_out = y
    return [pt] if pt is not None else []


def _frac_toward(eid: str, y: float, side: int) -> float:
    """How far y reaches towards the bound on `side` (0 when it sits on the other side of neutral)."""
    f = fraction_of_range(eid, y)
    e = CATALOG[eid]
    on_side = (y - e.neutral) * side > 0
    return abs(f) if on_side else 0.0


def _simulated_S(ctx: Context, base: Baseline, st: SetState, members: dict) -> float:
    return simulate_sets(ctx, base, [members], st)[0].S


def _confirm_end(ctx: Context, base: Baseline, st: SetState, prof, eid: str, cands: list, best: tuple, thr: float):
    """The value of the first of `cands` (from the outermost inwards) whose re-simulated misfit passes `thr`. When
    CONFIRM_TRIES of them are refused, the end is bisected by re-simulation between the best value and the innermost
    value refused (BISECTIONS steps); None when nothing beyond the best value holds."""
    refused = None
    for y, members, _S in cands[:CONFIRM_TRIES]:
        if (st.S if members == st.members else _simulated_S(ctx, base, st, members)) <= thr:
            return y
        refused = y
    if refused is None:
        return None
    y_in, y_out, found = best[0], refused, None
    for _ in range(BISECTIONS):
        y = 0.5 * (y_in + y_out)
        members, _S = prof.refit({**best[1], eid: y}, eid)
        if _simulated_S(ctx, base, st, members) <= thr:
            y_in, found = y, y
        else:
            y_out = y
    return found


def not_excluded_json(items: list) -> list:
    from tools.diagnosis.options import json_number as _r

    return [
        {
            "effect": n.effect,
            "parameter": CATALOG[n.effect].param,
            "range": [_r(n.low, 6), _r(n.high, 6)],
            "best": _r(n.best, 6),
            "indicated": bool(n.indicated),
            "evidence": _r(n.evidence, 2),
            "reach_low": _r(n.frac_low, 3),
            "reach_high": _r(n.frac_high, 3),
        }
        for n in items
    ]
