"""Project configuration (`--config FILE.toml`): which gearbox, which cooler, boundary temperatures, CAN addresses,
sensor options. Every section is optional; unknown keys are an error naming the key (typos must not pass silently).

Example::

    [gearbox]
    variant = "GRS905"          # or GRSO905, or params = "my_gearbox.toml"
    [cooler]
    kind = "liquid"             # none | liquid | air | hold | measured
    [boundary]                  # degC, constant defaults when a run table carries no bc_ columns
    ambient = 25.0
    hot_surroundings = 90.0
    [can]
    sensor_source_address = 0xE5
    engine_source_address = 0x00
    transmission_source_address = 0x03
    retarder_source_address = 0x10
    engine_reference_torque_nm = 2400   # used until EC1 (TP.BAM) has arrived
    retarder_reference_torque_nm = 3500
    [can.source_address]        # one message's source address alone, over the keys above
    TRF1 = 0x21                 # e.g. a Navistar: gear (ETC2) from 0x03, transmission oil (TRF1) from 0x21
    [sensor]
    oil_mode = "measured"        # measured | model
    held_step = "auto"           # auto | reference: a held SCADA table's step (docs/sensor.md)
    [diagnosis]                 # the commands' settings (SETTINGS): [simulate], [replay], [bus], [gateway], [plant],
    start = "running"           # [diagnosis], [calibration], [bench], [fleet], [export]; docs/interfaces.md section 8
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from firmware_model.errors import ParameterError
from firmware_model.parameters import Parameters, load_parameters, read_toml

ALLOWED = {
    "gearbox": {"variant", "params"},
    "cooler": {"kind"},
    "boundary": {
        "initial",
        "ambient",
        "engine_shaft",
        "flywheel_cover",
        "support_beam",
        "end_yoke",
        "hot_surroundings",
        "cold_surroundings",
        "coolant",
    },
    "can": {
        "sensor_source_address",
        "engine_source_address",
        "transmission_source_address",
        "retarder_source_address",
        "ambient_source_address",
        "vehicle_speed_source_address",
        "coolant_source_address",
        "source_address",
        "engine_reference_torque_nm",
        "retarder_reference_torque_nm",
        "gear_map",
        "output_period_s",
        "stale_factor",
        "counter_log_period_s",
        "name_identity_number",
        "name_manufacturer_code",
        "name_ecu_instance",
        "name_function_instance",
        "name_function",
        "name_vehicle_system",
        "name_vehicle_system_instance",
        "name_industry_group",
        "arbitrary_address_capable",
    },
    "sensor": {"oil_mode", "limits", "debounce_s", "hysteresis_c", "snapshot", "ttl_method", "held_step"},
}


@dataclass(frozen=True)
class Setting:
    """A command's setting that lives in the configuration (not on the command line): its default, what it may be
    (``kind``: "float" or "int" within ``low..high``, "bool", "str", or a tuple of the words allowed) and the
    command-line option it replaced (still accepted, hidden, and overriding the file)."""

    default: object
    kind: object
    option: str
    low: float = -math.inf
    high: float = math.inf
    unit: str = ""  # named in the error sentence: "a whole number of days"
    text: str = ""  # what a value must be, when it says more than the kind and range

    def describe(self) -> str:
        """What a value must be, for an error sentence."""
        if self.text:
            return self.text
        if isinstance(self.kind, tuple):
            return " or ".join(repr(k) for k in self.kind)
        if self.kind in ("float", "int"):
            whole = ("a whole number" if self.kind == "int" else "a number") + (f" of {self.unit}" if self.unit else "")
            return f"{whole} in {self.low:g}..{self.high:g}" if math.isfinite(self.high) else f"{whole} >= {self.low:g}"
        return {"bool": "true or false", "str": "a string in quotes"}[self.kind]

    def accepts(self, v) -> bool:
        if isinstance(self.kind, tuple):
            return v in self.kind
        if self.kind == "bool":
            return isinstance(v, bool)
        if self.kind == "str":
            return isinstance(v, str)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (self.kind == "int" and not float(v).is_integer()):
            return False
        return self.low <= v <= self.high


#: a temperature a user sets for the gearbox: the oil model's range (firmware_model.physics.oil.check_temperature_c)
_TEMPERATURE = "a plausible gearbox temperature: use -40..200 degC (the oil model's range)"
_STARTS = ("auto", "rest", "running")
#: the commands' settings read from the configuration, by section.key (docs/interfaces.md section 8); the option
#: each replaced is still accepted, hidden, and wins over the file
SETTINGS = {
    "simulate.rate_hz": Setting(10.0, "float", "--rate", 0.001, 1000.0),
    "simulate.noise": Setting(False, "bool", "--noise"),
    "simulate.dt_s": Setting(0.5, "float", "--dt", 0.01, 5.0),
    "simulate.out_dt_s": Setting(1.0, "float", "--out-dt", 0.01, 3600.0),
    "simulate.initial_temp_c": Setting(None, "float", "--initial-temp", -40.0, 200.0, text=_TEMPERATURE),
    "simulate.hold_oil_c": Setting(None, "float", "--hold-oil", -40.0, 200.0, text=_TEMPERATURE),
    "replay.initial_temp_c": Setting(None, "float", "--initial-temp", -40.0, 200.0, text=_TEMPERATURE),
    "replay.strict": Setting(False, "bool", "--strict"),
    "bus.bitrate_bit_s": Setting(
        None, "int", "--bitrate", 10_000, 1_000_000, text="a CAN bit rate in 10000..1000000 bit/s"
    ),
    "bus.receive_filters": Setting(True, "bool", "--no-filters"),
    "bus.receive_rig": Setting(False, "bool", "--rig"),
    "gateway.log_level": Setting("INFO", ("DEBUG", "INFO", "WARNING", "ERROR"), "--log-level"),
    "gateway.rt_priority": Setting(None, "int", "--rt-priority", 1, 99),
    "gateway.state_period_s": Setting(60.0, "float", "--state-period", 1.0, 86400.0),
    "plant.seed": Setting(0, "int", "--seed", 0),
    "plant.rig_frames": Setting(True, "bool", "--no-rig"),
    "diagnosis.grid_dt_s": Setting(2.0, "float", "--grid-dt", 0.1, 60.0),
    "diagnosis.plant_dt_s": Setting(1.0, "float", "--plant-dt", 0.05, 5.0),
    "diagnosis.workers": Setting(None, "int", "--workers", 1),
    "diagnosis.start": Setting("auto", _STARTS, "--start"),
    "calibration.plant_dt_s": Setting(2.0, "float", "--plant-dt", 0.05, 5.0),
    "calibration.workers": Setting(None, "int", "--workers", 1),
    "calibration.start": Setting("auto", _STARTS, "--start"),
    "bench.model": Setting("plant", ("plant", "onboard"), "--model"),
    "bench.train_s": Setting(1500.0, "float", "--train-s", 60.0, 86400.0),
    "bench.test_s": Setting(1500.0, "float", "--test-s", 60.0, 86400.0),
    "bench.setup": Setting("rig", ("truck", "rig"), "--setup"),
    "bench.cooler": Setting("liquid", ("liquid", "air"), "--cooler"),
    "bench.start": Setting("auto", _STARTS, "--start"),
    "fleet.estimates": Setting(False, "bool", "--estimates"),
    "fleet.period_days": Setting(7, "int", "--period-days", 1, 3650, "days"),
    "fleet.report": Setting(True, "bool", "--no-report"),
    "export.time_to_limit": Setting(True, "bool", "--no-ttl"),
}
for _key in SETTINGS:
    ALLOWED.setdefault(_key.split(".")[0], set()).add(_key.split(".")[1])


@dataclass
class Config:
    variant: str = "GRS905"
    params_path: str | None = None
    cooler: str | None = None
    boundary: dict = field(default_factory=dict)
    can: dict = field(default_factory=dict)
    sensor: dict = field(default_factory=dict)
    origin: str = "defaults"
    #: the values of :data:`SETTINGS` the file gives, by section.key
    settings: dict = field(default_factory=dict)

    def setting(self, key: str):
        """The value of a command's setting (:data:`SETTINGS`): the file's, else its default."""
        return self.settings.get(key, SETTINGS[key].default)

    def load_params(self) -> Parameters:
        p = load_parameters(self.params_path or self.variant)
        if self.boundary:
            p = p.with_overrides({f"boundary.{k}": float(v) for k, v in self.boundary.items()})
        if self.cooler:
            p.strings["cooler.kind"] = self.cooler
        return p


#: the type of each [gearbox] and [sensor] key: a string, or a number with its range (the [boundary] keys are
#: checked below, [can] by the CAN configuration)
KEY_TYPES = {
    "gearbox.variant": str,
    "gearbox.params": str,
    "sensor.oil_mode": str,
    "sensor.ttl_method": str,
    "sensor.held_step": str,
    "sensor.limits": str,
    "sensor.debounce_s": (0.0, 60.0),
    "sensor.hysteresis_c": (0.0, 50.0),
}


def _check_types(doc: dict, name: str) -> None:
    """ParameterError naming the key whose value has the wrong type (a number as a string, a list...), and for
    variant and params given together."""
    for key, kind in KEY_TYPES.items():
        sec, k = key.split(".")
        if k not in doc.get(sec, {}):
            continue
        v = doc[sec][k]
        if kind is str and not isinstance(v, str):
            raise ParameterError(f"config {name}: {key} = {v!r} must be a string in quotes")
        if isinstance(kind, tuple) and (
            isinstance(v, bool) or not isinstance(v, (int, float)) or not kind[0] <= v <= kind[1]
        ):
            raise ParameterError(f"config {name}: {key} = {v!r} must be a number in {kind[0]:g}..{kind[1]:g}")
    if {"variant", "params"} <= set(doc.get("gearbox", {})):
        raise ParameterError(
            f"config {name}: give gearbox.variant or gearbox.params, not both (params is a whole "
            f"parameter file, variant a built-in one)"
        )


def load_config(path: str | Path | Config | None) -> Config:
    """The configuration of a TOML file (None: the defaults; a Config: itself, for a caller that changed one)."""
    if path is None:
        return Config()
    if isinstance(path, Config):
        return path
    path = Path(path)
    doc = read_toml(path, f"config file {path}")
    for sec, body in doc.items():
        if sec not in ALLOWED:
            hint = (
                (
                    f" ({path.name} looks like a parameter file, e.g. one calibrate wrote: give it in a project "
                    f'configuration as [gearbox] params = "{path.name}")'
                )
                if sec == "meta"
                else ""
            )
            raise ParameterError(f"config {path.name}: unknown section [{sec}]; known: {', '.join(ALLOWED)}{hint}")
        if not isinstance(body, dict):
            raise ParameterError(f"config {path.name}: [{sec}] must be a table")
        for k in body:
            if k not in ALLOWED[sec]:
                raise ParameterError(
                    f"config {path.name}: unknown key {sec}.{k}; known: {', '.join(sorted(ALLOWED[sec]))}"
                )
    _check_types(doc, path.name)
    g = doc.get("gearbox", {})
    params = g.get("params")
    if params is not None and not Path(params).is_absolute():
        params = str((path.parent / params).resolve())
    cooler = doc.get("cooler", {}).get("kind")
    if cooler is not None and cooler not in ("none", "liquid", "air", "hold", "measured"):
        raise ParameterError(
            f"config {path.name}: cooler.kind = {cooler!r} must be none, liquid, air, hold or measured"
        )
    settings = {f"{sec}.{k}": v for sec, body in doc.items() for k, v in body.items() if f"{sec}.{k}" in SETTINGS}
    for key, v in settings.items():
        if not SETTINGS[key].accepts(v):
            raise ParameterError(f"config {path.name}: {key} = {v!r} must be {SETTINGS[key].describe()}")
    for k, v in doc.get("boundary", {}).items():
        if not isinstance(v, (int, float)) or not -60 <= v <= 250:
            raise ParameterError(f"config {path.name}: boundary.{k} = {v!r} must be a temperature in -60..250 degC")
    sensor = dict(doc.get("sensor", {}))
    limits = sensor.get("limits")
    if limits is not None and not Path(limits).is_absolute() and (path.parent / limits).exists():
        sensor["limits"] = str((path.parent / limits).resolve())  # relative to this file (else a shipped name)
    return Config(
        g.get("variant", "GRS905"),
        params,
        cooler,
        dict(doc.get("boundary", {})),
        dict(doc.get("can", {})),
        sensor,
        str(path),
        settings,
    )
