"""The physics predictor (tools/scada/physics.py): on readings its own sensor made with two effects and two reading
offsets planted, the fit finds them; an effect that moves no estimate is reported not identifiable and left neutral.

On the HR225 (the onboard sensor models it) with the column map of test_replay_scada.py, 6 h of 10-minute rows.
"""

from __future__ import annotations

import pytest

from firmware_model.config import load_config
from tests.tools.scada.test_reader import write
from tests.tools.scada.test_replay_scada import _map, _rows
from tools.cli.gearbox_option import with_gearbox
from tools.scada.nbm import TASKS
from tools.scada.physics import PhysicsModel
from tools.scada.reader import read_record
from tools.scada.replay import replay_record

PLANTED = {"bearing_loss_scale": 1.8, "housing_air_h_scale": 0.7}
#: the bearings' reading offsets planted with them [K] (the task fits one per channel, as the NBM its intercept)
OFFSETS_K = {"Gb1t_avg": 1.5, "Gb2t_avg": -0.8}


def test_the_fit_finds_the_planted_effects_of_its_own_sensor(tmp_path):
    rec = read_record([write(tmp_path / "a.csv", _rows(0, 36))], _map(tmp_path))
    cfg = with_gearbox(load_config(None), "HR225")
    truth = replay_record(rec, cfg, {"oil_mode": "measured"}, effects=PLANTED)
    for ch in ("Gb1t_avg", "Gb2t_avg"):
        rec.values[ch] = truth.table[f"est_{ch}"] + OFFSETS_K[ch]  # each bearing read a constant off
    model = PhysicsModel(TASKS["bearings"], cfg).fit([rec])
    assert model.report["not_identifiable"] == []
    for effect, value in PLANTED.items():
        assert model.effects[effect] == pytest.approx(value, rel=1e-3), model.report
    for ch, off_k in OFFSETS_K.items():
        assert model.effects[f"thermocouple_offset:{ch}"] == pytest.approx(off_k, abs=1e-3), model.report
    assert model.report["rms_k"] < 1e-3
    pred = model.predict(rec)
    assert abs(pred["Gb1t_avg"] - rec.values["Gb1t_avg"]).max() < 1e-3
