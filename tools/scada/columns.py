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
#: the kinds of time column a map may name
TIME_KINDS = ("iso8601_offset", "seconds")
#: the ways an input may be derived from other columns, with the columns each needs
DERIVATIONS = {
    "power_over_speed": ("power", "speed"),
    "torque_times_ratio": ("torque", "fast_speed", "slow_speed"),
}
#: the keys an entry may carry
ENTRY_KEYS = {"column", "unit", "scale", "offset", "range", "jump_k", "node", "what", "derive"} | {
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
    time = _table(raw, "time", where)
    kind = time.get("kind", "iso8601_offset")
    if kind not in TIME_KINDS:
        raise InputError(f"column map {where}: time.kind = {kind!r} is none of {', '.join(TIME_KINDS)}")
    inputs = {k: _channel(k, v, f"{where}: inputs.{k}") for k, v in _table(raw, "inputs", where).items()}
    measured = {k: _channel(k, v, f"{where}: measured.{k}") for k, v in raw.get("measured", {}).items()}
    for k, ch in measured.items():
        if ch.derive:
            raise InputError(f"column map {where}: measured.{k} is derived; a measured channel is one column")
    return ColumnMap(
        name=str(raw.get("format", path.stem)),
        time_column=_text(time, "column", f"{where}: time"),
        time_kind=kind,
        unit_column=raw.get("unit_id", {}).get("column"),
        period_s=_number(raw, "period_s", where, positive=True),
        standstill_rpm=_number(raw, "standstill_rpm", where, default=0.0),
        inputs=inputs,
        measured=measured,
        title=str(raw.get("title", "")),
    )


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


def _number(entry: dict, key: str, where: str, default=None, positive=False) -> float:
    val = entry.get(key, default)
    if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val):
        raise InputError(f"column map {where}: {key} must be a finite number, not {val!r}")
    if positive and val <= 0:
        raise InputError(f"column map {where}: {key} must be positive, not {val!r}")
    return float(val)


def _range(entry: dict, where: str) -> tuple[float, float] | None:
    val = entry.get("range")
    if val is None:
        return None
    ok = isinstance(val, list) and len(val) == 2 and all(isinstance(v, (int, float)) for v in val)
    if not ok or not val[0] < val[1]:
        raise InputError(f"column map {where}: range must be [low, high] with low < high, not {val!r}")
    return float(val[0]), float(val[1])


def _channel(name: str, entry: dict, where: str) -> Channel:
    if not isinstance(entry, dict):
        raise InputError(f"column map {where}: must be a table")
    unknown = sorted(set(entry) - ENTRY_KEYS)
    if unknown:
        raise InputError(f"column map {where}: unknown key {unknown[0]!r} (known: {', '.join(sorted(ENTRY_KEYS))})")
    common = dict(
        unit=_text(entry, "unit", where),
        range=_range(entry, where),
        jump_k=_number(entry, "jump_k", where, positive=True) if "jump_k" in entry else None,
        node=entry.get("node"),
        what=str(entry.get("what", "")),
    )
    derive = entry.get("derive")
    if derive is None:
        return Channel(
            name=name,
            column=_text(entry, "column", where),
            scale=_number(entry, "scale", where, default=1.0),
            offset=_number(entry, "offset", where, default=0.0),
            **common,
        )
    if derive not in DERIVATIONS:
        raise InputError(f"column map {where}: derive = {derive!r} is none of {', '.join(DERIVATIONS)}")
    sources = {role: _text(entry, role, where) for role in DERIVATIONS[derive]}
    scale_key = "power_scale" if derive == "power_over_speed" else "torque_scale"
    return Channel(
        name=name,
        column=None,
        derive=derive,
        sources=sources,
        source_scale=_number(entry, scale_key, where, default=1.0),
        **common,
    )
