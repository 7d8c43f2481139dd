"""Malformed lines of a text CAN log: found, skipped, counted and said (docs/can.md "Malformed log lines").

A line is malformed when python-can's reader for the format cannot read it as a frame (candump -L: a line that is
not ``(time) interface ID#DATA``; every format: a last line without its newline, cut short as by a logger unplugged
mid-write, even where the cut line would still parse as a shorter frame). Both replay paths read the same log without
those lines (:class:`LogDamage` ``.clean``, found by ``tools.replay.columns.scan_log``), so they keep the same frames
and give the same counts.

:func:`damage_finding` says how many were skipped and where, and whether the outputs can still be trusted: not when
more than ``MALFORMED_UNTRUSTED_SHARE`` of the lines are malformed, or when a malformed line breaks a frame sequence
the step needs (:func:`broken_sequences`). A cut last line alone is never untrusted.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar

import numpy as np

from firmware_model.errors import InputError
from firmware_model.service.degraded import Severity, pct

#: more than this share of the (non-empty) lines malformed, a cut last line not counted: untrusted
MALFORMED_UNTRUSTED_SHARE = 0.01
#: line numbers the sentences name
SHOWN_LINES = 5
#: a candump -L line exactly as the whole-log parser and python-can read it (after the line's surrounding whitespace)
CANDUMP_STRICT = re.compile(rb"\([0-9]+(?:\.[0-9]+)?\) [!-~]+ [0-9A-Fa-f]{1,8}#(?:[0-9A-Fa-f]{2}){0,8}(?: [RT])?")
#: the lines an ASC log may hold besides its frames (python-can's reader skips any other line without a word): the
#: header's and trigger block's keywords, comments, and events that start with their time stamp
ASC_KNOWN = re.compile(
    rb"(?:date |base |internal events logged|no internal events logged|begin triggerblock|end triggerblock|//|"
    rb"[0-9]+\.[0-9]+\s)",
    re.IGNORECASE,
)
#: an ASC classic data frame: time, channel, ID, direction, d, its DLC, then its data bytes (the rest: CANoe's
#: Length/BitCount/ID fields); a frame with fewer data bytes than its DLC is cut
ASC_FRAME = re.compile(
    rb"[0-9]+\.[0-9]+\s+[0-9]+\s+[0-9A-Fa-f]+x?\s+(?:Rx|Tx)\s+d\s+([0-9A-Fa-f])((?:\s+[0-9A-Fa-f]{2}(?=\s|$))*)"
)
#: a PCAN-View trace (.trc) holds ';' header lines and frames that start with their message number
TRC_KNOWN = re.compile(rb"(?:;|[0-9]+\)?\s)")
#: python-can's text readers by suffix, for a log read without its malformed lines
TEXT_READERS = {".log": "CanutilsLogReader", ".asc": "ASCReader", ".trc": "TRCReader"}
#: the messages whose frames the step needs (J1939 PGN: EEC1 speed and torque, ETC2 gear, TRF1 oil), their names
PRIMARY_PGNS = {61444: ("EEC1", "engine speed and torque"), 61445: ("ETC2", "gear"), 65272: ("TRF1", "oil temperature")}
#: TP.CM and TP.DT (J1939-21), the BAM control byte, and the longest wait between two packets of a transfer (T1)
TP_CM_PGN, TP_DT_PGN, TP_BAM, TP_T1_S = 0xEC00, 0xEB00, 0x20, 0.75


@dataclass(frozen=True)
class LogDamage:
    """What a log's reader skipped: ``lines`` non-empty lines read (text logs); ``bad`` the 1-based line numbers of
    the malformed ones; ``kept_before`` per malformed line the frames kept before it; ``cut_last``: the last line
    was cut short; ``clean`` the log without the malformed lines (None when none was skipped); ``first_text`` the
    first malformed line (60 characters); ``note`` a binary log cut short (read up to the cut)."""

    lines: int = 0
    bad: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    kept_before: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    cut_last: bool = False
    clean: bytes | None = None
    first_text: str = ""
    note: str = ""

    @property
    def skipped(self) -> int:
        return int(self.bad.size)

    @property
    def binary(self) -> bool:
        """The first malformed line holds control bytes or undecodable ones (a binary file, or noise)."""
        return any((ord(ch) < 32 and ch not in "\t\r") or ch == "\ufffd" for ch in self.first_text)

    def strict_sentence(self, path) -> str:
        """The sentence of ``replay --strict``: the first malformed line, named (today's refusal)."""
        if self.note:
            return f"{path}: {self.note}"
        n = int(self.bad[0])
        if self.cut_last and self.skipped == 1:
            return (
                f"{path}: the log ends in the middle of a line (line {n}: truncated, or still being written; "
                f"without --strict it is skipped and counted)"
            )
        if self.binary:
            return (
                f"{path}: line {n} holds binary data: noise in the log, or not a candump -L text log (without "
                f"--strict such lines are skipped and counted)"
            )
        return (
            f"{path}: line {n} is not a candump -L frame '(time) interface ID#DATA': {self.first_text!r} "
            f"(without --strict such lines are skipped and counted)"
        )

    def text_reader(self, suffix: str):
        """python-can's reader of the log without its malformed lines."""
        import can

        return getattr(can, TEXT_READERS[suffix])(io.StringIO(self.clean.decode("utf-8", "replace")))


def _python_can_reads(line: bytes) -> bool:
    """Whether python-can's candump -L reader reads ``line`` as one frame (the forms the strict pattern leaves out:
    remote and FD frames, tabs, exponents, odd hex)."""
    import can

    try:
        text = line.decode("utf-8")
        return "\r" not in text.rstrip("\r") and len(list(can.CanutilsLogReader(io.StringIO(text + "\n")))) == 1
    except Exception:  # python-can raises a variety of errors for a line it cannot read
        return False


def _reads(suffix: str, seg: bytes, stripped: bytes) -> bool:
    """Whether a (non-last) line of a ``suffix`` log is one its reader takes: a candump -L frame; an ASC line of a
    known kind, a data frame with all its bytes; a TRC header line or one that starts with its message number."""
    if suffix == ".log":
        return CANDUMP_STRICT.fullmatch(stripped) is not None or _python_can_reads(seg)
    if suffix == ".asc":
        if ASC_KNOWN.match(stripped) is None:
            return False
        frame = ASC_FRAME.match(stripped)
        return frame is None or len(frame.group(2).split()) >= int(frame.group(1), 16)
    if suffix == ".trc":
        return TRC_KNOWN.match(stripped) is not None
    return True


def scan_text_log(path: Path, raw: bytes | None = None) -> LogDamage:
    """The malformed lines of a text log (.log: every line checked; .asc: a line of no kind an ASC log holds, or a
    data frame short of its DLC's bytes; .trc: a line neither a ';' header nor numbered; any: a cut last line);
    InputError when no line is left or the file starts with a byte-order mark."""
    raw = path.read_bytes() if raw is None else raw
    suffix = path.suffix.lower()
    if suffix == ".log" and raw.startswith(b"\xef\xbb\xbf"):
        raise InputError(
            f"{path}: starts with a UTF-8 byte-order mark, which candump never writes (an editor added it); remove it"
        )
    segs = raw.split(b"\n")
    cut = bool(segs[-1].strip())
    keep, bad, before, lines, first = [], [], [], 0, b""
    for i, seg in enumerate(segs):
        s = seg.strip()
        if not s:
            continue
        lines += 1
        last = i == len(segs) - 1
        ok = not last and _reads(suffix, seg, s)
        if ok:
            keep.append(seg)
        else:
            first = first or seg
            bad.append(i + 1)
            before.append(len(keep))
    damage = LogDamage(
        lines,
        np.array(bad, np.int64),
        np.array(before, np.int64),
        cut,
        b"\n".join(keep) + b"\n" if bad else None,
        first.decode("utf-8", "replace")[:60],
    )
    if lines and len(bad) == lines:
        from tools.replay.formats import content_kind

        kind = content_kind(Path(path))
        if kind is not None and kind[1] != suffix:
            raise InputError(f"{path}: no CAN frame read as {suffix}: it looks like {kind[0]}; name it {kind[1]}")
        what = "it holds binary data" if damage.binary else f"line {bad[0]}: {damage.first_text!r}"
        # candump's default and -ta output ("  can0  18FEF100   [8]  00 ...") are for reading, not replaying
        text = damage.first_text or ""
        form = "; a .log is candump -L's form, '(1690000000.123456) can0 18FEF100#0011...'"
        hint = (
            f"{form}: write it with candump -L"
            if suffix == ".log" and not damage.binary and re.search(r"\[\d\]", text)
            # candump -L's lines without their interface name (a converter's): one word missing
            else f"{form}: its lines lack the interface name (can0) between the time and the frame"
            if suffix == ".log" and not damage.binary and re.match(r"\s*\(\d+(\.\d+)?\)\s+[0-9A-Fa-f]+#", text)
            else ""
        )
        raise InputError(
            f"{path}: none of its {lines} lines is a CAN frame ({what}): not a {suffix} text CAN log, "
            f"or one damaged throughout{hint}"
        )
    return damage


def broken_sequences(damage: LogDamage, cols, stale_factor: float) -> list[str]:
    """Where a malformed line (the cut last line aside) breaks a frame sequence the step needs, in words:

    - a TP.BAM transfer of EC1 (the engine's reference torque) that misses a packet, with a malformed line between
      its announcement (TP.CM) and the sender's next announcement or T1 (750 ms) per packet after it;
    - a gap in EEC1, ETC2 or TRF1 longer than the sensor's staleness limit (``stale_factor`` nominal periods) that
      holds at least as many malformed lines as frames of the message are missing in it (the gap over the
      message's median period, less one): the lost lines were those frames, and the input went stale.
    """
    from can_dbc.columnar import FLAG_ERROR, pgn_keys
    from can_dbc.j1939 import EC1_PGN
    from firmware_model.service.options import NOMINAL_PERIOD_S

    mid = damage.kept_before[: damage.skipped - int(damage.cut_last)]
    if not mid.size or not len(cols):
        return []
    t, data = cols.timestamp_s, cols.data
    pgn = np.where((cols.flags & FLAG_ERROR) != 0, -1, pgn_keys(cols.can_id))
    sa = cols.can_id & 0xFF
    out = []
    cm = np.flatnonzero((pgn == TP_CM_PGN) & (data[:, 0] == TP_BAM))
    ec1 = cm[
        (data[cm, 5].astype(np.int64) | data[cm, 6].astype(np.int64) << 8 | data[cm, 7].astype(np.int64) << 16)
        == EC1_PGN
    ]
    for c in ec1.tolist():
        n, later = int(data[c, 3]), cm[(cm > c) & (sa[cm] == sa[c])]
        end = int(later[0]) if later.size else len(cols)
        late = np.flatnonzero(t[c + 1 : end] > t[c] + TP_T1_S * (n + 1))  # (frame time, not file order: robust)
        end = c + 1 + int(late[0]) if late.size else end
        dt = c + 1 + np.flatnonzero((pgn[c + 1 : end] == TP_DT_PGN) & (sa[c + 1 : end] == sa[c]))
        lost = np.flatnonzero((mid > c) & (mid <= end))
        if lost.size and not set(range(1, n + 1)) <= set(data[dt, 0].tolist()):
            out.append(
                f"line {int(damage.bad[lost[0]])} broke a TP.BAM transfer of EC1 (the engine's reference "
                f"torque, from SA 0x{int(sa[c]):02X})"
            )
            break
    for p, (name, what) in PRIMARY_PGNS.items():
        idx = np.flatnonzero(pgn == p)
        if idx.size < 2:
            continue
        pos = np.searchsorted(idx, mid)
        inside = (pos > 0) & (pos < idx.size)
        gaps, counts = np.unique(pos[inside], return_counts=True)
        span = t[idx[gaps]] - t[idx[gaps - 1]]
        with np.errstate(divide="ignore", invalid="ignore"):  # a period of 0 or NaN: no frame counted missing
            missing = np.rint(span / float(np.median(np.diff(t[idx])))) - 1
        hit = np.flatnonzero((span > stale_factor * NOMINAL_PERIOD_S[name]) & (missing >= 1) & (counts >= missing))
        if hit.size:
            first = int(damage.bad[np.flatnonzero(inside & (pos == gaps[hit[0]]))[0]])
            out.append(
                f"the malformed lines from line {first} on left a {span[hit[0]]:.2f} s gap in {name} ({what}), "
                f"longer than the sensor's staleness limit of {stale_factor * NOMINAL_PERIOD_S[name]:.2f} s"
            )
    return out


def _numbers(first, total: int) -> str:
    """ "lines 5, 7, 9 and 12 more": the first line numbers of ``total``."""
    more = f" and {total - len(first)} more" if total > len(first) else ""
    return f"line{'s' if total > 1 else ''} {', '.join(str(int(n)) for n in first)}{more}"


@dataclass(frozen=True)
class MalformedLinesFinding:
    """``skipped`` malformed lines (the first at ``first``, 1-based) of ``lines`` were skipped; ``cut_last``: the
    last of them was the log's cut last line; ``broken``: the frame sequences they broke, in words; ``note``: a
    binary log read up to its cut."""

    kind: ClassVar[str] = "malformed_lines"
    lines: int
    skipped: int
    first: tuple
    cut_last: bool
    broken: tuple = ()
    note: str = ""
    name: str = ""  # the log's file name, put before the sentence where the file is not otherwise named

    @property
    def share(self) -> float:
        return (self.skipped - int(self.cut_last)) / self.lines if self.lines else 0.0

    @property
    def severity(self) -> Severity:
        if self.broken or self.share > MALFORMED_UNTRUSTED_SHARE:
            return Severity.UNTRUSTED
        return Severity.NOTE

    @property
    def summary(self) -> str:
        """One sentence: how many lines were skipped and the first line numbers (after the file's ``name``, if set)."""
        named = f"{self.name}: " if self.name else ""
        if self.note:
            return f"{named}{self.note}: the frames before the cut were replayed"
        cut = "; the last one cut short, as by a logger stopped mid-write" if self.cut_last else ""
        if self.cut_last and self.skipped == 1:
            cut = ", the last, cut short as by a logger stopped mid-write"
        return (
            f"{named}{self.skipped} malformed line{'s' if self.skipped > 1 else ''} skipped "
            f"({_numbers(self.first, self.skipped)}{cut})"
        )

    @property
    def sentence(self) -> str:
        if self.severity < Severity.UNTRUSTED:
            return self.summary
        why = list(self.broken)
        if self.share > MALFORMED_UNTRUSTED_SHARE:
            why.insert(
                0,
                f"they are {pct(self.skipped - int(self.cut_last), self.lines)} of the log's "
                f"{self.lines} lines, more than {100 * MALFORMED_UNTRUSTED_SHARE:g} %: the log is damaged "
                f"and the frames those lines held are missing",
            )
        return f"{self.summary}: {'; '.join(why)} (replay --strict refuses such a log)"


def damage_finding(damage: LogDamage | None, cols=None, stale_factor: float = 3.0) -> MalformedLinesFinding | None:
    """The finding of a log's skipped lines (``cols``: the frames kept, for :func:`broken_sequences`); None when
    nothing was skipped."""
    if damage is None or not (damage.skipped or damage.note):
        return None
    broken = tuple(broken_sequences(damage, cols, stale_factor)) if cols is not None else ()
    return MalformedLinesFinding(
        damage.lines,
        damage.skipped,
        tuple(int(n) for n in damage.bad[:SHOWN_LINES]),
        damage.cut_last,
        broken,
        damage.note,
    )
