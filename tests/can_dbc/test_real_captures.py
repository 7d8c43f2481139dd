"""The decoder on real truck captures (candump -L; where: tests/data_paths.py): the ranges their README lists."""

from __future__ import annotations

import functools
from collections import defaultdict

import can
import pytest

from can_dbc.adapter import REJECT_REASONS, J1939Decoder, pgn_of
from tests.data_paths import SKIP_REASON, real_capture_dir

DATA = real_capture_dir()
FILES = ("normal", "tsc1", "fuzz_1ms_ID_and_Data", "utulsa_logger2_drive")

pytestmark = pytest.mark.skipif(DATA is None, reason=SKIP_REASON)

# README.md "What a correct decoder finds": (low, high) as printed there; the tolerance is half a unit of the
# last printed digit (integers 0.5, one decimal 0.05). None: the file has no valid value of that signal.
INT, ONE_DECIMAL = 0.5, 0.05 + 1e-9
EXPECTED = {
    "normal": {
        "engine_speed_rpm": (1147, 1786, INT),
        "engine_torque_pct": (3, 45, INT),
        "gear": (2, 4, INT),
        "oil_temp_c": (77.3, 78.2, ONE_DECIMAL),
        "ambient_temp_c": (33.1, 33.1, ONE_DECIMAL),
        "vehicle_speed_kmh": (23.2, 54.9, ONE_DECIMAL),
        "coolant_temp_c": (92, 93, INT),
    },
    "tsc1": {
        "engine_speed_rpm": (711, 1700, INT),
        "engine_torque_pct": (0, 85, INT),
        "gear": (1, 4, INT),
        "oil_temp_c": (76.7, 77.6, ONE_DECIMAL),
        "ambient_temp_c": (35.4, 35.6, ONE_DECIMAL),
        "vehicle_speed_kmh": (14.1, 47.5, ONE_DECIMAL),
        "coolant_temp_c": (89, 93, INT),
    },
    "fuzz_1ms_ID_and_Data": {
        "engine_speed_rpm": (719, 730, INT),
        "engine_torque_pct": (5, 7, INT),
        "gear": (0, 0, INT),
        "oil_temp_c": (76.3, 77.3, ONE_DECIMAL),
        "ambient_temp_c": (34.5, 34.6, ONE_DECIMAL),
        "vehicle_speed_kmh": (0, 0, INT),
        "coolant_temp_c": (90, 90, INT),
    },
    "utulsa_logger2_drive": {
        "engine_speed_rpm": (409, 1859, INT),
        "engine_torque_pct": (0, 73, INT),
        "gear": None,
        "oil_temp_c": None,
        "ambient_temp_c": (21.4, 22.5, ONE_DECIMAL),
        "vehicle_speed_kmh": (0, 52.3, ONE_DECIMAL),
        "coolant_temp_c": (73, 79, INT),
    },
}
EC1_NM = {"normal": 1109.0, "tsc1": 1109.0, "fuzz_1ms_ID_and_Data": 1109.0, "utulsa_logger2_drive": 2457.0}


def read(name):
    return list(can.LogReader(DATA / f"{name}.candump.log"))


@functools.cache
def decoded(name, any_source_for=()):
    """(frames, decoder, name -> [(t, value)]) of one capture; ``any_source_for``: messages accepted from any SA."""
    frames = read(name)
    decoder = J1939Decoder(expected_sa={m: None for m in any_source_for})
    series = defaultdict(list)
    for msg in frames:
        for update in decoder.feed(msg):
            series[update.name].append((update.timestamp_s, update.value))
    return frames, decoder, dict(series)


@pytest.mark.parametrize("name", FILES)
@pytest.mark.parametrize(
    "signal",
    [
        "engine_speed_rpm",
        "engine_torque_pct",
        "gear",
        "oil_temp_c",
        "ambient_temp_c",
        "vehicle_speed_kmh",
        "coolant_temp_c",
    ],
)
def test_value_ranges_of_the_readme(name, signal):
    _, _, series = decoded(name)
    expected = EXPECTED[name][signal]
    if expected is None:
        assert signal not in series, f"{name} has no valid {signal}, the decoder found {series.get(signal, [])[:3]}"
        return
    low, high, tol = expected
    values = [v for _, v in series[signal]]
    assert min(values) == pytest.approx(low, abs=tol) and max(values) == pytest.approx(high, abs=tol)


@pytest.mark.parametrize("name", FILES)
def test_counters_balance_and_name_every_rejection(name):
    frames, decoder, _ = decoded(name)
    c = decoder.counters
    assert c["frames_seen"] == len(frames)
    assert c["frames_seen"] == c["frames_used"] + sum(c["rejected"].values())
    assert set(c["rejected"]) <= set(REJECT_REASONS)


@pytest.mark.parametrize("name", FILES)
def test_ec1_reference_torque_is_assembled_from_tp_bam(name):
    frames, decoder, series = decoded(name)
    announces = [
        m
        for m in frames
        if m.arbitration_id & 0x3FFFFFF == 0xECFF00 and m.data[0] == 32 and m.data[5:8] == b"\xe3\xfe\x00"
    ]  # BAMs of PGN 65251 from SA 0
    assert announces
    assert [v for _, v in series["engine_ref_torque_nm"]] == [EC1_NM[name]] * len(announces)
    assert decoder.counters["tp"]["ec1_received"] == len(announces)
    assert "tp_sequence_error" not in decoder.counters["rejected"]
    assert "tp_timeout" not in decoder.counters["rejected"]


@pytest.mark.parametrize("name", FILES)
def test_torque_in_nm_only_once_the_reference_torque_has_arrived(name):
    _, _, series = decoded(name)
    first_ec1 = series["engine_ref_torque_nm"][0][0]
    assert series["engine_torque_nm"][0][0] >= first_ec1
    after = [(t, v) for t, v in series["engine_torque_pct"] if t >= first_ec1]
    assert len(after) == len(series["engine_torque_nm"])
    for (t_pct, pct), (t_nm, nm) in zip(after, series["engine_torque_nm"]):
        assert t_pct == t_nm and nm == pytest.approx(pct / 100.0 * EC1_NM[name])


@pytest.mark.parametrize("name", FILES)
def test_the_cab_controller_trap_at_sa_49_is_ignored(name):
    frames, decoder, series = decoded(name)
    trap = [m for m in frames if pgn_of(m.arbitration_id) in (65272, 65265) and m.arbitration_id & 0xFF == 49]
    assert trap and all(bytes(m.data) == b"\xff" * 8 for m in trap if pgn_of(m.arbitration_id) == 65272)
    assert decoder.counters["rejected"]["wrong_source_address"] >= len(trap)
    assert all(v < 200.0 for _, v in series.get("oil_temp_c", []))  # never 1774.97 degC
    assert all(v < 250.0 for _, v in series.get("vehicle_speed_kmh", []))  # never 256 km/h


@pytest.mark.parametrize("name", FILES)
def test_accepting_any_source_still_never_decodes_not_available_as_data(name):
    """Even with the source check off, the 0xFF frames of SA 49 are rejected as not available, not decoded."""
    _, strict, strict_series = decoded(name)
    _, loose, series = decoded(name, ("TRF1", "CCVS1"))
    assert series.get("oil_temp_c") == strict_series.get("oil_temp_c")
    assert loose.counters["rejected"]["not_available"] > strict.counters["rejected"].get("not_available", 0)
    assert all(v < 250.0 for _, v in series.get("vehicle_speed_kmh", []))


def test_the_utulsa_truck_has_no_gear_and_no_valid_oil_temperature():
    frames, decoder, series = decoded("utulsa_logger2_drive")
    assert "gear" not in series and "oil_temp_c" not in series
    assert not any(pgn_of(m.arbitration_id) == 61445 for m in frames)  # no ETC2 at all
