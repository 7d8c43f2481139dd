"""The sensor's own frames out: :class:`OutputEncoder` (GBX_TEMP_*, GBX_WARN, GBX_TTL_*, GBX_STATUS, GBX_DM1) and
:class:`RigEncoder` (RIG_TC_*).

Layouts, scalings, value tables, priorities, PGNs and default source addresses are read once from the DBC at
construction; :meth:`OutputEncoder.encode` then only packs integers (``test_fast_encoder_matches_cantools_encode``
checks it bit for bit against cantools). Written here: the J1939 rules for values that are not data (not
available, clamping to the data range) and the J1939-73 DM1 policy (one DTC, lamps, occurrence count).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import NamedTuple

import can

from can_dbc import dbc
from can_dbc.errors import DecodeError, EncodeError
from can_dbc.j1939 import RAW16_DATA_MAX, RAW16_NOT_AVAILABLE, check_source_address

#: GBX_STATUS input keys; a missing key is sent as "not available" (max_warning_level: computed from levels,
#: counter: the encoder's own rolling counter)
STATUS_KEYS = (
    "speed_valid",
    "torque_valid",
    "gear_valid",
    "oil_valid",
    "ref_torque_valid",
    "degraded_mode",
    "oil_innovation_c",
    "model_oil_temp_c",
    "max_warning_level",
    "counter",
    "time_base_suspect",
)
_STATUS_KEY_SET = frozenset(STATUS_KEYS)
#: status key -> its two-bit GBX_STATUS signal
STATUS_FLAG_SIGNALS = (
    ("speed_valid", "SpeedValid"),
    ("torque_valid", "TorqueValid"),
    ("gear_valid", "GearValid"),
    ("oil_valid", "OilValid"),
    ("ref_torque_valid", "RefTorqueValid"),
    ("time_base_suspect", "TimeBaseSuspect"),
)
#: warning level "not available" (two-bit J1939 state)
LEVEL_NOT_AVAILABLE = 3
#: DM1 (J1939-73): FMI per warning level (16 above normal, moderately severe; 0 above normal, most severe), the
#: largest occurrence count
DM1_FMI = {1: 16, 2: 0}
#: the DM1 DTC while the sensor cannot evaluate because a drive input is missing: FMI 9 (abnormal update rate) on
#: the missing input's SPN, amber lamp (the gearbox is not monitored; interfaces.md 2.4)
DM1_FMI_MISSING = 9
#: FMI of an input whose whole record is implausible (a unit or sign mistake, clamps on many steps): 2, "data erratic,
#: intermittent or incorrect" (J1939-73); shown when no component DTC and no missing input is active
DM1_FMI_IMPLAUSIBLE = 2
DM1_OCCURRENCE_MAX = 126
#: the sensor's time-to-limit value table name for "never reached within the horizon"
TTL_NEVER = "never"


def _as_float(value: object, field: str, what: str) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise EncodeError(f"{field} = {value!r} is not {what}") from None


def _raw16(value: object, scale: float, offset: float, field: str) -> int:
    """16-bit J1939 raw value; None, NaN and +-inf -> 0xFFFF (no valid value); else rounded, clamped to data."""
    if value is None:
        return RAW16_NOT_AVAILABLE
    x = _as_float(value, field, "a number or None")
    if not math.isfinite(x):
        return RAW16_NOT_AVAILABLE
    raw = round((x - offset) / scale)
    return 0 if raw < 0 else RAW16_DATA_MAX if raw > RAW16_DATA_MAX else raw


def _raw_ttl(value: object, never_raw: int, field: str) -> int:
    """Time to limit: None/NaN not available, +inf never, else whole seconds clamped to 0..never_raw - 1."""
    if value is None:
        return RAW16_NOT_AVAILABLE
    x = _as_float(value, field, "a number of seconds, math.inf or None")
    if x != x:
        return RAW16_NOT_AVAILABLE
    if x == math.inf:
        return never_raw
    raw = round(x) if x > -1.0 else 0
    return 0 if raw < 0 else never_raw - 1 if raw > never_raw - 1 else raw


def _level(value: object, field: str) -> int:
    if value is None:
        return LEVEL_NOT_AVAILABLE
    if isinstance(value, bool) or value not in (0, 1, 2, 3):
        raise EncodeError(f"{field} = {value!r} is not a warning level 0, 1, 2, 3 or None")
    return int(value)


def _flag(value: object, field: str) -> int:
    if value is None:
        return 3
    if value is True or value is False or value in (0, 1):
        return 1 if value else 0
    raise EncodeError(f"{field} = {value!r} is not True, False or None")


def _frame(can_id: int, payload: int, timestamp_s: float) -> can.Message:
    return can.Message(
        timestamp=timestamp_s,
        arbitration_id=can_id,
        is_extended_id=True,
        data=payload.to_bytes(8, "little"),
        check=False,
    )


class ComponentFrame(NamedTuple):
    """A per-component message ready for packing: its frame id, the bits no signal covers and its signals."""

    can_id: int
    fill_mask: int
    signals: tuple[dbc.ComponentSignal, ...]


def component_frame(name: str, source_address: int, length: int, db: dbc.CanDatabase | None = None) -> ComponentFrame:
    """Message ``name`` of ``db`` (None: the shipped DBC) sent by ``source_address``, with its ``length``-bit
    per-component signals."""
    db = db or dbc.shipped()
    return ComponentFrame(db.message_id(name, source_address), db.fill_mask(name), db.component_signals(name, length))


def component_frames(
    prefix: str, source_address: int, length: int = 16, db: dbc.CanDatabase | None = None
) -> tuple[ComponentFrame, ...]:
    """The messages ``<prefix>1..N`` of ``db`` (None: the shipped DBC) sent by ``source_address``, with their
    per-component signals."""
    db = db or dbc.shipped()
    return tuple(component_frame(name, source_address, length, db) for name in db.numbered_messages(prefix))


def _pack_temperatures(
    frames: tuple[ComponentFrame, ...], temps_c: Mapping[str, float | None], timestamp_s: float
) -> list[can.Message]:
    out = []
    for can_id, fill, signals in frames:
        payload = fill
        for component, _, (start, scale, offset) in signals:
            payload |= _raw16(temps_c.get(component), scale, offset, f"temps_c[{component!r}]") << start
        out.append(_frame(can_id, payload, timestamp_s))
    return out


class OutputEncoder:
    """Encodes the sensor's outputs into GBX_TEMP_1..7, GBX_WARN, GBX_TTL_1..7, GBX_STATUS (and GBX_DM1).

    ``source_address``: None = the DBC's (0xE5); ConfigError outside 0..253. ``database``: the DBC of the gearbox
    (:func:`can_dbc.dbc.load_dbc`: a path, the text or a loaded one; None the shipped GRS905 DBC); its frames are the
    ones sent (GBX_TEMP_1..k, GBX_WARN or GBX_WARN_1..w, GBX_TTL_1..k). Attributes: ``components``, the
    component ids in the order of every per-component signal (the DBC's ``ComponentId`` attributes);
    ``degraded_modes``, the DegradedMode value table without "not available"; ``dm1_spns``, the DTC SPN of each
    component.
    """

    def __init__(self, source_address: int | None = None, database: dbc.CanDatabase | str | Path | None = None) -> None:
        self._db = db = dbc.load_dbc(database)
        if source_address is None:
            source_address = db.default_source("GBX_STATUS")
        self.source_address = check_source_address("source_address", source_address)
        self.components = db.published_components()
        self.degraded_modes = db.data_choices("GBX_STATUS", "DegradedMode")
        self._mode_not_available = db.not_available_raw("GBX_STATUS", "DegradedMode")
        self._temp = component_frames("GBX_TEMP_", self.source_address, 16, db)
        self._ttl = component_frames("GBX_TTL_", self.source_address, 16, db)
        for frame in self._ttl:
            if any((c.layout.scale, c.layout.offset) != (1.0, 0.0) for c in frame.signals):
                raise DecodeError("DBC messages GBX_TTL_* must scale 1 s/bit with offset 0")
        first_ttl = self._ttl[0].signals[0].signal_name
        self._ttl_never_raw = next(raw for raw, name in db.choices("GBX_TTL_1", first_ttl).items() if name == TTL_NEVER)
        self._warn = tuple(component_frame(name, self.source_address, 2, db) for name in db.warn_messages())
        self._init_status()
        self._init_dm1()

    def _init_status(self) -> None:
        db = self._db
        self._status_id = db.message_id("GBX_STATUS", self.source_address)
        self._status_fill = db.fill_mask("GBX_STATUS")
        self._status_flags = tuple(
            (key, db.signal_layout("GBX_STATUS", sig, 2).start_bit) for key, sig in STATUS_FLAG_SIGNALS
        )
        self._max_level_start = db.signal_layout("GBX_STATUS", "MaxWarnLevel", 2).start_bit
        self._mode_start = db.signal_layout("GBX_STATUS", "DegradedMode", 4).start_bit
        self._innovation = db.signal_layout("GBX_STATUS", "OilInnovation", 16)
        self._model_oil = db.signal_layout("GBX_STATUS", "ModelOilTemp", 16)
        self._counter_start = db.signal_layout("GBX_STATUS", "RollingCounter", 8).start_bit
        self._counter = 0

    def _init_dm1(self) -> None:
        db = self._db
        self._dm1_id = db.message_id("GBX_DM1", self.source_address)
        self._dm1_fill = db.fill_mask("GBX_DM1") | (0xFF << 8)  # + byte 2: do not flash
        self._dm1 = {
            sig: db.signal_layout("GBX_DM1", sig, length).start_bit
            for sig, length in (
                ("AmberWarningLampStatus", 2),
                ("RedStopLampStatus", 2),
                ("DTC1_SPN_Low", 16),
                ("DTC1_FMI", 5),
                ("DTC1_SPN_High", 3),
                ("DTC1_OccurrenceCount", 7),
            )
        }
        #: the DTC SPN of each component: the SPN the DBC gives its GBX_TEMP signal
        temp_spns = {s.name: s.spn for name in db.numbered_messages("GBX_TEMP_") for s in db.message(name).signals}
        self.dm1_spns = {c.component: temp_spns[c.signal_name] for frame in self._temp for c in frame.signals}
        self._dm1_occurrences: dict[tuple[str, int], int] = {}
        self._dm1_active: set[tuple[str, int]] = set()

    def encode(
        self,
        temps_c: Mapping[str, float | None],
        levels: Mapping[str, int | None],
        ttl_s: Mapping[str, float | None],
        status: Mapping[str, object],
        *,
        timestamp_s: float = 0.0,
    ) -> list[can.Message]:
        """The periodic frames: GBX_TEMP_1..k, GBX_WARN (or GBX_WARN_1..w), GBX_TTL_1..k, GBX_STATUS; 16 for the
        GRS905's 28 components (k = 7).

        ``temps_c``: component -> degC, None/NaN when there is no valid estimate. ``levels``: 0 normal,
        1 warning, 2 critical, 3 or None not available. ``ttl_s``: seconds to the warning limit, ``math.inf``
        never, None not available. A component missing from a dict is sent as not available; components not
        published are ignored. ``status``: keys :data:`STATUS_KEYS` (EncodeError on any other key).
        """
        frames = _pack_temperatures(self._temp, temps_c, timestamp_s)
        max_level = LEVEL_NOT_AVAILABLE
        for can_id, payload, signals in self._warn:
            for component, _, layout in signals:
                level = _level(levels.get(component), f"levels[{component!r}]")
                if level != LEVEL_NOT_AVAILABLE and (max_level == LEVEL_NOT_AVAILABLE or level > max_level):
                    max_level = level
                payload |= level << layout.start_bit
            frames.append(_frame(can_id, payload, timestamp_s))
        never_raw = self._ttl_never_raw
        for can_id, fill, signals in self._ttl:
            payload = fill
            for component, _, layout in signals:
                payload |= _raw_ttl(ttl_s.get(component), never_raw, f"ttl_s[{component!r}]") << layout.start_bit
            frames.append(_frame(can_id, payload, timestamp_s))
        frames.append(_frame(self._status_id, self._status_payload(status, max_level), timestamp_s))
        return frames

    def _status_payload(self, status: Mapping[str, object], max_level: int) -> int:
        unknown = status.keys() - _STATUS_KEY_SET
        if unknown:
            raise EncodeError(f"status has unknown keys {sorted(unknown)}; allowed: {', '.join(STATUS_KEYS)}")
        payload = self._status_fill
        for key, start in self._status_flags:
            payload |= _flag(status.get(key), f"status[{key!r}]") << start
        if status.get("max_warning_level") is not None:
            max_level = _level(status["max_warning_level"], "status['max_warning_level']")
        payload |= max_level << self._max_level_start
        mode = status.get("degraded_mode")
        if mode is None:
            mode = self._mode_not_available
        elif isinstance(mode, bool) or mode not in self.degraded_modes:
            raise EncodeError(f"status['degraded_mode'] = {mode!r} is not one of {self.degraded_modes} or None")
        payload |= int(mode) << self._mode_start
        start, scale, offset = self._innovation
        payload |= _raw16(status.get("oil_innovation_c"), scale, offset, "status['oil_innovation_c']") << start
        start, scale, offset = self._model_oil
        payload |= _raw16(status.get("model_oil_temp_c"), scale, offset, "status['model_oil_temp_c']") << start
        counter = status.get("counter")
        if counter is None:
            counter = self._counter
            self._counter = (self._counter + 1) & 0xFF
        elif isinstance(counter, bool) or not isinstance(counter, int) or not 0 <= counter <= 255:
            raise EncodeError(f"status['counter'] = {counter!r} is not an integer 0..255 or None")
        return payload | (counter << self._counter_start)

    def encode_dm1(
        self,
        levels: Mapping[str, int | None],
        *,
        missing_spn: int | None = None,
        timestamp_s: float = 0.0,
        implausible_spn: int | None = None,
    ) -> can.Message:
        """GBX_DM1 (J1939-73 DM1, single frame) with the most severe active component DTC; send at 1 s and on change.

        DTC: the SPN of the component's GBX_TEMP signal (520192 + published index), FMI 16 (warning) or 0
        (critical); most severe first, then published order. Lamps: amber if any warning, red stop if any critical.
        ``missing_spn``: the SPN of a drive input that is missing while no level can be evaluated: with no
        component DTC active, the DTC is that SPN with FMI 9 (abnormal update rate) and the amber lamp (a sensor that
        lost its inputs is not "no fault": without this, a critical DTC and the red stop lamp would go out when the
        engine speed stops). ``implausible_spn``: the SPN of an input whose whole record is implausible (the
        service's plausibility findings: oil in degF, torque negated, clamps on many steps): with neither a component
        DTC nor a missing input, the DTC is that SPN with FMI 2 (data erratic, intermittent or incorrect) and the
        amber lamp. The occurrence count of an SPN/FMI pair rises by one (max 126) each time it becomes active between
        two calls.
        """
        active: list[tuple[int, int, str, int]] = []  # (level, index, component, fmi): sorted by the first two
        for index, component in enumerate(self.components):
            level = _level(levels.get(component), f"levels[{component!r}]")
            if level in DM1_FMI:
                active.append((level, index, component, DM1_FMI[level]))
        for name, value in (("missing_spn", missing_spn), ("implausible_spn", implausible_spn)):
            if value is not None and not 0 < value < 1 << 19:
                raise EncodeError(f"{name} = {value!r} is not a J1939 SPN 1..524287")
        keys = {(component, fmi) for _, _, component, fmi in active}
        input_dtc = (
            None
            if active
            else (missing_spn, DM1_FMI_MISSING)
            if missing_spn is not None
            else (implausible_spn, DM1_FMI_IMPLAUSIBLE)
            if implausible_spn is not None
            else None
        )
        if input_dtc is not None:
            keys = {input_dtc}
        for key in keys - self._dm1_active:
            self._dm1_occurrences[key] = min(self._dm1_occurrences.get(key, 0) + 1, DM1_OCCURRENCE_MAX)
        self._dm1_active = keys
        amber = int(any(level == 1 for level, _, _, _ in active) or input_dtc is not None)
        red = int(any(level == 2 for level, _, _, _ in active))
        # protect lamp and MIL off, no flashing, bytes 7-8 0xFF (J1939-73); no DTC: SPN 0, FMI 0, OC 0
        at = self._dm1
        payload = self._dm1_fill | (amber << at["AmberWarningLampStatus"]) | (red << at["RedStopLampStatus"])
        spn = None
        if active:
            _, _, component, fmi = min(active, key=lambda a: (-a[0], a[1]))
            spn, count = self.dm1_spns[component], self._dm1_occurrences[(component, fmi)]
        elif input_dtc is not None:
            (spn, fmi), count = input_dtc, self._dm1_occurrences[input_dtc]
        if spn is not None:  # SPN conversion method 4 (CM bit 0): SPN bits 1-16, then bits 17-19 above the FMI
            payload |= (
                ((spn & 0xFFFF) << at["DTC1_SPN_Low"])
                | (fmi << at["DTC1_FMI"])
                | ((spn >> 16) << at["DTC1_SPN_High"])
                | (count << at["DTC1_OccurrenceCount"])
            )
        return _frame(self._dm1_id, payload, timestamp_s)


class RigEncoder:
    """Encodes rig thermocouple temperatures into RIG_TC_1..7 (source address: None = the DBC's, 0xF0; ``database``:
    the gearbox's DBC as for :class:`OutputEncoder`)."""

    def __init__(self, source_address: int | None = None, database: dbc.CanDatabase | str | Path | None = None) -> None:
        db = dbc.load_dbc(database)
        if source_address is None:
            source_address = db.default_source(db.numbered_messages("RIG_TC_")[0])
        self.source_address = check_source_address("source_address", source_address)
        self._frames = component_frames("RIG_TC_", self.source_address, 16, db)

    def encode(self, temps_c: Mapping[str, float | None], *, timestamp_s: float = 0.0) -> list[can.Message]:
        """Seven frames; a component missing, None or NaN is sent as not available."""
        return _pack_temperatures(self._frames, temps_c, timestamp_s)


def encode_rig(
    temps_c: Mapping[str, float | None], source_address: int | None = None, *, timestamp_s: float = 0.0
) -> list[can.Message]:
    """RIG_TC_1..7 frames for one sample of rig thermocouple temperatures."""
    return RigEncoder(source_address).encode(temps_c, timestamp_s=timestamp_s)
