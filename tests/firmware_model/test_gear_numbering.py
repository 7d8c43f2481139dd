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
    # the same steps, scaled: a vehicle speed in m/s looks alike, and was blamed on the gear numbers alone
    assert "either engine_speed_rpm or vehicle_speed_kmh is in another unit or scale (m/s for km/h" in f.sentence
    g = gear_ratio_finding(rpm, kmh / 3.6, gear, META["gear_ratios"], "GRS905")
    assert g is not None and "an axle ratio of 11 on 0.5 m tyres" in g.sentence and "give rpm and km/h" in g.sentence


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


def test_a_launch_on_a_slipping_clutch_is_not_judged():
    """Pulling away, the clutch holds the engine at ~1000 rpm while the truck gathers speed: its engine speed per
    km/h falls from 185 to the gear's 100 over 5 s and would read the launch gear's constant 10 % high (a false
    warning on the GRS905's own drive). Only steady rows count: over 1 s in the same gear the engine speed per km/h
    moves by at most GEAR_STEADY_TOL, which a slipping clutch's does not."""
    ratios = META["gear_ratios"]
    t = np.arange(0.0, 5.0, 0.1)
    slip_kmh = 5.0 + t  # 5 -> 10 km/h at 1000 rpm: a locked gear 6 would turn 1000 rpm at 10 km/h
    const = 1000.0 / 10.0 / ratios[6]  # rpm per km/h per unit of gearbox ratio (axle 3.1 on 0.5 m tyres)
    locked_s = 2.5  # the launch gear held briefly once locked, then the upper gears, each for 10 s
    rpm, kmh, gear = [np.full(t.size, 1000.0)], [slip_kmh], [np.full(t.size, 6.0)]
    for g, s in ((6, locked_s), (8, 10.0), (9, 10.0), (10, 10.0), (12, 10.0)):
        n = int(round(s / 0.1))
        v = np.full(n, 1300.0 / (const * ratios[g]))
        rpm.append(np.full(n, 1300.0))
        kmh.append(v)
        gear.append(np.full(n, float(g)))
    rpm, kmh, gear = (np.concatenate(x) for x in (rpm, kmh, gear))
    assert gear_ratio_finding(rpm, kmh, gear, ratios, "GRS905") is None
    # the same drive with gear 12 sent as 11 (a numbering that skips one) is still another gearbox's
    f = gear_ratio_finding(rpm, kmh, np.where(gear == 12.0, 11.0, gear), ratios, "GRS905")
    assert f is not None and f.gears == (8, 9, 10, 11), f


@pytest.fixture(scope="module")
def uphill_can_log(tmp_path_factory):
    """The tool's own synthetic GRS905 drive (simulate --cycle uphill --can-log)."""
    d = tmp_path_factory.mktemp("uphill")
    rc = main(["simulate", "--cycle", "uphill", "--out", str(d / "run.csv"), "--can-log", str(d / "up.log"), "--quiet"])
    assert rc == 0
    return d / "up.log"


@pytest.mark.parametrize("seconds", [45.0, 60.0, 120.0])
def test_a_short_launch_of_the_grs905_s_own_drive_gives_no_gear_warning(uphill_can_log, tmp_path, capsys, seconds):
    """The first minute of the synthetic uphill drive (a launch in gear 6 on a slipping clutch, gears 7-12 held
    for 2-10 s each, the vehicle speed sent once a second) replayed alone: it warned that the GRS905's own gears
    "do not follow the GRS905's ratios" (gear 6 at 111.6 rpm per km/h, the launch's slip), the full log did not."""
    cut = tmp_path / "cut.log"
    with open(uphill_can_log) as src, open(cut, "w") as out:
        for line in src:
            if float(line[1 : line.index(")")]) >= seconds:
                break
            out.write(line)
    capsys.readouterr()
    rc = main(["replay", str(cut), "--out", str(tmp_path / "e.csv"), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 0 and (tmp_path / "e.csv").exists()
    assert "does not follow" not in err, err


def test_a_higher_gear_turning_the_engine_faster_names_the_speed_columns_not_the_numbering():
    """Swapped speed and torque columns: the engine turned 51.2 then 56.3 then 32.2 then 38.3 rpm per km/h in
    gears 10 to 13, and the warning advised renumbering the gears, which no numbering mends."""
    from firmware_model.service.plausibility import GearRatioFinding

    f = GearRatioFinding((10, 11, 12, 13), (51.2, 56.3, 32.2, 45.0), (1.6, 1.29, 1.0, 0.8), "GRS905")
    assert "more in gear 13 than in the gear below: no gearbox's numbering does that" in f.sentence
    assert "engine_speed_rpm and vehicle_speed_kmh" in f.sentence and "renumber" not in f.sentence
    ok = GearRatioFinding((10, 11, 12), (60.0, 40.0, 30.0), (1.6, 1.29, 1.0), "GRS905")
    assert "renumber the gears" in ok.sentence
