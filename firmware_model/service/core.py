"""The CAN service core, :class:`SensorService`: J1939 frames in, the sensor stepped on frame time, GBX_* frames out.
Pure of threads, clocks and I/O; the timing model is in the package doc (``firmware_model.service``)."""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Iterable

import numpy as np

from can_dbc.decoder import J1939Decoder, LatestValues, signal_messages
from can_dbc.encoder import OutputEncoder
from can_dbc.errors import ConfigError
from can_dbc.j1939 import ID_MAX, pgn_key
from firmware_model.components import MODE_HOLDING, MODE_NOT_INITIALISED, STEP_S
from firmware_model.errors import InputError, ParameterError
from firmware_model.physics.oil import T_MAX_C as OIL_T_MAX_C
from firmware_model.physics.oil import T_MIN_C as OIL_T_MIN_C
from firmware_model.service.netmgmt import AddressClaim
from firmware_model.service.options import GEAR_RANGE, NOMINAL_PERIOD_S, SENSOR_INPUTS, ServiceOptions, wanted_pgns
from firmware_model.service.plausibility import FINDING_SPNS, RecordCheck, min_torque_nm
from firmware_model.service.protocol import StepSensor, check_sensor, start_state
from firmware_model.service.recorder import StepRecorder
from firmware_model.service.records import GbxStatus, StepInputs, StepKind, StepRequest
from firmware_model.service.trust import TIME_EVENT, Severity, TimeBaseCheck, log_time_glitch, trust_findings

log = logging.getLogger("gearbox_vsensor.can_service")

#: GBX_DM1 is sent at least every this many steps (1 s), and whenever its content changes
DM1_PERIOD_STEPS = 10
#: at most this many CAN ids are remembered as driving time or not (random ids, e.g. fuzzing, must not grow it)
_TIMING_ID_CACHE_MAX = 65536


def _opt_float(x) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


def _new_counters() -> dict:
    """The service's counters at the start of a run."""
    return {
        "steps": 0,
        "steps_sent": 0,
        "catchup_steps": 0,
        "time_jumps": 0,
        "frames_time_glitch": 0,
        "frames_not_timing": 0,
        "frames_sent": 0,
        "dm1_sent": 0,
        "stale_steps": {},
        "uninitialised_steps": 0,
        "mode_steps": {},
        "gear_unmapped_steps": 0,
        "started_without_oil": False,
        "frames_out_of_order": 0,
        "out_of_order_max_s": 0.0,
        "input_rejects": {},
        "oil_frozen_at_c": None,
        "time_base": {"windows_checked": 0, "windows_suspect": 0, "suspect": False, "finding": None},
    }


def _codecs(options: ServiceOptions, published: tuple) -> tuple[J1939Decoder, OutputEncoder]:
    """The decoder and encoder the options describe; their ConfigErrors become ParameterErrors."""
    from can_dbc.dbc import for_components
    from can_dbc.generate import GenerateError

    try:
        database = for_components(tuple(published))  # the gearbox's frames (the GRS905's: the shipped DBC)
    except GenerateError as exc:
        raise ParameterError(f"the gearbox's CAN frames cannot be laid out ({exc})") from None
    try:
        decoder = J1939Decoder(
            expected_sa=options.expected_sa,
            retarder_ref_torque_nm=options.retarder_ref_torque_nm,
            configured_ref_torque_nm=options.configured_ref_torque_nm,
            rig=options.rig,
            database=database,
        )
        encoder = OutputEncoder(options.sensor_source_address, database=database)
    except ConfigError as exc:
        raise ParameterError(f"can: {exc}") from None
    if tuple(encoder.components) != tuple(published):
        raise ParameterError(
            "the DBC's per-component signals (ComponentId) are not the sensor's published components "
            "(its gearbox description's published.order)"
        )
    return decoder, encoder


class SensorService:
    """Frames in, sensor stepped on frame time, frames out; see the package doc.

    ``sensor``: a :class:`~firmware_model.service.protocol.StepSensor` (the onboard ``VirtualSensor``);
    ``options``: :class:`ServiceOptions`; ``record``: keep one row per step for :meth:`recorded` (replay);
    ``emit_frames=False`` skips encoding the output frames (an offline replay to a run table that nobody sends: the
    steps, inputs and outputs are the same, ``feed`` returns nothing); ``logger``: where counters and events go.
    """

    def __init__(
        self,
        sensor: StepSensor,
        options: ServiceOptions | None = None,
        *,
        record: bool = False,
        emit_frames: bool = True,
        logger: logging.Logger | None = None,
    ) -> None:
        check_sensor(sensor)
        self.sensor = sensor
        self.options = options or ServiceOptions()
        #: the published components' ids (the sensor's, from its gearbox description): the outputs' order
        self.published = tuple(sensor.published)
        self.decoder, self.encoder = _codecs(self.options, self.published)
        self.log = logger or log
        self.record = record
        self.emit_frames = emit_frames
        #: the latest value and frame time of every decoded signal
        self.latest = LatestValues()
        self.counters: dict = _new_counters()
        self._time_base = TimeBaseCheck(self.options.time_base_window_s, self.options.time_base_windows)
        self._findings_logged: dict[tuple, int] = {}
        self._wanted = frozenset(wanted_pgns().values())
        self._timing_ids: dict[int, bool] = {}
        self._max_age_s = {m: self.options.stale_factor * p for m, p in NOMINAL_PERIOD_S.items()}
        messages = signal_messages()
        self._input_ages_s = tuple((signal, self._max_age_s[messages[signal]]) for _, signal in SENSOR_INPUTS)
        self._init_time()
        self._prev_frame_t_s = -math.inf  # the previous frame's (finite) time: frames out of time order
        # the sensor: a step leaves its slow time-to-limit refresh to finish_pending(), which the live loop runs
        # after the step's frames are sent and every step runs first (so outputs never depend on when)
        self.state = None
        #: a saved state to start from: a firmware_model.service.persist.Restore (snapshot, wall time off [s],
        #: clean stop), or None
        self.restore: tuple | None = None
        self._pending = None
        self._initialised = False
        self._last_dm1: bytes | None = None
        self._rejects_prev: np.ndarray | None = None  # the sensor's cumulative reject counters after the last step
        self._oil_frozen_j = (
            list(getattr(sensor, "reject_reasons", ())).index("oil_frozen")
            if "oil_frozen" in getattr(sensor, "reject_reasons", ())
            else None
        )
        self._last_dm1_frame = None
        self._steps_since_dm1 = 0
        #: J1939 address claim and requests (live runs: options.address_claim); None: not a network node
        self.netmgmt = (
            AddressClaim(self.options.j1939_name, self.options.sensor_source_address, self.log)
            if self.options.address_claim
            else None
        )
        self._claim_started = False
        self._meas_names = tuple(f"meas_T_{c}_c" for c in self.published)
        self._recorder = StepRecorder(self.published, self._meas_names, self.sensor.reject_reasons)
        self._names_checked = 0
        self._rig_seen = False
        #: the whole-record rules of a live run (firmware_model.service.plausibility; a replay judges its table)
        self.record_check = (
            None if record else RecordCheck(min_torque_nm(sensor), getattr(sensor, "reject_reasons", ()))
        )

    def _init_time(self) -> None:
        #: a timing frame far ahead of the step grid, held until the next one says whether the frame time jumped
        #: (the next is as far ahead: a logger pause) or this one frame's time stamp is a glitch (the next is back)
        self._ahead = None
        self._t0_s: float | None = None  # grid anchor (frame time)
        self._k = 0  # steps done since the anchor
        self._first_t_s: float | None = None  # frame time of the very first anchor (run-table time 0)
        self._time_offset_s = 0.0  # run-table time added after a backward restart
        self._next_log_t_s: float | None = None
        self._ref_warned = False

    # -- public -------------------------------------------------------------------------------------------------

    def feed(self, msg) -> list:
        """Use one received frame; returns the frames to send now (possibly none). Never raises on frame content."""
        out: list = []
        timestamp_s = msg.timestamp
        self._check_order(timestamp_s)
        if self.netmgmt is not None:
            out.extend(self._network_management(msg))
        if self._drives_time(msg):
            if self._ahead is not None:
                self._settle_ahead(timestamp_s)
            if self._t0_s is None:
                self._anchor(timestamp_s)
            elif timestamp_s >= self._next_boundary_s:
                due = self._due(timestamp_s)
                if due > self.options.max_catchup_steps:
                    self._ahead = msg  # decoded once the next timing frame settles what its time means
                    return out
                else:
                    n0 = len(out)
                    self._steps(due, out)
                    if self.netmgmt is not None and not self.netmgmt.can_transmit(timestamp_s):
                        held = len(out) - n0  # not sent: not counted as sent
                        self.counters["frames_held_no_address"] = self.counters.get("frames_held_no_address", 0) + held
                        self.counters["frames_sent"] -= held
                        del out[n0:]
            elif timestamp_s < self._next_boundary_s - STEP_S - self.options.backward_tolerance_s:
                self._time_jump(timestamp_s, "backward")
        else:
            self.counters["frames_not_timing"] += 1
        self.decoder.feed_into(msg, self.latest)
        return out

    def _settle_ahead(self, next_s: float) -> None:
        """The timing frame held far ahead (``self._ahead``), settled by the next one's time ``next_s``: as far ahead
        or more (within the step and backward_tolerance_s), the frame time jumped there (a logger pause); back
        near the grid, the held frame's time stamp alone was wrong: a glitch, counted and logged, its data used,
        and the grid goes on (a jump there shifted every later step's time and held the inputs over the gap). The
        whole-log path decides the same (firmware_model.service.columnar.step_grid)."""
        ahead, self._ahead = self._ahead, None
        if next_s >= ahead.timestamp - STEP_S - self.options.backward_tolerance_s:
            self._time_jump(ahead.timestamp, "forward")
        else:
            self._time_glitch(ahead.timestamp, next_s)
        self.decoder.feed_into(ahead, self.latest)

    def end_of_log(self) -> None:
        """At the end of a log: a timing frame still held far ahead (its log's last) is a glitch, its data used."""
        if self._ahead is not None:
            ahead, self._ahead = self._ahead, None
            self._time_glitch(ahead.timestamp, None)
            self.decoder.feed_into(ahead, self.latest)

    def _time_glitch(self, glitch_s: float, next_s: float | None) -> None:
        self.counters["frames_time_glitch"] += 1
        log_time_glitch(self.log, glitch_s, self.frame_time_s, next_s, self.counters["frames_time_glitch"])

    def _check_order(self, timestamp_s: float) -> None:
        """Count a frame earlier than the one before it by at most the step plus ``backward_tolerance_s`` (a log
        merged from several buffers; a timing frame further back than that behind the last step is a time jump):
        the decoder takes frames in file order, so its older value replaces a newer one (trust.OrderFinding)."""
        if not math.isfinite(timestamp_s):
            return
        back_s = self._prev_frame_t_s - timestamp_s
        if 0.0 < back_s <= STEP_S + self.options.backward_tolerance_s:
            self.counters["frames_out_of_order"] += 1
            self.counters["out_of_order_max_s"] = max(self.counters["out_of_order_max_s"], back_s)
        self._prev_frame_t_s = timestamp_s

    def _network_management(self, msg) -> list:
        """J1939-81/-21 (firmware_model.service.netmgmt): the claim at the first frame, replies to requests and to
        another node's claim; a new address (arbitrary-address capable) re-addresses the output frames."""
        out = []
        if not self._claim_started:
            self._claim_started = True
            out.extend(self.netmgmt.start(msg.timestamp))
        out.extend(self.netmgmt.on_frame(msg, lambda: self._last_dm1_frame))
        address = self.netmgmt.address
        if address is not None and address != self.encoder.source_address:
            self.encoder = OutputEncoder(address)
        return out

    def feed_all(self, msgs: Iterable) -> list:
        out: list = []
        for msg in msgs:
            out.extend(self.feed(msg))
        return out

    def finish_pending(self) -> None:
        """Run the work the last step left for after its frames were sent (the sensor's time-to-limit refresh).
        Idempotent; the next step runs it anyway, so calling it or not never changes an output."""
        if self._pending is not None:
            job, self._pending = self._pending, None
            self.state = self.sensor.refresh_ttl(self.state, job)

    @property
    def frame_time_s(self) -> float | None:
        """Frame time of the last step boundary (None before the first frame)."""
        return None if self._t0_s is None else self._t0_s + self._k * STEP_S

    def all_counters(self) -> dict:
        """The decoder's counters and the service's, in one dict."""
        return {"decoder": self.decoder.counters, "service": self.counters}

    def log_counters(self, level: int = logging.INFO) -> None:
        d = self.decoder.counters
        s = self.counters
        rejected = ", ".join(f"{k} {v}" for k, v in sorted(d["rejected"].items())) or "none"
        stale = ", ".join(f"{k} {v}" for k, v in sorted(s["stale_steps"].items())) or "none"
        self.log.log(
            level,
            "frames seen %d, used %d, rejected: %s; EC1 received %d, RC %d; steps %d (sent %d, "
            "catch-up %d), time jumps %d; stale steps per input: %s; frames sent %d",
            d["frames_seen"],
            d["frames_used"],
            rejected,
            d["tp"]["ec1_received"],
            d["tp"].get("rc_received", 0),
            s["steps"],
            s["steps_sent"],
            s["catchup_steps"],
            s["time_jumps"],
            stale,
            s["frames_sent"],
        )

    def findings(self) -> list:
        """What the run must not keep quiet about (``firmware_model.service.trust.trust_findings``): a suspect time
        base, inputs from unexpected source addresses, a large degraded share; most severe first."""
        oil_model = getattr(getattr(self.sensor, "options", None), "oil_mode", "measured") == "model"
        found = trust_findings(
            self.all_counters(),
            self.decoder.expected_sa,
            self.options.expected_sa,
            oil_model,
            self.options.stale_factor,
            self.options.source_address_keys or None,
        )
        if self.record_check is not None and self.record_check.findings:
            found = sorted(found + self.record_check.findings, key=lambda f: -f.severity)
        return found

    def log_findings(self, only_new: bool = False) -> None:
        """Log the findings (WARNING, or INFO for notes); ``only_new``: only those not logged yet, or more severe
        than when they were."""
        for f in self.findings():
            key = (f.kind, getattr(f, "message", ""), getattr(f, "source", -1), getattr(f, "column", ""))
            if only_new and self._findings_logged.get(key, -1) >= f.severity:
                continue
            self._findings_logged[key] = f.severity
            self.log.log(logging.WARNING if f.severity >= Severity.WARNING else logging.INFO, "%s", f.sentence)

    def recorded(self) -> dict[str, np.ndarray]:
        """The recorded steps (``record=True``) as columns of a sensor output run table (tools/runtable.py):
        time_s, the decoded inputs, T_/W_/ttl_ per published component, the status, and meas_T_<id>_c for the rig
        thermocouples that were received. ``can_time_s`` is the step's frame time."""
        values = self.latest.value
        return self._recorder.columns(tuple(name in values for name in self._meas_names))

    # -- time ---------------------------------------------------------------------------------------------------

    def _drives_time(self, msg) -> bool:
        """Only data frames of the PGNs the service listens to, with a finite frame time, move time (not a CAN FD
        frame: the decoder rejects it, and it set the step grid's start before a classic frame could)."""
        if (
            not msg.is_extended_id
            or msg.is_error_frame
            or msg.is_remote_frame
            or getattr(msg, "is_fd", False)
            or not math.isfinite(msg.timestamp)
        ):
            return False
        can_id = msg.arbitration_id
        known = self._timing_ids.get(can_id)
        if known is None:
            known = 0 <= can_id <= ID_MAX and pgn_key(can_id) in self._wanted
            if len(self._timing_ids) < _TIMING_ID_CACHE_MAX:
                self._timing_ids[can_id] = known
        return known

    @property
    def _next_boundary_s(self) -> float:
        return self._t0_s + (self._k + 1) * STEP_S

    def _due(self, timestamp_s: float) -> int:
        """Number of boundaries ``t0 + n x STEP_S`` (n > k) at or before the frame; exact in the float sums used."""
        t0_s, k = self._t0_s, self._k
        n = math.floor((timestamp_s - t0_s) / STEP_S)
        while n > k and t0_s + n * STEP_S > timestamp_s:
            n -= 1
        while t0_s + (n + 1) * STEP_S <= timestamp_s:
            n += 1
        return max(n - k, 0)

    def _anchor(self, timestamp_s: float) -> None:
        if self._first_t_s is None:
            self._first_t_s = timestamp_s
        self._t0_s = timestamp_s
        self._k = 0
        self._time_base.restart(timestamp_s, self.decoder.counters["arrivals"])
        if self._next_log_t_s is None:
            self._next_log_t_s = timestamp_s + self.options.counter_log_period_s

    def _time_jump(self, timestamp_s: float, direction: str) -> None:
        last_s = self._t0_s + self._k * STEP_S
        self.counters["time_jumps"] += 1
        self.log.warning(
            "frame time jumped %s by %.3f s (from %.6f to %.6f): restarting the step grid, inputs "
            "dropped, the sensor resumes from its state",
            direction,
            abs(timestamp_s - last_s),
            last_s,
            timestamp_s,
            extra={TIME_EVENT: "jump"},
        )
        if direction == "backward":
            # the frame that went back stands where the last step stood: the next step comes STEP_S after it, as
            # on a continuous clock (a STEP_S more here showed the sensor a 0.2 s step, counted as a forward jump)
            self._time_offset_s += last_s - timestamp_s
            self._next_log_t_s = timestamp_s + self.options.counter_log_period_s
        self.latest.forget()
        # the sensor sees the gap in the frame time of its next step (Inputs.t_s) and propagates over it
        self._anchor(timestamp_s)
        if direction == "forward":
            self._propagate_ahead()

    def _propagate_ahead(self) -> None:
        """Let the sensor propagate its state over a forward gap now, at the first frame after it, rather than in the
        next step (VirtualSensor.prepare_jump; a sensor without it does it in the step): the first output after a bus
        outage then waits for one step period, not for a step period plus the propagation. The step's outputs are the
        same bits either way."""
        prepare = getattr(self.sensor, "prepare_jump", None)
        if prepare is None or not self._initialised or self.state is None:
            return
        self.finish_pending()
        prepare(self.state, self._run_time_s(self._t0_s + 1 * STEP_S))

    def _run_time_s(self, t_step_s: float) -> float:
        """The run-table time of a step boundary (the sensor's Inputs.t_s)."""
        return t_step_s - self._first_t_s + self._time_offset_s

    def _steps(self, due: int, out: list) -> None:
        for i in range(due):
            self._k += 1
            t_step_s = self._t0_s + self._k * STEP_S
            last = i == due - 1
            if not last:
                self.counters["catchup_steps"] += 1
            frames = self._step(t_step_s, send=last)
            if last and frames:
                out.extend(frames)
                self.counters["steps_sent"] += 1
                self.counters["frames_sent"] += len(frames)
            self._check_time_base(t_step_s)
            self._check_record()
            if self._next_log_t_s is not None and t_step_s >= self._next_log_t_s:
                period_s = self.options.counter_log_period_s
                self._next_log_t_s += period_s * (1 + math.floor((t_step_s - self._next_log_t_s) / period_s))
                self.log_counters()
                if self.options.log_findings:
                    self.log_findings(only_new=True)

    def _check_record(self) -> None:
        """Judge the whole record when due (after the first minute, then every minute): the findings go into the
        counters (the health file's ``findings``), are logged once, and name their input in DM1."""
        check = self.record_check
        if check is None or check.update() is None:
            return
        self.counters["record_findings"] = [
            {"kind": f.kind, "severity": f.severity.name.lower(), "sentence": f.sentence} for f in check.findings
        ]
        if self.options.log_findings:
            self.log_findings(only_new=True)

    def _check_time_base(self, t_step_s: float) -> None:
        """Close the time-base check's window when due (firmware_model.service.trust); log when it turns."""
        check = self._time_base
        event = check.update(t_step_s, self.decoder.counters["arrivals"])
        tb = self.counters["time_base"]
        tb.update(windows_checked=check.windows_checked, windows_suspect=check.windows_suspect, suspect=check.suspect)
        if event is None:
            return
        if event == "cleared":
            if self.options.log_findings:
                self.log.info(
                    "time base plausible again at frame time %.3f s: the input messages arrive at their J1939 periods",
                    t_step_s,
                )
            return
        if tb["finding"] is None:
            tb["finding"] = dataclasses.asdict(event)
            tb["sentence"] = event.sentence  # (a property: not in the dict) for the health file
        if self.options.log_findings:
            self.log.warning("%s", event.sentence)

    # -- one step -----------------------------------------------------------------------------------------------
    #
    # A step has two halves: _gather (frame side: which inputs are fresh, the reference torque, initialisation,
    # the run-table head) and _apply (sensor side: the sensor's step, status, frames, the recorded outputs). _gather
    # never depends on what _apply computed (the whole-log path, firmware_model.service.columnar, runs all the
    # frame halves first and the sensor halves over the whole table).

    def _step(self, t_step_s: float, send: bool = True) -> list:
        return self._apply(self._gather(t_step_s), send)

    def _gather(self, t_step_s: float) -> StepRequest:
        """The frame half of a step."""
        self.counters["steps"] += 1
        inputs = self._fresh_inputs(t_step_s)
        ref_torque_nm = self.decoder.ref_torque_nm
        if ref_torque_nm is None:
            self._warn_no_ref_torque(t_step_s)
        kind = StepKind.STEP if self._initialised else self._initialisation(t_step_s, inputs.oil_temp_c)
        t_s = self._run_time_s(t_step_s)
        if self.record:
            self._record_head(t_s, t_step_s, inputs, ref_torque_nm)
        return StepRequest(kind, t_step_s, inputs, ref_torque_nm, t_s, self._time_base.suspect)

    def _fresh_inputs(self, t_step_s: float) -> StepInputs:
        """The sensor's inputs at a boundary: the latest values not older than their staleness limit (counted as
        stale otherwise), the gear mapped to the model's, the retarder torque as a magnitude."""
        stale = self.counters["stale_steps"]
        times, values = self.latest.time_s, self.latest.value
        fresh = []
        for name, max_age_s in self._input_ages_s:
            t_s = times.get(name)
            if t_s is None or t_step_s - t_s > max_age_s:
                stale[name] = stale.get(name, 0) + 1
                fresh.append(None)
            else:
                fresh.append(values[name])
        inputs = StepInputs._make(fresh)
        retarder_nm = inputs.retarder_torque_nm
        gear = self._model_gear(inputs.gear)
        if gear is None and inputs.gear is not None:  # a gear the map or the model's range leaves out
            self.counters["gear_unmapped_steps"] += 1
        return inputs._replace(
            gear=gear,  # J1939 reports retarder braking negative
            retarder_torque_nm=None if retarder_nm is None else abs(retarder_nm),
        )

    def _model_gear(self, gear):
        """The J1939 gear number as a seed Table 1 gear (``gear_map``), None outside the model's range."""
        if gear is None:
            return None
        if self.options.gear_map is not None:
            gear = self.options.gear_map.get(int(gear))
        if gear is not None and not GEAR_RANGE[0] <= gear <= GEAR_RANGE[1]:
            return None
        return gear

    def _warn_no_ref_torque(self, t_step_s: float) -> None:
        if (
            not self._ref_warned
            and self._first_t_s is not None
            and t_step_s - self._first_t_s >= self.options.no_ref_torque_warning_s
        ):
            self._ref_warned = True
            self.log.warning(
                "no EC1 (engine reference torque, SPN 544) received in %.0f s of traffic and no "
                "[can] engine_reference_torque_nm configured: engine torque is not available, the "
                "sensor runs degraded",
                t_step_s - self._first_t_s,
            )

    def _initialisation(self, t_step_s: float, oil_temp_c: float | None) -> StepKind:
        """Before the first step: wait up to ``init_wait_s`` for a plausible measured oil temperature (one outside
        the oil model's range is no start: VirtualSensor.initial_state)."""
        plausible = oil_temp_c is not None and OIL_T_MIN_C <= oil_temp_c <= OIL_T_MAX_C
        if not plausible and t_step_s - self._first_t_s < self.options.init_wait_s - 1e-9:
            self.counters["uninitialised_steps"] += 1
            return StepKind.NOT_INITIALISED
        self._initialised = True
        self.counters["started_without_oil"] = not plausible and self.restore is None  # (here: the frame half)
        self.log.info(
            "sensor initialised at frame time %.3f s with oil temperature %s",
            t_step_s,
            "not available" if oil_temp_c is None else f"{oil_temp_c:.2f} degC",
        )
        return StepKind.INITIALISE

    def _record_head(self, t_s: float, t_step_s: float, inputs: StepInputs, ref_torque_nm: float | None) -> None:
        nan = math.nan
        pct = self._fresh("engine_torque_pct", t_step_s)
        row = (
            t_s,
            t_step_s,
            *[nan if v is None else v for v in inputs],
            nan if pct is None else pct,
            nan if ref_torque_nm is None else ref_torque_nm,
        )
        self._recorder.add_head(row, self._rig_row(t_step_s) if self._rig_values_seen() else None)

    def _fresh(self, name: str, t_step_s: float):
        """The latest value of ``name`` if still fresh at ``t_step_s``, else None."""
        t_s = self.latest.time_s.get(name)
        if t_s is None:
            return None
        max_age_s = self._max_age_s[signal_messages().get(name, "RIG")]
        return self.latest.value[name] if t_step_s - t_s <= max_age_s else None

    def _rig_values_seen(self) -> bool:
        """True once any rig thermocouple was decoded (looked up again only when a new signal name appears)."""
        values = self.latest.value
        if len(values) != self._names_checked:
            self._names_checked = len(values)
            self._rig_seen = any(name in values for name in self._meas_names)
        return self._rig_seen

    def _rig_row(self, t_step_s: float) -> np.ndarray:
        times, values = self.latest.time_s, self.latest.value
        max_age_s = self._max_age_s["RIG"]
        return np.array(
            [
                values[name] if t_step_s - times.get(name, -math.inf) <= max_age_s else math.nan
                for name in self._meas_names
            ]
        )

    def _apply(self, req: StepRequest, send: bool = True) -> list:
        """The sensor half of a step (``req`` from :meth:`_gather`); returns the frames to send."""
        if req.kind == StepKind.NOT_INITIALISED:
            return self._not_initialised(req, send)
        if req.kind == StepKind.INITIALISE:
            self.state = self._initial_state(req.inputs.oil_temp_c, req.inputs.ambient_temp_c)
            start = getattr(self.state, "rejects", None)
            self._rejects_prev = None if start is None else np.array(start, dtype=np.int64).reshape(-1)
        nan = math.nan
        fields = {f: (nan if v is None else float(v)) for f, v in zip(StepInputs._fields, req.inputs)}
        inputs = self.sensor.Inputs(**fields, t_s=req.t_s)
        self.finish_pending()
        self.state, outputs, self._pending = self.sensor.step_deferred(self.state, inputs)
        self._count_rejects(outputs.status.rejects, fields["oil_temp_c"])
        T_c = np.asarray(outputs.T_c, dtype=float)
        level = np.asarray(outputs.level)
        ttl_s = np.asarray(outputs.ttl_s, dtype=float)
        status = self._status(outputs.status, req.ref_torque_nm)
        self._count_mode(status.degraded_mode)
        frames = []
        if self.emit_frames:
            frames = self._encode(
                req.t_step_s,
                dict(zip(self.published, T_c.tolist())),
                dict(zip(self.published, level.astype(int).tolist())),
                dict(zip(self.published, ttl_s.tolist())),
                status,
                send,
                req.time_base_suspect,
            )
        if self.record:
            self._recorder.add_outputs(T_c, level, ttl_s, status, outputs.status.rejects)
        if self.record_check is not None:
            self.record_check.add(
                fields["oil_temp_c"],
                fields["speed_rpm"],
                fields["torque_nm"],
                fields["gear"],
                getattr(outputs.status, "rejects", None),
            )
        return frames

    @staticmethod
    def _status(st, ref_torque_nm: float | None) -> GbxStatus:
        """The GBX_STATUS content of a step from the sensor's status record."""
        return GbxStatus(
            degraded_mode=int(st.degraded_mode),
            speed_valid=bool(st.speed_valid),
            torque_valid=bool(st.torque_valid),
            gear_valid=bool(st.gear_valid),
            oil_valid=bool(st.oil_valid),
            ref_torque_valid=ref_torque_nm is not None,
            oil_innovation_c=_opt_float(st.oil_innovation_c),
            model_oil_temp_c=_opt_float(st.model_oil_temp_c),
        )

    def _initial_state(self, oil_temp_c, ambient_temp_c):
        """The first state: the saved one (``restore`` = (snapshot, elapsed wall time[, clean stop]),
        firmware_model.service.persist.Restore) propagated over the time off and reconciled with the oil reading,
        else a cold start from the oil (no oil reading: from the ambient reading). A state saved while stepping, not
        at a clean stop (the service died while the truck drove), has its inputs held first, as over a forward time
        jump (at most ``time_jump_hold_s``), then cools with the engine off."""
        restore, self.restore = self.restore, None
        if restore is not None:
            snapshot, elapsed_s = restore[0], restore[1]
            clean = bool(getattr(restore, "clean_stop", True))
            try:
                kw = {} if clean else {"running_s": elapsed_s}
                state = self.sensor.initial_state(T_oil_c=oil_temp_c, snapshot=snapshot, elapsed_s=elapsed_s, **kw)
                self.counters["state_restored"] = True
                self.log.info(
                    "sensor state restored, %s for %.0f s off",
                    "cooled" if clean else "saved while stepping (no clean stop): inputs held, then cooled,",
                    elapsed_s,
                )
                return state
            except (InputError, ValueError, KeyError, TypeError) as exc:
                self.counters["state_cold_start"] = str(exc)
                self.log.warning("saved state not usable (%s): cold start from the oil temperature", exc)
        return start_state(self.sensor, oil_temp_c, ambient_temp_c)

    def _not_initialised(self, req: StepRequest, send: bool) -> list:
        inputs = req.inputs
        status = GbxStatus(
            degraded_mode=MODE_NOT_INITIALISED,
            speed_valid=inputs.speed_rpm is not None,
            torque_valid=inputs.torque_nm is not None,
            gear_valid=inputs.gear is not None,
            oil_valid=False,
            ref_torque_valid=req.ref_torque_nm is not None,
            oil_innovation_c=None,
            model_oil_temp_c=None,
        )
        self._count_mode(MODE_NOT_INITIALISED)
        frames = self._encode(req.t_step_s, {}, {}, {}, status, send, req.time_base_suspect)
        if self.record:
            n = len(self.published)
            self._recorder.add_outputs(np.full(n, np.nan), np.full(n, 3), np.full(n, np.nan), status)
        return frames

    def _count_rejects(self, rejects, oil_c: float) -> None:
        """The sensor's input checks of this run (counters ``input_rejects``, ``oil_frozen_at_c``) from its cumulative
        reject counters after a step, counted from those of the state it started from (a restored state carries an
        earlier run's)."""
        now = np.asarray(rejects).reshape(-1)
        prev = self._rejects_prev if self._rejects_prev is not None else np.zeros_like(now)
        if not np.array_equal(now, prev):
            counts = self.counters["input_rejects"]
            reasons = self.sensor.reject_reasons
            for j in np.flatnonzero(now != prev):
                counts[reasons[j]] = counts.get(reasons[j], 0) + int(now[j] - prev[j])
            if self._oil_frozen_j is not None and now[self._oil_frozen_j] > prev[self._oil_frozen_j]:
                self.counters["oil_frozen_at_c"] = float(oil_c)
        self._rejects_prev = now.copy()

    def _count_mode(self, mode: int | None) -> None:
        counts = self.counters["mode_steps"]
        counts[mode] = counts.get(mode, 0) + 1
        self.counters["mode_now"] = mode

    def _encode(
        self,
        t_step_s: float,
        temps_c: dict,
        levels: dict,
        ttl_s: dict,
        status: GbxStatus,
        send: bool,
        time_base_suspect: bool = False,
    ) -> list:
        """The step's frames; a catch-up step that is not sent leaves the DM1 schedule untouched. GBX_STATUS
        TimeBaseSuspect is 1 while the time base is suspect, else 3 ("no finding"; never 0: a rate check cannot
        prove a time base right)."""
        if not self.emit_frames:
            return []
        frames = []
        if self._k % self.options.output_every_steps == 0:
            st = status._asdict()
            if time_base_suspect:
                st["time_base_suspect"] = True
            frames = self.encoder.encode(temps_c, levels, ttl_s, st, timestamp_s=t_step_s)
        dm1 = self.encoder.encode_dm1(
            levels,
            missing_spn=_missing_input_spn(status, levels),
            timestamp_s=t_step_s,
            implausible_spn=self._implausible_spn(),
        )
        self._last_dm1_frame = dm1
        self._steps_since_dm1 += 1
        payload = bytes(dm1.data)
        if send and (payload != self._last_dm1 or self._steps_since_dm1 >= DM1_PERIOD_STEPS):
            frames.append(dm1)
            self._last_dm1 = payload
            self._steps_since_dm1 = 0
            self.counters["dm1_sent"] += 1
        return frames

    def _implausible_spn(self) -> int | None:
        """The SPN DM1 names for the most severe whole-record finding (FINDING_SPNS), or None."""
        check = self.record_check
        return FINDING_SPNS.get(check.findings[0].spn_key) if check is not None and check.findings else None


#: the J1939 SPN of each drive input, in the order a missing one is named in DM1 (engine speed, actual engine
#: percent torque, or the reference torque without which it has no Nm, current gear)
_DRIVE_INPUT_SPNS = (("speed_valid", 190), ("ref_torque_valid", 544), ("torque_valid", 513), ("gear_valid", 523))


def _missing_input_spn(status: GbxStatus, levels: dict) -> int | None:
    """The SPN DM1 names while the sensor holds its inputs (degraded mode 2) and no warning level can be evaluated:
    the first drive input missing (``can_dbc.encoder.OutputEncoder.encode_dm1``); None otherwise."""
    if status.degraded_mode != MODE_HOLDING or any(v not in (None, 3) for v in levels.values()):
        return None
    for key, spn in _DRIVE_INPUT_SPNS:
        if not getattr(status, key):
            return spn
    return None
