"""Effect oil_level_low on gearboxes other than the GRS905 family: its litres (8..13.5, neutral 13.5) are that
sump's, and a description's own oil volume (topology.oil.volume) is no parameter the effect can lower. A new
user's 6-speed gearbox (11 L) got "cannot override unknown parameter 'oil.volume'" from diagnose, simulate --effect
and fleet --diagnose, whose every log then failed one by one."""

from __future__ import annotations

from collections import namedtuple

import pytest

from firmware_model.config import load_config
from firmware_model.effects import oil_level_refusal, with_oil_volume
from firmware_model.errors import InputError
from tools.cli.gearbox_option import with_gearbox


def _params(gearbox):
    return with_gearbox(load_config(None), gearbox).load_params()


def test_the_effect_lowers_the_grs905_family_s_sump_and_refuses_another_gearbox_in_one_sentence():
    grs = _params("GRS905")
    assert oil_level_refusal(grs) is None
    assert with_oil_volume(grs, 9.0).values["oil.volume"] == pytest.approx(9e-3)
    r1 = _params("R1")
    assert "topology.oil.volume" in oil_level_refusal(r1)
    assert with_oil_volume(r1, 13.5) is r1  # neutral: nothing to lower
    with pytest.raises(InputError, match="GRS905 family's sump.*give a lower volume there"):
        with_oil_volume(r1, 9.0)


def test_the_diagnosis_leaves_it_out_of_its_candidates_where_it_cannot_act():
    from tools.diagnosis.core import default_candidates

    assert "oil_level_low" in default_candidates([], _params("GRS905"))
    r1 = default_candidates([], _params("R1"))
    assert "oil_level_low" not in r1 and "churning_scale" in r1


def test_fleet_diagnose_refuses_such_logs_before_any_work():
    from tools.cli.fleet import check_health_gearboxes

    entry = namedtuple("Entry", "variant")
    check_health_gearboxes([entry("GRS905"), entry(None)])
    with pytest.raises(InputError, match="--diagnose fits the cooler's effectiveness.*gearbox R1"):
        check_health_gearboxes([entry("GRS905"), entry("R1")])
