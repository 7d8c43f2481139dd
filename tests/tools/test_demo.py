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


#: a truck gearbox that publishes other components, in another order, than the GRS905 (so its frames differ)
G12 = """[meta]
inherit = "GRS905"
variant = "G12"

[topology.published]
order = { v = ["PS", "PP", "PR", "BIF", "BLF", "BLR", "BIM", "BMR", "BO", "LI.teeth", "LL", "oil"], u = "-", \
src = "assumed" }
gear = { v = ["LI.teeth", "LL"], u = "-", src = "assumed" }
bearing = { v = ["BIF", "BLF", "BLR", "BIM", "BMR", "BO"], u = "-", src = "assumed" }
sun = { v = ["PS"], u = "-", src = "assumed" }
planetary = { v = ["PP", "PR"], u = "-", src = "assumed" }
oil = { v = ["oil"], u = "-", src = "assumed" }
"""


def test_demo_of_another_gearbox_decodes_its_own_frames(tmp_path, capsys):
    """The demo decoded every gearbox's bus with the GRS905's DBC: a gearbox whose frames carry other components
    (a user's T6) stopped with a TypeError on a None temperature, and its plot looked its components up in the
    GRS905's limits. It now lays out, decodes and plots with the gearbox's own DBC and limits."""
    gb = tmp_path / "g12.toml"
    gb.write_text(G12)
    out = tmp_path / "demo"
    assert main(["demo", "--gearbox", str(gb), "--minutes", "2", "--out-dir", str(out), "--print-every", "60"]) == 0
    printed = capsys.readouterr().out
    assert "with the G12's DBC" in printed and "(8 per step; DM1 aside)" in printed, printed
    assert "oil   nan" not in printed
    assert "sensor vs plant truth over 12 components" in printed, printed  # its rig frames, decoded by its DBC
    assert (out / "demo.png").stat().st_size > 1000


def test_demo_of_a_fixed_ratio_drive(tmp_path, capsys):
    """A fixed-ratio gearbox (the R1) takes its own run table (input speed and torque) and its own limits."""
    import numpy as np

    from tools.runtable import RunTable, write_run_table

    t = np.arange(0.0, 121.0, 1.0)
    cyc = tmp_path / "c.csv"
    write_run_table(
        RunTable(
            {
                "time_s": t,
                "input_speed_rpm": np.full(t.size, 1000.0),
                "input_torque_nm": np.full(t.size, 200.0),
                "ambient_temp_c": np.full(t.size, 20.0),
            }
        ),
        cyc,
    )
    out = tmp_path / "demo"
    args = ["demo", "--gearbox", "R1", "--cycle", str(cyc), "--minutes", "2", "--out-dir", str(out)]
    assert main([*args, "--print-every", "60"]) == 0
    printed = capsys.readouterr().out
    assert "with the R1's DBC" in printed and "sensor vs plant truth over 7 components" in printed, printed
    assert (out / "demo.png").stat().st_size > 1000
