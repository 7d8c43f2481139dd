"""J1939 network management of the live sensor node (issue: in-vehicle gateway): it claims its address at start-up
and holds its periodic frames for the 250 ms contention window, answers requests, yields to a higher-priority NAME
(stops transmitting, or takes another address when arbitrary-address capable) and defends against a lower one; an
`address_claim` attack (a flood of claims for its address with random NAMEs) never makes it misbehave."""

from __future__ import annotations

import random

import can
import pytest

from can_dbc.j1939 import NULL_ADDRESS, can_id_of, pgn_of, source_address
from firmware_model.service import SensorService, ServiceOptions
from firmware_model.service.netmgmt import (
    PGN_ACKNOWLEDGEMENT,
    PGN_ADDRESS_CLAIMED,
    PGN_REQUEST,
    PGN_SOFTWARE_ID,
    J1939Name,
)
from tests.firmware_model.sensor_standin import VirtualSensor as StandIn
from tests.firmware_model.test_can_service import traffic

SA = 0xE5


def _service(**name):
    return SensorService(
        StandIn(), ServiceOptions(configured_ref_torque_nm=2000.0, address_claim=True, j1939_name=J1939Name(**name))
    )


def claim(t, sa, name_value):
    return can.Message(
        timestamp=t,
        arbitration_id=can_id_of(PGN_ADDRESS_CLAIMED, sa, 6),
        is_extended_id=True,
        data=name_value.to_bytes(8, "little"),
    )


def request(t, pgn, dest=0xFF, sa=0x21):
    return can.Message(
        timestamp=t,
        arbitration_id=can_id_of(PGN_REQUEST, sa, 6, dest),
        is_extended_id=True,
        data=pgn.to_bytes(3, "little"),
    )


def _pgns(frames):
    return [(pgn_of(m.arbitration_id), source_address(m.arbitration_id)) for m in frames]


def test_claims_at_start_and_waits_250_ms_before_its_outputs():
    svc = _service()
    out = svc.feed_all(traffic(0.0, 2.0))
    assert _pgns(out)[0] == (PGN_ADDRESS_CLAIMED, SA)
    assert int.from_bytes(bytes(out[0].data), "little") == J1939Name().value()
    gbx = [m for m in out if 0xFF40 <= pgn_of(m.arbitration_id) <= 0xFF4F]
    assert gbx and min(m.timestamp for m in gbx) >= out[0].timestamp + 0.25 - 1e-9
    assert svc.counters.get("frames_held_no_address", 0) > 0


def test_answers_requests_and_nacks_the_unknown():
    svc = _service()
    svc.feed_all(traffic(0.0, 3.0))
    assert _pgns(svc.feed(request(3.01, PGN_ADDRESS_CLAIMED))) == [(PGN_ADDRESS_CLAIMED, SA)]
    soft = svc.feed(request(3.02, PGN_SOFTWARE_ID, dest=SA))
    assert _pgns(soft) == [(PGN_SOFTWARE_ID, SA)] and bytes(soft[0].data).endswith(b"*")
    dm1 = svc.feed(request(3.03, 0xFECA))
    assert _pgns(dm1) == [(0xFECA, SA)]
    nack = svc.feed(request(3.04, 0xFEEE, dest=SA, sa=0x21))
    assert _pgns(nack) == [(PGN_ACKNOWLEDGEMENT, SA)] and nack[0].data[0] == 1 and nack[0].data[4] == 0x21
    assert svc.feed(request(3.05, 0xFEEE, dest=0x44)) == []  # to another node: none of its business


def test_loses_to_a_higher_priority_name_and_stops_transmitting(caplog):
    svc = _service()
    svc.feed_all(traffic(0.0, 2.0))
    out = svc.feed(claim(2.001, SA, 1))  # NAME 1 beats ours
    assert _pgns(out) == [(PGN_ADDRESS_CLAIMED, NULL_ADDRESS)]  # Cannot Claim Address
    later = svc.feed_all(traffic(2.002, 4.0))
    assert not [m for m in later if source_address(m.arbitration_id) == SA]
    assert svc.netmgmt.address is None and "stops transmitting" in caplog.text


def test_arbitrary_capable_takes_another_address_and_keeps_sending():
    svc = _service(arbitrary_address_capable=True)
    svc.feed_all(traffic(0.0, 2.0))
    out = svc.feed(claim(2.001, SA, 1))
    new = svc.netmgmt.address
    assert new is not None and 128 <= new <= 247 and _pgns(out) == [(PGN_ADDRESS_CLAIMED, new)]
    later = svc.feed_all(traffic(2.002, 4.0))
    assert [m for m in later if source_address(m.arbitration_id) == new and pgn_of(m.arbitration_id) == 0xFF4F]
    assert not [m for m in later if source_address(m.arbitration_id) == SA]


def test_defends_against_a_lower_priority_name():
    svc = _service()
    svc.feed_all(traffic(0.0, 2.0))
    out = svc.feed(claim(2.001, SA, (1 << 64) - 1))
    assert _pgns(out) == [(PGN_ADDRESS_CLAIMED, SA)] and svc.netmgmt.address == SA


def test_an_address_claim_flood_never_crashes_or_floods():
    """The address_claim attack pattern: random NAMEs claiming every address, ours included, many per second."""
    rng = random.Random(5)
    svc = _service()
    frames = traffic(0.0, 6.0)
    t = 0.0
    attack = []
    while t < 6.0:
        t += 0.002
        attack.append(claim(t, rng.choice([SA, rng.randrange(0, 254)]), rng.getrandbits(64) | (1 << 40)))
    mixed = sorted(frames + attack, key=lambda m: m.timestamp)
    out = svc.feed_all(mixed)
    claims_out = [m for m in out if pgn_of(m.arbitration_id) == PGN_ADDRESS_CLAIMED]
    assert len(claims_out) <= len([m for m in attack if source_address(m.arbitration_id) == SA]) + 1
    assert svc.netmgmt.address in (SA, None)
    if svc.netmgmt.address is None:  # lost to a lower NAME: silent from then on
        assert svc.counters["steps"] > 0


@pytest.mark.parametrize(
    "key, value", [("name_identity_number", -1), ("arbitrary_address_capable", 1), ("name_function", True)]
)
def test_bad_name_fields_in_the_config_are_refused(key, value):
    from firmware_model.errors import ParameterError

    class Cfg:
        can = {key: value}

    with pytest.raises(ParameterError, match=key):
        ServiceOptions.from_config(Cfg())
