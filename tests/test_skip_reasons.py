"""A default `python -m pytest` run says why tests skip, and each reason says how to get what is missing."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from tests.data_paths import CAPTURE_FILES, SKIP_REASON

ROOT = Path(__file__).resolve().parents[1]


def test_the_default_run_prints_the_skip_reasons(tmp_path):
    probe = tmp_path / "test_probe.py"
    probe.write_text("import pytest\n\n\ndef test_probe():\n    pytest.skip('PROBE: get it with `make probe`')\n")
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-p",
            "no:cacheprovider",
            "-c",
            str(ROOT / "pyproject.toml"),
            "--rootdir",
            str(tmp_path),
            str(probe),
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert res.returncode == 0, res.stdout + res.stderr
    assert "SKIPPED [1]" in res.stdout and "PROBE: get it with `make probe`" in res.stdout


def test_the_real_captures_reason_says_how_to_provide_them():
    assert "GVS_REAL_J1939=" in SKIP_REASON and all(f in SKIP_REASON for f in CAPTURE_FILES)
    can_md = (ROOT / "docs" / "can.md").read_text(encoding="utf-8")
    assert "\n### Real truck captures\n" in can_md and "'Real truck captures'" in SKIP_REASON
    assert all(f"`{f}`" in can_md for f in CAPTURE_FILES)


def test_the_real_scada_reason_says_how_to_provide_them():
    from tests.data_paths import SCADA_SKIP_REASON

    assert "GVS_REAL_SCADA=" in SCADA_SKIP_REASON
    md = (ROOT / "docs" / "real-data.md").read_text(encoding="utf-8")
    assert md.startswith("# Real measured temperatures\n") and "'Real measured temperatures'" in SCADA_SKIP_REASON
