"""The project DBC, ``gearbox_vsensor.dbc``: loaded once, and what the decoder and encoders read from it.

Every PGN, default source address, priority, byte position, scaling and choice table of the frames the sensor reads
or sends comes from the DBC through this module. Per-component signals (GBX_TEMP_*, GBX_WARN, GBX_TTL_*, RIG_TC_*)
name their component in the ``ComponentId`` signal attribute (``LI.teeth`` for ``T_LI_teeth``), so the DBC alone
says which component a signal carries; :func:`published_components` is their order (GBX_TEMP_1..7).
"""

from __future__ import annotations

import functools
import importlib.resources
from typing import NamedTuple

import cantools

from can_dbc.errors import DecodeError
from can_dbc.j1939 import pgn_of, source_address, with_source

DBC_NAME = "gearbox_vsensor.dbc"
#: signal attribute naming the published component a per-component signal carries
COMPONENT_ATTRIBUTE = "ComponentId"
#: choice name of the J1939 "not available" value in the DBC's value tables
NOT_AVAILABLE = "not available"


class SignalLayout(NamedTuple):
    """Where an unsigned little-endian signal sits in the 64-bit payload and how it scales (physical = raw x scale +
    offset)."""

    start_bit: int
    scale: float
    offset: float


class ComponentSignal(NamedTuple):
    """A per-component signal: the component id (``ComponentId``), the DBC signal name and its layout."""

    component: str
    signal_name: str
    layout: SignalLayout


@functools.cache
def load_database() -> cantools.database.can.Database:
    """The project DBC, loaded strictly once from the package data. Shared: do not modify it."""
    text = importlib.resources.files(__package__).joinpath(DBC_NAME).read_text(encoding="utf-8")
    return cantools.database.load_string(text, database_format="dbc", strict=True)


def message(name: str):
    """The DBC message ``name`` (a cantools ``Message``)."""
    return load_database().get_message_by_name(name)


@functools.cache
def message_pgn(name: str) -> int:
    """PGN of the DBC message ``name``."""
    return pgn_of(message(name).frame_id)


def default_source(name: str) -> int:
    """The source address the DBC gives message ``name`` (the last byte of its frame id)."""
    return source_address(message(name).frame_id)


def message_id(name: str, source: int) -> int:
    """Frame id of message ``name`` (the DBC's priority and PGN) sent by ``source``."""
    return with_source(message(name).frame_id, source)


def numbered_messages(prefix: str) -> tuple[str, ...]:
    """Names of the messages ``<prefix>1``, ``<prefix>2`` ... in the DBC, in number order."""
    names = [m.name for m in load_database().messages if m.name.startswith(prefix) and m.name[len(prefix) :].isdigit()]
    return tuple(sorted(names, key=lambda n: int(n[len(prefix) :])))


def signal_layout(message_name: str, signal_name: str, length: int) -> SignalLayout:
    """Layout of a signal; checks that it is little-endian unsigned of ``length`` bits."""
    signal = message(message_name).get_signal_by_name(signal_name)
    return _checked_layout(message_name, signal, length)


def _checked_layout(message_name: str, signal, length: int) -> SignalLayout:
    if signal.byte_order != "little_endian" or signal.is_signed or signal.length != length:
        raise DecodeError(f"DBC signal {message_name}.{signal.name} must be little-endian unsigned {length}-bit")
    return SignalLayout(signal.start, float(signal.scale), float(signal.offset))


def fill_mask(message_name: str) -> int:
    """Bits no signal of the message covers; J1939 sends them as 1."""
    used = 0
    for signal in message(message_name).signals:
        used |= ((1 << signal.length) - 1) << signal.start
    return ~used & 0xFFFF_FFFF_FFFF_FFFF


def component_of(signal) -> str | None:
    """The ``ComponentId`` of a cantools signal, None for a signal that carries no component."""
    attributes = signal.dbc.attributes if signal.dbc is not None else {}
    attribute = attributes.get(COMPONENT_ATTRIBUTE)
    return None if attribute is None or not attribute.value else str(attribute.value)


def component_signals(message_name: str, length: int) -> tuple[ComponentSignal, ...]:
    """The per-component signals of a message in payload order, each checked to be ``length``-bit unsigned LE."""
    out = []
    for signal in sorted(message(message_name).signals, key=lambda s: s.start):
        component = component_of(signal)
        if component is not None:
            out.append(ComponentSignal(component, signal.name, _checked_layout(message_name, signal, length)))
    return tuple(out)


@functools.cache
def published_components() -> tuple[str, ...]:
    """The component ids of GBX_TEMP_1..7 in signal order: what the sensor publishes, in the order of every
    per-component signal."""
    return tuple(c.component for name in numbered_messages("GBX_TEMP_") for c in component_signals(name, 16))


def choices(message_name: str, signal_name: str) -> dict[int, str]:
    """The value table of a signal: raw value -> name."""
    table = message(message_name).get_signal_by_name(signal_name).choices or {}
    return {int(k): str(v) for k, v in table.items()}


def not_available_raw(message_name: str, signal_name: str) -> int:
    """The raw value the signal's value table names "not available"."""
    for raw, name in choices(message_name, signal_name).items():
        if name == NOT_AVAILABLE:
            return raw
    raise DecodeError(f"DBC signal {message_name}.{signal_name} has no '{NOT_AVAILABLE}' value")


def data_choices(message_name: str, signal_name: str) -> dict[int, str]:
    """The value table without its "not available" entry."""
    return {raw: name for raw, name in choices(message_name, signal_name).items() if name != NOT_AVAILABLE}
