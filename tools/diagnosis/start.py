"""Stage 0 of the diagnosis: does each file start at rest, or while the gearbox was already running?

A file that starts running is scored from ``burn_in_s`` on (a rig thermocouple from ``burn_in_tc_s``:
:func:`scored_from`), and the housings' start is a second initial-state nuisance of that file, fitted with the uniform
one. ``Options.start`` (``auto``, ``rest`` or ``running``; the configuration's ``[diagnosis] start``) says which files
start running; ``auto`` decides per file on the residual the verdict leaves. Each file's start, with its reason and
evidence, is in the JSON (``starts``) and the report. docs/diagnosis.md, "Files that start while the gearbox runs", has
the why, the two tests of ``auto`` and what they were measured to do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from tools.diagnosis.context import Context
from tools.diagnosis.fit import lag1_rho
from tools.diagnosis.measurement import model_at_cells
from tools.diagnosis.models import Run
from tools.diagnosis.options import HOUSING_PERTURB_C, OIL, OIL_RIG, WARM_ABOVE_AMBIENT_K, Options
from tools.diagnosis.scoring import box_lsq

#: how a user asks for files that start running (the configuration's key; the command line's hidden option too)
RUNNING = '[diagnosis] start = "running" in the --config (or --start running)'


@dataclass(frozen=True)
class StartOf:
    """How one file starts."""

    name: str
    role: str
    start: str  # 'rest' or 'running'
    reason: str
    housing_offset_c: float | None  # the housings' offset fitted when the start was judged (None: not judged)
    evidence: float | None  # -dBIC of the housings' offset on the cells after the burn-in (None: not tested)
    hint: str | None = None  # a file kept at rest that looks cut from a drive (:func:`driving_at_start`),
    #                                  or one that --start running could not take running (why)
    cut_like: bool = False  # kept at rest while it begins driving and warm (:func:`driving_at_start`), and no
    #                           thermocouple shows its components at the oil (:func:`components_at_oil`)

    def to_json(self) -> dict:
        from tools.diagnosis.options import json_number

        return {
            "start": self.start,
            "reason": self.reason,
            "housing_offset_c": json_number(self.housing_offset_c, 2),
            "evidence": json_number(self.evidence, 1),
            "hint": self.hint,
        }


@dataclass(frozen=True)
class Starts:
    """The files as the diagnosis scores them (running files trimmed to their cells after the burn-in) and the
    per-file decisions."""

    train: list
    test: list
    records: tuple

    @property
    def running(self) -> tuple:
        return tuple(r.name for r in self.records if r.start == "running")


def scored_from(ds, cid: str, opts: Options) -> float:
    """When a running file's channel is scored from: the oil after ``burn_in_s``; a thermocouple after
    ``burn_in_tc_s`` (a component's start error dies slower than the oil's: the sun wheel's, with the housings
    right, 1.5-3 K RMS 300-600 s in and 0.1-0.2 K after 900 s), but never leaving it less than
    ``start_min_span_s``, nor before the oil's."""
    t_oil = ds.t_start_s + opts.burn_in_s
    if cid in (OIL, OIL_RIG):
        return t_oil
    return max(t_oil, min(ds.t_start_s + opts.burn_in_tc_s, ds.t_end_s - opts.start_min_span_s))


def trimmed(ds, opts: Options):
    """The running data set, each channel scored from :func:`scored_from` on (the model still runs from the file's
    start); a channel left with fewer than ``start_min_cells`` cells is dropped from this file, with a warning (None
    when no channel is left)."""
    chans, dropped = {}, []
    for cid, ch in ds.channels.items():
        t_cut_s = scored_from(ds, cid, opts)
        raw, cell = ch.t_s >= t_cut_s, ch.cell_t_s >= t_cut_s
        if int(np.sum(cell)) < opts.start_min_cells:
            dropped.append(cid)
            continue
        chans[cid] = replace(
            ch,
            t_s=ch.t_s[raw],
            y_c=ch.y_c[raw],
            cell_t_s=ch.cell_t_s[cell],
            cell_y_c=ch.cell_y_c[cell],
            cell_n=ch.cell_n[cell],
        )
    if not chans:
        return None
    warn = tuple(
        f"channel {c} has fewer than {opts.start_min_cells} valid cells after its burn-in (the file starts "
        f"running): left out of this file"
        for c in dropped
    )
    return replace(
        ds,
        channels=chans,
        start="running",
        scored_from_s=ds.t_start_s + opts.burn_in_s,
        warnings=tuple(ds.warnings) + warn,
    )


def _early_gap(ds, resid: list, sigma: dict, opts: Options) -> tuple | None:
    """(channel, systematic RMS, threshold) of the real gap the oil's residual shows in its first ``start_early_s``
    (the noise removed; a real gap as the verdict counts one: above max(gap_k sigma, gap_floor_c)), None when there is
    none. The oil only: an effect on a component shows on its thermocouple within minutes from rest too, while the
    oil, the heaviest mass, takes up an effect slowly but the components' stored heat at once."""
    best = None
    for (cid, ch), r in zip(ds.channels.items(), resid):
        if cid not in (OIL, OIL_RIG):
            continue
        early = ch.cell_t_s < ds.t_start_s + opts.start_early_s
        if not np.any(early):
            continue
        sig = sigma.get(cid, 0.1)
        sys_c = math.sqrt(max(float(np.mean(r[early] ** 2 - sig * sig / np.maximum(ch.cell_n[early], 1))), 0.0))
        thr = max(opts.gap_k * sig, opts.gap_floor_c)
        if sys_c > thr and (best is None or sys_c / thr > best[1] / best[2]):
            best = (cid, sys_c, thr)
    return best


def judge(ds, resid: list, sens: list, sens_h: list, w: list, sigma: dict, opts: Options) -> StartOf:
    """The start of one file from the residual a diagnosis left on it (per channel entry: residual, sensitivity to a
    uniform start, to the housings' start, weights; `sigma`: the noise per channel): running when the first minutes
    show a real gap (the components' unknown start) and, after them, the housings' start fits far better, unless
    its first reading lies within WARM_ABOVE_AMBIENT_K of the ambient (a gearbox that had not been running)."""
    span = ds.t_end_s - (ds.t_start_s + opts.burn_in_s)
    if span < opts.start_min_span_s:
        return StartOf(
            ds.name,
            ds.role,
            "rest",
            f"at rest: after the first {opts.burn_in_s:.0f} s the file keeps "
            f"{max(span, 0.0):.0f} s, too short to tell a running start (at least "
            f"{opts.start_min_span_s:.0f} s)",
            None,
            None,
        )
    early = _early_gap(ds, resid, sigma, opts)
    has_oil = any(c in (OIL, OIL_RIG) for c in ds.channels)
    fitted = _housings_fit(ds, resid, sens, sens_h, w, opts)
    if fitted is None:
        return StartOf(
            ds.name, ds.role, "rest", "at rest: no cell after the burn-in to judge a running start by", None, None
        )
    beta, ev = fitted
    house = f"the housings starting {abs(beta):.1f} K {'below' if beta < 0 else 'above'} the oil (evidence {ev:.0f})"
    cold_k = above_ambient_k(ds)
    if ev >= opts.evidence_min and early is not None and cold_k < WARM_ABOVE_AMBIENT_K:
        return StartOf(
            ds.name,
            ds.role,
            "rest",
            f"at rest: its first reading is {cold_k:.0f} K above the ambient (less than {WARM_ABOVE_AMBIENT_K:g} K), a "
            f"gearbox that had not been running; {house} would fit it better, as an effect that grows from rest "
            f"does too",
            beta,
            ev,
        )
    if ev >= opts.evidence_min and early is not None:
        return StartOf(
            ds.name,
            ds.role,
            "running",
            f"running: its first minutes do not fit a start at rest "
            f"({early[0]} {early[1]:.2f} > {early[2]:.2f} degC before the burn-in), and after them it is "
            f"fitted far better with {house} >= {opts.evidence_min:g}): the gearbox had been running "
            f"before the file began",
            beta,
            ev,
        )
    if ev >= opts.evidence_min and not has_oil:
        return StartOf(
            ds.name,
            ds.role,
            "rest",
            f"at rest: {house} would fit it better, but it has no oil channel to "
            f"judge its first minutes by; if it was cut from a drive, set {RUNNING}",
            beta,
            ev,
        )
    if ev >= opts.evidence_min:
        return StartOf(
            ds.name,
            ds.role,
            "rest",
            f"at rest: {house} would fit it better, but its first minutes fit a "
            f"start at rest (no real gap before the burn-in); if it begins after a short stop, try "
            f"{RUNNING}",
            beta,
            ev,
        )
    return StartOf(
        ds.name, ds.role, "rest", f"at rest: {house} < {opts.evidence_min:g}) does not fit it better", beta, ev
    )


def _housings_fit(ds, resid: list, sens: list, sens_h: list, w: list, opts: Options) -> tuple | None:
    """(the housings' start from the sump [K], its evidence -dBIC) on the cells after each channel's burn-in: the
    uniform start alone against the uniform start and the housings' (both bounded); None without such cells."""
    rs, su, sh, ws = [], [], [], []
    for (cid, ch), r, s_u, s_h, wk in zip(ds.channels.items(), resid, sens, sens_h, w):
        keep = ch.cell_t_s >= scored_from(ds, cid, opts)
        if np.any(keep):
            rs.append(r[keep])
            su.append(s_u[keep])
            sh.append(s_h[keep])
            ws.append(np.broadcast_to(wk, r.shape)[keep])
    if not rs:
        return None
    r, wt = np.concatenate(rs), np.concatenate(ws)
    d = opts.initial_offset_max_c
    _, S_rest = box_lsq(r, wt, np.concatenate(su)[:, None], np.array([-d]), np.array([d]))
    A = np.stack([np.concatenate(su), np.concatenate(sh)], axis=1)
    x2, S_run = box_lsq(r, wt, A, np.array([-d, opts.housing_offset_lo_c]), np.array([d, opts.housing_offset_hi_c]))
    n_eff = _n_eff(rs)
    ev = n_eff * math.log(max(S_rest, 1e-12) / max(S_run, 1e-12)) - math.log(max(n_eff, 2.0))
    return float(x2[1]), ev


def _n_eff(resid: list) -> float:
    """The effective sample size of residual pieces (each shrunk by its autocorrelation, as the criterion counts)."""
    rhos = [lag1_rho(r) for r in resid]
    return max(sum(r.size * (1 - q) / (1 + q) for r, q in zip(resid, rhos)), 2.0)


def above_ambient_k(ds) -> float:
    """How far the file's first reading (the model's start) lies above the ambient's first valid value [K]; NaN
    without an ambient column."""
    tb = getattr(ds, "inputs", None)
    if tb is None or not tb.has("ambient_temp_c"):
        return math.nan
    v = np.asarray(tb["ambient_temp_c"], dtype=float)
    ok = np.isfinite(v)
    return float(ds.initial_temp_c - v[ok][0]) if ok.any() else math.nan


def driving_at_start(ds) -> str | None:
    """A phrase when the file begins with the truck driving and the gearbox warm (a vehicle speed above 10 km/h, or
    more than 500 Nm at more than 600 rpm, and the oil's first reading 15 K or more above the ambient): what a file
    cut from a longer drive looks like; a log from key-on begins standing. None otherwise."""
    tb = ds.inputs

    def first(col):
        if not tb.has(col):
            return math.nan
        v = np.asarray(tb[col], dtype=float)
        ok = np.isfinite(v)
        return float(v[ok][0]) if ok.any() else math.nan

    v, tq, rpm = (first(c) for c in ("vehicle_speed_kmh", "engine_torque_nm", "engine_speed_rpm"))
    warm = above_ambient_k(ds)
    driving = v > 10.0 or (abs(tq) > 500.0 and rpm > 600.0)
    if not (driving and warm >= WARM_ABOVE_AMBIENT_K):
        return None
    what = f"{v:.0f} km/h" if math.isfinite(v) and v > 10.0 else f"{tq:.0f} Nm at {rpm:.0f} rpm"
    return f"it begins with the truck driving ({what}) and the oil {warm:.0f} K above the ambient"


def decide_starts(opts: Options, train: list, test: list, records: tuple = ()) -> Starts:
    """The data sets as scored: every file at rest, or running as ``opts.start`` forces or as the `records` of the
    after-verdict test say (one per file, in the order train then test: names need not be unique)."""
    recs, new = [], {"train": [], "test": []}
    known = iter(records)
    for role, dss in (("train", train), ("test", test)):
        for ds in dss:
            rec = next(known, None)
            if opts.start == "running":
                rec = StartOf(ds.name, role, "running", "running, as asked (--start running)", None, None)
            elif rec is None:
                rec = StartOf(
                    ds.name,
                    role,
                    "rest",
                    "at rest, as asked (--start rest)" if opts.start == "rest" else "at rest",
                    None,
                    None,
                )
            if rec.start == "running" and ds.t_end_s - (ds.t_start_s + opts.burn_in_s) < opts.start_min_span_s:
                rec = StartOf(
                    ds.name,
                    role,
                    "rest",
                    f"scored at rest: after its first {opts.burn_in_s:.0f} s the "
                    f"file keeps less than {opts.start_min_span_s:.0f} s",
                    None,
                    None,
                )
            cut = trimmed(ds, opts) if rec.start == "running" else None
            if rec.start == "running" and cut is None:
                rec = StartOf(
                    ds.name,
                    role,
                    "rest",
                    f"scored at rest: no channel keeps {opts.start_min_cells} cells after its burn-in",
                    None,
                    None,
                )
            hint = driving_at_start(ds) if opts.start == "auto" and rec.start == "rest" else None
            if hint:
                rec = replace(
                    rec,
                    hint=f"{hint}: if it was cut from a longer drive or logged after a short stop, "
                    f"diagnose with {RUNNING} (a running start scored at rest shows a false gap)",
                    cut_like=not components_at_oil(ds),
                )
            elif opts.start == "running" and rec.start == "rest":  # asked for, not possible: say so
                rec = replace(rec, hint=f"--start running was asked, but it is {rec.reason}")
            recs.append(rec)
            new[role].append(cut if cut is not None else ds)
    return Starts(new["train"], new["test"], tuple(recs))


def components_at_oil(ds, tol_k: float = 3.0) -> bool:
    """Whether the file's rig thermocouples show a uniform start: it has one, and every one's first reading lies
    within `tol_k` of the model's start (the components of a gearbox cut from a drive run kelvins off the oil: the
    sun wheel 15 K above it 40 minutes into a drive). An oil sensor alone cannot show it."""
    firsts = [
        float(ch.y_c[np.isfinite(ch.y_c)][0])
        for cid, ch in ds.channels.items()
        if cid not in (OIL, OIL_RIG) and np.isfinite(ch.y_c).any()
    ]
    return bool(firsts) and all(abs(f - ds.initial_temp_c) <= tol_k for f in firsts)


def start_caveat(records: tuple) -> str | None:
    """The sentence a verdict other than "none" carries when files that begin driving and warm were scored at rest
    (their channels showed no running start, e.g. the oil alone, or a false effect of the first pass took their
    start error up): the model started them uniform at their first reading, which a file cut from a drive is not,
    so the gap the verdict explains may be their start's. None when there is no such file."""
    names = [r.name for r in records if r.start == "rest" and r.cut_like]
    if not names:
        return None
    many = len(names) > 1
    return (
        f"{', '.join(names)} {'begin' if many else 'begins'} with the truck driving and the gearbox warm, but "
        f"{'their' if many else 'its'} start could not be set from {'their' if many else 'its'} channels and "
        f"{'they were' if many else 'it was'} scored at rest: the gap this verdict explains may be "
        f"{'their' if many else 'its'} unknown start rather than the gearbox; if cut from a longer drive, "
        f"diagnose with {RUNNING}."
    )


def starts_json(records: tuple) -> dict:
    """The JSON's ``starts``: per file name (``role:name`` where two files share a name)."""
    names = [r.name for r in records]
    return {
        (f"{r.role}:{r.name}" if names.count(r.name) > 1 else r.name): dict(r.to_json(), role=r.role) for r in records
    }


def starts_after_verdict(ctx: Context, base, res, which: str = "after") -> tuple:
    """Every file's start judged on a residual of a diagnosis at rest (:func:`judge`): the unmodified model's
    (``before``) or the verdict's (``after``; core passes that of an effect the held-out check refused, since a
    held-out file that starts running refuses the right effect, and on the unmodified model's residual that effect
    looks like a running start of the files from rest); the housings' start re-simulated once per file (one run)."""
    out = []
    for role, rd, resid in (
        ("train", base.train, getattr(res, f"train_{which}")),
        ("test", base.test, getattr(res, f"test_{which}")),
    ):
        house = ctx.sim.run(rd.datasets, [Run.of(housing_offset_c=HOUSING_PERTURB_C)])[0]
        base_outs = base.base_tr if role == "train" else base.base_te
        k = 0
        for ds, b_out, h_out in zip(rd.datasets, base_outs, house):
            n = len(ds.channels)
            idx = list(range(k, k + n))
            k += n
            sens_h = [
                (
                    model_at_cells(h_out, ch, base.lag0.get(cid, 0.0))
                    - model_at_cells(b_out, ch, base.lag0.get(cid, 0.0))
                )
                / HOUSING_PERTURB_C
                for cid, ch in ds.channels.items()
            ]
            out.append(
                judge(
                    ds,
                    [resid[i] for i in idx],
                    [rd.sens[i] for i in idx],
                    sens_h,
                    [rd.w[i] for i in idx],
                    base.sigma,
                    ctx.opts,
                )
            )
    return tuple(out)
