"""Column maps: which file column becomes which run-table input or measured channel (docs/real-data.md).

A column map is a TOML file: the time column and its kind, the column naming the unit (turbine, vehicle), the
nominal row period, then ``[inputs.<name>]`` (run-table inputs, named with their unit: ``input_speed_rpm``) and
``[measured.<name>]`` (measured temperatures, each with the ``node`` of the gearbox description it is tied to). Each
entry names its ``column``, the column's ``unit`` and ``scale``/``offset`` (value = raw * scale + offset), the
plausible ``range`` and the largest one-row spike believed (``jump_k``); an input may instead be ``derive``d from
other columns (the torque from power and speed). ``--columns NAME|FILE``: a NAME is a map shipped in
``tools/scada/maps/`` (``engie``), anything else is read as a file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from firmware_model.errors import InputError

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

MAP_DIR = Path(__file__).resolve().parent / "maps"
#: the kinds of time column a map may name: ISO 8601 stamps with their UTC offset, ISO 8601 stamps in UTC (an offset,
#: where a stamp has one, still counts), UTC seconds, UTC milliseconds
TIME_KINDS = ("iso8601_offset", "iso8601_utc", "seconds", "milliseconds")
#: the ways an input may be derived from other columns, with the columns each needs
DERIVATIONS = {
    "power_over_speed": ("power", "speed"),
    "torque_times_ratio": ("torque", "fast_speed", "slow_speed"),
}
#: the keys a map may carry at its top, in its ``time`` and in its ``unit_id``
MAP_KEYS = {"format", "title", "period_s", "time", "unit_id", "standstill_rpm", "inputs", "measured"}
TIME_KEYS = {"column", "kind", "zone", "format", "at"}
UNIT_ID_KEYS = {"column"}
#: the run-table inputs every map gives (the drive and the air around the gearbox: tools/scada/runtable.py)
REQUIRED_INPUTS = {
    "input_speed_rpm": "the gearbox input shaft's speed",
    "input_torque_nm": "the input torque",
    "ambient_temp_c": "the air around the gearbox",
}
#: units a map may give a column in: (dimension, factor, offset) to the dimension's base unit (degC, rpm, N m, W)
KNOWN_UNITS = {
    **dict.fromkeys(("degC", "°C", "C"), ("temperature", 1.0, 0.0)),
    "K": ("temperature", 1.0, -273.15),
    **dict.fromkeys(("degF", "°F", "F"), ("temperature", 5.0 / 9.0, -32.0 * 5.0 / 9.0)),
    **dict.fromkeys(("rpm", "1/min", "r/min"), ("speed", 1.0, 0.0)),
    "rad/s": ("speed", 30.0 / math.pi, 0.0),
    **dict.fromkeys(("N m", "Nm", "N.m"), ("torque", 1.0, 0.0)),
    **dict.fromkeys(("kN m", "kNm", "kN.m"), ("torque", 1.0e3, 0.0)),
    "W": ("power", 1.0, 0.0),
    "kW": ("power", 1.0e3, 0.0),
    "MW": ("power", 1.0e6, 0.0),
}
#: the unit a run-table input's name ends with (the project's naming rule); measured channels are degC
NAME_UNITS = {"_c": "degC", "_rpm": "rpm", "_nm": "N m", "_kw": "kW", "_w": "W"}
#: the entry keys of a derived input's source unit and scale, by derivation, and the unit the scale must give
SOURCE_UNITS = {
    "power_over_speed": ("power_unit", "power_scale", "W"),
    "torque_times_ratio": ("torque_unit", "torque_scale", "N m"),
}
#: the keys an entry may carry
ENTRY_KEYS = {
    "column",
    "unit",
    "scale",
    "offset",
    "range",
    "jump_k",
    "node",
    "what",
    "derive",
    "speed_unit",
    "response_s",
} | {
    "power_unit",
    "power_scale",
    "torque_unit",
    "torque_scale",
    *(c for cols in DERIVATIONS.values() for c in cols),
}


@dataclass(frozen=True)
class Channel:
    """One run-table input or measured channel: where it comes from and which values are believed."""

    name: str
    column: str | None
    unit: str
    scale: float = 1.0
    offset: float = 0.0
    range: tuple[float, float] | None = None
    jump_k: float | None = None
    node: str | None = None
    what: str = ""
    derive: str | None = None
    #: a derived input's source columns by role (power, speed; torque, fast_speed, slow_speed) and their scale
    sources: dict = field(default_factory=dict)
    source_scale: float = 1.0
    #: a derived input's speed columns to rpm (``speed_unit``, rpm by default)
    speed_scale: float = 1.0
    #: a measured channel's response [s]: the reading follows its part's rise over the sump through a first-order
    #: lag of this time constant (0: the part's temperature itself; tools.scada.replay.reading_response)
    response_s: float = 0.0

    @property
    def columns(self) -> tuple[str, ...]:
        """The file columns this channel reads."""
        return tuple(self.sources.values()) if self.derive else (self.column,)


@dataclass(frozen=True)
class ColumnMap:
    """A parsed column map (see the module's docstring)."""

    name: str
    time_column: str
    time_kind: str
    unit_column: str | None
    period_s: float
    standstill_rpm: float
    inputs: dict[str, Channel]
    measured: dict[str, Channel]
    title: str = ""
    time_zone: str | None = None  # an IANA zone: stamps without a UTC offset are its local time
    time_format: str | None = None  # a strptime format of the stamps (else ISO 8601)
    time_at: str = "end"  # what a stamp marks of its row's period: "end" (ENGIE's) or "start"

    @property
    def channels(self) -> dict[str, Channel]:
        return {**self.inputs, **self.measured}

    @property
    def columns(self) -> tuple[str, ...]:
        """Every file column the map reads, once each, in the map's order."""
        cols = [self.time_column] + ([self.unit_column] if self.unit_column else [])
        for ch in self.channels.values():
            cols.extend(c for c in ch.columns if c not in cols)
        return tuple(cols)

    @property
    def nodes(self) -> dict[str, str]:
        """measured channel -> the description node it is tied to."""
        return {k: ch.node for k, ch in self.measured.items() if ch.node}


def shipped_maps() -> tuple[str, ...]:
    return tuple(sorted(p.stem for p in MAP_DIR.glob("*.toml")))


def map_path(spec: str | Path) -> Path:
    """The file of ``--columns NAME|FILE``: a shipped map's name, or a path."""
    if isinstance(spec, str) and spec in shipped_maps():
        return MAP_DIR / f"{spec}.toml"
    path = Path(spec)
    if not path.is_file():
        raise InputError(
            f"column map {spec}: neither a shipped map ({', '.join(shipped_maps())}) nor a file that exists"
        )
    return path


def load_column_map(spec: str | Path) -> ColumnMap:
    """The column map ``spec`` (a shipped map's name or a TOML file), checked; an InputError names the key."""
    path = map_path(spec)
    try:
        raw = tomllib.loads(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise InputError(f"column map {path.name}: not a readable TOML file ({exc})") from None
    where = path.name
    _known_keys(raw, MAP_KEYS, where)
    time = _table(raw, "time", where)
    _known_keys(time, TIME_KEYS, f"{where}: time")
    unit_id = raw.get("unit_id", {})
    if not isinstance(unit_id, dict):
        raise InputError(f'column map {where}: unit_id must be a table, e.g. unit_id = {{ column = "Turbine" }}')
    _known_keys(unit_id, UNIT_ID_KEYS, f"{where}: unit_id")
    kind = time.get("kind", "iso8601_offset")
    if kind not in TIME_KINDS:
        raise InputError(f"column map {where}: time.kind = {kind!r} is none of {', '.join(TIME_KINDS)}")
    zone, fmt, at = _time_extras(time, kind, where)
    inputs = {k: _channel(k, v, f"{where}: inputs.{k}") for k, v in _table(raw, "inputs", where).items()}
    measured_raw = raw.get("measured", {})
    if not isinstance(measured_raw, dict):
        raise InputError(f"column map {where}: measured must be tables [measured.<channel>], not {measured_raw!r}")
    measured = {k: _channel(k, v, f"{where}: measured.{k}", "degC") for k, v in measured_raw.items()}
    for k, ch in measured.items():
        if ch.derive:
            raise InputError(f"column map {where}: measured.{k} is derived; a measured channel is one column")
        if not isinstance(ch.node, str) or not ch.node:
            raise InputError(
                f"column map {where}: measured.{k} needs node = the id of the gearbox part the reading is tied to "
                '(the description\'s, e.g. "oil" for the sump)'
            )
    for k, what in REQUIRED_INPUTS.items():
        if k not in inputs:
            raise InputError(f"column map {where}: needs [inputs.{k}] ({what}): no run table without it")
    sumps = [k for k, ch in measured.items() if ch.node == "oil"]
    if len(sumps) > 1:
        raise InputError(
            f'column map {where}: {" and ".join(sumps)} are both tied to the sump (node "oil"), which the '
            "sensor reads from one channel: tie one of them elsewhere or leave it out"
        )
    _check_responses(inputs, measured, where)
    standstill = _number(raw, "standstill_rpm", where, default=0.0)
    top = (inputs["input_speed_rpm"].range or (0.0, math.inf))[1]
    if not 0.0 <= standstill < top:
        raise InputError(
            f"column map {where}: standstill_rpm = {standstill:g} must lie in 0 .. {top:g} rpm (the input speed's "
            "range): the rotor counts as standing still below it"
        )
    return ColumnMap(
        name=str(raw.get("format", path.stem)),
        time_column=_text(time, "column", f"{where}: time"),
        time_kind=kind,
        unit_column=unit_id.get("column"),
        period_s=_number(raw, "period_s", where, positive=True),
        standstill_rpm=standstill,
        inputs=inputs,
        measured=measured,
        title=str(raw.get("title", "")),
        time_zone=zone,
        time_format=fmt,
        time_at=at,
    )


def _time_extras(time: dict, kind: str, where: str) -> tuple[str | None, str | None, str]:
    """A map's time.zone (an IANA zone the stamps without an offset are local time of), time.format (a strptime
    format) and time.at ("end" or "start" of the row's period), checked."""
    from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

    zone, fmt, at = time.get("zone"), time.get("format"), time.get("at", "end")
    if at not in ("end", "start"):
        raise InputError(f'column map {where}: time.at = {at!r} is neither "end" nor "start" of the row\'s period')
    iso = kind.startswith("iso8601")
    for key, val in (("zone", zone), ("format", fmt)):
        if val is not None and not iso:
            raise InputError(f"column map {where}: time.{key} is for ISO 8601 stamps, not time.kind = {kind!r}")
        if val is not None and (not isinstance(val, str) or not val):
            raise InputError(f"column map {where}: time.{key} must be a text, not {val!r}")
    if zone is not None:
        if kind == "iso8601_utc":
            raise InputError(f"column map {where}: time.zone with kind iso8601_utc: the stamps are UTC or local")
        try:
            ZoneInfo(zone)
        except (ZoneInfoNotFoundError, ValueError):
            raise InputError(
                f"column map {where}: time.zone = {zone!r} is no IANA time zone (e.g. Europe/Paris)"
            ) from None
    if fmt is not None and "%" not in fmt:
        raise InputError(f"column map {where}: time.format = {fmt!r} is no strptime format (e.g. %d.%m.%Y %H:%M)")
    return zone, fmt, at


def _table(raw: dict, key: str, where: str) -> dict:
    val = raw.get(key)
    if not isinstance(val, dict) or not val:
        raise InputError(f"column map {where}: needs a [{key}] table")
    return val


def _text(entry: dict, key: str, where: str) -> str:
    val = entry.get(key)
    if not isinstance(val, str) or not val:
        raise InputError(f"column map {where}: {key} must name a column (a non-empty string)")
    return val


def _check_responses(inputs: dict, measured: dict, where: str) -> None:
    """``response_s`` belongs to a measured channel that is not the sump's, in a map that reads the sump (the
    response is of the channel's rise over it)."""
    for k, ch in inputs.items():
        if ch.response_s:
            raise InputError(f"column map {where}: inputs.{k} has response_s, which only a measured channel has")
    sump = any(ch.node == "oil" for ch in measured.values())
    for k, ch in measured.items():
        if ch.response_s and ch.node == "oil":
            raise InputError(
                f"column map {where}: measured.{k} is the sump's and has response_s: a response is of a channel's "
                "rise over the sump"
            )
        if ch.response_s and not sump:
            raise InputError(
                f"column map {where}: measured.{k} has response_s, a response to its rise over the sump, but no "
                'channel is tied to the sump (node "oil")'
            )


def _number(entry: dict, key: str, where: str, default=None, positive=False) -> float:
    val = entry.get(key, default)
    if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val):
        raise InputError(f"column map {where}: {key} must be a finite number, not {val!r}")
    if positive and val <= 0:
        raise InputError(f"column map {where}: {key} must be positive, not {val!r}")
    return float(val)


def _response_s(entry: dict, where: str) -> float:
    """A measured channel's ``response_s`` (0 without one): a finite number of seconds, 0 or more."""
    val = _number(entry, "response_s", where, default=0.0)
    if val < 0.0:
        raise InputError(f"column map {where}: response_s must be 0 or more seconds, not {val!r}")
    return val


def _range(entry: dict, where: str) -> tuple[float, float] | None:
    val = entry.get("range")
    if val is None:
        return None
    ok = isinstance(val, list) and len(val) == 2 and all(isinstance(v, (int, float)) for v in val)
    if not ok or not val[0] < val[1]:
        raise InputError(f"column map {where}: range must be [low, high] with low < high, not {val!r}")
    return float(val[0]), float(val[1])


def _channel(name: str, entry: dict, where: str, target: str | None = "") -> Channel:
    """One entry of [inputs] or [measured]; ``target``: the unit its values are in after the scale ("": the unit
    its name ends with, NAME_UNITS)."""
    if not isinstance(entry, dict):
        raise InputError(f"column map {where}: must be a table")
    unknown = sorted(set(entry) - ENTRY_KEYS)
    if unknown:
        raise InputError(f"column map {where}: unknown key {unknown[0]!r} (known: {', '.join(sorted(ENTRY_KEYS))})")
    target = _name_unit(name) if target == "" else target
    scale, offset = _conversion(entry, "unit", "scale", "offset", target, where)
    common = dict(
        unit=_text(entry, "unit", where),
        scale=scale,
        offset=offset,
        range=_range(entry, where),
        jump_k=_number(entry, "jump_k", where, positive=True) if "jump_k" in entry else None,
        node=entry.get("node"),
        what=str(entry.get("what", "")),
        response_s=_response_s(entry, where),
    )
    derive = entry.get("derive")
    if derive is None:
        return Channel(name=name, column=_text(entry, "column", where), **common)
    if derive not in DERIVATIONS:
        raise InputError(f"column map {where}: derive = {derive!r} is none of {', '.join(DERIVATIONS)}")
    sources = {role: _text(entry, role, where) for role in DERIVATIONS[derive]}
    unit_key, scale_key, base = SOURCE_UNITS[derive]
    source_scale, _ = _conversion(entry, unit_key, scale_key, None, base, where)
    speed_unit = entry.get("speed_unit", "rpm")
    speed = KNOWN_UNITS.get(str(speed_unit))
    if speed is None or speed[0] != "speed":
        units = ", ".join(sorted(u for u, v in KNOWN_UNITS.items() if v[0] == "speed"))
        raise InputError(f"column map {where}: speed_unit = {speed_unit!r} is none of {units}")
    return Channel(
        name=name,
        column=None,
        derive=derive,
        sources=sources,
        source_scale=source_scale,
        speed_scale=speed[1],
        **common,
    )


def _known_keys(table: dict, known: set, where: str) -> None:
    unknown = sorted(set(table) - known)
    if unknown:
        raise InputError(f"column map {where}: unknown key {unknown[0]!r} (known: {', '.join(sorted(known))})")


def _name_unit(name: str) -> str | None:
    """The unit a run-table input's name ends with (None: a name without one of NAME_UNITS' suffixes)."""
    return next((u for suffix, u in NAME_UNITS.items() if name.endswith(suffix)), None)


def _conversion(entry: dict, unit_key: str, scale_key: str, offset_key: str | None, target, where: str):
    """(scale, offset) that turn the column's ``entry[unit_key]`` into ``target``: implied by a unit of KNOWN_UNITS
    (a scale or offset the map gives must agree with it), else the map's own, which a unit the tool does not know
    must give. No unit (``unit_key`` absent) takes the map's scale as it is."""
    scale = _number(entry, scale_key, where, default=1.0)
    offset = _number(entry, offset_key, where, default=0.0) if offset_key else 0.0
    if scale == 0.0:
        raise InputError(f"column map {where}: {scale_key} must not be 0 (every value would be {offset:g})")
    unit = entry.get(unit_key)
    if unit is None or target is None:
        return scale, offset
    have, want = KNOWN_UNITS.get(str(unit)), KNOWN_UNITS[target]
    if have is None:
        if scale_key not in entry:
            same = sorted(u for u, v in KNOWN_UNITS.items() if v[0] == want[0])
            raise InputError(
                f"column map {where}: {unit_key} = {unit!r} is not a unit the tool converts ({', '.join(same)}); "
                f"give {scale_key}{' and ' + offset_key if offset_key else ''} that turn it into {target}"
            )
        return scale, offset
    if have[0] != want[0]:
        raise InputError(
            f"column map {where}: {unit_key} = {unit!r} is a {have[0]}, but {where.split(': ')[-1]} is "
            f"a {want[0]} in {target}"
        )
    implied = (have[1] / want[1], (have[2] - want[2]) / want[1])
    given = (scale if scale_key in entry else implied[0], offset if offset_key and offset_key in entry else implied[1])
    if not (math.isclose(given[0], implied[0], rel_tol=1e-3) and math.isclose(given[1], implied[1], abs_tol=0.01)):
        raise InputError(
            f"column map {where}: {unit_key} = {unit!r} in {target} is {scale_key} {implied[0]:.6g}"
            + (f", {offset_key} {implied[1]:.6g}" if offset_key else "")
            + "; the map gives "
            + ", ".join(f"{k} {v:g}" for k, v in ((scale_key, given[0]), (offset_key, given[1])) if k and k in entry)
            + f" (leave {' and '.join(k for k in (scale_key, offset_key) if k and k in entry)} out and {unit!r} "
            "converts)"
        )
    return given
