"""The kinematics of any gearbox from its description (docs/description.md): every speed and mesh load of each gear.

For each gear of a :class:`~firmware_model.description.Description` the speed of every shaft, wheel and planetary
member per unit input speed is the solution of a linear system of constraints (seed section 2.3 for the GRS905):

- the input shaft turns at 1; the casing (``housing``) and a held planetary member stand;
- a fixed or cut wheel turns with its shaft, a sun with the sun's shaft, a carrier is its shaft; an idle wheel turns
  with its shaft only when an engaged coupling joins them, else its meshes set its speed; an engaged coupling makes
  its members equal, a ``locked`` planetary set turns as one body (these ties merge members into one unknown, so
  engaged members turn exactly alike);
- a mesh relates its wheels' speeds relative to the carrier of their axes (0 for fixed axes and for an idler on a
  pin): z_a (w_a - w_c) + z_b (w_b - w_c) = 0 for an external mesh, z_a (w_a - w_c) - z_b (w_b - w_c) = 0 for an
  internal one (the Willis equation of a planetary set, its meshes written once each);
- a member nothing determines (the main shaft in neutral) stands: the free unknowns are set to 0 in the
  description's order (shafts, wheels, planetary members) until the system has one solution.

The load of each mesh follows the gear's power path with losses neglected: the torque on the member carrying the
power starts at 1 on the input shaft, a coupling passes it on, a mesh multiplies it by z_out / z_in, a planetary set
splits it by its teeth (sun : ring : carrier = 1 : z_r/z_s : 1 + z_r/z_s). A mesh's load is the torque on its wheel
1 (the sum over a set's planets for a planetary mesh), its speed that of its wheel 2 relative to the carrier.

:func:`kinematic_table` lays the gears out as the :class:`~firmware_model.physics.kinematics.KinematicTable` the
plant and the onboard model index (one row per gear number GEAR_MIN..GEAR_MAX); :func:`kinematics_of` is that table
for a parameter set's own description.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from firmware_model.description import CASING, Description, description_of
from firmware_model.errors import ParameterError
from firmware_model.parameters import Parameters
from firmware_model.physics.kinematics import GEAR_MAX, GEAR_MIN, N_GEARS, KinematicTable

#: a relative speed this small (per unit input speed) is a rounding residue of the solve: the members turn alike
REL_ZERO = 1e-12


@dataclass(frozen=True)
class GearKinematics:
    """One gear of a description, per unit input speed and per unit input torque."""

    name: str
    number: int
    speed: dict  # member id -> speed (shafts, wheels, planetary members; a carrier is its shaft)
    planet_rel: dict  # planetary set id -> speed of its planets relative to the carrier
    mesh_torque: dict  # mesh id -> torque on its wheel 1 (all planets together), 0 when it carries no power
    mesh_omega2: dict  # mesh id -> |speed of its wheel 2 relative to the carrier| when loaded, else 0
    ratio: float  # input speed / output speed (inf: neutral)
    low_range: bool  # a planetary set of the path is held (not locked): its meshes carry the power
    driver: dict  # loaded mesh id -> (its driving wheel, the torque on it), in the path's order


class _Members:
    """The unknowns: every member, merged into classes by the rigid ties of one gear."""

    def __init__(self, d: Description):
        ids = [s.id for s in d.shafts] + [w.id for w in d.wheels]
        ids += [m for ps in d.planetary for m in (ps.sun, ps.planet, ps.ring)] + [CASING]
        self.ids = ids
        self.parent = {i: i for i in ids}

    def find(self, i: str) -> str:
        while self.parent[i] != i:
            self.parent[i] = self.parent[self.parent[i]]
            i = self.parent[i]
        return i

    def tie(self, a: str, b: str) -> None:
        ra, rb = self.find(a), self.find(b)
        if ra != rb:  # the earlier member (in the description's order) names the class
            first, second = sorted((ra, rb), key=self.ids.index)
            self.parent[second] = first


def _carrier_of(d: Description) -> dict:
    """Planetary member -> the carrier's shaft of its set (a wheel on a fixed axis has none)."""
    return {m: ps.carrier_shaft for ps in d.planetary for m in (ps.sun, ps.planet, ps.ring)}


def _teeth(d: Description) -> dict:
    z = {w.id: w.teeth for w in d.wheels}
    for ps in d.planetary:
        z.update({ps.sun: ps.z_sun, ps.planet: ps.z_planet, ps.ring: ps.z_ring})
    return z


def _on_shaft(d: Description) -> dict:
    """Wheel or sun -> the shaft it turns with (fixed, cut, a sun on its shaft)."""
    out = {w.id: w.shaft for w in d.wheels if w.mount in ("fixed", "cut")}
    out.update({ps.sun: ps.sun_shaft for ps in d.planetary})
    return out


class _PathLoads:
    """Follows a gear's power path (already checked by the description's loader): the ties it engages, the members
    it holds, and the torque on every loaded mesh's wheel 1."""

    def __init__(self, d: Description, start: str):
        self.d, self.at, self.torque = d, start, 1.0
        self.z, self.shaft_of = _teeth(d), _on_shaft(d)
        self.couplings = {c.id: c for c in d.couplings}
        self.meshes = {m.id: m for m in d.meshes}
        self.sets = {ps.id: ps for ps in d.planetary}
        self.ties, self.held, self.mesh_torque, self.driver = [], [], {}, {}

    def carried(self, wheel: str) -> bool:
        return self.at == wheel or self.shaft_of.get(wheel) == self.at

    def step(self, s: str) -> None:
        if s in self.couplings:
            other = next(j for j in self.couplings[s].joins if j != self.at)
            self.ties.append((self.at, other))
            self.at = other
        elif s in self.meshes:
            a, b = self.meshes[s].wheels
            w_in, w_out = (a, b) if self.carried(a) else (b, a)
            # torque on wheel 1: the driving torque, or the driven wheel's (same tooth force, z_1 / z_in)
            self.mesh_torque[s] = self.torque if w_in == a else self.torque * self.z[a] / self.z[w_in]
            self.driver[s] = (w_in, self.torque)
            self.torque = self.torque * self.z[w_out] / self.z[w_in]
            self.at = self.shaft_of.get(w_out, w_out)
        else:
            self.planet_step(*s.partition("/")[::2])

    def planet_step(self, pid: str, held: str) -> None:
        ps = self.sets[pid]
        where = {ps.sun_shaft: "sun", ps.sun: "sun", ps.carrier_shaft: "carrier", ps.ring: "ring"}
        into = where[self.at]
        out = next(m for m in ("carrier", "sun", "ring") if m not in (into, held))
        self.held.append((pid, held))
        self.at = {"sun": ps.sun_shaft, "carrier": ps.carrier_shaft, "ring": ps.ring}[out]
        if held == "locked":  # one body: the torque passes, the set's meshes carry nothing
            return
        # torques of sun : ring : carrier = 1 : z_r/z_s : 1 + z_r/z_s (losses neglected)
        share = {"sun": 1.0, "ring": ps.z_ring / ps.z_sun, "carrier": 1.0 + ps.z_ring / ps.z_sun}
        t_sun = self.torque if into == "sun" else self.torque / share[into]
        for m in self.meshes.values():
            a = m.wheels[0]
            if set(m.wheels) <= {ps.sun, ps.planet, ps.ring}:
                self.mesh_torque[m.id] = t_sun if a == ps.sun else t_sun * self.z[a] / ps.z_sun
        self.torque = t_sun if out == "sun" else t_sun * share[out]


def _constraints(d: Description, mem: _Members, walk: _PathLoads):
    """Ties of the gear merged into ``mem``; (known class values, mesh equations as {class: coefficient})."""
    for w in d.wheels:
        if w.mount in ("fixed", "cut"):
            mem.tie(w.shaft, w.id)
    for ps in d.planetary:
        mem.tie(ps.sun_shaft, ps.sun)
    for a, b in walk.ties:
        mem.tie(a, b)
    known = {mem.find(CASING): 0.0}
    for pid, held in walk.held:
        ps = walk.sets[pid]
        if held == "locked":
            mem.tie(ps.carrier_shaft, ps.sun)
            mem.tie(ps.carrier_shaft, ps.ring)
    for pid, held in walk.held:
        ps = walk.sets[pid]
        if held != "locked":
            member = {"sun": ps.sun, "ring": ps.ring, "carrier": ps.carrier_shaft}[held]
            known[mem.find(member)] = 0.0
    known = {mem.find(k): v for k, v in known.items()}
    start = mem.find(d.drive.input_shaft)
    if known.get(start, 1.0) != 1.0:
        raise ParameterError(f"{d.origin}: the input shaft {d.drive.input_shaft} is held to the casing")
    known[start] = 1.0
    carrier, z = _carrier_of(d), _teeth(d)
    equations = []
    for m in d.meshes:
        a, b = m.wheels
        c = carrier.get(a, carrier.get(b))
        eq: dict = {}
        for w, sign in ((a, 1.0), (b, -1.0 if m.internal else 1.0)):
            eq[mem.find(w)] = eq.get(mem.find(w), 0.0) + sign * z[w]
            if c is not None:
                eq[mem.find(c)] = eq.get(mem.find(c), 0.0) - sign * z[w]
        equations.append(eq)
    return known, equations


def _solve(classes: list, known: dict, equations: list, where: str) -> dict:
    """Values of every class: the known ones, the rest from the mesh equations (free ones stand)."""
    free = [c for c in classes if c not in known]
    col = {c: i for i, c in enumerate(free)}
    A = np.zeros((len(equations), len(free)))
    rhs = np.zeros(len(equations))
    for r, eq in enumerate(equations):
        for c, k in eq.items():
            if c in col:
                A[r, col[c]] += k
            else:
                rhs[r] -= k * known[c]
    pinned: list = []
    while free:
        M = np.vstack([A, np.eye(len(free))[pinned]]) if pinned else A
        _, sv, vt = np.linalg.svd(M) if M.size else (None, np.zeros(0), np.eye(len(free)))
        rank = int(np.sum(sv > 1e-9 * max(1.0, sv.max(initial=0.0))))
        if rank == len(free):
            break
        null = vt[rank:]
        pinned.append(next(i for i in range(len(free)) if np.max(np.abs(null[:, i])) > 1e-9))
    M = np.vstack([A, np.eye(len(free))[pinned]]) if pinned else A
    b = np.concatenate([rhs, np.zeros(len(pinned))])
    x = np.linalg.lstsq(M, b, rcond=None)[0] if free else np.zeros(0)
    if free and np.max(np.abs(M @ x - b), initial=0.0) > 1e-9:
        raise ParameterError(f"{where} locks up: its meshes and couplings allow no motion of the input shaft")
    out = dict(known)
    out.update({c: (0.0 if abs(v) < REL_ZERO else float(v)) for c, v in zip(free, x)})
    return out


def gear_kinematics(d: Description, gear) -> GearKinematics:
    """The speeds and mesh loads of one gear of a description (per unit input speed and torque)."""
    walk = _PathLoads(d, d.drive.input_shaft)
    for s in gear.path:
        walk.step(s)
    mem = _Members(d)
    known, equations = _constraints(d, mem, walk)
    classes = list(dict.fromkeys(mem.find(i) for i in mem.ids))
    value = _solve(classes, known, equations, f"{d.origin}: topology.gear.{gear.name}")
    speed = {i: value[mem.find(i)] for i in mem.ids if i != CASING}
    carrier = _carrier_of(d)
    planet_rel = {ps.id: _rel(speed[ps.planet], speed[ps.carrier_shaft]) for ps in d.planetary}
    torque, omega2 = {}, {}
    for m in d.meshes:
        t = walk.mesh_torque.get(m.id, 0.0) if m.id in gear.meshes else 0.0  # neutral transmits nothing
        torque[m.id] = t
        w2 = m.wheels[1]
        omega2[m.id] = abs(_rel(speed[w2], speed[carrier[w2]] if w2 in carrier else 0.0)) if t else 0.0
    w_out = speed[d.drive.output_shaft]
    ratio = 1.0 / w_out if gear.number != 0 and w_out != 0 else math.inf
    low = any(h != "locked" for _, h in walk.held)
    driver = {m: v for m, v in walk.driver.items() if m in gear.meshes}
    return GearKinematics(gear.name, gear.number, speed, planet_rel, torque, omega2, ratio, low, driver)


def _rel(a: float, b: float) -> float:
    """a - b, 0 when it is a rounding residue of the solve."""
    r = a - b
    return 0.0 if abs(r) <= REL_ZERO * max(1.0, abs(a), abs(b)) else r


def speed_names(d: Description) -> tuple:
    """The speed columns: the shafts, the idle wheels and idlers on pins, each planetary set's sun, planets relative
    to the carrier (``<planet>_rel``) and ring (the GRS905's: kinematics.SPEED_NAMES)."""
    out = [s.id for s in d.shafts] + [w.id for w in d.wheels if w.mount in ("idle", "pin")]
    out += [n for ps in d.planetary for n in (ps.sun, f"{ps.planet}_rel", ps.ring)]
    return tuple(out)


def _row(d: Description, g: GearKinematics, names: tuple) -> tuple:
    rel = {f"{ps.planet}_rel": g.planet_rel[ps.id] for ps in d.planetary}
    speed = [rel[n] if n in rel else g.speed[n] for n in names]
    wheel_shaft = {w.id: w.shaft for w in d.wheels}
    needle = [abs(_rel(g.speed[b.wheel], g.speed[wheel_shaft[b.wheel]])) for b in d.bearings if b.wheel is not None]
    # a synchronizer drags at the relative speed of each side it does not engage (0 on an engaged side)
    sync = []
    for c in d.couplings:
        if c.kind == "sync":
            first, others = c.joins[0], c.joins[1:]
            sides = [abs(_rel(g.speed[first], g.speed.get(o, 0.0))) for o in others]
            sync.append(sum(sides[1:], sides[0]))
    meshes = [m.id for m in d.meshes]
    return (
        speed,
        [g.mesh_torque[m] for m in meshes],
        [g.mesh_omega2[m] for m in meshes],
        needle,
        sync,
        [g.mesh_torque[m] != 0 for m in meshes],
    )


def kinematic_table(d: Description, split_inverted: bool = False) -> KinematicTable:
    """Every gear of a description as the table the plant and the onboard model index: one row per gear number
    GEAR_MIN..GEAR_MAX (a number the description has no gear for takes neutral's row, or, without a neutral, a
    standing gearbox's); ``active_pair`` is per mesh (the description's order)."""
    for g in d.gears:
        if not GEAR_MIN <= g.number <= GEAR_MAX:
            raise ParameterError(
                f"{d.origin}: topology.gear.{g.name}.number = {g.number} is outside the gear input's range "
                f"{GEAR_MIN}..{GEAR_MAX}"
            )
    names = speed_names(d)
    by_number = {g.number: gear_kinematics(d, g) for g in d.gears}
    rows = {n: _row(d, g, names) for n, g in by_number.items()}
    n_m = len(d.meshes)
    n_b = sum(b.wheel is not None for b in d.bearings)
    n_s = sum(c.kind == "sync" for c in d.couplings)
    standing = ([0.0] * len(names), [0.0] * n_m, [0.0] * n_m, [0.0] * n_b, [0.0] * n_s, [False] * n_m)
    table = [rows.get(n, rows.get(0, standing)) for n in range(GEAR_MIN, GEAR_MAX + 1)]
    ratio = [by_number[n].ratio if n in by_number else math.inf for n in range(GEAR_MIN, GEAR_MAX + 1)]
    low = [by_number[n].low_range if n in by_number else False for n in range(GEAR_MIN, GEAR_MAX + 1)]
    cols = list(zip(*table))
    assert len(table) == N_GEARS
    return KinematicTable(
        names,
        np.array(cols[0], dtype=float),
        np.array(cols[1], dtype=float),
        np.array(cols[2], dtype=float),
        np.array(cols[3], dtype=float).reshape(N_GEARS, n_b),
        np.array(cols[4], dtype=float).reshape(N_GEARS, n_s),
        np.array(cols[5], dtype=bool),
        np.array(ratio, dtype=float),
        np.array(low, dtype=bool),
        split_inverted,
    )


def kinematics_of(p: Parameters) -> KinematicTable:
    """The kinematic table of a parameter set's own gearbox (its description: description_of), kept with the set."""
    kin = p.__dict__.get("_kin_description")
    if kin is None:
        kin = kinematic_table(description_of(p), p.split_inverted)
        p.__dict__["_kin_description"] = kin
    return kin
