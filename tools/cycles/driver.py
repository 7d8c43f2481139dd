"""The driver of the synthetic road cycles: follows a route with the truck, shifts, stops, reverses.

A state machine stepped at the vehicle model's own step (:data:`VEHICLE_STEP_S`, 10 Hz; the cycle tables are
resampled to the requested rate afterwards, and this step has nothing to do with the onboard sensor's step):

* ``stopped``: idling in neutral for the dwell of a stop (loading or unloading on the way), then pulling away;
* ``reverse``: a trapezoidal reversing manoeuvre in RL with pauses in neutral, before the dwell of some stops;
* ``launch``: pulling away on a slipping clutch at ~1000 rpm until the gear's synchronous speed catches up;
* ``drive``: tracking the speed the route allows with engine torque, engine brake, retarder and service brakes,
  and the automated shift strategy (:func:`choose_gear`);
* ``shift``: the torque interruption of a gear change (0.6 s, range changes 1.0 s);
* ``coast``: below the lowest gear's speed while stopping: neutral, on the brakes to the stop point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from tools.cycles.route import Route, Segment, Stop
from tools.cycles.vehicle import (
    G_M_S2,
    IDLE_RPM,
    KMH_PER_M_S,
    Drivetrain,
    Vehicle,
    engine_max_torque_nm,
    engine_min_torque_nm,
)

#: the vehicle model's own time step (10 Hz); the cycle tables are resampled from it to the requested rate
VEHICLE_STEP_S = 0.1
#: gears the shift strategy uses on the road (crawler only to pull away)
ROAD_GEARS = tuple(range(3, 15))
#: engine speed the clutch holds while pulling away
LAUNCH_RPM = 1000.0
#: reverse gear (RL)
REVERSE_GEAR = -2


class Shift(NamedTuple):
    """A gear change under way: from, to, time into it, its duration, the engine torque when it began."""

    gear_from: int
    gear_to: int
    elapsed_s: float
    duration_s: float
    torque0_nm: float


class SpeedTarget(NamedTuple):
    """The speed the driver aims at a moment ahead and the acceleration that gets there."""

    v_target_m_s: float
    a_des_m_s2: float


@dataclass(frozen=True)
class DriveTrace:
    """What the driver did, at every VEHICLE_STEP_S."""

    time_s: np.ndarray
    engine_speed_rpm: np.ndarray
    engine_torque_nm: np.ndarray
    gear: np.ndarray
    vehicle_speed_kmh: np.ndarray
    retarder_torque_nm: np.ndarray
    distance_m: np.ndarray
    grade: np.ndarray
    altitude_m: np.ndarray


@dataclass(slots=True)
class DriverState:
    """The driver's and the truck's state along the route (mutable: stepped in place)."""

    mass_kg: float
    dwell_s: float
    next_start_gear: int | None
    x_m: float = 0.0
    v_m_s: float = 0.0
    mode: str = "stopped"
    gear: int = 0
    torque_nm: float = 0.0
    rpm: float = IDLE_RPM
    retarder_nm: float = 0.0
    stop_index: int = 0  # index of the next stop on the route
    pending_stop: Segment | None = None
    since_shift_s: float = 10.0
    shift: Shift | None = None
    reverse: list = field(default_factory=list)  # (v, a) samples (None: a pause) of a reversing manoeuvre

    def idle(self) -> None:
        """Neutral, idling, no retarder."""
        self.gear, self.torque_nm, self.rpm, self.retarder_nm = 0, 0.0, IDLE_RPM, 0.0


def upshift_rpm(load: float) -> float:
    """Upshift above this engine speed (light load early, full load late)."""
    return 1150.0 + 500.0 * load


def downshift_rpm(load: float) -> float:
    """Downshift below this engine speed: the strategy keeps a loaded engine above ~1200 rpm."""
    return 850.0 + 350.0 * load


def max_accel_m_s2(v_m_s: float) -> float:
    return max(0.15, 0.6 - 0.4 * v_m_s / 25.0)


def speed_target(route: Route, st: DriverState, v_allow_m_s: float, lookahead_s: float) -> SpeedTarget:
    """Aim at the speed allowed here and `lookahead_s` ahead; accelerate towards it within the truck's limits."""
    v = st.v_m_s
    v_t = min(v_allow_m_s, route.v_allow_at(st.x_m + v * lookahead_s))
    return SpeedTarget(v_t, min(max((v_t - v) * 0.4, -0.8), max_accel_m_s2(v)))


# ----------------------------------------------------------------------------------------------------------------
# the modes


def step_stopped(st: DriverState, drivetrain: Drivetrain, grade: float, route: Route) -> None:
    """Idle for the dwell; then load/unload and pull away (or idle to the end at the end of the route)."""
    st.idle()
    st.v_m_s = 0.0
    st.dwell_s -= VEHICLE_STEP_S
    if st.dwell_s <= 0:
        if st.pending_stop is not None and st.pending_stop.mass_after_kg:
            st.mass_kg = st.pending_stop.mass_after_kg
        g0 = st.next_start_gear if st.next_start_gear else drivetrain.start_gear_for(grade, st.mass_kg)
        st.next_start_gear = None
        st.pending_stop = None
        if st.x_m >= route.length_m - 1.0:
            st.dwell_s = math.inf  # end of the route: idle until the end
        else:
            st.mode, st.gear, st.since_shift_s = "launch", g0, 0.0


def step_reverse(st: DriverState, drivetrain: Drivetrain) -> bool:
    """One sample of the reversing manoeuvre; True on a pause in neutral (the truck does not move this step)."""
    veh = drivetrain.vehicle
    item = st.reverse.pop(0)
    if item is None:  # a pause in neutral before and after reversing
        st.idle()
        st.v_m_s = 0.0
        if not st.reverse:
            st.mode = "stopped"
        return True
    vr, ar = item
    st.gear = REVERSE_GEAR
    f = (
        st.mass_kg * (1.0 + veh.rotating_mass_factor) * ar
        + st.mass_kg * G_M_S2 * veh.crr
        + 0.5 * veh.rho_air_kg_m3 * veh.cda_m2 * vr * vr
    )
    st.torque_nm = max(drivetrain.torque_for_nm(f, REVERSE_GEAR), 0.0) if f > 0 else 0.0
    st.rpm = max(drivetrain.sync_rpm(REVERSE_GEAR, vr), 800.0)
    st.v_m_s, st.retarder_nm = vr, 0.0
    if not st.reverse:
        st.mode = "stopped"
    return False


def step_launch(st: DriverState, drivetrain: Drivetrain, grade: float, v_allow_m_s: float) -> None:
    """Clutch slipping: engine held at LAUNCH_RPM until the gear's synchronous speed catches up."""
    v, gear = st.v_m_s, st.gear
    f_road = drivetrain.road_force_n(v, grade, st.mass_kg)
    a_des = min(0.5, max(0.05, (v_allow_m_s - v) * 0.5))
    m_eq = drivetrain.equivalent_mass_kg(None, st.mass_kg)
    t_req = drivetrain.torque_for_nm(m_eq * a_des + f_road, gear)
    st.torque_nm = min(max(t_req, 200.0), engine_max_torque_nm(LAUNCH_RPM, gear))
    a = (drivetrain.wheel_force_n(st.torque_nm, gear) - f_road) / drivetrain.equivalent_mass_kg(None, st.mass_kg)
    st.v_m_s = max(v + a * VEHICLE_STEP_S, 0.0)
    st.retarder_nm = 0.0
    s = drivetrain.sync_rpm(gear, st.v_m_s)
    st.rpm = max(s, LAUNCH_RPM)
    if s >= LAUNCH_RPM:
        st.mode = "drive"
    st.since_shift_s = 0.0


class Engaged(NamedTuple):
    """The gear that carries engine torque in a shift (None: none) and that torque."""

    gear: int | None
    torque_nm: float


def _shift_torque(
    st: DriverState, drivetrain: Drivetrain, route: Route, sh: Shift, p: float, f_road: float, v_allow_m_s: float
) -> Engaged:
    """Engaged gear and engine torque in the interruption: ramp down, zero, ramp up to the demand."""
    if p < 0.25:
        return Engaged(sh.gear_from, sh.torque0_nm * (1.0 - p / 0.25))
    if p < 0.75:
        return Engaged(None, 0.0)
    v = st.v_m_s
    target = speed_target(route, st, v_allow_m_s, 1.0)
    m_eq = drivetrain.equivalent_mass_kg(sh.gear_to, st.mass_kg)
    t_req = drivetrain.torque_for_nm(m_eq * target.a_des_m_s2 + f_road, sh.gear_to)
    s = drivetrain.sync_rpm(sh.gear_to, v)
    t_req = min(max(t_req, engine_min_torque_nm(s)), engine_max_torque_nm(s, sh.gear_to))
    return Engaged(sh.gear_to, t_req * (p - 0.75) / 0.25)


def step_shift(st: DriverState, drivetrain: Drivetrain, route: Route, grade: float, v_allow_m_s: float) -> None:
    """One step of the torque interruption; the gear signal changes half way, the engine moves between the two
    synchronous speeds; the retarder and the service brakes keep working."""
    sh = st.shift
    sh = sh._replace(elapsed_s=sh.elapsed_s + VEHICLE_STEP_S)
    p = sh.elapsed_s / sh.duration_s
    v = st.v_m_s
    f_road = drivetrain.road_force_n(v, grade, st.mass_kg)
    g_eng, st.torque_nm = _shift_torque(st, drivetrain, route, sh, p, f_road, v_allow_m_s)
    f = drivetrain.wheel_force_n(st.torque_nm, g_eng) if g_eng else 0.0
    meq = drivetrain.equivalent_mass_kg(g_eng, st.mass_kg)
    target = speed_target(route, st, v_allow_m_s, 1.5)
    f_brk = max(f - f_road - meq * target.a_des_m_s2, 0.0)
    veh = drivetrain.vehicle
    st.retarder_nm = min(f_brk * veh.wheel_radius_m / veh.final_drive, drivetrain.retarder_available_nm(v))
    a = (f - f_road - f_brk) / meq
    v = max(v + a * VEHICLE_STEP_S, 0.0)
    st.v_m_s = v
    s0, s1 = drivetrain.sync_rpm(sh.gear_from, v), drivetrain.sync_rpm(sh.gear_to, v)
    rpm = s0 if p < 0.25 else (s1 if p >= 0.75 else s0 + (s1 - s0) * (p - 0.25) / 0.5)
    st.rpm = max(rpm, IDLE_RPM)
    st.gear = sh.gear_from if p < 0.5 else sh.gear_to
    st.shift = sh
    if sh.elapsed_s >= sh.duration_s - 1e-9:
        st.mode, st.shift, st.since_shift_s = "drive", None, 0.0


def step_coast(st: DriverState, drivetrain: Drivetrain, grade: float, target: SpeedTarget, x_stop_m: float) -> None:
    """Neutral on the brakes towards the stop point; pull away again when the road ahead allows it."""
    st.idle()
    v = st.v_m_s
    if x_stop_m - st.x_m > 30.0 and target.v_target_m_s > v + 0.5:
        st.mode, st.gear, st.since_shift_s = "launch", drivetrain.start_gear_for(grade, st.mass_kg), 0.0
    else:
        # creep on to the stop point on the brakes
        v_c = max(target.v_target_m_s, 0.8) if x_stop_m - st.x_m > 2.0 else 0.0
        st.v_m_s = max(v + min(max((v_c - v) * 0.5, -1.0), 0.3) * VEHICLE_STEP_S, 0.0)


class Traction(NamedTuple):
    """The force balance of one driving step."""

    f_need_n: float  # force the target acceleration needs
    t_req_nm: float  # engine torque for it
    t_max_nm: float  # the engine's full load at this speed
    deficit_n: float  # f_need - engine force (< 0: braking needed)


def step_drive(st: DriverState, drivetrain: Drivetrain, grade: float, target: SpeedTarget) -> Traction:
    """Track the target with engine torque; brake with the retarder first, then the service brakes."""
    veh = drivetrain.vehicle
    gear, v = st.gear, st.v_m_s
    f_road = drivetrain.road_force_n(v, grade, st.mass_kg)
    meq = drivetrain.equivalent_mass_kg(gear, st.mass_kg)
    f_need = meq * target.a_des_m_s2 + f_road
    t_req = drivetrain.torque_for_nm(f_need, gear)
    rpm = drivetrain.sync_rpm(gear, v)
    t_hi = engine_max_torque_nm(rpm, gear)
    t_lo = engine_min_torque_nm(rpm)
    st.torque_nm = min(max(t_req, t_lo), t_hi)
    f_eng = drivetrain.wheel_force_n(st.torque_nm, gear)
    deficit = f_need - f_eng
    ret_nm, f_brake = 0.0, 0.0
    if deficit < 0:
        f_ret = min(-deficit, drivetrain.retarder_available_nm(v) * veh.final_drive / veh.wheel_radius_m)
        ret_nm = f_ret * veh.wheel_radius_m / veh.final_drive
        f_brake = -deficit - f_ret
    st.retarder_nm = ret_nm
    a = (f_eng - ret_nm * veh.final_drive / veh.wheel_radius_m - f_brake - f_road) / meq
    st.v_m_s = max(v + a * VEHICLE_STEP_S, 0.0)
    st.since_shift_s += VEHICLE_STEP_S
    st.rpm = max(drivetrain.sync_rpm(gear, st.v_m_s), 0.0)
    return Traction(f_need, t_req, t_hi, deficit)


class GearChoice(NamedTuple):
    """The shift strategy's answer: a new gear (None: keep) and whether to drop to neutral and coast."""

    gear: int | None
    coast: bool


def _upshift(drivetrain: Drivetrain, gear: int, tr: Traction, cand: dict) -> int | None:
    """The highest of up to two gears up that carries the demand with margin at a comfortable speed."""
    for g in range(min(gear + 2, 14), gear, -1):
        tg = drivetrain.torque_for_nm(tr.f_need_n, g)
        tmax_g = engine_max_torque_nm(cand[g], g)
        if (
            tg <= 0.85 * tmax_g
            and tg >= engine_min_torque_nm(cand[g])
            and cand[g] >= downshift_rpm(max(tg, 0.0) / tmax_g) + 100.0
        ):
            return g
    return None


def _downshift(drivetrain: Drivetrain, gear: int, rpm: float, tr: Traction, cand: dict) -> GearChoice:
    """The highest lower road gear that carries the demand, else the strongest; coast below 650 rpm when none is
    left."""
    lower = [g for g in ROAD_GEARS if g < gear and cand[g] <= 1800.0]
    ok = [g for g in lower if drivetrain.torque_for_nm(tr.f_need_n, g) <= 0.95 * engine_max_torque_nm(cand[g], g)]
    if ok:
        return GearChoice(max(ok), False)
    if lower:
        strongest = max(lower, key=lambda g: drivetrain.wheel_force_n(engine_max_torque_nm(cand[g], g), g))
        return GearChoice(strongest, False)
    return GearChoice(None, rpm < 650.0)


def choose_gear(st: DriverState, drivetrain: Drivetrain, grade: float, target: SpeedTarget, tr: Traction) -> GearChoice:
    """The automated shift strategy, at most every 2 s unless the engine speed leaves 800..1950 rpm."""
    rpm, gear, v = st.rpm, st.gear, st.v_m_s
    new, coast = None, False
    load = st.torque_nm / tr.t_max_nm if st.torque_nm > 0 else 0.0
    if not (st.since_shift_s > 2.0 or rpm > 1950.0 or rpm < 800.0):
        return GearChoice(None, False)
    cand = {g: drivetrain.sync_rpm(g, v) for g in range(1, 15)}
    if rpm > 1950.0:
        new = min(gear + 1, 14)
    if new is None and rpm > upshift_rpm(load) and gear < 14:
        new = _upshift(drivetrain, gear, tr, cand)
    if new is None and (
        rpm < downshift_rpm(load)
        or (tr.t_req_nm > 0.98 * tr.t_max_nm and rpm < 1500.0 and target.v_target_m_s > v + 0.3)
    ):
        new, coast = _downshift(drivetrain, gear, rpm, tr, cand)
    if new is None and tr.deficit_n < -1.0 and grade < -0.02 and gear > 3:
        # long descent: a lower gear for more engine brake, if the engine can take the speed
        if cand[gear - 1] <= 1750.0:
            new = gear - 1
    return GearChoice(new, coast)


def step_drive_or_coast(
    st: DriverState, drivetrain: Drivetrain, route: Route, grade: float, v_allow_m_s: float, x_stop_m: float
) -> None:
    """Drive (and perhaps start a shift or drop to coasting), or coast towards a stop."""
    target = speed_target(route, st, v_allow_m_s, 1.5)  # the allowed speed here and a second and a half ahead
    if st.mode == "coast":
        step_coast(st, drivetrain, grade, target, x_stop_m)
        return
    tr = step_drive(st, drivetrain, grade, target)
    choice = choose_gear(st, drivetrain, grade, target, tr)
    if choice.coast:
        st.mode = "coast"
    if choice.gear is not None and choice.gear != st.gear and st.mode == "drive":
        dur = 1.0 if (choice.gear >= 9) != (st.gear >= 9) else 0.6
        st.mode, st.shift = "shift", Shift(st.gear, choice.gear, 0.0, dur, st.torque_nm)
    if st.mode == "coast":
        st.idle()


def reverse_profile(distance_m: float, v_kmh: float = 4.0, a_m_s2: float = 0.3) -> list:
    """(speed, acceleration) samples at VEHICLE_STEP_S of a trapezoidal reversing manoeuvre over `distance_m`, with
    3 s in neutral (None samples) before and after."""
    vmax = v_kmh / KMH_PER_M_S
    t_ramp = vmax / a_m_s2
    d_ramps = vmax * t_ramp
    t_const = max(distance_m - d_ramps, 0.0) / vmax
    total = 2 * t_ramp + t_const
    pause = [None] * int(round(3.0 / VEHICLE_STEP_S))
    out = list(pause)
    for i in range(int(math.ceil(total / VEHICLE_STEP_S))):
        t = i * VEHICLE_STEP_S
        if t < t_ramp:
            out.append((a_m_s2 * t, a_m_s2))
        elif t < t_ramp + t_const:
            out.append((vmax, 0.0))
        else:
            out.append((max(vmax - a_m_s2 * (t - t_ramp - t_const), 0.0), -a_m_s2))
    out.append((0.0, 0.0))
    return out + pause


def advance(st: DriverState, route: Route, stop: Stop | None) -> None:
    """Move along the route; arrive at a stop (reversing to it first where the stop says so) or at the end."""
    st.x_m += st.v_m_s * VEHICLE_STEP_S
    if st.mode in ("drive", "coast", "shift") and stop is not None and stop.x_m - st.x_m < 3.0 and st.v_m_s < 1.5:
        seg = stop.segment
        st.x_m, st.v_m_s = stop.x_m, 0.0
        st.mode, st.shift = "stopped", None
        st.idle()
        st.dwell_s = seg.stop_s
        st.pending_stop = seg
        st.next_start_gear = seg.start_gear
        st.stop_index += 1
        if seg.reverse_m > 0:
            st.reverse = reverse_profile(seg.reverse_m)
            st.mode = "reverse"
    elif st.x_m >= route.length_m - 1.0 and st.mode != "stopped":
        st.mode, st.dwell_s, st.v_m_s = "stopped", math.inf, 0.0
        st.idle()


def step(st: DriverState, drivetrain: Drivetrain, route: Route) -> None:
    """One VEHICLE_STEP_S of the driver in its current mode, then the move along the route."""
    road = route.at(st.x_m)
    stop = route.stop_after(st.stop_index)
    if st.mode == "stopped":
        step_stopped(st, drivetrain, road.grade, route)
    elif st.mode == "reverse":
        if step_reverse(st, drivetrain):
            return  # a pause in neutral: the truck stands
    elif st.mode == "launch":
        step_launch(st, drivetrain, road.grade, road.v_allow_m_s)
    elif st.mode == "shift":
        step_shift(st, drivetrain, route, road.grade, road.v_allow_m_s)
    elif st.mode in ("drive", "coast"):
        step_drive_or_coast(st, drivetrain, route, road.grade, road.v_allow_m_s, stop.x_m if stop else math.inf)
    advance(st, route, stop)


def drive(
    segments: list[Segment],
    vehicle: Vehicle,
    duration_s: float,
    rng: np.random.Generator,
    idle_start_s: float = 20.0,
    first_gear: int | None = None,
) -> DriveTrace:
    """Drive along the route for `duration_s`, starting with `idle_start_s` idling; the trace at VEHICLE_STEP_S."""
    route = Route(segments, rng)
    drivetrain = Drivetrain.of(vehicle)
    n = int(round(duration_s / VEHICLE_STEP_S))
    rpm, tq, gear, v, ret, x = (np.empty(n) for _ in range(6))
    st = DriverState(mass_kg=vehicle.mass_kg, dwell_s=idle_start_s, next_start_gear=first_gear)
    for k in range(n):
        step(st, drivetrain, route)
        rpm[k], tq[k], gear[k], v[k], ret[k], x[k] = st.rpm, st.torque_nm, st.gear, st.v_m_s, st.retarder_nm, st.x_m
    return DriveTrace(
        time_s=np.arange(n) / round(1.0 / VEHICLE_STEP_S),
        engine_speed_rpm=rpm,
        engine_torque_nm=tq,
        gear=gear,
        vehicle_speed_kmh=v * KMH_PER_M_S,
        retarder_torque_nm=ret,
        distance_m=x,
        grade=np.interp(x, route.x, route.grade),
        altitude_m=np.interp(x, route.x, route.altitude_m),
    )
