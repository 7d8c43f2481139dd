"""The gear-numbering rule (firmware_model.service.plausibility.gear_ratio_finding): a vehicle whose gear numbers are
not its gearbox's (another transmission, or another numbering) is said out loud, from the engine speed per km/h in
each gear, while every named cycle, driven with the GRS905's own ratios, passes."""

from __future__ import annotations

import numpy as np
import pytest

from firmware_model.description import description_of
from firmware_model.parameters import load_parameters
from firmware_model.service.degraded import Severity
from firmware_model.service.plausibility import gear_ratio_finding
from tests.data_paths import SKIP_REASON, real_capture_dir
from tools.cli import main
from tools.cycles.named import get_cycle
from tools.replay.table import gear_meta

DATA = real_capture_dir()
needs_captures = pytest.mark.skipif(DATA is None, reason=SKIP_REASON)
META = gear_meta(description_of(load_parameters("GRS905")))


def _drive(gears, numbers, kmh_per_rpm_ratio=0.06, seconds=20.0):
    """0.1 s steps at 1400 rpm in each of ``gears`` (the GRS905's numbers) with the speed they give (km/h per rpm
    of the gearbox's output: 0.06 is an axle ratio of 3.1 on 0.5 m tyres), the gear column written as ``numbers``."""
    n = int(seconds / 0.1)
    rpm, kmh, gear = [], [], []
    for g, label in zip(gears, numbers):
        rpm.append(np.full(n, 1400.0))
        kmh.append(np.full(n, 1400.0 / META["gear_ratios"][g] * kmh_per_rpm_ratio))
        gear.append(np.full(n, float(label)))
    return np.concatenate(rpm), np.concatenate(kmh), np.concatenate(gear)


def test_gears_numbered_as_the_gearbox_pass_and_other_numbers_are_a_warning():
    rpm, kmh, gear = _drive([3, 4, 5, 6, 7, 8], [3, 4, 5, 6, 7, 8])
    assert gear_ratio_finding(rpm, kmh, gear, META["gear_ratios"], "GRS905") is None
    # numbered from 1 without the two crawler gears (CL, CH): 1L..3H reported as 1..6, steps that are not the ratios'
    f = gear_ratio_finding(rpm, kmh, gear - 2.0, META["gear_ratios"], "GRS905", source="can")
    assert f is not None and f.severity == Severity.WARNING and f.gears == (1, 2, 3, 4, 5, 6)
    assert (
        "ETC2 SPN 523" in f.sentence
        and "set [can] gear_map" in f.sentence
        and "where the GRS905's ratios step" in f.sentence
    )
    # crawling (under 5 km/h: a launch's clutch or converter slip) and a gear held under 3 s are not judged
    assert gear_ratio_finding(rpm, kmh * 0.01, gear - 2.0, META["gear_ratios"], "GRS905") is None
    r2, k2, g2 = _drive([7, 8], [5, 6], seconds=2.0)
    assert gear_ratio_finding(r2, k2, g2, META["gear_ratios"], "GRS905") is None


def test_a_shift_along_a_geometric_ladder_is_caught_by_the_axle_it_would_need():
    """The GRS905's upper gears step ~1.24 each: a numbering one off there keeps the steps, but the same speeds in
    gears whose ratios are 1.24x larger (here 4 gears up: 2.2x) need an axle ratio no road vehicle has."""
    rpm, kmh, gear = _drive([9, 10, 11, 12], [9, 10, 11, 12], kmh_per_rpm_ratio=0.06)  # axle 3.1 at 0.5 m
    assert gear_ratio_finding(rpm, kmh, gear, META["gear_ratios"], "GRS905") is None
    f = gear_ratio_finding(rpm, kmh, gear - 4.0, META["gear_ratios"], "GRS905")
    assert f is not None and "axle ratio of" in f.sentence and "where road vehicles have 2-7" in f.sentence
    assert "column gear" in f.sentence and "renumber the gears" in f.sentence


@pytest.mark.parametrize("name", ["all_gears", "long_haul", "uphill", "mining"])
def test_no_named_cycle_trips_the_rule(name):
    t = get_cycle(name, noise=True)  # measurement-like noise: the constants spread 4 % at most
    assert (
        gear_ratio_finding(t["engine_speed_rpm"], t["vehicle_speed_kmh"], t["gear"], META["gear_ratios"], "GRS905")
        is None
    )


@needs_captures
def test_the_real_trucks_gear_numbers_are_not_the_grs905s(tmp_path, capsys):
    """The university truck drives gears 2-4 at 51, 39 and 28 rpm per km/h: steps of 1.30 and 1.41, where the
    GRS905's gears 2-4 (CH, 1L, 1H) step 1.17 and 1.24, and in those gears an axle ratio of 0.6-0.7 (no truck's);
    a warning, the outputs written, exit 0."""
    rc = main(["replay", str(DATA / "normal.candump.log"), "--out", str(tmp_path / "e.csv"), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 0 and (tmp_path / "e.csv").exists()
    assert "warning: the gear (ETC2 SPN 523) does not follow the GRS905's ratios: driving in gears 2, 3, 4" in err
    assert (
        "(steps 1.30 : 1.41, where the GRS905's ratios step 1.17 : 1.24; over the GRS905's ratios an axle ratio" in err
    )
    assert "of 0.57-0.72 on 0.5 m tyres, where road vehicles have 2-7)" in err


@needs_captures
def test_replay_and_fleet_give_a_log_the_same_findings_the_gear_rule_included(tmp_path):
    """The findings of a log are one list (tools.replay.log.log_findings over replay_log's table): `fleet` used to
    drop the gear-numbering warning that `replay` added beside it (trusted, no trust_warnings, on the same
    capture)."""
    from firmware_model.service import build_service
    from tools.fleet.manifest import LogEntry
    from tools.fleet.run import process_log
    from tools.replay.log import log_findings, replay_log, replay_log_file

    log = DATA / "normal.candump.log"
    service = build_service(None, record=True, emit_frames=False, log_findings=False)
    found = log_findings(service, replay_log(log, service))
    gear = [f for f in found if "does not follow the GRS905's ratios" in f.sentence]
    assert len(gear) == 1 and gear[0].severity == Severity.WARNING, [f.sentence for f in found]
    status, row = process_log(LogEntry(log, "truck", None, None, None, "k"))
    assert status == "ok" and row["trusted"], row
    assert row["trust_warnings"] == " | ".join(f.sentence for f in found if f.severity >= Severity.WARNING)
    assert gear[0].sentence in row["trust_warnings"]
    replayed = replay_log_file(log, tmp_path / "e.csv")
    assert [f.sentence for f in replayed.findings] == [f.sentence for f in found]
