"""Golden-output cases: what the code computed before a refactor, so that the refactor can prove it changed nothing.

Each case is a function returning ``{name: ndarray}`` computed through the public API (the same functions the CLI
calls). ``record`` stores, per case and column, a SHA-256 of the full float64 array (bit identity), the full-length
sum / min / max, and every ``STRIDE``-th row at full precision (for the 1e-9 K comparison where reordered sums move
the last bits). Stored in ``tests/golden/data/`` (small: subsampled rows only).

Run ``python -m tests.golden.cases record`` to re-record (only on purpose: the point is that they do not change).
"""

from __future__ import annotations

import functools
import hashlib
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
DATA = HERE / "data"
#: rows kept at full precision: one in STRIDE (a 3 h table at 10 Hz keeps ~360 rows)
STRIDE = 300
CYCLES = ("steady", "all_gears", "long_haul", "uphill", "mining")
#: the real truck captures (shipped with the tests' data when present; see tests/data/README.md)
CAPTURES = (
    "normal.candump.log",
    "tsc1.candump.log",
    "fuzz_1ms_ID_and_Data.candump.log",
    "utulsa_logger2_drive.candump.log",
)
BENCH_SCENARIOS = (0, 3)


def capture_dir() -> Path | None:
    from tests.data_paths import real_capture_dir

    return real_capture_dir()


def _params():
    from firmware_model.parameters import load_parameters

    return load_parameters("GRS905")


def _table_arrays(table) -> dict:
    return {c: np.asarray(table[c], dtype=float) for c in table.columns}


@functools.cache
def _plant_table(cycle: str):
    """The reference plant's run table of ``cycle``: run once per process for its plant case and its sensor case
    (read only)."""
    from tools.cycles.named import get_cycle
    from tools.plant.reference import ReferencePlant

    return ReferencePlant(_params()).run(get_cycle(cycle), progress=False).table


def plant_case(cycle: str) -> dict:
    return {c: np.array(v, copy=True) for c, v in _table_arrays(_plant_table(cycle)).items()}


def sensor_case(cycle: str) -> dict:
    """The onboard sensor over the plant's run table of ``cycle`` (inputs and the plant's sump as the oil sensor)."""
    from firmware_model.config import load_config
    from firmware_model.onboard.sensor import VirtualSensor
    from tools.replay.table import replay_table

    params = _params()
    plant = _plant_table(cycle)
    with tempfile.TemporaryDirectory() as d:
        from tools.replay.table import read_inputs_table
        from tools.runtable import write_run_table

        p = Path(d) / "plant.csv"
        write_run_table(plant, p)
        table = read_inputs_table(p)
    sensor = VirtualSensor(params, config=load_config(None))
    return _table_arrays(replay_table(table, sensor))


def batch_case() -> dict:
    """Three vehicles stepped as one batch (the batch API), 20 min of the uphill cycle with different oils."""
    from firmware_model.onboard.sensor import VirtualSensor
    from tools.cycles.named import get_cycle

    params = _params()
    sensor = VirtualSensor(params)
    tb = get_cycle("uphill")
    n = 12000
    state = sensor.initial_state(T_oil_c=np.array([40.0, 60.0, 80.0]), n_vehicles=3)
    T, L, ttl = [], [], []
    for i in range(n):
        sp = tb["engine_speed_rpm"][i] * np.array([1.0, 0.9, 1.1])
        tq = tb["engine_torque_nm"][i] * np.array([1.0, 1.2, 0.8])
        g = np.full(3, tb["gear"][i])
        oil = np.full(3, np.nan)
        inp = sensor.Inputs(
            speed_rpm=sp,
            torque_nm=tq,
            gear=g,
            oil_temp_c=oil,
            ambient_temp_c=np.full(3, 25.0),
            coolant_temp_c=np.full(3, 85.0),
            vehicle_speed_kmh=np.full(3, 50.0),
            retarder_torque_nm=np.zeros(3),
            t_s=np.full(3, 0.1 * (i + 1)),
        )
        state, out = sensor.step(state, inp)
        if i % 10 == 0:
            T.append(np.array(out.T_c, dtype=float))
            L.append(np.array(out.level, dtype=float))
            ttl.append(np.array(out.ttl_s, dtype=float))
    return {
        "T_c": np.stack(T).reshape(len(T), -1),
        "level": np.stack(L).reshape(len(L), -1),
        "ttl_s": np.stack(ttl).reshape(len(ttl), -1),
    }


def capture_case(name: str) -> dict:
    """A real capture through the CAN service (decoder, freshness, step) with its output frames."""
    from firmware_model.service import build_service
    from tools.replay.log import replay_log

    d = capture_dir()
    if d is None:
        raise FileNotFoundError("real captures not found")
    service = build_service(None, record=True, emit_frames=True)
    frames = []
    table = replay_log(d / name, service, on_frames=frames.extend, columnar=False)
    out = _table_arrays(table)
    out["frames_id"] = np.array([f.arbitration_id for f in frames], dtype=float)
    out["frames_t"] = np.array([f.timestamp for f in frames], dtype=float)
    data = np.zeros((len(frames), 8))
    for i, f in enumerate(frames):
        data[i, : len(f.data)] = list(f.data)
    out["frames_data"] = data
    return out


def bench_case(index: int) -> dict:
    """One bench-diagnosis scenario (plant model, 900 s cycles): the diagnosis JSON, flattened to numbers + text."""
    from tools.diagnosis.bench import run_bench

    with tempfile.TemporaryDirectory() as d:
        run_bench(40, 1, d, model="plant", train_s=900.0, test_s=900.0, only={index}, progress=lambda m: None)
        js = json.loads((Path(d) / f"scenario_{index:02d}.json").read_text())
    js.pop("timing", None)
    nums, text = [], []

    def walk(x, path):
        if isinstance(x, dict):
            for k in sorted(x):
                if k in ("seconds", "wall_s", "diag_s", "elapsed_s", "time_s_wall"):
                    continue
                walk(x[k], f"{path}/{k}")
        elif isinstance(x, list):
            for i, v in enumerate(x):
                walk(v, f"{path}[{i}]")
        elif isinstance(x, bool) or x is None or isinstance(x, str):
            text.append(f"{path}={x}")
        elif isinstance(x, (int, float)):
            nums.append(float(x))
            text.append(f"{path}=#")

    walk(js, "")
    h = hashlib.sha256("\n".join(text).encode()).digest()
    return {"numbers": np.asarray(nums, dtype=float), "text_sha": np.frombuffer(h, dtype=np.uint8).astype(float)}


def all_cases() -> dict:
    cases = {}
    for c in CYCLES:
        cases[f"plant_{c}"] = (plant_case, (c,))
        cases[f"sensor_{c}"] = (sensor_case, (c,))
    cases["sensor_batch3"] = (batch_case, ())
    for c in CAPTURES:
        cases[f"capture_{c.split('.')[0]}"] = (capture_case, (c,))
    for i in BENCH_SCENARIOS:
        cases[f"bench_{i:02d}"] = (bench_case, (i,))
    return cases


def _sha(a: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(a, dtype=float).tobytes()).hexdigest()


def summarise(arrays: dict) -> tuple[dict, dict]:
    """(manifest entry, subsampled arrays) of one case."""
    meta, sub = {}, {}
    for k, a in arrays.items():
        a = np.asarray(a, dtype=float)
        fin = a[np.isfinite(a)]
        meta[k] = {
            "shape": list(a.shape),
            "sha256": _sha(a),
            "n_nan": int(np.isnan(a).sum()),
            "sum": float(fin.sum()) if fin.size else 0.0,
            "min": float(fin.min()) if fin.size else None,
            "max": float(fin.max()) if fin.size else None,
        }
        sub[k] = a[::STRIDE] if a.ndim >= 1 and a.shape[0] > STRIDE else a
    return meta, sub


def record(names=None) -> None:
    DATA.mkdir(parents=True, exist_ok=True)
    manifest_path = DATA / "manifest.json"
    manifest = json.loads(manifest_path.read_text()) if manifest_path.exists() else {}
    for name, (fn, args) in all_cases().items():
        if names and name not in names:
            continue
        print(f"recording {name} ...", flush=True)
        meta, sub = summarise(fn(*args))
        manifest[name] = meta
        np.savez_compressed(DATA / f"{name}.npz", **{k.replace("/", "_"): v for k, v in sub.items()})
        manifest_path.write_text(json.dumps(manifest, indent=1, sort_keys=True))


if __name__ == "__main__":
    if len(sys.argv) >= 2 and sys.argv[1] == "record":
        record(set(sys.argv[2:]) or None)
    else:
        print(__doc__)
