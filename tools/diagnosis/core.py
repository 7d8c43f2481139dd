"""Sim-to-real gap diagnosis: where the model misses, which unmodelled effect explains it, how far it shrinks.

Input: measured run tables (tools/runtable.py) or CAN logs with the oil sensor ``oil_temp_c`` and/or rig
thermocouples ``meas_T_<id>_c``, split into TRAINING and TEST files. Output: the gap-diagnosis JSON (schema
``gap-diagnosis/1``), see :func:`diagnose`. The method and the reasons behind each choice are in docs/diagnosis.md;
the stages, each in its own module, pass typed records:

1. **Prepare** (:mod:`.prepare`): load, validate, put each channel on the analysis grid (`grid_dt_s`, default 2 s).
2. **Start** (:mod:`.start`): whether each file starts at rest or while the gearbox was running (cut from a longer
   drive, a warm restart); a running file is scored after its first 300 s, with its housings' start fitted.
   **Baseline** (:mod:`.baseline`, :mod:`.measurement`, :mod:`.scoring`): the model predicts the node temperature,
   with three nuisances that are state or sensor, never an effect: a first-order sensor lag of 0..10 s per channel,
   the initial temperature of every file (+-0.25 K around the first reading, least squares on its sensitivity), and
   the model's own numerical error (the plant re-simulated with half the step), which floors the weights and the
   thresholds. Noise per sample comes from the high-frequency content of the residual, floored at the J1939
   quantisation.
3. **Where** (:mod:`.regimes`, :mod:`.heat`): residual = measured - model, its square apportioned to operating regimes
   and episodes; for the oil it is inverted into the unexplained heat flow ``Q = C_eff d(r)/dt + G_eff r``.
4. **Which** (:mod:`.fit`, :mod:`.identify`): every catalog effect fitted on the training files (grid, surrogate,
   re-simulated check) and ranked by ``score = -dBIC`` with an effective sample size; identifiability per channel.
5. **Verdict and shrink** (:mod:`.decide`): "none", the best candidate, or "unexplained"; confusable candidates and
   the measurement that separates them; RMS and max residual before/after on the TEST files only.
6. **Result** (:mod:`.result`): the JSON; the Markdown report is :mod:`.report`.
"""

from __future__ import annotations

import time
from dataclasses import replace

from firmware_model.effects import EFFECT_IDS, channel_effect
from firmware_model.errors import InputError
from tools.diagnosis.baseline import establish_baseline
from tools.diagnosis.combine import rescue, select_set
from tools.diagnosis.context import Context, Simulator
from tools.diagnosis.decide import (
    confusable_with,
    decide,
    held_out_check,
    residuals,
    suggestions,
    with_combination,
    with_not_excluded,
    with_structure,
)
from tools.diagnosis.exclude import not_excluded
from tools.diagnosis.fit import fit_all, grid_plan, rank, simulate_test_files
from tools.diagnosis.heat import unexplained_heat
from tools.diagnosis.identify import identifiability
from tools.diagnosis.measurement import lag_filter
from tools.diagnosis.options import OIL, STAGES, Options
from tools.diagnosis.prepare import load_table, prepare, prepare_runs
from tools.diagnosis.regimes import regimes_before_after, residual_structure, where_residual
from tools.diagnosis.result import Outcome, PlotData, build_json, plot_data
from tools.diagnosis.start import decide_starts, start_caveat, starts_after_verdict, starts_json

__all__ = ["Diagnosis", "Options", "diagnose", "lag_filter", "load_table", "make_model", "prepare"]


def default_candidates(train: list, params=None) -> tuple:
    """Every catalog effect that can act on ``params``' gearbox (oil_level_low only on the GRS905 family's sump:
    firmware_model.effects.oil_level_refusal), and an offset of every rig thermocouple the training files
    measure."""
    from firmware_model.effects import oil_level_refusal

    tcs = sorted({c for ds in train for c in ds.channels if c != OIL})
    effects = tuple(e for e in EFFECT_IDS if e != "oil_level_low" or params is None or not oil_level_refusal(params))
    return effects + tuple(channel_effect("thermocouple_offset", c) for c in tcs)


class Diagnosis:
    """One diagnosis run of prepared training and test files. `run()` returns the JSON-ready dict; afterwards
    `outcome` holds every stage's records and `plot_data` what the report plots."""

    def __init__(
        self,
        train,
        test,
        model,
        params,
        opts: Options | None = None,
        cooler: str | None = None,
        progress=None,
        candidates=None,
    ):
        self.train, self.test = train, test
        opts = opts or Options()
        cooler = cooler or params.strings.get("cooler.kind", "liquid")
        self.ctx = Context(
            model, params, opts, cooler, tuple(candidates or default_candidates(train, params)), Simulator(model)
        )
        self.progress = progress or (lambda msg: None)
        self.outcome: Outcome | None = None
        self.plot_data: PlotData | None = None
        self.starts = None

    @property
    def n_sims(self) -> int:
        return self.ctx.sim.n_sims

    def run(self) -> dict:
        """Diagnose (and, with ``Options.start`` auto, again when files turn out to have started running:
        :mod:`.start`); the JSON-ready dict."""
        wall0_s = time.perf_counter()
        ctx = self.ctx
        self.starts = decide_starts(ctx.opts, self.train, self.test)
        self._run_once(self.starts)
        if ctx.opts.start == "auto":
            recs = starts_after_verdict(ctx, self.outcome.base, self.outcome.start_residuals)
            self.starts = decide_starts(ctx.opts, self.train, self.test, recs)
            if self.starts.running:  # every stage again (the progress callback is told so)
                self._run_once(self.starts)
        caveat = start_caveat(self.starts.records)
        if caveat and self.outcome.verdict.effect != "none":  # said in the verdict, not only in the warnings
            v = self.outcome.verdict
            sep = " " if v.reason.rstrip().endswith(".") else ". "
            self.outcome = replace(self.outcome, verdict=replace(v, reason=v.reason.rstrip() + sep + caveat))
        self.plot_data = plot_data(self.outcome)
        res = build_json(ctx, self.outcome, time.perf_counter() - wall0_s)
        res["starts"] = starts_json(self.starts.records)
        res["warnings"] += [f"{r.name}: {r.hint}" for r in self.starts.records if r.hint]
        return res

    def _run_once(self, starts) -> None:
        """One pass of every stage over the files as `starts` scores them; sets ``outcome``."""
        ctx, train, test = self.ctx, starts.train, starts.test
        p = ctx.params
        stage = iter(STAGES)
        self.progress(next(stage))  # baseline and candidate grid
        grid = grid_plan(ctx)
        base = establish_baseline(ctx, train, test, grid)
        self.progress(next(stage))  # where
        where = where_residual(
            train, base.base_tr, [y - q for y, q in zip(base.train.obs, base.p0_tr)], p, ctx.cooler, ctx.opts
        )
        heat = unexplained_heat(p, train + test, base.heat_pair, base.p0_tr + base.p0_te, ctx.opts.grid_dt_s)
        self.progress(next(stage))  # fit
        fits = fit_all(ctx, base, grid)
        self.progress(next(stage))  # test
        crit = rank(base, fits, simulate_test_files(ctx, base, fits))
        ident = identifiability(ctx, base, fits)
        self.progress(next(stage))  # verdict
        verdict = decide(ctx, base, crit)
        combo, set_note = None, ""
        conf = confusable_with(crit, ctx.opts)
        if verdict.is_effect:
            combo, set_note = select_set(ctx, base, crit, fits, verdict.gap_thr_c, conf)
        elif verdict.effect == "unexplained" and verdict.thin is None:
            combo = rescue(ctx, base, crit, fits, verdict.gap_thr_c)
        verdict = with_combination(ctx, base, verdict, combo)
        if set_note:
            verdict = replace(verdict, reason=verdict.reason + set_note)
        res = residuals(base, verdict, crit, combo)
        checked = held_out_check(ctx, base, verdict, res, where.where)
        start_res = res  # the starts are judged on the effect's residual even when the held-out files refuse it
        if checked.effect != verdict.effect:  # refused: "unexplained", the baseline's residuals
            verdict, combo = checked, None
            res = residuals(base, verdict, crit)
        else:  # kept (perhaps with a note in its reason): the set stays
            verdict = checked
        structure = self._structure(base, fits, verdict)
        verdict = with_structure(verdict, structure, crit.candidates[0].fit.effect)
        nex = self._not_excluded(base, crit, fits, verdict, combo, ident)
        verdict = with_not_excluded(verdict, nex)
        sugg = suggestions(ctx, train, verdict, crit, conf)
        regs = regimes_before_after(test, base.base_te, res.test_before, res.test_after, p, ctx.cooler, ctx.opts)
        self.outcome = Outcome(
            base, where, heat, crit, ident, verdict, conf, sugg, res, regs, structure, combo, tuple(nex), start_res
        )

    def _not_excluded(self, base, crit, fits: list, verdict, combo, ident: dict) -> list:
        """The effects the training files cannot rule out beside an effect verdict (:mod:`.exclude`)."""
        if not verdict.is_effect or not self.ctx.opts.not_excluded:
            return []
        start = ()
        if combo is not None:
            members, out, start = combo.members, combo.out_train, combo.start
        else:
            top = crit.candidates[0].fit
            if top.effect != verdict.effect:
                return []
            members, out = {top.effect: top.value}, top.out_train
        skip = {e for e, i in ident.items() if not i.identifiable}
        return not_excluded(self.ctx, base, crit, fits, members, out, skip, start)

    def _structure(self, base, fits: list, verdict) -> dict:
        """The regime structure of the training residual (regimes.residual_structure) per channel with a gap, with
        the model started from the sump that the fitted oil-sensor offset implies: a sensor offset leaves the same
        residual in every regime, a heat-flow effect does not."""
        ctx, train = self.ctx, base.train.datasets
        gap = [c for c, v in verdict.systematic.rms_c.items() if v > verdict.gap_thr_c[c]]
        off = next((f.value for f in fits if f.effect == "oil_sensor_offset"), 0.0)
        preds = base.scorer.adjust(
            base.scorer.preds(base.train.datasets, base.base_tr, "oil_sensor_offset", off), "train"
        )
        chans = [c for ds in base.train.datasets for c in ds.channels]
        resid = [y - q + (off if c == OIL else 0.0) for y, q, c in zip(base.train.obs, preds, chans)]
        where = where_residual(train, base.base_tr, resid, ctx.params, ctx.cooler, ctx.opts)
        return residual_structure(where.where_by, gap)


def make_model(kind: str, params, cooler: str | None, opts: Options):
    """(model under diagnosis, note): the onboard model or the reference plant; the note says when the plant stands
    in for an onboard model that is not available."""
    from tools.diagnosis.models import OnboardModel, PlantModel, onboard_available

    plant = PlantModel(params, cooler=cooler, dt_s=opts.plant_dt_s, out_dt_s=opts.out_dt_s, workers=opts.workers)
    note = None
    if kind == "plant":
        return plant, note
    if kind != "onboard":
        raise InputError(f"--model {kind!r} must be onboard or plant")
    if not onboard_available():
        note = (
            "the onboard model (firmware_model.onboard.sensor) is not available yet; the reference plant was "
            "diagnosed instead"
        )
        return plant, note
    return OnboardModel(params, cooler=cooler, fallback=plant, out_dt_s=opts.out_dt_s, workers=opts.workers), note


def boundary_note(runs) -> str | None:
    """The note for an onboard diagnosis of files with bc_* boundary columns (the onboard runs take them as their
    boundary temperatures, tools.diagnosis.models.run_onboard_pass), None without them."""
    cols = sorted({c for ds in (*runs.train, *runs.test) for c in ds.inputs.columns if c.startswith("bc_")})
    if not cols:
        return None
    return (
        f"the files give boundary temperatures ({', '.join(cols)}) that a truck does not send (only the ambient "
        f"and the coolant): the onboard model was run with them, as the reference plant is"
    )


def diagnose(
    train_tables,
    test_tables,
    params,
    model: str = "onboard",
    cooler: str | None = None,
    opts: Options | None = None,
    progress=None,
    train_names=None,
    test_names=None,
    candidates=None,
    keep=False,
    config_path=None,
):
    """Run the diagnosis on lists of RunTables (or paths). Returns the JSON dict (and the Diagnosis object when
    `keep`). `progress(stage)` is told each stage of :data:`tools.diagnosis.options.STAGES` as it begins."""
    opts = opts or Options()
    cooler = cooler or params.strings.get("cooler.kind", "liquid")
    runs = prepare_runs(
        train_tables, test_tables, opts, cooler in ("measured", "hold"), train_names, test_names, config_path, params
    )
    m, note = make_model(model, params, cooler, opts)
    if m.name == "onboard":
        note = "; ".join(n for n in (note, boundary_note(runs)) if n) or None
    try:
        d = Diagnosis(runs.train, runs.test, m, params, opts, cooler, progress, candidates)
        res = d.run()
    finally:
        m.close()
    res["model"]["requested"] = model
    if note:
        res["model"]["note"] = note
    return (res, d) if keep else res
