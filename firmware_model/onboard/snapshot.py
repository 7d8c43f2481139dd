"""Snapshots of the sensor state: JSON (UTF-8) with every state array base64-encoded, restorable in another process
by a sensor built on the same thermal network (``VirtualSensor.snapshot`` / ``initial_state(snapshot=...)``).
"""
from __future__ import annotations

import base64
import json

import numpy as np

from firmware_model.errors import InputError
from firmware_model.onboard.reduce import ReducedParams
from firmware_model.onboard.records import SensorState

SNAPSHOT_SCHEMA = "vsensor-snapshot/1"


def encode_snapshot(state: SensorState, reduced: ReducedParams) -> bytes:
    """Serialise a state (JSON, UTF-8) with the network it belongs to (variant, partition, node list)."""
    doc = {"schema": SNAPSHOT_SCHEMA, "variant": reduced.variant, "partition": reduced.partition,
           "nodes": list(reduced.nodes)}
    for name, arr in state._asdict().items():
        a = np.asarray(arr)
        doc[name] = {"dtype": str(a.dtype), "shape": list(a.shape),
                     "data": base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii")}
    return json.dumps(doc, separators=(",", ":")).encode("utf-8")


def decode_snapshot(snap, reduced: ReducedParams) -> SensorState:
    """A SensorState from a snapshot (a SensorState as is, or the bytes / str / dict of :func:`encode_snapshot`);
    InputError when it is not one, was taken with another network, or holds a non-finite temperature."""
    if isinstance(snap, SensorState):
        return snap
    if isinstance(snap, (bytes, bytearray, str)):
        try:
            snap = json.loads(snap)
        except (ValueError, UnicodeDecodeError) as exc:
            raise InputError(f"snapshot is not valid JSON: {exc}") from None
    if not isinstance(snap, dict) or snap.get("schema") != SNAPSHOT_SCHEMA:
        raise InputError(f"snapshot schema must be {SNAPSHOT_SCHEMA!r}")
    if snap.get("nodes") != list(reduced.nodes):
        raise InputError("snapshot was taken with another thermal network (its node list differs)")
    vals = {}
    for name in SensorState._fields:
        d = snap.get(name)
        if not isinstance(d, dict):
            raise InputError(f"snapshot field {name!r} is missing")
        try:
            a = np.frombuffer(base64.b64decode(d["data"]), dtype=np.dtype(d["dtype"])).reshape(d["shape"])
        except (KeyError, ValueError, TypeError) as exc:
            raise InputError(f"snapshot field {name!r} cannot be decoded: {exc}") from None
        vals[name] = a.copy()
    if not np.all(np.isfinite(vals["T_c"])):
        raise InputError("snapshot temperatures are not all finite")
    return SensorState(**vals)


def state_bytes(state: SensorState, dtype=np.float32) -> int:
    """Bytes of a state as an ECU would hold it (floats as ``dtype``, levels 1 byte, counters and the step count 4
    bytes)."""
    fb = np.dtype(dtype).itemsize
    total = 0
    for name, a in state._asdict().items():
        a = np.asarray(a)
        if name == "level":
            total += a.size
        elif name in ("rejects", "k"):
            total += 4 * a.size
        else:
            total += fb * a.size
    return total
