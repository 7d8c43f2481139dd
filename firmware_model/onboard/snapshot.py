"""Snapshots of the sensor state: JSON (UTF-8) with every state array base64-encoded, restorable in another process
by a sensor built on the same thermal network (``VirtualSensor.snapshot`` / ``initial_state(snapshot=...)``).

A snapshot carries a CRC-32 of its content (``crc32``): a damaged file (one flipped bit in a temperature) is refused,
not restored. Every field is checked for its shape, type and range before it is used (a saved warning level of 16,
restored, would stop the service at its first step, and again after every restart). Snapshots written before the
checksum (no ``crc32``) are still read, with the same checks.
"""

from __future__ import annotations

import base64
import json
import zlib

import numpy as np

from firmware_model.errors import InputError
from firmware_model.onboard.evaluate import ReducedParams
from firmware_model.onboard.records import N_REJECT, SensorState

SNAPSHOT_SCHEMA = "vsensor-snapshot/1"
#: a restored node temperature outside this is no state the sensor can have reached [degC]
STATE_TEMP_RANGE_C = (-273.15, 2000.0)
#: warning levels a state may hold (0 normal, 1 warning, 2 critical, 3 not available)
LEVEL_MAX = 3
#: state fields added after the schema's first version: a snapshot without one restores it as zeros (it was saved
#: before the field existed; a field after T_c, so the batch shape is known by then)
ADDED_FIELDS = ("recover_s",)


def _crc32(doc: dict) -> int:
    """CRC-32 of a snapshot's content: its JSON without the checksum, as :func:`encode_snapshot` writes it."""
    body = {k: v for k, v in doc.items() if k != "crc32"}
    return zlib.crc32(json.dumps(body, separators=(",", ":")).encode("utf-8"))


def _trailing_shapes(reduced: ReducedParams) -> dict:
    """Each state field's shape after the batch axes."""
    n, ns = len(reduced.nodes), int(reduced.src_matrix.shape[0])
    vec8, pub = (8,), (len(reduced.published),)
    return {
        "T_c": (2, n),
        "lag_w": (ns,),
        "hold": vec8,
        "age_s": vec8,
        "same_s": vec8,
        "raw_prev": vec8,
        "oil_ref_c": (),
        "level": pub,
        "pending_s": pub,
        "ttl_s": pub,
        "t_last_s": (),
        "k": (),
        "rejects": (N_REJECT,),
        "recover_s": (),
    }


def _check_values(vals: dict) -> None:
    """InputError naming the first field whose values no state of the sensor can hold."""
    lo, hi = STATE_TEMP_RANGE_C
    T = vals["T_c"]
    if not (np.all(np.isfinite(T)) and np.all(T >= lo) and np.all(T <= hi)):
        raise InputError(f"snapshot temperatures are not all finite and within {lo:g}..{hi:g} degC")
    checks = {
        "lag_w": np.all(np.isfinite(vals["lag_w"])),
        "level": np.all((vals["level"] >= 0) & (vals["level"] <= LEVEL_MAX)),
        "pending_s": np.all(vals["pending_s"] >= 0.0),
        "age_s": np.all(vals["age_s"] >= 0.0),
        "same_s": np.all(vals["same_s"] >= 0.0),
        "ttl_s": not np.any(vals["ttl_s"] < 0.0),
        "oil_ref_c": not np.any(np.isinf(vals["oil_ref_c"])),
        "t_last_s": not np.any(np.isinf(vals["t_last_s"])),
        "k": np.all(vals["k"] >= 0),
        "rejects": np.all(vals["rejects"] >= 0),
        "recover_s": np.all(vals["recover_s"] >= 0.0),
    }
    for name, ok in checks.items():
        if not ok:
            raise InputError(f"snapshot field {name!r} holds values no sensor state can have (a damaged file)")


def encode_snapshot(state: SensorState, reduced: ReducedParams) -> bytes:
    """Serialise a state (JSON, UTF-8) with the network it belongs to (variant, partition, node list)."""
    doc = {
        "schema": SNAPSHOT_SCHEMA,
        "variant": reduced.variant,
        "partition": reduced.partition,
        "nodes": list(reduced.nodes),
    }
    for name, arr in state._asdict().items():
        a = np.asarray(arr)
        doc[name] = {
            "dtype": str(a.dtype),
            "shape": list(a.shape),
            "data": base64.b64encode(np.ascontiguousarray(a).tobytes()).decode("ascii"),
        }
    doc["crc32"] = _crc32(doc)
    return json.dumps(doc, separators=(",", ":")).encode("utf-8")


def decode_snapshot(snap, reduced: ReducedParams) -> SensorState:
    """A SensorState from a snapshot (a SensorState as is, or the bytes / str / dict of :func:`encode_snapshot`);
    InputError when it is not one, was taken with another network, fails its checksum, or holds a field of the wrong
    shape or type or values no state of the sensor can have (module doc)."""
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
    if "crc32" in snap and snap["crc32"] != _crc32(snap):
        raise InputError("snapshot checksum does not match its content (a damaged file)")
    trailing = _trailing_shapes(reduced)
    vals, batch = {}, None
    for name in SensorState._fields:
        d = snap.get(name)
        if d is None and name in ADDED_FIELDS and batch is not None:
            vals[name] = np.zeros(batch)  # a snapshot of a version before the field: nothing to recover from
            continue
        if not isinstance(d, dict):
            raise InputError(f"snapshot field {name!r} is missing")
        try:
            a = np.frombuffer(base64.b64decode(d["data"]), dtype=np.dtype(d["dtype"])).reshape(d["shape"])
        except (KeyError, ValueError, TypeError) as exc:
            raise InputError(f"snapshot field {name!r} cannot be decoded: {exc}") from None
        want = trailing[name]
        if batch is None:
            batch = a.shape[: a.ndim - len(want)] if a.ndim >= len(want) else None
        if batch is None or len(batch) > 1 or a.shape != batch + want:
            raise InputError(f"snapshot field {name!r} has shape {a.shape}, not (vehicles...) + {want}")
        integer = name in ("level", "k", "rejects")
        if a.dtype.kind != ("i" if integer else "f"):
            raise InputError(
                f"snapshot field {name!r} has type {a.dtype}, not {'an integer' if integer else 'a float'}"
            )
        vals[name] = a.copy()
    _check_values(vals)
    vals["level"] = vals["level"].astype(np.int8)
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
