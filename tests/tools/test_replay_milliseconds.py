"""A CAN log whose time stamps are milliseconds (read as seconds: every frame ~1000x too far apart for its J1939
period) is said to look like milliseconds, by `replay` and by `fleet` alike, without stale_factor advice the option
refuses; in Unix milliseconds `fleet` puts it in its errors table with that sentence, not a raw "year 57983"."""

from __future__ import annotations

import logging
import re

import pytest

from firmware_model.errors import InputError
from firmware_model.service.options import STALE_FACTOR_MAX
from tools.cli import main

#: a one-minute steady drive: every input message at its J1939 rate
SPEC = "steady:gear=4L,rpm=1300,nm=2000,s=60"
UNIX_S = 1767600000.0  # 2026-01-05


def _scaled(lines: list[bytes], scale: float, offset_s: float) -> bytes:
    out = []
    for line in lines:
        stamp, rest = line.split(b")", 1)
        out.append(b"(%.3f" % (offset_s + scale * float(stamp[1:])) + b")" + rest)
    return b"\n".join(out) + b"\n"


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("ms")
    assert main(["simulate", "--cycle", SPEC, "--can-log", str(d / "s.log"), "--out", str(d / "run.csv")]) == 0
    lines = (d / "s.log").read_bytes().split(b"\n")[:-1]
    t0 = float(lines[0].split(b")")[0][1:])
    (d / "ms_rel.log").write_bytes(_scaled(lines, 1000.0, -1000.0 * t0))
    (d / "ms_unix.log").write_bytes(_scaled(lines, 1000.0, 1000.0 * (UNIX_S - t0)))
    # the drive in seconds cut into pieces of 2 s, each 100 s after the one before: 29 honest time jumps
    pieces = [
        line.replace(b"(%s" % stamp, b"(%.6f" % (float(stamp) + 100.0 * int((float(stamp) - t0) / 2.0)), 1)
        for line in lines
        for stamp in [line.split(b")")[0][1:]]
    ]
    (d / "jumps.log").write_bytes(b"\n".join(pieces) + b"\n")
    return d


def test_replay_says_milliseconds_and_names_no_refused_stale_factor(logs, capsys):
    rc = main(["replay", str(logs / "ms_rel.log"), "--out", str(logs / "e.csv")])
    err = capsys.readouterr().err
    assert rc == 3, err
    assert "warning: the log's time stamps look like milliseconds, not seconds" in err
    assert "give the time stamps in seconds" in err
    # not beside it "replayed slower than real time": the milliseconds explain the slow messages (a review)
    assert "time base suspect" not in err
    advised = [float(x.split()[0].rstrip(")")) for x in err.split("stale_factor = ")[1:]]
    assert all(f <= STALE_FACTOR_MAX for f in advised), advised
    # the same drive in seconds: no such finding
    assert main(["replay", str(logs / "s.log"), "--out", str(logs / "s.csv")]) == 0
    assert "milliseconds" not in capsys.readouterr().err


def _time_lines(caplog) -> list[str]:
    return [
        r.getMessage()
        for r in caplog.records
        if r.name.startswith("gearbox_vsensor.can_service")
        and re.match(r"frame time jumped|\d+ more frame time jumps|one frame's time stamp lies", r.getMessage())
    ]


@pytest.mark.parametrize("frames_out", [False, True], ids=["whole-log", "frame-by-frame"])
def test_a_millisecond_log_gives_its_one_sentence_not_a_flood_of_time_jumps(logs, capsys, caplog, frames_out):
    """The milliseconds finding explains every time jump and glitch of such a log: they are counted (the summary's
    note, the finding's count, the counters) but not logged one by one first (20 lines on the whole-log path, all
    4000 on the frame path)."""
    extra = ["--frames-out", str(logs / "gbx.log")] if frames_out else []
    with caplog.at_level(logging.INFO, logger="gearbox_vsensor.can_service"):
        rc = main(["replay", str(logs / "ms_rel.log"), "--out", str(logs / "e.csv"), *extra])
    out, err = capsys.readouterr()
    assert rc == 3, err
    assert _time_lines(caplog) == []
    [ms] = [line for line in err.splitlines() if "look like milliseconds" in line]
    jumps = int(re.search(r"and (\d+) of the gaps between them were taken for time jumps", ms).group(1))
    assert jumps > 20
    [note] = [line for line in out.splitlines() if line.startswith("note:") and "time jump" in line]
    assert note.startswith(f"note: {jumps} time jumps") and "milliseconds" in note and "above" not in note


@pytest.mark.parametrize("frames_out", [False, True], ids=["whole-log", "frame-by-frame"])
def test_honest_time_jumps_are_still_logged_alike_on_both_paths(logs, capsys, caplog, frames_out):
    """A log in seconds with 29 logger pauses: the first 20 jumps logged one by one and the rest counted in one
    line, whichever path replays it (the frame path logged all of them)."""
    extra = ["--frames-out", str(logs / "gbx2.log")] if frames_out else []
    with caplog.at_level(logging.INFO, logger="gearbox_vsensor.can_service"):
        main(["replay", str(logs / "jumps.log"), "--out", str(logs / "j.csv"), *extra])
    out, err = capsys.readouterr()
    assert "milliseconds" not in err
    lines = _time_lines(caplog)
    jumped = [line for line in lines if line.startswith("frame time jumped forward by 10")]
    assert len(jumped) == 20 and lines[-1] == "9 more frame time jumps (not logged one by one)", lines
    assert "note: 29 time jumps in the log (the warnings above say where)" in out


def test_fleet_marks_a_millisecond_log_untrusted_or_refuses_it_in_one_sentence(logs):
    from tools.fleet.manifest import LogEntry
    from tools.fleet.run import process_log

    status, row = process_log(LogEntry(logs / "ms_rel.log", "truck", None, None, None, "a"))
    assert status == "ok" and not row["trusted"], row
    assert "the log's time stamps look like milliseconds" in row["trust_warnings"]
    status, row = process_log(LogEntry(logs / "ms_unix.log", "truck", None, None, None, "b"))
    assert status == "error", row
    assert row["reason"].startswith("the log's first frame time 17676000000")
    assert row["reason"].endswith(
        "s is no date in seconds, but 2026-01-05 in milliseconds: its time stamps look like milliseconds; give "
        "seconds (candump -L writes seconds)"
    )


def test_log_date_has_an_upper_bound():
    from tools.fleet.summary import log_date

    assert log_date(UNIX_S) == "2026-01-05" and log_date(45.4) is None
    with pytest.raises(InputError, match="look like milliseconds"):
        log_date(1000 * UNIX_S)
    assert log_date(5e9) is None and log_date(1e18) is None  # no logger's clock, and no date in ms either
