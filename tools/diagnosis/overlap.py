"""Test files that are not held out: a test file that repeats rows of a training file (the same rows, a time window
cut from it, its time stamps kept or shifted to start at 0, every other row, its values rounded).

Two rows are the same row when the drive (engine speed, torque, gear; and the oil when it is an input) and every
measured channel both files carry agree within the files' rounding (half the coarser of their steps:
:func:`column_step`). A test file overlaps a training file when, at one time shift between them, at least
MIN_SHARED_ROWS rows and AGREE_SHARE of the rows in their common time span are the same, also at the span's start.
Two runs of one cycle (the same inputs) differ in their measured temperatures; two runs from different starts that
meet later (a steady load) differ at the start.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from firmware_model.errors import InputError

#: the fewest shared rows that count as an overlap (a file needs 10 rows to be diagnosed at all)
MIN_SHARED_ROWS = 10
#: share of the rows in the common time span (and of its first START_SHARE) that must be the same rows
AGREE_SHARE, START_SHARE = 0.95, 0.05
#: the coarsest rounding taken for one (1 K, 1 rpm, 1 Nm: a column with a few distinct values far apart is not
#: rounded that coarsely, and must not pass rows 50 K apart as the same)
MAX_STEP = 1.0
#: rows of the shorter file tried as anchors of a shift, and the most rows of the longer one an anchor may match
#: (more: a constant stretch, which says no shift)
N_ANCHORS, MAX_MATCHES = 8, 20
DRIVE = ("engine_speed_rpm", "engine_torque_nm", "gear")


class Overlap(NamedTuple):
    """Rows of a test file that repeat rows of a training file."""

    shared: int  # rows the same
    rows: int  # rows of the test file
    t0_s: float  # the span in the training file's time
    t1_s: float
    shift_s: float  # training time - test time


def column_step(v: np.ndarray) -> float:
    """The smallest step between distinct finite values of a column (its rounding; 0 when it has one value), at most
    MAX_STEP."""
    u = np.unique(v[np.isfinite(v)])
    return min(float(np.min(np.diff(u))), MAX_STEP) if u.size > 1 else 0.0


def _columns(a, b, oil_is_input: bool) -> tuple:
    """(the inputs, the measured columns) both tables carry: the drive, and the oil when it is an input (a held sump
    is a set point, the same in every run at it); the thermocouples (meas_T_*_c), and the oil when it is measured."""
    oil = ["oil_temp_c"] if a.has("oil_temp_c") and b.has("oil_temp_c") else []
    inputs = [c for c in DRIVE if a.has(c) and b.has(c)] + (oil if oil_is_input else [])
    meas = [c for c in a.columns if c.startswith("meas_T_") and c.endswith("_c") and b.has(c)]
    return inputs, meas + ([] if oil_is_input else oil)


class _Side(NamedTuple):
    t: np.ndarray
    cols: list  # arrays in the order of the compared columns


def _side(table, cols) -> _Side:
    return _Side(np.asarray(table["time_s"], dtype=float), [np.asarray(table[c], dtype=float) for c in cols])


def _same(x: np.ndarray, y: np.ndarray, tol: float) -> np.ndarray:
    """Row by row: equal within tol, or missing in either (no evidence against)."""
    with np.errstate(invalid="ignore"):
        return ~(np.abs(x - y) > tol)


def _shifts(short: _Side, long: _Side, tols: list) -> set:
    """Candidate time shifts (long time - short time): 0, and those that put an anchor row of the short file on a row
    of the long one with the same drive and temperatures."""
    out = {0.0}
    for a in np.linspace(0, short.t.size - 1, N_ANCHORS).astype(int):
        ok = np.ones(long.t.size, dtype=bool)
        for xs, xl, tol in zip(short.cols, long.cols, tols):
            ok &= _same(xl, xs[a], tol)
        j = np.flatnonzero(ok)
        if 0 < j.size <= MAX_MATCHES:
            out.update(float(x) for x in np.round(long.t[j] - short.t[a], 9))
    return out


def _agreement(short: _Side, long: _Side, tols: list, n_drive: int, shift: float) -> tuple:
    """(rows in the common span, rows the same, of the span's first START_SHARE the share the same, the span's
    indices in the short file) at one shift."""
    ts = short.t + shift
    span = np.flatnonzero((ts >= long.t[0] - 1e-9) & (ts <= long.t[-1] + 1e-9))
    if span.size < MIN_SHARED_ROWS:
        return 0, 0, 0.0, span
    half_dt = 0.5 * min(float(np.median(np.diff(short.t))), float(np.median(np.diff(long.t))))
    j = np.clip(np.searchsorted(long.t, ts[span]), 1, long.t.size - 1)
    j = np.where(np.abs(long.t[j - 1] - ts[span]) < np.abs(long.t[j] - ts[span]), j - 1, j)
    same = np.abs(long.t[j] - ts[span]) <= half_dt + 1e-9
    seen = np.zeros(span.size, dtype=bool)
    for k, (xs, xl, tol) in enumerate(zip(short.cols, long.cols, tols)):
        same &= _same(xs[span], xl[j], tol)
        if k >= n_drive:
            seen |= np.isfinite(xs[span]) & np.isfinite(xl[j])
    same &= seen  # at least one measured channel compared
    head = same[: max(MIN_SHARED_ROWS, int(START_SHARE * span.size))]
    return span.size, int(same.sum()), float(head.mean()), span


def find_overlap(train, test, oil_is_input: bool = False) -> Overlap | None:
    """The rows of the RunTable ``test`` that repeat rows of the RunTable ``train`` (module note), or None."""
    inputs, meas = _columns(train, test, oil_is_input)
    if not meas:
        return None  # no measured channel in common: the same inputs alone are the same cycle, not the same run
    cols, n_drive = inputs + meas, len(inputs)
    tr, te = _side(train, cols), _side(test, cols)
    tols = [0.5 * max(column_step(a), column_step(b)) * (1 + 1e-6) + 1e-9 for a, b in zip(tr.cols, te.cols)]
    flip = te.t.size > tr.t.size  # anchors from the shorter file
    short, long = (tr, te) if flip else (te, tr)
    for shift in sorted(_shifts(short, long, tols), key=abs):
        n, shared, head, span = _agreement(short, long, tols, n_drive, shift)
        if shared >= MIN_SHARED_ROWS and shared >= AGREE_SHARE * n and head >= AGREE_SHARE:
            t_long = short.t[span] + shift
            t0, t1 = (float(short.t[span[0]]), float(short.t[span[-1]])) if flip else (t_long[0], t_long[-1])
            return Overlap(shared, te.t.size, float(t0), float(t1), -shift if flip else shift)
    return None


def check_held_out(train: list, test: list, oil_is_input: bool = False) -> None:
    """InputError when a test file repeats rows of a training file (``train``, ``test``: items with ``name`` and
    ``table``): its held-out figures would score rows the fit has seen."""
    for te in test:
        for tr in train:
            o = find_overlap(tr.table, te.table, oil_is_input)
            if o is None:
                continue
            shifted = f", its time shifted by {o.shift_s:.10g} s" if o.shift_s else ""
            raise InputError(
                f"{te.name} repeats {o.shared} of its {o.rows} rows from the training file {tr.name} (t = "
                f"{o.t0_s:.10g}..{o.t1_s:.10g} s there{shifted}: the same drive and measured temperatures within the "
                f"files' rounding), so its held-out figures would score data the fit has seen; give a test run that "
                f"is not cut from a training file"
            )
