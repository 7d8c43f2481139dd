"""The named cycles on a vehicle gearbox outside the GRS905 family (tools.cycles.fit, docs/cycles.md "Another
gearbox"): its own gear ratios give the vehicle speed, its own boundary temperatures stand, the road cycles are
fitted to its gears and drive limits, and `export-c` builds its test vectors from them. The gearbox is T6
(tests/firmware_model/gearboxes/T6.toml): six speeds, direct 6th, 2600 Nm, ambient 20 and end yoke 60 degC."""

from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from firmware_model.description import description_of
from firmware_model.errors import InputError
from firmware_model.parameters import load_parameters
from tools.cli import main
from tools.cycles.named import get_cycle
from tools.cycles.vehicle import KMH_PER_M_S, Vehicle
from tools.runtable import read_run_table

T6 = Path(__file__).resolve().parents[1] / "firmware_model" / "gearboxes" / "T6.toml"
HAVE_CC = shutil.which("make") is not None and (shutil.which("cc") or shutil.which("gcc")) is not None


@pytest.fixture(scope="module")
def t6():
    return description_of(load_parameters(T6))


def _kmh(rpm: float, ratio: float) -> float:
    """Vehicle speed through the cycles' axle and wheel (final drive 3.07, wheel radius 0.5 m)."""
    veh = Vehicle()
    return rpm * math.pi / 30.0 / (ratio * veh.final_drive) * veh.wheel_radius_m * KMH_PER_M_S


def test_steady_takes_the_gearboxs_own_ratio_and_boundaries(tmp_path, capsys):
    out = tmp_path / "s.csv"
    spec = "steady:gear=6,rpm=1500,nm=1000,s=20"
    assert main(["simulate", "--gearbox", str(T6), "--cycle", spec, "--out", str(out), "--quiet"]) == 0
    tb = read_run_table(out)
    # direct 6th at 1500 rpm: ~92 km/h, a truck's cruise (the GRS905's 6th gear ratio gave 15.35 km/h)
    np.testing.assert_allclose(tb["vehicle_speed_kmh"], _kmh(1500.0, 1.0), rtol=1e-9)
    assert 90.0 < tb["vehicle_speed_kmh"][0] < 94.0
    # its description's ambient and end yoke (20, 60 degC), not the GRS905's Table 11 (25, 80 degC)
    assert np.all(tb["ambient_temp_c"] == 20.0) and np.all(tb["bc_end_yoke_c"] == 60.0)
    assert not tb.has("bc_support_beam_c")  # a boundary of the GRS905's, not of T6's


def test_steady_gears_are_the_gearboxs_own(t6):
    low = get_cycle("steady:gear=1,rpm=1500,nm=1000,s=10", description=t6)
    np.testing.assert_allclose(low["vehicle_speed_kmh"], _kmh(1500.0, 5.5), rtol=1e-9)
    named = get_cycle("steady:gear=G6,rpm=1500,nm=1000,s=10", description=t6)
    assert np.all(named["gear"] == 6)
    # left out: its forward gear nearest the GRS905's 4L (3.03) in ratio, its 3rd (2.8)
    assert np.all(get_cycle("steady:rpm=1300,nm=1000,s=10", description=t6)["gear"] == 3)
    idle = get_cycle("steady:gear=N,s=10", description=t6)
    assert np.all(idle["engine_torque_nm"] == 0) and np.all(idle["vehicle_speed_kmh"] == 0)
    # the GRS905's Table 1 names and numbers it does not have are refused in one sentence naming its gears
    for gear in ("4L", "14"):
        with pytest.raises(InputError, match=rf"gear={gear} is no gear of T6; its gears: -1 \(R\), 0 \(N\)"):
            get_cycle(f"steady:gear={gear},s=10", description=t6)


@pytest.mark.parametrize("name", ["all_gears", "uphill"])
def test_named_cycles_are_fitted_to_its_gears_and_limits(t6, name):
    tb = get_cycle(name, description=t6)
    gears = {g.number: abs(g.ratio) for g in t6.gears}
    assert set(np.unique(tb["gear"]).astype(int)) <= set(gears)
    assert 6 in tb["gear"]  # the GRS905's direct 6H onto its direct 6th
    tq = tb["engine_torque_nm"]
    assert tq.max() <= t6.drive.max_torque_nm and tq.min() >= t6.drive.min_torque_nm
    grs = get_cycle(name)
    np.testing.assert_allclose(tq.max(), grs["engine_torque_nm"].max() * 2600.0 / 4200.0, rtol=1e-12)
    ratio = np.array([gears[int(g)] for g in tb["gear"]])
    kmh = np.where(np.isfinite(ratio), _kmh(1.0, 1.0) * tb["engine_speed_rpm"] / ratio, 0.0)
    np.testing.assert_allclose(tb["vehicle_speed_kmh"], kmh, rtol=1e-9, atol=1e-9)
    assert np.all(tb["ambient_temp_c"] == 20.0) and np.all(tb["bc_end_yoke_c"] == 60.0)
    assert "fitted to T6" in tb.meta["fitted"]


def test_the_grs905_family_runs_the_cycles_as_they_are():
    d = description_of(load_parameters("GRS905"))
    for spec in ("uphill", "steady:gear=4L,rpm=1300,nm=2000,s=10"):
        a, b = get_cycle(spec), get_cycle(spec, description=d)
        assert a.columns == b.columns and "fitted" not in b.meta
        for c in a.columns:
            np.testing.assert_array_equal(a[c], b[c])


@pytest.mark.skipif(not HAVE_CC, reason="needs make and a C compiler")
def test_export_c_of_another_truck_gearbox_passes_its_vectors(tmp_path):
    out = tmp_path / "t6_c"
    # the vectors came from the GRS905's uphill cycle as it is: 3000 Nm, over T6's 2600 Nm, refused
    assert main(["export-c", "--gearbox", str(T6), "--out", str(out), "--quiet"]) == 0
    assert "the uphill cycle fitted to T6" in (out / "README.md").read_text()
    run = subprocess.run(["make", "-C", str(out), "test"], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0 and "PASS" in run.stdout, run.stdout + run.stderr
