"""Settings of the CAN service (:class:`ServiceOptions`, the config's ``[can]`` section) and the wiring between the
J1939 decoder's signals, the sensor's inputs and the run table: which message each input comes from, how long a
value stays fresh, which PGNs the service listens to."""

from __future__ import annotations

import functools
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field

from can_dbc.dbc import default_source, message_pgn, numbered_messages
from can_dbc.decoder import input_messages
from can_dbc.j1939 import receive_filter
from firmware_model.components import STEP_S
from firmware_model.errors import ParameterError
from firmware_model.service.netmgmt import PGN_ADDRESS_CLAIMED, PGN_REQUEST, J1939Name
from firmware_model.service.records import INPUT_SIGNALS, SENSOR_INPUTS, StepInputs  # noqa: F401 (re-exported)

#: nominal transmission period of each input message [s], the service's staleness clock: J1939-71 defaults (EEC1 is
#: engine-speed dependent, 10-20 ms: its upper bound), except CCVS1 taken as 1 s (synthesized logs and some trucks
#: send it every second; the DBC's cycle time is J1939's 100 ms); RIG = the rig thermocouple frames
NOMINAL_PERIOD_S = {
    "EEC1": 0.02,
    "ETC2": 0.1,
    "TRF1": 1.0,
    "ET1": 1.0,
    "AMB": 1.0,
    "CCVS1": 1.0,
    "ERC1": 0.1,
    "RIG": 0.1,
}
#: run-table columns of the decoded inputs (StepInputs order) and the two extra decoded columns
INPUT_COLUMNS = (*INPUT_SIGNALS, "engine_torque_pct", "engine_ref_torque_nm")
#: the time-base check (``firmware_model.service.trust``): windows of this much frame time, this many in a row
TIME_BASE_WINDOW_S = 10.0
TIME_BASE_WINDOWS = 3
#: the model's gear range (seed Table 1); other J1939 gear numbers (after gear_map) are not available to the sensor
GEAR_RANGE = (-2, 14)
#: config [can] source-address keys -> the messages they set; a later key overrides an earlier one for its messages
#: (CCVS1 comes from the tachograph on many trucks, AMB from the body controller: their own keys)
SOURCE_ADDRESS_KEYS = (
    ("engine_source_address", ("EEC1", "EC1", "ET1", "CCVS1", "AMB")),
    ("transmission_source_address", ("ETC2", "TRF1")),
    ("retarder_source_address", ("ERC1", "RC")),
    ("ambient_source_address", ("AMB",)),
    ("vehicle_speed_source_address", ("CCVS1",)),
    ("coolant_source_address", ("ET1",)),
)
#: config ``[can.source_address]``: message name -> its source address alone, over every key above (a Navistar truck
#: sends ETC2 from 0x03 and TRF1 from 0x21: ``ETC2 = 0x03``, ``TRF1 = 0x21``)
SOURCE_ADDRESS_TABLE = "source_address"
SOURCE_ADDRESS_MESSAGES = ("EEC1", "EC1", "ETC2", "TRF1", "ET1", "AMB", "CCVS1", "ERC1", "RC")


def _check_address(key: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 253:
        shown = (
            f"{value} (0x{value:X})"
            if isinstance(value, int) and not isinstance(value, bool) and value >= 0
            else repr(value)
        )
        quoted = ""
        if isinstance(value, str) and re.fullmatch(r"\s*(0[xX][0-9a-fA-F]+|\d+)\s*", value):
            quoted = f": write it without quotes, {key} = {value.strip()}"
        raise ParameterError(f"can.{key} = {shown} is not a J1939 source address 0..253 (0x00..0xFD){quoted}")
    return value


def source_addresses(can: Mapping) -> tuple[dict[str, int], dict[str, str]]:
    """The source addresses a config's ``[can]`` section sets: (message -> address, message -> the key that set it,
    e.g. ``transmission_source_address`` or ``source_address.TRF1``). The group keys apply in SOURCE_ADDRESS_KEYS
    order (a later, narrower key wins for its messages), then the ``[can.source_address]`` table per message.
    ParameterError naming the key for an address outside 0..253 or a message the table does not know."""
    sa: dict[str, int] = {}
    keys: dict[str, str] = {}
    for key, names in SOURCE_ADDRESS_KEYS:
        if key in can:
            value = _check_address(key, can[key])
            for n in names:
                sa[n], keys[n] = value, key
    table = can.get(SOURCE_ADDRESS_TABLE, {})
    if not isinstance(table, Mapping):
        raise ParameterError(
            f"can.{SOURCE_ADDRESS_TABLE} = {table!r} must be a table of message = address, e.g. "
            f"[can.{SOURCE_ADDRESS_TABLE}] TRF1 = 0x21"
        )
    for name, value in table.items():
        if name not in SOURCE_ADDRESS_MESSAGES:
            raise ParameterError(
                f"can.{SOURCE_ADDRESS_TABLE}.{name}: unknown message {name!r}; known: "
                f"{', '.join(SOURCE_ADDRESS_MESSAGES)} "
                f"(e.g. [can.{SOURCE_ADDRESS_TABLE}] TRF1 = 0x21)"
            )
        sa[name] = _check_address(f"{SOURCE_ADDRESS_TABLE}.{name}", value)
        keys[name] = f"{SOURCE_ADDRESS_TABLE}.{name}"
    return sa, keys


@functools.cache
def wanted_pgns() -> dict[str, int]:
    """Message name -> PGN of every message the service listens to (the input messages, TP.CM and TP.DT), from the
    DBC; PDU1 PGNs (TP.CM, TP.DT) without their destination byte."""
    return {**{m.name: m.pgn for m in input_messages()}, "TP_CM": message_pgn("TP_CM"), "TP_DT": message_pgn("TP_DT")}


@functools.cache
def rig_pgns() -> tuple[int, ...]:
    """PGNs of the rig thermocouple frames RIG_TC_1..7, from the DBC."""
    return tuple(message_pgn(name) for name in numbered_messages("RIG_TC_"))


def can_filters(rig: bool = False, network: bool = True) -> list[dict]:
    """python-can receive filters for the wanted PGNs: the mask covers the PGN bits only (no priority, no source
    address; for PDU1 PGNs no destination either); ``rig`` adds the rig thermocouple PGNs, ``network`` the J1939
    network management (Request, Address Claimed)."""
    extra = (PGN_REQUEST, PGN_ADDRESS_CLAIMED) if network else ()
    return [receive_filter(pgn) for pgn in (*wanted_pgns().values(), *(rig_pgns() if rig else ()), *extra)]


#: config [can] keys of the sensor's J1939 NAME -> J1939Name fields
NAME_KEYS = {
    "name_identity_number": "identity_number",
    "name_manufacturer_code": "manufacturer_code",
    "name_ecu_instance": "ecu_instance",
    "name_function_instance": "function_instance",
    "name_function": "function",
    "name_vehicle_system": "vehicle_system",
    "name_vehicle_system_instance": "vehicle_system_instance",
    "name_industry_group": "industry_group",
    "arbitrary_address_capable": "arbitrary_address_capable",
}
#: the bits of each NAME field (J1939-81): a larger value would be cut to its low bits on the bus
NAME_BITS = {
    "name_identity_number": 21,
    "name_manufacturer_code": 11,
    "name_ecu_instance": 3,
    "name_function_instance": 5,
    "name_function": 8,
    "name_vehicle_system": 7,
    "name_vehicle_system_instance": 4,
    "name_industry_group": 3,
}
#: can.stale_factor at most this many nominal periods (a larger factor never declares an input stale)
STALE_FACTOR_MAX = 20.0


def _positive(name: str, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
        raise ParameterError(f"can.{name} = {value!r} must be a positive finite number")


@dataclass(frozen=True)
class ServiceOptions:
    """Service settings; :meth:`from_config` reads the config's ``[can]`` section. ``sensor_source_address``
    defaults to the DBC's (0xE5). ``time_base_window_s``/``time_base_windows``: the time-base check
    (``firmware_model.service.trust``); ``log_findings`` False: the trust findings are not logged while running
    (an offline replay prints them once at the end)."""

    expected_sa: Mapping[str, int | None] = field(default_factory=dict)
    #: message -> the [can] key that set its ``expected_sa`` (``transmission_source_address``,
    #: ``source_address.TRF1``): the key a foreign-source finding names
    source_address_keys: Mapping[str, str] = field(default_factory=dict)
    sensor_source_address: int = field(default_factory=lambda: default_source("GBX_STATUS"))
    configured_ref_torque_nm: float | None = None
    retarder_ref_torque_nm: float | None = None
    gear_map: Mapping[int, int] | None = None
    stale_factor: float = 3.0
    output_period_s: float = STEP_S
    counter_log_period_s: float = 60.0
    max_catchup_steps: int = 50
    backward_tolerance_s: float = 1.0
    init_wait_s: float = 3.0
    no_ref_torque_warning_s: float = 10.0
    rig: bool = True
    time_base_window_s: float = TIME_BASE_WINDOW_S
    time_base_windows: int = TIME_BASE_WINDOWS
    log_findings: bool = True
    #: J1939-81 address claim and J1939-21 requests (a live node on a bus; offline replays send nothing)
    address_claim: bool = False
    j1939_name: J1939Name = field(default_factory=J1939Name)

    def __post_init__(self) -> None:
        _positive("stale_factor", self.stale_factor)
        _positive("counter_log_period_s", self.counter_log_period_s)
        _positive("backward_tolerance_s", self.backward_tolerance_s)
        _positive("time_base_window_s", self.time_base_window_s)
        if not (isinstance(self.time_base_windows, int) and self.time_base_windows >= 1):
            raise ParameterError(f"time_base_windows = {self.time_base_windows!r} must be an integer >= 1")
        if not 1.0 <= self.stale_factor <= STALE_FACTOR_MAX:
            raise ParameterError(
                f"can.stale_factor = {self.stale_factor!r} must be in 1..{STALE_FACTOR_MAX:g} (a "
                f"multiple of the nominal period)"
            )
        _positive("output_period_s", self.output_period_s)
        ratio = self.output_period_s / STEP_S
        if not (abs(ratio - round(ratio)) < 1e-9 and round(ratio) >= 1):
            raise ParameterError(
                f"can.output_period_s = {self.output_period_s!r} must be a whole multiple of the sensor step {STEP_S} s"
            )
        if not (isinstance(self.max_catchup_steps, int) and self.max_catchup_steps >= 1):
            raise ParameterError(f"max_catchup_steps = {self.max_catchup_steps!r} must be an integer >= 1")
        if not 0.0 <= self.init_wait_s <= 60.0:
            raise ParameterError(f"init_wait_s = {self.init_wait_s!r} must be in 0..60 s")

    @property
    def output_every_steps(self) -> int:
        """Steps per sent set of periodic frames."""
        return int(round(self.output_period_s / STEP_S))

    @classmethod
    def from_config(cls, config=None, **overrides) -> ServiceOptions:
        """Options from a config's ``[can]`` section (None: defaults); ``overrides``: fields set directly."""
        c = dict(getattr(config, "can", None) or {})
        _check_can_keys(c)
        sa, sa_keys = source_addresses(c)
        kw: dict = {"expected_sa": sa, "source_address_keys": sa_keys}
        for key, name in (
            ("sensor_source_address", "sensor_source_address"),
            ("engine_reference_torque_nm", "configured_ref_torque_nm"),
            ("retarder_reference_torque_nm", "retarder_ref_torque_nm"),
            ("stale_factor", "stale_factor"),
            ("output_period_s", "output_period_s"),
            ("counter_log_period_s", "counter_log_period_s"),
        ):
            if key in c:
                kw[name] = c[key]
        if "gear_map" in c:
            kw["gear_map"] = parse_gear_map(c["gear_map"])
        name = {}
        for key, field_ in NAME_KEYS.items():
            if key not in c:
                continue
            v, flag = c[key], key == "arbitrary_address_capable"
            if isinstance(v, bool) != flag or (not flag and (not isinstance(v, int) or v < 0)):
                raise ParameterError(f"can.{key} = {v!r} must be {'true or false' if flag else 'an integer >= 0'}")
            if not flag and v >= 1 << NAME_BITS[key]:
                raise ParameterError(
                    f"can.{key} = {v!r} does not fit the NAME's {NAME_BITS[key]} bits (0..{(1 << NAME_BITS[key]) - 1})"
                )
            name[field_] = v
        if name:
            kw["j1939_name"] = J1939Name(**name)
        kw.update(overrides)
        return cls(**kw)


def _check_can_keys(c: dict) -> None:
    """ParameterError naming the [can] key (not the field it feeds) for a source address outside 0..253 or a
    reference torque that is not a positive number of Nm."""
    for key in [k for k, _ in SOURCE_ADDRESS_KEYS] + ["sensor_source_address"]:
        if key in c:
            _check_address(key, c[key])
    for key in ("engine_reference_torque_nm", "retarder_reference_torque_nm"):
        v = c.get(key)
        if key in c and (isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < 1e5):
            raise ParameterError(f"can.{key} = {v!r} must be a positive number of Nm")


def parse_gear_map(raw) -> dict[int, int]:
    """``gear_map = {"1" = 3, "2" = 4}`` (TOML keys are strings): J1939 gear number -> seed Table 1 gear."""
    if not isinstance(raw, Mapping):
        raise ParameterError(f"can.gear_map = {raw!r} must be a table of J1939 gear -> seed gear")
    out = {}
    for k, v in raw.items():
        try:
            j = int(k)
        except (TypeError, ValueError):
            raise ParameterError(f"can.gear_map key {k!r} is not an integer J1939 gear number") from None
        if isinstance(v, bool) or not isinstance(v, int) or not GEAR_RANGE[0] <= v <= GEAR_RANGE[1]:
            raise ParameterError(
                f"can.gear_map[{k!r}] = {v!r} is not a seed Table 1 gear {GEAR_RANGE[0]}..{GEAR_RANGE[1]}"
            )
        out[j] = v
    return out
