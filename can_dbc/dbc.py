"""The project DBC, ``gearbox_vsensor.dbc``: loaded once, and what the decoder and encoders read from it; another
gearbox's DBC (``gearbox-vsensor export-dbc``, can_dbc.generate) through :func:`load_dbc` as a :class:`CanDatabase`,
whose methods are the module functions below (these read the shipped DBC).

Every PGN, default source address, priority, byte position, scaling and choice table of the frames the sensor reads
or sends comes from the DBC through this module. Per-component signals (GBX_TEMP_*, GBX_WARN, GBX_TTL_*, RIG_TC_*)
name their component in the ``ComponentId`` signal attribute (``LI.teeth`` for ``T_LI_teeth``), so the DBC alone
says which component a signal carries; :func:`published_components` is their order (GBX_TEMP_1..k).
"""

from __future__ import annotations

import functools
import importlib.resources
from pathlib import Path
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


class CanDatabase:
    """A DBC of the sensor's frames (the shipped one or one ``gearbox-vsensor export-dbc`` generated for another
    gearbox) and what the decoder and encoders read from it. Shared: do not modify ``database``."""

    def __init__(self, database: cantools.database.can.Database) -> None:
        self.database = database
        self._published: tuple[str, ...] | None = None

    def message(self, name: str):
        """The DBC message ``name`` (a cantools ``Message``)."""
        return self.database.get_message_by_name(name)

    def message_pgn(self, name: str) -> int:
        """PGN of the DBC message ``name``."""
        return pgn_of(self.message(name).frame_id)

    def default_source(self, name: str) -> int:
        """The source address the DBC gives message ``name`` (the last byte of its frame id)."""
        return source_address(self.message(name).frame_id)

    def message_id(self, name: str, source: int) -> int:
        """Frame id of message ``name`` (the DBC's priority and PGN) sent by ``source``."""
        return with_source(self.message(name).frame_id, source)

    def numbered_messages(self, prefix: str) -> tuple[str, ...]:
        """Names of the messages ``<prefix>1``, ``<prefix>2`` ... in the DBC, in number order."""
        names = [
            m.name for m in self.database.messages if m.name.startswith(prefix) and m.name[len(prefix) :].isdigit()
        ]
        return tuple(sorted(names, key=lambda n: int(n[len(prefix) :])))

    def warn_messages(self) -> tuple[str, ...]:
        """The warning-level messages: GBX_WARN, or GBX_WARN_1..w for more than 32 published components."""
        names = {m.name for m in self.database.messages}
        return ("GBX_WARN",) if "GBX_WARN" in names else self.numbered_messages("GBX_WARN_")

    def signal_layout(self, message_name: str, signal_name: str, length: int) -> SignalLayout:
        """Layout of a signal; checks that it is little-endian unsigned of ``length`` bits."""
        return checked_layout(message_name, self.message(message_name).get_signal_by_name(signal_name), length)

    def fill_mask(self, message_name: str) -> int:
        """Bits no signal of the message covers; J1939 sends them as 1."""
        used = 0
        for signal in self.message(message_name).signals:
            used |= ((1 << signal.length) - 1) << signal.start
        return ~used & 0xFFFF_FFFF_FFFF_FFFF

    def component_signals(self, message_name: str, length: int) -> tuple[ComponentSignal, ...]:
        """The per-component signals of a message in payload order, each checked to be ``length``-bit unsigned
        LE."""
        out = []
        for signal in sorted(self.message(message_name).signals, key=lambda s: s.start):
            component = component_of(signal)
            if component is not None:
                out.append(ComponentSignal(component, signal.name, checked_layout(message_name, signal, length)))
        return tuple(out)

    def published_components(self) -> tuple[str, ...]:
        """The component ids of GBX_TEMP_1..k in signal order: what the sensor publishes, in the order of every
        per-component signal."""
        if self._published is None:
            self._published = tuple(
                c.component for name in self.numbered_messages("GBX_TEMP_") for c in self.component_signals(name, 16)
            )
        return self._published

    def choices(self, message_name: str, signal_name: str) -> dict[int, str]:
        """The value table of a signal: raw value -> name."""
        table = self.message(message_name).get_signal_by_name(signal_name).choices or {}
        return {int(k): str(v) for k, v in table.items()}

    def not_available_raw(self, message_name: str, signal_name: str) -> int:
        """The raw value the signal's value table names "not available"."""
        for raw, name in self.choices(message_name, signal_name).items():
            if name == NOT_AVAILABLE:
                return raw
        raise DecodeError(f"DBC signal {message_name}.{signal_name} has no '{NOT_AVAILABLE}' value")

    def data_choices(self, message_name: str, signal_name: str) -> dict[int, str]:
        """The value table without its "not available" entry."""
        return {raw: n for raw, n in self.choices(message_name, signal_name).items() if n != NOT_AVAILABLE}


@functools.cache
def shipped() -> CanDatabase:
    """The shipped DBC (the GRS905's), loaded once."""
    return CanDatabase(load_database())


def load_dbc(source: CanDatabase | str | Path | None = None) -> CanDatabase:
    """A DBC of the sensor's frames: None the shipped one; a :class:`CanDatabase` as it is; a ``Path``, or a string
    without a line break, the path of a .dbc file; any other string the DBC's text. Loaded strictly; DecodeError
    naming the file when cantools cannot read it."""
    if source is None:
        return shipped()
    if isinstance(source, CanDatabase):
        return source
    is_text = isinstance(source, str) and "\n" in source
    what = "the DBC text" if is_text else f"DBC file {source}"
    try:
        if is_text:
            database = cantools.database.load_string(source, database_format="dbc", strict=True)
        else:
            database = cantools.database.load_file(str(source), database_format="dbc", strict=True, encoding="utf-8")
    except OSError as exc:
        raise DecodeError(f"{what} cannot be read: {exc.strerror or exc}") from None
    except Exception as exc:  # cantools raises parse, strictness and value errors of several types
        raise DecodeError(
            f"{what} is no valid DBC: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}"
        ) from None
    return CanDatabase(database)


@functools.lru_cache(maxsize=8)
def for_components(components: tuple) -> CanDatabase:
    """The DBC of a gearbox whose published components are ``components`` (ids in CAN order): the shipped one when
    they are the GRS905's, else the one can_dbc.generate lays out for them (as `gearbox-vsensor export-dbc` writes
    it; the signal comments name the ids only). GenerateError when they cannot be laid out."""
    from can_dbc.generate import generate_dbc

    if tuple(components) == tuple(shipped().published_components()):
        return shipped()
    return load_dbc(generate_dbc(list(components)))


def message(name: str):
    """The shipped DBC's message ``name`` (a cantools ``Message``)."""
    return shipped().message(name)


@functools.cache
def message_pgn(name: str) -> int:
    """PGN of the shipped DBC's message ``name``."""
    return shipped().message_pgn(name)


def default_source(name: str) -> int:
    """The source address the shipped DBC gives message ``name`` (the last byte of its frame id)."""
    return shipped().default_source(name)


def message_id(name: str, source: int) -> int:
    """Frame id of the shipped DBC's message ``name`` (its priority and PGN) sent by ``source``."""
    return shipped().message_id(name, source)


def numbered_messages(prefix: str) -> tuple[str, ...]:
    """Names of the shipped DBC's messages ``<prefix>1``, ``<prefix>2`` ..., in number order."""
    return shipped().numbered_messages(prefix)


def signal_layout(message_name: str, signal_name: str, length: int) -> SignalLayout:
    """Layout of a signal of the shipped DBC; checks that it is little-endian unsigned of ``length`` bits."""
    return shipped().signal_layout(message_name, signal_name, length)


def checked_layout(message_name: str, signal, length: int) -> SignalLayout:
    """The layout of a cantools signal; DecodeError unless it is little-endian unsigned of ``length`` bits."""
    if signal.byte_order != "little_endian" or signal.is_signed or signal.length != length:
        raise DecodeError(f"DBC signal {message_name}.{signal.name} must be little-endian unsigned {length}-bit")
    return SignalLayout(signal.start, float(signal.scale), float(signal.offset))


def fill_mask(message_name: str) -> int:
    """Bits no signal of the shipped DBC's message covers; J1939 sends them as 1."""
    return shipped().fill_mask(message_name)


def component_of(signal) -> str | None:
    """The ``ComponentId`` of a cantools signal, None for a signal that carries no component."""
    attributes = signal.dbc.attributes if signal.dbc is not None else {}
    attribute = attributes.get(COMPONENT_ATTRIBUTE)
    return None if attribute is None or not attribute.value else str(attribute.value)


def component_signals(message_name: str, length: int) -> tuple[ComponentSignal, ...]:
    """The per-component signals of a message of the shipped DBC (:meth:`CanDatabase.component_signals`)."""
    return shipped().component_signals(message_name, length)


def published_components() -> tuple[str, ...]:
    """The component ids the shipped DBC publishes, in the order of every per-component signal."""
    return shipped().published_components()


def choices(message_name: str, signal_name: str) -> dict[int, str]:
    """The value table of a signal of the shipped DBC: raw value -> name."""
    return shipped().choices(message_name, signal_name)


def not_available_raw(message_name: str, signal_name: str) -> int:
    """The raw value the shipped DBC's value table of the signal names "not available"."""
    return shipped().not_available_raw(message_name, signal_name)


def data_choices(message_name: str, signal_name: str) -> dict[int, str]:
    """The value table of a signal of the shipped DBC without its "not available" entry."""
    return shipped().data_choices(message_name, signal_name)
