"""Stage 2 of the diagnosis: the unmodified model on every file, and the measurement model fitted around it.

One batch per training file: the baseline, a 2 K warmer start (the sensitivity to the initial temperature; the oil's
effective conductance to the outside), the baseline at half the step (the model's own numerical error, plant only)
and the candidates' grid (bounds, at the coarse step where the backend has one, see :func:`fit.grid_plan`). Then
the noise per channel, the nuisance sensor lags, the model error floor, the weights, and the baseline's
predictions with the initial-temperature nuisance solved per file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from tools.diagnosis.context import Context
from tools.diagnosis.measurement import fit_nuisance_lags, noise_per_channel
from tools.diagnosis.models import Run
from tools.diagnosis.options import HOUSING_PERTURB_C
from tools.diagnosis.scoring import RoleData, Scorer, file_groups, observations, predictions, weights


class GridPlan(NamedTuple):
    """The candidates' grid re-simulations: the runs and, per run, (effect, value) (None: the coarse baseline)."""

    runs: list
    keys: list


class HeatPair(NamedTuple):
    """Baseline and 2 K warmer start of the same files (for the oil's effective conductance to the outside)."""

    base: list
    warmer: list


@dataclass(frozen=True)
class Baseline:
    base_tr: list  # model outputs per training file
    base_te: list  # model outputs per test file
    heat_pair: HeatPair
    grid_outs: list  # outputs of the GridPlan's runs (training files)
    sigma: dict  # noise per sample, per channel
    floor: dict  # model error floor, per channel
    lag0: dict  # nuisance lags refitted on the full misfit of the baseline
    scorer: Scorer
    p0_hp: list  # baseline predictions with the high-pass nuisance lags, no initial-temperature shift
    p0_tr: list  # baseline predictions as scored (lag0, initial temperature solved), training files
    p0_te: list  # the same on the test files
    S0: float  # misfit of the baseline (training files)
    S_noise: float  # the part of S the noise and the model error floor explain
    #: per channel, the model's error the verdict's thresholds take: the floor and, for the plant, its inputs'
    #: sampling error in quadrature (model_error_floor); the weights keep the floor alone
    thr_floor: dict = None

    @property
    def train(self) -> RoleData:
        return self.scorer.train

    @property
    def test(self) -> RoleData:
        return self.scorer.test


class Sims(NamedTuple):
    base_tr: list
    warm_tr: list
    ref_tr: list | None  # the model's error reference: plant, itself at half the step; onboard, the plant
    thin_tr: list | None  # plant: itself on thinned inputs (the inputs' sampling error, model_error_floor)
    grid_outs: list
    base_te: list
    warm_te: list
    heat_pair: HeatPair
    house_tr: list | None = None  # the housings' start moved (files that start running, tools/diagnosis/start.py)
    house_te: list | None = None


def _simulate(ctx: Context, train: list, test: list, grid: GridPlan) -> Sims:
    head = [Run.of(), Run.of(initial_offset_c=2.0)] + (
        [Run.of(fine=True), Run.of(thinned=True)] if ctx.is_plant else []
    )
    out_tr = ctx.sim.run(train, head + grid.runs)
    out_te = ctx.sim.run(test, head[:2])
    house = (None, None)
    if any(ds.start == "running" for ds in train + test):
        # files that start running (tools/diagnosis/start.py): the housings' start moved, their nuisance
        hr = [Run.of(housing_offset_c=HOUSING_PERTURB_C)]
        house = (ctx.sim.run(train, hr)[0], ctx.sim.run(test, hr)[0])
    ref_tr = None
    if ctx.is_plant:
        pair = HeatPair(out_tr[0], out_tr[1])
    elif getattr(ctx.model, "fallback", None) is not None:
        # the reference plant beside the onboard model: the baseline and a 2 K warmer start of the first training
        # file (the heat pair), and its baseline at half its step on every training file (the onboard model's
        # reduction error, model_error_floor; the half step keeps the plant's own step error out of it)
        pp = ctx.model.fallback.simulate(train[:1], [Run.of(), Run.of(initial_offset_c=2.0)], [])
        cols = sorted({ch.model_column for ds in train for ch in ds.channels.values()})
        ref_tr = ctx.model.fallback.simulate(train, [Run.of(fine=True)], cols)[0]
        ctx.sim.count(2 + len(train))
        pair = HeatPair(pp[0], pp[1])
    else:
        pair = HeatPair([], [])
    return Sims(
        out_tr[0],
        out_tr[1],
        out_tr[2] if ctx.is_plant else ref_tr,
        out_tr[3] if ctx.is_plant else None,
        out_tr[len(head) :],
        out_te[0],
        out_te[1],
        pair,
        *house,
    )


#: a channel whose noise per sample is under this is noise-free (the J1939 quantisation alone is 0.009 degC): there
#: the thresholds fall to the model's error, and the plant's include its inputs' sampling error [degC]
NOISE_FREE_C = 0.02


def model_error_floor(ctx: Context, train: list, sims: Sims, lag: dict, channels) -> tuple[dict, dict]:
    """Per channel, the model's own error, at least model_floor_c: the plant's numerical error (BDF2: error ~ dt^2,
    so the full step's error is about 4/3 of its difference to the half step); the onboard model's reduction error,
    its RMS difference to the reference plant on the same files (``ref_tr``). Returns (that floor, the floor the
    thresholds take): for the plant the latter adds, in quadrature, its inputs' sampling error: its RMS difference
    on inputs thinned (``thin_tr``: every second row's drive inputs from its neighbours, about the same error again
    where the drive varies faster than the rows, next to none where it moves smoothly between them). The weights
    keep the floor alone, and the sampling error counts on noise-free channels only (``channels``: the noise per
    channel; NOISE_FREE_C). Where
    the reduced model departs from the plant no effect is to absorb it (a third effect took up a rig's reduction
    error of 1.2 times the threshold beside a planted pair; an arctic start without any effect was called
    synchronizer heat)."""
    o = ctx.opts
    floor = {c: o.model_floor_c for c in channels}
    if sims.ref_tr is None:
        return floor, dict(floor)
    factor = 4.0 / 3.0 if ctx.is_plant else 1.0
    err = _rms_by_channel(train, predictions(train, sims.base_tr, lag), predictions(train, sims.ref_tr, lag))
    # the plant: its step's error and, in quadrature, its inputs' sampling error (their odd rows from their
    # neighbours: noise-free 1 s rows of a 10 Hz drive, 0.19 K on the LI teeth, read as a gap beyond the step's)
    samp = (
        _rms_by_channel(train, predictions(train, sims.base_tr, lag), predictions(train, sims.thin_tr, lag))
        if sims.thin_tr is not None
        else {}
    )
    thr = dict(floor)
    for cid, e in err.items():
        floor[cid] = max(o.model_floor_c, factor * e)
        # only on a channel without measurement noise: with noise, its threshold covers the inputs' error (with the
        # sampling error in the thresholds of noisy channels a rig's weak cooler, bench-diagnosis' scenario 1,
        # went unseen)
        s_c = samp.get(cid, 0.0) if channels.get(cid, 0.0) < NOISE_FREE_C else 0.0
        thr[cid] = max(o.model_floor_c, math.hypot(factor * e, s_c))
    return floor, thr


def _rms_by_channel(datasets: list, a_preds: list, b_preds: list) -> dict:
    """Per channel id, the RMS difference of two prediction lists over the data sets' channels."""
    acc: dict = {}
    for (cid, _), a, b in zip([(c, h) for ds in datasets for c, h in ds.channels.items()], a_preds, b_preds):
        x = acc.setdefault(cid, [0.0, 0])
        x[0] += float(np.sum((a - b) ** 2))
        x[1] += a.size
    return {cid: math.sqrt(ss / max(n, 1)) for cid, (ss, n) in acc.items()}


def _role(
    datasets: list, base: list, warm: list, lag: dict, sigma: dict, floor: dict, ctx: Context, house: list | None = None
) -> RoleData:
    """The measurements of one role and the sensitivity of every prediction to the initial temperature (and, for
    the files that start running, to the housings' start)."""
    sb, sp = predictions(datasets, base, lag), predictions(datasets, warm, lag)
    sens_h = None
    if house is not None and any(ds.start == "running" for ds in datasets):
        sens_h = [(q - p) / HOUSING_PERTURB_C for p, q in zip(sb, predictions(datasets, house, lag))]
    return RoleData(
        datasets,
        observations(datasets),
        weights(datasets, sigma, floor, ctx.opts),
        [(q - p) / 2.0 for p, q in zip(sb, sp)],
        file_groups(datasets),
        sens_h,
    )


def establish_baseline(ctx: Context, train: list, test: list, grid: GridPlan) -> Baseline:
    """Simulate the baseline batch and fit the measurement model around it (files that start running,
    tools/diagnosis/start.py, with their housings' start as a second nuisance)."""
    sims = _simulate(ctx, train, test, grid)
    # noise per channel (pooled median over the files), nuisance lags
    sigma = noise_per_channel(train + test, sims.base_tr + sims.base_te)
    lag = fit_nuisance_lags(train, sims.base_tr, ctx.opts)
    floor, thr_floor = model_error_floor(ctx, train, sims, lag, sigma)
    scorer = Scorer(
        _role(train, sims.base_tr, sims.warm_tr, lag, sigma, floor, ctx, sims.house_tr),
        _role(test, sims.base_te, sims.warm_te, lag, sigma, floor, ctx, sims.house_te),
        lag,
        ctx.opts,
    )
    lag0 = scorer.refit_lags(sims.base_tr)
    p0_tr = scorer.adjust(scorer.preds(train, sims.base_tr, lags=lag0), "train")
    p0_te = scorer.adjust(scorer.preds(test, sims.base_te, lags=lag0), "test")
    S0 = scorer.S(p0_tr)
    # noise-expected part of S (for the explained share of the excess)
    S_noise = float(
        sum(
            np.sum(wi * (sigma[cid] ** 2 / ch.cell_n + floor[cid] ** 2))
            for wi, (cid, ch) in zip(scorer.train.w, [(c, h) for ds in train for c, h in ds.channels.items()])
        )
    )
    return Baseline(
        sims.base_tr,
        sims.base_te,
        sims.heat_pair,
        sims.grid_outs,
        sigma,
        floor,
        lag0,
        scorer,
        scorer.preds(train, sims.base_tr),
        p0_tr,
        p0_te,
        S0,
        S_noise,
        thr_floor,
    )
