"""Behaviour pinned across refactors: every case of tests/golden/cases.py against what was recorded before.

A column passes when its full float64 array is bit-identical to the recording (same SHA-256), or else, where a
reordered sum moves the last bits, when every recorded row (one in STRIDE, full precision) is within 1e-9 (absolute)
or 1e-11 of the column's largest magnitude, whichever is larger, and the full-length NaN count, min and max agree to
the same tolerance. The relative part is for the heat flows: numpy's reductions group their sums by the CPU's SIMD
width, so an AVX-512 machine moves the plant's temperatures by ~1e-13 K from an AVX2 one, and the stored power
C dT / h by up to 1e-8 W on a column of 1.4e4 W (measured 2026-12-02: 2.7e-9 to 9.6e-9 W on Q_stored_w, every
temperature within 3e-13 K); 1e-11 of a temperature column (~150 degC) is 1.5e-9 K, the absolute bound's size.
Integer-valued columns (warning levels, modes,
counters, frame ids and bytes) must be identical. The test prints which columns are bit-identical and which only
within tolerance, with the largest difference.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.golden import cases as C

TOL = 1e-9
REL_TOL = 1e-11
MANIFEST = json.loads((C.DATA / "manifest.json").read_text()) if (C.DATA / "manifest.json").exists() else {}


def _integer_valued(meta: dict, sub: np.ndarray) -> bool:
    fin = sub[np.isfinite(sub)]
    return (
        fin.size > 0
        and bool(np.all(fin == np.round(fin)))
        and meta["max"] is not None
        and float(meta["max"]) == round(float(meta["max"]))
        and float(meta["min"]) == round(float(meta["min"]))
    )


def column_tolerance(meta: dict) -> float:
    """The largest difference a recorded column may show: TOL, or REL_TOL of its largest finite magnitude."""
    scale = max(
        (abs(float(meta[k])) for k in ("min", "max") if meta[k] is not None and np.isfinite(meta[k])), default=0.0
    )
    return max(TOL, REL_TOL * scale)


def compare(want: dict, stored, arrays: dict) -> tuple[list, list, list]:
    """(bit-identical columns, within-tolerance columns with max diff, failures) of ``arrays`` against a recording
    (``want``: the manifest entry, ``stored``: its subsampled arrays)."""
    exact, close, bad = [], [], []
    missing = set(want) - set(arrays)
    extra = set(arrays) - set(want)
    if missing:
        bad.append(f"columns missing: {sorted(missing)}")
    if extra:
        bad.append(f"new columns: {sorted(extra)}")
    for col in sorted(set(want) & set(arrays)):
        meta, a = want[col], np.asarray(arrays[col], dtype=float)
        if list(a.shape) != meta["shape"]:
            bad.append(f"{col}: shape {a.shape} != {tuple(meta['shape'])}")
            continue
        if C._sha(a) == meta["sha256"]:
            exact.append(col)
            continue
        ref = stored[col.replace("/", "_")]
        got = a[:: C.STRIDE] if a.ndim >= 1 and a.shape[0] > C.STRIDE else a
        if int(np.isnan(a).sum()) != meta["n_nan"] or not np.array_equal(np.isnan(got), np.isnan(ref)):
            bad.append(f"{col}: NaN pattern differs")
            continue
        diff = np.abs(np.nan_to_num(got - ref, nan=0.0, posinf=0.0, neginf=0.0))
        inf_ok = np.array_equal(np.isinf(got), np.isinf(ref)) and np.array_equal(got[np.isinf(got)], ref[np.isinf(ref)])
        fin = a[np.isfinite(a)]
        ext = 0.0 if not fin.size else max(abs(float(fin.min()) - meta["min"]), abs(float(fin.max()) - meta["max"]))
        worst = max(float(diff.max(initial=0.0)), ext)
        tol = column_tolerance(meta)
        if _integer_valued(meta, ref) and worst > 0:
            bad.append(f"{col}: integer-valued column differs (max {worst:g})")
        elif worst > tol or not inf_ok:
            bad.append(f"{col}: differs by {worst:.3g} > {tol:.3g}")
        else:
            close.append((col, worst))
    return exact, close, bad


_cache: dict = {}


@pytest.mark.parametrize("name", sorted(C.all_cases()))
def test_golden(name):
    if name not in MANIFEST:
        pytest.skip(f"no golden recording for {name}")
    if name.startswith("capture_") and C.capture_dir() is None:
        from tests.data_paths import SKIP_REASON

        pytest.skip(SKIP_REASON)
    fn, args = C.all_cases()[name]
    exact, close, bad = compare(MANIFEST[name], np.load(C.DATA / f"{name}.npz"), fn(*args))
    print(
        f"\n{name}: {len(exact)} columns bit-identical, {len(close)} within tolerance"
        + (": " + ", ".join(f"{c} {d:.1e}" for c, d in close[:12]) if close else "")
    )
    assert not bad, f"{name}: " + "; ".join(bad[:20])


def test_compare_detects_a_change():
    """The comparison itself: bit-identical passes, 1e-12 passes as 'within', 1e-8 fails, a flipped level fails; on a
    column of 2e4 (a heat flow in W) 1e-8 passes and 1e-6 fails."""
    rng = np.random.default_rng(0)
    arrays = {"T_c": 60 + 40 * rng.random(2000), "W": rng.integers(0, 3, 2000).astype(float)}
    meta, sub = C.summarise(arrays)
    assert compare(meta, sub, arrays) == (["T_c", "W"], [], [])
    moved = dict(arrays, T_c=arrays["T_c"] + 1e-12)
    exact, close, bad = compare(meta, sub, moved)
    assert exact == ["W"] and [c for c, _ in close] == ["T_c"] and not bad
    far = dict(arrays, T_c=arrays["T_c"] + 1e-8)
    assert compare(meta, sub, far)[2]
    w = arrays["W"].copy()
    w[0] = (w[0] + 1) % 3
    assert compare(meta, sub, dict(arrays, W=w))[2]
    flows = {"Q_w": 2e4 * rng.random(2000) - 4e3}
    meta, sub = C.summarise(flows)
    assert not compare(meta, sub, {"Q_w": flows["Q_w"] + 1e-8})[2]
    assert compare(meta, sub, {"Q_w": flows["Q_w"] + 1e-6})[2]
