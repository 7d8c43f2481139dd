"""The README's main job: `gearbox-vsensor demo` runs end to end (short drive) and shows something readable."""

from tools.cli import main


def test_demo_runs_end_to_end(tmp_path, capsys):
    rc = main(["demo", "--minutes", "3", "--out-dir", str(tmp_path), "--print-every", "60"])
    out = capsys.readouterr().out
    assert rc == 0
    assert "frames in" in out and "GBX frames out" in out and "closest to their limits" in out
    assert "t=   180 s" in out, "the table covers the whole drive, its last step included"
    assert "TTL 0 s" not in out
    for f in ("plant.csv", "drive.log", "sensor.csv", "demo.png"):
        assert (tmp_path / f).stat().st_size > 1000, f


def test_component_errors_against_the_truth_on_the_bus():
    """Sensor minus the rig thermocouples that travelled on the bus, per component; NaN samples ignored."""
    import numpy as np

    from tools.demo import component_errors
    from tools.runtable import RunTable

    est = RunTable(
        {
            "time_s": [0.0, 0.1, 0.2],
            "T_PS_c": [80.0, 81.0, 82.0],
            "meas_T_PS_c": [79.0, 81.0, np.nan],
            "T_oil_c": [70.0, 70.0, 70.0],
        }
    )
    (e,) = component_errors(est)
    assert e.component == "PS" and e.max_abs_k == 1.0 and e.rms_k == np.sqrt(0.5)
