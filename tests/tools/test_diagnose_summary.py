"""What `diagnose` prints on the console (tools.cli.diagnose._print_summary is the command's own)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

from tools.cli import diagnose as cli

EXAMPLE = Path(__file__).resolve().parents[2] / "docs" / "diagnosis" / "truck.json"


def test_the_console_names_the_confusable_candidates(capsys):
    """The console named the verdict alone while the JSON and the report listed the candidates that fit the files
    about as well (a user went by the console)."""
    res = json.loads(EXAMPLE.read_text())
    cli.print_summary(SimpleNamespace(json="gap.json"), res)
    out = capsys.readouterr().out
    assert "verdict: churning_scale" in out
    assert "confusable with: bearing_loss_scale, oil_sensor_offset" in out
