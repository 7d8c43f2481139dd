"""The README's main job: `gearbox-vsensor demo` runs end to end (short drive) and shows something readable."""
from tools.cli import main


def test_demo_runs_end_to_end(tmp_path, capsys):
    rc = main(["demo", "--minutes", "3", "--out-dir", str(tmp_path), "--print-every", "60"])
    out = capsys.readouterr().out
    assert rc == 0
    assert "frames in" in out and "sensor frames out" in out and "hottest" in out
    for f in ("plant.csv", "drive.log", "sensor.csv", "demo.png"):
        assert (tmp_path / f).stat().st_size > 1000, f
