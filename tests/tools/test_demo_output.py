"""What `gearbox-vsensor demo` leaves on disk: 1 s run tables, where it says, and not in git's way."""

from pathlib import Path

import numpy as np

from tools.cli import main
from tools.runtable import read_run_table

ROOT = Path(__file__).resolve().parents[2]
MB_PER_MINUTE = 0.7  # 40 minutes of drive wrote 60 MB (10 Hz run tables); now about 23 MB


def test_demo_writes_little_says_where_and_is_ignored_by_git(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--minutes", "2", "--out-dir", str(out), "--print-every", "60"]) == 0
    printed = capsys.readouterr().out
    for name in ("plant.csv", "sensor.csv"):
        t = read_run_table(out / name, required=("time_s",))
        assert t.n >= 100 and np.allclose(np.diff(t["time_s"]), 1.0, atol=0.01), name
    size_mb = sum(f.stat().st_size for f in out.iterdir()) / 1e6
    assert size_mb < 2 * MB_PER_MINUTE, f"{size_mb:.1f} MB for 2 minutes of drive"
    assert f"to {out.resolve()}" in printed
    assert "/demo_out/" in (ROOT / ".gitignore").read_text().split()


def test_every_keeps_whole_seconds_or_the_first_row_of_each_second():
    from tools.demo import every
    from tools.runtable import RunTable

    assert list(every(RunTable({"time_s": [0.1, 0.2, 1.0, 1.1, 2.0, 2.1]}))["time_s"]) == [1.0, 2.0]
    assert list(every(RunTable({"time_s": [0.0, 0.35, 0.9, 1.2, 2.05]}))["time_s"]) == [0.0, 1.2, 2.05]
