"""Whether the CAN service's outputs can be trusted: what a replay or a live run must say out loud instead of
publishing wrong numbers in silence (docs/can.md "Trust findings").

Three findings, each a typed record with a :class:`Severity` and one sentence (``.sentence``):

- :class:`TimeBaseFinding`: the input messages keep arriving several times faster (or slower) than their J1939
  periods *in frame time*, so the service's clock (frame time) is not the vehicle's: typically a bus replayed
  faster than real time whose frames are stamped on arrival (socketcan, udp_multicast). Found by
  :class:`TimeBaseCheck`, which the service runs at its step boundaries.
- :class:`ForeignSourceFinding`: frames of a message the sensor uses, carrying data, came from another source
  address than the one configured (``[can] *_source_address`` or ``[can.source_address]``, else the DBC's), and
  none from the configured one: almost always a wrong address in the config; it names the key that fixes it
  without moving another input.
- :class:`DegradedFinding`: the sensor ran degraded (``degraded_mode`` not 0) on a large share of its steps.
- :class:`MillisecondsFinding` (a whole log, :func:`milliseconds_finding`): the input messages arrived about 1000
  times more slowly than their J1939 periods over the whole log: its time stamps are milliseconds.

:func:`trust_findings` derives them from the service's counters (``SensorService.all_counters()``);
:func:`degraded_finding` also serves a run-table replay, which has no CAN counters. The thresholds are the constants
below; ``gearbox-vsensor replay`` exits 3 when a finding is :attr:`Severity.UNTRUSTED` (docs/interfaces.md 7.2).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

from can_dbc.decoder import EC1_KEY, RC_KEY, signal_messages
from can_dbc.j1939 import EC1_PGN, RC_PGN
from firmware_model.components import STEP_S
from firmware_model.service.degraded import (  # noqa: F401 (the degraded-share finding is re-exported here)
    DEGRADED_UNTRUSTED_SHARE,
    DEGRADED_WARN_SHARE,
    INPUT_NAMES,
    DegradedFinding,
    Severity,
    degraded_finding,
    pct,
    untrusted,
)
from firmware_model.service.options import (
    NOMINAL_PERIOD_S,
    SOURCE_ADDRESS_KEYS,
    SOURCE_ADDRESS_TABLE,
    STALE_FACTOR_MAX,
    TIME_BASE_WINDOW_S,
    TIME_BASE_WINDOWS,
    wanted_pgns,
)

#: the transmission periods a real J1939 bus uses for each input message, (fastest, slowest) [s]: EEC1 is engine
#: speed dependent (J1939-71: 10-20 ms); CCVS1 is 100 ms in J1939 but 1 s on some trucks and in synthesized logs;
#: ERC1 50-100 ms. The slowest is the service's staleness period (``NOMINAL_PERIOD_S``, checked by a test).
PERIOD_RANGE_S = {
    "EEC1": (0.01, 0.02),
    "ETC2": (0.1, 0.1),
    "TRF1": (1.0, 1.0),
    "ET1": (1.0, 1.0),
    "AMB": (1.0, 1.0),
    "CCVS1": (0.1, 1.0),
    "ERC1": (0.05, 0.1),
}
#: the time base is suspect when the messages agree on arriving at least this many times faster (or slower) than
#: their periods ...
TIME_BASE_FACTOR = 3.0
#: ... over TIME_BASE_WINDOWS (3) consecutive windows of TIME_BASE_WINDOW_S (10 s) of frame time (defaults of
#: ServiceOptions; 30 s: a burst of buffered frames, a gap or the jitter of one window does not make it) ...
#: ... counting only the messages with at least this many frames in a window (a rate needs a few frames), each
#: allowed this much error either way (jitter, a frame more or less at the window's edges)
TIME_BASE_MIN_FRAMES = 5
TIME_BASE_TOLERANCE = 1.3
#: frames with data from one foreign source address before it is a finding (a stray frame of a fuzzer is not)
FOREIGN_MIN_FRAMES = 10
#: the signals whose absence degrades the sensor (speed, torque, gear, oil, reference torque): a message that
#: carries one is primary; the others (ambient, coolant, vehicle speed, retarder) have defaults
PRIMARY_SIGNALS = ("engine_speed_rpm", "engine_torque_pct", "gear", "oil_temp_c", "engine_ref_torque_nm")
#: the likely cause of a suspect time base, by direction
TIME_BASE_CAUSES = {
    "faster": "the bus is replayed faster than real time, and frames are stamped on arrival",
    "slower": "the bus is replayed slower than real time (or its frames are held back), and frames "
    "are stamped on arrival",
}


@dataclass(frozen=True)
class TimeBaseFinding:
    """The frames of the input messages arrived about ``ratio`` times ``direction`` ("faster"/"slower") than their
    J1939 periods in frame time, over ``windows`` windows of ``window_s``; ``periods_s``: message -> mean period
    seen in the window that raised it."""

    kind: ClassVar[str] = "time_base"
    direction: str
    ratio: float
    windows: int
    window_s: float
    periods_s: dict = field(default_factory=dict)

    @property
    def severity(self) -> Severity:
        return Severity.UNTRUSTED

    @property
    def sentence(self) -> str:
        seen = _periods_seen(self.periods_s)
        clock = "slow" if self.direction == "faster" else "fast"
        return (
            f"time base suspect: the input messages arrive about {self.ratio:.1f}x {self.direction} than their "
            f"J1939 periods in frame time ({seen}), for {self.windows * self.window_s:.0f} s of frame time; "
            f"likely cause: {TIME_BASE_CAUSES[self.direction]}; the sensor's clock runs about "
            f"{self.ratio:.1f}x too {clock}, so its temperatures and warnings are wrong"
        )


@dataclass(frozen=True)
class ForeignSourceFinding:
    """``frames`` frames of ``message`` (``with_data`` of them carrying a usable value) came from source address
    ``source``, while ``expected`` is configured (``config_key``; ``configured`` False: the DBC's default) and
    ``expected_frames`` came from it; ``primary``: the message carries an input whose absence degrades the sensor."""

    kind: ClassVar[str] = "foreign_source"
    message: str
    pgn: int
    source: int
    frames: int
    with_data: int
    expected: int
    expected_frames: int
    config_key: str
    configured: bool
    primary: bool
    #: frames (EC1, RC: transfers received) from the expected source address before this one's first (None: not known)
    expected_before: int | None = None
    #: the key that fixes it without moving another input ("" = ``config_key``): ``source_address.<message>`` when
    #: ``config_key`` would also move ``also_moved``, (message, source address) pairs that arrive as expected
    fix_key: str = ""
    also_moved: tuple[tuple[str, int], ...] = ()

    @property
    def moved(self) -> bool:
        """The expected address sent before this one started and never after: the sender moved (a new address
        claim, another ECU fitted), not a second sender beside it."""
        return self.expected_before is not None and 0 < self.expected_frames == self.expected_before

    @property
    def severity(self) -> Severity:
        if self.expected_frames == 0 or self.moved:
            return Severity.UNTRUSTED if self.primary else Severity.NOTE
        return Severity.NOTE

    @property
    def advice(self) -> str:
        """How to set the address this message came from, e.g. "set [can.source_address] TRF1 = 0x21; setting
        [can] transmission_source_address would also move ETC2, which arrives from SA 0x03 as expected"."""
        out = f"set {config_key_words(self.fix_key or self.config_key)} = 0x{self.source:02X}"
        if not self.also_moved:
            return out
        if len(self.also_moved) == 1:
            moved = f"{self.also_moved[0][0]}, which arrives from SA 0x{self.also_moved[0][1]:02X} as expected"
        else:
            moved = (
                ", ".join(f"{m} (SA 0x{sa:02X})" for m, sa in self.also_moved[:-1])
                + f" and {self.also_moved[-1][0]} (SA 0x{self.also_moved[-1][1]:02X}), which arrive as expected"
            )
        return f"{out}; {'changing' if self.configured else 'setting'} [can] {self.config_key} would also move {moved}"

    @property
    def sentence(self) -> str:
        data = "" if self.with_data == self.frames else f" ({self.with_data} with data)"
        brake = NON_DRIVELINE_RETARDERS.get(self.source) if self.message in ("ERC1", RC_KEY) else None
        if brake and not self.expected_frames and not self.moved:  # no advice to take an engine brake's heat
            return (
                f"{self.message} (PGN {self.pgn}) arrived {self.frames} times from SA 0x{self.source:02X}{data}, "
                f"J1939's preferred address of the {brake}, not the driveline retarder (SA 0x{self.expected:02X}) "
                "whose heat reaches the gearbox oil: left out, rightly (a driveline retarder that really sends from "
                f"there: set {config_key_words(self.fix_key or self.config_key)} = 0x{self.source:02X})"
            )
        if not self.configured:
            where = f"the DBC's default SA 0x{self.expected:02X} is expected ({self.advice})"
        elif self.also_moved:
            where = f"[can] expects SA 0x{self.expected:02X} ({self.config_key}; {self.advice})"
        else:
            where = f"[can] expects SA 0x{self.expected:02X} ({config_key_words(self.config_key, bare=True)})"
        what = (
            f"{self.message} (PGN {self.pgn})"
            if self.message not in (EC1_KEY, RC_KEY)
            else f"{self.message} (PGN {self.pgn}, TP.BAM transfers)"
        )
        tail = ": check the source addresses"
        if self.moved:
            tail = (
                f", after {self.expected_frames} from SA 0x{self.expected:02X} and none from it since: the sender "
                f"moved to SA 0x{self.source:02X} (a new address claim or another ECU) and the sensor has not "
                f"used it since (the setting reads one address: a log that holds both is read whole only split at "
                f"the move, each part with its own address)"
            )
        elif self.expected_frames:
            tail = f" (and {self.expected_frames} times from SA 0x{self.expected:02X}): a second sender"
        elif not self.primary:
            tail += " (an auxiliary input: the sensor uses its default instead)"
        return f"{what} arrived {self.frames} times from SA 0x{self.source:02X}{data} but {where}{tail}"


Finding = TimeBaseFinding | ForeignSourceFinding | DegradedFinding

#: J1939's preferred source addresses of retarders whose heat does not reach the gearbox (SAE J1939 appendix B)
NON_DRIVELINE_RETARDERS = {0x0F: "engine retarder", 0x29: "exhaust retarder"}


def config_key_words(key: str, bare: bool = False) -> str:
    """A [can] source-address key as a config file spells it: ``[can] transmission_source_address`` or
    ``[can.source_address] TRF1`` (``bare``: the group key without ``[can]``)."""
    table, _, message = key.partition(".")
    if message:
        return f"[can.{table}] {message}"
    return key if bare else f"[can] {key}"


def _periods_seen(periods_s: dict) -> str:
    """The first three input messages' mean periods against their J1939 ranges, in words."""
    shown = [m for m in PERIOD_RANGE_S if m in periods_s][:3]
    return ", ".join(f"{m} every {_ms(periods_s[m])} against {_period_range(m)}" for m in shown)


def _ms(period_s: float) -> str:
    return f"{period_s * 1e3:.3g} ms" if period_s < 1.0 else f"{period_s:.3g} s"


def _period_range(message: str) -> str:
    lo, hi = PERIOD_RANGE_S[message]
    if lo == hi:
        return _ms(lo)
    return f"{lo * 1e3:.3g}-{hi * 1e3:.3g} ms" if hi < 1.0 else f"{_ms(lo)}-{_ms(hi)}"


# -- the time-base check ----------------------------------------------------------------------------------------


def window_ratio(counts: Mapping[str, int], span_s: float) -> tuple[float, float, dict] | None:
    """How many times faster than nominal the messages arrived in a window of ``span_s`` frame time (``counts``:
    message -> frames in the window): the (low, high) bounds all judged messages agree on and their mean periods;
    None when no message has TIME_BASE_MIN_FRAMES frames or the messages disagree (a single odd sender)."""
    low, high, periods = 0.0, math.inf, {}
    for message, (fastest_s, slowest_s) in PERIOD_RANGE_S.items():
        n = counts.get(message, 0)
        if n < TIME_BASE_MIN_FRAMES or span_s <= 0:
            continue
        period_s = span_s / n
        periods[message] = period_s
        low = max(low, fastest_s / period_s / TIME_BASE_TOLERANCE)
        high = min(high, slowest_s / period_s * TIME_BASE_TOLERANCE)
    if not periods or low > high:
        return None
    return low, high, periods


class TimeBaseCheck:
    """Counts the input messages' frames (``arrivals``: message -> frames from the expected source, cumulative)
    over windows of ``window_s`` frame time; after ``windows`` consecutive windows that agree on "at least
    ``factor`` times faster" (or slower) the time base is :attr:`suspect` until a window agrees on neither.

    ``restart`` at the first frame and after a time jump; ``update`` at every step boundary returns a new
    :class:`TimeBaseFinding` when the time base becomes suspect, ``"cleared"`` when it stops being suspect, else
    None. ``windows_checked`` and ``windows_suspect`` count the windows judged and found suspect."""

    def __init__(
        self, window_s: float = TIME_BASE_WINDOW_S, windows: int = TIME_BASE_WINDOWS, factor: float = TIME_BASE_FACTOR
    ) -> None:
        self.window_s, self.windows, self.factor = window_s, windows, factor
        self.suspect = False
        self.finding: TimeBaseFinding | None = None
        self.windows_checked = 0
        self.windows_suspect = 0
        self._start_s: float | None = None
        self._start: dict[str, int] = {}
        self._run: list[str] = []

    @property
    def window_start_s(self) -> float | None:
        """Frame time the current window started at (None before :meth:`restart`)."""
        return self._start_s

    def restart(self, t_s: float, arrivals: Mapping[str, int]) -> None:
        self._start_s = t_s
        self._start = dict(arrivals)
        self._run = []

    def update(self, t_s: float, arrivals: Mapping[str, int]):
        if self._start_s is None or t_s - self._start_s < self.window_s:
            return None
        span_s = t_s - self._start_s
        counts = {m: arrivals.get(m, 0) - self._start.get(m, 0) for m in PERIOD_RANGE_S}
        self._start_s, self._start = t_s, dict(arrivals)
        judged = window_ratio(counts, span_s)
        if judged is None:
            return None
        self.windows_checked += 1
        low, high, periods = judged
        direction = "faster" if low >= self.factor else "slower" if high <= 1.0 / self.factor else None
        if direction is None:
            self._run = []
            if self.suspect:
                self.suspect = False
                return "cleared"
            return None
        self.windows_suspect += 1
        self._run = [d for d in self._run if d == direction] + [direction]
        if self.suspect or len(self._run) < self.windows:
            return None
        self.suspect = True
        ratio = math.sqrt(low * high) if direction == "faster" else 1.0 / math.sqrt(low * high)
        self.finding = TimeBaseFinding(direction, ratio, len(self._run), self.window_s, periods)
        return self.finding


#: a whole log whose input messages agree on arriving about this many times slower than their J1939 periods has
#: its time stamps in milliseconds, read as seconds (give or take MS_SPREAD either way); the windows of the time-base
#: check cannot see it: EEC1 every 15 "s" puts too few frames into 10 s to judge a rate
MS_RATIO, MS_SPREAD = 1000.0, 3.0


@dataclass(frozen=True)
class MillisecondsFinding:
    """Over a whole log of ``span_s`` frame time the input messages arrived about ``ratio`` times more slowly than
    their J1939 periods (``periods_s``: message -> mean period): time stamps in milliseconds read as seconds."""

    kind: ClassVar[str] = "milliseconds"
    ratio: float
    span_s: float
    periods_s: dict = field(default_factory=dict)
    time_jumps: int = 0

    @property
    def severity(self) -> Severity:
        return Severity.UNTRUSTED

    @property
    def sentence(self) -> str:
        seen = _periods_seen(self.periods_s)
        jumps = f", and {self.time_jumps} of the gaps between them were taken for time jumps" if self.time_jumps else ""
        return (
            f"the log's time stamps look like milliseconds, not seconds: over its {self.span_s:.0f} s of frame time "
            f"the input messages arrive about {self.ratio:.0f}x more slowly than their J1939 periods ({seen}){jumps}; "
            f"give the time stamps in seconds (candump -L writes seconds: divide them by 1000)"
        )


def milliseconds_finding(arrivals: Mapping[str, int], span_s: float, time_jumps: int = 0):
    """The :class:`MillisecondsFinding` of a whole log (``arrivals``: message -> frames from its expected source,
    ``span_s``: the log's frame time), or None: every message with a few frames agrees on MS_RATIO, within
    MS_SPREAD (one slow sender, or a log that is mostly a logger's pause, does not)."""
    judged = window_ratio({m: arrivals.get(m, 0) for m in PERIOD_RANGE_S}, span_s)
    if judged is None:
        return None
    low, high, periods = judged
    if not (MS_RATIO / MS_SPREAD <= 1.0 / high and 1.0 / low <= MS_RATIO * MS_SPREAD):
        return None
    return MillisecondsFinding(1.0 / math.sqrt(low * high), float(span_s), periods, int(time_jumps))


# -- findings from the counters ----------------------------------------------------------------------------------


def _config_keys() -> dict[str, str]:
    """Message -> the [can] key that sets its source address alone: the most specific one (for a CCVS1 from the
    tachograph, engine_source_address would move the engine's messages too)."""
    out: dict[str, str] = {}
    for key, names in SOURCE_ADDRESS_KEYS:
        for name in names:
            out[name] = key
    return out


def _moved_along(message: str, key: str, set_by: Mapping[str, str]) -> list[str]:
    """The other messages whose address setting [can] ``key`` would change: those of its group that no narrower
    key (later in SOURCE_ADDRESS_KEYS) nor the [can.source_address] table sets."""
    order = [k for k, _ in SOURCE_ADDRESS_KEYS]
    names = dict(SOURCE_ADDRESS_KEYS).get(key, ())
    return [
        m for m in names if m != message and (set_by.get(m) not in order or order.index(set_by[m]) <= order.index(key))
    ]


def _fix(
    message: str,
    key: str,
    set_by: Mapping[str, str],
    expected_sa: Mapping[str, int | None],
    received: Mapping[str, int],
    moved_with: frozenset = frozenset(),
) -> tuple[str, tuple[tuple[str, int], ...]]:
    """(the key that fixes a foreign address of ``message`` without moving another input, the inputs ``key``
    would move that arrive as expected): ``key`` when its other messages moved with this one (none arrives from
    its expected address, or those that do moved to the same address: ``moved_with``), else the message's own
    ``source_address.<message>`` (a Navistar: ETC2 from 0x03, TRF1 from 0x21; transmission_source_address for the
    oil lost the gear)."""
    if key.startswith(SOURCE_ADDRESS_TABLE + "."):
        return key, ()
    working = tuple(
        (m, expected_sa[m])
        for m in _moved_along(message, key, set_by)
        if received.get(m, 0) > 0 and expected_sa.get(m) is not None and m not in moved_with
    )
    return (f"{SOURCE_ADDRESS_TABLE}.{message}", working) if working else (key, ())


def foreign_findings(
    decoder_counters: Mapping,
    expected_sa: Mapping[str, int | None],
    configured: Mapping[str, int] | None = None,
    config_keys: Mapping[str, str] | None = None,
) -> list[ForeignSourceFinding]:
    """A finding per (message, foreign source address) that sent at least FOREIGN_MIN_FRAMES frames with data;
    ``expected_sa``: the decoder's, ``configured``: the messages whose address the config set, ``config_keys``:
    the key that set each (``ServiceOptions.source_address_keys``; None: the most specific group key)."""
    pgns = {**wanted_pgns(), EC1_KEY: EC1_PGN, RC_KEY: RC_PGN}
    messages = signal_messages()
    primary = {messages[s] for s in PRIMARY_SIGNALS}
    set_by = (
        dict(config_keys)
        if config_keys is not None
        else {m: k for m, k in _config_keys().items() if m in (configured or {})}
    )
    keys = {**_config_keys(), **set_by}
    arrivals = decoder_counters.get("arrivals", {})
    with_data = decoder_counters.get("foreign_source_data", {})
    first_arrivals = decoder_counters.get("foreign_first_arrivals", {})
    received = {
        EC1_KEY: decoder_counters.get("tp", {}).get("ec1_received", 0),
        RC_KEY: decoder_counters.get("tp", {}).get("rc_received", 0),
    }
    out = []
    for message, per_sa in sorted(decoder_counters.get("foreign_source", {}).items()):
        expected = expected_sa.get(message)
        if expected is None or message not in pgns:
            continue
        key = keys.get(message, "?")
        for sa, frames in sorted(per_sa.items()):
            n_data = with_data.get(message, {}).get(sa, 0)
            if n_data < FOREIGN_MIN_FRAMES:
                continue
            # the group's messages that moved to this address too (their expected address sent before, not since):
            # a group key moves them where they are (the engine's messages all moving from 0x00 to 0x01 were said
            # to "arrive as expected")
            moved_with = frozenset(
                m
                for m, firsts in first_arrivals.items()
                if with_data.get(m, {}).get(sa, 0) >= FOREIGN_MIN_FRAMES
                and 0 < {**arrivals, **received}.get(m, 0) == firsts.get(sa)
            )
            fix_key, also_moved = _fix(message, key, set_by, expected_sa, {**arrivals, **received}, moved_with)
            expected_frames = received[message] if message in received else arrivals.get(message, 0)
            out.append(
                ForeignSourceFinding(
                    message,
                    pgns[message],
                    sa,
                    frames,
                    n_data,
                    expected,
                    expected_frames,
                    key,
                    message in (configured or {}),
                    message in primary,
                    first_arrivals.get(message, {}).get(sa),
                    "" if fix_key == key else fix_key,
                    also_moved,
                )
            )
    return out


#: a J1939 input missing on at least this share of the steps has its cause looked up in the decoder's counters
CAUSE_MIN_SHARE = 0.2
#: the inputs whose causes are named, with the words for them
CAUSE_INPUTS = {
    "engine_speed_rpm": "engine speed",
    "engine_torque_nm": "engine torque",
    "gear": "gear",
    "oil_temp_c": "oil temperature",
    "coolant_temp_c": "coolant temperature",
}


def input_causes(
    decoder_counters: Mapping,
    stale_steps: Mapping[str, int],
    steps: int,
    gear_unmapped: int = 0,
    stale_factor: float = 3.0,
) -> list[str]:
    """Why the inputs missing on at least CAUSE_MIN_SHARE of the steps were missing, as far as the decoder's
    counters tell ("gear 100 %" alone does not tell a message never sent from one sent with 5 data bytes, nor say
    why the coolant fell to its default): frames shorter than 8 bytes, no frame at all, values sent
    as not available or error, no engine reference torque (EC1), EC1 by connection mode. A foreign source address
    has its own finding (foreign_findings)."""
    messages = signal_messages()
    arrivals = decoder_counters.get("arrivals", {})
    short = decoder_counters.get("short_frames", {})
    foreign = decoder_counters.get("foreign_source_data", {})
    sig_rej = decoder_counters.get("signal_rejected", {})
    tp = decoder_counters.get("tp", {})
    not_broadcast = decoder_counters.get("rejected", {}).get("tp_not_broadcast", 0)
    out = []
    slow_said: set = set()
    for sig, words in CAUSE_INPUTS.items():
        if not steps or stale_steps.get(sig, 0) < CAUSE_MIN_SHARE * steps:
            continue
        msg = messages.get(sig)
        if sig == "gear" and gear_unmapped >= CAUSE_MIN_SHARE * steps:
            out.append(
                f"gear: on {gear_unmapped} steps {msg} sent a gear that [can] gear_map does not map or that lies "
                f"outside the model's -2..14 (seed Table 1): set [can] gear_map for this gearbox"
            )
        elif short.get(msg):
            out.append(
                f"{words}: {short[msg]} {msg} frames came with fewer than 8 data bytes (J1939 sends 8; none of "
                f"a short frame's values is used)"
            )
        elif not arrivals.get(msg) and not foreign.get(msg):
            others = decoder_counters.get("foreign_source", {}).get(msg, {})
            if others:
                # frames came, only from other nodes and with nothing in them (e.g. all-0xFF TRF1 from 0x31):
                # "no TRF1 frame arrived" alone would be wrong
                sas = ", ".join(f"0x{sa:02X}" for sa in sorted(others)[:4])
                out.append(
                    f"{words}: no {msg} frame arrived from its expected source address; "
                    f"{sum(others.values())} came from {sas} with no usable value (not available)"
                )
            else:
                out.append(f"{words}: no {msg} frame arrived")
        elif sig == "engine_torque_nm" and not tp.get("ec1_received"):
            cmdt = (
                (
                    f"; {not_broadcast} transport transfers were addressed to one node (TP.CMDT), which the sensor "
                    f"does not receive: EC1 may have come that way"
                )
                if not_broadcast
                else ""
            )
            out.append(
                f"{words}: no engine reference torque arrived (EC1, SPN 544, by TP.BAM from the engine){cmdt}; "
                f"set [can] engine_reference_torque_nm"
            )
        else:
            src = "engine_torque_pct" if sig == "engine_torque_nm" else sig
            bad = {r: n for r, n in sig_rej.get(src, {}).items() if n}
            if bad:
                out.append(
                    f"{words}: {msg} sent it as "
                    + ", ".join(
                        f"{r.replace('_', ' ')} {n} times" for r, n in sorted(bad.items(), key=lambda kv: -kv[1])
                    )
                )
            slow = _slow_message(msg, arrivals.get(msg, 0), steps, stale_factor, stale_steps.get(sig, 0))
            if slow:
                out.append(f"{words}: {slow if msg not in slow_said else f'{msg} as slow (above)'}")
                slow_said.add(msg)
    return out


#: a message's stale share may differ by this much from the share a steady slow rate gives [-]
SLOW_SHARE_TOL = 0.15


def _slow_message(msg: str, arrivals: int, steps: int, stale_factor: float, stale: int) -> str:
    """The words for a message that arrived, on average, more slowly than the staleness rule allows (a logger that
    down-samples EEC1 to 10 Hz makes 40 % of the steps stale), or ''. Only when the stale share is what a steady
    slow rate gives (1 - max age / period, within SLOW_SHARE_TOL): a message at its own rate with long gaps has the
    same mean period, and a larger stale_factor would not help it."""
    nominal_s = NOMINAL_PERIOD_S.get(msg)
    if not nominal_s or not arrivals or not steps:
        return ""
    period_s = steps * STEP_S / arrivals
    max_age_s = stale_factor * nominal_s
    if period_s <= max_age_s or abs(stale / steps - (1.0 - max_age_s / period_s)) > SLOW_SHARE_TOL:
        return ""
    need = math.ceil(1.5 * period_s / nominal_s)
    said = (
        f"{msg} arrived every {1000 * period_s:.0f} ms on average, while a value older than {stale_factor:g} x "
        f"its J1939 period ({1000 * nominal_s:.0f} ms) is stale"
    )
    if need > STALE_FACTOR_MAX:
        # advice the option would refuse is no advice (a log in milliseconds asked for 70 and 91)
        return (
            f"{said}, far slower than any [can] stale_factor (at most {STALE_FACTOR_MAX:g}) accepts (time stamps "
            f"in milliseconds, or a node that slow?)"
        )
    return f"{said} (a logger that down-samples, or a slow node?): [can] stale_factor = {need} accepts it"


@dataclass(frozen=True)
class CoolantFinding:
    """ET1 frames arrived, but the coolant temperature was missing on ``missing`` of ``steps`` steps: the liquid
    cooler's medium took the parameter file's default (a truck that sends no ET1 at all gets the default as
    documented, without a finding)."""

    kind: ClassVar[str] = "coolant"
    steps: int
    missing: int
    causes: tuple = ()

    @property
    def severity(self) -> Severity:
        return Severity.WARNING

    @property
    def sentence(self) -> str:
        why = f" ({'; '.join(self.causes)})" if self.causes else ""
        return (
            f"the coolant temperature was not usable on {pct(self.missing, self.steps)} of {self.steps} "
            f"steps{why}: a liquid cooler exchanged with the parameter file's default coolant instead, which can "
            f"put the sump and the parts the oil streams feed tens of K off"
        )


@dataclass(frozen=True)
class StartFinding:
    """The sensor started without a plausible oil reading: at the ambient reading, else the parameters' ambient."""

    kind: ClassVar[str] = "start"

    @property
    def severity(self) -> Severity:
        return Severity.NOTE

    @property
    def sentence(self) -> str:
        return (
            "the sensor started without an oil reading, every part at the ambient reading (else the parameters' "
            "ambient): if the gearbox was already warm (a log cut mid-drive, a restart), its first temperatures "
            "are low until the model catches up; replay's configuration [replay] initial_temp_c (or --initial-temp) "
            "sets the start (live: the state saved at shutdown)"
        )


#: a message's frames from its expected address at a second J1939 priority on at least this share (and
#: TWO_SENDERS_MIN frames) are a second sender at that address
TWO_SENDERS_SHARE, TWO_SENDERS_MIN = 0.01, 10


@dataclass(frozen=True)
class TwoSendersFinding:
    """A message from its expected source address at two J1939 priorities: one node sends a message at one priority,
    so two nodes send it from one address (an address conflict, a bridge's copy, a test box), and the sensor takes
    each frame as it comes: their values mix (a second EEC1 sender at 600 rpm beside the engine's 1526: 39 % of the
    steps read 600, exit 0 and no word before; a new user's review)."""

    kind: ClassVar[str] = "two_senders"
    message: str
    sa: int | None
    frames: tuple  # ((priority, frames), ...), most first

    @property
    def severity(self) -> Severity:
        return Severity.WARNING

    @property
    def sentence(self) -> str:
        total = sum(n for _, n in self.frames)
        at = ", ".join(f"{p}: {pct(n, total)}" for p, n in self.frames)
        sa = f"SA 0x{self.sa:02X}" if self.sa is not None else "its source address"
        return (
            f"{self.message} came from {sa} at {len(self.frames)} J1939 priorities ({at} of its {total} frames): one "
            "node sends a message at one priority, so two nodes send it from that address (an address conflict, a "
            "bridge's copy, a test box), and the sensor takes each frame as it comes: if their values differ they "
            "mix; find the second sender on the bus"
        )


def two_senders_findings(decoder_counters: Mapping, expected_sa: Mapping[str, int | None]) -> list:
    """A TwoSendersFinding per message whose frames from its expected address came at a second priority on at least
    TWO_SENDERS_SHARE of them (and TWO_SENDERS_MIN frames)."""
    out = []
    for key, per in sorted(decoder_counters.get("priorities", {}).items()):
        total = sum(per.values())
        frames = tuple(sorted(per.items(), key=lambda kv: -kv[1]))
        if len(frames) > 1 and sum(n for _, n in frames[1:]) >= max(TWO_SENDERS_MIN, TWO_SENDERS_SHARE * total):
            out.append(TwoSendersFinding(key, expected_sa.get(key), frames))
    return out


@dataclass(frozen=True)
class OrderFinding:
    """Frames out of time order (up to the step plus backward_tolerance_s earlier than the frame before them,
    SensorService._check_order): the decoder takes frames in file order, so an older value replaces a newer one
    (every 50th frame 0.1 s late leaves 4 % of the steps 'missing', which this finding explains)."""

    kind: ClassVar[str] = "order"
    frames: int
    max_back_s: float

    @property
    def severity(self) -> Severity:
        return Severity.NOTE

    @property
    def sentence(self) -> str:
        return (
            f"{self.frames} frames came earlier in time than the frame before them (up to "
            f"{1000 * self.max_back_s:.0f} ms): the frames are not in time order (a log merged from several "
            f"buffers or channels?), and a frame taken in arrival order can replace a newer value with an older "
            f"one, which may leave inputs stale; sort a log by time (candump -L: LC_ALL=C sort -s -n -k1.2 "
            f"IN.log > OUT.log)"
        )


def trust_findings(
    counters: Mapping,
    expected_sa: Mapping[str, int | None],
    configured: Mapping[str, int] | None = None,
    oil_model: bool = False,
    stale_factor: float = 3.0,
    config_keys: Mapping[str, str] | None = None,
) -> list[Finding]:
    """The findings of a CAN run, most severe first: ``counters`` = ``SensorService.all_counters()``. The degraded
    share is a finding from DEGRADED_WARN_SHARE on (``oil_model``: the sensor models the oil by request, which is
    not degraded); foreign source addresses are findings when a message came only
    from them or moved to them, or when the run was degraded that much (then they are the likely cause)."""
    service = counters["service"]
    out: list[Finding] = []
    raised = service.get("time_base", {}).get("finding")
    if raised is not None:
        out.append(TimeBaseFinding(**raised))
    stale = dict(service.get("stale_steps", {}))
    unmapped = int(service.get("gear_unmapped_steps", 0))
    if unmapped:  # a gear that arrived but that [can] gear_map or the model's -2..14 leaves out is missing too
        stale["gear"] = stale.get("gear", 0) + unmapped
    causes = input_causes(counters["decoder"], stale, int(service.get("steps", 0)), unmapped, stale_factor)
    degraded = degraded_finding(
        service.get("mode_steps", {}), stale, oil_model, service.get("input_rejects"), service.get("oil_frozen_at_c")
    )
    degraded = dataclasses.replace(degraded, causes=tuple(c for c in causes if not c.startswith("coolant")))
    loud = degraded.severity >= Severity.WARNING
    for f in foreign_findings(counters["decoder"], expected_sa, configured, config_keys):
        if loud or f.expected_frames == 0 or f.moved:
            out.append(f)
    if loud:
        out.append(degraded)
    steps = int(service.get("steps", 0))
    sent = counters["decoder"].get("arrivals", {}).get(signal_messages()["coolant_temp_c"], 0)
    if steps and sent and stale.get("coolant_temp_c", 0) >= CAUSE_MIN_SHARE * steps:  # sent, but not usable
        out.append(
            CoolantFinding(
                steps,
                int(stale["coolant_temp_c"]),
                tuple(c[len("coolant temperature: ") :] for c in causes if c.startswith("coolant")),
            )
        )
    if service.get("started_without_oil"):
        out.append(StartFinding())
    out += two_senders_findings(counters["decoder"], expected_sa)
    if service.get("frames_out_of_order"):
        out.append(OrderFinding(int(service["frames_out_of_order"]), float(service.get("out_of_order_max_s", 0.0))))
    return sorted(out, key=lambda f: -f.severity)


#: time-stamp glitches logged one by one (a run counts them all: the service's frames_time_glitch)
GLITCHES_LOGGED = 20
#: the log record attribute that marks the time-base events (``extra={TIME_EVENT: ...}``): "jump", "jumps_more"
#: (how many more jumps, not logged one by one) and "glitch"; an offline replay holds these records until the whole
#: log is judged (tools/replay/timelog.py: a log in milliseconds explains them all)
TIME_EVENT = "gvs_time_event"


def log_time_glitch(log, glitch_s: float, grid_s: float | None, next_s: float | None, count: int) -> None:
    """Log the ``count``-th glitch of a run (one timing frame stamped ``glitch_s``, far ahead of the step grid at
    ``grid_s`` and of the next timing frame at ``next_s``, None at the log's end), as both replay paths do."""
    if count > GLITCHES_LOGGED:
        return
    nxt = "the log ends there" if next_s is None else f"the next frame at {next_s:.6f}"
    log.warning(
        "one frame's time stamp lies %.3f s ahead of the step grid (%.6f against %.6f; %s): a glitch of its time "
        "stamp, not a time jump: its data used, the grid goes on",
        glitch_s - (grid_s if grid_s is not None else glitch_s),
        glitch_s,
        grid_s if grid_s is not None else float("nan"),
        nxt,
        extra={TIME_EVENT: "glitch"},
    )
