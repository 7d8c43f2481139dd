"""Faults put into a synthesized J1939 log: what a real truck bus does to the sensor's inputs, one named kind each.

:func:`inject` takes the frames of a synthesized drive (``tools.can.logsynth.synth_frames``) and returns them as
``can.Message`` in file order with the faults of ``kinds`` applied; the service handles every one of them (docs/can.md)
and the whole-log path must give the same table as the frame path on each (tests/firmware_model/test_columnar.py).

==========================  ==========================================================================================
kind                        what happens
==========================  ==========================================================================================
``dropout``                 EEC1 silent for 15 s, TRF1 (oil) silent for 25 s: stale inputs, holding, oil modelled
``late_oil``                no TRF1 for the first 8 s: the sensor waits, then starts without the oil reading
``not_available``           ETC2 gear and EEC1 speed sent as 0xFF/0xFFFF ("not available") for a while
``error_value``             TRF1 oil as 0xFExx (error) for a while
``out_of_range``            gear 0xFB (park) and an oil temperature above the plausibility limit
``foreign_source``          EEC1 and TRF1 copies from another source address, with data
``wrong_dlc``               some ETC2 frames with 6 data bytes
``jump_forward``            the frame time jumps 20 s ahead (a logger pause)
``jump_backward``           the frame time jumps 30 s back (a logger clock reset)
``time_glitch``             one EEC1 frame stamped 30 s ahead of its neighbours (a logger's glitch, not a jump)
``jitter``                  frames a few ms out of order
``hostile``                 error, remote, FD, 11-bit and random-identifier frames, broken TP.CM/TP.DT
==========================  ==========================================================================================
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from can_dbc.columnar import pgn_keys
from can_dbc.j1939 import can_id_of, source_address
from firmware_model.errors import InputError

FAULT_KINDS = (
    "dropout",
    "late_oil",
    "not_available",
    "error_value",
    "out_of_range",
    "foreign_source",
    "wrong_dlc",
    "jump_forward",
    "jump_backward",
    "time_glitch",
    "jitter",
    "hostile",
)
_EEC1, _ETC2, _TRF1 = 0xF004, 0xF005, 0xFEF8


def _window(t: np.ndarray, start_frac: float, length_s: float) -> np.ndarray:
    t0 = t[0] + start_frac * (t[-1] - t[0])
    return (t >= t0) & (t < t0 + length_s)


def _hostile(t0: float, t1: float, n: int, rng: np.random.Generator) -> list:
    import can

    out = []
    for t in np.sort(rng.uniform(t0, t1, n)).tolist():
        kind = int(rng.integers(0, 6))
        data = bytes(rng.integers(0, 256, 8, dtype=np.uint8))
        if kind == 0:
            out.append(can.Message(timestamp=t, is_error_frame=True))
        elif kind == 1:
            out.append(
                can.Message(timestamp=t, arbitration_id=can_id_of(_EEC1, 0), is_remote_frame=True, dlc=8, check=False)
            )
        elif kind == 2:
            out.append(
                can.Message(timestamp=t, arbitration_id=can_id_of(_EEC1, 0), is_fd=True, data=bytes(12), check=False)
            )
        elif kind == 3:
            out.append(
                can.Message(timestamp=t, arbitration_id=int(rng.integers(0, 0x800)), is_extended_id=False, data=data)
            )
        elif kind == 4:
            out.append(can.Message(timestamp=t, arbitration_id=int(rng.integers(0, 1 << 29)), data=data))
        else:
            pgn = (0xEC00, 0xEB00)[int(rng.integers(0, 2))]
            out.append(
                can.Message(timestamp=t, arbitration_id=can_id_of(pgn, 0, 7, int(rng.choice([0xFF, 0x21]))), data=data)
            )
    return out


def inject(frames, kinds: Iterable[str], seed: int = 0) -> list:
    """The frames of a synthesized log (``SynthFrames``) with the faults ``kinds`` (:data:`FAULT_KINDS`), as
    ``can.Message`` in file order."""
    import can

    kinds = tuple(kinds)
    unknown = sorted(set(kinds) - set(FAULT_KINDS))
    if unknown:
        raise InputError(f"unknown log fault {', '.join(unknown)}; known: {', '.join(FAULT_KINDS)}")
    rng = np.random.default_rng(seed)
    t = frames.timestamp_s.astype(float).copy()
    ids = frames.can_id.astype(np.int64).copy()
    data = frames.data.copy()
    pgn = pgn_keys(ids)
    keep = np.ones(t.size, dtype=bool)
    dlc = np.full(t.size, 8)
    if "dropout" in kinds:
        keep &= ~((pgn == _EEC1) & _window(t, 0.2, 15.0)) & ~((pgn == _TRF1) & _window(t, 0.5, 25.0))
    if "late_oil" in kinds:
        keep &= ~((pgn == _TRF1) & (t < t[0] + 8.0))
    if "not_available" in kinds:
        data[(pgn == _ETC2) & _window(t, 0.3, 10.0), 3] = 0xFF
        data[(pgn == _EEC1) & _window(t, 0.6, 5.0), 3:5] = 0xFF
    if "error_value" in kinds:
        data[(pgn == _TRF1) & _window(t, 0.4, 6.0), 5] = 0xFE
    if "out_of_range" in kinds:
        data[(pgn == _ETC2) & _window(t, 0.7, 4.0), 3] = 0xFB
        data[(pgn == _TRF1) & _window(t, 0.8, 5.0), 4:6] = (0x00, 0xF0)
    extra = []
    if "foreign_source" in kinds:
        copy = np.flatnonzero(((pgn == _EEC1) | (pgn == _TRF1)) & _window(t, 0.1, 20.0))[::3]
        for i in copy.tolist():
            extra.append(
                can.Message(
                    timestamp=float(t[i]) + 1e-4,
                    arbitration_id=can_id_of(int(pgn[i]), (source_address(int(ids[i])) + 3) % 250),
                    data=data[i].tobytes(),
                )
            )
    if "wrong_dlc" in kinds:
        dlc[(pgn == _ETC2) & _window(t, 0.15, 3.0)] = 6
    if "jitter" in kinds:
        t = t + np.where(rng.random(t.size) < 0.02, -rng.uniform(0.0, 0.004, t.size), 0.0)
    if "jump_forward" in kinds:
        t = np.where(t >= t[0] + 0.45 * (t[-1] - t[0]), t + 20.0, t)
    if "jump_backward" in kinds:
        t = np.where(t >= t[0] + 0.75 * (t[-1] - t[0]), t - 30.0, t)
    if "time_glitch" in kinds:
        t = t.copy()
        t[np.flatnonzero((pgn == _EEC1) & (t >= t[0] + 0.35 * (t[-1] - t[0])))[0]] += 30.0
    if "hostile" in kinds:
        extra.extend(_hostile(float(t[0]), float(t[-1]), max(200, t.size // 50), rng))
    msgs = [
        can.Message(timestamp=ts, arbitration_id=cid, data=row.tobytes()[:n], dlc=n, check=False)
        for ts, cid, row, n in zip(t[keep].tolist(), ids[keep].tolist(), data[keep], dlc[keep].tolist())
    ]
    if extra:  # into file order by time, the originals' (jittered, jumped) order kept
        order = np.argsort(
            np.concatenate([np.arange(len(msgs)) + 0.5, np.searchsorted(t[keep], [m.timestamp for m in extra])]),
            kind="stable",
        )
        allm = msgs + extra
        msgs = [allm[i] for i in order]
    return msgs


__all__ = ["FAULT_KINDS", "inject"]
