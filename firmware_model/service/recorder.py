"""One run-table row per step of the CAN service (``record=True``): the frame half's head (time, the inputs as the
sensor got them, percent and reference torque, rig thermocouples) and the sensor half's outputs (temperatures,
warning levels, time to limit, status). The whole-log replay records the two halves apart and joins them
(:meth:`StepRecorder.adopt`)."""

from __future__ import annotations

import math

import numpy as np

from firmware_model.service.options import INPUT_COLUMNS
from firmware_model.service.records import GbxStatus, OutputRow, RecordedOutputs

#: head columns of a recorded row
HEAD_COLUMNS = ("time_s", "can_time_s", *INPUT_COLUMNS)


class StepRecorder:
    """The recorded steps of one service. ``components``: the published components (order of the per-component
    arrays); ``meas_names``: the rig thermocouple columns (``meas_T_<id>_c``, the same order);
    ``reject_reasons``: the sensor's reject counters (``rejects_<reason>`` columns)."""

    def __init__(
        self, components: tuple[str, ...], meas_names: tuple[str, ...], reject_reasons: tuple[str, ...]
    ) -> None:
        self.components = components
        self.meas_names = meas_names
        self.reject_reasons = tuple(reject_reasons)
        self.tail_names = ("degraded", *GbxStatus._fields, *(f"rejects_{r}" for r in self.reject_reasons))
        self._heads: list[tuple[float, ...]] = []  # per step: HEAD_COLUMNS
        self._meas_rows: dict[int, np.ndarray] = {}  # step -> rig thermocouples (when any were seen)
        self._outs: list[OutputRow] = []
        self._adopted: RecordedOutputs | None = None
        self._head_block: np.ndarray | None = None  # every head at once (the whole-log path)
        self._meas_block: np.ndarray | None = None

    def adopt_heads(self, head: np.ndarray, meas_c: np.ndarray) -> None:
        """Every step's frame half at once (``firmware_model.service.columnar``): ``head`` (steps x HEAD_COLUMNS)
        and ``meas_c`` (steps x thermocouples, NaN where none is fresh or none was seen yet)."""
        self._head_block, self._meas_block = head, meas_c
        self._heads, self._meas_rows = [], {}

    @property
    def steps(self) -> int:
        return len(self._heads) if self._head_block is None else self._head_block.shape[0]

    def head_column(self, name: str) -> np.ndarray:
        """One column of the recorded heads (HEAD_COLUMNS), every step."""
        j = HEAD_COLUMNS.index(name)
        if self._head_block is not None:
            return self._head_block[:, j]
        return np.array([h[j] for h in self._heads], dtype=float)

    def add_head(self, row: tuple[float, ...], meas_c: np.ndarray | None = None) -> None:
        """The frame half of a step: a row of HEAD_COLUMNS and, when rig thermocouples were seen, their values."""
        if meas_c is not None:
            self._meas_rows[len(self._heads)] = meas_c
        self._heads.append(row)

    def add_outputs(self, T_c, level, ttl_s, status: GbxStatus, rejects=None) -> None:
        """The sensor half of a step: published temperatures, levels, time to limit, the status and the sensor's
        cumulative reject counters (None: zeros)."""
        nan = math.nan
        mode = status.degraded_mode
        tail = [nan if mode is None else float(mode != 0), *(nan if v is None else float(v) for v in status)]
        if self.reject_reasons:
            n_r = len(self.reject_reasons)
            tail += np.asarray(rejects, dtype=float).reshape(-1)[:n_r].tolist() if rejects is not None else [0.0] * n_r
        self._outs.append(
            OutputRow(np.array(T_c, dtype=float), np.array(level, dtype=float), np.array(ttl_s, dtype=float), tail)
        )

    def outputs(self) -> RecordedOutputs:
        """The sensor half of the recorded rows as arrays."""
        if self._adopted is not None:
            return self._adopted
        n, m, k = len(self.components), len(self.tail_names), len(self._outs)
        outs = self._outs
        return RecordedOutputs(
            np.array([r.T_c for r in outs], dtype=float).reshape(k, n),
            np.array([r.level for r in outs], dtype=float).reshape(k, n),
            np.array([r.ttl_s for r in outs], dtype=float).reshape(k, n),
            np.array([r.tail for r in outs], dtype=float).reshape(k, m),
        )

    def adopt(self, outputs: RecordedOutputs) -> None:
        """Take the sensor half recorded elsewhere (the whole-log replay, firmware_model.service.columnar)."""
        self._adopted = outputs
        self._outs = []

    def columns(self, meas_seen: tuple[bool, ...]) -> dict[str, np.ndarray]:
        """The recorded steps as run-table columns (tools/runtable.py): the head, T_/W_/ttl_ per published
        component ("never" is an empty ttl cell), the status tail, and meas_T_<id>_c for each thermocouple seen."""
        k = self.steps
        head = (
            np.array(self._heads, dtype=float).reshape(k, len(HEAD_COLUMNS))
            if self._head_block is None
            else self._head_block
        )
        cols = {name: head[:, j] for j, name in enumerate(HEAD_COLUMNS)}
        out = self.outputs()
        if out.T_c.shape[0] != k:
            raise RuntimeError(f"recorded {k} step heads but {out.T_c.shape[0]} sensor outputs")
        ttl = out.ttl_s.copy()
        ttl[np.isinf(ttl)] = np.nan  # a run table writes "never" as an empty cell
        for block, (prefix, suffix) in zip((out.T_c, out.level, ttl), (("T_", "_c"), ("W_", ""), ("ttl_", "_s"))):
            for j, c in enumerate(self.components):
                cols[f"{prefix}{c}{suffix}"] = block[:, j]
        for j, name in enumerate(self.tail_names):
            cols[name] = out.tail[:, j]
        if any(meas_seen):
            meas = np.full((k, len(self.meas_names)), np.nan) if self._meas_block is None else self._meas_block
            for i, row in self._meas_rows.items():
                meas[i] = row
            for j, name in enumerate(self.meas_names):
                if meas_seen[j]:
                    cols[name] = meas[:, j]
        return cols
