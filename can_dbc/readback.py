"""Reading the sensor's own frames back through cantools: the inverse of the encoders, an independent check of
them, for tests and tools (``decode_outputs``, ``decode_rig``)."""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

import can
import cantools
from cantools.database.namedsignalvalue import NamedSignalValue

from can_dbc import dbc
from can_dbc.encoder import STATUS_FLAG_SIGNALS, TTL_NEVER
from can_dbc.errors import DecodeError
from can_dbc.j1939 import pgn_of, source_key


def _messages_by_pgn(prefixes: tuple[str, ...], db: dbc.CanDatabase) -> dict[int, object]:
    return {pgn_of(m.frame_id): m for m in db.database.messages if m.name.startswith(prefixes)}


def _temperature(value: object) -> float | None:
    return None if isinstance(value, NamedSignalValue) else float(value)


def _decoded(msgs: Iterable[can.Message], prefixes: tuple[str, ...], source_address: int | None, db: dbc.CanDatabase):
    """``(message, values)`` of every data frame of a PGN of the messages named ``prefixes*`` (from
    ``source_address`` only, if given), decoded with their value tables; DecodeError if cantools cannot."""
    messages = _messages_by_pgn(prefixes, db)
    for msg in msgs:
        if not msg.is_extended_id or msg.is_error_frame or msg.is_remote_frame:
            continue
        message = messages.get(pgn_of(msg.arbitration_id))
        if message is None or (source_address is not None and source_key(msg.arbitration_id) != source_address):
            continue
        try:
            values = message.decode(bytes(msg.data), decode_choices=True)
        except (cantools.database.DecodeError, ValueError) as exc:
            raise DecodeError(f"frame {msg.arbitration_id:#x} ({message.name}) cannot be decoded: {exc}") from None
        yield message, values


def _by_component(message, values) -> dict[str, object]:
    """The decoded per-component signals of a message: component id -> value."""
    return {c: values[s.name] for s in message.signals if (c := dbc.component_of(s)) is not None and s.name in values}


def _ttl(value: object) -> float | None:
    if isinstance(value, NamedSignalValue):
        return math.inf if value.name == TTL_NEVER else None
    return float(value)


def _status(values, db: dbc.CanDatabase) -> dict:
    modes = db.data_choices("GBX_STATUS", "DegradedMode")
    status = {key: {0: False, 1: True}.get(values[sig].value) for key, sig in STATUS_FLAG_SIGNALS}
    mode = values["DegradedMode"]
    status["degraded_mode"] = mode.value if mode.value in modes else None
    status["max_warning_level"] = values["MaxWarnLevel"].value
    status["oil_innovation_c"] = _temperature(values["OilInnovation"])
    status["model_oil_temp_c"] = _temperature(values["ModelOilTemp"])
    status["counter"] = int(values["RollingCounter"])
    return status


def _dm1(values, component_of_spn: dict[int, str]) -> dict:
    raw = {k: (v.value if isinstance(v, NamedSignalValue) else int(v)) for k, v in values.items()}
    spn = raw["DTC1_SPN_Low"] + (raw["DTC1_SPN_High"] << 16)
    dtc = None
    if spn:
        dtc = {
            "spn": spn,
            "fmi": raw["DTC1_FMI"],
            "occurrence_count": raw["DTC1_OccurrenceCount"],
            "component": component_of_spn.get(spn),
        }
    return {
        "amber_warning_lamp": raw["AmberWarningLampStatus"],
        "red_stop_lamp": raw["RedStopLampStatus"],
        "protect_lamp": raw["ProtectLampStatus"],
        "malfunction_lamp": raw["MalfunctionIndLampStatus"],
        "dtc": dtc,
    }


def decode_outputs(
    msgs: Iterable[can.Message],
    source_address: int | None = None,
    database: dbc.CanDatabase | str | Path | None = None,
) -> dict:
    """Decode GBX_* frames (matched by PGN; from ``source_address`` only, if given) with cantools and the gearbox's
    DBC ``database`` (:func:`can_dbc.dbc.load_dbc`; None the shipped GRS905 DBC).

    Returns the keys present among ``temps_c`` (component -> degC or None), ``levels`` (component -> 0..3),
    ``ttl_s`` (component -> s, math.inf never, None not available), ``status`` (the keys of
    ``can_dbc.encoder.STATUS_KEYS``, None where not available) and ``dm1`` (lamps and the DTC; its component is the
    one whose GBX_TEMP signal has the DTC's SPN). The last frame of a kind wins. Raises DecodeError for a frame of a
    GBX PGN that cantools cannot decode.
    """
    db = dbc.load_dbc(database)
    component_of_spn = {
        s.spn: dbc.component_of(s) for name in db.numbered_messages("GBX_TEMP_") for s in db.message(name).signals
    }
    result: dict = {}
    for message, values in _decoded(msgs, ("GBX_",), source_address, db):
        name = message.name
        if name.startswith("GBX_TEMP_"):
            result.setdefault("temps_c", {}).update(
                {c: _temperature(v) for c, v in _by_component(message, values).items()}
            )
        elif name == "GBX_WARN" or name.startswith("GBX_WARN_"):
            result.setdefault("levels", {}).update({c: int(v.value) for c, v in _by_component(message, values).items()})
        elif name.startswith("GBX_TTL_"):
            result.setdefault("ttl_s", {}).update({c: _ttl(v) for c, v in _by_component(message, values).items()})
        elif name == "GBX_STATUS":
            result["status"] = _status(values, db)
        elif name == "GBX_DM1":
            result["dm1"] = _dm1(values, component_of_spn)
    return result


def decode_rig(
    msgs: Iterable[can.Message],
    source_address: int | None = None,
    database: dbc.CanDatabase | str | Path | None = None,
) -> dict[str, float | None]:
    """Decode RIG_TC_* frames (matched by PGN; from ``source_address`` only, if given) with the gearbox's DBC
    ``database`` (None: the shipped one): component -> degC or None."""
    result: dict[str, float | None] = {}
    for message, values in _decoded(msgs, ("RIG_TC_",), source_address, dbc.load_dbc(database)):
        result.update({c: _temperature(v) for c, v in _by_component(message, values).items()})
    return result
