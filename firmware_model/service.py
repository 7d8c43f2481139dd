"""The live CAN service core: J1939 frames in, the virtual sensor stepped on frame time, GBX_* frames out.

:class:`SensorService` owns time and is pure of threads, clocks and I/O: ``feed(msg)`` takes one received frame and
returns the frames to send. Live (``gearbox-vsensor run``, :func:`serve`), replay of a log (tools/cli/replay.py) and
the tests all call the same ``feed``, so the same traffic gives bit-identical outputs at any replay speed.

Timing model (docs/can.md "Service"):

- **Time is frame time.** The first frame that drives time anchors the step grid: boundaries at ``t0 + k x 0.1 s``.
  Only frames the service listens to drive time (data frames of the PGNs in :data:`WANTED_PGNS`, the same set the
  live receive filters pass); every other frame is still decoded and counted but never moves time, so a replay
  without filters steps exactly like a live run with them.
- **A step is due** when a frame's timestamp reaches the next boundary; the step runs *before* that frame is used,
  on the latest values of the frames before the boundary. Missing boundaries (a silent bus) are stepped one by one
  up to ``max_catchup_steps`` (default 50 = 5 s); only the last of a burst of catch-up steps is sent (the older ones
  would be stale on the bus), every step is recorded.
- **Time jumps**: a frame more than ``max_catchup_steps`` steps ahead, or more than ``backward_tolerance_s``
  behind the last step, restarts the grid at that frame: values are dropped, the sensor resumes from its state
  (``elapsed_s`` = the forward gap) and the event is counted (``time_jumps``) and logged.
- **Staleness**: a value older than ``stale_factor`` (default 3) x its message's nominal period
  (:data:`NOMINAL_PERIOD_S`) at a step boundary is given to the sensor as NaN ("not available"); it recovers with
  the next valid frame. A J1939 "not available" or "error" value is not a value: the signal goes stale the same way.
- **Outputs** every step (100 ms): the 16 GBX frames with the step's frame time as timestamp; GBX_DM1 every
  second and whenever its content changes. Before the sensor is initialised (it waits up to ``init_wait_s`` for a
  measured oil temperature) the frames say "not initialised" (DegradedMode 3), every value not available.

Counters (:attr:`SensorService.counters`, logged every ``counter_log_period_s`` of frame time): the decoder's
(frames seen = used + rejected per reason; values rejected per signal; TP.BAM) plus the service's (steps, steps
sent, catch-up steps, time jumps, frames that did not drive time, steps with each input stale, frames sent).

Only the standard library, numpy and the CAN adapter (python-can, cantools) are imported (docs/CONVENTIONS.md).
"""
from __future__ import annotations

import logging
import math
import queue
import threading
import time
from dataclasses import dataclass, field
from typing import Callable, Iterable, Mapping

import numpy as np

from can_dbc.adapter import (SENSOR_SOURCE_ADDRESS, TP_CM_PGN, TP_DT_PGN, J1939Decoder, OutputEncoder,
                             load_database)
from firmware_model.components import PUBLISHED
from firmware_model.errors import ParameterError

log = logging.getLogger("gearbox_vsensor.can_service")

#: the sensor's fixed step [s]
STEP_S = 0.1
#: nominal transmission period of each input message [s] (J1939-71 defaults; EEC1 is engine-speed dependent,
#: 10-20 ms, its upper bound is used); RIG = the rig thermocouple frames
NOMINAL_PERIOD_S = {"EEC1": 0.02, "ETC2": 0.1, "TRF1": 1.0, "ET1": 1.0, "AMB": 1.0, "CCVS1": 1.0, "ERC1": 0.1,
                    "RIG": 0.1}
#: decoder signal -> the message that carries it (for staleness)
SIGNAL_MESSAGE = {"engine_speed_rpm": "EEC1", "engine_torque_pct": "EEC1", "engine_torque_nm": "EEC1",
                  "gear": "ETC2", "oil_temp_c": "TRF1", "coolant_temp_c": "ET1", "ambient_temp_c": "AMB",
                  "vehicle_speed_kmh": "CCVS1", "retarder_torque_pct": "ERC1", "retarder_torque_nm": "ERC1"}
#: the sensor's inputs (field name) <- decoder signal
SENSOR_INPUTS = (("speed_rpm", "engine_speed_rpm"), ("torque_nm", "engine_torque_nm"), ("gear", "gear"),
                 ("oil_temp_c", "oil_temp_c"), ("ambient_temp_c", "ambient_temp_c"),
                 ("coolant_temp_c", "coolant_temp_c"), ("vehicle_speed_kmh", "vehicle_speed_kmh"),
                 ("retarder_torque_nm", "retarder_torque_nm"))
#: run-table column of each decoded input (CONTRACTS.md section 3) and extra decoded columns
INPUT_COLUMNS = ("engine_speed_rpm", "engine_torque_nm", "gear", "oil_temp_c", "ambient_temp_c", "coolant_temp_c",
                 "vehicle_speed_kmh", "retarder_torque_nm", "engine_torque_pct", "engine_ref_torque_nm")
#: PGNs the service listens to; PDU1 PGNs (TP.CM, TP.DT) are matched without their destination byte
WANTED_PGNS = {"EEC1": 61444, "ETC2": 61445, "TRF1": 65272, "ET1": 65262, "AMB": 65269, "CCVS1": 65265,
               "ERC1": 61440, "TP_CM": TP_CM_PGN, "TP_DT": TP_DT_PGN}
#: status keys of the GBX_STATUS frame that the service fills
STATUS_FLAGS = ("speed_valid", "torque_valid", "gear_valid", "oil_valid", "ref_torque_valid")
#: DegradedMode code sent before the sensor is initialised
MODE_NOT_INITIALISED = 3
#: the model's gear range (seed Table 1); other J1939 gear numbers (after gear_map) are not available to the sensor
GEAR_RANGE = (-2, 14)

_DM1_PERIOD_STEPS = 10


def rig_pgns() -> list[int]:
    """PGNs of the rig thermocouple frames RIG_TC_1..7."""
    db = load_database()
    return [(m.frame_id >> 8) & 0x3FFFF for m in db.messages if m.name.startswith("RIG_TC_")]


def can_filters(rig: bool = False) -> list[dict]:
    """python-can receive filters for the wanted PGNs: the mask covers the PGN bits only (no priority, no source
    address; for PDU1 PGNs no destination either); ``rig`` adds the rig thermocouple PGNs."""
    pgns = list(WANTED_PGNS.values()) + (rig_pgns() if rig else [])
    filters = []
    for pgn in pgns:
        pdu1 = (pgn >> 8) & 0xFF < 240
        filters.append({"can_id": pgn << 8, "can_mask": 0x3FF0000 if pdu1 else 0x3FFFF00, "extended": True})
    return filters


def _wanted_key(can_id: int) -> int:
    pgn = (can_id >> 8) & 0x3FFFF
    return pgn & 0x3FF00 if (pgn >> 8) & 0xFF < 240 else pgn


@dataclass(frozen=True)
class ServiceOptions:
    """Service settings; :meth:`from_config` reads the config's ``[can]`` section."""
    expected_sa: Mapping[str, int | None] = field(default_factory=dict)
    sensor_source_address: int = SENSOR_SOURCE_ADDRESS
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

    def __post_init__(self) -> None:
        for name in ("stale_factor", "counter_log_period_s", "backward_tolerance_s"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise ParameterError(f"can.{name} = {value!r} must be a positive number")
        if self.stale_factor < 1.0:
            raise ParameterError(f"can.stale_factor = {self.stale_factor!r} must be >= 1 (a multiple of the "
                                 f"nominal period)")
        ratio = self.output_period_s / STEP_S
        if not (abs(ratio - round(ratio)) < 1e-9 and round(ratio) >= 1):
            raise ParameterError(f"can.output_period_s = {self.output_period_s!r} must be a whole multiple of the "
                                 f"sensor step {STEP_S} s")
        if not (isinstance(self.max_catchup_steps, int) and self.max_catchup_steps >= 1):
            raise ParameterError(f"max_catchup_steps = {self.max_catchup_steps!r} must be an integer >= 1")
        if not 0.0 <= self.init_wait_s <= 60.0:
            raise ParameterError(f"init_wait_s = {self.init_wait_s!r} must be in 0..60 s")

    @classmethod
    def from_config(cls, config=None, **overrides) -> "ServiceOptions":
        c = dict(getattr(config, "can", None) or {})
        sa: dict[str, int] = {}
        for key, names in (("engine_source_address", ("EEC1", "EC1", "ET1", "CCVS1", "AMB")),
                           ("transmission_source_address", ("ETC2", "TRF1")),
                           ("retarder_source_address", ("ERC1",)),
                           ("ambient_source_address", ("AMB",))):
            if key in c:
                for n in names:
                    sa[n] = c[key]
        kw: dict = {"expected_sa": sa}
        if "sensor_source_address" in c:
            kw["sensor_source_address"] = c["sensor_source_address"]
        if "engine_reference_torque_nm" in c:
            kw["configured_ref_torque_nm"] = c["engine_reference_torque_nm"]
        if "retarder_reference_torque_nm" in c:
            kw["retarder_ref_torque_nm"] = c["retarder_reference_torque_nm"]
        if "gear_map" in c:
            kw["gear_map"] = _gear_map(c["gear_map"])
        for key in ("stale_factor", "output_period_s", "counter_log_period_s"):
            if key in c:
                kw[key] = c[key]
        kw.update(overrides)
        return cls(**kw)


def _gear_map(raw) -> dict[int, int]:
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
            raise ParameterError(f"can.gear_map[{k!r}] = {v!r} is not a seed Table 1 gear "
                                 f"{GEAR_RANGE[0]}..{GEAR_RANGE[1]}")
        out[j] = v
    return out


# ---------------------------------------------------------------------------------------------------------------
# the sensor seen through its agreed API (firmware_model/onboard/sensor.py)
# ---------------------------------------------------------------------------------------------------------------

def _inputs_factory(sensor) -> Callable[..., object]:
    """The sensor's inputs record type: ``sensor.Inputs`` / the module's ``SensorInputs``."""
    for holder in (sensor, type(sensor)):
        for name in ("Inputs", "inputs_type"):
            factory = getattr(holder, name, None)
            if callable(factory):
                return factory
    import importlib
    module = importlib.import_module(type(sensor).__module__)
    for name in ("SensorInputs", "Inputs"):
        factory = getattr(module, name, None)
        if callable(factory):
            return factory
    raise ParameterError(f"{type(sensor).__name__} exposes no inputs record type (SensorInputs)")


def _status_value(status, *names, default=None):
    for name in names:
        if isinstance(status, Mapping):
            if name in status:
                return status[name]
        elif hasattr(status, name):
            return getattr(status, name)
    return default


def _opt_float(x) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


# ---------------------------------------------------------------------------------------------------------------
# the service
# ---------------------------------------------------------------------------------------------------------------

class SensorService:
    """Frames in, sensor stepped on frame time, frames out; see the module doc.

    ``sensor``: a ``VirtualSensor`` (pure ``step``); ``options``: :class:`ServiceOptions`; ``record``: keep one row
    per step for :meth:`recorded` (replay); ``emit_frames=False`` skips encoding the output frames (an offline
    replay to a run table that nobody sends: the steps, inputs and outputs are the same, ``feed`` returns nothing);
    ``logger``: where counters and events are logged.
    """

    def __init__(self, sensor, options: ServiceOptions | None = None, *, record: bool = False,
                 emit_frames: bool = True, logger: logging.Logger | None = None) -> None:
        self.sensor = sensor
        self.options = options or ServiceOptions()
        o = self.options
        self.decoder = J1939Decoder(expected_sa=o.expected_sa, retarder_ref_torque_nm=o.retarder_ref_torque_nm,
                                    configured_ref_torque_nm=o.configured_ref_torque_nm, rig=o.rig)
        self.encoder = OutputEncoder(o.sensor_source_address)
        self.log = logger or log
        self._inputs = _inputs_factory(sensor)
        self._inputs_have_time = "t_s" in getattr(self._inputs, "_fields", ())
        import importlib
        reasons = getattr(importlib.import_module(type(sensor).__module__), "REJECT_REASONS", None)
        self._reject_names = tuple(reasons) if isinstance(reasons, (tuple, list)) else ()
        self._wanted = {_wanted_key(f["can_id"]) for f in can_filters(rig=False)}
        self._timing_ids: dict[int, bool] = {}
        # latest value and frame time per decoder signal
        self.latest: dict[str, tuple[float, float]] = {}
        self._max_age = {m: o.stale_factor * p for m, p in NOMINAL_PERIOD_S.items()}
        self._input_ages = tuple((name, self._max_age[SIGNAL_MESSAGE[name]]) for _, name in SENSOR_INPUTS)
        self._input_fields = tuple(f for f, _ in SENSOR_INPUTS)
        self._out_every = int(round(o.output_period_s / STEP_S))
        # time
        self._t0: float | None = None       # grid anchor (frame time)
        self._k = 0                         # steps done since the anchor
        self._first_t: float | None = None  # frame time of the very first anchor (run-table time 0)
        self._time_offset = 0.0             # run-table time added after a backward restart
        self._next_log_t: float | None = None
        self._ref_warned = False
        # sensor; a sensor with step_deferred leaves its slow time-to-limit refresh to finish_pending(), which the
        # live loop runs after the step's frames are sent and every step runs first (so outputs never depend on when)
        self.state = None
        self._deferred = getattr(sensor, "step_deferred", None)
        self._pending = None
        self._initialised = False
        self._last_dm1: bytes | None = None
        self._steps_since_dm1 = 0
        self._last_levels: dict | None = None
        self.counters: dict = {"steps": 0, "steps_sent": 0, "catchup_steps": 0, "time_jumps": 0,
                               "frames_not_timing": 0, "frames_sent": 0, "dm1_sent": 0, "stale_steps": {},
                               "uninitialised_steps": 0}
        self._stale_prev: dict[str, bool] = {}
        # recording (replay)
        self.record = record
        self.emit_frames = emit_frames
        self._heads: list[tuple] = []       # per recorded step: time, inputs, torque %, reference torque
        self._meas_rows: dict[int, np.ndarray] = {}   # recorded step -> rig thermocouples (when any were seen)
        self._outs: list | tuple = []       # per recorded step: (T, level, ttl, status tail); see recorded_outputs
        #: None, or a callable that takes each step's _gather request instead of _apply (two-process replay)
        self._sink: Callable[[tuple], None] | None = None
        self._meas_names = [f"meas_T_{c}_c" for c in PUBLISHED]
        self._meas_index = {name: j for j, name in enumerate(self._meas_names)}
        n = len(PUBLISHED)
        self._meas_t = np.full(n, -np.inf)
        self._meas_v = np.full(n, np.nan)
        self._meas_seen = np.zeros(n, dtype=bool)

    # -- public -------------------------------------------------------------------------------------------------

    def feed(self, msg) -> list:
        """Use one received frame; returns the frames to send now (possibly none). Never raises on frame content."""
        out: list = []
        ts = msg.timestamp
        if self._drives_time(msg):
            if self._t0 is None:
                self._anchor(ts, gap_s=0.0)
            elif ts >= self._next_boundary:
                due = self._due(ts)
                if due > self.options.max_catchup_steps:
                    self._time_jump(ts, "forward")
                else:
                    self._steps(due, out)
            elif ts < self._next_boundary - STEP_S - self.options.backward_tolerance_s:
                self._time_jump(ts, "backward")
        else:
            self.counters["frames_not_timing"] += 1
        latest = self.latest
        for update in self.decoder.feed_raw(msg):
            name = update[1]
            j = self._meas_index.get(name)
            if j is None:
                latest[name] = (update[0], update[2])
            else:
                self._meas_t[j] = update[0]
                self._meas_v[j] = update[2]
                self._meas_seen[j] = True
        return out

    # -- the two halves of a step, for a replay that runs them in two processes (tools/can/replay_log.py) -----------

    def split_steps(self, sink: Callable[[tuple], None] | None) -> None:
        """From now on hand each step's frame-half request to ``sink`` instead of stepping the sensor (None: step
        again). The sensor half runs elsewhere: :meth:`apply_request` on a copy of this service."""
        self._sink = sink

    def apply_request(self, req: tuple) -> None:
        """Run the sensor half of a step that :meth:`split_steps` handed out (not sent: offline)."""
        self._apply(req, False)

    def adopt_outputs(self, outputs: tuple, state) -> None:
        """Take the sensor half's results from the copy that ran them: :meth:`recorded_outputs` and its final state
        (its time-to-limit refresh done)."""
        self._outs = outputs
        self.state = state
        self._pending = None

    def finish_pending(self) -> None:
        """Run the work the last step left for after its frames were sent (the sensor's time-to-limit refresh).
        Idempotent; the next step runs it anyway, so calling it or not never changes an output."""
        if self._pending is not None:
            job, self._pending = self._pending, None
            self.state = self.sensor.refresh_ttl(self.state, job)

    def feed_all(self, msgs: Iterable) -> list:
        out: list = []
        for msg in msgs:
            out.extend(self.feed(msg))
        return out

    @property
    def frame_time_s(self) -> float | None:
        """Frame time of the last step boundary (None before the first frame)."""
        return None if self._t0 is None else self._t0 + self._k * STEP_S

    def all_counters(self) -> dict:
        """The decoder's counters and the service's, in one dict."""
        return {"decoder": self.decoder.counters, "service": self.counters}

    def log_counters(self, level: int = logging.INFO) -> None:
        d = self.decoder.counters
        s = self.counters
        rejected = ", ".join(f"{k} {v}" for k, v in sorted(d["rejected"].items())) or "none"
        stale = ", ".join(f"{k} {v}" for k, v in sorted(s["stale_steps"].items())) or "none"
        self.log.log(level, "frames seen %d, used %d, rejected: %s; EC1 received %d; steps %d (sent %d, catch-up "
                     "%d), time jumps %d; stale steps per input: %s; frames sent %d",
                     d["frames_seen"], d["frames_used"], rejected, d["tp"]["ec1_received"], s["steps"],
                     s["steps_sent"], s["catchup_steps"], s["time_jumps"], stale, s["frames_sent"])

    def recorded(self) -> dict[str, np.ndarray]:
        """The recorded steps (``record=True``) as columns of a sensor output run table (CONTRACTS.md section 3):
        time_s, the decoded inputs, T_/W_/ttl_ per published component, the status, and meas_T_<id>_c for the rig
        thermocouples that were received. ``can_time_s`` is the step's frame time."""
        n = len(PUBLISHED)
        k = len(self._heads)
        head = np.array(self._heads, dtype=float).reshape(k, len(self._head_names()))
        cols = {name: head[:, j] for j, name in enumerate(self._head_names())}
        T, lev, ttl, tail = self.recorded_outputs()
        if T.shape[0] != k:
            raise RuntimeError(f"recorded {k} step heads but {T.shape[0]} sensor outputs")
        for block, (prefix, suffix) in zip((T, lev, ttl), (("T_", "_c"), ("W_", ""), ("ttl_", "_s"))):
            if prefix == "ttl_":
                block = block.copy()
                block[np.isinf(block)] = np.nan  # CONTRACTS 3: "never" is an empty cell
            for j, c in enumerate(PUBLISHED):
                cols[f"{prefix}{c}{suffix}"] = block[:, j]
        for j, name in enumerate(self._tail_names()):
            cols[name] = tail[:, j]
        if self._meas_seen.any():
            meas = np.full((k, n), np.nan)
            for i, row in self._meas_rows.items():
                meas[i] = row
            for j, name in enumerate(self._meas_names):
                if self._meas_seen[j]:
                    cols[name] = meas[:, j]
        return cols

    # -- time ---------------------------------------------------------------------------------------------------

    def _drives_time(self, msg) -> bool:
        if not msg.is_extended_id or msg.is_error_frame or msg.is_remote_frame:
            return False
        can_id = msg.arbitration_id
        known = self._timing_ids.get(can_id)
        if known is None:
            known = 0 <= can_id <= 0x1FFFFFFF and _wanted_key(can_id) in self._wanted
            if len(self._timing_ids) < 65536:  # random IDs (fuzzing) must not grow it without bound
                self._timing_ids[can_id] = known
        return known

    @property
    def _next_boundary(self) -> float:
        return self._t0 + (self._k + 1) * STEP_S

    def _due(self, ts: float) -> int:
        """Number of boundaries ``t0 + n x STEP_S`` (n > k) at or before ``ts``; exact in the float sums used."""
        t0, k = self._t0, self._k
        n = math.floor((ts - t0) / STEP_S)
        while n > k and t0 + n * STEP_S > ts:
            n -= 1
        while t0 + (n + 1) * STEP_S <= ts:
            n += 1
        return max(n - k, 0)

    def _anchor(self, ts: float, gap_s: float) -> None:
        if self._first_t is None:
            self._first_t = ts
        self._t0 = ts
        self._k = 0
        if self._next_log_t is None:
            self._next_log_t = ts + self.options.counter_log_period_s

    def _time_jump(self, ts: float, direction: str) -> None:
        last = self._t0 + self._k * STEP_S
        gap = ts - last
        self.counters["time_jumps"] += 1
        self.log.warning("frame time jumped %s by %.3f s (from %.6f to %.6f): restarting the step grid, inputs "
                         "dropped, the sensor resumes from its state", direction, gap, last, ts)
        if direction == "backward":
            self._time_offset += last - ts + STEP_S
            self._next_log_t = ts + self.options.counter_log_period_s
        self.latest.clear()
        self._meas_t[:] = -np.inf
        # the sensor sees the gap in the frame time of its next step (SensorInputs.t_s) and propagates over it
        self._anchor(ts, gap)

    def _fresh(self, name: str, t_step: float | None):
        item = self.latest.get(name)
        if item is None:
            return None
        if t_step is None:
            return item[1]
        message = SIGNAL_MESSAGE.get(name, "RIG")
        return item[1] if t_step - item[0] <= self._max_age[message] else None

    def _steps(self, due: int, out: list) -> None:
        for i in range(due):
            self._k += 1
            t_step = self._t0 + self._k * STEP_S
            last = i == due - 1
            if not last:
                self.counters["catchup_steps"] += 1
            frames = self._step(t_step, send=last)
            if last and frames:
                out.extend(frames)
                self.counters["steps_sent"] += 1
                self.counters["frames_sent"] += len(frames)
            if self._next_log_t is not None and t_step >= self._next_log_t:
                self._next_log_t += self.options.counter_log_period_s * (
                    1 + math.floor((t_step - self._next_log_t) / self.options.counter_log_period_s))
                self.log_counters()

    # -- one step -----------------------------------------------------------------------------------------------
    #
    # A step has two halves: _gather (frame side: which inputs are fresh, the reference torque, initialisation,
    # the run-table head) and _apply (sensor side: the sensor's step, status, frames, the recorded outputs). _gather
    # never depends on what _apply computed, so an offline replay can run the halves in two processes
    # (tools/can/replay_log.py) and get the same outputs.

    def _step(self, t_step: float, send: bool = True) -> list:
        req = self._gather(t_step)
        if self._sink is not None:
            self._sink(req)
            return []
        return self._apply(req, send)

    def _gather(self, t_step: float) -> tuple:
        """The frame half of a step: ``(kind, t_step, inputs (SENSOR_INPUTS order, None = not available), reference
        torque, sensor time)``; kind 0 not initialised, 1 initialise then step, 2 step."""
        self.counters["steps"] += 1
        stale = self.counters["stale_steps"]
        latest = self.latest
        vals = []
        for name, max_age in self._input_ages:
            item = latest.get(name)
            if item is None or t_step - item[0] > max_age:
                stale[name] = stale.get(name, 0) + 1
                vals.append(None)
            else:
                vals.append(item[1])
        gear = vals[2]
        if gear is not None:
            if self.options.gear_map is not None:
                gear = self.options.gear_map.get(int(gear))
            if gear is not None and not GEAR_RANGE[0] <= gear <= GEAR_RANGE[1]:
                gear = None
            vals[2] = gear
        if vals[7] is not None:
            vals[7] = abs(vals[7])  # J1939 reports retarder braking negative
        ref = self.decoder.ref_torque_nm
        if ref is None and not self._ref_warned and self._first_t is not None \
                and t_step - self._first_t >= self.options.no_ref_torque_warning_s:
            self._ref_warned = True
            self.log.warning("no EC1 (engine reference torque, SPN 544) received in %.0f s of traffic and no "
                             "[can] engine_reference_torque_nm configured: engine torque is not available, the "
                             "sensor runs degraded", t_step - self._first_t)
        kind = 2
        if not self._initialised:
            oil = vals[3]
            if oil is None and t_step - self._first_t < self.options.init_wait_s - 1e-9:
                self.counters["uninitialised_steps"] += 1
                kind = 0
            else:
                kind = 1
                self._initialised = True
                self.log.info("sensor initialised at frame time %.3f s with oil temperature %s", t_step,
                              "not available" if oil is None else f"{oil:.2f} degC")
        vals = tuple(vals)
        t_s = t_step - self._first_t + self._time_offset
        if self.record:
            nan = math.nan
            pct = self._fresh("engine_torque_pct", t_step)
            self._heads.append((t_s, t_step, *[nan if v is None else v for v in vals],
                                nan if pct is None else pct, nan if ref is None else ref))
            if self._meas_seen.any():
                self._meas_rows[len(self._heads) - 1] = np.where(t_step - self._meas_t <= self._max_age["RIG"],
                                                                 self._meas_v, nan)
        return kind, t_step, vals, ref, t_s

    def _apply(self, req: tuple, send: bool = True) -> list:
        """The sensor half of a step (``req`` from :meth:`_gather`); returns the frames to send."""
        kind, t_step, vals, ref, t_s = req
        if kind == 0:
            return self._not_initialised(t_step, vals, ref, send)
        if kind == 1:
            self.state = self.sensor.initial_state(T_oil_c=vals[3])
        nan = math.nan
        fields = {f: (nan if v is None else float(v)) for f, v in zip(self._input_fields, vals)}
        if self._inputs_have_time:
            fields["t_s"] = t_s
        inputs = self._inputs(**fields)
        self.finish_pending()
        if self._deferred is not None:
            self.state, outputs, self._pending = self._deferred(self.state, inputs)
        else:
            self.state, outputs = self.sensor.step(self.state, inputs)
        T = np.asarray(outputs.T_c, dtype=float)
        lev = np.asarray(outputs.level)
        ttl = np.asarray(outputs.ttl_s, dtype=float)
        status = self._status(outputs.status, vals, ref)
        frames = []
        if self.emit_frames:
            temps = dict(zip(PUBLISHED, T.tolist()))
            levels = dict(zip(PUBLISHED, lev.astype(int).tolist()))
            ttls = dict(zip(PUBLISHED, ttl.tolist()))
            frames = self._encode(t_step, temps, levels, ttls, status, send)
        if self.record:
            rejects = _status_value(outputs.status, "rejects", default=None)
            self._record(T, lev, ttl, status, rejects)
        return frames

    def _status(self, st, vals, ref) -> dict:
        """The GBX_STATUS keys of a step; ``vals``: the inputs given to the sensor (SENSOR_INPUTS order)."""
        if type(st).__name__ == "SensorStatus" and type(st).__module__ == "firmware_model.onboard.sensor":
            # the onboard sensor's own record: the generic lookups below, without their per-field probing
            return {"speed_valid": bool(st.speed_valid), "torque_valid": bool(st.torque_valid),
                    "gear_valid": bool(st.gear_valid), "oil_valid": bool(st.oil_valid),
                    "ref_torque_valid": ref is not None, "degraded_mode": int(st.degraded_mode),
                    "oil_innovation_c": _opt_float(st.oil_innovation_c),
                    "model_oil_temp_c": _opt_float(st.model_oil_temp_c)}
        flags = {
            "speed_valid": vals[0] is not None,
            "torque_valid": vals[1] is not None,
            "gear_valid": vals[2] is not None,
            "oil_valid": vals[3] is not None,
        }
        valid = _status_value(st, "inputs_valid", "valid", default=None)
        if isinstance(valid, Mapping):
            for key in flags:
                for name in (key, key.replace("_valid", "")):
                    if name in valid:
                        flags[key] = bool(valid[name])
        else:
            for key in flags:
                v = _status_value(st, key, default=None)
                if v is not None:
                    flags[key] = bool(v)
        mode = _status_value(st, "degraded_mode", "mode", default=None)
        return {**flags, "ref_torque_valid": ref is not None,
                "degraded_mode": None if mode is None else int(mode),
                "oil_innovation_c": _opt_float(_status_value(st, "oil_innovation_c", "innovation_c")),
                "model_oil_temp_c": _opt_float(_status_value(st, "model_oil_temp_c", "T_oil_model_c"))}

    def _not_initialised(self, t_step: float, vals, ref, send: bool) -> list:
        status = {"speed_valid": vals[0] is not None, "torque_valid": vals[1] is not None,
                  "gear_valid": vals[2] is not None, "oil_valid": False,
                  "ref_torque_valid": ref is not None, "degraded_mode": MODE_NOT_INITIALISED,
                  "oil_innovation_c": None, "model_oil_temp_c": None}
        frames = self._encode(t_step, {}, {}, {}, status, send)
        if self.record:
            n = len(PUBLISHED)
            self._record(np.full(n, np.nan), np.full(n, 3), np.full(n, np.nan), status)
        return frames

    def _encode(self, t_step: float, temps, levels, ttls, status, send: bool) -> list:
        """The step's frames; a catch-up step that is not sent leaves the DM1 schedule untouched."""
        if not self.emit_frames:
            return []
        frames = []
        if self._k % self._out_every == 0:
            frames = self.encoder.encode(temps, levels, ttls, status, timestamp_s=t_step)
        dm1 = self.encoder.encode_dm1(levels, timestamp_s=t_step)
        self._steps_since_dm1 += 1
        payload = bytes(dm1.data)
        if send and (payload != self._last_dm1 or self._steps_since_dm1 >= _DM1_PERIOD_STEPS):
            frames.append(dm1)
            self._last_dm1 = payload
            self._steps_since_dm1 = 0
            self.counters["dm1_sent"] += 1
        return frames

    # -- recording ----------------------------------------------------------------------------------------------

    @staticmethod
    def _head_names() -> list[str]:
        return ["time_s", "can_time_s", *INPUT_COLUMNS]

    def _tail_names(self) -> list[str]:
        return ["degraded", *_TAIL_KEYS, *(f"rejects_{r}" for r in self._reject_names)]

    def _record(self, T, lev, ttl, status, rejects=None) -> None:
        """The sensor half of a recorded row: published temperatures, levels, time to limit and the status tail
        (the head, inputs and rig thermocouples, is recorded by :meth:`_gather`)."""
        nan = math.nan
        mode = status["degraded_mode"]
        tail = [nan if mode is None else float(mode != 0),
                *(nan if status[k] is None else float(status[k]) for k in _TAIL_KEYS)]
        if self._reject_names:
            n_r = len(self._reject_names)
            tail += np.asarray(rejects, dtype=float).reshape(-1)[:n_r].tolist() if rejects is not None \
                else [0.0] * n_r
        self._outs.append((np.array(T, dtype=float), np.array(lev, dtype=float), np.array(ttl, dtype=float),
                           tail))

    def recorded_outputs(self) -> tuple:
        """The sensor half of the recorded rows as arrays: (T (n, 28), level (n, 28), ttl (n, 28), tail (n, m))."""
        n, m = len(PUBLISHED), len(self._tail_names())
        outs = self._outs
        if isinstance(outs, tuple):
            return outs
        k = len(outs)
        return (np.array([r[0] for r in outs], dtype=float).reshape(k, n),
                np.array([r[1] for r in outs], dtype=float).reshape(k, n),
                np.array([r[2] for r in outs], dtype=float).reshape(k, n),
                np.array([r[3] for r in outs], dtype=float).reshape(k, m))


_TAIL_KEYS = ("degraded_mode", *STATUS_FLAGS, "oil_innovation_c", "model_oil_temp_c")


# ---------------------------------------------------------------------------------------------------------------
# live: a python-can bus, a listener that only queues frames, one loop that owns time
# ---------------------------------------------------------------------------------------------------------------

class QueueListener:
    """A python-can listener that only queues frames (the Notifier's thread calls it)."""

    def __init__(self) -> None:
        # queue.Queue, not SimpleQueue: CPython 3.11's SimpleQueue.get(timeout) waits forever when a signal handler
        # that runs inside the wait outlasts the timeout (seen as `run` hanging after SIGTERM on a silent bus in the
        # QEMU VM); Queue waits on a lock whose timed acquire keeps its deadline. ~2 us more per frame.
        self.queue: queue.Queue = queue.Queue()
        self.errors: list[BaseException] = []

    def __call__(self, msg) -> None:
        self.queue.put(msg)

    def on_message_received(self, msg) -> None:
        self.queue.put(msg)

    def on_error(self, exc: BaseException) -> None:
        self.errors.append(exc)

    def stop(self) -> None:
        pass


@dataclass
class ServeResult:
    """What :func:`serve` did. ``step_latency_s``: per sent step, wall time from the receive timestamp of the frame
    that completed the step to the end of sending its frames (meaningful when the bus stamps frames with the wall
    clock, as socketcan, udp_multicast and virtual do; the last 100000 steps)."""
    frames_in: int = 0
    frames_out: int = 0
    send_errors: int = 0
    wall_s: float = 0.0
    cpu_s: float = 0.0
    reason: str = ""
    step_latency_s: list = field(default_factory=list)

    @property
    def cpu_share(self) -> float:
        return self.cpu_s / self.wall_s if self.wall_s > 0 else 0.0

    def latency_ms(self) -> dict:
        """Median, p99 and max of ``step_latency_s`` in ms (empty dict without steps)."""
        if not self.step_latency_s:
            return {}
        a = np.sort(np.asarray(self.step_latency_s)) * 1e3
        return {"median": float(np.median(a)), "p99": float(np.percentile(a, 99)), "max": float(a[-1])}


def serve(bus, service: SensorService, *, stop: threading.Event | None = None, duration_s: float | None = None,
          poll_s: float = 0.05, on_sent: Callable | None = None,
          on_ready: Callable[[], None] | None = None) -> ServeResult:
    """Run ``service`` on ``bus`` until ``stop`` is set or ``duration_s`` of wall time passed.

    A ``can.Notifier`` thread receives and queues frames (:class:`QueueListener`); this loop, in the calling thread,
    takes them in order, feeds the service and sends what it returns. On stop it drains the queue, stops the
    notifier and returns (the caller shuts the bus down). Send errors (a full transmit queue) are counted and logged
    once per 10 s, never fatal. The wall clock is only used for ``duration_s`` and the CPU figure.
    """
    import can
    stop = stop or threading.Event()
    listener = QueueListener()
    result = ServeResult()
    wall0, cpu0 = time.perf_counter(), time.process_time()
    deadline = None if duration_s is None else wall0 + duration_s
    notifier = can.Notifier(bus, [listener], timeout=0.1)
    if on_ready is not None:
        on_ready()
    last_err_log = -math.inf
    q = listener.queue

    latencies = result.step_latency_s

    def handle(msg) -> None:
        nonlocal last_err_log
        result.frames_in += 1
        frames = service.feed(msg)
        if not frames:
            return
        for frame in frames:
            try:
                bus.send(frame)
                result.frames_out += 1
                if on_sent is not None:
                    on_sent(frame)
            except can.CanError as exc:
                result.send_errors += 1
                now = time.perf_counter()
                if now - last_err_log > 10.0:
                    last_err_log = now
                    service.log.warning("cannot send %08X: %s (%d send errors so far)", frame.arbitration_id, exc,
                                        result.send_errors)
        if len(latencies) >= 100_000:
            del latencies[:50_000]
        latencies.append(time.time() - msg.timestamp)
        service.finish_pending()           # the slow part of the step, now that its frames are out

    try:
        while not stop.is_set():
            if deadline is not None and time.perf_counter() >= deadline:
                result.reason = "duration"
                break
            try:
                msg = q.get(timeout=poll_s)
            except queue.Empty:
                if listener.errors:
                    raise listener.errors[0]
                continue
            handle(msg)
        else:
            result.reason = "stop"
    finally:
        notifier.stop(timeout=1.0)
        while True:  # drain what was received before the notifier stopped
            try:
                handle(q.get_nowait())
            except queue.Empty:
                break
        result.wall_s = time.perf_counter() - wall0
        result.cpu_s = time.process_time() - cpu0
    return result
