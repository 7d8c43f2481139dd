"""J1939 log synthesis: a drive cycle and the plant's answer to it, as the CAN traffic a truck and a rig would record.

:func:`write_can_log` turns a drive cycle (the plant's input run table) and the reference plant's output run table
into J1939 frames at the rates a truck sends them, plus the plant's true component temperatures as rig thermocouple
frames, and writes them as a CAN log (``.log`` candump -L, ``.asc``, ``.blf`` by suffix). ``gearbox-vsensor simulate
--can-log RUN.log`` calls it; ``gearbox-vsensor replay RUN.log`` reads such a log back through the onboard sensor.
:func:`synth_frames` gives the same frames as arrays (for the HIL plant, tools/can/hil.py). docs/can.md, "Log
synthesis", has the messages, their periods, sources and content, the timing and the sample delay.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from can_dbc import dbc
from can_dbc.j1939 import (
    EC1_PGN,
    EC1_REF_TORQUE_BYTE0,
    RAW8_DATA_MAX,
    RAW8_NOT_AVAILABLE,
    RAW16_DATA_MAX,
    RAW16_NOT_AVAILABLE,
    RC_PGN,
    RC_REF_TORQUE_BYTE0,
    TP_BAM_CONTROL,
    TP_DT_DATA_BYTES,
)
from firmware_model.errors import InputError, ParameterError

#: default engine reference torque (SPN 544) sent in EC1 when the config has none [Nm]; assumed, a 13 l truck engine
DEFAULT_REF_TORQUE_NM = 3000.0
#: default retarder reference torque used to express the cycle's retarder torque in percent [Nm]; assumed
DEFAULT_RETARDER_REF_TORQUE_NM = 3500.0
#: EC1 transfer: size (J1939-71 EC1, 39 bytes as on the utulsa truck), packets, period, TP.DT spacing
EC1_SIZE_BYTES = 39
EC1_PACKETS = 6
EC1_PERIOD_S = 5.0
TP_DT_SPACING_S = 0.050
#: the largest engine reference torque SPN 544 carries [Nm]
REF_TORQUE_MAX_NM = 64255
#: default J1939 source addresses (docs/can.md "Inputs"); the rig logger's is the DBC's
DEFAULT_SOURCES = {"engine": 0x00, "transmission": 0x03, "retarder": 0x10, "ambient": 0x00}
#: EEC1 bytes the DBC does not describe: engine torque mode (low idle governor / no request; bits 5-8 reserved),
#: driver's demand percent torque (byte 2, sent equal to the actual), source address of the controlling device
EEC1_TORQUE_MODE = 0xF0
EEC1_DEMAND_BYTE0 = 1
EEC1_CONTROLLER_SA_BYTE0 = 5
#: ETC2 byte 1 selected gear (not in the DBC; sent equal to the current gear); ERC1 byte 1 retarder torque mode
ETC2_SELECTED_GEAR_BYTE0 = 0
ERC1_TORQUE_MODE = 0xF0
#: percent torque range of SPN 513/520
PCT_RANGE = (-125, 125)
#: EEC1 period: 20 ms at idle (600 rpm) down to 10 ms at 2100 rpm, on a 10 ms grid
EEC1_PERIOD_IDLE_S, EEC1_PERIOD_FAST_S = 0.020, 0.010
EEC1_IDLE_RPM, EEC1_FAST_RPM = 600.0, 2100.0
EEC1_GRID_S = 0.01


class Schedule(NamedTuple):
    """A periodic message: its period and its phase inside each slot of that period [s]."""

    period_s: float
    phase_s: float


#: message -> schedule; EEC1 has its own rpm-dependent schedule, EC1 its BAM
SCHEDULES = {
    "ETC2": Schedule(0.1, 0.050),
    "ERC1": Schedule(0.1, 0.055),
    "RIG": Schedule(0.1, 0.075),
    "TRF1": Schedule(1.0, 0.045),
    "ET1": Schedule(1.0, 0.050),
    "AMB": Schedule(1.0, 0.060),
    "CCVS1": Schedule(1.0, 0.040),
}
_PERIODIC_JITTER_S = 0.001
_EEC1_JITTER_S = 0.0003
#: EC1 BAM: TP.CM at this phase of each 5 s period; the last of its 6 TP.DT completes 300 ms later (phase 0.35)
_EC1_PHASE_S = 0.050
#: RC (retarder configuration) by BAM: 19 bytes as real retarders send it, in 3 packets, every 5 s at this phase
#: (after EC1's: the first completes 0.6 s into the log)
RC_SIZE_BYTES = 19
RC_PACKETS = 3
_RC_PHASE_S = 0.450
#: order of the messages at equal timestamps (RIG_TC_k: RIG_ORDER + k - 1)
_ORDER = {"EEC1": 0, "ETC2": 1, "TRF1": 2, "ET1": 3, "AMB": 4, "CCVS1": 5, "ERC1": 6, "EC1": 7, "RC": 7}
RIG_ORDER = 8


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
            yield can.Message(
                timestamp=ts, arbitration_id=cid, is_extended_id=True, data=row.tobytes(), channel=channel, check=False
            )


class SynthResult(NamedTuple):
    """The synthesized frames and the number of frames per message."""

    frames: SynthFrames
    counts: dict


@dataclass
class LogSummary:
    path: Path
    frames: int
    duration_s: float
    per_message: dict


class _Part(NamedTuple):
    """The frames of one message: times [s], identifiers, payloads, and its order at equal times."""

    timestamp_s: np.ndarray
    can_id: np.ndarray
    data: np.ndarray
    order: int


#: the group of _sources that sends each input message unless the config sets the message's own address
MESSAGE_GROUPS = {
    "EEC1": "engine",
    "EC1": "engine",
    "ETC2": "transmission",
    "TRF1": "transmission",
    "ET1": "coolant",
    "AMB": "ambient",
    "CCVS1": "vehicle_speed",
    "ERC1": "retarder",
    "RC": "retarder",
}


def _sources(config) -> dict:
    """Sender -> source address: the groups (engine, transmission, ..., rig) and each input message by name, from
    the config's [can] keys and its [can.source_address] table (firmware_model.service.options.source_addresses)."""
    from firmware_model.service.options import source_addresses

    src = {**DEFAULT_SOURCES, "rig": dbc.default_source(dbc.numbered_messages("RIG_TC_")[0])}
    can_cfg = getattr(config, "can", None) or {}
    try:
        per_message, _ = source_addresses(can_cfg)
    except ParameterError as e:
        raise ParameterError(f"config {e}") from None
    for key, name in (
        ("engine_source_address", "engine"),
        ("transmission_source_address", "transmission"),
        ("retarder_source_address", "retarder"),
        ("ambient_source_address", "ambient"),
        ("vehicle_speed_source_address", "vehicle_speed"),
        ("coolant_source_address", "coolant"),
    ):
        if key in can_cfg:
            src[name] = can_cfg[key]
    for key, name in (
        ("ambient_source_address", "ambient"),
        ("vehicle_speed_source_address", "vehicle_speed"),
        ("coolant_source_address", "coolant"),
    ):
        if key not in can_cfg:
            src[name] = src["engine"]  # AMB, CCVS1 and ET1 come from the engine unless configured otherwise
    for message, group in MESSAGE_GROUPS.items():
        src[message] = per_message.get(message, src[group])
    return src


def _positive(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
        raise ParameterError(f"{name} = {value!r} must be a positive number of Nm")
    return float(value)


def _zoh(t_table_s: np.ndarray, values: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Zero-order hold of a table column at times t_s (before the first sample: the first sample)."""
    idx = np.searchsorted(t_table_s, t_s, side="right") - 1
    return values[np.clip(idx, 0, t_table_s.size - 1)]


def _lin(t_table_s: np.ndarray, values: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Linear interpolation ignoring NaN samples; all NaN -> NaN."""
    ok = np.isfinite(values)
    if not ok.any():
        return np.full(t_s.shape, np.nan)
    return np.interp(t_s, t_table_s[ok], values[ok])


def _raw8(x: np.ndarray, scale: float, offset: float) -> np.ndarray:
    """J1939 8-bit raw: NaN -> 0xFF not available, else rounded and clamped to the data range 0..250."""
    raw = np.rint((np.nan_to_num(x, nan=0.0) - offset) / scale)
    raw = np.clip(raw, 0, RAW8_DATA_MAX).astype(np.uint8)
    raw[~np.isfinite(x)] = RAW8_NOT_AVAILABLE
    return raw


def _raw16(x: np.ndarray, scale: float, offset: float) -> np.ndarray:
    """J1939 16-bit raw: NaN -> 0xFFFF not available, else rounded and clamped to 0..0xFAFF."""
    raw = np.rint((np.nan_to_num(x, nan=0.0) - offset) / scale)
    raw = np.clip(raw, 0, RAW16_DATA_MAX).astype(np.uint16)
    raw[~np.isfinite(x)] = RAW16_NOT_AVAILABLE
    return raw


def _put16(data: np.ndarray, byte0: int, raw: np.ndarray) -> None:
    data[:, byte0] = raw & 0xFF
    data[:, byte0 + 1] = raw >> 8


def _put(data: np.ndarray, message: str, signal: str, x: np.ndarray, db=None) -> np.ndarray:
    """Quantise ``x`` as the DBC's byte-aligned 8- or 16-bit ``message.signal`` into ``data``; returns the raw.
    ``db``: the gearbox's DBC (can_dbc.dbc.CanDatabase; None: the shipped one)."""
    sig = (db or dbc).message(message).get_signal_by_name(signal)
    if sig.length == 8:
        raw = _raw8(x, float(sig.scale), float(sig.offset))
        data[:, sig.start // 8] = raw
        return raw
    raw = _raw16(x, float(sig.scale), float(sig.offset))
    _put16(data, sig.start // 8, raw)
    return raw


def _empty(n: int) -> np.ndarray:
    """n payloads with every byte 0xFF (J1939: not available / unused bits 1)."""
    return np.full((n, 8), 0xFF, dtype=np.uint8)


def _slots(t0_s: float, t1_s: float, schedule: Schedule, rng: np.random.Generator) -> np.ndarray:
    """Frame times of a periodic message from t0_s to t1_s, with +-1 ms of uniform jitter."""
    n = int(np.floor((t1_s - t0_s - schedule.phase_s) / schedule.period_s)) + 1
    if n <= 0:
        return np.empty(0)
    t_s = t0_s + schedule.phase_s + schedule.period_s * np.arange(n)
    return t_s + rng.uniform(-_PERIODIC_JITTER_S, _PERIODIC_JITTER_S, n)


def _eec1_times(
    t_table_s: np.ndarray, speed_rpm: np.ndarray, t0_s: float, t1_s: float, rng: np.random.Generator
) -> np.ndarray:
    """EEC1 every 20 ms at idle (600 rpm) down to 10 ms at 2100 rpm, with gaussian jitter; first frame at t0_s."""
    # the period as a function of time on a 10 ms grid, then the frame times by accumulating it
    grid_s = np.arange(t0_s, t1_s + EEC1_GRID_S, EEC1_GRID_S)
    grid_rpm = _zoh(t_table_s, speed_rpm, grid_s)
    period_s = np.clip(
        EEC1_PERIOD_IDLE_S
        - (grid_rpm - EEC1_IDLE_RPM) / (EEC1_FAST_RPM - EEC1_IDLE_RPM) * (EEC1_PERIOD_IDLE_S - EEC1_PERIOD_FAST_S),
        EEC1_PERIOD_FAST_S,
        EEC1_PERIOD_IDLE_S,
    )
    # cumulative "phase" in frames: integral of 1/period; frame k is where the phase crosses k
    phase = np.concatenate([[0.0], np.cumsum(EEC1_GRID_S / period_s[:-1])])
    k = np.arange(0, int(phase[-1]) + 1)
    t_s = np.interp(k, phase, grid_s)
    t_s[1:] += rng.normal(0.0, _EEC1_JITTER_S, t_s.size - 1).clip(-3 * _EEC1_JITTER_S, 3 * _EEC1_JITTER_S)
    return np.sort(t_s[t_s <= t1_s])


class _Synth:
    """The frames of one drive cycle, message by message (the module doc); ``parts`` and ``counts`` fill up. The
    random generator is drawn from in a fixed order (EEC1, ETC2, TRF1, ET1, AMB, CCVS1, ERC1, RIG): the same seed
    gives the same frames."""

    def __init__(self, input_table, plant_output_table, src: dict, seed: int, sample_delay_s: float, db=None) -> None:
        self.db = db or dbc.shipped()  # the gearbox's DBC: its rig messages carry its components
        self.inputs = input_table
        self.plant = plant_output_table
        self.src = src
        self.sample_delay_s = sample_delay_s
        self.t_in_s = np.asarray(input_table["time_s"], dtype=float)
        self.t0_s, self.t1_s = float(self.t_in_s[0]), float(self.t_in_s[-1])
        self.t_plant_s = None if plant_output_table is None else np.asarray(plant_output_table["time_s"], float)
        self.rng = np.random.default_rng(seed)
        self.parts: list[_Part] = []
        self.counts: dict[str, int] = {}

    def add(self, name: str, order: int, t_s: np.ndarray, can_id, data: np.ndarray) -> None:
        ids = np.broadcast_to(np.asarray(can_id, dtype=np.uint32), t_s.shape)
        self.parts.append(_Part(t_s, ids, data, order))
        self.counts[name] = self.counts.get(name, 0) + int(t_s.size)

    def column(self, name: str) -> np.ndarray:
        return np.asarray(self.inputs[name], dtype=float)

    def at(self, name: str, t_s: np.ndarray) -> np.ndarray:
        """The cycle's column ``name`` sample_delay_s before each time, held between samples."""
        return _zoh(self.t_in_s, self.column(name), t_s - self.sample_delay_s)

    def slots(self, name: str) -> np.ndarray:
        return _slots(self.t0_s, self.t1_s, SCHEDULES[name], self.rng)

    def eec1(self, ref_torque_nm: float) -> None:
        """EEC1: actual percent torque = torque / reference x 100 (rounded to 1 %), engine speed."""
        t_s = _eec1_times(self.t_in_s, self.column("engine_speed_rpm"), self.t0_s, self.t1_s, self.rng)
        pct = np.clip(np.rint(self.at("engine_torque_nm", t_s) / ref_torque_nm * 100.0), *PCT_RANGE)
        data = _empty(t_s.size)
        data[:, 0] = EEC1_TORQUE_MODE
        data[:, EEC1_DEMAND_BYTE0] = _put(data, "EEC1", "ActualEngPercentTorque", pct)
        speed_max_rpm = float(dbc.message("EEC1").get_signal_by_name("EngSpeed").maximum)
        _put(data, "EEC1", "EngSpeed", np.clip(self.at("engine_speed_rpm", t_s), 0.0, speed_max_rpm))
        data[:, EEC1_CONTROLLER_SA_BYTE0] = self.src["EEC1"]
        self.add("EEC1", _ORDER["EEC1"], t_s, dbc.message_id("EEC1", self.src["EEC1"]), data)

    def etc2(self) -> None:
        """ETC2: current gear (and the selected gear, equal)."""
        t_s = self.slots("ETC2")
        data = _empty(t_s.size)
        data[:, ETC2_SELECTED_GEAR_BYTE0] = _put(data, "ETC2", "TransCurrentGear", self.at("gear", t_s))
        self.add("ETC2", _ORDER["ETC2"], t_s, dbc.message_id("ETC2", self.src["ETC2"]), data)

    def trf1(self) -> None:
        """TRF1: oil temperature from the plant's sensor (oil_temp_c, else its sump T_oil_c), else the cycle's."""
        t_s = self.slots("TRF1")
        oil_c = None
        if self.plant is not None:
            for name in ("oil_temp_c", "T_oil_c"):
                if self.plant.has(name):
                    oil_c = _lin(self.t_plant_s, np.asarray(self.plant[name], float), t_s - self.sample_delay_s)
                    break
        if oil_c is None and self.inputs.has("oil_temp_c"):
            oil_c = self.at("oil_temp_c", t_s)
        if oil_c is not None:
            data = _empty(t_s.size)
            _put(data, "TRF1", "TransOilTemp", oil_c)
            if self.inputs.has("oil_level_pct"):  # SPN 124, byte 2; else 0xFF (not available)
                _put(data, "TRF1", "TransOilLevel", self.at("oil_level_pct", t_s))
            self.add("TRF1", _ORDER["TRF1"], t_s, dbc.message_id("TRF1", self.src["TRF1"]), data)

    def engine_1s(self) -> None:
        """ET1 coolant, AMB ambient, CCVS1 vehicle speed, each if the cycle has its column."""
        for name, col, signal in (
            ("ET1", "coolant_temp_c", "EngCoolantTemp"),
            ("AMB", "ambient_temp_c", "AmbientAirTemp"),
            ("CCVS1", "vehicle_speed_kmh", "WheelBasedVehicleSpeed"),
        ):
            if not self.inputs.has(col):
                continue
            t_s = self.slots(name)
            x = self.at(col, t_s)
            data = _empty(t_s.size)
            _put(data, name, signal, np.clip(x, 0.0, None) if name == "CCVS1" else x)
            self.add(name, _ORDER[name], t_s, dbc.message_id(name, self.src[name]), data)

    def erc1(self, retarder_ref_torque_nm: float) -> None:
        """ERC1: actual retarder percent torque; braking is negative in J1939."""
        if not self.inputs.has("retarder_torque_nm"):
            return
        t_s = self.slots("ERC1")
        x = np.nan_to_num(self.at("retarder_torque_nm", t_s), nan=0.0)
        pct = np.clip(np.rint(-np.abs(x) / retarder_ref_torque_nm * 100.0), *PCT_RANGE)
        data = _empty(t_s.size)
        data[:, 0] = ERC1_TORQUE_MODE
        _put(data, "ERC1", "ActualRetarderPercentTorque", pct)
        self.add("ERC1", _ORDER["ERC1"], t_s, dbc.message_id("ERC1", self.src["ERC1"]), data)

    def ec1(self, ref_torque_nm: float) -> None:
        """EC1 by TP.BAM every 5 s: TP.CM BAM to global, then 6 TP.DT 50 ms apart; SPN 544 in bytes 20-21."""
        self.bam(
            "EC1",
            EC1_PGN,
            EC1_SIZE_BYTES,
            EC1_PACKETS,
            EC1_REF_TORQUE_BYTE0,
            ref_torque_nm,
            _EC1_PHASE_S,
            self.src["EC1"],
        )

    def rc(self, retarder_ref_torque_nm: float) -> None:
        """RC by TP.BAM every 5 s from the retarder, with ERC1 only: SPN 556 in bytes 17-18."""
        if self.inputs.has("retarder_torque_nm"):
            self.bam(
                "RC",
                RC_PGN,
                RC_SIZE_BYTES,
                RC_PACKETS,
                RC_REF_TORQUE_BYTE0,
                retarder_ref_torque_nm,
                _RC_PHASE_S,
                self.src["RC"],
            )

    def bam(
        self, name: str, pgn: int, size: int, packets: int, byte0: int, ref_torque_nm: float, phase_s: float, sa: int
    ) -> None:
        """A reference torque (1 Nm/bit at ``byte0``; every other byte 0xFF) by TP.BAM every EC1_PERIOD_S: TP.CM BAM
        to global at ``phase_s``, then ``packets`` TP.DT 50 ms apart."""
        n_bam = int(np.floor((self.t1_s - self.t0_s - phase_s) / EC1_PERIOD_S)) + 1
        if n_bam <= 0:
            return
        payload = np.full(packets * TP_DT_DATA_BYTES, 0xFF, dtype=np.uint8)
        payload[byte0] = int(round(ref_torque_nm)) & 0xFF
        payload[byte0 + 1] = int(round(ref_torque_nm)) >> 8
        cm = np.array(
            [TP_BAM_CONTROL, size & 0xFF, size >> 8, packets, 0xFF, pgn & 0xFF, (pgn >> 8) & 0xFF, pgn >> 16],
            dtype=np.uint8,
        )
        start_s = self.t0_s + phase_s + EC1_PERIOD_S * np.arange(n_bam)
        n = TP_DT_DATA_BYTES
        rows = [cm] + [np.concatenate([[k + 1], payload[n * k : n * k + n]]).astype(np.uint8) for k in range(packets)]
        t_s = (start_s[:, None] + TP_DT_SPACING_S * np.arange(packets + 1)[None, :]).ravel()
        ids = np.tile(
            np.array([dbc.message_id("TP_CM", sa)] + [dbc.message_id("TP_DT", sa)] * packets, dtype=np.uint32), n_bam
        )
        data = np.tile(np.stack(rows), (n_bam, 1))
        keep = t_s <= self.t1_s + packets * TP_DT_SPACING_S  # a transfer started inside the cycle is finished
        self.add(name, _ORDER[name], t_s[keep], ids[keep], data[keep])

    def rig(self) -> None:
        """RIG_TC_<k> (the DBC's rig messages): the plant's true temperatures of the components they carry, linearly
        interpolated."""
        db = self.db
        messages = db.numbered_messages("RIG_TC_")
        carried = [c for name in messages for c, _, _ in db.component_signals(name, 16)]  # the DBC's components
        if self.plant is None or not any(self.plant.has(f"T_{c}_c") for c in carried):
            return
        t_s = self.slots("RIG")
        for k, name in enumerate(messages):
            data = _empty(t_s.size)
            for component, signal, _ in db.component_signals(name, 16):
                col = f"T_{component}_c"
                x = (
                    _lin(self.t_plant_s, np.asarray(self.plant[col], float), t_s - self.sample_delay_s)
                    if self.plant.has(col)
                    else np.full(t_s.shape, np.nan)
                )
                _put(data, name, signal, x, db)
            self.add(name, RIG_ORDER + k, t_s, db.message_id(name, self.src["rig"]), data)

    def frames(self, start_timestamp_s: float) -> SynthFrames:
        """Every part merged and sorted by time (then message order), in whole microseconds from
        ``start_timestamp_s``."""
        parts = self.parts
        t_all = np.concatenate([p.timestamp_s for p in parts])
        t_all = np.round((t_all - self.t0_s + start_timestamp_s) * 1e6) / 1e6  # whole microseconds, like candump -L
        order = np.concatenate([np.full(p.timestamp_s.size, p.order, dtype=np.int16) for p in parts])
        ids = np.concatenate([p.can_id for p in parts]).astype(np.uint32)
        data = np.concatenate([p.data for p in parts])
        idx = np.lexsort((order, t_all))
        return SynthFrames(t_all[idx], ids[idx], data[idx])


def _reference_torques_nm(config, ref_torque_nm, retarder_ref_torque_nm) -> tuple[float, float]:
    """The engine and retarder reference torques: given, else the config's ``[can]``, else the defaults."""
    can_cfg = getattr(config, "can", None) or {}
    if ref_torque_nm is None:
        ref_torque_nm = can_cfg.get("engine_reference_torque_nm", DEFAULT_REF_TORQUE_NM)
    ref = _positive("engine reference torque", ref_torque_nm)
    if ref > REF_TORQUE_MAX_NM:
        raise ParameterError(f"engine reference torque = {ref:g} Nm is above the J1939 SPN 544 range 0..64255 Nm")
    if retarder_ref_torque_nm is None:
        retarder_ref_torque_nm = can_cfg.get("retarder_reference_torque_nm", DEFAULT_RETARDER_REF_TORQUE_NM)
    return ref, _positive("retarder reference torque", retarder_ref_torque_nm)


def reference_torques_nm(input_table, config=None, ref_torque_nm=None, retarder_ref_torque_nm=None):
    """The engine and retarder reference torques a log of ``input_table`` sends (:func:`_reference_for`); the
    checks run before any plant run (simulate --can-log)."""
    given = ref_torque_nm is not None or "engine_reference_torque_nm" in (getattr(config, "can", None) or {})
    ref_nm, retarder_ref_nm = _reference_torques_nm(config, ref_torque_nm, retarder_ref_torque_nm)
    _check_cycle(input_table)
    return _reference_for(input_table, ref_nm, given), retarder_ref_nm


def _reference_for(input_table, ref_nm: float, given: bool) -> float:
    """The engine reference torque the log sends: ``ref_nm``, or (not ``given``) the least whole N m under which
    the cycle's torque stays within EEC1's 125 %; InputError where EEC1 cannot carry the torque (it clipped it)."""
    torque = np.asarray(input_table["engine_torque_nm"], dtype=float)
    torque = torque[np.isfinite(torque)]  # (a non-finite row is the plant's to refuse, with its row)
    peak = float(np.max(np.abs(torque))) if torque.size else 0.0
    top = PCT_RANGE[1] / 100.0
    if peak <= top * ref_nm:
        return ref_nm
    if peak > top * REF_TORQUE_MAX_NM:
        raise InputError(
            f"the cycle's torque reaches {peak:.4g} N m, past the most a J1939 EEC1 frame carries ({top:.0%} of the "
            f"largest reference torque, {REF_TORQUE_MAX_NM} N m): a CAN log cannot carry this drive; use its run table"
        )
    if given:
        raise InputError(
            f"the cycle's torque reaches {peak:.4g} N m, past {top:.0%} of the engine reference torque {ref_nm:g} N m "
            f"that EEC1 carries (it would be clipped): raise [can] engine_reference_torque_nm to at least "
            f"{math.ceil(peak / top):d}"
        )
    return float(math.ceil(peak / top))


def _check_cycle(input_table) -> None:
    for col in ("time_s", "engine_speed_rpm", "engine_torque_nm", "gear"):
        if not input_table.has(col):
            raise InputError(f'the drive cycle has no column "{col}"; a J1939 log needs it')
    t_in = np.asarray(input_table["time_s"], dtype=float)
    if t_in.size < 2 or not np.all(np.diff(t_in) > 0):
        raise InputError("the drive cycle needs at least two samples with strictly increasing time_s")


def rig_dbc(params):
    """The DBC whose rig messages carry the published components of the gearbox ``params`` describe."""
    from firmware_model.description import description_of
    from firmware_model.onboard.reduce import published_ids

    return dbc.for_components(published_ids(description_of(params)))


def synth_frames(
    input_table,
    plant_output_table=None,
    *,
    config=None,
    ref_torque_nm: float | None = None,
    retarder_ref_torque_nm: float | None = None,
    seed: int = 0,
    sample_delay_s: float = 0.05,
    start_timestamp_s: float = 0.0,
    rig: bool = True,
    db=None,
) -> SynthResult:
    """The J1939 and rig frames of a drive cycle (see the module doc) and a count per message; ``db``: the gearbox's
    DBC (can_dbc.dbc.for_components; None: the shipped GRS905 one), whose RIG_TC messages carry its components.

    ``input_table``: the plant's input run table (time_s, engine_speed_rpm, engine_torque_nm, gear, optional
    inputs). ``plant_output_table``: the plant's output (T_<id>_c columns for the rig frames, oil_temp_c for TRF1);
    None sends no rig frames. ``ref_torque_nm`` / ``retarder_ref_torque_nm``: default from the config's ``[can]``
    (engine_reference_torque_nm, retarder_reference_torque_nm), else 3000 Nm / 3500 Nm.
    """
    ref_nm, retarder_ref_nm = _reference_torques_nm(config, ref_torque_nm, retarder_ref_torque_nm)
    if not 0.0 <= sample_delay_s < 1.0:
        raise InputError(f"sample_delay_s = {sample_delay_s!r} must be in 0..1 s")
    src = _sources(config)  # (the configuration's sentences before the cycle's)
    ref_nm, retarder_ref_nm = reference_torques_nm(input_table, config, ref_torque_nm, retarder_ref_torque_nm)
    synth = _Synth(input_table, plant_output_table, src, seed, sample_delay_s, db)
    synth.eec1(ref_nm)
    synth.etc2()
    synth.trf1()
    synth.engine_1s()
    synth.erc1(retarder_ref_nm)
    synth.ec1(ref_nm)
    synth.rc(retarder_ref_nm)
    if rig:
        synth.rig()
    return SynthResult(synth.frames(start_timestamp_s), synth.counts)


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
        last_s = None
        for i in range(0, len(frames), chunk):
            t_s = frames.timestamp_s[i : i + chunk]
            if last_s is None:
                last_s = float(t_s[0]) if t_s.size else 0.0
            t_s = np.maximum.accumulate(np.maximum(t_s, last_s))  # CanutilsLogWriter never writes a time backwards
            last_s = float(t_s[-1]) if t_s.size else last_s
            ids = frames.can_id[i : i + chunk]
            d = frames.data[i : i + chunk]
            hexd = np.empty((d.shape[0], 16), dtype=np.uint8)
            hexd[:, 0::2] = hexdigits[d >> 4]
            hexd[:, 1::2] = hexdigits[d & 0xF]
            hex_rows = hexd.view("S16").ravel()
            lines = [
                f"({t:f}) {channel} {cid:08X}#{h.decode()} R\n"
                for t, cid, h in zip(t_s.tolist(), ids.tolist(), hex_rows.tolist())
            ]
            fh.write("".join(lines))


def write_can_log(
    input_table,
    plant_output_table,
    path: str | os.PathLike,
    params=None,
    *,
    config=None,
    ref_torque_nm: float | None = None,
    retarder_ref_torque_nm: float | None = None,
    seed: int = 0,
    sample_delay_s: float = 0.05,
    start_timestamp_s: float = 0.0,
    rig: bool = True,
    channel: str = "can0",
) -> LogSummary:
    """Write the J1939 traffic of a drive cycle and the plant's true temperatures as a CAN log (module doc).

    ``params`` (the gearbox parameters): its DBC's rig messages carry its published components (None: the GRS905's);
    every other value comes from the two tables and the config's ``[can]`` section. Returns the path, frame count,
    duration and a count per message.
    """
    db = None if params is None else rig_dbc(params)
    frames, counts = synth_frames(
        input_table,
        plant_output_table,
        config=config,
        ref_torque_nm=ref_torque_nm,
        retarder_ref_torque_nm=retarder_ref_torque_nm,
        seed=seed,
        sample_delay_s=sample_delay_s,
        start_timestamp_s=start_timestamp_s,
        rig=rig,
        db=db,
    )
    target = write_frames(frames, path, channel)
    duration = float(frames.timestamp_s[-1] - frames.timestamp_s[0]) if len(frames) else 0.0
    return LogSummary(target, len(frames), duration, counts)


def _bench(argv=None) -> None:  # pragma: no cover - a benchmark, run by benchmarks/bench_can.py too
    import time

    from tools.cycles.named import get_cycle
    from tools.published import ids
    from tools.runtable import RunTable

    table = get_cycle("long_haul")
    t = np.asarray(table["time_s"])
    reps = int(np.ceil(10800.0 / (t[-1] + 0.1)))
    big = RunTable(
        {
            c: np.concatenate(
                [np.asarray(table[c]) + (k * (t[-1] + 0.1) if c == "time_s" else 0.0) for k in range(reps)]
            )
            for c in table.columns
        }
    )
    fake = RunTable(
        {
            "time_s": big["time_s"][::10],
            **{f"T_{c}_c": np.full(big.n // 10 + (big.n % 10 > 0), 90.0) for c in ids()},
        }
    )
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        t_0 = time.perf_counter()
        s = write_can_log(big, fake, Path(d) / "big.log")
        dt = time.perf_counter() - t_0
        print(
            f"logsynth: {s.frames} frames, {s.duration_s / 3600:.2f} h of traffic in {dt:.1f} s "
            f"({s.frames / dt / 1e3:.0f} k frames/s)"
        )


if __name__ == "__main__":  # pragma: no cover
    _bench()
