"""The whole-log path (can_dbc.columnar, firmware_model.service.columnar, tools.replay.columns) against the frame
path: the same run table bit for bit and the same counters, on real captures, on synthesized logs with every fault
the service handles, and on hostile traffic."""

from __future__ import annotations

import can
import numpy as np
import pytest

from can_dbc.columnar import FrameColumns, decode_columns
from can_dbc.decoder import J1939Decoder
from firmware_model.errors import InputError
from firmware_model.service import build_service
from firmware_model.service.columnar import run_columns
from tests.data_paths import CAPTURE_FILES, SKIP_REASON, real_capture_dir
from tools.can.logfaults import FAULT_KINDS, inject
from tools.can.logsynth import synth_frames
from tools.replay.columns import parse_candump, read_columns
from tools.replay.log import replay_log
from tools.runtable import RunTable

from .test_can_service import random_frames


def _service(**overrides):
    return build_service(None, record=True, emit_frames=False, log_findings=False, **overrides)


def assert_same(path, **overrides):
    """The frame path and the whole-log path on one log: every column and counter equal."""
    s_frames, s_cols = _service(**overrides), _service(**overrides)
    ref = replay_log(path, s_frames, columnar=False)
    fast = replay_log(path, s_cols, columnar=True)
    assert "whole log" in fast.meta["reader"]
    assert list(ref.columns) == list(fast.columns)
    for c in ref.columns:
        assert np.array_equal(np.asarray(ref[c]), np.asarray(fast[c]), equal_nan=True), c
    assert s_frames.counters == s_cols.counters
    assert s_frames.decoder.counters == s_cols.decoder.counters
    return ref, s_frames


def _cycle(seconds=240.0):
    t = np.arange(0.0, seconds, 0.1)
    return RunTable(
        {
            "time_s": t,
            "engine_speed_rpm": 1100.0 + 500.0 * np.sin(t / 9.0),
            "engine_torque_nm": 900.0 + 700.0 * np.cos(t / 13.0),
            "gear": np.clip(8 + np.round(3 * np.sin(t / 30.0)), 1, 12),
            "ambient_temp_c": np.full(t.size, 20.0),
            "coolant_temp_c": np.full(t.size, 85.0),
            "vehicle_speed_kmh": np.full(t.size, 60.0),
            "retarder_torque_nm": np.where((t > 100) & (t < 130), 800.0, 0.0),
        }
    )


@pytest.fixture(scope="module")
def drive():
    from tests.tools.can_fixtures import plant_output

    inp = _cycle()
    return synth_frames(inp, plant_output(inp, oil0_c=60.0, oil_rate_k_s=0.05), start_timestamp_s=1.7e9).frames


def _write(msgs, path):
    with can.Logger(path) as w:
        for m in msgs:
            w.on_message_received(m)
    return path


@pytest.mark.parametrize("kind", FAULT_KINDS)
def test_each_fault_gives_the_same_table_and_counters(tmp_path, drive, kind):
    path = _write(inject(drive, [kind], seed=3), tmp_path / f"{kind}.log")
    ref, svc = assert_same(path)
    assert ref.n > 1000
    if kind.startswith("jump_"):
        assert svc.counters["time_jumps"] == 1


def test_every_fault_at_once_with_other_settings(tmp_path, drive):
    path = _write(inject(drive, FAULT_KINDS, seed=5), tmp_path / "all.log")
    ref, svc = assert_same(path)
    counters = svc.decoder.counters
    assert svc.counters["time_jumps"] >= 1 and svc.counters["stale_steps"]
    for reason in (
        "error_frame",
        "remote_frame",
        "not_extended_id",
        "fd_frame",
        "wrong_source_address",
        "wrong_dlc",
        "unknown_pgn",
    ):
        assert counters["rejected"].get(reason, 0) > 0, reason
    assert {"not_available", "error_value", "out_of_range"} <= {
        r for v in counters["signal_rejected"].values() for r in v
    }
    assert counters["tp"]["ec1_received"] > 0
    assert_same(
        path,
        gear_map={g: g - 1 for g in range(2, 13)},
        configured_ref_torque_nm=2600.0,
        max_catchup_steps=5,
        stale_factor=1.5,
        init_wait_s=0.5,
    )
    assert_same(path, expected_sa={"EEC1": None, "TRF1": 0x03})


def test_hostile_traffic_through_both_paths(tmp_path):
    msgs = list(random_frames(30_000, seed=7))
    cols = FrameColumns.from_messages(msgs)
    s_frames = _service(configured_ref_torque_nm=2500.0)
    s_frames.feed_all(msgs)
    s_cols = _service(configured_ref_torque_nm=2500.0)
    out = run_columns(s_cols, cols)
    ref = s_frames.recorded()
    assert list(ref) == list(out)
    for c in ref:
        assert np.array_equal(ref[c], out[c], equal_nan=True), c
    assert s_frames.counters == s_cols.counters and s_frames.decoder.counters == s_cols.decoder.counters


def test_the_decoder_over_columns_gives_every_value_of_the_frame_path(drive):
    msgs = inject(drive, ("hostile", "foreign_source", "not_available", "jitter"), seed=1)
    one = J1939Decoder(rig=True)
    by_frame: dict = {}
    for i, m in enumerate(msgs):
        for u in one.feed(m):
            by_frame.setdefault(u.name, []).append((i, u.timestamp_s, float(u.value)))
    other = J1939Decoder(rig=True)
    decoded = decode_columns(FrameColumns.from_messages(msgs), other)
    assert one.counters == other.counters
    assert one.ec1_ref_torque_nm == other.ec1_ref_torque_nm
    assert set(by_frame) == set(decoded.tracks)
    for name, rows in by_frame.items():
        track = decoded.tracks[name]
        assert np.array_equal(np.array(rows), np.column_stack([track.frame, track.time_s, track.value])), name


@pytest.mark.parametrize("name", CAPTURE_FILES)
def test_real_captures_give_the_same_table_and_counters(name):
    d = real_capture_dir()
    if d is None:
        pytest.skip(SKIP_REASON)
    assert read_columns(d / name).reader == "numpy candump"
    assert_same(d / name)


LINES = [
    b"(1543509533.000838) can0 18FEF100#FFFF07FFFFFFFFFF\n",
    b"(0.5) vcan0 0CF00400#1122334455667788 R\n",
    b"(12) can1 123#0102\n",
    b"(.25) x 18FEEE00# T\n",
    b"(99999999999.999999) can0 18FEF8E5#aabbccddeeff0011\n",
    b"(3.14159265358979323) can0 18FEF8E5#AABBCCDDEEFF0011\n",
    b"(7.000001) can0 20000080#0000000000000000\n",
    b"(7.5) can0 1FFFFFFF#00\n",
]


@pytest.mark.parametrize("line", LINES)
def test_candump_lines_parse_exactly_as_python_can_reads_them(tmp_path, line):
    path = tmp_path / "one.log"
    path.write_bytes(line * 3)
    cols = parse_candump(path.read_bytes())
    assert cols is not None
    ref = FrameColumns.from_messages(can.LogReader(path))
    for field in ("timestamp_s", "can_id", "flags", "dlc", "length", "data"):
        assert np.array_equal(getattr(cols, field), getattr(ref, field)), field


@pytest.mark.parametrize(
    "text",
    [
        b"(1.0) can0 18FEF100#1122 R\n(1.1) can0 0CF00400#R\n",
        b"(1.0) can0 18FEF100##1112233\n",
        b"(1.0)\tcan0 18FEF100#11\n",
        b"(1.0) can0 18FEF100#112\n",
        b"(1e3) can0 18FEF100#11\n",
        b"(1.0) can0 18FEF100#1122\r\n",
        b"# a comment\n(1.0) can0 18FEF100#11\n",
        b"(1.0) can0 18FEF100#11\n(2.0) can0 18FE",
    ],
)
def test_other_candump_forms_are_left_to_python_can(tmp_path, text):
    """Remote and FD frames, tabs, odd hex, exponents, CRLF, comments, a truncated last line: python-can reads the
    file (its frames, or its error as the frame path reports it)."""
    assert parse_candump(text) is None
    path = tmp_path / "odd.log"
    path.write_bytes(text)
    try:
        ref = FrameColumns.from_messages(can.LogReader(path))
    except Exception:
        with pytest.raises(InputError):
            read_columns(path)
        return
    got = read_columns(path)
    assert got.reader == "python-can"
    assert np.array_equal(got.columns.timestamp_s, ref.timestamp_s)


def test_mf4_columns_are_python_cans_frames_and_the_replay_is_the_same(tmp_path, drive):
    pytest.importorskip("asammdf", reason="the optional package asammdf (pip install .[mf4]) is not installed")
    msgs = inject(drive, ("hostile", "not_available", "dropout"), seed=2)
    msgs.sort(key=lambda m: m.timestamp)  # an MF4 group is written in time order
    path = _write(msgs, tmp_path / "drive.mf4")
    got = read_columns(path)
    assert got.reader == "asammdf columns"
    ref = FrameColumns.from_messages(can.LogReader(path))
    for field in ("timestamp_s", "can_id", "flags", "dlc", "length", "data"):
        assert np.array_equal(getattr(got.columns, field), getattr(ref, field)), field
    assert_same(path)


def test_frames_without_a_finite_time_are_rejected_by_both_paths_and_never_move_time(drive):
    msgs = inject(drive, ("hostile",), seed=4)[:20_000]
    for i, t in ((500, float("nan")), (900, float("inf")), (1400, float("-inf")), (5000, float("nan"))):
        msgs[i] = can.Message(timestamp=t, arbitration_id=msgs[i].arbitration_id, data=msgs[i].data, check=False)
    s_frames, s_cols = _service(), _service()
    s_frames.feed_all(msgs)
    out = run_columns(s_cols, FrameColumns.from_messages(msgs))
    ref = s_frames.recorded()
    for c in ref:
        assert np.array_equal(ref[c], out[c], equal_nan=True), c
    assert s_frames.decoder.counters["rejected"]["bad_timestamp"] == 4
    assert s_frames.counters == s_cols.counters and s_frames.decoder.counters == s_cols.decoder.counters
    assert s_frames.counters["time_jumps"] == 0


def test_a_log_without_oil_starts_at_the_ambient_reading_on_both_paths(tmp_path):
    """No oil temperature (no TRF1) at key-on: the sensor starts at the truck's ambient reading (a cold-soaked
    truck at -25 degC), not at the parameters' 25 degC, on the frame path and the whole-log path alike."""
    from tests.tools.can_fixtures import plant_output

    inp = _cycle(60.0)
    inp["ambient_temp_c"] = np.full(inp.n, -25.0)
    frames = list(
        synth_frames(inp, plant_output(inp, oil0_c=-25.0, oil_rate_k_s=0.0), start_timestamp_s=1.7e9).frames.messages()
    )
    no_oil = [m for m in frames if (m.arbitration_id >> 8) & 0x3FFFF != 0xFEF8]  # TRF1 (PGN 65272) left out
    assert len(no_oil) < len(frames)
    ref, _ = assert_same(_write(no_oil, tmp_path / "no_oil.log"))
    first = int(np.argmax(np.isfinite(np.asarray(ref["T_PS_c"], dtype=float))))
    T0 = np.array([ref[c][first] for c in ref.columns if c.startswith("T_") and c.endswith("_c")])
    assert np.all(np.abs(T0 + 25.0) < 1.0)


def test_both_paths_log_the_same_time_jumps(tmp_path, drive, caplog):
    """The whole-log path logs each time jump as the frame path does: replay's note points to these log messages,
    so both paths must write them."""
    import logging

    path = _write(inject(drive, ["jump_forward", "jump_backward"], seed=3), tmp_path / "jumps.log")
    logged = {}
    for columnar in (False, True):
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="gearbox_vsensor.can_service"):
            replay_log(path, _service(), columnar=columnar)
        logged[columnar] = [r.getMessage() for r in caplog.records if "frame time jumped" in r.getMessage()]
    assert len(logged[False]) == 2 and logged[True] == logged[False]


def test_frames_out_of_time_order_are_counted_alike_and_named(tmp_path, drive):
    """Every 50th frame stamped 0.1 s earlier (a log merged from several buffers): both paths count the frames out
    of time order and how far back, and a note says to sort the log (else 4 % of the steps go 'missing' without a
    word); a later frame a whole 2 s back is a clock going back, not counted here."""
    from firmware_model.service.trust import OrderFinding

    msgs = list(drive.messages(channel="can0"))
    for m in msgs[::50]:
        m.timestamp -= 0.1
    ref, svc = assert_same(_write(msgs, tmp_path / "late.log"))
    n_late = sum(1 for a, b in zip(msgs, msgs[1:]) if 0 < a.timestamp - b.timestamp <= 1.0)
    assert svc.counters["frames_out_of_order"] == n_late > 0
    assert 0.09 < svc.counters["out_of_order_max_s"] <= 0.101  # 0.1 s plus the spacing of neighbours
    notes = [f for f in svc.findings() if isinstance(f, OrderFinding)]
    assert len(notes) == 1 and "sort a log by time" in notes[0].sentence
    svc = _service()
    svc.feed_all(list(drive.messages(channel="can0"))[:500])
    assert svc.counters["frames_out_of_order"] == 0 and not any(isinstance(f, OrderFinding) for f in svc.findings())


def test_a_frozen_oil_reading_is_named_as_the_cause_of_the_degraded_run_on_both_paths(tmp_path):
    """a log whose oil reading froze was called degraded (untrusted in a fleet) for "engine torque
    0.0 %", the 3 steps a torque came late, because only the decoder's stale inputs were named, not the sensor's own
    checks. The sensor's rejects now count in the service (the same on both paths) and lead the finding's causes."""
    from firmware_model.service.degraded import DegradedFinding, pct
    from tests.tools.can_fixtures import plant_output
    from tools.can.logsynth import write_frames

    inp = _cycle(480.0)
    frames = synth_frames(inp, plant_output(inp, oil0_c=80.0, oil_rate_k_s=0.0), start_timestamp_s=1.7e9).frames
    _, svc = assert_same(write_frames(frames, tmp_path / "frozen_oil.log"))
    frozen = svc.counters["input_rejects"]["oil_frozen"]
    assert frozen > 0.3 * svc.counters["steps"] and svc.counters["oil_frozen_at_c"] == 80.0
    degraded = next(f for f in svc.findings() if isinstance(f, DegradedFinding))
    causes = degraded.sentence.split("inputs not usable (missing, stale or rejected as implausible or frozen): ")[1]
    assert causes.startswith(f"oil temperature frozen at 80.0 degC for {pct(frozen, degraded.steps)} of the steps"), (
        degraded.sentence
    )


def test_one_frame_stamped_ahead_is_a_glitch_not_a_time_jump(tmp_path, drive, caplog):
    """One EEC1 frame stamped 30 s ahead (a logger's glitch) was a forward jump and the next frame a backward one:
    every later step's time 30 s off, the inputs held over a gap that never was. Both paths now take it for a
    glitch: no jump, the same steps at the same times as the clean log, the glitch counted and logged alike."""
    import logging

    clean = replay_log(_write(inject(drive, [], seed=3), tmp_path / "clean.log"), _service(), columnar=True)
    path = _write(inject(drive, ["time_glitch"], seed=3), tmp_path / "glitch.log")
    logged = {}
    for columnar in (False, True):
        caplog.clear()
        svc = _service()
        with caplog.at_level(logging.WARNING, logger="gearbox_vsensor.can_service"):
            out = replay_log(path, svc, columnar=columnar)
        logged[columnar] = [r.getMessage() for r in caplog.records if "glitch of its time stamp" in r.getMessage()]
        assert svc.counters["time_jumps"] == 0 and svc.counters["frames_time_glitch"] == 1
        assert np.array_equal(out["time_s"], clean["time_s"])
        for c in (c for c in clean.columns if c.startswith("T_")):
            assert np.nanmax(np.abs(out[c] - clean[c])) < 1e-6, c
    assert len(logged[False]) == 1 and logged[True] == logged[False]
    assert "lies 30." in logged[False][0]


def test_a_real_jump_is_still_a_jump_when_the_next_frame_follows_it(tmp_path, drive):
    """The frame after a far-ahead one settles it: as far ahead, the time jumped (a logger pause), as before."""
    svc = _service()
    replay_log(_write(inject(drive, ["jump_forward"], seed=3), tmp_path / "jump.log"), svc, columnar=False)
    assert svc.counters["time_jumps"] == 1 and svc.counters["frames_time_glitch"] == 0
