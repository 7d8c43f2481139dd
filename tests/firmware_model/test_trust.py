"""The CAN service says when its outputs cannot be trusted (firmware_model/service/trust.py): a time base that runs
several times too fast or too slow, inputs that come from unexpected source addresses, a large degraded share."""

from __future__ import annotations

import logging
import re

import can
import pytest

from can_dbc.adapter import decode_outputs, pgn_of
from firmware_model.service import NOMINAL_PERIOD_S
from firmware_model.service.trust import (
    DEGRADED_UNTRUSTED_SHARE,
    DEGRADED_WARN_SHARE,
    PERIOD_RANGE_S,
    DegradedFinding,
    ForeignSourceFinding,
    Severity,
    TimeBaseFinding,
    degraded_finding,
    untrusted,
    window_ratio,
)

from .test_can_service import frame, service, traffic, trf1

STATUS_PGN = 0xFF4F
LOGGER = "gearbox_vsensor.can_service"


def scaled(frames, factor, t0=0.0):
    """The frames with their time since ``t0`` divided by ``factor`` (a bus replayed ``factor`` x faster whose
    frames are stamped on arrival)."""
    out = []
    for m in frames:
        out.append(
            can.Message(
                timestamp=t0 + (m.timestamp - t0) / factor,
                arbitration_id=m.arbitration_id,
                is_extended_id=True,
                data=m.data,
            )
        )
    return out


def statuses(out):
    """(timestamp, time_base_suspect) of every GBX_STATUS frame sent."""
    return [
        (m.timestamp, decode_outputs([m])["status"]["time_base_suspect"])
        for m in out
        if pgn_of(m.arbitration_id) == STATUS_PGN
    ]


def test_the_slowest_periods_are_the_services_staleness_periods():
    assert {m: hi for m, (_, hi) in PERIOD_RANGE_S.items()} == {m: NOMINAL_PERIOD_S[m] for m in PERIOD_RANGE_S}


def test_real_time_traffic_is_not_suspect_and_the_status_bit_stays_no_finding(caplog):
    svc = service()
    with caplog.at_level(logging.INFO, logger=LOGGER):
        out = svc.feed_all(traffic(0.0, 45.0))
    tb = svc.counters["time_base"]
    assert tb["windows_checked"] >= 4 and tb["windows_suspect"] == 0 and not tb["suspect"]
    assert not [f for f in svc.findings() if f.kind == "time_base"]
    assert {s for _, s in statuses(out)} == {None}
    status = [m for m in out if pgn_of(m.arbitration_id) == STATUS_PGN][-1]
    assert status.data[6] == 0xFF  # byte 7 as before the signal existed
    assert not [r for r in caplog.records if "time base" in r.getMessage()]


def test_traffic_ten_times_too_fast_is_flagged_once_with_the_ratio_and_the_likely_cause(caplog):
    svc = service()
    with caplog.at_level(logging.INFO, logger=LOGGER):
        out = svc.feed_all(scaled(traffic(0.0, 450.0), 10.0))  # 45 s of frame time
    tb = svc.counters["time_base"]
    assert tb["suspect"] and tb["windows_suspect"] >= 3
    lines = [r for r in caplog.records if "time base suspect" in r.getMessage()]
    assert len(lines) == 1 and lines[0].levelno == logging.WARNING
    text = lines[0].getMessage()
    assert (
        "10.0x faster" in text
        and "the bus is replayed faster than real time, and frames are stamped on arrival" in text
    )
    found = [f for f in svc.findings() if isinstance(f, TimeBaseFinding)]
    assert len(found) == 1 and found[0].severity == Severity.UNTRUSTED and found[0].direction == "faster"
    assert found[0].ratio == pytest.approx(10.0, rel=0.05)
    # GBX_STATUS: "no finding" for the first 30 s of frame time (three windows), "suspect" from then on
    marks = statuses(out)
    assert {s for t, s in marks if t < 29.9} == {None}
    assert {s for t, s in marks if t > 30.1} == {True}
    suspect = [m for m in out if pgn_of(m.arbitration_id) == STATUS_PGN][-1]
    assert suspect.data[6] == 0xFD


def test_traffic_four_times_too_slow_is_flagged_as_slower():
    svc = service()
    svc.feed_all(scaled(traffic(0.0, 12.0), 0.25))  # 48 s of frame time
    found = [f for f in svc.findings() if isinstance(f, TimeBaseFinding)]
    assert len(found) == 1 and found[0].direction == "slower" and found[0].ratio == pytest.approx(4.0, rel=0.1)
    assert "replayed slower than real time" in found[0].sentence


def test_a_burst_of_buffered_frames_is_not_a_wrong_time_base():
    """100 s of traffic delivered within 10 s of frame time (a logger flushing its buffer), real time around it:
    at most two windows look fast, three in a row are needed."""
    before = traffic(0.0, 20.0)
    burst = scaled([m for m in traffic(20.0, 120.0)], 10.0, t0=20.0)
    after = [
        can.Message(timestamp=m.timestamp - 90.0, arbitration_id=m.arbitration_id, is_extended_id=True, data=m.data)
        for m in traffic(120.0, 170.0)
    ]
    svc = service()
    svc.feed_all(before + burst + after)
    tb = svc.counters["time_base"]
    assert 1 <= tb["windows_suspect"] <= 2 and not tb["suspect"] and tb["finding"] is None


def test_a_single_odd_sender_is_no_verdict():
    # ETC2 five times too fast while EEC1 and TRF1 keep their periods: the messages disagree, nothing is judged
    assert window_ratio({"EEC1": 1000, "ETC2": 500, "TRF1": 10}, 10.0) is None
    low, high, periods = window_ratio({"EEC1": 1000, "ETC2": 100, "TRF1": 10}, 10.0)
    assert low <= 1.0 <= high and periods["ETC2"] == pytest.approx(0.1)
    assert window_ratio({"EEC1": 3, "TRF1": 2}, 10.0) is None  # too few frames for a rate


def test_a_wrong_engine_source_address_is_named_with_the_degraded_share(caplog):
    """EEC1 from 0x00 while [can] expects 0x01: the sensor holds its inputs the whole run; the finding names the
    message, PGN, both addresses and the config key; the cab node's frames of 0xFF bytes are not a finding."""
    frames = traffic(0.0, 30.0) + [frame(t + 0.5, 65272, 0x31, [0xFF] * 8) for t in range(30)]
    frames.sort(key=lambda m: m.timestamp)
    svc = service(expected_sa={"EEC1": 0x01}, counter_log_period_s=10.0)
    with caplog.at_level(logging.INFO, logger=LOGGER):
        svc.feed_all(frames)
    d = svc.decoder.counters
    assert d["foreign_source"] == {"EEC1": {0x00: 3000}, "TRF1": {0x31: 30}}
    assert d["foreign_source_data"] == {"EEC1": {0x00: 3000}} and d["arrivals"]["TRF1"] == 30
    findings = svc.findings()
    assert untrusted(findings)
    foreign = [f for f in findings if isinstance(f, ForeignSourceFinding)]
    assert len(foreign) == 1 and foreign[0].severity == Severity.UNTRUSTED
    assert foreign[0].sentence.startswith(
        "EEC1 (PGN 61444) arrived 3000 times from SA 0x00 but [can] expects "
        "SA 0x01 (engine_source_address): check the source addresses"
    )
    degraded = [f for f in findings if isinstance(f, DegradedFinding)]
    assert len(degraded) == 1 and degraded[0].share > 0.95 and "engine speed 100 %" in degraded[0].sentence
    # logged while running, each finding once although three counter periods passed
    warned = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert sum(m.startswith("EEC1 (PGN 61444)") for m in warned) == 1
    assert sum(m.startswith("the sensor ran degraded") for m in warned) == 1


def test_the_right_addresses_give_no_finding():
    frames = traffic(0.0, 30.0) + [frame(t + 0.5, 65272, 0x31, [0xFF] * 8) for t in range(30)]
    svc = service()
    svc.feed_all(sorted(frames, key=lambda m: m.timestamp))
    assert svc.findings() == []


def test_a_second_sender_beside_the_expected_one_is_only_a_note():
    frames = traffic(0.0, 30.0, oil=80.0) + [trf1(t + 0.5, 60.0) for t in range(30)]
    for m in frames[-30:]:
        m.arbitration_id = (m.arbitration_id & ~0xFF) | 0x05
    svc = service()
    svc.feed_all(sorted(frames, key=lambda m: m.timestamp))
    # the run is fine: no finding at all (a second sender is only reported when the run was degraded)
    assert svc.findings() == []
    assert svc.decoder.counters["foreign_source_data"] == {"TRF1": {0x05: 30}}


def test_a_sender_that_moved_to_another_address_is_not_called_a_second_sender():
    """The transmission controller's TRF1 moving from SA 0x03 to 0x04 halfway (a new address claim), after which
    the oil is not used, is a sender that moved, untrusted (a primary input), not "a second sender" note; on both
    decoders (frame by frame and columnar)."""
    from can_dbc.columnar import FrameColumns, decode_columns
    from firmware_model.service.trust import foreign_findings

    frames = traffic(0.0, 60.0, oil=80.0)
    for m in frames:
        if m.timestamp > 30.0 and pgn_of(m.arbitration_id) == 65272:
            m.arbitration_id = (m.arbitration_id & ~0xFF) | 0x04
    svc = service()
    svc.feed_all(frames)
    moved = [f for f in svc.findings() if f.kind == "foreign_source"]
    assert len(moved) == 1 and moved[0].moved and moved[0].expected_before == moved[0].expected_frames == 30
    assert "the sender moved to SA 0x04" in moved[0].sentence and "second sender" not in moved[0].sentence
    assert moved[0].severity == Severity.UNTRUSTED
    assert svc.decoder.counters["foreign_first_arrivals"] == {"TRF1": {0x04: 30}}
    dec = type(svc.decoder)(svc.decoder.expected_sa)  # the columnar decoder counts the same
    decode_columns(FrameColumns.from_messages(frames), dec)
    assert dec.counters["foreign_first_arrivals"] == {"TRF1": {0x04: 30}}
    # both at once: a second sender, as before
    both = traffic(0.0, 30.0, oil=80.0) + [trf1(t + 0.5, 60.0) for t in range(30)]
    for m in both[-30:]:
        m.arbitration_id = (m.arbitration_id & ~0xFF) | 0x05
    svc = service()
    svc.feed_all(sorted(both, key=lambda m: m.timestamp))
    f = foreign_findings(svc.decoder.counters, svc.decoder.expected_sa)
    assert len(f) == 1 and not f[0].moved and "a second sender" in f[0].sentence


def test_an_engine_whose_messages_all_moved_is_told_its_group_key():
    """Every engine message moving from SA 0x00 to 0x01 halfway (a new address claim): EEC1's finding said setting
    engine_source_address 'would also move EC1, ET1, CCVS1 and AMB ..., which arrive as expected' and EC1 was called
    'a second sender', though all had moved (a new user's review). The group key, and EC1 moved too."""
    et1 = [frame(t + 0.3, 65262, 0x00, [125] + [0xFF] * 7) for t in range(60)]  # the coolant, 85 degC
    frames = sorted(traffic(0.0, 60.0, oil=80.0) + et1, key=lambda m: m.timestamp)
    for m in frames:
        if m.timestamp > 30.0 and (m.arbitration_id & 0xFF) == 0x00:
            m.arbitration_id = (m.arbitration_id & ~0xFF) | 0x01
    svc = service()
    svc.feed_all(frames)
    found = {f.message: f for f in svc.findings() if f.kind == "foreign_source"}
    assert found["EEC1"].moved and "set [can] engine_source_address = 0x01" in found["EEC1"].sentence
    assert "would also move" not in found["EEC1"].sentence
    if "EC1" in found:  # (the traffic's reference torque transfers, when it sends them)
        assert found["EC1"].moved and "second sender" not in found["EC1"].sentence


def test_a_second_sender_at_the_expected_address_is_named_by_its_priority():
    """A second EEC1 at SA 0x00 with priority 6 (the engine's is 3) carrying 600 rpm: 39 % of the steps read 600
    rpm, exit 0, no word (a new user's review). Two priorities from one address are two senders: a warning, on both
    decoders (frame by frame and columnar); one priority, none."""
    import copy

    from can_dbc.columnar import FrameColumns, decode_columns
    from firmware_model.service.trust import two_senders_findings

    frames = traffic(0.0, 30.0, oil=80.0)
    second = [copy.copy(m) for m in frames if pgn_of(m.arbitration_id) == 61444]
    for m in second:
        m.arbitration_id = (m.arbitration_id & ~(7 << 26)) | (6 << 26)
        m.timestamp += 0.001
    svc = service()
    svc.feed_all(sorted(frames + second, key=lambda m: m.timestamp))
    [f] = [f for f in svc.findings() if f.kind == "two_senders"]
    assert f.message == "EEC1" and f.sa == 0x00 and "at 2 J1939 priorities" in f.sentence
    assert f.severity == Severity.WARNING
    dec = type(svc.decoder)(svc.decoder.expected_sa)
    decode_columns(FrameColumns.from_messages(sorted(frames + second, key=lambda m: m.timestamp)), dec)
    assert dec.counters["priorities"] == svc.decoder.counters["priorities"]
    svc = service()
    svc.feed_all(frames)
    assert two_senders_findings(svc.decoder.counters, svc.decoder.expected_sa) == []


@pytest.mark.parametrize(
    "modes, severity",
    [({0: 90, 3: 10}, Severity.NOTE), ({0: 70, 1: 30}, Severity.WARNING), ({0: 40, 2: 60}, Severity.UNTRUSTED)],
)
def test_degraded_share_thresholds(modes, severity):
    f = degraded_finding(modes, {"gear": modes.get(2, 0)})
    assert f.severity == severity
    assert DEGRADED_WARN_SHARE < DEGRADED_UNTRUSTED_SHARE
    assert f"of {sum(modes.values())} steps" in f.sentence


def test_short_frames_and_a_missing_reference_torque_are_named_as_causes():
    """The causes tell ETC2 never sent from ETC2 sent with 5 data bytes ("gear 100 %" alone does not), name an ET1
    with 5 bytes as why the coolant is at its default, and name a missing EC1 in a whole-log replay too."""
    from firmware_model.service.trust import CoolantFinding

    frames = traffic(0.0, 30.0) + [frame(t + 0.7, 65262, 0x00, [0x78, 0xFF, 0xFF, 0xFF, 0xFF]) for t in range(30)]
    for m in frames:
        if pgn_of(m.arbitration_id) == 61445:  # ETC2 with 5 data bytes (the gear is in byte 4)
            m.data, m.dlc = m.data[:5], 5
    svc = service()
    svc.feed_all(sorted(frames, key=lambda m: m.timestamp))
    assert svc.decoder.counters["short_frames"]["ETC2"] > 250 and svc.decoder.counters["short_frames"]["ET1"] == 30
    findings = svc.findings()
    degraded = next(f for f in findings if isinstance(f, DegradedFinding))
    assert "gear: " in degraded.sentence and "ETC2 frames came with fewer than 8 data bytes" in degraded.sentence
    coolant = next(f for f in findings if isinstance(f, CoolantFinding))
    assert coolant.severity == Severity.WARNING and "30 ET1 frames came with fewer than 8" in coolant.sentence
    svc = service(configured_ref_torque_nm=None)  # neither EC1 nor a configured reference
    svc.feed_all(traffic(0.0, 30.0))
    degraded = next(f for f in svc.findings() if isinstance(f, DegradedFinding))
    assert "no engine reference torque arrived (EC1" in degraded.sentence
    assert "engine_reference_torque_nm" in degraded.sentence


def test_a_gear_the_map_leaves_out_is_a_missing_gear_with_its_cause():
    """ETC2 gears 14-16 of a 16-speed box, or a gear_map without them, make the sensor degraded: the warning's list
    of missing inputs names the gear (counted after the mapping, not before)."""
    svc = service()
    svc.feed_all(traffic(0.0, 30.0, gear=16))
    assert svc.counters["gear_unmapped_steps"] > 250 and svc.counters["stale_steps"].get("gear", 0) < 10
    degraded = next(f for f in svc.findings() if isinstance(f, DegradedFinding))
    assert re.search(r"frozen\): [^(]*gear \d+ %", degraded.sentence) and "set [can] gear_map" in degraded.sentence


def test_a_start_without_an_oil_reading_is_a_note_that_names_initial_temp():
    """A log cut mid-drive without TRF1 starts every part at ambient (80 K below the truck): a note says so and
    names initial_temp, the way to give the start."""
    from firmware_model.service.trust import StartFinding

    frames = [m for m in traffic(0.0, 30.0) if pgn_of(m.arbitration_id) != 65272]
    svc = service()
    svc.feed_all(frames)
    assert svc.counters["started_without_oil"] is True
    note = next(f for f in svc.findings() if isinstance(f, StartFinding))
    assert note.severity == Severity.NOTE and "--initial-temp" in note.sentence
    svc = service()
    svc.feed_all(traffic(0.0, 30.0))
    assert svc.counters["started_without_oil"] is False
    assert not any(isinstance(f, StartFinding) for f in svc.findings())


def test_an_input_sent_only_empty_from_another_node_is_not_called_absent():
    """The cause of a missing input names frames that came only from other source addresses with nothing in them
    (e.g. all-0xFF TRF1 from 0x31, not "no TRF1 frame arrived"); with no frame at all it still says so."""
    from firmware_model.service.trust import input_causes

    counters = {"arrivals": {"EEC1": 100}, "foreign_source": {"TRF1": {0x31: 170}}, "foreign_source_data": {}}
    causes = input_causes(counters, {"oil_temp_c": 100}, 100)
    assert causes == [
        "oil temperature: no TRF1 frame arrived from its expected source address; 170 came from 0x31 "
        "with no usable value (not available)"
    ]
    assert input_causes({"arrivals": {}}, {"oil_temp_c": 100}, 100) == ["oil temperature: no TRF1 frame arrived"]


def test_a_vehicle_speed_from_the_tachograph_is_set_by_its_own_key():
    """CCVS1 from the tachograph (0xEE): the finding names vehicle_speed_source_address, which moves CCVS1 alone
    (not engine_source_address, which would move EEC1 and EC1 too)."""
    from firmware_model.service import ServiceOptions

    frames = traffic(0.0, 30.0) + [frame(t + 0.3, 65265, 0xEE, [0, 0, 50, 0, 0, 0, 0, 0]) for t in range(30)]
    frames.sort(key=lambda m: m.timestamp)
    svc = service(counter_log_period_s=10.0)
    svc.feed_all(frames)
    foreign = [f for f in svc.findings() if isinstance(f, ForeignSourceFinding) and f.message == "CCVS1"]
    assert len(foreign) == 1 and "set [can] vehicle_speed_source_address" in foreign[0].sentence, foreign
    opts = ServiceOptions.from_config(
        type("C", (), {"can": {"vehicle_speed_source_address": 0xEE, "coolant_source_address": 0x05}})()
    )
    assert opts.expected_sa["CCVS1"] == 0xEE and opts.expected_sa["ET1"] == 0x05
    assert "EEC1" not in opts.expected_sa and "EC1" not in opts.expected_sa
    opts = ServiceOptions.from_config(
        type("C", (), {"can": {"engine_source_address": 0x01, "vehicle_speed_source_address": 0xEE}})()
    )
    assert opts.expected_sa["EEC1"] == 0x01 and opts.expected_sa["CCVS1"] == 0xEE


def test_a_message_slower_than_the_staleness_rule_is_named_with_the_stale_factor_that_accepts_it():
    """EEC1 down-sampled to 10 Hz by a logger (J1939: 10-20 ms) makes 40 % of the steps stale: the cause names the
    mean period and the [can] stale_factor that accepts it, not only "missing, stale", once per message; at its
    J1939 rate nothing is said."""
    from firmware_model.service.trust import input_causes

    counters = {"arrivals": {"EEC1": 1000}, "tp": {"ec1_received": 20}}
    causes = input_causes(counters, {"engine_speed_rpm": 400, "engine_torque_nm": 400}, 1000)
    assert causes[0] == (
        "engine speed: EEC1 arrived every 100 ms on average, while a value older than 3 x its J1939 "
        "period (20 ms) is stale (a logger that down-samples, or a slow node?): [can] stale_factor = "
        "8 accepts it"
    )
    assert causes[1] == "engine torque: EEC1 as slow (above)"
    assert input_causes({"arrivals": {"EEC1": 5000}}, {"engine_speed_rpm": 400}, 1000) == []
    assert input_causes(counters, {"engine_speed_rpm": 400}, 1000, stale_factor=8.0) == []
    # at its own 20 ms for a quarter of the run, then absent: the same mean period, but no rate to accept
    gaps = input_causes({"arrivals": {"EEC1": 1250}, "tp": {"ec1_received": 20}}, {"engine_speed_rpm": 750}, 1000)
    assert not any("stale_factor" in c for c in gaps), gaps


def test_the_stale_factor_advice_never_names_a_value_the_option_refuses():
    """A message far slower than any [can] stale_factor accepts (a log in milliseconds: EEC1 every 926 ms of steps)
    is said without advice: it used to say "stale_factor = 70 accepts it", which ServiceOptions refuses (1..20).
    Every factor the advice names is one the option takes."""
    from firmware_model.service import ServiceOptions
    from firmware_model.service.options import STALE_FACTOR_MAX
    from firmware_model.service.trust import input_causes

    steps = 108685
    slow = input_causes({"arrivals": {"EEC1": 11733}, "tp": {"ec1_received": 20}}, {"engine_speed_rpm": steps}, steps)
    assert len(slow) == 1 and "stale_factor =" not in slow[0], slow
    assert f"far slower than any [can] stale_factor (at most {STALE_FACTOR_MAX:g}) accepts" in slow[0]
    for arrivals in (100, 200, 400, 700, 1000):  # EEC1 at 1000 ms down to 100 ms over 1000 steps
        stale = int(1000 * (1.0 - 0.06 / (100.0 / arrivals)))
        for cause in input_causes({"arrivals": {"EEC1": arrivals}}, {"engine_speed_rpm": stale}, 1000):
            if "stale_factor = " in cause:
                factor = float(cause.split("stale_factor = ")[1].split()[0])
                assert ServiceOptions(stale_factor=factor).stale_factor == factor


def test_a_whole_log_about_1000x_too_slow_looks_like_milliseconds():
    """Every input message 1000x slower than its J1939 period over the whole log (a log in milliseconds read as
    seconds: EEC1 every 15 "s", too few frames for any 10 s window of the time-base check) is said; 10x slower (the
    time-base check's), at its rate, or one message alone that slow (a log mostly paused agrees on no ratio) is not."""
    from firmware_model.service.trust import milliseconds_finding

    at_rate = {"EEC1": 9000, "ETC2": 1800, "TRF1": 180, "ET1": 180, "AMB": 180, "CCVS1": 180, "ERC1": 1800}
    found = milliseconds_finding(at_rate, 180_000.0, 12370)
    assert found is not None and found.severity == Severity.UNTRUSTED and 700 < found.ratio < 1400
    assert found.sentence.startswith("the log's time stamps look like milliseconds, not seconds: over its 180000 s")
    assert "ETC2 every 100 s against 100 ms" in found.sentence and "12370 of the gaps" in found.sentence
    assert milliseconds_finding(at_rate, 180.0) is None
    assert milliseconds_finding(at_rate, 1800.0) is None
    assert milliseconds_finding({**at_rate, "EEC1": 9}, 180.0) is None


def test_a_run_without_any_oil_reading_is_told_how_to_model_the_oil_by_request():
    """A table without oil_temp_c is degraded throughout (the oil modelled as a fault); the sentence says how to ask
    for the model instead. A run missing the oil for part of the time gets no such advice."""
    from firmware_model.components import MODE_NORMAL, MODE_OIL_MODEL
    from firmware_model.service.degraded import degraded_finding

    whole = degraded_finding({MODE_OIL_MODEL: 600}, {"oil_valid": 600})
    part = degraded_finding({MODE_OIL_MODEL: 400, MODE_NORMAL: 200}, {"oil_valid": 400})
    assert 'oil_mode = "model"' in whole.sentence and "oil_mode" not in part.sentence


def test_an_engine_or_exhaust_retarder_s_erc1_is_left_out_rightly_not_advised_in():
    """The real captures' ERC1 from SA 0x29 and 0x0F (J1939's exhaust and engine retarders) came with the advice
    "set [can] retarder_source_address = 0x29", which would feed an engine brake's heat into the gearbox."""
    from firmware_model.service.trust import ForeignSourceFinding

    f = ForeignSourceFinding("ERC1", 61440, 0x29, 300, 300, 0x10, 0, "retarder_source_address", False, False)
    assert "J1939's preferred address of the exhaust retarder, not the driveline retarder (SA 0x10)" in f.sentence
    assert "left out, rightly" in f.sentence and f.severity == Severity.NOTE
    other = ForeignSourceFinding("ERC1", 61440, 0x11, 300, 300, 0x10, 0, "retarder_source_address", False, False)
    assert "left out, rightly" not in other.sentence and "set [can] retarder_source_address = 0x11" in other.sentence
