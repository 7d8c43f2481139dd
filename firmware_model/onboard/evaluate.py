"""The onboard model at run time: its tables (:class:`ReducedParams`, built by firmware_model.onboard.reduce) and the
pure functions the step evaluates them with, each mirrored one for one by a function of the C kernel
(firmware_model/onboard/c/gvs_kernel.c names the function it mirrors): :func:`oil_row`, :func:`conductances`,
:func:`heat_sources`, :func:`retarder_heat_w`, :func:`cooler_heat`, :func:`explicit_step`. Every function broadcasts
over vehicles (arrays of shape (..., V)); names carry their SI units; indices are named (``gear_row``: gear -
GEAR_MIN; ``T_grid_x``: the fractional index on T_GRID_C).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from functools import cached_property

import numpy as np

from firmware_model.effects import EffectScales
from firmware_model.network import MIN_SPEED_RAD_S, NamedNodes
from firmware_model.onboard.kernel_interface import (
    EFFECT_HOUSING_AIR_H,
    EFFECT_PLANET_OIL_H,
    EFFECT_TEETH_OIL_H,
    P_CP,
    P_K,
    P_LN_MU,
    P_LN_NU_CST,
    P_LN_PR,
    P_LN_ROLL,
    P_LOG10_MU,
    P_RHO,
    PUMP_KINDS,
)
from firmware_model.physics import heat_transfer as ht
from firmware_model.physics import losses as L
from firmware_model.physics.conductance_matrix import link_topology
from firmware_model.physics.cooler import (
    COOLER_KINDS,
    air_temperature_c,
    cooler_params,
    heater_heat_w,
    measured_balance_heat_w,
    oil_cooler_heat,
)
from firmware_model.physics.heat_lag import heat_lag
from firmware_model.units import KELVIN_OFFSET_K, RPM_PER_RAD_S, SIGMA_W_PER_M2K4

#: the vehicle speed's place in ReducedParams.aux_expected (ambient, coolant, vehicle speed, retarder)
AUX_VKMH = 2

#: oil-temperature grid of the property and conductance tables [degC]; outside it the end rows are held
T_GRID_C = np.arange(-40.0, 200.0 + 1e-9, 5.0)
#: number of speed points of the bilinear conductance tables (in sqrt(omega / omega_max))
N_U = 17
#: number of layshaft-speed points of the churning table (in sqrt(omega / omega_max)); on the full oil grid
N_U_CHURN = 33
#: the 2-D conductance tables use every second row of T_GRID_C (10 K)
T2_STRIDE = 2
#: spacing of the mesh slip-loss tables in x = log10(torque1 / (mu omega2^3))
X_STEP = 0.125
#: linearised radiation is evaluated with housing temperatures clipped to this range [degC]
RAD_T_RANGE_C = (-40.0, 200.0)
#: cooler kind -> cooler_code (hold and measured sumps have no cooler: 0)
COOLER_CODES = {kind: code for code, kind in enumerate(COOLER_KINDS)}
#: below this input speed the conductances are evaluated at standstill (conductance_bins) [rad/s] ...
SPEED_BIN_MIN_RAD_S = 1.0
#: ... or below this share of the drive's top speed when that is less (a wind turbine's rotor turns at <= 20 rpm, its
#: high-speed shaft at 100x that): ReducedParams.speed_bin_min_rad_s
SPEED_BIN_MIN_FRAC = 0.01
#: oil pump kind (kernel_interface.PUMP_KINDS) -> pump_code
PUMP_CODES = {kind: code for code, kind in enumerate(PUMP_KINDS)}
#: ln(1e-6): kinematic viscosity from cSt (the property table's P_LN_NU_CST) to m2/s
LN_M2_S_PER_CST = math.log(1e-6)


@dataclass(frozen=True)
class ReducedParams(NamedNodes):
    """Everything the onboard step needs, as read-only arrays (a frozen, typed record; dynamax style).

    Shapes: n nodes, nl links, nb boundaries (reduce.onboard_boundaries), ns sources (src_names: reduce.source_names),
    17 gears (gear_row = gear - GEAR_MIN). Links: ``link_a`` is a node; ``link_b`` a node, or ``n + boundary index``.
    """

    variant: str
    partition: str
    nodes: tuple
    dt_s: float
    margin: float
    C_j_per_k: np.ndarray  # (n,)
    i_oil: int
    published_index: np.ndarray  # (n_pub,) node index of each published component
    published: tuple  # (n_pub,) ids of the published components (the description's published.order)
    members: tuple  # full-network node names of each reduced node
    # --- links
    link_a: np.ndarray  # (nl,)
    link_b: np.ndarray  # (nl,)
    link_name: tuple
    G_const_w_per_k: np.ndarray  # (nl,) constant part
    # power-law terms: G = coef[gear, t] * omega_in^exp[t] * (phi[T_oil, col[t]] or 1) * effect scale
    pw_link: np.ndarray  # (npw,)
    pw_exp: np.ndarray  # (npw,)
    pw_gear_coef: np.ndarray  # (17, npw) includes |shaft speed / input speed|^exp and gear masks
    pw_col: np.ndarray  # (npw,) column of pw_phi or -1
    pw_phi: np.ndarray  # (nT, ncol) oil-temperature factors
    pw_effect: np.ndarray  # (npw,) EFFECT_* (kernel_interface): none or the vehicle field that scales it
    # bilinear terms: G = table[t](sqrt(omega_t / w_max[t]), T_oil), omega_t = |speed coef[gear, t]| omega_in
    t2_link: np.ndarray  # (n2,)
    t2_speed_coef: np.ndarray  # (17, n2)
    t2_omega_max_rad_s: np.ndarray  # (n2,) rad/s
    t2_table: np.ndarray  # (n2, N_U, nT2) W/K
    t2_stream: np.ndarray  # (n2,) bool: oil-system stream (the cooler's inlet drop applies)
    t2_frac: np.ndarray  # (n2,) oil-flow fraction of a stream (for the stability bound)
    t2_effect: np.ndarray  # (n2,) 0 none (pipe flows and immersed wheels)
    # immersed wheels, Nusselt part in closed form (Eq 46-48 with the bridge of
    # heat_transfer.nusselt_rotating_cylinder): G = c[t] k_oil Nu(Re, Pr), Re = R_p^2 omega_t / nu,
    # omega_t = max(|speed coef[gear, t]| omega_in, MIN_SPEED_RAD_S)
    # (their fling-off part, Eq 54-58, is an exact sqrt(w) power law among the pw terms)
    cyl_link: np.ndarray  # (nc,)
    cyl_speed_coef: np.ndarray  # (17, nc)
    cyl_c: np.ndarray  # (nc,) area / R_p [m]
    cyl_ln_rp2: np.ndarray  # (nc,) ln(R_p^2 [m2])
    # oil-system streams in closed form (Eq 69-80, NTU): G = m (1 - exp(-hA / m)), m = mcp[t] rho cp(T) x the pump's
    # drive (pump_drive: |w_LS| of a shaft pump, 1 for a motor pump),
    # hA = alpha[t] k_oil(T) + beta[t] (channel flows: 7.54 k / D_h x area; planetary: imposed h x area)
    ef_link: np.ndarray  # (ne,)
    ef_mcp: np.ndarray  # (ne,) flow fraction x flow per unit drive (flow_per_drive: [m3/rad] shaft, [m3/s] motor)
    ef_alpha: np.ndarray  # (ne,) [m]
    ef_beta: np.ndarray  # (ne,) [W/K]
    ef_effect: np.ndarray  # (ne,) EFFECT_PLANET_OIL_H: planet_oil_h scales beta
    # radiation links: G = area_eps[r] * sigma (T1^2 + T2^2)(T1 + T2)
    rad_link: np.ndarray
    rad_area_eps: np.ndarray
    # --- oil properties on T_GRID_C
    prop: np.ndarray  # (nT, N_PROP)
    # --- losses
    speed_coef: np.ndarray  # (17, speed columns: drivetrain.speed_names) per unit input speed
    # columns of speed_coef (-1: none): the shaft that drives the oil pump (the description's oil.pump_shaft: oil
    # flow, cooler), the one whose dipping wheels churn (the churning table's speed), the output shaft (retarder)
    pump_speed_col: int
    churn_speed_col: int
    output_speed_col: int
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
    bear_rr: np.ndarray  # (17, 6) SKF rolling moment per |T|^0.31 (nu n)^0.6 (0: Palmgren alone)
    bear_ish: np.ndarray  # (6,) SKF inlet shear: the rolling moment over 1 + bear_ish (n^2 nu)^0.64
    needle_rel: np.ndarray  # (17, 6)
    needle_c: np.ndarray  # (6,)
    sync_coef: np.ndarray  # (17,) sum_k c_k rel_k^2: P_sync = mu omega_in^2 sync_coef
    pump_coef: np.ndarray  # (17,) P_pump = pump_coef omega_in^2
    # (17,) bool: the description has this gear; a gear input it has not is unknown (rejected, the last good gear held)
    gear_defined: np.ndarray
    churn_omega_max_rad_s: float
    churn_table: np.ndarray  # (N_U_CHURN, nT) W at the layshaft speed u^2 w_max
    churn_heat_sf: float
    src_matrix: np.ndarray  # (ns, n) node heat = src_power @ src_matrix
    heat_lag_tau_s: float
    # --- cooler (seed 3.4, Eq 82-83)
    cooler_code: int
    cooler: dict
    flow_m3_per_rad: float  # oil-system flow per radian of the pump shaft (a shaft-driven pump; else 0)
    pump_code: int  # PUMP_CODES: none, shaft, motor
    pump_flow_m3_s: float  # a motor-driven pump's fixed volume flow (else 0)
    pump_stop_rad_s: float  # a motor-driven pump runs only while the input shaft turns faster (0: always)
    default_v_kmh: float  # the cooler's air speed when the input has none (the plant's: a vehicle's 50, else 200)
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
    # below this input speed the conductances are evaluated at standstill (conductance_bins.speed_bin_min_rad_s)
    speed_bin_min_rad_s: float
    stability: dict = field(default_factory=dict)
    # --- the loss sources (the columns of src_matrix; reduce.source_names) and those of a planetary set
    src_names: tuple = ()
    src_planetary: tuple = ()
    # a forced oil system (the description's derived oil.inlet): the step outputs its oil inlet, the sump minus the
    # cooler's drop (SensorStatus.oil_inlet_temp_c); False: NaN
    oil_inlet: bool = False
    # the auxiliary inputs (ambient, coolant, vehicle speed, retarder) the description's drive has
    # (reduce.aux_inputs_expected); a missing one it has not is not counted in aux_missing
    aux_expected: tuple = (True, True, True, True)

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

    @cached_property
    def helpers(self) -> Helpers:
        """The derived index splits and scatter matrices (:class:`Helpers`), built on first use and kept on these
        tables (a copy of the tables builds its own)."""
        return Helpers(self)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state.pop("helpers", None)  # derived: rebuilt on first use after unpickling
        return state


def shaft_speed_rad_s(rp: ReducedParams, gear_row, col: int, omega_in_rad_s):
    """|speed| [rad/s] of the shaft in column ``col`` of speed_coef (pump_speed_col, churn_speed_col,
    output_speed_col) at this gear row and input speed; a column -1 (no such shaft) turns at 0. C: shaft_speed."""
    if col < 0:
        return 0.0 * np.abs(np.asarray(omega_in_rad_s, dtype=float))
    return np.abs(rp.speed_coef[gear_row, col]) * omega_in_rad_s


def speed_bin_min_rad_s(max_speed_rad_s: float) -> float:
    """The input speed below which the conductances are evaluated at standstill: SPEED_BIN_MIN_RAD_S (~10 rpm), or
    SPEED_BIN_MIN_FRAC of the drive's top speed when that is less."""
    return min(SPEED_BIN_MIN_RAD_S, SPEED_BIN_MIN_FRAC * max_speed_rad_s)


def pump_drive(rp: ReducedParams, gear_row, omega_in_rad_s):
    """What the oil-system flow is proportional to (flow = flow_per_drive(rp) x it): a shaft-driven pump's shaft speed
    |w| [rad/s], a motor-driven pump's 1 (its volume flow is fixed, as the plant's
    network.ConductanceEvaluator.oil_mass_flow_kg_s: rho x pump_flow, no speed, no viscosity law) and 0 while the
    input shaft turns at or below rp.pump_stop_rad_s (a pump that stops with the machine), 0 without a pump.
    C: pump_drive."""
    if rp.pump_code == PUMP_CODES["motor"]:
        if rp.pump_stop_rad_s > 0.0:
            return np.where(np.abs(omega_in_rad_s) > rp.pump_stop_rad_s, 1.0, 0.0)
        return np.ones(np.shape(omega_in_rad_s))
    return shaft_speed_rad_s(rp, gear_row, rp.pump_speed_col, omega_in_rad_s)


def flow_per_drive(rp: ReducedParams) -> float:
    """The oil-system flow per unit of pump_drive: [m3/rad] of a shaft pump, [m3/s] of a motor pump.
    C: flow_per_drive."""
    return rp.pump_flow_m3_s if rp.pump_code == PUMP_CODES["motor"] else rp.flow_m3_per_rad


def cyl_nusselt(ln_re, ln_pr):
    """Eq 46 / 47 with the geometric bridge between Re = 2.5e5 and 3.2e5, in logarithms (identical to
    heat_transfer.nusselt_rotating_cylinder)."""
    ln46 = _LN_04 + 0.5 * ln_re + ln_pr / 3.0
    ln47 = _LN_0238 + 0.8 * ln_re + 0.6 * ln_pr
    s = np.clip((ln_re - _LN_RE_LAM) / _LN_RE_BRIDGE, 0.0, 1.0)
    return np.exp(ln46 + s * (ln47 - ln46))


_LN_04, _LN_0238 = math.log(0.4), math.log(0.238)
_LN_RE_LAM = math.log(ht.RE_LAMINAR_MAX)
_LN_RE_BRIDGE = math.log(ht.RE_TURBULENT_MIN / ht.RE_LAMINAR_MAX)


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
        self.mesh_base = np.arange(rp.mesh_phi.shape[0]) * self.nx
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


def oil_row(rp: ReducedParams, T_oil_c, h: Helpers | None = None):
    """(T_grid_x, property row (..., N_PROP), pw phi row (..., ncol)) at the oil temperature; T_grid_x is the
    fractional index on T_GRID_C (held at the ends). C: oil_row."""
    h = h or rp.helpers
    T_grid_x = (np.clip(np.asarray(T_oil_c, dtype=float), T_GRID_C[0], T_GRID_C[-1]) - h.T0) / h.dT
    i = np.minimum(T_grid_x.astype(np.int64), h.nT - 2)
    f = (T_grid_x - i)[..., None]
    prop = rp.prop[i] * (1.0 - f) + rp.prop[i + 1] * f
    phi = rp.pw_phi[i] * (1.0 - f) + rp.pw_phi[i + 1] * f
    return T_grid_x, prop, phi


def sqrt_speed_index(omega_rad_s, omega_max_rad_s, n_u: int):
    """(iu, fu): the cell and fraction of ``omega_rad_s`` on a table's speed axis u = sqrt(omega / omega_max) with
    n_u points (held at omega_max). C: sqrt_speed_index."""
    uu = np.sqrt(np.minimum(omega_rad_s / omega_max_rad_s, 1.0)) * (n_u - 1)
    iu = np.minimum(np.asarray(uu).astype(np.int64), n_u - 2)
    return iu, uu - iu


def grid_index(x, n: int):
    """(j, f): the cell and fraction of a fractional index ``x`` >= 0 on a grid of n points (held at the end)."""
    x = np.asarray(x)
    j = np.minimum(x.astype(np.int64), n - 2)
    return j, x - j


def bilinear(flat, base, stride: int, fu, fT):
    """Bilinear interpolation in a table stored row-major as ``flat``: ``base`` the index of the cell's first
    corner (speed row iu, temperature column jT), ``stride`` the length of a speed row, (fu, fT) the fractions along
    speed and temperature. The one interpolation of the 2-D tables (conductances and churning). C: bilinear."""
    lo = flat[base] * (1.0 - fT) + flat[base + 1] * fT
    hi = flat[base + stride] * (1.0 - fT) + flat[base + stride + 1] * fT
    return lo + (hi - lo) * fu


def retarder_heat_w(rp: ReducedParams, gear_row, omega_in_rad_s, retarder_torque_nm, retarder_frac):
    """Heat of the retarder into the sump [W]: the share ``retarder_frac`` (effect retarder_heat) of its braking
    power, torque [N m] (a magnitude) x output-shaft speed. C: retarder_heat_w."""
    return retarder_frac * retarder_torque_nm * shaft_speed_rad_s(rp, gear_row, rp.output_speed_col, omega_in_rad_s)


def _scaled(G, idx, val):
    if idx.size == 0 or (np.ndim(val) == 0 and float(val) == 1.0):
        return G
    G = np.array(G, copy=True)
    G[..., idx] *= np.asarray(val, dtype=float)[..., None]
    return G


def conductances(
    rp: ReducedParams,
    gear_row,
    omega_in_rad_s,
    T_grid_x,
    prop,
    phi,
    T_nodes_c,
    T_bc_c,
    eff: EffectScales | None = None,
    h: Helpers | None = None,
    radiation: bool = True,
):
    """Conductance of every reduced link [W/K] (..., nl) and of the oil-system stream terms (..., nst).

    gear_row: gear - GEAR_MIN, omega_in_rad_s: input speed >= 0, (T_grid_x, prop, phi): :func:`oil_row` at the oil
    temperature; T_nodes_c / T_bc_c: node and boundary temperatures (radiation, Eq 81). C: bin_conductances."""
    h = h or rp.helpers
    omega_in_rad_s = np.asarray(omega_in_rad_s, dtype=float)
    # power laws: coef(gear) omega^e phi(T)
    ph = np.where(h.pw_has_col, np.take(phi, h.pw_colc, axis=-1), 1.0)
    Gp = rp.pw_gear_coef[gear_row] * np.power(omega_in_rad_s[..., None], rp.pw_exp) * ph
    if eff is not None:
        Gp = _scaled(Gp, h.pw_eff[EFFECT_TEETH_OIL_H], eff.teeth_oil_h)
        Gp = _scaled(Gp, h.pw_eff[EFFECT_HOUSING_AIR_H], eff.housing_air_h)
    # bilinear tables over (sqrt(omega_t / omega_max), T)
    iu, fu = sqrt_speed_index(rp.t2_speed_coef[gear_row] * omega_in_rad_s[..., None], rp.t2_omega_max_rad_s, N_U)
    jT, fT = grid_index(np.asarray(T_grid_x) / T2_STRIDE, h.nT2)
    G2 = bilinear(h.t2_flat, h.t2_base + iu * h.nT2 + jT[..., None], h.nT2, fu, fT[..., None])
    G_streams_ntu = _stream_conductances(rp, gear_row, omega_in_rad_s, prop, eff, h)
    # immersed wheels: Nusselt (Eq 46-48) in closed form
    omega_c_rad_s = np.maximum(rp.cyl_speed_coef[gear_row] * omega_in_rad_s[..., None], MIN_SPEED_RAD_S)
    ln_re = rp.cyl_ln_rp2 + np.log(omega_c_rad_s) - (prop[..., P_LN_NU_CST, None] + LN_M2_S_PER_CST)
    Gc = rp.cyl_c * prop[..., P_K, None] * cyl_nusselt(ln_re, prop[..., P_LN_PR, None])
    G = rp.G_const_w_per_k + Gp @ h.pw_scatter + G2 @ h.t2_scatter + G_streams_ntu @ h.ef_scatter + Gc @ h.cyl_scatter
    if radiation and rp.rad_link.size:
        G[..., rp.rad_link] = radiation_conductances(rp, T_nodes_c, T_bc_c, h)
    G_streams = np.concatenate([G2[..., h.t2_streams], G_streams_ntu], axis=-1)
    return G, G_streams


def _stream_conductances(rp: ReducedParams, gear_row, omega_in_rad_s, prop, eff, h: Helpers):
    """Closed-form oil-system streams [W/K]: m (1 - exp(-hA / m)), m = mdot cp (NTU effectiveness, Eq 69-80)."""
    drive = pump_drive(rp, gear_row, omega_in_rad_s)
    mcp_w_per_k = rp.ef_mcp * (prop[..., P_RHO] * prop[..., P_CP] * drive)[..., None]
    beta_w_per_k = rp.ef_beta
    if eff is not None and h.ef_planet.size and not (np.ndim(eff.planet_oil_h) == 0 and eff.planet_oil_h == 1.0):
        beta_w_per_k = _scaled(np.broadcast_to(beta_w_per_k, mcp_w_per_k.shape), h.ef_planet, eff.planet_oil_h)
    hA_w_per_k = rp.ef_alpha * prop[..., P_K, None] + beta_w_per_k
    mcp_safe_w_per_k = np.where(mcp_w_per_k > 0.0, mcp_w_per_k, 1.0)
    return np.where(mcp_w_per_k > 0.0, -mcp_safe_w_per_k * np.expm1(-hA_w_per_k / mcp_safe_w_per_k), 0.0)


def explicit_step(
    T_c, q_w, G_int_w_per_k, G_ext_w_per_k, T_bc_c, ia, ib, ea, eb, dt_over_C_s_k_per_j, B_int=None, B_ext=None
):
    """One forward-Euler step of C dT/dt = sum_links G (T_other - T) + q on any graph (pure array math).

    T_c (..., n); q_w (..., n) heat into each node; G_int_w_per_k (..., n_int) conductances of the node-node links
    (ia, ib); G_ext_w_per_k (..., n_ext) of the node-boundary links (ea, eb into T_bc_c (..., nb));
    dt_over_C_s_k_per_j (n,). B_int / B_ext: the links' incidence matrices (Helpers) to scatter with one matrix
    product instead of index sums. C: the explicit step of network_step."""
    n = T_c.shape[-1]
    f_int = G_int_w_per_k * (np.take(T_c, ia, axis=-1) - np.take(T_c, ib, axis=-1))  # heat from a to b [W]
    f_ext = G_ext_w_per_k * (np.take(T_c, ea, axis=-1) - np.take(T_bc_c, eb, axis=-1))
    if B_int is not None:
        # one matrix product over every vehicle and copy (a stacked matmul would loop over small ones)
        lead = np.broadcast_shapes(f_int.shape[:-1], f_ext.shape[:-1], T_c.shape[:-1])
        rows = int(np.prod(lead, dtype=np.int64))
        rate = np.array(q_w, dtype=float) + np.zeros(lead + (n,))
        for f, Bm in ((f_int, B_int), (f_ext, B_ext)):
            if f.shape[-1]:
                rate += (np.broadcast_to(f, lead + f.shape[-1:]).reshape(rows, f.shape[-1]) @ Bm).reshape(lead + (n,))
    else:
        rate = q_w - _scatter(f_int, ia, n) + _scatter(f_int, ib, n) - _scatter(f_ext, ea, n)
    return T_c + dt_over_C_s_k_per_j * rate


def _scatter(f, idx, n):
    """out[..., j] = sum of f[..., k] over idx[k] == j."""
    out = np.zeros(f.shape[:-1] + (n,))
    if f.size:
        flat = out.reshape(-1, n)
        np.add.at(flat, (slice(None), idx), f.reshape(-1, f.shape[-1]))
    return out


def radiation_conductances(rp: ReducedParams, T_nodes_c, T_bc_c, h: Helpers | None = None):
    """Linearised radiation conductance of every radiation link [W/K] (Eq 81), housing temperatures clipped."""
    h = h or rp.helpers
    T_node_k = (
        np.minimum(np.maximum(np.take(T_nodes_c, h.rad_node, axis=-1), RAD_T_RANGE_C[0]), RAD_T_RANGE_C[1])
        + KELVIN_OFFSET_K
    )
    T_bc_k = np.take(T_bc_c, h.rad_bc, axis=-1) + KELVIN_OFFSET_K
    return radiation_w_per_k(rp.rad_area_eps, T_node_k, T_bc_k)


def radiation_w_per_k(area_eps_m2, T_node_k, T_bc_k):
    """Linearised radiation conductance [W/K] of a surface (area x emissivity) at T_node_k facing T_bc_k (Eq 81)."""
    return area_eps_m2 * SIGMA_W_PER_M2K4 * (T_node_k * T_node_k + T_bc_k * T_bc_k) * (T_node_k + T_bc_k)


def heat_sources(
    rp: ReducedParams,
    gear_row,
    omega_in_rad_s,
    torque_abs_nm,
    prop,
    T_grid_x,
    src_scale=None,
    churn_scale=1.0,
    needle_scale=1.0,
    retarder_w=0.0,
    h: Helpers | None = None,
):
    """Heat of every source [W], shape (..., ns: rp.src_names): meshes (Eq 7-22, x seed heat factors), shaft bearings
    (Eq 35-40, with SKF's rolling term where a description gives one: physics.losses.skf_rolling_torque_nm), the
    oil-lumped sources (churning x 1.33, needle bearings, synchronizers, pump) and the retarder
    (:func:`retarder_heat_w`). C: heat_sources."""
    h = h or rp.helpers
    omega_in_rad_s = np.asarray(omega_in_rad_s, dtype=float)
    torque_nm = np.asarray(torque_abs_nm, dtype=float)
    P_mesh_w = _mesh_heat_w(rp, gear_row, omega_in_rad_s, torque_nm, prop, h)
    # shaft bearings (Eq 35-40)
    omega_in_col = omega_in_rad_s[..., None]
    omega_b_rad_s = rp.bear_speed[gear_row] * omega_in_col
    nu_cst = np.exp(prop[..., P_LN_NU_CST, None])
    M0_nm = rp.bear_c * np.maximum(nu_cst * omega_b_rad_s * RPM_PER_RAD_S, L.PALMGREN_NU_N_MIN) ** (2.0 / 3.0)
    M_load_nm = rp.bear_load[gear_row] * torque_nm[..., None]
    if rp.bear_rr.any():  # SKF's rolling term over its inlet shear, where a description gives bearing.R1_<kind>
        n_b_rpm = omega_b_rad_s * RPM_PER_RAD_S
        M_load_nm = M_load_nm + (
            rp.bear_rr[gear_row]
            * torque_nm[..., None] ** L.SKF_RR_LOAD_EXP
            * (nu_cst * n_b_rpm) ** L.SKF_RR_NU_N_EXP
            / (1.0 + rp.bear_ish * (n_b_rpm * n_b_rpm * nu_cst) ** L.SKF_ISH_EXP)
        )
    P_bear_w = (M0_nm + M_load_nm) * omega_b_rad_s
    # lumped into the sump: needle bearings (Eq 36-37 on relative speed), synchronizers (Eq 41), pump (Eq 42),
    # churning (Eq 23-34, table)
    omega_rel_rad_s = rp.needle_rel[gear_row] * omega_in_col
    M_needle_nm = rp.needle_c * np.maximum(nu_cst * omega_rel_rad_s * RPM_PER_RAD_S, L.PALMGREN_NU_N_MIN) ** (2.0 / 3.0)
    P_needle_w = np.sum(M_needle_nm * omega_rel_rad_s, axis=-1)
    omega_in_sq = omega_in_rad_s * omega_in_rad_s
    P_sync_w = np.exp(prop[..., P_LN_MU]) * omega_in_sq * rp.sync_coef[gear_row]
    P_pump_w = rp.pump_coef[gear_row] * omega_in_sq
    omega_ls_rad_s = shaft_speed_rad_s(rp, gear_row, rp.churn_speed_col, omega_in_rad_s)
    iu, fu = sqrt_speed_index(omega_ls_rad_s, rp.churn_omega_max_rad_s, N_U_CHURN)
    jT, fT = grid_index(T_grid_x, h.nT)
    P_churn_w = bilinear(h.churn_flat, iu * h.nT + jT, h.nT, fu, fT)
    P_oil_w = P_churn_w * rp.churn_heat_sf * churn_scale + P_needle_w * needle_scale + P_sync_w + P_pump_w
    P_lumped_w = np.stack([P_oil_w, np.broadcast_to(retarder_w, np.shape(P_oil_w))], -1)
    out = np.concatenate([P_mesh_w, P_bear_w, P_lumped_w], -1)
    if src_scale is not None:
        out = out * src_scale
    return out


def _mesh_heat_w(rp: ReducedParams, gear_row, omega_in_rad_s, torque_nm, prop, h: Helpers):
    """Heat of every mesh [W] (..., 9): slip (Eq 7-10, one 1-D table per mesh) and rolling (Eq 14-22), x the seed's
    loss-to-heat factor; torque1 is the torque on the mesh's wheel 1, omega2 the speed of its wheel 2."""
    torque1_nm = rp.mesh_torque[gear_row] * torque_nm[..., None]
    omega2_rad_s = rp.mesh_omega2[gear_row] * omega_in_rad_s[..., None]
    on = (torque1_nm > 0.0) & (omega2_rad_s > 0.0)
    torque1_safe_nm = np.where(on, torque1_nm, 1.0)
    omega2_safe_rad_s = np.where(on, omega2_rad_s, 1.0)
    log10_torque1, log10_omega2 = np.log10(torque1_safe_nm), np.log10(omega2_safe_rad_s)
    x = (log10_torque1 - prop[..., P_LOG10_MU, None] - 3.0 * log10_omega2 - rp.mesh_x0) / X_STEP
    x = np.clip(x, 0.0, h.nx - 1.000001)
    ix = x.astype(np.int64)
    fx = x - ix
    mf = h.mesh_flat
    b = h.mesh_base + ix
    phi = mf[b] * (1.0 - fx) + mf[b + 1] * fx
    # slip: torque1 omega2 phi; rolling: K mu^0.7 a^0.54 omega2^1.7 torque1^-0.13 (Eq 18: exact power law) down to
    # the mesh's torque1_min (L.ROLL_TORQUE_MIN_NM per contact), below it the loss at torque1_min scaled by
    # torque1 / torque1_min: the same expression with torque1^-1.13 taken at torque1_min (continuous there and at 0)
    log10_torque1_roll = np.maximum(log10_torque1, rp.mesh_roll_lt_min)
    rolling = rp.mesh_roll_k * np.exp(
        prop[..., P_LN_ROLL, None] + math.log(10.0) * (0.7 * log10_omega2 - 1.13 * log10_torque1_roll)
    )
    P_w = torque1_safe_nm * omega2_safe_rad_s * (phi + rolling)
    return np.where(on, P_w, 0.0) * rp.mesh_heat_sf


def cooler_heat(
    rp: ReducedParams,
    T_oil_c,
    drive,
    omega_eng_rad_s,
    T_coolant_c,
    T_ambient_c,
    v_kmh,
    rho_cp_j_per_m3k,
    effectiveness_scale=1.0,
    thermostat_offset_c=0.0,
):
    """Heat from the sump to the cooler [W] (Eq 83), the oil-system flow capacity mdot cp [W/K] and the cooler's hA
    [W/K] at this operating point: :func:`firmware_model.physics.cooler.oil_cooler_heat`, the plant's model, with
    the oil flow flow_per_drive x ``drive`` (:func:`pump_drive`: the layshaft speed of the GRS905's pump) and a
    missing vehicle speed (or any, for a drive that has none) taken as rp.default_v_kmh; the inner flow over the data
    sheet's: a shaft pump's speed over the reference speed, a motor pump's 1 (it runs at its own flow, as the
    plant's); ``effectiveness_scale``: the effect cooler_effectiveness_scale. The sump heater's heat
    (:func:`firmware_model.physics.cooler.heater_heat_w`) is taken off: the heat the sump gives the oil system,
    net. C: cooler_op, cooler_heat and heater_heat."""
    drive = np.asarray(drive, dtype=float)
    mcp_w_per_k = rho_cp_j_per_m3k * flow_per_drive(rp) * drive
    c = rp.helpers.cooler
    if rp.cooler_code == 0:
        z = np.zeros(np.broadcast(T_oil_c, drive).shape)
        return z - heater_heat_w(c, T_oil_c), mcp_w_per_k, z
    Q_w, hA_w_per_k = oil_cooler_heat(
        c,
        COOLER_KINDS[rp.cooler_code],
        T_oil_c,
        drive if rp.pump_code == PUMP_CODES["motor"] else drive / c.ref_ls_speed_rad_s,
        omega_eng_rad_s,
        T_coolant_c,
        T_ambient_c,
        # a drive without a vehicle speed (a wind turbine, a rig) has no ram air and no recirculation at low speed:
        # rp.default_v_kmh whatever the input holds (the plant's stationary machine), as the C kernel's cooler_op
        np.nan_to_num(v_kmh, nan=rp.default_v_kmh) if rp.aux_expected[AUX_VKMH] else rp.default_v_kmh,
        mcp_w_per_k,
        effectiveness_scale,
        thermostat_offset_c,
    )
    return Q_w - heater_heat_w(c, T_oil_c), mcp_w_per_k, hA_w_per_k


def measured_cooler_heat(rp, H_w, G_streams_sum_w_per_k, mcp_w_per_k, hA_w_per_k, T_oil_c, T_ambient_c, v_kmh):
    """The cooler's heat net of the heater [W] with the sump measured and the description's ``measured_cooler`` =
    "balance" (:func:`firmware_model.physics.cooler.measured_balance_heat_w`): the sump's gain ``H_w``, the jets'
    stream conductances summed over mdot cp, the cooler's hA and air as :func:`cooler_heat`'s (a drive without a
    vehicle speed: rp.default_v_kmh); no oil flow: 0. C: balance_heat."""
    m = np.asarray(mcp_w_per_k, dtype=float)
    frac = np.where(m > 0.0, G_streams_sum_w_per_k / np.where(m > 0.0, m, 1.0), 0.0)
    v = np.nan_to_num(v_kmh, nan=rp.default_v_kmh) if rp.aux_expected[AUX_VKMH] else rp.default_v_kmh
    T_air_c = air_temperature_c(T_ambient_c, v)
    Q_w = measured_balance_heat_w(rp.helpers.cooler, H_w, frac, hA_w_per_k, T_oil_c, T_air_c)
    return np.where(m > 0.0, Q_w, 0.0)


def sump_gain_w(h, i_oil: int, T_c, q_nodes_w, G_int_w_per_k, G_ext_w_per_k, T_bc_c):
    """The heat into the sump node [W] at temperatures ``T_c`` (B + (n,)): its share of the sources ``q_nodes_w`` and
    its links to the other nodes and to the boundaries (the jets' streams and the cooler left out). C: the sum in
    network_step."""
    gain_w = q_nodes_w[..., i_oil] - (G_int_w_per_k * (T_c[..., h.ib] - T_c[..., h.ia])) @ h.B_int[:, i_oil]
    return gain_w - (G_ext_w_per_k * (T_bc_c[..., h.eb] - T_c[..., h.ea])) @ h.B_ext[:, i_oil]
