"""What the onboard step memoises, in one explicit object the sensor owns and passes to the step.

The memos are bounded and hold pure functions of their keys (the conductances of an operating-point bin, the modes
of a held-input system, one time-jump propagation done ahead of its step), so a step gives the same outputs with a
fresh cache, a warm one or one shared by sensors built from the same parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from firmware_model.onboard.conductance_bins import BinCache
from firmware_model.onboard.held_modes import ModeCache


@dataclass
class StepCache:
    """The step's memos: conductances per operating-point bin (one vehicle) and held-input modes (time to limit,
    time jumps, cool-down)."""

    bins: BinCache = field(default_factory=BinCache)
    modes: ModeCache = field(default_factory=ModeCache)
    ahead: JumpAhead = field(default_factory=lambda: JumpAhead())


@dataclass
class JumpAhead:
    """One time-jump propagation done ahead of its step (held_inputs.prepare_jump): the live service propagates the
    state as soon as the first frame after a gap arrives, and the step that then sees the gap takes the result
    instead of computing it (the propagation is two eigen-decompositions: milliseconds natively, a few hundred under
    emulation, which would otherwise all fall between the first frame after an outage and the first output).

    A pure memo like the others: the key is everything the propagation reads (one vehicle's temperatures, held
    inputs and input ages, and the gap), so a hit is the same bits the step would compute. ``hits`` counts the steps
    that took a prepared result; an entry is used once."""

    key: tuple | None = None
    T_c: np.ndarray | None = None
    hits: int = 0

    @staticmethod
    def key_of(state, gap_s: float) -> tuple:
        """What a single vehicle's jump propagation depends on, as bytes (float64)."""
        return (float(gap_s),) + tuple(
            np.asarray(x, dtype=float).tobytes() for x in (state.T_c, state.hold, state.age_s)
        )

    def put(self, key: tuple, T_c: np.ndarray) -> None:
        self.key, self.T_c = key, np.array(T_c, dtype=float, copy=True)

    def take(self, key: tuple) -> np.ndarray | None:
        """The prepared temperatures for ``key``, or None; the entry is dropped either way (one jump, one use)."""
        hit = self.key is not None and key == self.key
        T_c, self.key, self.T_c = self.T_c, None, None
        if not hit:
            return None
        self.hits += 1
        return T_c
