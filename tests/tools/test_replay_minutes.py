"""A run table whose time_s is in minutes (one row a minute, a drive of hours stored as 0..N): its oil, read over
seconds, changes faster than any gearbox sump can, and `replay` says so (exit 3) instead of silently stepping
hours of drive as minutes; the same rows in seconds, and the honest 1 s table, draw no such finding. The rule:
firmware_model.service.plausibility.oil_rate_finding (docs/can.md "Trust findings")."""

from __future__ import annotations

import numpy as np
import pytest

from tools.cli import main
from tools.cycles.named import BC_COLUMNS, COLUMNS
from tools.runtable import RunTable, read_run_table, write_run_table

#: the named cycles' input columns (not their boundary temperatures, which no replay reads) and the plant's oil
INPUTS = (*COLUMNS[: -len(BC_COLUMNS)], "oil_temp_c")


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    """The long-haul cycle's plant (1 h from a cold sump, one row a second), as recorded and as one row a minute
    with time_s in seconds and in minutes."""
    d = tmp_path_factory.mktemp("minutes")
    assert main(["simulate", "--cycle", "long_haul", "--out", str(d / "plant.csv"), "--quiet"]) == 0
    plant = read_run_table(d / "plant.csv")
    cols = {c: np.asarray(plant[c], dtype=float) for c in INPUTS}
    write_run_table(RunTable(cols), d / "s1.csv")
    rows = {c: v[::60] for c, v in cols.items()}
    write_run_table(RunTable(rows), d / "s60.csv")
    write_run_table(RunTable({**rows, "time_s": rows["time_s"] / 60.0}), d / "minutes.csv")
    return d


def test_a_table_in_minutes_is_untrusted_with_the_oils_rate(tables, capsys):
    rc = main(["replay", str(tables / "minutes.csv"), "--out", str(tables / "e.csv")])
    err = capsys.readouterr().err
    assert rc == 3, err
    [line] = [x for x in err.splitlines() if "where a gearbox sump" in x]
    assert line.startswith("warning: column oil_temp_c changes")
    assert "if time_s is in minutes, give seconds (time_s x 60)" in line


@pytest.mark.parametrize("name", ["s1.csv", "s60.csv"])
def test_the_same_drive_in_seconds_has_no_such_finding(tables, capsys, name):
    rc = main(["replay", str(tables / name), "--out", str(tables / "e.csv")])
    err = capsys.readouterr().err
    assert "where a gearbox sump" not in err and rc == 0, err


@pytest.mark.parametrize("every_s", [60, 1])
def test_a_12_minute_table_in_minutes_is_found_too(tables, capsys, every_s):
    """The drive's first 12 minutes with time_s in minutes (one row a minute: 0..12, 13 rows; or every second's row:
    0..12 in steps of 1/60): 12 s of time_s hold less than two windows, so the whole record must be that fast."""
    s1 = read_run_table(tables / "s1.csv")
    rows = {c: np.asarray(s1[c], dtype=float)[: 12 * 60 + 1 : every_s] for c in INPUTS}
    path = tables / f"short_minutes_{every_s}.csv"
    write_run_table(RunTable({**rows, "time_s": rows["time_s"] / 60.0}), path)
    rc = main(["replay", str(path), "--out", str(tables / "e.csv")])
    err = capsys.readouterr().err
    assert rc == 3, err
    assert "if time_s is in minutes, give seconds (time_s x 60)" in err


@pytest.mark.parametrize("seconds", [12, 15, 25])
def test_the_first_seconds_of_the_drive_have_no_such_finding(tables, capsys, seconds):
    """Honest short tables (the drive's first 12-25 s, one row a second) are not judged faster than a sump."""
    s1 = read_run_table(tables / "s1.csv")
    path = tables / f"first_{seconds}.csv"
    write_run_table(RunTable({c: np.asarray(s1[c], dtype=float)[: seconds + 1] for c in INPUTS}), path)
    rc = main(["replay", str(path), "--out", str(tables / "e.csv")])
    err = capsys.readouterr().err
    assert "where a gearbox sump" not in err and rc == 0, err
