"""Malformed lines of a CAN log: skipped, counted and said in both replay paths; untrusted over 1 %
of the lines or where a line breaks a frame sequence the step needs; ``--strict`` refuses the log as before."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from firmware_model.service import build_service
from tools.cli import main
from tools.replay.log import replay_log

from ..data_paths import SKIP_REASON, real_capture_dir

#: a two-minute steady drive (the shortest simulated log with EC1 transfers, gear and oil)
SPEC = "steady:gear=4L,rpm=1300,nm=2000,s=120"


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    d = tmp_path_factory.mktemp("drive")
    assert main(["simulate", "--cycle", SPEC, "--can-log", str(d / "drive.log"), "--out", str(d / "run.csv")]) == 0
    return (d / "drive.log").read_bytes().split(b"\n")[:-1]  # the lines, without the final newline's empty tail


def _write(path, lines, cut: int = 0) -> str:
    raw = b"\n".join(lines) + b"\n"
    path.write_bytes(raw[: len(raw) - cut] if cut else raw)
    return str(path)


def _replay(path, capsys, *extra):
    rc = main(["replay", path, "--out", path + ".csv", *extra])
    out = capsys.readouterr()
    return rc, out.out, out.err


def _both_paths(path):
    """The whole-log path and the frame-by-frame path: their tables, counters and malformed findings."""
    got = []
    for columnar in (True, False):
        service = build_service(None, record=True, emit_frames=False, log_findings=False)
        t = replay_log(path, service, columnar=columnar)
        got.append(t)
    a, b = got
    for c in a.columns:
        assert np.array_equal(a[c], b[c], equal_nan=True), c
    assert a.meta["counters"] == b.meta["counters"]
    assert a.meta["malformed"] == b.meta["malformed"]
    return a


def _line_of(lines, frame_id: bytes, k: int) -> int:
    """The 0-based index of the k-th line carrying ``frame_id``."""
    return [i for i, x in enumerate(lines) if b" " + frame_id + b"#" in x][k]


def test_a_garbage_line_in_the_middle_is_skipped_counted_and_said(tmp_path, drive, capsys):
    lines = list(drive)
    lines[4999] = b"(12.3) can0 garb#age!!"
    path = _write(tmp_path / "one.log", lines)
    table = _both_paths(path)
    assert table.meta["malformed"].skipped == 1 and table.meta["malformed"].first == (5000,)
    assert table.meta["counters"]["decoder"]["frames_seen"] == len(drive) - 1
    rc, out, err = _replay(path, capsys)
    assert rc == 0, err
    # said on stderr with the file's name, not among the summary's lines
    assert "\nnote: one.log: 1 malformed line skipped (line 5000)\n" in "\n" + err and "malformed" not in out


def test_a_truncated_last_line_alone_is_counted_not_untrusted(tmp_path, drive, capsys):
    path = _write(tmp_path / "cut.log", drive, cut=9)  # the last frame cut in its data: it would still parse
    table = _both_paths(path)
    assert table.meta["counters"]["decoder"]["frames_seen"] == len(drive) - 1
    rc, out, err = _replay(path, capsys)
    assert rc == 0, err
    assert f"note: cut.log: 1 malformed line skipped (line {len(drive)}, the last, cut short" in err
    rc, out, err = _replay(path, capsys, "--strict")
    assert rc == 2 and err.count("\n") == 1
    assert f"the log ends in the middle of a line (line {len(drive)}:" in err


def test_more_than_one_percent_garbage_is_untrusted(tmp_path, drive, capsys):
    lines = [b"xx garbage" if k % 50 == 7 else x for k, x in enumerate(drive)]
    path = _write(tmp_path / "many.log", lines, cut=5)
    n_bad = sum(1 for k in range(len(drive)) if k % 50 == 7) + 1
    table = _both_paths(path)
    assert table.meta["malformed"].skipped == n_bad
    rc, out, err = _replay(path, capsys)
    assert rc == 3
    assert (
        f"warning: many.log: {n_bad} malformed lines skipped (lines 8, 58, 108, 158, 208 and {n_bad - 5} more; "
        f"the last one cut short" in err
    )
    assert f"of the log's {len(drive)} lines, more than 1 %" in err
    rc, out, err = _replay(path, capsys, "--allow-untrusted")
    assert rc == 0 and "more than 1 %" in err
    rc, out, err = _replay(path, capsys, "--strict")
    assert rc == 2 and err.count("\n") == 1 and "line 8 is not a candump -L frame" in err and "'xx garbage'" in err


def test_a_broken_tp_dt_line_of_ec1_is_untrusted(tmp_path, drive, capsys):
    lines = list(drive)
    k = _line_of(lines, b"1CEBFF00", 30)  # a packet of an EC1 transfer from the engine (TP.BAM)
    lines[k] = lines[k].replace(b"#", b"#~")  # a byte of noise in its data
    path = _write(tmp_path / "dt.log", lines)
    table = _both_paths(path)
    assert table.meta["malformed"].broken
    rc, out, err = _replay(path, capsys)
    assert rc == 3
    assert f"1 malformed line skipped (line {k + 1}): line {k + 1} broke a TP.BAM transfer of EC1" in err
    # the same packet line intact and a garbage line elsewhere, outside any transfer: not untrusted
    lines = list(drive)
    j = _line_of(lines, b"18FEF803", 50) + 1  # just after a TRF1 frame
    lines.insert(j, b"garbage")
    rc, out, err = _replay(_write(tmp_path / "ok.log", lines), capsys)
    assert rc == 0, err


def test_a_burst_that_leaves_a_primary_input_stale_is_untrusted(tmp_path, drive, capsys):
    """40 lines (0.2 % of the log) lost in a row: EEC1 is missing for 0.2 s, beyond its 60 ms staleness limit."""
    lines = list(drive)
    start = _line_of(lines, b"0CF00400", 3000)
    lines[start : start + 40] = [b"\x00\x7f\x13 binary noise"] * 40
    path = _write(tmp_path / "burst.log", lines)
    _both_paths(path)
    rc, out, err = _replay(path, capsys)
    assert rc == 3
    assert (
        f"the malformed lines from line {start + 1} on left a" in err
        and "gap in EEC1 (engine speed and torque), longer than the sensor's staleness limit of 0.06 s" in err
    )
    rc, out, err = _replay(path, capsys, "--strict")
    assert rc == 2 and f"line {start + 1} holds binary data" in err


def test_a_cut_blf_keeps_its_frames_and_says_so(tmp_path, drive, capsys):
    import can

    from tools.replay.columns import scan_log

    src = _write(tmp_path / "drive.log", drive)
    with can.Logger(tmp_path / "drive.blf") as w:
        for m in can.LogReader(src):
            w.on_message_received(m)
    raw = (tmp_path / "drive.blf").read_bytes()
    cut = tmp_path / "cut.blf"
    cut.write_bytes(raw[: int(len(raw) * 0.8)])
    assert scan_log(cut).note.startswith("the BLF log is shorter than its header records")
    rc, out, err = _replay(str(cut), capsys)
    assert rc in (0, 3), err
    assert "cut.blf: the BLF log is shorter than its header records" in err
    assert "the frames before the cut were replayed" in err
    rc, out, err = _replay(str(cut), capsys, "--strict")
    assert rc == 2 and err.count("\n") == 1 and "shorter than its header records" in err


def test_a_real_capture_with_a_garbage_line_and_a_cut_last_line(tmp_path, capsys):
    d = real_capture_dir()
    if d is None:
        pytest.skip(SKIP_REASON)
    shutil.copy(d / "normal.candump.log", tmp_path / "normal.log")
    lines = (tmp_path / "normal.log").read_bytes().split(b"\n")[:-1]
    lines[len(lines) // 2] = b"(1543509533.9) can0 18FE"
    path = _write(tmp_path / "normal.log", lines, cut=4)
    table = _both_paths(path)
    f = table.meta["malformed"]
    assert f.skipped == 2 and f.first == (len(lines) // 2 + 1, len(lines))
    rc, out, err = _replay(path, capsys, "--allow-untrusted")
    assert rc == 0
    assert f"normal.log: 2 malformed lines skipped (lines {len(lines) // 2 + 1}, {len(lines)}; the last one cut" in err


def test_a_log_with_no_frame_at_all_is_one_sentence_without_the_strict_hint(tmp_path, capsys):
    """A file none of whose lines is a frame is not a CAN log: one sentence saying so (exit 2), not the --strict
    refusal's hint that such lines would be skipped."""
    path = tmp_path / "notes.log"
    path.write_text("garbage\nmore garbage\n")
    assert main(["replay", str(path), "--out", str(tmp_path / "e.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert "none of its 2 lines is a CAN frame" in err and "--strict" not in err and len(err.splitlines()) == 1
    assert not (tmp_path / "e.csv").exists()


def test_candump_s_default_output_is_told_to_write_with_minus_l(tmp_path, capsys):
    """candump's default and -ta output ('  can0  18FEF100   [8]  00 ...') were refused as 'not a .log text CAN log,
    or one damaged throughout', without the fix."""
    log = tmp_path / "plain.log"
    log.write_text("".join(f" ({k * 0.01:.6f})  can0  18FEF100   [8]  00 11 22 33 44 55 66 77\n" for k in range(20)))
    assert main(["replay", str(log), "--out", str(tmp_path / "o.csv")]) == 2
    assert "a .log is candump -L's form" in capsys.readouterr().err


def test_candump_lines_without_their_interface_are_told_so(tmp_path, capsys):
    """'(0.000000) 18FCF200#E1FF...' (a converter's candump -L without the interface name) got only 'none of its
    lines is a CAN frame' (a new user's review)."""
    log = tmp_path / "noiface.log"
    log.write_text("".join(f"({k * 0.01:.6f}) 18FEF100#0011223344556677\n" for k in range(20)))
    assert main(["replay", str(log), "--out", str(tmp_path / "o.csv")]) == 2
    assert "its lines lack the interface name (can0) between the time and the frame" in capsys.readouterr().err
