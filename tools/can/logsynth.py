"""J1939 log synthesis: a drive cycle and the plant's answer to it, as the CAN traffic a truck and a rig would record.

:func:`write_can_log` turns a drive cycle (the plant's input run table) and the reference plant's output run table
into J1939 frames at the rates a truck sends them, plus the plant's true component temperatures as rig thermocouple
frames, and writes them as a CAN log (``.log`` candump -L, ``.asc``, ``.blf`` by suffix). ``gearbox-vsensor simulate
--can-log RUN.log`` calls it; ``gearbox-vsensor replay RUN.log`` reads such a log back through the onboard sensor.
:func:`synth_frames` gives the same frames as arrays (for the HIL plant, tools/cli/plant.py).

What is sent (CONTRACTS.md section 1; source addresses from ``[can]`` of the config, defaults in brackets):

======== ================== ================ ====================================================================
message  period             source           content
======== ================== ================ ====================================================================
EEC1     10-20 ms (rpm)     engine [0x00]    speed (0.125 rpm/bit), actual percent torque = torque / reference
                                             torque x 100, rounded to 1 %, clipped to -125..125 %
ETC2     100 ms             gearbox [0x03]   current and selected gear (seed Table 1 numbers, 0 = neutral)
TRF1     1 s                gearbox [0x03]   oil temperature: the plant's ``oil_temp_c`` (the vehicle's sensor),
                                             else the cycle's ``oil_temp_c``, else the plant's ``T_oil_c``
ET1      1 s                engine [0x00]    coolant temperature (1 degC/bit), if the cycle has ``coolant_temp_c``
AMB      1 s                engine [0x00]    ambient air temperature, if the cycle has ``ambient_temp_c``
CCVS1    1 s                engine [0x00]    wheel-based vehicle speed, if the cycle has ``vehicle_speed_kmh``
ERC1     100 ms             retarder [0x10]  actual retarder percent torque (braking is negative, J1939), if the
                                             cycle has ``retarder_torque_nm``
EC1      5 s, TP.BAM        engine [0x00]    39 bytes, SPN 544 reference torque in bytes 20-21; TP.CM BAM then 6
                                             TP.DT packets 50 ms apart
RIG_TC_* 100 ms             rig 0xF0         the plant's true temperatures of the 28 published components
======== ================== ================ ====================================================================

Timing: EEC1 follows the engine (20 ms at idle, 10 ms at 2100 rpm) with 0.3 ms of gaussian jitter; the other
messages keep their period with +-1 ms of jitter at fixed phases inside each 100 ms slot. Timestamps are whole
microseconds (the resolution of candump -L), counted from ``start_timestamp_s`` (default 0).

Values: every frame carries the cycle's value *sample_delay_s* (default 50 ms) before its timestamp, held (zero-order
hold) between the cycle's samples; plant temperatures are interpolated linearly. The delay stands for the sampling
and transmission delay of the ECUs; its real purpose is determinism on a real bus: the onboard sensor steps every
100 ms of frame time counted from the first frame (the first EEC1, at the cycle's first sample), so with a 10 Hz
cycle every value change and every 1 s / 100 ms message falls half-way between two sensor steps. Played onto a bus
with a few milliseconds of timing jitter (canplayer, a HIL), the sensor then samples exactly the same inputs as in an
offline replay of the log, which the vcan test (tests/tools/test_vcan_e2e.py) checks bit for bit.

Speed: ~1.6 M frames for a 3 h cycle; ``.log`` is written by a vectorised formatter that produces exactly the text of
python-can's ``CanutilsLogWriter`` (tests check it line for line); ``.asc`` and ``.blf`` go through python-can's
writers (slower, ~10 us per frame). See docs/can.md for figures.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

import numpy as np

from can_dbc.adapter import (EC1_PGN, RIG_SOURCE_ADDRESS, TP_BAM_CONTROL, TP_CM_PGN, TP_DT_PGN, can_id_of,
                             load_database)
from firmware_model.components import PUBLISHED
from firmware_model.errors import InputError, ParameterError

#: default engine reference torque (SPN 544) sent in EC1 when the config has none [Nm]; assumed, a 13 l truck engine
DEFAULT_REF_TORQUE_NM = 3000.0
#: default retarder reference torque used to express the cycle's retarder torque in percent [Nm]; assumed
DEFAULT_RETARDER_REF_TORQUE_NM = 3500.0
#: EC1 transfer: size (J1939-71 EC1, 39 bytes as on the utulsa truck), period, TP.DT spacing
EC1_SIZE_BYTES = 39
EC1_PERIOD_S = 5.0
TP_DT_SPACING_S = 0.050
#: default J1939 source addresses (CONTRACTS.md section 1)
DEFAULT_SOURCES = {"engine": 0x00, "transmission": 0x03, "retarder": 0x10, "ambient": 0x00, "rig": RIG_SOURCE_ADDRESS}

#: message -> (PGN, priority, period s, phase s inside the 100 ms slot); EEC1 has its own rpm-dependent schedule
_PERIODIC = {
    "ETC2": (61445, 3, 0.1, 0.050),
    "ERC1": (61440, 6, 0.1, 0.055),
    "RIG": (None, 6, 0.1, 0.075),
    "TRF1": (65272, 6, 1.0, 0.045),
    "ET1": (65262, 6, 1.0, 0.050),
    "AMB": (65269, 6, 1.0, 0.060),
    "CCVS1": (65265, 6, 1.0, 0.040),
}
_PERIODIC_JITTER_S = 0.001
_EEC1_JITTER_S = 0.0003
#: EC1 BAM: TP.CM at this phase of each 5 s period; the last of its 6 TP.DT completes 300 ms later (phase 0.35)
_EC1_PHASE_S = 0.050


@dataclass
class SynthFrames:
    """Frames as arrays, sorted by time: timestamps [s], 29-bit identifiers, payloads (n x 8 bytes)."""
    timestamp_s: np.ndarray
    can_id: np.ndarray
    data: np.ndarray

    def __len__(self) -> int:
        return int(self.timestamp_s.size)

    def messages(self, channel: str | None = None) -> Iterator:
        """The frames as ``can.Message`` (extended 8-byte data frames)."""
        import can
        for ts, cid, row in zip(self.timestamp_s.tolist(), self.can_id.tolist(), self.data):
            yield can.Message(timestamp=ts, arbitration_id=cid, is_extended_id=True, data=row.tobytes(),
                              channel=channel, check=False)


@dataclass
class LogSummary:
    path: Path
    frames: int
    duration_s: float
    per_message: dict


def _sources(config) -> dict:
    src = dict(DEFAULT_SOURCES)
    can_cfg = getattr(config, "can", None) or {}
    for key, name in (("engine_source_address", "engine"), ("transmission_source_address", "transmission"),
                      ("retarder_source_address", "retarder"), ("ambient_source_address", "ambient")):
        if key in can_cfg:
            value = can_cfg[key]
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 253:
                raise ParameterError(f"config can.{key} = {value!r} is not a J1939 source address 0..253")
            src[name] = value
    if "ambient_source_address" not in can_cfg:
        src["ambient"] = src["engine"]  # AMB comes from the engine unless configured otherwise
    return src


def _positive(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
        raise ParameterError(f"{name} = {value!r} must be a positive number of Nm")
    return float(value)


def _zoh(t_table: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Zero-order hold of a table column at times t (before the first sample: the first sample)."""
    idx = np.searchsorted(t_table, t, side="right") - 1
    return values[np.clip(idx, 0, t_table.size - 1)]


def _lin(t_table: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Linear interpolation ignoring NaN samples; all NaN -> NaN."""
    ok = np.isfinite(values)
    if not ok.any():
        return np.full(t.shape, np.nan)
    return np.interp(t, t_table[ok], values[ok])


def _raw8(x: np.ndarray, scale: float, offset: float) -> np.ndarray:
    """J1939 8-bit raw: NaN -> 0xFF not available, else rounded and clamped to the data range 0..250."""
    raw = np.rint((np.nan_to_num(x, nan=0.0) - offset) / scale)
    raw = np.clip(raw, 0, 250).astype(np.uint8)
    raw[~np.isfinite(x)] = 0xFF
    return raw


def _raw16(x: np.ndarray, scale: float, offset: float) -> np.ndarray:
    """J1939 16-bit raw: NaN -> 0xFFFF not available, else rounded and clamped to 0..0xFAFF."""
    raw = np.rint((np.nan_to_num(x, nan=0.0) - offset) / scale)
    raw = np.clip(raw, 0, 0xFAFF).astype(np.uint16)
    raw[~np.isfinite(x)] = 0xFFFF
    return raw


def _put16(data: np.ndarray, byte0: int, raw: np.ndarray) -> None:
    data[:, byte0] = raw & 0xFF
    data[:, byte0 + 1] = raw >> 8


def _slots(t0: float, t1: float, period_s: float, phase_s: float, rng: np.random.Generator) -> np.ndarray:
    n = int(np.floor((t1 - t0 - phase_s) / period_s)) + 1
    if n <= 0:
        return np.empty(0)
    t = t0 + phase_s + period_s * np.arange(n)
    return t + rng.uniform(-_PERIODIC_JITTER_S, _PERIODIC_JITTER_S, n)


def _eec1_times(t_table: np.ndarray, rpm: np.ndarray, t0: float, t1: float, rng: np.random.Generator) -> np.ndarray:
    """EEC1 every 20 ms at idle (600 rpm) down to 10 ms at 2100 rpm, with gaussian jitter; first frame at t0."""
    # the period as a function of time on a 10 ms grid, then the frame times by accumulating it
    grid = np.arange(t0, t1 + 0.01, 0.01)
    speed = _zoh(t_table, rpm, grid)
    period = np.clip(0.020 - (speed - 600.0) / 1500.0 * 0.010, 0.010, 0.020)
    # cumulative "phase" in frames: integral of 1/period; frame k is where the phase crosses k
    phase = np.concatenate([[0.0], np.cumsum(0.01 / period[:-1])])
    k = np.arange(0, int(phase[-1]) + 1)
    t = np.interp(k, phase, grid)
    t[1:] += rng.normal(0.0, _EEC1_JITTER_S, t.size - 1).clip(-3 * _EEC1_JITTER_S, 3 * _EEC1_JITTER_S)
    return np.sort(t[t <= t1])


def synth_frames(input_table, plant_output_table=None, *, config=None, ref_torque_nm: float | None = None,
                 retarder_ref_torque_nm: float | None = None, seed: int = 0, sample_delay_s: float = 0.05,
                 start_timestamp_s: float = 0.0, rig: bool = True) -> tuple[SynthFrames, dict]:
    """The J1939 and rig frames of a drive cycle (see the module doc); returns the frames and a count per message.

    ``input_table``: the plant's input run table (time_s, engine_speed_rpm, engine_torque_nm, gear, optional
    inputs). ``plant_output_table``: the plant's output (T_<id>_c columns for the rig frames, oil_temp_c for TRF1);
    None sends no rig frames. ``ref_torque_nm`` / ``retarder_ref_torque_nm``: default from the config's ``[can]``
    (engine_reference_torque_nm, retarder_reference_torque_nm), else 3000 Nm / 3500 Nm.
    """
    can_cfg = getattr(config, "can", None) or {}
    if ref_torque_nm is None:
        ref_torque_nm = can_cfg.get("engine_reference_torque_nm", DEFAULT_REF_TORQUE_NM)
    ref = _positive("engine reference torque", ref_torque_nm)
    if ref > 64255:
        raise ParameterError(f"engine reference torque = {ref:g} Nm is above the J1939 SPN 544 range 0..64255 Nm")
    if retarder_ref_torque_nm is None:
        retarder_ref_torque_nm = can_cfg.get("retarder_reference_torque_nm", DEFAULT_RETARDER_REF_TORQUE_NM)
    ret_ref = _positive("retarder reference torque", retarder_ref_torque_nm)
    if not 0.0 <= sample_delay_s < 1.0:
        raise InputError(f"sample_delay_s = {sample_delay_s!r} must be in 0..1 s")
    src = _sources(config)
    for col in ("time_s", "engine_speed_rpm", "engine_torque_nm", "gear"):
        if not input_table.has(col):
            raise InputError(f'the drive cycle has no column "{col}"; a J1939 log needs it')
    t_in = np.asarray(input_table["time_s"], dtype=float)
    if t_in.size < 2 or not np.all(np.diff(t_in) > 0):
        raise InputError("the drive cycle needs at least two samples with strictly increasing time_s")
    t0, t1 = float(t_in[0]), float(t_in[-1])
    rng = np.random.default_rng(seed)
    out_t = None
    if plant_output_table is not None:
        out_t = np.asarray(plant_output_table["time_s"], dtype=float)

    def col_in(name: str) -> np.ndarray | None:
        return np.asarray(input_table[name], dtype=float) if input_table.has(name) else None

    def at(name: str, t: np.ndarray) -> np.ndarray:
        return _zoh(t_in, col_in(name), t - sample_delay_s)

    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, int]] = []  # (t, id, data, message order)
    counts: dict[str, int] = {}

    def add(name: str, order: int, t: np.ndarray, can_id, data: np.ndarray) -> None:
        ids = np.broadcast_to(np.asarray(can_id, dtype=np.uint32), t.shape)
        parts.append((t, ids, data, order))
        counts[name] = counts.get(name, 0) + int(t.size)

    # EEC1 (PGN 61444): byte 3 actual percent torque, bytes 4-5 speed; byte 2 driver's demand = actual
    t = _eec1_times(t_in, col_in("engine_speed_rpm"), t0, t1, rng)
    pct = np.clip(np.rint(at("engine_torque_nm", t) / ref * 100.0), -125, 125)
    data = np.full((t.size, 8), 0xFF, dtype=np.uint8)
    data[:, 0] = 0xF0  # torque mode 0 "low idle governor/no request"; bits 5-8 reserved
    data[:, 1] = data[:, 2] = _raw8(pct, 1.0, -125.0)
    _put16(data, 3, _raw16(np.clip(at("engine_speed_rpm", t), 0.0, 8031.875), 0.125, 0.0))
    data[:, 5] = src["engine"]  # source address of the controlling device
    add("EEC1", 0, t, can_id_of(61444, src["engine"], 3), data)

    # ETC2 (PGN 61445): byte 1 selected gear, byte 4 current gear (offset -125)
    t = _slots(t0, t1, *_PERIODIC["ETC2"][2:], rng)
    gear = _raw8(at("gear", t), 1.0, -125.0)
    data = np.full((t.size, 8), 0xFF, dtype=np.uint8)
    data[:, 0] = data[:, 3] = gear
    add("ETC2", 1, t, can_id_of(61445, src["transmission"], 6), data)

    # TRF1 (PGN 65272): bytes 5-6 oil temperature, from the plant's sensor if it has one
    t = _slots(t0, t1, *_PERIODIC["TRF1"][2:], rng)
    oil = None
    if plant_output_table is not None:
        for name in ("oil_temp_c", "T_oil_c"):
            if plant_output_table.has(name):
                oil = _lin(out_t, np.asarray(plant_output_table[name], float), t - sample_delay_s)
                break
    if oil is None and input_table.has("oil_temp_c"):
        oil = at("oil_temp_c", t)
    if oil is not None:
        data = np.full((t.size, 8), 0xFF, dtype=np.uint8)
        _put16(data, 4, _raw16(oil, 0.03125, -273.0))
        add("TRF1", 2, t, can_id_of(65272, src["transmission"], 6), data)

    # ET1 byte 1 coolant; AMB bytes 4-5 ambient; CCVS1 bytes 2-3 vehicle speed
    for name, col, order, fill in (("ET1", "coolant_temp_c", 3, None), ("AMB", "ambient_temp_c", 4, None),
                                   ("CCVS1", "vehicle_speed_kmh", 5, None)):
        if not input_table.has(col):
            continue
        pgn, prio, period, phase = _PERIODIC[name]
        t = _slots(t0, t1, period, phase, rng)
        x = at(col, t)
        data = np.full((t.size, 8), 0xFF, dtype=np.uint8)
        if name == "ET1":
            data[:, 0] = _raw8(x, 1.0, -40.0)
        elif name == "AMB":
            _put16(data, 3, _raw16(x, 0.03125, -273.0))
        else:
            _put16(data, 1, _raw16(np.clip(x, 0.0, None), 1.0 / 256.0, 0.0))
        add(name, order, t, can_id_of(pgn, src["ambient" if name == "AMB" else "engine"], prio), data)

    # ERC1 byte 2 actual retarder percent torque; braking is negative in J1939
    if input_table.has("retarder_torque_nm"):
        t = _slots(t0, t1, *_PERIODIC["ERC1"][2:], rng)
        x = np.nan_to_num(at("retarder_torque_nm", t), nan=0.0)
        pct = np.clip(np.rint(-np.abs(x) / ret_ref * 100.0), -125, 125)
        data = np.full((t.size, 8), 0xFF, dtype=np.uint8)
        data[:, 0] = 0xF0
        data[:, 1] = _raw8(pct, 1.0, -125.0)
        add("ERC1", 6, t, can_id_of(61440, src["retarder"], 6), data)

    # EC1 by TP.BAM every 5 s: TP.CM BAM to global, then 6 TP.DT 50 ms apart
    n_ec1 = int(np.floor((t1 - t0 - _EC1_PHASE_S) / EC1_PERIOD_S)) + 1
    if n_ec1 > 0:
        payload = np.full(6 * 7, 0xFF, dtype=np.uint8)
        payload[19] = int(round(ref)) & 0xFF
        payload[20] = int(round(ref)) >> 8
        cm = np.array([TP_BAM_CONTROL, EC1_SIZE_BYTES & 0xFF, EC1_SIZE_BYTES >> 8, 6, 0xFF,
                       EC1_PGN & 0xFF, (EC1_PGN >> 8) & 0xFF, EC1_PGN >> 16], dtype=np.uint8)
        start = t0 + _EC1_PHASE_S + EC1_PERIOD_S * np.arange(n_ec1)
        rows = [cm] + [np.concatenate([[k + 1], payload[7 * k:7 * k + 7]]).astype(np.uint8) for k in range(6)]
        t = (start[:, None] + TP_DT_SPACING_S * np.arange(7)[None, :]).ravel()
        ids = np.tile(np.array([can_id_of(TP_CM_PGN, src["engine"], 7)] + [can_id_of(TP_DT_PGN, src["engine"], 7)]
                               * 6, dtype=np.uint32), n_ec1)
        data = np.tile(np.stack(rows), (n_ec1, 1))
        keep = t <= t1 + 6 * TP_DT_SPACING_S  # a transfer started inside the cycle is finished
        add("EC1", 7, t[keep], ids[keep], data[keep])

    # rig thermocouples: RIG_TC_1..7, 4 published components each, J1939 temperatures
    if rig and plant_output_table is not None:
        cols = [f"T_{c}_c" for c in PUBLISHED]
        if any(plant_output_table.has(c) for c in cols):
            t = _slots(t0, t1, *_PERIODIC["RIG"][2:], rng)
            db = load_database()
            for k in range(0, len(PUBLISHED), 4):
                msg = db.get_message_by_name(f"RIG_TC_{k // 4 + 1}")
                data = np.full((t.size, 8), 0xFF, dtype=np.uint8)
                for j, c in enumerate(PUBLISHED[k:k + 4]):
                    sig = msg.get_signal_by_name("TC_" + c.replace(".", "_"))
                    x = (_lin(out_t, np.asarray(plant_output_table[f"T_{c}_c"], float), t - sample_delay_s)
                         if plant_output_table.has(f"T_{c}_c") else np.full(t.shape, np.nan))
                    _put16(data, sig.start // 8, _raw16(x, float(sig.scale), float(sig.offset)))
                add(f"RIG_TC_{k // 4 + 1}", 8 + k // 4, t, (msg.frame_id & ~0xFF) | src["rig"], data)

    t_all = np.concatenate([p[0] for p in parts])
    t_all = np.round((t_all - t0 + start_timestamp_s) * 1e6) / 1e6  # whole microseconds, like candump -L
    order = np.concatenate([np.full(p[0].size, p[3], dtype=np.int16) for p in parts])
    ids = np.concatenate([p[1] for p in parts]).astype(np.uint32)
    data = np.concatenate([p[2] for p in parts])
    idx = np.lexsort((order, t_all))
    return SynthFrames(t_all[idx], ids[idx], data[idx]), counts


#: formats by suffix (python-can's Logger choice); .log is written by the fast formatter
SUFFIXES = (".log", ".asc", ".blf")


def write_frames(frames: SynthFrames, path: str | os.PathLike, channel: str = "can0") -> Path:
    """Write frames as a CAN log chosen by suffix: ``.log`` (candump -L), ``.asc``, ``.blf``."""
    target = Path(path)
    suffix = target.suffix.lower()
    if suffix not in SUFFIXES:
        raise InputError(f"{target}: unknown CAN log suffix {suffix!r}; use .log (candump -L), .asc or .blf")
    if not (target.parent if str(target.parent) else Path(".")).is_dir():
        raise InputError(f"{target}: the directory {target.parent} does not exist")
    if suffix == ".log":
        _write_candump(frames, target, channel)
        return target
    import can
    with can.Logger(target) as writer:
        for msg in frames.messages(channel=channel):
            writer.on_message_received(msg)
    return target


def _write_candump(frames: SynthFrames, target: Path, channel: str, chunk: int = 65536) -> None:
    """candump -L lines exactly as python-can's CanutilsLogWriter writes them (extended 8-byte data, " R")."""
    hexdigits = np.frombuffer(b"0123456789ABCDEF", dtype=np.uint8)
    with open(target, "w", encoding="ascii", newline="\n") as fh:
        last = None
        for i in range(0, len(frames), chunk):
            ts = frames.timestamp_s[i:i + chunk]
            if last is None:
                last = float(ts[0]) if ts.size else 0.0
            ts = np.maximum.accumulate(np.maximum(ts, last))  # CanutilsLogWriter never writes a time backwards
            last = float(ts[-1]) if ts.size else last
            ids = frames.can_id[i:i + chunk]
            d = frames.data[i:i + chunk]
            hexd = np.empty((d.shape[0], 16), dtype=np.uint8)
            hexd[:, 0::2] = hexdigits[d >> 4]
            hexd[:, 1::2] = hexdigits[d & 0xF]
            hex_rows = hexd.view("S16").ravel()
            lines = [f"({t:f}) {channel} {cid:08X}#{h.decode()} R\n"
                     for t, cid, h in zip(ts.tolist(), ids.tolist(), hex_rows.tolist())]
            fh.write("".join(lines))


def write_can_log(input_table, plant_output_table, path: str | os.PathLike, params=None, *, config=None,
                  ref_torque_nm: float | None = None, retarder_ref_torque_nm: float | None = None, seed: int = 0,
                  sample_delay_s: float = 0.05, start_timestamp_s: float = 0.0, rig: bool = True,
                  channel: str = "can0") -> LogSummary:
    """Write the J1939 traffic of a drive cycle and the plant's true temperatures as a CAN log (module doc).

    ``params`` (the gearbox parameters) is accepted for symmetry with the plant and not needed: every value comes
    from the two tables and the config's ``[can]`` section. Returns the path, frame count, duration and a count per
    message.
    """
    frames, counts = synth_frames(input_table, plant_output_table, config=config, ref_torque_nm=ref_torque_nm,
                                  retarder_ref_torque_nm=retarder_ref_torque_nm, seed=seed,
                                  sample_delay_s=sample_delay_s, start_timestamp_s=start_timestamp_s, rig=rig)
    target = write_frames(frames, path, channel)
    duration = float(frames.timestamp_s[-1] - frames.timestamp_s[0]) if len(frames) else 0.0
    return LogSummary(target, len(frames), duration, counts)


def _bench(argv=None) -> None:  # pragma: no cover - a benchmark, run by benchmarks/bench_can.py too
    import time
    from tools.cycles.named import get_cycle
    from tools.runtable import RunTable
    table = get_cycle("long_haul")
    t = np.asarray(table["time_s"])
    reps = int(np.ceil(10800.0 / (t[-1] + 0.1)))
    big = RunTable({c: np.concatenate([np.asarray(table[c]) + (k * (t[-1] + 0.1) if c == "time_s" else 0.0)
                                       for k in range(reps)]) for c in table.columns})
    fake = RunTable({"time_s": big["time_s"][::10], **{f"T_{c}_c": np.full(big.n // 10 + (big.n % 10 > 0), 90.0)
                                                       for c in PUBLISHED}})
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        t_0 = time.perf_counter()
        s = write_can_log(big, fake, Path(d) / "big.log")
        dt = time.perf_counter() - t_0
        print(f"logsynth: {s.frames} frames, {s.duration_s / 3600:.2f} h of traffic in {dt:.1f} s "
              f"({s.frames / dt / 1e3:.0f} k frames/s)")


if __name__ == "__main__":  # pragma: no cover
    _bench()
