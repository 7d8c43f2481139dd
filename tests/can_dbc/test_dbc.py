"""The project DBC: loads strictly, survives dump-then-reload, matches the J1939 inputs of docs/can.md, names the
component of every per-component signal and round-trips every output."""

from __future__ import annotations

import math
import random
import subprocess
import sys
from pathlib import Path

import cantools
import pytest

from can_dbc import adapter, dbc
from firmware_model.components import PUBLISHED

DBC = Path(adapter.__file__).with_name(adapter.DBC_NAME)
REPO = Path(__file__).resolve().parents[2]

#: the J1939 inputs of docs/can.md, written out by hand: message -> (PGN, default SA, {SPN: (first byte 1-based, bits,
#: scale, offset[, first bit in that byte, 1-based])})
CONTRACT_INPUTS = {
    "EEC1": (61444, 0x00, {190: (4, 16, 0.125, 0.0), 513: (3, 8, 1.0, -125.0)}),
    "ETC2": (61445, 0x03, {523: (4, 8, 1.0, -125.0)}),
    "TRF1": (65272, 0x03, {177: (5, 16, 0.03125, -273.0), 124: (2, 8, 0.4, 0.0), 3026: (8, 4, 1.0, 0.0, 5)}),
    "ET1": (65262, 0x00, {110: (1, 8, 1.0, -40.0)}),
    "AMB": (65269, 0x00, {171: (4, 16, 0.03125, -273.0)}),
    "CCVS1": (65265, 0x00, {84: (2, 16, 1 / 256, 0.0)}),
    "ERC1": (61440, 0x10, {520: (2, 8, 1.0, -125.0)}),
}

#: the output table of docs/can.md: name -> PGN
OUTPUT_PGNS = {
    **{f"GBX_TEMP_{k + 1}": 0xFF40 + k for k in range(7)},
    "GBX_WARN": 0xFF47,
    **{f"GBX_TTL_{k + 1}": 0xFF48 + k for k in range(7)},
    "GBX_STATUS": 0xFF4F,
    "GBX_DM1": 65226,
    **{f"RIG_TC_{k + 1}": 0xFF50 + k for k in range(7)},
}


@pytest.fixture(scope="module")
def db():
    return cantools.database.load_file(str(DBC), strict=True)


def test_loads_strictly_and_from_package_data(db):
    packaged = adapter.load_database()
    assert packaged is adapter.load_database()  # cached
    assert [m.name for m in packaged.messages] == [m.name for m in db.messages]


def test_every_message_is_a_j1939_pg_with_an_extended_id_and_8_bytes(db):
    assert db.dbc.attribute_definitions["VFrameFormat"].choices[3] == "J1939PG"
    for message in db.messages:
        assert message.protocol == "j1939", message.name
        assert message.is_extended_frame and message.length == 8, message.name
        assert message.comment, message.name
        for signal in message.signals:
            assert signal.comment, f"{message.name}.{signal.name}"


def _signature(db):
    return [
        (
            m.name,
            m.frame_id,
            m.length,
            m.protocol,
            m.cycle_time,
            m.senders,
            m.comment,
            [
                (
                    s.name,
                    s.start,
                    s.length,
                    s.byte_order,
                    s.is_signed,
                    s.scale,
                    s.offset,
                    s.minimum,
                    s.maximum,
                    s.unit,
                    s.spn,
                    s.comment,
                    s.multiplexer_ids,
                    s.is_multiplexer,
                    None if s.choices is None else {k: str(v) for k, v in s.choices.items()},
                )
                for s in sorted(m.signals, key=lambda s: (s.start, s.name))
            ],
        )  # the dumper may reorder signals
        for m in db.messages
    ]


def test_dump_then_reload_is_identical(db, tmp_path):
    dumped = tmp_path / "dumped.dbc"
    cantools.database.dump_file(db, str(dumped))
    reloaded = cantools.database.load_file(str(dumped), strict=True)
    assert _signature(reloaded) == _signature(db)
    assert [(n.name, n.dbc.attributes["NmStationAddress"].value) for n in reloaded.nodes] == [
        (n.name, n.dbc.attributes["NmStationAddress"].value) for n in db.nodes
    ]


@pytest.mark.parametrize("name", sorted(CONTRACT_INPUTS))
def test_inputs_match_interfaces_section_1(db, name):
    pgn, sa, spns = CONTRACT_INPUTS[name]
    message = db.get_message_by_name(name)
    assert adapter.pgn_of(message.frame_id) == pgn
    assert adapter.source_address(message.frame_id) == sa
    by_spn = {s.spn: s for s in message.signals}
    assert set(by_spn) == set(spns)
    for spn, (byte1, bits, scale, offset, *bit1) in spns.items():
        signal = by_spn[spn]
        assert (signal.start, signal.length, signal.byte_order, signal.is_signed) == (
            (byte1 - 1) * 8 + (bit1[0] - 1 if bit1 else 0),
            bits,
            "little_endian",
            False,
        )
        assert signal.scale == pytest.approx(scale) and signal.offset == offset


def test_transport_protocol_frames_describe_the_ec1_bam(db):
    cm = db.get_message_by_name("TP_CM")
    dt = db.get_message_by_name("TP_DT")
    assert adapter.pgn_of(cm.frame_id) == dbc.message_pgn("TP_CM") == 0xEC00
    assert adapter.pgn_of(dt.frame_id) == dbc.message_pgn("TP_DT") == 0xEB00
    assert adapter.destination_address(cm.frame_id) == 0xFF
    bam = bytes.fromhex("20220005FFE3FE00")  # the BAM announcing EC1 in normal.candump.log
    decoded = cm.decode(bam, decode_choices=False)
    assert decoded["TP_CM_Control"] == 32 and decoded["TP_BAM_MessageSize"] == 34
    assert decoded["TP_BAM_NumPackets"] == 5 and decoded["TP_CM_PGN"] == adapter.EC1_PGN
    assert "EC1" in cm.comment and "544" in cm.comment


@pytest.mark.parametrize("name", sorted(OUTPUT_PGNS))
def test_output_ids_priority_and_source(db, name):
    message = db.get_message_by_name(name)
    assert adapter.pgn_of(message.frame_id) == OUTPUT_PGNS[name]
    assert adapter.priority(message.frame_id) == 6
    expected_sa = 0xF0 if name.startswith("RIG_") else 0xE5
    assert adapter.source_address(message.frame_id) == expected_sa


def test_per_component_signals_follow_published_order(db):
    def names(prefix, message_prefix):
        return [s.name for k in range(7) for s in db.get_message_by_name(f"{message_prefix}{k + 1}").signals]

    expected = [c.replace(".", "_") for c in PUBLISHED]
    assert names("T_", "GBX_TEMP_") == [f"T_{c}" for c in expected]
    assert names("TTL_", "GBX_TTL_") == [f"TTL_{c}" for c in expected]
    assert names("TC_", "RIG_TC_") == [f"TC_{c}" for c in expected]
    assert [s.name for s in db.get_message_by_name("GBX_WARN").signals] == [f"W_{c}" for c in expected]
    for k in range(7):
        for signal in db.get_message_by_name(f"GBX_TEMP_{k + 1}").signals:
            assert (signal.unit, signal.scale, signal.offset) == ("degC", 0.03125, -273)
            assert str(signal.choices[0xFFFF]) == "not available"
        for signal in db.get_message_by_name(f"GBX_TTL_{k + 1}").signals:
            assert signal.unit == "s"
            assert str(signal.choices[0xFAFF]) == "never" and str(signal.choices[0xFFFF]) == "not available"


def test_every_per_component_signal_names_its_component(db, tmp_path):
    assert dbc.published_components() == PUBLISHED
    for prefix, kinds in (("GBX_TEMP_", "T_"), ("GBX_TTL_", "TTL_"), ("RIG_TC_", "TC_"), ("GBX_WARN", "W_")):
        names = dbc.numbered_messages(prefix) or (prefix,)
        got = [(s.name, dbc.component_of(s)) for n in names for s in db.get_message_by_name(n).signals]
        assert got == [(kinds + c.replace(".", "_"), c) for c in PUBLISHED], prefix
    assert dbc.component_of(db.get_message_by_name("GBX_STATUS").signals[0]) is None
    dumped = tmp_path / "dumped.dbc"
    cantools.database.dump_file(db, str(dumped))
    reloaded = cantools.database.load_file(str(dumped), strict=True)
    assert [dbc.component_of(s) for s in reloaded.get_message_by_name("GBX_TEMP_7").signals] == list(PUBLISHED[-4:])


def test_message_helpers_read_the_dbc():
    assert dbc.numbered_messages("GBX_TEMP_") == tuple(f"GBX_TEMP_{k}" for k in range(1, 8))
    assert dbc.message_pgn("EEC1") == 61444 and dbc.default_source("ERC1") == 0x10
    assert dbc.message_id("GBX_STATUS", 0x80) == 0x18FF4F80
    assert dbc.signal_layout("TRF1", "TransOilTemp", 16) == (32, 0.03125, -273.0)
    with pytest.raises(adapter.DecodeError, match="8-bit"):
        dbc.signal_layout("TRF1", "TransOilTemp", 8)
    assert dbc.not_available_raw("GBX_STATUS", "DegradedMode") == 15
    assert dbc.data_choices("GBX_STATUS", "DegradedMode") == {
        0: "normal",
        1: "oil model only",
        2: "inputs missing - holding",
        3: "not initialised",
    }


def _random_outputs(rng):
    temps = {
        c: rng.choice([None, math.nan, rng.uniform(-300, 1800), round(rng.uniform(-40, 200), 5)]) for c in PUBLISHED
    }
    levels = {c: rng.choice([0, 1, 2, 3, None]) for c in PUBLISHED}
    ttl = {c: rng.choice([None, math.inf, math.nan, -5.0, float(rng.randrange(0, 70000))]) for c in PUBLISHED}
    status = {
        "speed_valid": rng.choice([True, False, None]),
        "torque_valid": rng.choice([True, False, None]),
        "gear_valid": rng.choice([True, False, None]),
        "oil_valid": rng.choice([True, False, None]),
        "ref_torque_valid": rng.choice([True, False, None]),
        "degraded_mode": rng.choice([0, 1, 2, 3, None]),
        "oil_innovation_c": rng.choice([None, rng.uniform(-1100, 1100)]),
        "model_oil_temp_c": rng.choice([None, rng.uniform(-40, 150)]),
        "time_base_suspect": rng.choice([True, False, None]),
    }
    return temps, levels, ttl, status


def _expected_temp(value, low=-273.0, high=1734.96875):
    if value is None or not math.isfinite(value):
        return None
    return min(max(round((value - low) / 0.03125) * 0.03125 + low, low), high)


def test_output_round_trip_of_every_signal_including_not_available_and_never():
    encoder = adapter.OutputEncoder()
    rng = random.Random(20240611)
    for _ in range(200):
        temps, levels, ttl, status = _random_outputs(rng)
        frames = encoder.encode(temps, levels, ttl, status) + [encoder.encode_dm1(levels)]
        got = adapter.decode_outputs(frames, source_address=0xE5)
        for c in PUBLISHED:
            expected = _expected_temp(temps[c])
            assert got["temps_c"][c] == (None if expected is None else pytest.approx(expected, abs=1e-9)), c
            assert got["levels"][c] == (3 if levels[c] is None else levels[c])
            value = ttl[c]
            if value is None or value != value:
                assert got["ttl_s"][c] is None
            elif value == math.inf:
                assert got["ttl_s"][c] == math.inf
            else:
                assert got["ttl_s"][c] == min(max(round(value), 0), 64254)
        for key in (
            "speed_valid",
            "torque_valid",
            "gear_valid",
            "oil_valid",
            "ref_torque_valid",
            "degraded_mode",
            "time_base_suspect",
        ):
            assert got["status"][key] == status[key], key
        innovation = status["oil_innovation_c"]
        expected = None if innovation is None else _expected_temp(innovation, -1000.0, 1007.96875)
        assert got["status"]["oil_innovation_c"] == (None if expected is None else pytest.approx(expected))
        assert got["status"]["model_oil_temp_c"] == (
            None if status["model_oil_temp_c"] is None else pytest.approx(_expected_temp(status["model_oil_temp_c"]))
        )
        available = [lv for lv in levels.values() if lv is not None and lv != 3]
        assert got["status"]["max_warning_level"] == (max(available) if available else 3)


def test_fast_encoder_matches_cantools_encode(db):
    """The encoder packs integers itself for speed; cantools with the DBC must produce the same bits."""
    encoder = adapter.OutputEncoder()
    rng = random.Random(7)
    for _ in range(50):
        temps, levels, ttl, status = _random_outputs(rng)
        status["counter"] = rng.randrange(256)
        for msg in encoder.encode(temps, levels, ttl, status) + [encoder.encode_dm1(levels)]:
            message = db.get_message_by_frame_id(msg.arbitration_id)
            raw = message.decode(bytes(msg.data), decode_choices=False, scaling=False)
            reference = message.encode(raw, scaling=False, strict=True)
            unused = int.from_bytes(dbc.fill_mask(message.name).to_bytes(8, "little"), "little")
            ours = int.from_bytes(bytes(msg.data), "little")
            assert ours & ~unused == int.from_bytes(reference, "little"), message.name
            assert ours & unused == unused, f"{message.name}: unused bits must be sent as 1"


def test_rig_round_trip():
    rng = random.Random(3)
    temps = {c: rng.choice([None, math.nan, rng.uniform(-40, 300)]) for c in PUBLISHED}
    frames = adapter.encode_rig(temps)
    assert [adapter.pgn_of(m.arbitration_id) for m in frames] == list(range(0xFF50, 0xFF57))
    assert {adapter.source_address(m.arbitration_id) for m in frames} == {0xF0}
    got = adapter.decode_rig(frames, source_address=0xF0)
    for c in PUBLISHED:
        expected = _expected_temp(temps[c])
        assert got[c] == (None if expected is None else pytest.approx(expected)), c
    assert adapter.decode_rig(frames, source_address=0x12) == {}


def test_dm1_round_trip_spn_fmi_lamps_and_occurrence_count():
    encoder = adapter.OutputEncoder()
    nothing = adapter.decode_outputs([encoder.encode_dm1({})])["dm1"]
    assert nothing == {
        "amber_warning_lamp": 0,
        "red_stop_lamp": 0,
        "protect_lamp": 0,
        "malfunction_lamp": 0,
        "dtc": None,
    }
    warn = adapter.decode_outputs([encoder.encode_dm1({"BO": 1, "PS": 1})])["dm1"]
    assert warn["amber_warning_lamp"] == 1 and warn["red_stop_lamp"] == 0
    assert warn["dtc"] == {"spn": 520192 + PUBLISHED.index("BO"), "fmi": 16, "occurrence_count": 1, "component": "BO"}
    crit = adapter.decode_outputs([encoder.encode_dm1({"BO": 1, "PS": 2})])["dm1"]
    assert crit["red_stop_lamp"] == 1 and crit["amber_warning_lamp"] == 1
    assert crit["dtc"] == {"spn": 520192 + PUBLISHED.index("PS"), "fmi": 0, "occurrence_count": 1, "component": "PS"}
    encoder.encode_dm1({})
    again = adapter.decode_outputs([encoder.encode_dm1({"PS": 2})])["dm1"]
    assert again["dtc"]["occurrence_count"] == 2
    assert encoder.encode_dm1({}).data[6:] == b"\xff\xff"


def test_dm1_names_a_missing_input_only_when_no_component_dtc_is_active(db):
    encoder = adapter.OutputEncoder()
    miss = encoder.encode_dm1({}, missing_spn=190)
    d = adapter.decode_outputs([miss])["dm1"]
    assert d["amber_warning_lamp"] == 1 and d["red_stop_lamp"] == 0
    assert d["dtc"]["spn"] == 190 and d["dtc"]["fmi"] == 9 and d["dtc"]["occurrence_count"] == 1
    assert str(db.decode_message(miss.arbitration_id, miss.data)["DTC1_FMI"]).startswith("abnormal update rate")
    crit = adapter.decode_outputs([encoder.encode_dm1({"PS": 2}, missing_spn=190)])["dm1"]
    assert crit["dtc"]["fmi"] == 0 and crit["red_stop_lamp"] == 1  # a component DTC comes first
    with pytest.raises(adapter.EncodeError, match="missing_spn"):
        encoder.encode_dm1({}, missing_spn=1 << 19)


def test_dm1_without_an_active_dtc_reads_as_no_active_dtc(db):
    """SPN 0 / FMI 0 / OC 0 is J1939's "no DTC": cantools must not show it as a most severe fault."""
    encoder = adapter.OutputEncoder()
    nothing, warning, critical = (
        db.decode_message(m.arbitration_id, m.data)
        for m in (encoder.encode_dm1({}), encoder.encode_dm1({"PS": 1}), encoder.encode_dm1({"PS": 2}))
    )
    assert str(nothing["DTC1_OccurrenceCount"]) == "no active DTC"
    assert str(nothing["DTC1_FMI"]).startswith("no active DTC")
    assert nothing["DTC1_SPN_Low"] + 65536 * nothing["DTC1_SPN_High"] == 0
    assert "warning" in str(warning["DTC1_FMI"]) and "critical" in str(critical["DTC1_FMI"])
    assert warning["DTC1_OccurrenceCount"] == 1 and critical["DTC1_OccurrenceCount"] == 1


def test_per_component_signal_comments_spell_out_the_component(db):
    from firmware_model.components import describe

    for message in db.messages:
        for signal in message.signals:
            component = dbc.component_of(signal)
            if component is not None:
                assert describe(component) in (signal.comment or ""), (message.name, signal.name)


def _run_cli(*args, stdin=""):
    return subprocess.run(
        [sys.executable, "-m", "cantools", *args],
        input=stdin,
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=120,
        check=True,
    ).stdout


def test_cantools_decode_cli_shows_names_units_and_not_available():
    encoder = adapter.OutputEncoder()
    temps = {c: 80.0 for c in PUBLISHED}
    temps["PS"] = None
    ttl = {"oil": math.inf}
    frames = encoder.encode(temps, {"PS": 2}, ttl, {"oil_innovation_c": -2.5, "degraded_mode": 1})
    lines = "".join(
        f"({k * 0.1:.6f}) vcan0 {m.arbitration_id:08X}#{bytes(m.data).hex().upper()}\n" for k, m in enumerate(frames)
    )
    out = _run_cli("decode", "--single-line", str(DBC), stdin=lines)
    assert "GBX_TEMP_7(T_PS: not available, T_PP: 80.0 degC, T_PR: 80.0 degC, T_oil: 80.0 degC)" in out
    assert "TTL_oil: never" in out and "W_PS: critical" in out
    assert "OilInnovation: -2.5 degC" in out and "DegradedMode: oil model only" in out


def test_cantools_dump_cli_lists_messages_with_units():
    out = _run_cli("dump", "--with-comments", str(DBC))
    for name in OUTPUT_PGNS:
        assert f"Name:           {name}" in out
    assert "[degC]" in out and "[s]" in out and "PGN:            0x0ff4f" in out
