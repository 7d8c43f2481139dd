"""Synthetic roads of the road cycles: segments (grade, speed limit, stops) and the route the driver follows."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from tools.cycles.vehicle import KMH_PER_M_S


@dataclass(frozen=True)
class Segment:
    """A stretch of synthetic road. Grade is rise/run (+ uphill). A stop, if any, is at the end of the segment."""

    length_m: float
    grade: float = 0.0
    limit_kmh: float = 80.0
    hills: float = 0.0  # amplitude of superposed small hills (grade, rise/run)
    stop_s: float = 0.0  # dwell at the end (engine idling in neutral)
    reverse_m: float = 0.0  # reversing manoeuvre (RL) before the dwell, e.g. to the loader or tipping point
    mass_after_kg: float | None = None  # loading / unloading during the dwell
    start_gear: int | None = None  # gear to pull away in after the stop


class RoadPoint(NamedTuple):
    """The road at one place: grade (rise/run) and the speed the driver allows there."""

    grade: float
    v_allow_m_s: float


class Stop(NamedTuple):
    """A stop on the route: where (the end of its segment) and the segment that defines it."""

    x_m: float
    segment: Segment


class Route:
    """Grade, speed limit and stops on a 5 m grid along the driven path."""

    DX = 5.0

    def __init__(self, segments: list[Segment], rng: np.random.Generator, a_dec: float = 0.4):
        ends = np.cumsum([s.length_m for s in segments])
        starts = ends - np.array([s.length_m for s in segments])
        self.length_m = float(ends[-1])
        x = np.arange(0.0, self.length_m + self.DX, self.DX)
        idx = np.minimum(np.searchsorted(ends, x, side="right"), len(segments) - 1)
        self.x = x
        self.grade = _grade(segments, idx, x, rng, self.DX)
        self.altitude_m = np.concatenate([[0.0], np.cumsum(self.grade[:-1] * self.DX)])
        lim = np.array([s.limit_kmh for s in segments])[idx] / KMH_PER_M_S
        self.stops = [Stop(float(ends[i]), s) for i, s in enumerate(segments) if s.stop_s > 0]
        self.seg_starts = starts
        self.v_allow = _allowed_speed(lim, self.stops, self.DX, a_dec)
        self._v_list = self.v_allow.tolist()
        self._g_list = self.grade.tolist()

    def at(self, x_m: float) -> RoadPoint:
        i = min(int(x_m / self.DX), len(self._g_list) - 1)
        return RoadPoint(self._g_list[i], self._v_list[i])

    def v_allow_at(self, x_m: float) -> float:
        """The speed the driver allows at `x_m` [m/s]."""
        return self._v_list[min(int(x_m / self.DX), len(self._g_list) - 1)]

    def stop_after(self, index: int) -> Stop | None:
        """The `index`-th stop on the route, None when there are no more."""
        return self.stops[index] if index < len(self.stops) else None


def _grade(segments: list[Segment], idx: np.ndarray, x: np.ndarray, rng: np.random.Generator, dx_m: float):
    """Grade on the grid: the segments' grades smoothed over ~150 m, plus seeded small hills."""
    g_seg = np.array([s.grade for s in segments])
    # grade changes over ~150 m (a road has no kinks): smooth the piecewise-constant grade
    g = g_seg[idx]
    w = int(150 / dx_m)
    kern = np.ones(w) / w
    g = np.convolve(np.pad(g, (w // 2, w - 1 - w // 2), mode="edge"), kern, mode="valid")
    # small hills: a sum of three sinusoids of 1.5-6 km wavelength, seeded phases
    amp = np.array([s.hills for s in segments])[idx]
    if np.any(amp > 0):
        hill = np.zeros_like(x)
        for lam, a in ((6000.0, 0.5), (2900.0, 0.35), (1500.0, 0.25)):
            hill += a * np.sin(2 * np.pi * x / (lam * rng.uniform(0.8, 1.25)) + rng.uniform(0, 2 * np.pi))
        g = g + amp * hill / 1.1
    return g


def _allowed_speed(limit_m_s: np.ndarray, stops: list[Stop], dx_m: float, a_dec_m_s2: float) -> np.ndarray:
    """The speed the driver allows: limits ahead braked down at `a_dec_m_s2`; zero at every stop and at the end."""
    v = limit_m_s.copy()
    for xs, _ in stops:
        v[min(int(round(xs / dx_m)), len(v) - 1)] = 0.0
    v[-1] = 0.0
    step = 2.0 * a_dec_m_s2 * dx_m
    for i in range(len(v) - 2, -1, -1):
        vb = math.sqrt(v[i + 1] * v[i + 1] + step)
        if vb < v[i]:
            v[i] = vb
    return v
