"""Each input message's source address set on its own: config ``[can.source_address]``.

A Navistar truck sends ETC2 (gear) from SA 0x03 and TRF1 (transmission oil) from SA 0x21; with the group key
``transmission_source_address`` alone, setting it for the oil lost the gear. Shown on a real capture whose TRF1 is
moved to 0x21 in a copy (skipped without the captures) and on a synthesized log moved the same way (always runs):
both replay paths decode gear and oil with ``TRF1 = 0x21``, and without it the finding names that key.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from can_dbc.adapter import pgn_of
from firmware_model.errors import ParameterError
from firmware_model.service import ServiceOptions, build_service
from firmware_model.service.trust import ForeignSourceFinding
from tests.data_paths import SKIP_REASON, real_capture_dir
from tools.can.logsynth import synth_frames
from tools.cli import main
from tools.replay.log import replay_log

TRF1_PGN = 65272
ETC2_PGN = 61445
TABLE = "[can.source_address]\nTRF1 = 0x21\n"
LINE = re.compile(rb"^(\([^)]*\) \S+ )([0-9A-Fa-f]{8})(#.*)$", re.S)


def moved(src, dst, pgns=(TRF1_PGN,), old=0x03, new=0x21):
    """A copy of candump -L log ``src`` with the frames of ``pgns`` from SA ``old`` sent from ``new`` (the other
    senders of those PGNs, e.g. the cab node 0x31 with all bytes 0xFF, as they are); returns how many were moved."""
    n, out = 0, []
    for line in src.read_bytes().splitlines(keepends=True):
        m = LINE.match(line)
        if m:
            can_id = int(m.group(2), 16)
            if pgn_of(can_id) in pgns and can_id & 0xFF == old:
                line = m.group(1) + b"%08X" % ((can_id & ~0xFF) | new) + m.group(3)
                n += 1
        out.append(line)
    dst.write_bytes(b"".join(out))
    return n


def cfg(can):
    return type("C", (), {"can": can})()


def replay_both(log, config=None):
    """The run table and service of the whole-log path and of the frame-by-frame path (tools/replay), asserted
    equal column for column and counter for counter."""
    out = []
    for columnar in (True, False):
        svc = build_service(config, record=True, emit_frames=False, log_findings=False)
        out.append((replay_log(log, svc, columnar=columnar), svc))
    (fast, s_fast), (ref, s_ref) = out
    assert "whole log" in fast.meta["reader"] and "whole log" not in ref.meta["reader"]
    for c in ref.columns:
        assert np.array_equal(np.asarray(ref[c]), np.asarray(fast[c]), equal_nan=True), c
    assert s_fast.decoder.counters == s_ref.decoder.counters
    return out


def foreign(svc):
    return [f for f in svc.findings() if isinstance(f, ForeignSourceFinding)]


def test_the_table_sets_one_message_over_its_group_key():
    opts = ServiceOptions.from_config(
        cfg({"transmission_source_address": 0x05, "source_address": {"ETC2": 0x03, "TRF1": 0x21, "CCVS1": 0xEE}})
    )
    assert opts.expected_sa["ETC2"] == 0x03 and opts.expected_sa["TRF1"] == 0x21 and opts.expected_sa["CCVS1"] == 0xEE
    assert opts.source_address_keys["TRF1"] == "source_address.TRF1"
    assert "EEC1" not in opts.expected_sa  # the engine's keys untouched
    # the existing keys as before
    opts = ServiceOptions.from_config(cfg({"transmission_source_address": 0x21}))
    assert opts.expected_sa["ETC2"] == opts.expected_sa["TRF1"] == 0x21
    assert opts.source_address_keys["ETC2"] == "transmission_source_address"


@pytest.mark.parametrize(
    "table, match",
    [
        (
            {"TRF": 0x21},
            r"can\.source_address\.TRF: unknown message 'TRF'; known: EEC1, EC1, ETC2, TRF1, ET1, AMB, "
            r"CCVS1, ERC1, RC",
        ),
        ({"TRF1": 254}, r"can\.source_address\.TRF1 = 254 \(0xFE\) is not a J1939 source address 0\.\.253"),
        ({"TRF1": 0x121}, r"can\.source_address\.TRF1 = 289 \(0x121\) is not a J1939 source address"),
        ({"TRF1": -1}, r"can\.source_address\.TRF1 = -1 is not a J1939 source address"),
        ({"TRF1": True}, r"can\.source_address\.TRF1 = True is not a J1939 source address"),
        (
            {"TRF1": "0x21"},
            r"can\.source_address\.TRF1 = '0x21' is not a J1939 source address .*: write it without quotes, "
            r"source_address\.TRF1 = 0x21",
        ),
        (0x21, r"can\.source_address = 33 must be a table of message = address"),
    ],
)
def test_a_bad_table_entry_is_one_sentence_naming_the_key(table, match):
    with pytest.raises(ParameterError, match=match):
        ServiceOptions.from_config(cfg({"source_address": table}))
    with pytest.raises(ParameterError, match="config " + match):  # simulate --can-log reads it too
        synth_frames(None, None, config=cfg({"source_address": table}))


def test_a_bad_table_entry_exits_2_offline(tmp_path, capsys):
    (tmp_path / "bad.toml").write_text("[can.source_address]\nTRF = 0x21\n")
    (tmp_path / "x.log").write_text("(0.0) can0 0CF00400#F07D7DA02800FFFF\n")
    assert (
        main(
            [
                "replay",
                str(tmp_path / "x.log"),
                "--config",
                str(tmp_path / "bad.toml"),
                "--out",
                str(tmp_path / "x.csv"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "can.source_address.TRF: unknown message 'TRF'; known: EEC1, EC1, ETC2, TRF1" in err, err
    assert not (tmp_path / "x.csv").exists()


@pytest.fixture(scope="module")
def synth(tmp_path_factory):
    """simulate --can-log of a steady drive in gear 4 (ETC2 and TRF1 from 0x03), and a copy with TRF1 from 0x21."""
    d = tmp_path_factory.mktemp("sa")
    assert (
        main(
            [
                "simulate",
                "--cycle",
                "steady:gear=4L,rpm=1300,nm=1500,s=40",
                "--out",
                str(d / "run.csv"),
                "--can-log",
                str(d / "run.log"),
                "--quiet",
            ]
        )
        == 0
    )
    assert moved(d / "run.log", d / "navistar.log") >= 30
    (d / "table.toml").write_text(TABLE)
    (d / "group.toml").write_text("[can]\ntransmission_source_address = 0x21\n")
    return d


def test_a_synthesized_log_with_trf1_from_its_own_address_decodes_gear_and_oil(synth):
    (ref, _), _ = replay_both(synth / "run.log")
    (est, svc), _ = replay_both(synth / "navistar.log", synth / "table.toml")
    assert np.nanmin(est["gear"]) == np.nanmax(est["gear"]) == ref["gear"][-1]
    assert np.isfinite(est["oil_temp_c"][20:]).all()
    for c in ref.columns:  # the same drive as the log with both from 0x03, bit for bit
        assert np.array_equal(np.asarray(ref[c]), np.asarray(est[c]), equal_nan=True), c
    assert foreign(svc) == [] and svc.decoder.counters["rejected"].get("wrong_source_address", 0) == 0


def test_without_the_table_the_finding_names_the_key_that_breaks_nothing(synth, capsys):
    _, (_, svc) = replay_both(synth / "navistar.log")
    (f,) = foreign(svc)
    assert f.message == "TRF1" and f.source == 0x21
    assert (
        "(set [can.source_address] TRF1 = 0x21; setting [can] transmission_source_address would also move "
        "ETC2, which arrives from SA 0x03 as expected)" in f.sentence
    ), f.sentence
    # the group key set for the oil: the gear is lost, and the finding says which key keeps both
    (est, svc), _ = replay_both(synth / "navistar.log", synth / "group.toml")
    assert np.isnan(est["gear"]).all()
    (f,) = foreign(svc)
    assert (
        f.message == "ETC2"
        and "set [can.source_address] ETC2 = 0x03; changing [can] transmission_source_address would also move TRF1"
        in f.sentence
    ), f.sentence
    # the command line: exit 3 with the sentence, exit 0 with the table
    rc = main(["replay", str(synth / "navistar.log"), "--out", str(synth / "est.csv"), "--quiet"])
    assert rc == 3 and "set [can.source_address] TRF1 = 0x21" in capsys.readouterr().err
    rc = main(
        [
            "replay",
            str(synth / "navistar.log"),
            "--config",
            str(synth / "table.toml"),
            "--out",
            str(synth / "est.csv"),
            "--quiet",
        ]
    )
    assert rc == 0 and "source_address" not in capsys.readouterr().err


def test_a_whole_transmission_moved_keeps_the_group_key(synth):
    """ETC2 and TRF1 both from 0x21: nothing arrives as expected, the group key fixes both and is named."""
    assert moved(synth / "run.log", synth / "all.log", (TRF1_PGN, ETC2_PGN)) > 300
    _, (_, svc) = replay_both(synth / "all.log")
    sentences = {f.message: f.sentence for f in foreign(svc)}
    assert set(sentences) == {"ETC2", "TRF1"}
    assert all("(set [can] transmission_source_address = 0x21)" in s for s in sentences.values()), sentences


def test_simulate_sends_each_message_from_its_table_address():
    from tests.tools.test_replay_log import cycle, plant

    inp = cycle(12.0)
    fr, _ = synth_frames(inp, plant(inp), config=cfg({"source_address": {"TRF1": 0x21, "EC1": 0x01}}))
    sas = {}
    for i in fr.can_id:
        sas.setdefault(pgn_of(int(i)), set()).add(int(i) & 0xFF)
    assert sas[TRF1_PGN] == {0x21} and sas[ETC2_PGN] == {0x03} and sas[61444] == {0x00}
    assert sas[0xEC00] == {0x01}  # EC1's TP.CM from its own address


def test_a_real_capture_with_gear_and_oil_from_two_addresses(tmp_path):
    """normal.candump.log with TRF1 from SA 0x21 (its 30 frames from SA 3; SA 49's all-0xFF frames kept): with
    TRF1 = 0x21 both replay paths decode gear 2-4 and oil 77.3-78.2 degC, as on the capture as recorded."""
    d = real_capture_dir()
    if d is None:
        pytest.skip(SKIP_REASON)
    log = tmp_path / "navistar.candump.log"
    assert moved(d / "normal.candump.log", log) == 30
    assert b"18FEF831#FFFFFFFFFFFFFFFF" in log.read_bytes()  # the cab node's TRF1 as it was
    (tmp_path / "truck.toml").write_text(TABLE)
    (est, svc), _ = replay_both(log, tmp_path / "truck.toml")
    gear, oil = np.asarray(est["gear"]), np.asarray(est["oil_temp_c"])
    assert np.isfinite(gear).all() and gear.min() == 2 and gear.max() == 4
    assert np.isfinite(oil[10:]).all() and 77.3 <= np.nanmin(oil) and np.nanmax(oil) <= 78.2
    assert not [f for f in foreign(svc) if f.message in ("ETC2", "TRF1")]
    (orig, _), _ = replay_both(d / "normal.candump.log")  # the capture as recorded, bit for bit
    for c in orig.columns:
        assert np.array_equal(np.asarray(orig[c]), np.asarray(est[c]), equal_nan=True), c
    # without the table: the oil is lost and the finding names the TRF1 key
    _, (_, svc) = replay_both(log)
    (f,) = [f for f in foreign(svc) if f.message == "TRF1"]
    assert f.source == 0x21 and "set [can.source_address] TRF1 = 0x21;" in f.sentence, f.sentence


def test_fleet_reads_the_table_from_a_logs_config(synth):
    """fleet (tools/fleet/run.py): the same log untrusted with the finding's advice without the table, trusted with
    it."""
    from tools.fleet.manifest import LogEntry, log_key
    from tools.fleet.run import process_batch

    log = synth / "navistar.log"
    rows = {
        cfg: process_batch([LogEntry(log, "navistar", None, cfg, None, log_key(log))])[0]
        for cfg in (None, str(synth / "table.toml"))
    }
    (kind, bare), (kind2, table) = rows[None], rows[str(synth / "table.toml")]
    assert kind == kind2 == "ok"
    assert not bare["trusted"] and "set [can.source_address] TRF1 = 0x21" in bare["trust_warnings"]
    assert table["trusted"] and table["trust_warnings"] == "" and table["degraded_share"] < bare["degraded_share"]


def test_the_advice_lists_every_input_the_group_key_would_move():
    """EEC1 from 0x01 while EC1, ET1 and CCVS1 arrive from the engine's 0x00: engine_source_address would move
    them all, so EEC1's own key is advised; a message that a narrower key already sets is not moved by it."""
    from can_dbc.decoder import J1939Decoder
    from firmware_model.service.trust import foreign_findings

    counters = {
        "foreign_source": {"EEC1": {0x01: 500}},
        "foreign_source_data": {"EEC1": {0x01: 500}},
        "arrivals": {"ET1": 10, "CCVS1": 10},
        "tp": {"ec1_received": 3},
    }
    expected = J1939Decoder().expected_sa
    (f,) = foreign_findings(counters, expected)
    assert (
        "(set [can.source_address] EEC1 = 0x01; setting [can] engine_source_address would also move EC1 "
        "(SA 0x00), ET1 (SA 0x00) and CCVS1 (SA 0x00), which arrive as expected)" in f.sentence
    ), f.sentence
    (f,) = foreign_findings(
        counters, {**expected, "CCVS1": 0x00}, {"CCVS1": 0x00}, {"CCVS1": "vehicle_speed_source_address"}
    )
    assert "would also move EC1 (SA 0x00) and ET1 (SA 0x00), which" in f.sentence, f.sentence
    counters["arrivals"], counters["tp"] = {}, {}  # nothing else arrives: the group key is fine
    (f,) = foreign_findings(counters, expected)
    assert "(set [can] engine_source_address = 0x01)" in f.sentence, f.sentence
