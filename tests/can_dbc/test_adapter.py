"""J1939 identifiers, the decoder (hand-built frames, TP.BAM, 100,000 random frames) and the output encoder."""

from __future__ import annotations

import math
import random

import can
import pytest

from can_dbc import adapter
from can_dbc.adapter import J1939Decoder, OutputEncoder, SignalUpdate
from can_dbc.errors import ConfigError, DecodeError, EncodeError
from firmware_model.components import PUBLISHED


def frame(pgn, sa, data, *, prio=6, da=0xFF, ts=0.0, **kwargs):
    return can.Message(
        timestamp=ts,
        arbitration_id=adapter.can_id_of(pgn, sa, prio, da),
        is_extended_id=True,
        data=bytes(data),
        **kwargs,
    )


def assert_balanced(decoder):
    c = decoder.counters
    assert c["frames_seen"] == c["frames_used"] + sum(c["rejected"].values())
    assert set(c["rejected"]) <= set(adapter.REJECT_REASONS)


def only(decoder, msg):
    """Feed one frame; return (updates as {name: value}, the frame's rejection reason or None)."""
    before = dict(decoder.counters["rejected"])
    used_before = decoder.counters["frames_used"]
    updates = decoder.feed(msg)
    assert_balanced(decoder)
    changed = [r for r, n in decoder.counters["rejected"].items() if n != before.get(r, 0)]
    if decoder.counters["frames_used"] != used_before:
        assert not changed
        return {u.name: u.value for u in updates}, None
    assert len(changed) == 1 and not updates
    return {}, changed[0]


# ---- identifiers -------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "can_id, pgn, sa, prio",
    [
        (0x0CF00400, 61444, 0x00, 3),  # EEC1, PDU2
        (0x18FEF831, 65272, 0x31, 6),  # TRF1 from SA 49
        (0x1CECFF00, 60416, 0x00, 7),  # TP.CM to global: PS is a destination
        (0x1CEC2300, 60416, 0x00, 7),  # TP.CM to 0x23: same PGN
        (0x18EA00F9, 59904, 0xF9, 6),  # request, PDU1
        (0x19FEF100, 0x1FEF1, 0x00, 6),  # data page 1
        (0x1BFEF100, 0x3FEF1, 0x00, 6),  # extended data page + data page
        (0x1A00AB00, 0x20000, 0x00, 6),  # EDP only, PDU1 with destination 0xAB
        (0x18FF40E5, 0xFF40, 0xE5, 6),  # the sensor's first output
    ],
)
def test_pgn_source_priority(can_id, pgn, sa, prio):
    assert adapter.pgn_of(can_id) == pgn
    assert adapter.source_address(can_id) == sa
    assert adapter.priority(can_id) == prio


def test_can_id_of_round_trips_and_puts_the_destination_in_pdu1():
    assert adapter.can_id_of(60416, 0x00, 7) == 0x1CECFF00
    assert adapter.can_id_of(60416, 0x00, 7, 0x23) == 0x1CEC2300
    assert adapter.destination_address(0x1CEC2300) == 0x23
    assert adapter.destination_address(0x18FEF100) == 0xFF
    assert adapter.can_id_of(0xFEF1, 0x00, 3, 0x23) == 0x0CFEF100  # PDU2 ignores the destination
    with pytest.raises(DecodeError, match="PS = 0"):
        adapter.can_id_of(0xEC23, 0x00)
    with pytest.raises(DecodeError, match="29-bit"):
        adapter.pgn_of(1 << 29)


def test_j1939_helpers_source_filter_and_value_ranges():
    from can_dbc import j1939

    assert j1939.with_source(0x18FF40E5, 0x80) == 0x18FF4080
    f = j1939.receive_filter(60416)
    assert f == {"can_id": 60416 << 8, "can_mask": 0x3FF0000, "extended": True}
    assert j1939.receive_filter(65272)["can_mask"] == 0x3FFFF00
    assert j1939.check_source_address("sa", 0x10) == 0x10
    for bad in (254, -1, True, "3"):
        with pytest.raises(ConfigError, match="sa"):
            j1939.check_source_address("sa", bad)
    assert [j1939.raw_reason(r, 1) for r in (0xFA, 0xFB, 0xFE, 0xFF)] == [
        None,
        "out_of_range",
        "error_value",
        "not_available",
    ]
    assert [j1939.raw_reason(r, 2) for r in (0xFAFF, 0xFB00, 0xFE00, 0xFF00)] == [
        None,
        "out_of_range",
        "error_value",
        "not_available",
    ]


def test_feed_into_keeps_the_latest_values_and_forget_makes_them_stale():
    d = J1939Decoder(configured_ref_torque_nm=2000.0)
    latest = adapter.LatestValues()
    d.feed_into(frame(61444, 0x00, [0xF0, 0x7D, 0x91, 0x40, 0x38, 0, 0xF0, 0xFF], prio=3, ts=1.5), latest)
    d.feed_into(frame(61444, 0x00, [0xF0, 0x7D, 0x92, 0x40, 0x38, 0, 0xF0, 0xFF], prio=3, ts=1.6), latest)
    assert latest.value == {"engine_torque_pct": 21, "engine_torque_nm": 420.0, "engine_speed_rpm": 1800.0}
    assert set(latest.time_s.values()) == {1.6}
    latest.forget()
    assert set(latest.time_s.values()) == {-math.inf} and latest.value["engine_speed_rpm"] == 1800.0
    assert adapter.signal_messages()["engine_torque_nm"] == "EEC1" and "RIG" in adapter.message_names()


# ---- single-frame messages ---------------------------------------------------------------------------------------


def test_eec1_speed_and_percent_torque_without_reference_torque():
    d = J1939Decoder()
    values, reason = only(d, frame(61444, 0x00, [0xF0, 0x7D, 0x91, 0x40, 0x38, 0, 0xF0, 0xFF], prio=3, ts=1.5))
    assert reason is None
    assert values == {"engine_torque_pct": 20, "engine_speed_rpm": 0x3840 * 0.125}
    assert d.feed(frame(61444, 0, [0xFF, 0xFF, 0x91, 0x40, 0x38, 0, 0, 0], ts=2.0))[0] == SignalUpdate(
        2.0, "engine_torque_pct", 20.0
    )


def test_engine_and_retarder_torque_in_nm_use_the_configured_references():
    d = J1939Decoder(retarder_ref_torque_nm=3000.0, configured_ref_torque_nm=2000.0)
    values, _ = only(d, frame(61444, 0x00, [0xFF, 0xFF, 125 + 50, 0, 0x20, 0xFF, 0xFF, 0xFF]))
    assert values["engine_torque_nm"] == pytest.approx(1000.0)
    values, _ = only(d, frame(61440, 0x10, [0xFF, 125 - 40, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF]))
    assert values == {"retarder_torque_pct": -40.0, "retarder_torque_nm": pytest.approx(-1200.0)}
    assert d.ref_torque_nm == 2000.0


@pytest.mark.parametrize(
    "pgn, sa, data, name, value",
    [
        (61445, 0x03, [0xFF, 0, 0, 125 + 3, 0xFF, 0xFF, 0xFF, 0xFF], "gear", 3),
        (61445, 0x03, [0xFF, 0, 0, 125 - 2, 0xFF, 0xFF, 0xFF, 0xFF], "gear", -2),
        (65272, 0x03, [0xFF] * 4 + list(((78 + 273) * 32).to_bytes(2, "little")) + [0xFF, 0xFF], "oil_temp_c", 78.0),
        (65262, 0x00, [40 + 92] + [0xFF] * 7, "coolant_temp_c", 92.0),
        (
            65269,
            0x00,
            [0xFF] * 3 + list(int((33.09375 + 273) * 32).to_bytes(2, "little")) + [0xFF] * 3,
            "ambient_temp_c",
            33.09375,
        ),
        (65265, 0x00, [0xFF, 0x00, 0x36, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF], "vehicle_speed_kmh", 54.0),
        (61440, 0x10, [0xFF, 125 + 7, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF], "retarder_torque_pct", 7.0),
    ],
)
def test_each_input_signal(pgn, sa, data, name, value):
    values, reason = only(J1939Decoder(), frame(pgn, sa, data))
    assert reason is None and values == {name: value}
    if name == "gear":
        assert isinstance(values[name], int)


@pytest.mark.parametrize(
    "data, reason",
    [
        ([0xFF, 0xFF, 0xFF, 0x00, 0xFF, 0xFF, 0xFF, 0xFF], "not_available"),  # both 0xFF / 0xFFxx
        ([0xFF, 0xFF, 0xFE, 0x00, 0xFE, 0xFF, 0xFF, 0xFF], "error_value"),  # both 0xFE / 0xFExx
        ([0xFF, 0xFF, 0xFE, 0x00, 0xFF, 0xFF, 0xFF, 0xFF], "error_value"),  # error beats not available
        ([0xFF, 0xFF, 0xFB, 0x00, 0xFB, 0xFF, 0xFF, 0xFF], "out_of_range"),  # indicator ranges: no data
        ([0xFF, 0xFF, 0xFF, 0xFF, 0xFA, 0xFF, 0xFF, 0xFF], "not_available"),  # 0xFAFF = 8031.875 rpm is data ...
    ],
)
def test_eec1_values_that_are_not_data(data, reason):
    d = J1939Decoder()
    values, got = only(d, frame(61444, 0, data))
    if data[4] == 0xFA:  # ... so the frame is used for the speed even though the torque is not available
        assert got is None and values == {"engine_speed_rpm": 8031.875}
        assert d.counters["signal_rejected"] == {"engine_torque_pct": {"not_available": 1}}
    else:
        assert got == reason and values == {}


def test_gear_park_and_reserved_values_are_out_of_range():
    d = J1939Decoder()
    for raw in (251, 252, 253):
        assert only(d, frame(61445, 3, [0xFF, 0, 0, raw, 0xFF, 0xFF, 0xFF, 0xFF]))[1] == "out_of_range"


def test_plausibility_limits_are_applied_and_configurable():
    hot = [0xFF] * 4 + list(((300 + 273) * 32).to_bytes(2, "little")) + [0xFF, 0xFF]
    assert only(J1939Decoder(), frame(65272, 3, hot))[1] == "out_of_range"
    values, reason = only(J1939Decoder(limits={"oil_temp_c": (-60.0, 400.0)}), frame(65272, 3, hot))
    assert reason is None and values == {"oil_temp_c": 300.0}
    with pytest.raises(ConfigError, match="limits"):
        J1939Decoder(limits={"oil_temp_c": (5.0, 1.0)})
    with pytest.raises(ConfigError, match="limits"):
        J1939Decoder(limits={"oil_temperature": (0.0, 1.0)})


def test_source_address_is_checked_per_message_and_configurable():
    ff = [0xFF] * 8
    oil = [0xFF] * 4 + [0x00, 0x2C, 0xFF, 0xFF]
    d = J1939Decoder()
    assert only(d, frame(65272, 49, ff))[1] == "wrong_source_address"  # the SA-49 trap
    assert only(d, frame(65272, 49, oil))[1] == "wrong_source_address"  # even with plausible data
    assert only(d, frame(65265, 49, ff))[1] == "wrong_source_address"
    moved = J1939Decoder(expected_sa={"TRF1": 0x05})
    assert only(moved, frame(65272, 0x05, oil))[0] == {"oil_temp_c": 0x2C00 / 32 - 273}
    assert only(moved, frame(65272, 0x03, oil))[1] == "wrong_source_address"
    anyone = J1939Decoder(expected_sa={"TRF1": None})
    assert only(anyone, frame(65272, 49, ff))[1] == "not_available"
    assert only(anyone, frame(65272, 0x77, oil))[1] is None
    assert only(J1939Decoder(), frame(65272, 3, oil, prio=3))[1] is None  # another priority: same PGN


def test_bad_configuration_raises_parameter_error():
    with pytest.raises(ConfigError, match="expected_sa"):
        J1939Decoder(expected_sa={"EEC2": 0})
    with pytest.raises(ConfigError, match="source address"):
        J1939Decoder(expected_sa={"EEC1": 255})
    with pytest.raises(ConfigError, match="configured_ref_torque_nm"):
        J1939Decoder(configured_ref_torque_nm=-5.0)


@pytest.mark.parametrize(
    "msg, reason",
    [
        (
            can.Message(arbitration_id=0x0CF00400, is_extended_id=True, is_error_frame=True, data=b"\0" * 8),
            "error_frame",
        ),
        (can.Message(arbitration_id=0x0CF00400, is_extended_id=True, is_remote_frame=True, dlc=8), "remote_frame"),
        (can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\x01" * 8), "not_extended_id"),
        (can.Message(arbitration_id=0x2CF00400, is_extended_id=True, data=b"\x01" * 8, check=False), "invalid_id"),
        (can.Message(arbitration_id=0x0CF00400, is_extended_id=True, is_fd=True, data=b"\x01" * 12), "fd_frame"),
        (can.Message(arbitration_id=0x18EA00F9, is_extended_id=True, data=b"\xe3\xfe\x00"), "unknown_pgn"),
        (can.Message(arbitration_id=0x0CF00400, is_extended_id=True, data=b"\x01" * 7), "wrong_dlc"),
        (
            can.Message(arbitration_id=0x0CF00400, is_extended_id=True, data=b"\x01" * 3, dlc=8, check=False),
            "wrong_dlc",
        ),
        (can.Message(arbitration_id=0x0CF00400, is_extended_id=True, data=b"", dlc=0), "wrong_dlc"),
    ],
)
def test_frames_that_are_not_j1939_inputs(msg, reason):
    assert only(J1939Decoder(), msg)[1] == reason


def test_rig_frames_are_decoded_only_when_asked():
    temps = {c: 20.0 + i for i, c in enumerate(PUBLISHED)}
    temps["PP"] = None
    frames = adapter.encode_rig(temps, timestamp_s=4.0)
    plain = J1939Decoder()
    assert all(only(plain, m)[1] == "unknown_pgn" for m in frames)
    rig = J1939Decoder(rig=True)
    got = {u.name: u.value for m in frames for u in rig.feed(m)}
    assert got == {f"meas_T_{c}_c": t for c, t in temps.items() if t is not None}
    assert rig.counters["signal_rejected"] == {"meas_T_PP_c": {"not_available": 1}}


# ---- EC1 over TP.BAM ---------------------------------------------------------------------------------------------


def ec1_payload(ref_nm, size=34):
    payload = bytearray(k % 251 for k in range(1, size + 1))
    payload[19:21] = ref_nm.to_bytes(2, "little")
    return bytes(payload)


def rc_payload(ref_nm, size=19):
    """RC (PGN 65249) as a retarder sends it: 19 bytes, SPN 556 reference retarder torque in bytes 17-18."""
    payload = bytearray(k % 251 for k in range(1, size + 1))
    payload[16:18] = ref_nm.to_bytes(2, "little")
    return bytes(payload)


def bam(payload, pgn=adapter.EC1_PGN, sa=0x00, t0=10.0, dt=0.05, packets=None):
    """TP.CM BAM + TP.DT frames, 50 ms apart, last packet padded with 0xFF."""
    n = (len(payload) + 6) // 7 if packets is None else packets
    cm = [32, len(payload) & 0xFF, len(payload) >> 8, n, 0xFF, pgn & 0xFF, (pgn >> 8) & 0xFF, pgn >> 16]
    frames = [frame(60416, sa, cm, prio=7, ts=t0)]
    padded = payload + b"\xff" * (7 * n - len(payload))
    for k in range(n):
        frames.append(frame(60160, sa, bytes([k + 1]) + padded[7 * k : 7 * k + 7], prio=7, ts=t0 + dt * (k + 1)))
    return frames


def feed_all(decoder, frames):
    out = [(u.name, u.value) for m in frames for u in decoder.feed(m)]
    assert_balanced(decoder)
    return out


def test_ec1_is_reassembled_and_then_converts_percent_torque():
    d = J1939Decoder(configured_ref_torque_nm=1000.0)
    eec1 = frame(61444, 0, [0xFF, 0xFF, 125 + 50, 0, 0x20, 0xFF, 0xFF, 0xFF], prio=3)
    assert dict(feed_all(d, [eec1]))["engine_torque_nm"] == pytest.approx(500.0)  # configured, before EC1
    assert feed_all(d, bam(ec1_payload(1109))) == [("engine_ref_torque_nm", 1109.0)]
    assert d.counters["frames_used"] == 1 + 1 + 5 and d.counters["tp"]["ec1_received"] == 1
    assert dict(feed_all(d, [eec1]))["engine_torque_nm"] == pytest.approx(554.5)  # EC1 wins over configured
    assert d.ref_torque_nm == 1109.0


def test_ec1_of_exactly_21_bytes_and_of_the_maximum_size():
    d = J1939Decoder()
    assert feed_all(d, bam(ec1_payload(2457, size=21))) == [("engine_ref_torque_nm", 2457.0)]
    assert feed_all(d, bam(ec1_payload(800, size=1785), dt=0.01)) == [("engine_ref_torque_nm", 800.0)]


def test_ec1_not_available_or_zero_reference_torque_is_not_data():
    d = J1939Decoder()
    assert feed_all(d, bam(ec1_payload(0xFFFF))) == []
    assert d.counters["rejected"] == {"not_available": 1}  # the completing packet; the others were used
    assert feed_all(d, bam(ec1_payload(0))) == []
    assert d.counters["rejected"]["out_of_range"] == 1 and d.ec1_ref_torque_nm is None


def test_out_of_order_packet_aborts_the_transfer_cleanly():
    d = J1939Decoder()
    frames = bam(ec1_payload(1109))
    frames[2], frames[3] = frames[3], frames[2]
    for m, t in zip(frames, sorted(m.timestamp for m in frames)):
        m.timestamp = t
    assert feed_all(d, frames) == []
    assert d.counters["rejected"] == {"tp_sequence_error": 1, "tp_no_session": 3}
    assert d.counters["tp"]["aborted"] == 1
    assert feed_all(d, bam(ec1_payload(1109), t0=20.0)) == [("engine_ref_torque_nm", 1109.0)]  # next one is fine


def test_a_repeated_packet_is_ignored_a_changed_or_missing_one_is_a_sequence_error():
    """A TP.DT packet repeated byte for byte (a logger or gateway that copies frames: every line of a log twice lost
    the engine's reference torque) is ignored and counted; the same sequence number with other data, or a missing
    packet, aborts the transfer."""
    frames = bam(ec1_payload(1109))
    d = J1939Decoder()
    assert feed_all(d, frames[:3] + [frames[2]] + frames[3:]) == [("engine_ref_torque_nm", 1109.0)]
    assert d.counters["rejected"] == {"tp_duplicate": 1}
    d = J1939Decoder()
    assert feed_all(d, [f for f in frames for _ in (0, 1)]) == [("engine_ref_torque_nm", 1109.0)]
    changed = can.Message(
        arbitration_id=frames[2].arbitration_id,
        data=bytes([frames[2].data[0]]) + bytes(7),
        timestamp=frames[2].timestamp,
    )
    d = J1939Decoder()
    assert feed_all(d, frames[:3] + [changed] + frames[3:]) == []
    assert d.counters["rejected"]["tp_sequence_error"] == 1
    d = J1939Decoder()
    assert feed_all(d, frames[:2] + frames[3:]) == []
    assert d.counters["rejected"]["tp_sequence_error"] == 1


def test_packet_after_more_than_750_ms_times_out():
    d = J1939Decoder()
    assert feed_all(d, bam(ec1_payload(1109), dt=0.76)) == []
    assert d.counters["rejected"] == {"tp_timeout": 1, "tp_no_session": 4}
    d = J1939Decoder()
    assert feed_all(d, bam(ec1_payload(1109), dt=0.75)) == [("engine_ref_torque_nm", 1109.0)]
    backwards = bam(ec1_payload(1109))
    backwards[1].timestamp = 5.0
    d = J1939Decoder()
    assert feed_all(d, backwards) == []
    assert d.counters["rejected"]["tp_timeout"] == 1


def test_new_bam_from_the_same_source_replaces_an_unfinished_one():
    d = J1939Decoder()
    first = bam(ec1_payload(1000))
    second = bam(ec1_payload(1109), t0=10.2)
    assert feed_all(d, first[:3] + second) == [("engine_ref_torque_nm", 1109.0)]
    assert d.counters["tp"]["aborted"] == 1 and d.counters["tp"]["completed"] == 1


def test_the_retarder_reference_torque_arrives_by_rc_and_wins_over_the_configured_one():
    """RC (PGN 65249, SPN 556 in bytes 17-18) from the retarder's address gives ERC1's percent a torque in Nm (as
    EC1 does for the engine); the configured reference serves until then. Real trucks send RC every 5 s by TP.BAM
    (the captures: an exhaust retarder at SA 0x29 with 450 Nm, an engine retarder at SA 0x0F with 1588 Nm)."""
    erc1 = frame(61440, 0x10, [0xFF, 125 - 40, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF], ts=20.0)
    d = J1939Decoder()
    assert feed_all(d, [erc1]) == [("retarder_torque_pct", -40.0)]  # no reference: no Nm
    assert feed_all(d, bam(rc_payload(1588), pgn=adapter.RC_PGN, sa=0x10)) == [("retarder_ref_torque_nm", 1588.0)]
    assert d.counters["tp"]["rc_received"] == 1 and d.retarder_ref_in_use_nm == 1588.0
    assert dict(feed_all(d, [erc1]))["retarder_torque_nm"] == pytest.approx(-0.4 * 1588.0)
    d = J1939Decoder(retarder_ref_torque_nm=3500.0)
    assert dict(feed_all(d, [erc1]))["retarder_torque_nm"] == pytest.approx(-1400.0)  # configured, until RC
    feed_all(d, bam(rc_payload(1588), pgn=adapter.RC_PGN, sa=0x10))
    assert dict(feed_all(d, [erc1]))["retarder_torque_nm"] == pytest.approx(-0.4 * 1588.0)
    d = J1939Decoder()  # an engine retarder's RC: another node, not ours
    assert feed_all(d, bam(rc_payload(450), pgn=adapter.RC_PGN, sa=0x29)) == []
    assert d.counters["rejected"] == {"wrong_source_address": 4} and d.counters["foreign_source"] == {"RC": {0x29: 1}}
    d = J1939Decoder()
    for bad, reason in ((0xFFFF, "not_available"), (0xFE10, "error_value"), (0, "out_of_range")):
        assert feed_all(d, bam(rc_payload(bad), pgn=adapter.RC_PGN, sa=0x10)) == []
        assert d.counters["signal_rejected"]["retarder_ref_torque_nm"][reason] == 1
    assert d.retarder_ref_in_use_nm is None
    short = bam(rc_payload(1588)[:17], pgn=adapter.RC_PGN, sa=0x10)  # cut before byte 18
    assert feed_all(J1939Decoder(), short[:1]) == []
    assert J1939Decoder().dispatch(short[0], adapter.LatestValues()) == "tp_bad_announce"


def test_bams_of_other_pgns_or_sources_and_connection_mode_are_not_used():
    d = J1939Decoder()
    assert feed_all(d, bam(bytes(14), pgn=65226)) == []  # DM1 with two DTCs
    assert d.counters["rejected"] == {"tp_other_pgn": 3}
    d = J1939Decoder()
    assert feed_all(d, bam(ec1_payload(1109), sa=0x29)) == []  # EC1 from another node
    assert d.counters["rejected"] == {"wrong_source_address": 6}
    assert feed_all(J1939Decoder(expected_sa={"EC1": 0x29}), bam(ec1_payload(1109), sa=0x29)) == [
        ("engine_ref_torque_nm", 1109.0)
    ]
    d = J1939Decoder()
    rts = frame(60416, 0x00, [16, 34, 0, 5, 0xFF, 0xE3, 0xFE, 0x00], prio=7, da=0xF9)
    dt = frame(60160, 0x00, [1, 1, 2, 3, 4, 5, 6, 7], prio=7, da=0xF9)
    cts_global = frame(60416, 0x00, [17, 5, 1, 0xFF, 0xFF, 0xE3, 0xFE, 0x00], prio=7)
    orphan = frame(60160, 0x00, [1, 1, 2, 3, 4, 5, 6, 7], prio=7)
    assert feed_all(d, [rts, dt, cts_global, orphan]) == []
    assert d.counters["rejected"] == {"tp_not_broadcast": 2, "tp_bad_control": 1, "tp_no_session": 1}


@pytest.mark.parametrize("size, packets", [(8, 2), (34, 4), (34, 6), (1786, 255), (20, 3)])
def test_inconsistent_or_too_short_announces_are_rejected(size, packets):
    d = J1939Decoder()
    cm = [32, size & 0xFF, size >> 8, packets, 0xFF, 0xE3, 0xFE, 0x00]
    assert only(d, frame(60416, 0, cm, prio=7))[1] == "tp_bad_announce"
    assert only(d, frame(60160, 0, [1] + [0] * 7, prio=7))[1] == "tp_no_session"


def test_short_packet_inside_a_transfer():
    frames = bam(ec1_payload(1109))
    short = frame(60160, 0, frames[2].data[:5], prio=7, ts=frames[2].timestamp)
    d = J1939Decoder()
    assert feed_all(d, frames[:2] + [short] + frames[3:]) == []
    assert d.counters["rejected"] == {"wrong_dlc": 1, "tp_sequence_error": 1, "tp_no_session": 2}


# ---- robustness --------------------------------------------------------------------------------------------------


def random_frames(n, seed):
    """Frames of every kind a bus or a broken node can produce, weighted towards the PGNs the decoder uses."""
    rng = random.Random(seed)
    pgns = [61444, 61445, 65272, 65262, 65269, 65265, 61440, 60416, 60160]
    t = 0.0
    out = []
    transfers = []
    while len(out) < n:
        t += rng.uniform(0.0, 0.02)
        kind = rng.randrange(12)
        size = rng.choice([8, 8, 8, 0, 1, 3, 7, 9 if kind == 0 else 8])
        data = bytes(rng.randrange(256) for _ in range(min(size, 8)))
        if kind == 0:  # random 11-bit
            out.append(can.Message(timestamp=t, arbitration_id=rng.randrange(0x800), is_extended_id=False, data=data))
        elif kind == 1:  # random 29-bit
            out.append(can.Message(timestamp=t, arbitration_id=rng.randrange(1 << 29), is_extended_id=True, data=data))
        elif kind == 2:  # remote / error frames
            out.append(
                can.Message(
                    timestamp=t,
                    arbitration_id=rng.randrange(1 << 29),
                    is_extended_id=True,
                    is_remote_frame=rng.random() < 0.5,
                    is_error_frame=rng.random() < 0.5,
                    dlc=rng.randrange(9),
                    check=False,
                )
            )
        elif kind in (3, 4, 5):  # a used PGN, random SA or the expected one, random or J1939-special values
            pgn = rng.choice(pgns[:7])
            sa = rng.choice([0x00, 0x03, 0x10, rng.randrange(256)])
            special = bytes(rng.choice([0xFF, 0xFE, 0xFB, 0xFA, 0x00, rng.randrange(256)]) for _ in range(8))
            payload = rng.choice([data, special])
            out.append(
                can.Message(
                    timestamp=t,
                    arbitration_id=adapter.can_id_of(pgn, sa, rng.randrange(8)),
                    is_extended_id=True,
                    data=payload,
                )
            )
        elif kind in (6, 7):  # TP.CM with random or plausible content, random destination
            control = rng.choice([32, 32, 16, 17, 19, 255, rng.randrange(256)])
            length = rng.choice([21, 34, 40, rng.randrange(2000)])
            packets = rng.choice([(length + 6) // 7, rng.randrange(256)]) & 0xFF
            pgn = rng.choice([adapter.EC1_PGN, adapter.EC1_PGN, 65226, rng.randrange(1 << 18)])
            cm = bytes(
                [control, length & 0xFF, (length >> 8) & 0xFF, packets, 0xFF, pgn & 0xFF, (pgn >> 8) & 0xFF, pgn >> 16]
            )
            out.append(
                can.Message(
                    timestamp=t,
                    arbitration_id=adapter.can_id_of(
                        60416, rng.choice([0, 0, rng.randrange(256)]), 7, rng.choice([0xFF, 0xFF, rng.randrange(256)])
                    ),
                    is_extended_id=True,
                    data=cm[: rng.choice([8, 8, 8, 5])],
                )
            )
        elif kind in (8, 9):  # TP.DT with mostly plausible but sometimes broken sequence numbers
            seq = rng.choice([1, 2, 3, 4, 5, 6, rng.randrange(256)])
            out.append(
                can.Message(
                    timestamp=t,
                    arbitration_id=adapter.can_id_of(
                        60160, rng.choice([0, 0, rng.randrange(256)]), 7, rng.choice([0xFF, 0xFF, rng.randrange(256)])
                    ),
                    is_extended_id=True,
                    data=bytes([seq]) + data[1:],
                )
            )
        elif kind == 10:  # a whole EC1 (engine) or RC (retarder) BAM, sometimes broken (dropped, swapped, late)
            ref_nm, late = rng.choice([1109, 2457, 0, 0xFFFF, 0xFE10]), rng.choice([0.05, 0.05, 0.8])
            transfer = (
                bam(ec1_payload(ref_nm), t0=t, dt=late)
                if rng.random() < 0.7
                else bam(rc_payload(ref_nm), pgn=adapter.RC_PGN, sa=0x10, t0=t, dt=late)
            )
            if rng.random() < 0.3:
                del transfer[rng.randrange(1, len(transfer))]
            if rng.random() < 0.3:
                i = rng.randrange(1, len(transfer) - 1)
                transfer[i], transfer[i + 1] = transfer[i + 1], transfer[i]
            if rng.random() < 0.1:  # a packet copied by a gateway
                i = rng.randrange(1, len(transfer))
                transfer.insert(i + 1, transfer[i])
            transfers.append(len(transfer))
            out.extend(transfer)
            t = transfer[-1].timestamp
        else:  # time going backwards, FD frames
            out.append(
                can.Message(
                    timestamp=t - rng.uniform(0, 5),
                    arbitration_id=rng.randrange(1 << 29),
                    is_extended_id=True,
                    is_fd=rng.random() < 0.5,
                    data=data,
                )
            )
    return out[:n]


def test_100000_random_frames_never_raise_and_every_frame_is_counted_once():
    frames = random_frames(100_000, seed=1939)
    for i, t in ((10, math.nan), (20, math.inf), (30, -math.inf)):  # a logger's broken clock
        m = frames[i]
        frames[i] = can.Message(
            timestamp=t, arbitration_id=m.arbitration_id, is_extended_id=m.is_extended_id, data=m.data, check=False
        )
    d = J1939Decoder(retarder_ref_torque_nm=2500.0)
    names = set()
    for msg in frames:
        for update in d.feed(msg):
            names.add(update.name)
            assert math.isfinite(update.value)
    c = d.counters
    assert c["frames_seen"] == 100_000
    assert c["frames_seen"] == c["frames_used"] + sum(c["rejected"].values())
    assert set(c["rejected"]) <= set(adapter.REJECT_REASONS)
    assert all(n > 0 for n in c["rejected"].values())
    # the generator reaches every reason and the decoder still finds real data in the noise
    assert set(c["rejected"]) == set(adapter.REJECT_REASONS) - {"invalid_id"}
    assert names == set(adapter.SIGNAL_NAMES)
    assert c["tp"]["ec1_received"] > 0 and c["tp"]["rc_received"] > 0 and c["tp"]["aborted"] > 0


def test_every_decoded_value_is_within_its_limits():
    d = J1939Decoder()
    for msg in random_frames(20_000, seed=5):
        for update in d.feed(msg):
            low, high = adapter.DEFAULT_LIMITS.get(update.name, (-math.inf, math.inf))
            assert low <= update.value <= high, update


# ---- encoder -----------------------------------------------------------------------------------------------------


def test_encode_returns_the_16_periodic_frames_in_order_with_the_configured_source():
    frames = OutputEncoder(source_address=0x80).encode({}, {}, {}, {}, timestamp_s=12.5)
    assert [adapter.pgn_of(m.arbitration_id) for m in frames] == list(range(0xFF40, 0xFF50))
    assert all(
        adapter.source_address(m.arbitration_id) == 0x80 and adapter.priority(m.arbitration_id) == 6 for m in frames
    )
    assert all(m.is_extended_id and len(m.data) == 8 and m.timestamp == 12.5 for m in frames)
    empty = adapter.decode_outputs(frames)
    assert set(empty["temps_c"].values()) == {None} and set(empty["levels"].values()) == {3}
    assert set(empty["ttl_s"].values()) == {None}
    assert empty["status"] == {
        "speed_valid": None,
        "torque_valid": None,
        "gear_valid": None,
        "oil_valid": None,
        "ref_torque_valid": None,
        "degraded_mode": None,
        "max_warning_level": 3,
        "oil_innovation_c": None,
        "model_oil_temp_c": None,
        "counter": 0,
        "time_base_suspect": None,
    }
    assert adapter.decode_outputs(frames, source_address=0xE5) == {}


def test_encode_clamps_and_marks_not_available():
    enc = OutputEncoder()
    temps = {
        "LI.teeth": -400.0,
        "3M.teeth": 5000.0,
        "2M.teeth": math.inf,
        "1M.teeth": math.nan,
        "CM.teeth": 80.01,
        "not-a-component": 1.0,
    }
    ttl = {"LI.teeth": -3.0, "3M.teeth": 1e9, "2M.teeth": math.inf, "1M.teeth": 12.4, "CM.teeth": 12.6}
    got = adapter.decode_outputs(enc.encode(temps, {}, ttl, {"oil_innovation_c": -5000.0}))
    assert [got["temps_c"][c] for c in PUBLISHED[:5]] == [-273.0, 1734.96875, None, None, 80.0]
    assert [got["ttl_s"][c] for c in PUBLISHED[:5]] == [0.0, 64254.0, math.inf, 12.0, 13.0]
    assert got["status"]["oil_innovation_c"] == -1000.0


def test_rolling_counter_increments_and_wraps_unless_given():
    enc = OutputEncoder()
    counters = [adapter.decode_outputs(enc.encode({}, {}, {}, {}))["status"]["counter"] for _ in range(258)]
    assert counters[:3] == [0, 1, 2] and counters[255:] == [255, 0, 1]
    assert adapter.decode_outputs(enc.encode({}, {}, {}, {"counter": 77}))["status"]["counter"] == 77


@pytest.mark.parametrize(
    "args, match",
    [
        (({"PS": "hot"}, {}, {}, {}), r"temps_c\['PS'\]"),
        (({}, {"PS": 4}, {}, {}), r"levels\['PS'\]"),
        (({}, {"PS": 1.5}, {}, {}), r"levels\['PS'\]"),
        (({}, {}, {"PS": "soon"}, {}), r"ttl_s\['PS'\]"),
        (({}, {}, {}, {"speed_vaild": True}), "unknown keys"),
        (({}, {}, {}, {"speed_valid": 2}), "speed_valid"),
        (({}, {}, {}, {"degraded_mode": 7}), "degraded_mode"),
        (({}, {}, {}, {"counter": 256}), "counter"),
    ],
)
def test_encode_rejects_values_it_cannot_represent(args, match):
    with pytest.raises(EncodeError, match=match):
        OutputEncoder().encode(*args)


def test_bad_source_address_is_a_config_error():
    for sa in (-1, 254, 255, 0x1E5, "E5"):
        with pytest.raises(ConfigError, match="source_address"):
            OutputEncoder(source_address=sa)
    with pytest.raises(ConfigError, match="source_address"):
        adapter.RigEncoder(source_address=300)


def test_outputs_over_the_virtual_bus():
    """End to end on python-can's in-process bus: what the encoder sends, a listener decodes."""
    enc = OutputEncoder()
    temps = {c: 70.0 + i for i, c in enumerate(PUBLISHED)}
    levels = {c: 1 for c in PUBLISHED}
    with (
        can.Bus(interface="virtual", channel="gbx-test", receive_own_messages=False) as tx,
        can.Bus(interface="virtual", channel="gbx-test") as rx,
    ):
        for msg in enc.encode(temps, levels, {"oil": math.inf}, {"speed_valid": True}) + [enc.encode_dm1(levels)]:
            tx.send(msg)
        received = [rx.recv(timeout=1.0) for _ in range(17)]
    assert None not in received
    got = adapter.decode_outputs(received)
    assert got["temps_c"] == temps and set(got["levels"].values()) == {1}
    assert got["ttl_s"]["oil"] == math.inf and got["status"]["speed_valid"] is True
    assert got["dm1"]["dtc"]["component"] == PUBLISHED[0] and got["dm1"]["amber_warning_lamp"] == 1
