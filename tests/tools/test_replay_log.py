"""Replay of CAN logs (.log, .asc, .blf, .mf4) through the sensor service into a sensor output run table."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from firmware_model.components import PUBLISHED
from firmware_model.errors import InputError
from firmware_model.service import SensorService, ServiceOptions
from tools.can.logsynth import synth_frames, write_frames
from tools.replay.log import is_can_log, read_log, replay_log
from tools.runtable import RunTable, read_run_table, write_run_table

from ..firmware_model.sensor_standin import make_sensor
from .can_fixtures import plant_output


def cycle(seconds=20.0):
    t = np.arange(0.0, seconds, 0.1)
    n = t.size
    return RunTable(
        {
            "time_s": t,
            "engine_speed_rpm": 1000.0 + 500.0 * np.sin(t / 3.0),
            "engine_torque_nm": 800.0 + 600.0 * np.cos(t / 4.0),
            "gear": np.where(t < 10, 7, 8),
            "ambient_temp_c": np.full(n, 20.0),
            "coolant_temp_c": np.full(n, 85.0),
            "vehicle_speed_kmh": np.full(n, 50.0),
        }
    )


def plant(inputs):
    return plant_output(inputs, oil0_c=60.0, oil_rate_k_s=0.2, T0_c=61.0, T_rate_k_s=0.3)


@pytest.fixture(scope="module")
def frames():
    inp = cycle()
    return inp, synth_frames(inp, plant(inp)).frames


def replay(path, **kw):
    return replay_log(
        path, SensorService(make_sensor(), ServiceOptions(configured_ref_torque_nm=None), record=True), **kw
    )


def test_replay_table_has_the_contract_columns_and_the_decoded_inputs(tmp_path, frames):
    inp, fr = frames
    table = replay(write_frames(fr, tmp_path / "drive.log"))
    for col in (
        "time_s",
        "engine_speed_rpm",
        "engine_torque_nm",
        "gear",
        "oil_temp_c",
        "ambient_temp_c",
        "coolant_temp_c",
        "vehicle_speed_kmh",
        "retarder_torque_nm",
    ):
        assert table.has(col), col
    for c in PUBLISHED:
        for col in (f"T_{c}_c", f"W_{c}", f"ttl_{c}_s", f"meas_T_{c}_c"):
            assert table.has(col), col
    assert np.allclose(np.diff(table["time_s"]), 0.1) and table.n == 198
    # at step k (time 0.1 k) the sensor had the cycle's sample k - 1 (values change half-way between steps)
    t = table["time_s"]
    k = np.round(t / 0.1).astype(int) - 1
    assert np.abs(table["engine_speed_rpm"] - inp["engine_speed_rpm"][k]).max() <= 0.0625
    assert np.array_equal(table["gear"], inp["gear"][k])
    ok = t > 0.36  # EC1 completes at 0.35 s
    want = np.clip(np.rint(inp["engine_torque_nm"][k] / 3000.0 * 100.0), -125, 125) * 30.0
    assert np.allclose(table["engine_torque_nm"][ok], want[ok]) and np.isnan(table["engine_torque_nm"][~ok]).all()
    assert np.isnan(table["retarder_torque_nm"]).all()  # no ERC1 in this cycle
    assert np.allclose(
        table["meas_T_PS_c"], 61.0 + PUBLISHED.index("PS") + 0.3 * (t - 0.025 - 0.05), atol=1 / 64 + 1e-6
    )
    assert table.meta["counters"]["decoder"]["frames_seen"] == len(fr)
    out = write_run_table(table, tmp_path / "est.csv")
    back = read_run_table(out, required=("time_s",))
    assert back.n == table.n and back.has("W_PS")


@pytest.mark.parametrize("suffix", [".asc", ".blf", ".mf4", ".trc"])
def test_every_log_format_gives_the_same_table(tmp_path, frames, suffix):
    """The same frames from every log format replay to the same table (.trc: PEAK's PCAN-View trace, common on
    other makes' loggers)."""
    if suffix == ".trc":
        import can

        with can.Logger(tmp_path / "drive.trc") as w:
            for m in fr_messages(frames[1]):
                w.on_message_received(m)
        path = tmp_path / "drive.trc"
    elif suffix == ".mf4":
        pytest.importorskip("asammdf", reason="the optional package asammdf (pip install .[mf4]) is not installed")
        import can

        with can.Logger(tmp_path / "drive.mf4") as w:
            for m in fr_messages(frames[1]):
                w.on_message_received(m)
        path = tmp_path / "drive.mf4"
    else:
        path = write_frames(frames[1], tmp_path / f"drive{suffix}")
    ref = replay(write_frames(frames[1], tmp_path / "drive.log"))
    table = replay(path)
    assert table.n == ref.n
    for col in ref.columns:
        if col == "can_time_s":
            continue
        assert np.array_equal(table[col], ref[col], equal_nan=True), col


def test_a_truncated_mf4_or_a_gzip_log_is_one_sentence(tmp_path, frames):
    """A cut .mf4 is refused in one sentence that says it is truncated, with none of asammdf's "Exception ignored"
    tracebacks from its finaliser around it; a .log.gz says how to decompress it."""
    import gzip
    import subprocess

    pytest.importorskip("asammdf", reason="the optional package asammdf (pip install .[mf4]) is not installed")
    import can

    with can.Logger(tmp_path / "drive.mf4") as w:
        for m in fr_messages(frames[1]):
            w.on_message_received(m)
    raw = (tmp_path / "drive.mf4").read_bytes()
    (tmp_path / "cut.mf4").write_bytes(raw[: len(raw) // 2])
    write_frames(frames[1], tmp_path / "drive.log")
    (tmp_path / "drive.log.gz").write_bytes(gzip.compress((tmp_path / "drive.log").read_bytes()))
    for name, words in (("cut.mf4", "truncated"), ("drive.log.gz", "gzip-compressed; decompress it first")):
        run = subprocess.run(
            [
                sys.executable,
                "-m",
                "tools.cli",
                "replay",
                str(tmp_path / name),
                "--out",
                str(tmp_path / "o.csv"),
                "--quiet",
            ],
            capture_output=True,
            text=True,
        )
        assert run.returncode == 2, (name, run.stderr)
        assert run.stderr.count("\n") == 1 and words in run.stderr, (name, run.stderr)
        assert not (tmp_path / "o.csv").exists()


def fr_messages(fr):
    return fr.messages(channel=0)


def test_errors_name_the_file_and_the_rule(tmp_path, monkeypatch):
    with pytest.raises(InputError, match="does not exist"):
        list(read_log(tmp_path / "missing.log"))
    (tmp_path / "x.txt").write_text("hello")
    with pytest.raises(InputError, match="unknown log suffix '.txt'"):
        list(read_log(tmp_path / "x.txt"))
    (tmp_path / "bad.log").write_text("(0.0) can0 18FEF100#00\nthis is not candump\n")
    with pytest.raises(InputError, match="bad.log: line 2 is not a candump -L frame"):
        list(read_log(tmp_path / "bad.log"))
    (tmp_path / "cut.log").write_text("(0.0) can0 18FEF100#00\n(0.1) can0")  # a truncated copy
    with pytest.raises(InputError, match="cut.log: the log ends in the middle of a line"):
        list(read_log(tmp_path / "cut.log"))
    with pytest.raises(InputError, match="cut.log: the log ends in the middle of a line"):
        replay(tmp_path / "cut.log", strict=True)  # the fast candump parser too
    with pytest.raises(InputError, match=r"no sensor step.*\(1 malformed line skipped \(line 2, the last, cut"):
        replay(tmp_path / "cut.log")  # without strict: skipped, and said
    import can

    with can.BLFWriter(tmp_path / "whole.blf") as w:
        for i in range(3000):
            w.on_message_received(can.Message(timestamp=i * 0.01, arbitration_id=0x18FEF100, data=bytes(8)))
    (tmp_path / "cut.blf").write_bytes((tmp_path / "whole.blf").read_bytes()[:6000])  # read to its end silently
    with pytest.raises(InputError, match="cut.blf: the BLF log is shorter than its header records"):
        list(read_log(tmp_path / "cut.blf"))
    assert len(list(read_log(tmp_path / "whole.blf"))) == 3000
    (tmp_path / "other.log").write_text("(0.000000) can0 18FECA00#0000000000000000\n(0.5) can0 123#00\n")
    with pytest.raises(InputError, match="no sensor step") as few:
        replay(tmp_path / "other.log")
    assert "time stamps equal" not in str(few.value)
    (tmp_path / "empty.trc").write_text("")
    with pytest.raises(InputError, match="empty.trc: no sensor step: the log holds no CAN frame"):
        replay(tmp_path / "empty.trc")
    # 200 used frames with one time stamp: the message asks about the time stamps
    (tmp_path / "equal.log").write_text("".join("(5.000000) can0 0CF00400#F07D7DA02800FFFF\n" for _ in range(200)))
    with pytest.raises(InputError, match="are all time stamps equal"):
        replay(tmp_path / "equal.log")
    lines = "".join("(nan) can0 0CF00400#F0C0C0A02800FFFF\n" for _ in range(50))  # every frame time lost
    (tmp_path / "nan.log").write_text(lines)
    for columnar in (True, False):
        with pytest.raises(InputError, match="all 50 frames were rejected as a frame time that is not a finite"):
            replay_log(
                tmp_path / "nan.log",
                SensorService(make_sensor(), ServiceOptions(), record=True, emit_frames=False),
                columnar=columnar,
            )
    (tmp_path / "x.mf4").write_bytes(b"\0" * 64)
    monkeypatch.setitem(sys.modules, "asammdf", None)
    with pytest.raises(InputError, match=r"needs the optional package asammdf.*gearbox-vsensor\[mf4\]"):
        list(read_log(tmp_path / "x.mf4"))
    assert is_can_log("a.LOG") and is_can_log("b.blf") and not is_can_log("c.csv")


def messy_log(path):
    """A 60 s drive with what the service handles specially: no oil temperature for the first 3 s (not
    initialised), EEC1 missing for 2 s (stale inputs), a forward and a backward time jump, rig thermocouples."""
    from can_dbc.adapter import pgn_of

    inp = cycle(60.0)
    fr = synth_frames(inp, plant(inp)).frames
    t, ids, data = fr.timestamp_s.copy(), fr.can_id.copy(), fr.data.copy()
    pgn = np.array([pgn_of(int(i)) for i in ids])
    keep = ~((pgn == 65272) & (t < 3.0)) & ~((pgn == 61444) & (t > 20.0) & (t < 22.0))
    t, ids, data = t[keep], ids[keep], data[keep]
    t = np.where(t > 35.0, t + 100.0, t)  # forward jump
    t = np.where(t > 145.0, t - 7.0, t)  # backward jump
    with open(path, "w") as fh:  # candump -L by hand (our writer never goes backwards)
        for ts, i, d in zip(t.tolist(), ids.tolist(), data):
            fh.write(f"({ts:.6f}) can0 {i:08X}#{d.tobytes().hex().upper()}\n")
    return path


def test_whole_log_replay_equals_frame_by_frame_bit_for_bit(tmp_path):
    """The two replay paths on a messy log (time jumps, stale inputs, no oil at the start, rig thermocouples): the
    same table, counters and final state."""
    path = messy_log(tmp_path / "messy.log")
    sensor = make_sensor()
    tables, services = [], []
    for columnar in (False, True):
        svc = SensorService(sensor, ServiceOptions(configured_ref_torque_nm=None), record=True, emit_frames=False)
        tables.append(replay_log(path, svc, columnar=columnar))
        services.append(svc)
    one, whole = tables
    assert "whole log" in whole.meta["reader"] and "whole log" not in one.meta["reader"]
    c = one.meta["counters"]
    assert c["service"]["time_jumps"] == 2 and c["service"]["uninitialised_steps"] > 0
    assert c["service"]["stale_steps"].get("engine_speed_rpm", 0) > 0
    assert one.has("meas_T_PS_c") and (one["degraded"] == 1).any() and (one["degraded"] == 0).any()
    assert one.columns == whole.columns and one.n == whole.n
    for col in one.columns:
        assert np.array_equal(one[col], whole[col], equal_nan=True), col
    assert whole.meta["counters"] == c
    services[0].finish_pending()
    for a, b in zip(services[0].state, services[1].state):
        assert np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)


def test_retarder_frames_without_a_reference_torque_are_named(tmp_path):
    """ERC1 frames arrive but neither an RC (the retarder's reference torque, SPN 556) nor [can]
    retarder_reference_torque_nm: the summary says so (it said "auxiliary inputs not given (retarder_torque_nm)" as
    if the log had none); with the configured reference, or with RC in the log, nothing is said."""
    from tools.can.logsynth import SynthFrames
    from tools.replay.summary import summary_lines

    inp = cycle()
    inp["retarder_torque_nm"] = np.full(inp.n, 700.0)
    fr = synth_frames(inp, plant(inp)).frames
    without_rc = ~np.isin(fr.can_id, [0x1CECFF10, 0x1CEBFF10])
    paths = {
        "rc": write_frames(fr, tmp_path / "rc.log"),
        "no_rc": write_frames(
            SynthFrames(fr.timestamp_s[without_rc], fr.can_id[without_rc], fr.data[without_rc]), tmp_path / "no_rc.log"
        ),
    }
    lines = {}
    for log, ref in (("no_rc", None), ("no_rc", 3500.0), ("rc", None)):
        service = SensorService(
            make_sensor(), ServiceOptions(configured_ref_torque_nm=None, retarder_ref_torque_nm=ref), record=True
        )
        lines[log, ref] = summary_lines(replay_log(paths[log], service))[-1]
    assert "retarder frames (ERC1) arrived, but without a retarder reference torque" in lines["no_rc", None]
    for key in (("no_rc", 3500.0), ("rc", None)):
        assert "retarder" not in lines[key] and "not given" not in lines[key], lines[key]


def test_retarder_frames_without_a_usable_percent_are_not_blamed_on_the_reference(tmp_path):
    """ERC1 frames whose percent torque is "not available" (0xFF), with the reference known (RC from the retarder,
    or [can] retarder_reference_torque_nm): the summary said "without a retarder reference torque (no RC ...)",
    which is not what happened (docs/can.md: the Nm is percent / 100 x that reference); it now says the frames
    carried no usable value."""
    from tools.can.logsynth import SynthFrames
    from tools.replay.summary import summary_lines

    inp = cycle()
    inp["retarder_torque_nm"] = np.full(inp.n, 700.0)
    fr = synth_frames(inp, plant(inp)).frames
    data = fr.data.copy()
    erc1 = fr.can_id == 0x18F00010
    assert erc1.any()
    data[erc1, 1] = 0xFF  # SPN 520, byte 2: not available
    has_rc = write_frames(SynthFrames(fr.timestamp_s, fr.can_id, data), tmp_path / "na.log")
    no_rc = ~np.isin(fr.can_id, [0x1CECFF10, 0x1CEBFF10])
    configured = write_frames(SynthFrames(fr.timestamp_s[no_rc], fr.can_id[no_rc], data[no_rc]), tmp_path / "na2.log")
    for path, ref in ((has_rc, None), (configured, 3500.0)):
        service = SensorService(
            make_sensor(), ServiceOptions(configured_ref_torque_nm=None, retarder_ref_torque_nm=ref), record=True
        )
        out = replay_log(path, service)
        rc_received = out.meta["counters"]["decoder"]["tp"]["rc_received"]
        assert (rc_received == 0) if ref else (rc_received > 0)  # the reference: configured, else from RC
        line = summary_lines(out)[-1]
        assert "without a retarder reference torque" not in line, line
        assert f"retarder_torque_nm ({int(erc1.sum())} ERC1 frames), none with a usable value" in line, line


def test_a_line_that_is_no_frame_is_named(tmp_path):
    """A candump -L line that is no frame is named by its number and text, not python-can's unpacking error."""
    log = tmp_path / "mixed.log"
    log.write_text("(1.000000) can0 18FEF100#0011223344556677\n(1.100000) can0 garbage\n")
    with pytest.raises(InputError, match=r"line 2 is not a candump -L frame .*'\(1\.100000\) can0 garbage'"):
        replay(log, strict=True)


def test_a_log_with_a_byte_order_mark_is_one_sentence(tmp_path, frames):
    _, fr = frames
    path = write_frames(fr, tmp_path / "drive.log")
    bom = tmp_path / "bom.log"
    bom.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    with pytest.raises(InputError, match="starts with a UTF-8 byte-order mark"):
        replay(bom)


def test_a_gzipped_log_and_a_directory_are_one_sentence(tmp_path, frames):
    """A gzip-compressed log under a .log name, and a directory, are one sentence each, with no binary bytes
    dumped into the message."""
    import gzip

    _, fr = frames
    path = write_frames(fr, tmp_path / "drive.log")
    packed = tmp_path / "packed.log"
    packed.write_bytes(gzip.compress(path.read_bytes()))
    with pytest.raises(InputError, match=r"packed.log: the file is gzip-compressed; decompress it first"):
        replay(packed)
    (tmp_path / "dir.log").mkdir()
    with pytest.raises(InputError, match="is a directory"):
        replay(tmp_path / "dir.log")


def test_a_log_of_two_can_channels_is_one_sentence(tmp_path, frames):
    """A log of can0 and can1 (the same traffic twice) is one sentence naming the two channels: replayed as one bus,
    the EC1 transfers collide and the run is 100 % degraded, the warning naming the torque, not the cause."""
    _, fr = frames
    text = write_frames(fr, tmp_path / "drive.log").read_text()
    two = tmp_path / "two.log"
    two.write_text(text + text.replace(" can0 ", " can1 "))
    with pytest.raises(InputError, match=r"holds the frames of 2 CAN channels \(can0, can1\)"):
        replay(two)


def test_the_channels_of_a_trc_and_an_asc_are_named_as_the_files_number_them():
    """A TRC of buses 1 and 2 was said to hold channels (2, 3): python-can reads a .trc's numbers as they are, an
    .asc's and a .blf's from 0 (a new user's review)."""
    from pathlib import Path

    from tools.replay.formats import mixed_channels

    assert "2 CAN channels (1, 2)" in mixed_channels(Path("t.trc"), [1, 2])
    assert "2 CAN channels (1, 2)" in mixed_channels(Path("t.asc"), [0, 1])
    assert "2 CAN channels (1, 2)" in mixed_channels(Path("t.blf"), [0, 1])
    assert "2 CAN channels (can0, can1)" in mixed_channels(Path("t.log"), ["can0", "can1"])


def test_a_trc_cut_mid_line_is_refused(tmp_path, frames):
    """A PCAN-View trace cut in the middle of its last line is refused as the other text logs are (python-can would
    read the cut line as a shorter frame)."""
    import can

    with can.Logger(tmp_path / "drive.trc") as w:
        for m in fr_messages(frames[1]):
            w.on_message_received(m)
    raw = (tmp_path / "drive.trc").read_bytes()
    (tmp_path / "cut.trc").write_bytes(raw[:-7])
    with pytest.raises(InputError, match="cut.trc: the log ends in the middle of a line"):
        replay(tmp_path / "cut.trc", strict=True)
    cut = replay(tmp_path / "cut.trc")  # without strict: the cut line skipped, the frames before it kept
    whole = replay(tmp_path / "drive.trc")
    assert cut.meta["malformed"].summary.startswith("1 malformed line skipped (line ")
    assert cut.meta["counters"]["decoder"]["frames_seen"] == whole.meta["counters"]["decoder"]["frames_seen"] - 1


@pytest.mark.parametrize("suffix", [".asc", ".trc"])
def test_garbage_lines_in_asc_and_trc_logs_are_counted_not_skipped_in_silence(tmp_path, frames, suffix):
    """python-can's ASC and TRC readers skip a line they do not know without a word: such a line, and an ASC frame
    cut short of its DLC's bytes, are now counted and named as a candump log's are; the frames are those of the
    whole log, less the cut one."""
    import can

    with can.Logger(tmp_path / f"drive{suffix}") as w:
        for m in fr_messages(frames[1]):
            w.on_message_received(m)
    lines = (tmp_path / f"drive{suffix}").read_text().splitlines()
    body = next(i for i, line in enumerate(lines) if line.strip()[:1].isdigit() and ("Rx" in line))
    frame = lines[body + 5]
    lines.insert(body + 3, "### logger restarted ###")
    cut = frame.rsplit(" ", 3)[0] if suffix == ".asc" else None
    if cut is not None:  # an ASC frame line that lost its last three bytes: python-can read it as a shorter frame
        lines[body + 6] = cut
    (tmp_path / f"bad{suffix}").write_text("\n".join(lines) + "\n")
    bad = replay(tmp_path / f"bad{suffix}")
    whole = replay(tmp_path / f"drive{suffix}")
    skipped = 2 if cut is not None else 1
    assert bad.meta["malformed"].summary.startswith(f"{skipped} malformed line{'s' if skipped > 1 else ''} skipped")
    seen = bad.meta["counters"]["decoder"]["frames_seen"]
    assert seen == whole.meta["counters"]["decoder"]["frames_seen"] - (skipped - 1)


def test_a_log_named_for_another_format_says_what_it_is(tmp_path, capsys):
    """A candump log named .asc ('the log holds no CAN frame'), a BLF named .log ('binary data') and python-can's
    CSV log (a run table's 'column arbitration_id is not a number') each say what they are and what to do."""
    import can

    from tools.cli import main

    frames = [can.Message(timestamp=0.1 * i, arbitration_id=0x0CF00400, data=bytes(8)) for i in range(20)]
    candump = tmp_path / "drive.asc"
    candump.write_text("".join(f"({m.timestamp:.6f}) can0 0CF00400#{m.data.hex().upper()}\n" for m in frames))
    blf = tmp_path / "drive.blf"
    with can.Logger(str(blf)) as log:
        for m in frames:
            log.on_message_received(m)
    blf_named = tmp_path / "drive_blf.log"
    blf_named.write_bytes(blf.read_bytes())
    pycsv = tmp_path / "frames.csv"
    with can.Logger(str(pycsv)) as log:
        for m in frames:
            log.on_message_received(m)
    for path, words in (
        (candump, "it looks like a candump -L log; name it .log"),
        (blf_named, "it looks like a BLF log; name it .blf"),
        (pycsv, "is a python-can CSV log of CAN frames, not a run table"),
    ):
        assert main(["replay", str(path), "--out", str(tmp_path / "o.csv")]) == 2
        err = capsys.readouterr().err
        assert words in err and len(err.strip().splitlines()) == 1, err


def test_a_log_written_backwards_says_so_and_how_to_sort_it(tmp_path, frames):
    """Every frame a step back in time gives no sensor step; the error said 'less than 100 ms of traffic ... are
    all time stamps equal?'."""
    _, fr = frames
    fwd = tmp_path / "fwd.log"
    write_frames(fr, fwd)
    back = tmp_path / "back.log"
    back.write_text("".join(reversed(fwd.read_text().splitlines(keepends=True))))
    with pytest.raises(
        InputError,
        match=r"back.log: no sensor step: its frame time falls at 100 % of its changes over .* the log "
        r"runs backwards; sort it by time \(candump -L: LC_ALL=C sort -s -n -k1.2 back.log",
    ):
        replay(back)
    assert replay(fwd).n > 0
