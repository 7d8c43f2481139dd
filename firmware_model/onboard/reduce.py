"""The onboard model: the full thermal network and loss model, rebuilt as cheap, fixed-size tables for a 10 Hz
explicit step, with a stability guarantee checked when the parameters load.

Everything here is derived by code from the same description the reference plant integrates
(:func:`firmware_model.network.build_network`, :class:`~firmware_model.network.ConductanceEvaluator`,
:class:`~firmware_model.physics.gearbox_losses.GearboxLosses`): no number is copied by hand. The cooler
(:func:`cooler_heat` over :func:`firmware_model.physics.cooler.oil_cooler_heat`), the heat lag
(:mod:`firmware_model.physics.heat_lag`, coefficients in ``helpers(rp).heat_lag``) and the conductance matrix
(:func:`firmware_model.physics.conductance_matrix.conductance_matrix` of ``helpers(rp).topology``) are the plant's.

Reduction (docs/sensor.md, "Reduction")
---------------------------------------
* **Nodes by aggregation.** A *partition* maps every full node to a reduced node. A reduced node's heat capacity is
  the sum of its members'; a reduced link's conductance is the sum of the full links between two groups (links
  inside a group vanish); heat sources follow their node. ``PARTITIONS["fine"]`` (the default) keeps every node of
  the full network: an error-driven search (docs/sensor.md) showed that every merge of two nodes costs a published
  bearing more than the 0.3 K RMS budget on at least one cycle, because each bearing reads the temperature of the
  shaft segment and housing it sits in. ``PARTITIONS["compact"]`` (40 nodes: one node per shaft, one housing, the
  reverse idler in the sump) is the cheaper alternative for ECUs that can accept larger errors on bearings.
* **Conductance laws.** Every speed- or oil-temperature-dependent link is tabulated from the full evaluator on a
  grid of its own shaft speed x oil temperature and classified: *power law* ``a(gear) w^e phi(T_oil)`` when the
  table is separable to 1e-9 (splash Eq 59, Harris Eq 63, immersed bearings Eq 52: exact), else a bilinear table
  over ``(sqrt(w / w_max), T_oil)`` (immersed wheels with their laminar/turbulent bridge and fling-off, oil-system
  streams with their flow-limited effectiveness). Gear contacts (Eq 45) are a per-gear mask, the ring gear is a
  splash law at high range and a constant at low range, radiation (Eq 81) is evaluated from the housing
  temperature every step.
* **Loss maps.** Gear-contact slip (Eq 7-10) of a mesh is exactly ``T1 w2 phi(log10 T1 - log10 mu - 3 log10 w2)``
  (the Benedict-Kelley argument is load / (mu V_g V_r^2) and both speeds are proportional to w2), so each mesh needs
  one 1-D table; rolling (Eq 14-22) is exactly ``K mu^0.7 a_p^0.54 w2^1.7 T1^-0.13``; bearings (Eq 35-40),
  needle bearings, synchronizers (Eq 41) and the pump (Eq 42) are closed forms with per-gear coefficients; churning
  (Eq 23-34) is a table over layshaft speed x oil temperature. Oil properties are one row of a table over the oil
  temperature (5 K steps).

Stability (docs/sensor.md, "Stability")
---------------------------------------
Forward Euler on ``C dT/dt = -K T + b`` is stable (and monotone: every new temperature is a convex combination of
the old ones and the sources, so no overshoot) when ``dt <= C_i / sum_j G_ij`` for every node i (Gershgorin:
every eigenvalue of ``C^-1 K`` lies in ``[0, 2 max_i sum_j G_ij / C_i]``). :func:`check_stability` bounds every
link's conductance over the whole operating range (every gear, 0..max engine speed, oil -40..150 degC) from the
laws themselves (power laws are monotone in speed, bilinear tables stay inside their corner values, the oil-
temperature columns are piecewise linear), adds the cooler and its inlet-temperature coupling, and raises
:class:`~firmware_model.errors.StabilityError` naming the node when ``dt > margin x C_i / max sum_j G_ij``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import NamedTuple

import numpy as np

from firmware_model.components import PUBLISHED, SHAFT_BEARINGS, STEP_S
from firmware_model.effects import CATALOG, FIELD_OF_EFFECT, EffectScales, effect_value, with_oil_volume
from firmware_model.errors import ParameterError, StabilityError
from firmware_model.network import (
    BOUNDARIES,
    K_BRG_SPLASH,
    K_CONST,
    K_CONTACT,
    K_EXT_CONV,
    K_EXT_RAD,
    K_IMM_BRG,
    K_IMM_GEAR,
    K_RING,
    K_SPLASH,
    K_STREAM,
    MIN_SPEED_RAD_S,
    S_CHANNEL,
    S_IMPOSED,
    SHAFT_SEGMENTS,
    ConductanceEvaluator,
    NamedNodes,
    Network,
    build_network,
)
from firmware_model.onboard.kernel_interface import (
    EFFECT_HOUSING_AIR_H,
    EFFECT_NONE,
    EFFECT_PLANET_OIL_H,
    EFFECT_TEETH_OIL_H,
    N_PROP,
    P_CP,
    P_K,
    P_LN_MU,
    P_LN_NU_CST,
    P_LN_PR,
    P_LN_ROLL,
    P_LOG10_MU,
    P_RHO,
    SPEED_COL_LAYSHAFT,
)
from firmware_model.parameters import Parameters
from firmware_model.physics import heat_transfer as ht
from firmware_model.physics import losses as L
from firmware_model.physics import oil as oilprops
from firmware_model.physics.conductance_matrix import link_topology, node_conductance_w_per_k
from firmware_model.physics.cooler import (
    COOLER_KINDS,
    DEFAULT_VEHICLE_SPEED_KMH,
    cooler_hA_bound_w_per_k,
    cooler_params,
    cooler_values,
    oil_cooler_heat,
)
from firmware_model.physics.gearbox_losses import ROLL_POINTS, GearboxLosses
from firmware_model.physics.heat_lag import heat_lag
from firmware_model.physics.kinematics import GEAR_MIN, MESHES, N_GEARS, SPEED_NAMES
from firmware_model.units import KELVIN_OFFSET_K, RAD_S_PER_RPM, RPM_PER_RAD_S, SIGMA_W_PER_M2K4

#: rpm -> rad/s (firmware_model.units)
RPM = RAD_S_PER_RPM
#: fixed step of the onboard model [s] (firmware_model.components.STEP_S)
DT_S = STEP_S
#: engine-off relaxation of the boundary temperatures to ambient [s] when the parameter file has no
#: boundary.engine_off_tau (assumed: a heavy diesel's block and coolant, ~0.65 MJ/K, losing ~180 W/K at rest)
ENGINE_OFF_TAU_S = 3600.0
#: the stability check requires dt <= STABILITY_MARGIN x min_i C_i / max sum_j G_ij
STABILITY_MARGIN = 0.8
#: oil temperature range over which stability is guaranteed [degC]
OIL_RANGE_C = (-40.0, 150.0)
#: oil-temperature grid of the property and conductance tables [degC]; outside it the end rows are held
T_GRID_C = np.arange(-40.0, 200.0 + 1e-9, 5.0)
#: number of speed points of the bilinear conductance and churning tables (in sqrt(w / w_max))
N_U = 17
#: number of layshaft-speed points of the churning table (in sqrt(w / w_max)); on the full oil grid
N_U_CHURN = 33
#: the 2-D tables use every second row of T_GRID_C (10 K)
T2_STRIDE = 2
#: spacing of the mesh slip-loss tables in x = log10(T1 / (mu w2^3))
X_STEP = 0.125
#: separability tolerance for power-law conductances (relative)
SEPARABLE_RTOL = 1e-7
#: linearised radiation is evaluated with housing temperatures clipped to this range [degC]
RAD_T_RANGE_C = (-40.0, 200.0)

#: effect ids the onboard model represents, each per vehicle (arrays) as well as scalar; oil_level_low changes the
#: geometry and is applied when the model is built (scalar only)
EFFECT_HOOKS = (
    "retarder_heat",
    "churning_scale",
    "gear_friction_scale",
    "planetary_loss_scale",
    "bearing_loss_scale",
    "teeth_oil_h_scale",
    "planet_oil_h_scale",
    "housing_air_h_scale",
    "cooler_effectiveness_scale",
    "thermostat_offset",
    "hot_surroundings_offset",
)
BUILD_EFFECTS = ("oil_level_low",)

# ---------------------------------------------------------------------------------------------------------------
# partitions


def _compact_partition() -> dict:
    part = {}
    for shaft, segs in SHAFT_SEGMENTS.items():
        for s in segs:
            part[s] = shaft
    for h in ("H1", "H2", "H3"):
        part[h] = "H"
    part["RI"] = "oil"
    return part


#: name -> {full node: reduced node}; nodes not named keep their own name
PARTITIONS = {"fine": {}, "compact": _compact_partition()}

# loss sources of the onboard model (columns of the source matrix)
SRC_NAMES = (
    tuple(f"mesh:{m}" for m in MESHES) + tuple(f"bearing:{b}" for b in SHAFT_BEARINGS) + ("oil_lumped", "retarder")
)
N_SRC = len(SRC_NAMES)
I_SRC_BEARING = len(MESHES)
I_SRC_OIL = I_SRC_BEARING + len(SHAFT_BEARINGS)
I_SRC_RET = I_SRC_OIL + 1
#: cooler kind -> cooler_code (hold and measured sumps have no cooler: 0)
COOLER_CODES = {kind: code for code, kind in enumerate(COOLER_KINDS)}


def _ro(a, dtype=float) -> np.ndarray:
    a = np.array(a, dtype=dtype)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class ReducedParams(NamedNodes):
    """Everything the onboard step needs, as read-only arrays (a frozen, typed record; dynamax style).

    Shapes: n nodes, nl links, nb boundaries (network.BOUNDARIES), ns sources (SRC_NAMES), 17 gears (row =
    gear - GEAR_MIN). Links: ``link_a`` is a node; ``link_b`` a node, or ``n + boundary index``.
    """

    variant: str
    partition: str
    nodes: tuple
    dt_s: float
    margin: float
    C_j_per_k: np.ndarray  # (n,)
    i_oil: int
    published_index: np.ndarray  # (28,) node index of each PUBLISHED component
    members: tuple  # full-network node names of each reduced node
    # --- links
    link_a: np.ndarray  # (nl,)
    link_b: np.ndarray  # (nl,)
    link_name: tuple
    G_const_w_per_k: np.ndarray  # (nl,) constant part
    # power-law terms: G = coef[gear, t] * w_in^exp[t] * (phi[T_oil, col[t]] or 1) * effect scale
    pw_link: np.ndarray  # (npw,)
    pw_exp: np.ndarray  # (npw,)
    pw_gear_coef: np.ndarray  # (17, npw) includes |shaft speed / input speed|^exp and gear masks
    pw_col: np.ndarray  # (npw,) column of pw_phi or -1
    pw_phi: np.ndarray  # (nT, ncol) oil-temperature factors
    pw_effect: np.ndarray  # (npw,) EFFECT_* (kernel_interface): none or the vehicle field that scales it
    # bilinear terms: G = table[t](sqrt(w_t / w_max[t]), T_oil), w_t = |speed coef[gear, t]| w_in
    t2_link: np.ndarray  # (n2,)
    t2_speed_coef: np.ndarray  # (17, n2)
    t2_w_max: np.ndarray  # (n2,) rad/s
    t2_table: np.ndarray  # (n2, N_U, nT2) W/K
    t2_stream: np.ndarray  # (n2,) bool: oil-system stream (the cooler's inlet drop applies)
    t2_frac: np.ndarray  # (n2,) oil-flow fraction of a stream (for the stability bound)
    t2_effect: np.ndarray  # (n2,) 0 none (pipe flows and immersed wheels)
    # immersed wheels, Nusselt part in closed form (Eq 46-48 with the bridge of heat_transfer.nusselt_rotating_cylinder):
    # G = c[t] k_oil Nu(Re, Pr), Re = R_p^2 w_t / nu, w_t = max(|speed coef[gear, t]| w_in, MIN_SPEED_RAD_S)
    # (their fling-off part, Eq 54-58, is an exact sqrt(w) power law among the pw terms)
    cyl_link: np.ndarray  # (nc,)
    cyl_speed_coef: np.ndarray  # (17, nc)
    cyl_c: np.ndarray  # (nc,) area / R_p [m]
    cyl_ln_rp2: np.ndarray  # (nc,) ln(R_p^2 [m2])
    # oil-system streams in closed form (Eq 69-80, NTU): G = m (1 - exp(-hA / m)), m = mcp[t] rho cp(T) |w_LS|,
    # hA = alpha[t] k_oil(T) + beta[t] (channel flows: 7.54 k / D_h x area; planetary: imposed h x area)
    ef_link: np.ndarray  # (ne,)
    ef_mcp: np.ndarray  # (ne,) flow fraction x flow per radian [m3/rad]
    ef_alpha: np.ndarray  # (ne,) [m]
    ef_beta: np.ndarray  # (ne,) [W/K]
    ef_effect: np.ndarray  # (ne,) EFFECT_PLANET_OIL_H: planet_oil_h scales beta
    # radiation links: G = area_eps[r] * sigma (T1^2 + T2^2)(T1 + T2)
    rad_link: np.ndarray
    rad_area_eps: np.ndarray
    # --- oil properties on T_GRID_C
    prop: np.ndarray  # (nT, N_PROP)
    # --- losses
    speed_coef: np.ndarray  # (17, 14) SPEED_NAMES per unit input speed
    mesh_torque: np.ndarray  # (17, 9)
    mesh_omega2: np.ndarray  # (17, 9)
    mesh_x0: np.ndarray  # (9,)
    mesh_phi: np.ndarray  # (9, nx)
    mesh_roll_k: np.ndarray  # (9,)
    mesh_heat_sf: np.ndarray  # (9,) seed loss-to-heat factor (0.75 gear contact, 0.80 planetary)
    mesh_roll_lt_min: np.ndarray  # (9,) log10 of wheel 1's torque below which the rolling loss ramps to 0
    bear_speed: np.ndarray  # (17, 6) |bearing speed| per unit input speed
    bear_c: np.ndarray  # (6,) Palmgren M0 coefficient 9.78e-2 f0 Dm^3
    bear_load: np.ndarray  # (17, 6) load torque per N m of input torque
    needle_rel: np.ndarray  # (17, 6)
    needle_c: np.ndarray  # (6,)
    sync_coef: np.ndarray  # (17,) sum_k c_k rel_k^2: P_sync = mu w_in^2 sync_coef
    pump_coef: np.ndarray  # (17,) P_pump = pump_coef w_in^2
    churn_w_max: float
    churn_table: np.ndarray  # (N_U_CHURN, nT) W at the layshaft speed u^2 w_max
    churn_heat_sf: float
    src_matrix: np.ndarray  # (ns, n) node heat = src_power @ src_matrix
    heat_lag_tau_s: float
    # --- cooler (seed 3.4, Eq 82-83)
    cooler_code: int
    cooler: dict
    flow_m3_per_rad: float  # oil-system flow per radian of layshaft rotation
    # --- boundaries
    bc_default_c: np.ndarray  # (nb,)
    engine_off_tau_s: float  # with the engine off, the boundaries relax to ambient with this time constant
    i_ambient: int
    i_coolant: int
    i_hot: int
    # --- limits of the operating range (inputs are clamped to these)
    max_speed_rpm: float
    min_torque_nm: float
    max_torque_nm: float
    stability: dict = field(default_factory=dict)

    def footprint(self, dtype=np.float32) -> dict:
        """Bytes an ECU would hold for these parameters: every float table as ``dtype``, index arrays as int16.
        (The dense scatter helpers numpy uses are implementation detail, not counted.)"""
        fb = np.dtype(dtype).itemsize
        floats = ints = 0
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray):
                if v.dtype.kind in "iub":
                    ints += v.size
                else:
                    floats += v.size
            elif isinstance(v, float):
                floats += 1
            elif isinstance(v, dict) and f.name == "cooler":
                floats += len(v)
        return {"float_values": floats, "index_values": ints, "bytes": floats * fb + ints * 2}


#: the effect values the onboard model applies at run time (the one effect record, firmware_model.effects); its
#: ``src_scale`` (..., N_SRC) multiplies each loss source's heat
Effects = EffectScales


def make_effects(effects: dict | None = None) -> Effects:
    """Effects record from {effect id: value or array of per-vehicle values}; unknown or unsupported ids raise.
    Each value is a float or an array over vehicles (V,)."""
    effects = dict(effects or {})
    for eid, v in effects.items():
        if eid not in CATALOG:
            raise ParameterError(f"unknown effect id {eid!r}")
        if eid not in EFFECT_HOOKS and eid not in BUILD_EFFECTS:
            raise ParameterError(
                f"effect {eid} is not represented by the onboard model (it represents "
                f"{', '.join(EFFECT_HOOKS + BUILD_EFFECTS)})"
            )
        a = np.asarray(v, dtype=float)
        e = CATALOG[eid]
        if np.any(~np.isfinite(a)) or np.any(a < e.low) or np.any(a > e.high):
            raise ParameterError(
                f"effect {eid}: {e.param} = {v} is outside its plausible range "
                f"{e.low:g}..{e.high:g}{'' if e.unit in ('', '-') else ' ' + e.unit}"
            )

    def val(eid):
        v = effects.get(eid, CATALOG[eid].neutral)
        a = np.asarray(v, dtype=float)
        return float(a) if a.ndim == 0 else a

    gf, pl, ch, br = (
        np.asarray(val(k), dtype=float)
        for k in ("gear_friction_scale", "planetary_loss_scale", "churning_scale", "bearing_loss_scale")
    )
    shape = np.broadcast(gf, pl, ch, br).shape
    s = np.ones(shape + (N_SRC,))
    for j, m in enumerate(MESHES):
        s[..., j] = pl if m in ("PSP", "PPR") else gf
    s[..., I_SRC_BEARING:I_SRC_OIL] = br[..., None] if br.ndim else br
    s[..., I_SRC_OIL] = 1.0  # the lumped oil source carries its own scales (churning, needle bearings)
    s.setflags(write=False)
    return Effects(src_scale=s, **{FIELD_OF_EFFECT[eid]: val(eid) for eid in EFFECT_HOOKS})


# ---------------------------------------------------------------------------------------------------------------
# aggregation


@dataclass(frozen=True)
class Aggregation:
    nodes: tuple
    members: tuple
    C: np.ndarray
    node_of_full: np.ndarray  # (n_full,) reduced node index
    link_of_full: np.ndarray  # (nl_full,) reduced link index or -1 (inside a group)
    link_a: np.ndarray
    link_b: np.ndarray
    link_name: tuple


def aggregate(net: Network, partition: dict) -> Aggregation:
    """Merge full nodes into groups: C summed, links between groups summed, links inside a group dropped."""
    for k in partition:
        if k not in net.nodes:
            raise ParameterError(f"partition names node {k!r}, which is not in the thermal network")
    names = []
    for nm in net.nodes:
        g = partition.get(nm, nm)
        if g not in names:
            names.append(g)
    for c in PUBLISHED:
        if c not in names:
            raise ParameterError(f"the partition has no node named {c!r} (every published component must be one)")
    gi = {g: i for i, g in enumerate(names)}
    n_full, m = net.n, len(names)
    node_of = np.array([gi[partition.get(nm, nm)] for nm in net.nodes])
    C = np.bincount(node_of, net.C_j_per_k, minlength=m)
    members = tuple(tuple(nm for nm in net.nodes if partition.get(nm, nm) == g) for g in names)
    keys: dict = {}
    link_of = np.full(len(net.link_a), -1)
    for k, (a, b) in enumerate(zip(net.link_a, net.link_b)):
        ga = node_of[a]
        gb = node_of[b] if b < n_full else m + (b - n_full)
        if ga == gb:
            continue
        if gb < m and gb < ga:
            ga, gb = gb, ga
        kind_class = "rad" if net.link_kind[k] == K_EXT_RAD else "lin"
        key = (ga, gb, kind_class)
        if key not in keys:
            keys[key] = len(keys)
        link_of[k] = keys[key]
    la = np.array([k[0] for k in keys], dtype=np.int64)
    lb = np.array([k[1] for k in keys], dtype=np.int64)
    allnames = list(names) + list(BOUNDARIES)
    lname = tuple(f"{allnames[a]}-{allnames[b]}{':rad' if c == 'rad' else ''}" for a, b, c in keys)
    return Aggregation(tuple(names), members, C, node_of, link_of, la, lb, lname)


# ---------------------------------------------------------------------------------------------------------------
# build


def oil_property_table(T_c: np.ndarray) -> np.ndarray:
    op = oilprops.oil_properties(T_c)
    prop = np.empty((T_c.size, N_PROP))
    prop[:, P_LOG10_MU] = np.log10(op.mu_pa_s)
    prop[:, P_LN_NU_CST] = np.log(op.nu_m2_s * 1e6)
    prop[:, P_LN_MU] = np.log(op.mu_pa_s)
    prop[:, P_LN_ROLL] = 0.7 * np.log(op.mu_pa_s) + 0.54 * np.log(op.piezo_per_pa)
    prop[:, P_RHO] = op.rho_kg_m3
    prop[:, P_CP] = op.cp_j_per_kgk
    prop[:, P_K] = op.k_w_per_mk
    prop[:, P_LN_PR] = np.log(op.pr)
    return prop


def _speed_of_link(net: Network, k: int) -> int:
    kind = int(net.link_kind[k])
    if kind == K_STREAM:
        return SPEED_NAMES.index("LS")
    j = int(np.sum(net.link_kind[:k] == kind))
    return int(net.kind_params[kind]["speed"][j])


def _link_param(net: Network, k: int, key: str):
    kind = int(net.link_kind[k])
    j = int(np.sum(net.link_kind[:k] == kind))
    return net.kind_params[kind][key][j]


class PowerTerm(NamedTuple):
    """G = gear_coef[gear] w_in^exp (phi[T_oil, col] or 1) x effect scale."""

    link: int
    exp: float
    gear_coef: np.ndarray  # (17,)
    col: int  # column of the phi table, -1 for none
    effect: int  # EFFECT_* (kernel_interface)


class TableTerm(NamedTuple):
    """G = table(sqrt(w / w_max), T_oil), w = speed_coef[gear] w_in."""

    link: int
    speed_coef: np.ndarray  # (17,)
    w_max_rad_s: float
    table: np.ndarray  # (N_U, nT2) W/K
    stream: bool  # an oil-system stream (the cooler's inlet drop applies)
    frac: float  # its share of the oil flow
    effect: int


class StreamTerm(NamedTuple):
    """Closed-form stream G = m (1 - exp(-hA / m)), m = flow_m3_per_rad rho cp |w_LS|, hA = alpha k_oil + beta."""

    link: int
    flow_m3_per_rad: float
    alpha_m: float
    beta_w_per_k: float
    effect: int


class CylinderTerm(NamedTuple):
    """Immersed wheel, Nusselt part: G = c k_oil Nu(Re, Pr), Re = R_p^2 w / nu, w = speed_coef[gear] w_in."""

    link: int
    speed_coef: np.ndarray  # (17,)
    c_m: float  # area / R_p
    ln_rp2: float  # ln(R_p^2 [m2])


class LawGrid(NamedTuple):
    """Every link tabulated from the full evaluator at its own shaft speed w x oil temperature (T_GRID_C)."""

    tables: dict  # speed source -> (N_U, nT, n_links) W/K at w = u^2 w_max
    src_of_link: np.ndarray  # speed source of every variable link (-1: constant)
    w_src_max: np.ndarray  # max speed of every speed source over all gears [rad/s]
    u: np.ndarray  # (N_U,) sqrt(w / w_max)
    G_ring_low: np.ndarray  # every link at low range, standstill, 60 degC (the ring gear's low-range value)


def law_grid(net: Network, p: Parameters, batched: bool = True) -> LawGrid:
    """Tabulate every speed- or oil-dependent link with all shafts at the same speed (each link reads its own).

    The full evaluator is called once per oil temperature with every grid speed as a batch; ``batched=False``
    calls it once per grid point instead (the same numbers bit for bit, ~50x slower; kept as the reference the
    tests and benchmarks/bench_build.py compare with)."""
    ev = ConductanceEvaluator(net, p, EffectScales())
    speed_abs = np.abs(p.kinematics.speed)  # (17, 14)
    w_src_max = speed_abs.max(axis=0) * p["engine.max_speed_rad_s"]
    u = np.linspace(0.0, 1.0, N_U)
    n_links = len(net.link_a)
    variable = (K_SPLASH, K_IMM_GEAR, K_IMM_BRG, K_BRG_SPLASH, K_STREAM, K_RING)
    src_of_link = np.full(n_links, -1)
    for k in range(n_links):
        if int(net.link_kind[k]) in variable:
            src_of_link[k] = _speed_of_link(net, k)
    zero_mt = np.zeros(len(MESHES))
    T_dummy = np.full(net.n, 60.0)
    bc_dummy = np.full(len(BOUNDARIES), 40.0)

    def eval_all(w, T, low_range=False):
        """Every link with all shafts at the speed w (an array of speeds: a batch, see evaluate) [W/K]."""
        sp = np.repeat(np.asarray(w, dtype=float)[..., None], len(SPEED_NAMES), axis=-1)
        return ev.evaluate(float(T), sp, 0, zero_mt, low_range, T_dummy, bc_dummy).copy()

    sources = sorted(set(src_of_link[src_of_link >= 0].tolist()))
    # one batch per oil temperature: every source's speeds u^2 w_max (the oil properties are scalars per call)
    w = np.array([[ui * ui * max(w_src_max[s], 1e-6) for ui in u] for s in sources]).reshape(-1)
    tab = np.empty((len(sources), N_U, T_GRID_C.size, n_links))
    for j, Tj in enumerate(T_GRID_C):
        if batched:
            tab[:, :, j] = eval_all(w, Tj).reshape(len(sources), N_U, n_links)
        else:
            for k, wk in enumerate(w):
                tab[k // N_U, k % N_U, j] = eval_all(wk, Tj)
    tables = {s: tab[k] for k, s in enumerate(sources)}
    return LawGrid(tables, src_of_link, w_src_max, u, eval_all(0.0, 60.0, low_range=True))


class _Laws:
    """The conductance law of every reduced link, collected link by link of the full network (module doc)."""

    def __init__(self, net: Network, agg: Aggregation, p: Parameters, grid: LawGrid):
        self.net, self.agg, self.p, self.grid = net, agg, p, grid
        self.kin = p.kinematics
        self.speed_abs = np.abs(self.kin.speed)
        self.G_const = np.zeros(len(agg.link_a))
        self.pw: list = []
        self.t2: list = []
        self.ef: list = []
        self.cyl: list = []
        self.rad: dict = {}  # reduced link -> area x emissivity
        self.phi_cols: list = []

    def phi_col(self, values) -> int:
        for c, v in enumerate(self.phi_cols):
            if np.allclose(v, values, rtol=1e-12, atol=0):
                return c
        self.phi_cols.append(values)
        return len(self.phi_cols) - 1

    def phi_table(self) -> np.ndarray:
        pw_phi = np.ones((T_GRID_C.size, max(len(self.phi_cols), 1)))
        for c, v in enumerate(self.phi_cols):
            pw_phi[:, c] = v
        return pw_phi

    def add_link(self, k: int) -> None:
        r = int(self.agg.link_of_full[k])
        if r < 0:
            return  # inside a group
        net, p = self.net, self.p
        kind = int(net.link_kind[k])
        if kind == K_CONST:
            self.G_const[r] += net.link_G0[k]
        elif kind == K_CONTACT:
            mask = (self.kin.mesh_torque[:, int(_link_param(net, k, "mesh"))] != 0).astype(float)
            self.pw.append(PowerTerm(r, 0.0, net.link_G0[k] * mask, -1, EFFECT_NONE))
        elif kind == K_EXT_CONV:
            self.pw.append(
                PowerTerm(r, 0.0, np.full(N_GEARS, net.link_G0[k] * p["housing.h_air"]), -1, EFFECT_HOUSING_AIR_H)
            )
        elif kind == K_EXT_RAD:
            # housings merged into one node: their radiation areas add (same boundary, same law)
            area_eps = net.link_G0[k] * p["housing.emissivity"]
            self.rad[r] = self.rad[r] + area_eps if r in self.rad else area_eps
        elif kind == K_IMM_GEAR:
            self._immersed_wheel(k, r)
        elif kind == K_STREAM and int(_link_param(net, k, "sub")) in (S_CHANNEL, S_IMPOSED):
            self._closed_form_stream(k, r)
        else:
            self._tabulated(k, r, kind)

    def _immersed_wheel(self, k: int, r: int) -> None:
        """Nusselt (Eq 46-48, closed form) plus fling-off (Eq 54-58, an exact sqrt(w) power law)."""
        net, s = self.net, self.grid.src_of_link[k]
        w = self.grid.u * self.grid.u * self.grid.w_src_max[s]
        R_p = float(_link_param(net, k, "R_p"))
        fo = _fling_off_table(net, k, w, T_GRID_C)
        law = _separable_power_law(fo, w)
        nus = _cyl_table(net.link_G0[k] / R_p, R_p, w, T_GRID_C)
        tab = self.grid.tables[s][:, :, k]
        if law is None or np.max(np.abs(nus + fo - tab)) > 1e-9 * np.abs(tab).max():
            raise ParameterError(
                f"link {net.link_name[k]}: the immersed-wheel conductance is not Nusselt (Eq 46-48) "
                f"plus fling-off (Eq 54-58) as the onboard model assumes"
            )
        e, a, phi = law
        self.pw.append(PowerTerm(r, e, a * self.speed_abs[:, s] ** e, self.phi_col(phi), EFFECT_NONE))
        self.cyl.append(CylinderTerm(r, self.speed_abs[:, s], net.link_G0[k] / R_p, math.log(R_p * R_p)))

    def _closed_form_stream(self, k: int, r: int) -> None:
        """Channel flows (Eq 77-80: 7.54 k / D_h x area) and the planetary's imposed h, through the NTU law."""
        net = self.net
        sub = int(_link_param(net, k, "sub"))
        frac = float(_link_param(net, k, "frac"))
        if sub == S_CHANNEL:
            alpha, beta = net.link_G0[k] * ht.NU_CHANNEL / float(_link_param(net, k, "D")), 0.0  # Eq 77-80
        else:
            alpha, beta = 0.0, net.link_G0[k] * float(_link_param(net, k, "h"))
        self.ef.append(
            StreamTerm(
                r,
                frac * self.p["oil_system.flow_m3_per_rad"],
                alpha,
                beta,
                EFFECT_PLANET_OIL_H if sub == S_IMPOSED else EFFECT_NONE,
            )
        )

    def _tabulated(self, k: int, r: int, kind: int) -> None:
        """A power law where the table is separable (splash Eq 59, Harris Eq 63, immersed bearings Eq 52), else a
        bilinear table; the ring gear is a splash law at high range and a constant at low range."""
        net, s = self.net, self.grid.src_of_link[k]
        tab = self.grid.tables[s][:, :, k]  # (N_U, nT)
        wmax = self.grid.w_src_max[s]
        name = net.link_name[k]
        law = _separable_power_law(tab, self.grid.u * self.grid.u * wmax)
        if kind == K_RING:
            # low range: housing-like constant h (seed 3.3); high range: the ring turns with the sun (splash)
            G_low = float(self.grid.G_ring_low[k])
            if law is not None:
                self.pw.append(PowerTerm(r, 0.0, G_low * self.kin.low_range.astype(float), -1, EFFECT_NONE))
            elif not np.allclose(tab[0, :], G_low, rtol=1e-9):
                raise ParameterError(
                    "ring-gear conductance: the high-range law at standstill differs from the "
                    "low-range value; the onboard tables cannot represent it"
                )
            # else: the table at zero ring speed (the ring does not turn at low range) is the low-range value
        if law is not None:
            e, a, phi = law
            col = -1 if np.allclose(phi, 1.0, rtol=1e-12) else self.phi_col(phi)
            coef = a * self.speed_abs[:, s] ** e
            if kind == K_RING:
                coef = coef * (~self.kin.low_range)
            eff = EFFECT_TEETH_OIL_H if (name.startswith("splash:") and name.endswith(".teeth")) else EFFECT_NONE
            self.pw.append(PowerTerm(r, e, coef, col, eff))
        else:
            frac = float(_link_param(net, k, "frac")) if kind == K_STREAM else 0.0
            self.t2.append(
                TableTerm(r, self.speed_abs[:, s], wmax, tab[:, ::T2_STRIDE], kind == K_STREAM, frac, EFFECT_NONE)
            )


class LossMaps(NamedTuple):
    """The loss model as the onboard step evaluates it (module doc, "Loss maps")."""

    mesh_x0: np.ndarray
    mesh_phi: np.ndarray
    mesh_roll_k: np.ndarray
    mesh_heat_sf: np.ndarray
    bear_speed: np.ndarray
    bear_c: np.ndarray
    bear_load: np.ndarray
    needle_c: np.ndarray
    sync_coef: np.ndarray
    pump_coef: np.ndarray
    churn_w_max: float
    churn_table: np.ndarray
    mesh_roll_lt_min: np.ndarray


def _loss_maps(p: Parameters, net: Network, w_ls_max_rad_s: float) -> LossMaps:
    """Mesh slip tables and rolling constants (Eq 7-22), Palmgren coefficients of the shaft and needle bearings
    (Eq 35-40), synchronizer (Eq 41) and pump (Eq 42) coefficients per gear, churning table (Eq 23-34)."""
    kin = p.kinematics
    gl = GearboxLosses(p, net.geometry)
    mesh_x0, mesh_phi_rows, roll_k, roll_lt_min = _mesh_tables(gl)
    speed_abs = np.abs(kin.speed)
    bear_speed = np.zeros((N_GEARS, len(SHAFT_BEARINGS)))
    for j, b in enumerate(SHAFT_BEARINGS):
        if b == "BIM":
            bear_speed[:, j] = np.abs(kin.speed[:, SPEED_NAMES.index("IS")] - kin.speed[:, SPEED_NAMES.index("MS")])
        else:
            bear_speed[:, j] = speed_abs[:, gl.bearing_speed_idx[j]]
    sync_c = np.array(
        [
            n_r * 2.0 * math.pi * R**3 * p["sync.w_ring"] / (J * math.sin(p["sync.theta_ring"]))
            for n_r, R, J in gl.sync_geo
        ]
    )
    u_ch = np.linspace(0.0, 1.0, N_U_CHURN)
    heat_sf = np.array(
        [p["scale.planet_to_heat"] if m in ("PSP", "PPR") else p["scale.gear_contact_to_heat"] for m in MESHES]
    )
    return LossMaps(
        mesh_x0,
        mesh_phi_rows,
        roll_k,
        heat_sf,
        bear_speed,
        L.PALMGREN_SEED_C * gl.f0 * gl.Dm**3,
        gl.load_torque_coef,
        L.PALMGREN_SEED_C * gl.needle_f0 * gl.needle_Dm**3,
        (kin.sync_rel**2) @ sync_c,
        gl.pump_k * kin.speed[:, SPEED_NAMES.index("LS")] ** 2,
        w_ls_max_rad_s,
        _churn_table(gl, u_ch * u_ch * w_ls_max_rad_s, T_GRID_C, kin),
        roll_lt_min,
    )


def _source_matrix(net: Network, agg: Aggregation) -> np.ndarray:
    """(N_SRC, n): where each source's heat goes, in reduced nodes."""
    S = np.zeros((N_SRC, len(agg.nodes)))
    for j, nm in enumerate(SRC_NAMES):
        if nm.startswith("mesh:") and nm[5:] in ("PSP", "PPR"):
            dist = net.sources["planetary"]
        elif nm == "oil_lumped":
            dist = net.sources["churning"]
        else:
            dist = net.sources[nm]
        for node, frac in dist:
            S[j, agg.node_of_full[node]] += frac
    return S


def _resolve_partition(partition: str | dict) -> tuple[str, dict]:
    if not isinstance(partition, str):
        return "custom", partition
    if partition not in PARTITIONS:
        raise ParameterError(f"unknown partition {partition!r}; known: {', '.join(PARTITIONS)}")
    return partition, PARTITIONS[partition]


def _law_fields(laws: _Laws) -> dict:
    """The ReducedParams fields of the conductance laws (read-only arrays)."""
    pw, t2, ef, cyl = laws.pw, laws.t2, laws.ef, laws.cyl
    nT2 = T_GRID_C[::T2_STRIDE].size

    def col(rows, name, dtype=float):
        return _ro(np.array([getattr(r, name) for r in rows], dtype=dtype), dtype)

    def per_gear(rows, name):
        return _ro(np.array([getattr(r, name) for r in rows]).T.reshape(N_GEARS, len(rows)))

    return dict(
        G_const_w_per_k=_ro(laws.G_const),
        pw_link=col(pw, "link", np.int64),
        pw_exp=col(pw, "exp"),
        pw_gear_coef=per_gear(pw, "gear_coef"),
        pw_col=col(pw, "col", np.int64),
        pw_phi=_ro(laws.phi_table()),
        pw_effect=col(pw, "effect", np.int64),
        t2_link=col(t2, "link", np.int64),
        t2_speed_coef=per_gear(t2, "speed_coef"),
        t2_w_max=col(t2, "w_max_rad_s"),
        t2_table=_ro(np.array([r.table for r in t2]).reshape(len(t2), N_U, nT2)),
        t2_stream=col(t2, "stream", bool),
        t2_frac=col(t2, "frac"),
        t2_effect=col(t2, "effect", np.int64),
        cyl_link=col(cyl, "link", np.int64),
        cyl_speed_coef=per_gear(cyl, "speed_coef"),
        cyl_c=col(cyl, "c_m"),
        cyl_ln_rp2=col(cyl, "ln_rp2"),
        ef_link=col(ef, "link", np.int64),
        ef_mcp=col(ef, "flow_m3_per_rad"),
        ef_alpha=col(ef, "alpha_m"),
        ef_beta=col(ef, "beta_w_per_k"),
        ef_effect=col(ef, "effect", np.int64),
        rad_link=_ro(np.array(list(laws.rad), dtype=np.int64), np.int64),
        rad_area_eps=_ro(np.array(list(laws.rad.values()), dtype=float)),
    )


def build_reduced(
    p: Parameters,
    partition: str | dict = "fine",
    effects: dict | None = None,
    dt_s: float = DT_S,
    margin: float = STABILITY_MARGIN,
    check: bool = True,
) -> ReducedParams:
    """Build the onboard model from a validated parameter set; raises StabilityError if dt is unsafe.

    ``effects``: only the build-time effect oil_level_low is used here (the others are applied at run time through
    :func:`make_effects`)."""
    p = with_oil_volume(p, effect_value(effects, "oil_level_low"))
    if not 0.0 < dt_s <= 1.0:
        raise ParameterError(f"dt_s = {dt_s} s must be in (0, 1] s")
    if not 0.0 < margin <= 1.0:
        raise ParameterError(f"stability margin = {margin} must be in (0, 1]")
    part_name, partition = _resolve_partition(partition)
    net = build_network(p)
    agg = aggregate(net, partition)
    kin = p.kinematics
    grid = law_grid(net, p)
    laws = _Laws(net, agg, p, grid)
    for k in range(len(net.link_a)):
        laws.add_link(k)
    lm = _loss_maps(p, net, float(grid.w_src_max[SPEED_NAMES.index("LS")]))
    kind = p.strings.get("cooler.kind", "liquid")
    rp = ReducedParams(
        variant=p.variant,
        partition=part_name,
        nodes=agg.nodes,
        dt_s=float(dt_s),
        margin=float(margin),
        C_j_per_k=_ro(agg.C),
        i_oil=agg.nodes.index("oil"),
        published_index=_ro(np.array([agg.nodes.index(c) for c in PUBLISHED]), np.int64),
        members=agg.members,
        link_a=_ro(agg.link_a, np.int64),
        link_b=_ro(agg.link_b, np.int64),
        link_name=agg.link_name,
        **_law_fields(laws),
        prop=_ro(oil_property_table(T_GRID_C)),
        speed_coef=_ro(kin.speed),
        mesh_torque=_ro(kin.mesh_torque),
        mesh_omega2=_ro(kin.mesh_omega2),
        mesh_x0=_ro(lm.mesh_x0),
        mesh_phi=_ro(lm.mesh_phi),
        mesh_roll_k=_ro(lm.mesh_roll_k),
        mesh_heat_sf=_ro(lm.mesh_heat_sf),
        mesh_roll_lt_min=_ro(lm.mesh_roll_lt_min),
        bear_speed=_ro(lm.bear_speed),
        bear_c=_ro(lm.bear_c),
        bear_load=_ro(lm.bear_load),
        needle_rel=_ro(kin.wheel_bearing_rel),
        needle_c=_ro(lm.needle_c),
        sync_coef=_ro(lm.sync_coef),
        pump_coef=_ro(lm.pump_coef),
        churn_w_max=float(lm.churn_w_max),
        churn_table=_ro(lm.churn_table),
        churn_heat_sf=float(p["scale.churn_to_heat"]),
        src_matrix=_ro(_source_matrix(net, agg)),
        heat_lag_tau_s=float(p["scale.heat_lag_tau"]),
        cooler_code=COOLER_CODES.get(kind, 0),
        cooler=cooler_values(p),
        flow_m3_per_rad=float(p["oil_system.flow_m3_per_rad"]),
        bc_default_c=_ro(np.array([p[f"boundary.{b}"] for b in BOUNDARIES])),
        engine_off_tau_s=float(p.get("boundary.engine_off_tau", ENGINE_OFF_TAU_S)),
        i_ambient=BOUNDARIES.index("ambient"),
        i_coolant=BOUNDARIES.index("coolant"),
        i_hot=BOUNDARIES.index("hot_surroundings"),
        max_speed_rpm=float(p["engine.max_speed_rad_s"] / RPM),
        min_torque_nm=float(p["engine.min_torque"]),
        max_torque_nm=float(p["engine.max_torque"]),
    )
    if check:
        object.__setattr__(rp, "stability", check_stability(rp))
    return rp


def _separable_power_law(tab: np.ndarray, w: np.ndarray):
    """(exponent e, a, phi(T)) with tab[i, j] = a w_i^e phi_j to SEPARABLE_RTOL for every w_i > 0, else None.

    phi is normalised to 1 at 60 degC. At w = 0 the law gives 0 (the full evaluator floors some speeds at
    MIN_SPEED_RAD_S, a conductance below 0.3 % of its value at 100 rpm)."""
    if not np.all(np.isfinite(tab)) or np.any(tab < 0):
        return None
    pos = np.flatnonzero(w > 0)
    j_ref = int(np.argmin(np.abs(T_GRID_C - 60.0)))
    i1, i2 = pos[0], pos[-1]
    if tab[i1, j_ref] <= 0 or tab[i2, j_ref] <= 0:
        return None
    e = math.log(tab[i2, j_ref] / tab[i1, j_ref]) / math.log(w[i2] / w[i1])
    if abs(e) < 1e-9:
        e = 0.0
    a = tab[i2, j_ref] / w[i2] ** e
    phi = tab[i2, :] / tab[i2, j_ref]
    model = a * w[pos, None] ** e * phi[None, :]
    if np.max(np.abs(model - tab[pos])) <= SEPARABLE_RTOL * np.abs(tab).max():
        return e, a, phi
    return None


def _cyl_nusselt(ln_re, ln_pr):
    """Eq 46 / 47 with the geometric bridge between Re = 2.5e5 and 3.2e5, in logarithms (identical to
    heat_transfer.nusselt_rotating_cylinder)."""
    ln46 = _LN_04 + 0.5 * ln_re + ln_pr / 3.0
    ln47 = _LN_0238 + 0.8 * ln_re + 0.6 * ln_pr
    s = np.clip((ln_re - _LN_RE_LAM) / _LN_RE_BRIDGE, 0.0, 1.0)
    return np.exp(ln46 + s * (ln47 - ln46))


_LN_04, _LN_0238 = math.log(0.4), math.log(0.238)
_LN_RE_LAM = math.log(ht.RE_LAMINAR_MAX)
_LN_RE_BRIDGE = math.log(ht.RE_TURBULENT_MIN / ht.RE_LAMINAR_MAX)
_LN_1E6 = math.log(1e-6)


def _cyl_table(c, R_p, w, T):
    op = oilprops.oil_properties(T)
    wf = np.maximum(w, MIN_SPEED_RAD_S)[:, None]
    re = R_p * R_p * wf / op.nu_m2_s[None, :]
    return c * op.k_w_per_mk[None, :] * ht.nusselt_rotating_cylinder(re, op.pr[None, :])


def _fling_off_table(net: Network, k: int, w, T):
    kp = {key: float(_link_param(net, k, key)) for key in ("z", "width", "h_t", "R_p", "h_i")}
    op = oilprops.oil_properties(T)
    wf = np.maximum(w, MIN_SPEED_RAD_S)[:, None]
    return ht.fling_off_hA(
        kp["z"],
        kp["width"],
        kp["h_t"],
        kp["R_p"],
        kp["h_i"],
        wf,
        op.k_w_per_mk[None, :],
        op.alpha_m2_s[None, :],
        op.nu_m2_s[None, :],
    ).hA_w_per_k


def _mesh_tables(gl: GearboxLosses):
    """Per mesh: x0 and phi on x = x0 + X_STEP i (slip loss / (T1 w2)), the rolling-loss constant and log10 of the
    torque T1 below which the rolling loss ramps to 0 (the plant's L.ROLL_TORQUE_MIN_NM per contact)."""
    n_pl = gl.n_planets
    rows, x0s, roll, lt_min = [], [], [], []
    # x range: beyond it f_g is clipped at both ends for every point of the line of action
    xs = np.arange(-16.0, 24.0 + 1e-9, X_STEP)
    for m, mesh in zip(MESHES, gl.meshes):
        planetary = m in ("PSP", "PPR")
        # total torque T on wheel 1; the loss model splits it over the planets
        T_tot = 10.0**xs
        T1 = T_tot / n_pl if planetary else T_tot
        P = L.gear_slip_loss_w(mesh, T1, 1.0, 1.0, 1.0)
        if planetary:
            P = P * n_pl
        phi = P / T_tot
        # trim constant ends (keep one point of each plateau)
        d = np.abs(np.diff(phi)) > 1e-14 * np.abs(phi).max()
        lo = max(int(np.argmax(d)) - 1, 0)
        hi = min(len(phi) - int(np.argmax(d[::-1])) + 1, len(phi))
        rows.append(phi[lo:hi])
        x0s.append(xs[lo])
        Tr = 1000.0 / (n_pl if planetary else 1.0)
        Pr = L.gear_rolling_loss_w(mesh, Tr, 100.0, 1.0, 1.0, gl.E, gl.E, gl.poisson, gl.poisson, n_points=ROLL_POINTS)
        if planetary:
            Pr = Pr * n_pl
        roll.append(float(Pr) / (100.0**1.7 * 1000.0**-0.13))
        # the plant's ramp starts at ROLL_TORQUE_MIN_NM per contact: n_pl times that on the sun's total torque
        lt_min.append(math.log10((n_pl if planetary else 1.0) * L.ROLL_TORQUE_MIN_NM))
    nx = max(len(r) for r in rows)
    tab = np.empty((len(MESHES), nx))
    for i, r in enumerate(rows):
        tab[i, : len(r)] = r
        tab[i, len(r) :] = r[-1]
    return np.array(x0s), tab, np.array(roll), np.array(lt_min)


def _churn_table(gl: GearboxLosses, w_ls: np.ndarray, T2: np.ndarray, kin) -> np.ndarray:
    """Churning loss [W] of every immersed wheel at layshaft speed w_ls x oil temperature T2 (Eq 23-34)."""
    ri_ratio = abs(kin.speed[0 - GEAR_MIN, SPEED_NAMES.index("RI")] / kin.speed[0 - GEAR_MIN, SPEED_NAMES.index("LS")])
    out = np.zeros((w_ls.size, T2.size))
    for j, T in enumerate(T2):
        op = oilprops.oil_properties(T)
        wc = np.where(gl.ch_is_RI[None, :] > 0, (w_ls * ri_ratio)[:, None], w_ls[:, None])
        ch = L.churning_loss(
            wc, gl.ch_Ra, gl.ch_Rp, gl.ch_ht, gl.ch_w, gl.ch_hi, gl.ch_Vp, gl.V0, op.rho_kg_m3, op.nu_m2_s, gl.h_t0
        )
        out[:, j] = np.sum(np.where(gl.ch_mask, ch.power_w, 0.0), axis=1)
    return out


# ---------------------------------------------------------------------------------------------------------------
# evaluation (pure functions of the parameters and the current operating point; broadcast over vehicles)


class Helpers:
    """Dense scatter matrices and index splits numpy uses to evaluate a ReducedParams quickly (derived, cached;
    an ECU would loop over the index arrays instead)."""

    def __init__(self, rp: ReducedParams):
        n, nl = rp.n, len(rp.link_a)
        self.nl = nl
        self.pw_scatter = np.zeros((len(rp.pw_link), nl))
        self.pw_scatter[np.arange(len(rp.pw_link)), rp.pw_link] = 1.0
        self.t2_scatter = np.zeros((len(rp.t2_link), nl))
        self.t2_scatter[np.arange(len(rp.t2_link)), rp.t2_link] = 1.0
        self.ef_scatter = np.zeros((len(rp.ef_link), nl))
        self.ef_scatter[np.arange(len(rp.ef_link)), rp.ef_link] = 1.0
        self.cyl_scatter = np.zeros((len(rp.cyl_link), nl))
        self.cyl_scatter[np.arange(len(rp.cyl_link)), rp.cyl_link] = 1.0
        # which links join which nodes (physics.conductance_matrix: K = conductance_matrix(G, topology).K_w_per_k)
        self.topology = topo = link_topology(rp.link_a, rp.link_b, n)
        self.internal, self.int_idx, self.ext_idx = topo.internal, topo.int_idx, topo.ext_idx
        self.ia, self.ib, self.ea, self.eb = topo.ia, topo.ib, topo.ea, topo.eb
        # flux -> node rate: q_nodes = flux_int @ B_int + flux_ext @ B_ext (flux = G (T_a - T_b), from a to b)
        self.B_int = np.zeros((self.ia.size, n))
        self.B_int[np.arange(self.ia.size), self.ia] = -1.0
        self.B_int[np.arange(self.ia.size), self.ib] += 1.0
        self.B_ext = np.zeros((self.ea.size, n))
        self.B_ext[np.arange(self.ea.size), self.ea] = -1.0
        # oil-system streams (pipe tables, then closed-form channels): the cooler's inlet drop dT moves G dT from
        # the component to the sump
        self.t2_streams = np.flatnonzero(rp.t2_stream)
        links = np.concatenate([rp.t2_link[self.t2_streams], rp.ef_link]).astype(np.int64)
        la, lb = rp.link_a[links], rp.link_b[links]
        node = np.where(la == rp.i_oil, lb, la)
        self.stream_scatter = np.zeros((links.size, n))
        self.stream_scatter[np.arange(links.size), node] -= 1.0
        self.stream_scatter[np.arange(links.size), rp.i_oil] += 1.0
        self.nT = T_GRID_C.size
        self.T0 = float(T_GRID_C[0])
        self.dT = float(T_GRID_C[1] - T_GRID_C[0])
        self.nT2 = rp.t2_table.shape[2]
        self.t2_flat = np.ascontiguousarray(rp.t2_table).reshape(-1)
        self.t2_base = np.arange(len(rp.t2_link)) * N_U * self.nT2
        self.churn_flat = np.ascontiguousarray(rp.churn_table).reshape(-1)
        self.mesh_flat = np.ascontiguousarray(rp.mesh_phi).reshape(-1)
        self.nx = rp.mesh_phi.shape[1]
        self.mesh_base = np.arange(len(MESHES)) * self.nx
        self.rad_node = rp.link_a[rp.rad_link]
        self.rad_bc = rp.link_b[rp.rad_link] - n
        self.pw_eff = {k: np.flatnonzero(rp.pw_effect == k) for k in (EFFECT_TEETH_OIL_H, EFFECT_HOUSING_AIR_H)}
        self.ef_planet = np.flatnonzero(rp.ef_effect == EFFECT_PLANET_OIL_H)
        self.pw_colc = np.maximum(rp.pw_col, 0)
        self.pw_has_col = rp.pw_col >= 0
        self.C = np.array(rp.C_j_per_k, dtype=float)
        self.inv_C = 1.0 / self.C
        # links to the sump and their other end (a measured sump is a boundary of the held-input system)
        self.oil_links = np.flatnonzero((self.ia == rp.i_oil) | (self.ib == rp.i_oil))
        self.oil_other = np.where(self.ia[self.oil_links] == rp.i_oil, self.ib[self.oil_links], self.ia[self.oil_links])
        # published components among the free nodes of the held-input system (sump measured / modelled)
        free_meas = np.flatnonzero(np.arange(n) != rp.i_oil)
        pub = np.asarray(rp.published_index)
        self.pub_free_meas = pub != rp.i_oil
        self.pub_rows_meas = np.searchsorted(free_meas, pub[self.pub_free_meas])
        self.pub_free_all = np.ones(pub.size, dtype=bool)
        self.pub_rows_all = pub.copy()
        # published components whose crossing re-linearises the time to limit (not the sump itself)
        self.ttl_relin_pub = pub != rp.i_oil
        self.cooler = cooler_params(rp.cooler)
        # the heat lag's coefficients at the onboard step (physics.heat_lag.heat_lag_step(lag_w, src, h.heat_lag))
        self.heat_lag = heat_lag(rp.heat_lag_tau_s, rp.dt_s)


_HELPERS: dict = {}


def helpers(rp: ReducedParams) -> Helpers:
    key = id(rp)
    item = _HELPERS.get(key)
    if item is None or item[0] is not rp:
        item = (rp, Helpers(rp))
        _HELPERS[key] = item
        if len(_HELPERS) > 64:
            _HELPERS.pop(next(iter(_HELPERS)))
    return item[1]


def oil_row(rp: ReducedParams, T_oil_c, h: Helpers | None = None):
    """(x, property row (..., N_PROP), pw phi row (..., ncol)) at the oil temperature; x is the fractional index
    on T_GRID_C (held at the ends)."""
    h = h or helpers(rp)
    x = (np.clip(np.asarray(T_oil_c, dtype=float), T_GRID_C[0], T_GRID_C[-1]) - h.T0) / h.dT
    i = np.minimum(x.astype(np.int64), h.nT - 2)
    f = (x - i)[..., None]
    prop = rp.prop[i] * (1.0 - f) + rp.prop[i + 1] * f
    phi = rp.pw_phi[i] * (1.0 - f) + rp.pw_phi[i + 1] * f
    return x, prop, phi


def _scaled(G, idx, val):
    if idx.size == 0 or (np.ndim(val) == 0 and float(val) == 1.0):
        return G
    G = np.array(G, copy=True)
    G[..., idx] *= np.asarray(val, dtype=float)[..., None]
    return G


def conductances(
    rp: ReducedParams,
    row,
    w_in,
    x_T,
    prop,
    phi,
    T_nodes_c,
    T_bc_c,
    eff: Effects | None = None,
    h: Helpers | None = None,
    radiation: bool = True,
):
    """Conductance of every reduced link [W/K] (..., nl) and of the oil-system stream terms (..., nst).

    row: gear row (gear - GEAR_MIN), w_in: input speed [rad/s] >= 0, (x_T, prop, phi): :func:`oil_row` at the oil
    temperature; T_nodes_c / T_bc_c: node and boundary temperatures (radiation, Eq 81)."""
    h = h or helpers(rp)
    omega_in_rad_s = np.asarray(w_in, dtype=float)
    # power laws: coef(gear) w^e phi(T)
    ph = np.where(h.pw_has_col, np.take(phi, h.pw_colc, axis=-1), 1.0)
    Gp = rp.pw_gear_coef[row] * np.power(omega_in_rad_s[..., None], rp.pw_exp) * ph
    if eff is not None:
        Gp = _scaled(Gp, h.pw_eff[EFFECT_TEETH_OIL_H], eff.teeth_oil_h)
        Gp = _scaled(Gp, h.pw_eff[EFFECT_HOUSING_AIR_H], eff.housing_air_h)
    # bilinear tables over (sqrt(w_t / w_max), T)
    omega_t_rad_s = rp.t2_speed_coef[row] * omega_in_rad_s[..., None]
    uu = np.sqrt(np.minimum(omega_t_rad_s / rp.t2_w_max, 1.0)) * (N_U - 1)
    iu = np.minimum(uu.astype(np.int64), N_U - 2)
    fu = uu - iu
    xT2 = np.asarray(x_T) / T2_STRIDE
    jT = np.minimum(xT2.astype(np.int64), h.nT2 - 2)
    fT = (xT2 - jT)[..., None]
    base = h.t2_base + iu * h.nT2 + jT[..., None]
    tf = h.t2_flat
    lo = tf[base] * (1.0 - fT) + tf[base + 1] * fT
    hi = tf[base + h.nT2] * (1.0 - fT) + tf[base + h.nT2 + 1] * fT
    G2 = lo + (hi - lo) * fu
    # closed-form streams: m (1 - exp(-hA / m)), m = mdot cp  (NTU effectiveness, Eq 69-80)
    omega_ls_rad_s = np.abs(rp.speed_coef[row, SPEED_COL_LAYSHAFT]) * omega_in_rad_s
    mcp_w_per_k = rp.ef_mcp * (prop[..., P_RHO] * prop[..., P_CP] * omega_ls_rad_s)[..., None]
    beta = rp.ef_beta
    if eff is not None and h.ef_planet.size and not (np.ndim(eff.planet_oil_h) == 0 and eff.planet_oil_h == 1.0):
        beta = _scaled(np.broadcast_to(beta, mcp_w_per_k.shape), h.ef_planet, eff.planet_oil_h)
    hA = rp.ef_alpha * prop[..., P_K, None] + beta
    mcp_safe_w_per_k = np.where(mcp_w_per_k > 0.0, mcp_w_per_k, 1.0)
    Ge = np.where(mcp_w_per_k > 0.0, -mcp_safe_w_per_k * np.expm1(-hA / mcp_safe_w_per_k), 0.0)
    # immersed wheels: Nusselt (Eq 46-48) in closed form
    omega_c_rad_s = np.maximum(rp.cyl_speed_coef[row] * omega_in_rad_s[..., None], MIN_SPEED_RAD_S)
    ln_re = rp.cyl_ln_rp2 + np.log(omega_c_rad_s) - (prop[..., P_LN_NU_CST, None] + _LN_1E6)
    Gc = rp.cyl_c * prop[..., P_K, None] * _cyl_nusselt(ln_re, prop[..., P_LN_PR, None])
    G = rp.G_const_w_per_k + Gp @ h.pw_scatter + G2 @ h.t2_scatter + Ge @ h.ef_scatter + Gc @ h.cyl_scatter
    if radiation and rp.rad_link.size:
        G[..., rp.rad_link] = radiation_conductances(rp, T_nodes_c, T_bc_c, h)
    G_streams = np.concatenate([G2[..., h.t2_streams], Ge], axis=-1)
    return G, G_streams


def explicit_step(T, q_w, G_int, G_ext, T_bc_c, ia, ib, ea, eb, dt_over_C, B_int=None, B_ext=None):
    """One forward-Euler step of C dT/dt = sum_links G (T_other - T) + q on any graph (pure array math).

    T (..., n); q_w (..., n) heat into each node; G_int (..., n_int) conductances of the node-node links (ia, ib);
    G_ext (..., n_ext) of the node-boundary links (ea, eb into T_bc_c (..., nb)); dt_over_C (n,). B_int / B_ext:
    the links' incidence matrices (Helpers) to scatter with one matrix product instead of index sums."""
    n = T.shape[-1]
    f_int = G_int * (np.take(T, ia, axis=-1) - np.take(T, ib, axis=-1))  # heat from a to b
    f_ext = G_ext * (np.take(T, ea, axis=-1) - np.take(T_bc_c, eb, axis=-1))
    if B_int is not None:
        # one matrix product over every vehicle and copy (a stacked matmul would loop over small ones)
        lead = np.broadcast_shapes(f_int.shape[:-1], f_ext.shape[:-1], T.shape[:-1])
        rows = int(np.prod(lead, dtype=np.int64))
        rate = np.array(q_w, dtype=float) + np.zeros(lead + (n,))
        for f, Bm in ((f_int, B_int), (f_ext, B_ext)):
            if f.shape[-1]:
                rate += (np.broadcast_to(f, lead + f.shape[-1:]).reshape(rows, f.shape[-1]) @ Bm).reshape(lead + (n,))
    else:
        rate = q_w - _scatter(f_int, ia, n) + _scatter(f_int, ib, n) - _scatter(f_ext, ea, n)
    return T + dt_over_C * rate


def _scatter(f, idx, n):
    """out[..., j] = sum of f[..., k] over idx[k] == j."""
    out = np.zeros(f.shape[:-1] + (n,))
    if f.size:
        flat = out.reshape(-1, n)
        np.add.at(flat, (slice(None), idx), f.reshape(-1, f.shape[-1]))
    return out


def radiation_conductances(rp: ReducedParams, T_nodes_c, T_bc_c, h: Helpers | None = None):
    """Linearised radiation conductance of every radiation link [W/K] (Eq 81), housing temperatures clipped."""
    h = h or helpers(rp)
    T1 = (
        np.minimum(np.maximum(np.take(T_nodes_c, h.rad_node, axis=-1), RAD_T_RANGE_C[0]), RAD_T_RANGE_C[1])
        + KELVIN_OFFSET_K
    )
    T2 = np.take(T_bc_c, h.rad_bc, axis=-1) + KELVIN_OFFSET_K
    return rp.rad_area_eps * SIGMA_W_PER_M2K4 * (T1 * T1 + T2 * T2) * (T1 + T2)  # Eq 81


def heat_sources(
    rp: ReducedParams,
    row,
    w_in,
    torque_abs_nm,
    prop,
    x_T,
    src_scale=None,
    churn_scale=1.0,
    needle_scale=1.0,
    retarder_w=0.0,
    h: Helpers | None = None,
):
    """Heat of every source [W], shape (..., N_SRC): meshes (Eq 7-22, x seed heat factors), shaft bearings
    (Eq 35-40), the oil-lumped sources (churning x 1.33, needle bearings, synchronizers, pump) and the retarder."""
    h = h or helpers(rp)
    omega_in_rad_s = np.asarray(w_in, dtype=float)
    torque_nm = np.asarray(torque_abs_nm, dtype=float)
    omega_in_col = omega_in_rad_s[..., None]
    T1 = rp.mesh_torque[row] * torque_nm[..., None]
    omega2_rad_s = rp.mesh_omega2[row] * omega_in_col
    on = (T1 > 0.0) & (omega2_rad_s > 0.0)
    T1s = np.where(on, T1, 1.0)
    omega2_safe = np.where(on, omega2_rad_s, 1.0)
    lT, lw = np.log10(T1s), np.log10(omega2_safe)
    x = (lT - prop[..., P_LOG10_MU, None] - 3.0 * lw - rp.mesh_x0) / X_STEP
    x = np.clip(x, 0.0, h.nx - 1.000001)
    ix = x.astype(np.int64)
    fx = x - ix
    mf = h.mesh_flat
    b = h.mesh_base + ix
    phi = mf[b] * (1.0 - fx) + mf[b + 1] * fx
    # slip: T1 w2 phi; rolling: K mu^0.7 a^0.54 w2^1.7 T1^-0.13 (Eq 18: exact power law) down to the mesh's
    # T_min (L.ROLL_TORQUE_MIN_NM per contact), below it the loss at T_min scaled by T1 / T_min: the same expression
    # with T1^-1.13 taken at T_min (continuous at T_min and at 0)
    lT_roll = np.maximum(lT, rp.mesh_roll_lt_min)
    P = (
        T1s
        * omega2_safe
        * (phi + rp.mesh_roll_k * np.exp(prop[..., P_LN_ROLL, None] + math.log(10.0) * (0.7 * lw - 1.13 * lT_roll)))
    )
    P_mesh = np.where(on, P, 0.0) * rp.mesh_heat_sf
    # shaft bearings (Eq 35-40)
    omega_b_rad_s = rp.bear_speed[row] * omega_in_col
    nu = np.exp(prop[..., P_LN_NU_CST, None])
    M0 = rp.bear_c * np.maximum(nu * omega_b_rad_s * RPM_PER_RAD_S, L.PALMGREN_NU_N_MIN) ** (2.0 / 3.0)
    P_bear = (M0 + rp.bear_load[row] * torque_nm[..., None]) * omega_b_rad_s
    # lumped into the sump: needle bearings (Eq 36-37 on relative speed), synchronizers (Eq 41), pump (Eq 42),
    # churning (Eq 23-34, table)
    rel = rp.needle_rel[row] * omega_in_col
    Mn = rp.needle_c * np.maximum(nu * rel * RPM_PER_RAD_S, L.PALMGREN_NU_N_MIN) ** (2.0 / 3.0)
    P_needle = np.sum(Mn * rel, axis=-1)
    omega_in_sq = omega_in_rad_s * omega_in_rad_s
    P_sync = np.exp(prop[..., P_LN_MU]) * omega_in_sq * rp.sync_coef[row]
    P_pump = rp.pump_coef[row] * omega_in_sq
    omega_ls_rad_s = np.abs(rp.speed_coef[row, SPEED_COL_LAYSHAFT]) * omega_in_rad_s
    uu = np.sqrt(np.minimum(omega_ls_rad_s / rp.churn_w_max, 1.0)) * (N_U_CHURN - 1)
    iu = np.minimum(np.asarray(uu).astype(np.int64), N_U_CHURN - 2)
    fu = uu - iu
    xT = np.asarray(x_T)
    jT = np.minimum(xT.astype(np.int64), h.nT - 2)
    fT = xT - jT
    cf = h.churn_flat
    b = iu * h.nT + jT
    lo = cf[b] * (1.0 - fT) + cf[b + 1] * fT
    hi = cf[b + h.nT] * (1.0 - fT) + cf[b + h.nT + 1] * fT
    P_churn = lo + (hi - lo) * fu
    P_oil = P_churn * rp.churn_heat_sf * churn_scale + P_needle * needle_scale + P_sync + P_pump
    out = np.concatenate([P_mesh, P_bear, np.stack([P_oil, np.broadcast_to(retarder_w, np.shape(P_oil))], -1)], -1)
    if src_scale is not None:
        out = out * src_scale
    return out


def cooler_heat(
    rp: ReducedParams, T_oil_c, w_ls, w_eng, T_coolant_c, T_ambient_c, v_kmh, rho_cp, scale=1.0, thermostat_offset_c=0.0
):
    """Heat from the sump to the cooler [W] (Eq 83), the oil-system flow capacity mdot cp [W/K] and the cooler's hA
    [W/K] at this operating point: :func:`firmware_model.physics.cooler.oil_cooler_heat`, the plant's model, with
    the oil flow from the layshaft speed ``w_ls`` [rad/s] and a missing vehicle speed taken as
    DEFAULT_VEHICLE_SPEED_KMH."""
    omega_ls_rad_s = np.asarray(w_ls, dtype=float)
    mcp_w_per_k = rho_cp * rp.flow_m3_per_rad * omega_ls_rad_s
    if rp.cooler_code == 0:
        z = np.zeros(np.broadcast(T_oil_c, omega_ls_rad_s).shape)
        return z, mcp_w_per_k, z
    c = helpers(rp).cooler
    Q_w, hA_w_per_k = oil_cooler_heat(
        c,
        COOLER_KINDS[rp.cooler_code],
        T_oil_c,
        omega_ls_rad_s / c.ref_ls_speed_rad_s,
        w_eng,
        T_coolant_c,
        T_ambient_c,
        np.nan_to_num(v_kmh, nan=DEFAULT_VEHICLE_SPEED_KMH),
        mcp_w_per_k,
        scale,
        thermostat_offset_c,
    )
    return Q_w, mcp_w_per_k, hA_w_per_k


# ---------------------------------------------------------------------------------------------------------------
# stability


def max_conductances(rp: ReducedParams) -> dict:
    """Upper bounds over the operating range (every gear, 0..max speed, oil OIL_RANGE_C, effects at the top of their
    plausible ranges) of every link's conductance and of the cooler's slope, from the laws themselves: power laws
    grow with speed (exponents >= 0), bilinear tables stay within their corner values, oil-temperature columns are
    piecewise linear, NTU streams are below both hA and mdot cp, radiation grows with temperature."""
    w_max = rp.max_speed_rpm * RPM
    jT = (T_GRID_C >= OIL_RANGE_C[0] - 1e-9) & (T_GRID_C <= OIL_RANGE_C[1] + 1e-9)
    jT = np.convolve(jT.astype(int), [1, 1, 1], mode="same") > 0  # neighbours bound the interpolation
    G = np.array(rp.G_const_w_per_k, dtype=float)
    phi_max = np.max(rp.pw_phi[jT], axis=0)
    eff_max = {
        EFFECT_TEETH_OIL_H: CATALOG["teeth_oil_h_scale"].high,
        EFFECT_PLANET_OIL_H: CATALOG["planet_oil_h_scale"].high,
        EFFECT_HOUSING_AIR_H: CATALOG["housing_air_h_scale"].high,
    }
    if np.any(rp.pw_exp < 0):
        raise ParameterError("a conductance law has a negative speed exponent; the stability bound needs >= 0")
    for t in range(len(rp.pw_link)):
        ph = phi_max[rp.pw_col[t]] if rp.pw_col[t] >= 0 else 1.0
        G[rp.pw_link[t]] += (
            np.max(rp.pw_gear_coef[:, t]) * w_max ** rp.pw_exp[t] * ph * eff_max.get(int(rp.pw_effect[t]), 1.0)
        )
    jT2 = jT[::T2_STRIDE]
    for t in range(len(rp.t2_link)):
        G[rp.t2_link[t]] += np.max(rp.t2_table[t][:, jT2])
    prop = rp.prop[jT]
    w_ls_max = np.max(np.abs(rp.speed_coef[:, SPEED_COL_LAYSHAFT])) * w_max
    for t in range(len(rp.ef_link)):
        planet = eff_max[EFFECT_PLANET_OIL_H] if rp.ef_effect[t] == EFFECT_PLANET_OIL_H else 1.0
        hA = rp.ef_alpha[t] * np.max(prop[:, P_K]) + rp.ef_beta[t] * planet
        m = rp.ef_mcp[t] * np.max(prop[:, P_RHO] * prop[:, P_CP]) * w_ls_max
        G[rp.ef_link[t]] += min(hA, m)
    if len(rp.cyl_link):
        # monotone in speed (Re); over the oil range sampled every 0.25 K of the interpolated properties, +2 %
        Td = np.arange(OIL_RANGE_C[0], OIL_RANGE_C[1] + 1e-9, 0.25)
        x = (Td - T_GRID_C[0]) / (T_GRID_C[1] - T_GRID_C[0])
        i = np.minimum(x.astype(np.int64), T_GRID_C.size - 2)
        f = (x - i)[:, None]
        pr = rp.prop[i] * (1.0 - f) + rp.prop[i + 1] * f
        wc = np.max(rp.cyl_speed_coef, axis=0) * w_max
        ln_re = rp.cyl_ln_rp2 + np.log(np.maximum(wc, MIN_SPEED_RAD_S)) - (pr[:, P_LN_NU_CST, None] + _LN_1E6)
        Gc = rp.cyl_c * pr[:, P_K, None] * _cyl_nusselt(ln_re, pr[:, P_LN_PR, None])
        np.add.at(G, rp.cyl_link, 1.02 * Gc.max(axis=0))
    if rp.rad_link.size:
        T1 = RAD_T_RANGE_C[1] + KELVIN_OFFSET_K
        T2 = 250.0 + KELVIN_OFFSET_K
        G[rp.rad_link] = rp.rad_area_eps * SIGMA_W_PER_M2K4 * (T1 * T1 + T2 * T2) * (T1 + T2)
    # cooler: the largest slope dQ/dT_oil (hA at the highest flows, effectiveness scale at its maximum)
    hA = cooler_hA_bound_w_per_k(
        cooler_params(rp.cooler),
        COOLER_KINDS[rp.cooler_code],
        w_ls_max,
        w_max,
        CATALOG["cooler_effectiveness_scale"].high,
    )
    return {"G": G, "cooler_hA": float(hA)}


def check_stability(rp: ReducedParams) -> dict:
    """Prove dt <= margin x C_i / max sum_j G_ij for every node (module doc); raise StabilityError naming the node."""
    h = helpers(rp)
    mc = max_conductances(rp)
    n = rp.n
    rowsum = node_conductance_w_per_k(mc["G"], h.topology)
    hA = mc["cooler_hA"]
    # the cooler on the sump, and its inlet-temperature drop dT_in = Q / (mdot cp): a stream term moves G_s dT_in
    # from its component to the sump and |d(G_s dT_in)/dT_oil| <= G_s hA / (mdot cp) <= frac_s hA
    extra = np.zeros(n)
    extra[rp.i_oil] += hA
    fracs = np.concatenate([rp.t2_frac[h.t2_streams], rp.ef_mcp / rp.flow_m3_per_rad])
    nodes = np.argmin(h.stream_scatter, axis=1)
    np.add.at(extra, nodes, fracs * hA)
    extra[rp.i_oil] += fracs.sum() * hA
    total = rowsum + extra
    dt_max = rp.margin * h.C / total
    i = int(np.argmin(dt_max))
    info = {
        "dt_max_s": dt_max,
        "max_sum_G_w_per_k": total,
        "limiting_node": rp.nodes[i],
        "C_j_per_k": float(h.C[i]),
        "margin": rp.margin,
        "tau_min_s": float(h.C[i] / total[i]),
    }
    if rp.dt_s > dt_max[i]:
        raise StabilityError(
            f"node {rp.nodes[i]} (C = {h.C[i]:.4g} J/K) has a maximum total conductance of {total[i]:.4g} W/K over "
            f"the operating range (every gear, 0..{rp.max_speed_rpm:.0f} rpm, oil {OIL_RANGE_C[0]:g}.."
            f"{OIL_RANGE_C[1]:g} degC): the explicit step dt = {rp.dt_s:g} s exceeds margin {rp.margin:g} x "
            f"C / sum G = {dt_max[i]:.4g} s; merge the node with a neighbour or raise its thermal mass"
        )
    return info
