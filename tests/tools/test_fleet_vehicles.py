"""Which vehicle a log of a fleet folder belongs to (tools.fleet.manifest.entries_and_rule, without a manifest)."""

from __future__ import annotations

from tools.fleet.manifest import entries_and_rule


def _touch(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("(0.000000) can0 0CF00400#0000000000000000\n")
    return path


def test_a_truck_s_folder_with_month_folders_is_still_that_truck(tmp_path):
    """logs/truck1/2026-01/d05.log and logs/truck3/2026-01/d05.log were one vehicle, "2026-01" (the folder holding
    each log), their health fits blended into one (a healthy cooler and a fouled one: 0.69). The vehicle is the
    folder directly inside the folder given, at any depth; a log directly in it is its own vehicle, as before."""
    for truck in ("truck1", "truck3"):
        for month in ("2026-01", "2026-02"):
            _touch(tmp_path / truck / month / "d05.log")
    _touch(tmp_path / "truck2" / "d05.log")
    _touch(tmp_path / "loose_truck9.log")
    entries, rule = entries_and_rule([tmp_path])
    by_vehicle = sorted({(e.vehicle, e.log.relative_to(tmp_path).as_posix()) for e in entries})
    assert by_vehicle == [
        ("loose_truck9", "loose_truck9.log"),
        ("truck1", "truck1/2026-01/d05.log"),
        ("truck1", "truck1/2026-02/d05.log"),
        ("truck2", "truck2/d05.log"),
        ("truck3", "truck3/2026-01/d05.log"),
        ("truck3", "truck3/2026-02/d05.log"),
    ]
    assert rule.startswith("vehicles: 4: 3 from the folders holding 5 logs")


def test_a_folder_of_scada_files_without_columns_says_to_give_columns(tmp_path):
    """`fleet turbines/ --out o` on a folder of SCADA .csv.gz files said only "no CAN log (...) to run": the user
    who forgot --columns is told the folder's files are read with it."""
    import pytest

    from firmware_model.errors import InputError

    (tmp_path / "turbine_A_1.csv.gz").write_bytes(b"")
    (tmp_path / "turbine_B_1.csv").write_text("Date_time\n")
    with pytest.raises(
        InputError,
        match=r"no CAN log .* 2 SCADA file\(s\) \(\.csv, \.csv\.gz, e\.g\. turbine_A_1\.csv\.gz\).*--columns",
    ):
        entries_and_rule([tmp_path])
    (tmp_path / "turbine_A_1.csv.gz").unlink()
    (tmp_path / "turbine_B_1.csv").unlink()
    with pytest.raises(InputError, match=r"no CAN log") as err:  # an empty folder: no word of SCADA
        entries_and_rule([tmp_path])
    assert "--columns" not in str(err.value)


def test_the_report_counts_the_trusted_logs_hours_and_the_untrusted_apart():
    """A 3-minute log in milliseconds (untrusted) added 3.0 truck-hours to the report."""
    from tools.fleet.report import truck_hours

    c = {"duration_s": [3600.0, 10800.0, 1800.0], "trusted": [True, False, True]}
    assert (
        truck_hours(c)
        == "1.5 truck-hours (3.0 h more in 1 untrusted logs, not counted: their time base or inputs are suspect)"
    )
    assert truck_hours({"duration_s": [3600.0], "trusted": [True]}) == "1.0 truck-hours"
    assert truck_hours({"duration_s": [3600.0, 1800.0], "trusted": [None, True]}) == "1.5 truck-hours"  # (old rows)
    assert truck_hours({"duration_s": [3600.0, float("nan")]}) == "1.0 truck-hours"  # a row without a duration


def test_files_of_a_folder_that_are_no_log_by_their_suffix_are_named(tmp_path):
    """A candump log saved as .candump or .txt was dropped without a word (22 files, "20 logs"): the vehicles'
    sentence counts and names the files not taken; a folder of logs only says nothing more."""
    _touch(tmp_path / "a.log")
    _, rule = entries_and_rule([tmp_path])
    assert "not taken" not in rule
    _touch(tmp_path / "tsc1.candump")
    _touch(tmp_path / "tsc1.txt")
    entries, rule = entries_and_rule([tmp_path])
    assert [e.log.name for e in entries] == ["a.log"]
    assert "; 2 other file(s) not taken, no CAN log by their suffix (tsc1.candump, tsc1.txt)" in rule, rule
    assert "logconvert" not in rule
    # a python-can CSV log was told to run 'renamed to .log' (it is no candump text): converted (a review)
    _touch(tmp_path / "pycan.csv")
    _, rule = entries_and_rule([tmp_path])
    assert "a python-can CSV log runs converted (python -m can.logconvert IN.csv OUT.log)" in rule, rule


def test_a_log_copied_under_another_vehicle_is_named_a_copy():
    """A logger's log (Unix frame times) copied into two trucks' folders gave one drive to both without a word (a
    review: copies were looked for within a vehicle only). Two trucks' equally long logs with relative frame times
    (both from 0 s) are no copies of each other; within one vehicle they are, as before."""
    from tools.fleet.report import copy_vehicles, duplicate_logs

    t0 = 1.77e9
    c = {
        "vehicle": ["truck1", "truck2", "truck3", "truck4", "truck4", "truck5"],
        "log": ["a/d1.log", "b/d1.log", "c/r.log", "d/r.log", "d/r2.log", "e/other.log"],
        "start_s": [t0, t0, 0.0, 0.0, 0.0, t0 + 1.0],
        "end_s": [t0 + 3600.0, t0 + 3600.0, 3600.0, 3600.0, 3600.0, t0 + 3600.0],
        "frames": [9000, 9000, 9000, 9000, 9000, 9000],
    }
    groups = duplicate_logs(c)
    assert sorted(groups) == [["a/d1.log", "b/d1.log"], ["d/r.log", "d/r2.log"]]
    assert copy_vehicles(c, ["a/d1.log", "b/d1.log"]) == ["truck1", "truck2"]
    c["start_s"][1] += 0.001  # one frame time apart: two drives
    assert duplicate_logs(c) == [["d/r.log", "d/r2.log"]]


def test_a_clock_at_its_reset_day_dates_no_log_and_a_date_unlike_the_frames_is_named():
    """Logs from clocks reset to 2000-01-01 or GPS's 1980-01-06 were dated so ('dates 1980-01-06 to 2026-01-07'),
    and a manifest's date four days off the frames' won without a word (a new user's review)."""
    import datetime as dt

    from tools.fleet.report import misdated_logs
    from tools.fleet.summary import log_date

    def unix(day):
        return dt.datetime.combine(day, dt.time(8), tzinfo=dt.timezone.utc).timestamp()

    assert log_date(unix(dt.date(2000, 1, 1))) is None and log_date(unix(dt.date(1980, 1, 7))) is None
    assert log_date(unix(dt.date(2026, 1, 5))) == "2026-01-05" and log_date(unix(dt.date(2000, 2, 1))) == "2000-02-01"
    c = {
        "log": ["a.log", "b.log", "c.log", "d.log"],
        "date": ["2026-01-09", "2026-01-06", "unknown", "2026-01-09"],
        "start_s": [unix(dt.date(2026, 1, 5)), unix(dt.date(2026, 1, 5)), unix(dt.date(2026, 1, 5)), 12.0],
    }
    assert misdated_logs(c) == [("a.log", "2026-01-09", "2026-01-05")]  # a day apart (midnight) is no mistake
