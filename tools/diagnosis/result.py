"""The gap-diagnosis JSON (schema gap-diagnosis/1) of a finished diagnosis, and what its report plots."""

from __future__ import annotations

from dataclasses import dataclass

from firmware_model.effects import CATALOG
from tools.diagnosis.baseline import Baseline
from tools.diagnosis.context import Context
from tools.diagnosis.decide import Residuals, Verdict, max_abs, pooled_rms
from tools.diagnosis.fit import Criterion
from tools.diagnosis.heat import UnexplainedHeat
from tools.diagnosis.options import OIL, SCHEMA
from tools.diagnosis.options import json_number as _r
from tools.diagnosis.regimes import Where


@dataclass(frozen=True)
class Outcome:
    """Everything a diagnosis found, stage by stage."""

    base: Baseline
    where: Where
    heat: UnexplainedHeat
    crit: Criterion
    ident: dict  # effect -> identify.Identifiability
    verdict: Verdict
    confusable: dict  # effect -> effects it is confusable with
    suggestions: list  # the JSON's measurement_suggestions
    residuals: Residuals
    test_regimes: list  # the JSON's test_regimes
    structure: dict  # channel -> the baseline residual's regime structure (regimes.residual_structure)
    combination: object = None  # the effects found together (combine.Combination), None for one effect
    not_excluded: tuple = ()  # exclude.NotExcluded: effects the data cannot rule out beside the verdict
    # the residuals a file's start is judged on (start.starts_after_verdict): the verdict's, or those of the effect
    # the held-out check refused (a held-out file that starts running, scored at rest, refuses the right effect)
    start_residuals: Residuals | None = None


@dataclass(frozen=True)
class PlotData:
    """What the Markdown report plots: per role the files, measured cells, the model before and after the verdict
    (None for 'none' and 'unexplained'), and the oil's unexplained heat flow."""

    train: list
    test: list
    obs_tr: list
    obs_te: list
    p0_tr: list
    p0_te: list
    after_tr: list | None
    after_te: list | None
    heat_series: list  # heat.HeatSeries


def plot_data(out: Outcome) -> PlotData:
    b, top = out.base, out.crit.candidates[0]
    effect = out.verdict.effect in CATALOG
    return PlotData(
        b.train.datasets,
        b.test.datasets,
        b.train.obs,
        b.test.obs,
        b.p0_tr,
        b.p0_te,
        top.fit.preds_train if effect else None,
        top.p_te if effect else None,
        out.heat.series,
    )


def _channels_json(out: Outcome) -> dict:
    b, v, res = out.base, out.verdict, out.residuals
    train, test = b.train.datasets, b.test.datasets
    chan_ids = sorted({c for ds in train + test for c in ds.channels}, key=lambda c: (c != OIL, c))
    pairs_tr = [cid for ds in train for cid in ds.channels]
    pairs_te = [cid for ds in test for cid in ds.channels]
    channels = {}
    for cid in chan_ids:

        def sel(rs, pairs):
            return [r for r, c in zip(rs, pairs) if c == cid]  # noqa: B023 (called in this iteration)

        a, bb = sel(res.train_before, pairs_tr), sel(res.test_before, pairs_te)
        c_, d = sel(res.train_after, pairs_tr), sel(res.test_after, pairs_te)
        channels[cid] = {
            "train_rms_c": _r(pooled_rms(a)),
            "train_max_c": _r(max_abs(a)),
            "test_rms_c": _r(pooled_rms(bb)),
            "test_max_c": _r(max_abs(bb)),
            "train_rms_after_c": _r(pooled_rms(c_)),
            "test_rms_after_c": _r(pooled_rms(d)),
            "test_max_after_c": _r(max_abs(d)),
            "noise_c": _r(b.sigma.get(cid, float("nan"))),
            "model_error_c": _r(b.floor.get(cid, float("nan"))),
            "systematic_train_c": _r(v.systematic.rms_c.get(cid, float("nan"))),
            "none_threshold_c": _r(v.systematic.none_thr_c.get(cid, float("nan"))),
            "gap_threshold_c": _r(v.gap_thr_c.get(cid, float("nan"))),
            "sensor_lag_s": _r(b.lag0.get(cid, 0.0)),
            "column": "oil_temp_c" if cid == OIL else f"meas_T_{cid}_c",
        }
    return channels


def _candidates_json(ctx: Context, out: Outcome) -> list:
    b, res = out.base, out.residuals
    rms_tr0, rms_te0 = _r(pooled_rms(res.train_before)), _r(res.test_rms_before_c)
    cand_json = []
    for c in out.crit.candidates:
        f = c.fit
        e = CATALOG[f.effect]
        res_e_te = [y - p for y, p in zip(b.test.obs, c.p_te)]
        res_e_tr = [y - p for y, p in zip(b.train.obs, f.preds_train)]
        cand_json.append(
            {
                "effect": f.effect,
                "parameters": {e.param: _r(f.value, 6)},
                "train_rms_before_c": rms_tr0,
                "train_rms_after_c": _r(pooled_rms(res_e_tr)),
                "test_rms_before_c": rms_te0,
                "test_rms_after_c": _r(pooled_rms(res_e_te)),
                "score": _r(c.score, 3),
                "confusable_with": list(out.confusable[f.effect]),
                "explained_share": _r(min(max(c.explained, -1.0), 1.0), 4),
                "at_bound": bool(f.at_bound),
                "unit": e.unit,
                "range": [e.low, e.high],
                "identifiable": out.ident[f.effect].identifiable,
                "backend": ctx.backend_of(f.effect),
            }
        )
    return cand_json


def _verdict_json(out: Outcome, cand_json: list) -> dict:
    v, res = out.verdict, out.residuals
    js = {
        "effect": v.effect,
        "test_rms_before_c": _r(res.test_rms_before_c),
        "test_rms_after_c": _r(res.test_rms_after_c),
        "shrink": _r(res.shrink, 4),
        "reason": v.reason,
        "test_max_before_c": _r(max_abs(res.test_before)),
        "test_max_after_c": _r(max_abs(res.test_after)),
    }
    if v.is_effect:
        js.update(
            {
                "parameters": cand_json[0]["parameters"],
                "confusable_with": list(out.confusable[v.effect]),
                "remaining_gap_c": {c: _r(x) for c, x in v.remaining_gap_c().items()},
            }
        )
    if v.effect == "unexplained":
        js["closest_candidate"] = cand_json[0]["effect"]
    if v.thin is not None:
        js.update(_thin_json(v.thin, cand_json[0]))
    if out.combination is not None:
        js.update(_effects_json(out))
    if v.is_effect:
        from tools.diagnosis.exclude import not_excluded_json

        js["not_excluded"] = not_excluded_json(out.not_excluded)
    js["residual_structure"] = out.structure
    return js


def _thin_json(th, best: dict) -> dict:
    """verdict.evidence "thin" and verdict.thin_evidence (only when too few effective samples to decide)."""
    return {
        "evidence": "thin",
        "thin_evidence": {
            "n_eff": _r(th.n_eff, 2),
            "n_eff_needed": th.needed,
            "n": int(th.n),
            "train_s": _r(th.train_s, 1),
            "best_candidate": best["effect"],
            "parameters": best["parameters"],
            "score": best["score"],
            "explained_share": best["explained_share"],
            "test_rms_before_c": _r(th.test_rms_before_c),
            "test_rms_after_c": _r(th.test_rms_after_c),
            "text": f"thin evidence (n_eff = {th.n_eff:.0f}, at least {th.needed} needed to decide): "
            f"{th.what_it_would_cut()}; {th.advice()}",
        },
    }


def _effects_json(out: Outcome) -> dict:
    """verdict.effects (each member with its share of the explained residual and its confusable alternatives) and
    the set's score; ``parameters`` become the leading effect's value in the set."""
    cb = out.combination
    steps = {s.effect: s for s in cb.steps}
    lead = next(iter(cb.members))
    effects = []
    for eid, x in cb.members.items():
        e = CATALOG[eid]
        item = {"effect": eid, "parameters": {e.param: _r(x, 6)}, "share": _r(cb.shares[eid], 4)}
        if eid in steps:
            item.update(
                {
                    "score_added": _r(steps[eid].score, 3),
                    "explained_added": _r(steps[eid].explained, 4),
                    "confusable_with": list(steps[eid].alternatives),
                }
            )
        else:
            item["confusable_with"] = list(out.confusable[eid])
        effects.append(item)
    return {
        "effects": effects,
        "parameters": {CATALOG[lead].param: _r(cb.members[lead], 6)},
        "effects_score": _r(cb.score, 3),
        "effects_explained_share": _r(min(max(cb.explained, -1.0), 1.0), 4),
    }


def _criterion_json(ctx: Context, out: Outcome) -> dict:
    cr, o = out.crit, ctx.opts
    return {
        "name": "BIC with effective sample size",
        "n": int(cr.n),
        "n_eff": _r(cr.n_eff, 2),
        "rho_lag1": {k: _r(v, 4) for k, v in cr.rho.items()},
        "grid_dt_s": o.grid_dt_s,
        "S_baseline": _r(out.base.S0, 3),
        "S_expected_noise_and_model_error": _r(out.base.S_noise, 3),
        "evidence_min": o.evidence_min,
        "explain_min": o.explain_min,
        "score": "score = -dBIC = -(n_eff ln(S_effect/S_baseline) + k ln n_eff), k = 1",
    }


def build_json(ctx: Context, out: Outcome, total_s: float) -> dict:
    """The gap-diagnosis JSON; `total_s`: the diagnosis's wall time."""
    train, test = out.base.train.datasets, out.base.test.datasets
    cand_json = _candidates_json(ctx, out)
    return {
        "schema": SCHEMA,
        "train": [ds.name for ds in train],
        "test": [ds.name for ds in test],
        "channels": _channels_json(out),
        "where": out.where.where,
        "candidates": cand_json,
        "verdict": _verdict_json(out, cand_json),
        "where_by": out.where.where_by,
        "episodes": out.where.episodes,
        "test_regimes": out.test_regimes,
        "unexplained_heat": out.heat.json,
        "identifiability": {eid: x.to_json() for eid, x in out.ident.items()},
        "measurement_suggestions": out.suggestions,
        "criterion": _criterion_json(ctx, out),
        "model": ctx.model.describe(),
        "cooler": ctx.cooler,
        "warnings": [f"{ds.name}: {w}" for ds in train + test for w in ds.warnings],
        "timing": {"total_s": _r(total_s, 2), "simulate_s": _r(ctx.sim.simulate_s, 2), "simulations": ctx.sim.n_sims},
    }
