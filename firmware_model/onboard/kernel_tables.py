"""The C kernel's data, generated from the one description: :func:`table_arrays` turns a
:class:`~firmware_model.onboard.params.SensorParams` (the onboard build of a gearbox variant, its limits, options and
effects) into the named arrays and numbers of the kernel's ``gvs_tables`` struct, and :func:`vehicle_arrays` into
each vehicle's ``gvs_vehicle`` (effects and boundary defaults). The same arrays are handed to the kernel at run time
(firmware_model.onboard.compiled) and written as C ``const`` arrays for an embedded build (tools, export-c). No
number is copied by hand: every value comes from the build or from the named constants of the physics modules.
The fields and their order are the struct's, described once in :mod:`firmware_model.onboard.kernel_interface`.
"""

from __future__ import annotations

import math

import numpy as np

from firmware_model.network import MIN_SPEED_RAD_S
from firmware_model.onboard import evaluate as E
from firmware_model.onboard.conductance_bins import LN_SPEED_BIN, OIL_BIN_C
from firmware_model.onboard.kernel_interface import STRUCT, VEHICLE_EFFECTS, struct_values
from firmware_model.onboard.params import SensorParams
from firmware_model.onboard.sparse_ldl import ldl_pattern
from firmware_model.physics import heat_transfer as ht
from firmware_model.physics import losses as L
from firmware_model.physics.cooler import (
    AIR_FLOW_MAX_REL,
    AIR_RECIRC_DT_K,
    AIR_RECIRC_V_KMH,
    AIR_REF_SPEED_KMH,
    BALANCE_KEEP_MIN,
    INLET_DROP_MAX_K,
)
from firmware_model.physics.kinematics import GEAR_MIN
from firmware_model.units import KELVIN_OFFSET_K, RAD_S_PER_RPM, RPM_PER_RAD_S, SIGMA_W_PER_M2K4


def _i32(a) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a).reshape(-1), dtype=np.int32)


def _f64(a) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=float).reshape(-1))


def _gear_bits(defined) -> int:
    """The description's gears as the bits of one int32 (bit r: gear row r), a flag per gear in 4 B of flash."""
    defined = np.asarray(defined, dtype=bool).reshape(-1)
    if defined.size > 31:  # bit 31 would be the sign of the int32
        raise ValueError(f"{defined.size} gear rows do not fit the int32 gear_defined (at most 31)")
    return int(sum(1 << r for r in np.flatnonzero(defined)))


def _streams(sp: SensorParams) -> tuple[np.ndarray, np.ndarray]:
    """(t2 term of each table stream, component node of every stream) from the stream scatter matrix (its row:
    -1 at the component, +1 at the sump)."""
    h, rp = sp.helpers, sp.reduced
    S = np.asarray(h.stream_scatter)
    node = np.argmin(S, axis=1)
    expect = np.zeros_like(S)
    expect[np.arange(S.shape[0]), node] = -1.0
    expect[:, rp.i_oil] += 1.0
    if not np.array_equal(S, expect):
        raise ValueError("every oil-system stream must join one component to the sump")
    return _i32(h.t2_streams), _i32(node)


def _sources(rp: E.ReducedParams) -> dict:
    """The source -> node matrix as its non-zeros (the kernel loops over them)."""
    src, node = np.nonzero(np.asarray(rp.src_matrix))
    return dict(
        nsrc_nz=int(src.size),
        src_nz_src=_i32(src),
        src_nz_node=_i32(node),
        src_nz_w=_f64(np.asarray(rp.src_matrix)[src, node]),
    )


def _network(sp: SensorParams) -> dict:
    rp, h = sp.reduced, sp.helpers
    t2_stream_term, stream_node = _streams(sp)
    return dict(
        n=rp.n,
        nl=len(rp.link_a),
        nb=len(rp.bc_default_c),
        ns=len(rp.src_names),
        npw=len(rp.pw_link),
        n2=len(rp.t2_link),
        nc=len(rp.cyl_link),
        ne=len(rp.ef_link),
        nrad=len(rp.rad_link),
        nst=int(stream_node.size),
        nT=h.nT,
        ncol=rp.pw_phi.shape[1],
        n_u=E.N_U,
        nT2=h.nT2,
        n_u_churn=E.N_U_CHURN,
        nx=h.nx,
        n_mesh=rp.mesh_torque.shape[1],
        n_bear=rp.bear_c.size,
        n_needle=rp.needle_c.size,
        n_speed=rp.speed_coef.shape[1],
        n_gears=rp.speed_coef.shape[0],
        n_pub=len(rp.published_index),
        pump_speed_col=rp.pump_speed_col,
        churn_speed_col=rp.churn_speed_col,
        output_speed_col=rp.output_speed_col,
        i_oil=rp.i_oil,
        i_ambient=rp.i_ambient,
        i_coolant=rp.i_coolant,
        cooler_code=rp.cooler_code,
        pump_code=rp.pump_code,
        oil_inlet=int(rp.oil_inlet),
        gear_min=GEAR_MIN,
        gear_defined=_gear_bits(rp.gear_defined),
        aux_expected=int(sum(1 << i for i, has in enumerate(rp.aux_expected) if has)),
        dt_over_C=_f64(sp.dt_over_C_s_k_per_j),
        link_a=_i32(rp.link_a),
        link_b=_i32(rp.link_b),
        G_const=_f64(rp.G_const_w_per_k),
        published_index=_i32(rp.published_index),
        pw_link=_i32(rp.pw_link),
        pw_col=_i32(rp.pw_col),
        pw_effect=_i32(rp.pw_effect),
        pw_exp=_f64(rp.pw_exp),
        pw_gear_coef=_f64(rp.pw_gear_coef),
        pw_phi=_f64(rp.pw_phi),
        t2_link=_i32(rp.t2_link),
        t2_speed_coef=_f64(rp.t2_speed_coef),
        t2_omega_max_rad_s=_f64(rp.t2_omega_max_rad_s),
        t2_table=_f64(rp.t2_table),
        t2_scale=np.ones(rp.t2_table.shape[0]),
        t2_stride=E.T2_STRIDE,
        cyl_link=_i32(rp.cyl_link),
        cyl_speed_coef=_f64(rp.cyl_speed_coef),
        cyl_c=_f64(rp.cyl_c),
        cyl_ln_rp2=_f64(rp.cyl_ln_rp2),
        ef_link=_i32(rp.ef_link),
        ef_effect=_i32(rp.ef_effect),
        ef_mcp=_f64(rp.ef_mcp),
        ef_alpha=_f64(rp.ef_alpha),
        ef_beta=_f64(rp.ef_beta),
        rad_link=_i32(rp.rad_link),
        rad_node=_i32(h.rad_node),
        rad_bc=_i32(h.rad_bc),
        rad_area_eps=_f64(rp.rad_area_eps),
        t2_stream_term=t2_stream_term,
        stream_node=stream_node,
        prop=_f64(rp.prop),
        T_grid0_c=h.T0,
        T_grid_step_k=h.dT,
    )


def _losses(sp: SensorParams) -> dict:
    rp = sp.reduced
    return dict(
        speed_coef=_f64(rp.speed_coef),
        mesh_torque=_f64(rp.mesh_torque),
        mesh_omega2=_f64(rp.mesh_omega2),
        mesh_x0=_f64(rp.mesh_x0),
        mesh_phi=_f64(rp.mesh_phi),
        mesh_roll_k=_f64(rp.mesh_roll_k),
        mesh_heat_sf=_f64(rp.mesh_heat_sf),
        mesh_roll_lt_min=_f64(rp.mesh_roll_lt_min),
        bear_speed=_f64(rp.bear_speed),
        bear_c=_f64(rp.bear_c),
        bear_load=_f64(rp.bear_load),
        bear_rr=_f64(rp.bear_rr),
        bear_ish=_f64(rp.bear_ish),
        needle_rel=_f64(rp.needle_rel),
        needle_c=_f64(rp.needle_c),
        sync_coef=_f64(rp.sync_coef),
        pump_coef=_f64(rp.pump_coef),
        churn_table=_f64(rp.churn_table),
        churn_omega_max_rad_s=rp.churn_omega_max_rad_s,
        churn_heat_sf=rp.churn_heat_sf,
        x_step=E.X_STEP,
        ln10=math.log(10.0),
        lag_gain=sp.helpers.heat_lag.gain,
        lag_tau_over_dt=sp.helpers.heat_lag.tau_over_dt,
        **_sources(rp),
    )


def _cooler(sp: SensorParams) -> dict:
    rp = sp.reduced
    c = sp.helpers.cooler
    return dict(
        flow_m3_per_rad=rp.flow_m3_per_rad,
        pump_flow_m3_s=rp.pump_flow_m3_s,
        pump_stop_rad_s=rp.pump_stop_rad_s,
        speed_bin_min=rp.speed_bin_min_rad_s,
        liquid_hA_ref=c.liquid_hA_ref_w_per_k,
        liquid_Qmax_cool=c.liquid_Q_max_cool_w,
        liquid_Qmax_heat=c.liquid_Q_max_heat_w,
        air_hA_ref=c.air_hA_ref_w_per_k,
        air_Qmax_cool=c.air_Q_max_cool_w,
        thermostat_open_c=c.thermostat_open_c,
        thermostat_full_c=c.thermostat_full_c,
        thermostat_sump=c.thermostat_sump,
        heater_w=c.heater_w,
        heater_set_c=c.heater_set_c,
        heater_band_k=c.heater_band_k,
        measured_balance=c.measured_balance,
        balance_keep_min=BALANCE_KEEP_MIN,
        ref_ls_speed=c.ref_ls_speed_rad_s,
        ref_engine_speed=c.ref_engine_speed_rad_s,
        exp_inner=c.exp_inner,
        exp_outer=c.exp_outer,
        air_flow_min_frac=c.air_flow_min_frac,
        air_ref_speed_kmh=AIR_REF_SPEED_KMH,
        air_flow_max_rel=AIR_FLOW_MAX_REL,
        inlet_drop_max_k=INLET_DROP_MAX_K,
        default_vkmh=rp.default_v_kmh,
        recirc_v_kmh=_f64(AIR_RECIRC_V_KMH),
        recirc_dT_k=_f64(AIR_RECIRC_DT_K),
        n_recirc=AIR_RECIRC_V_KMH.size,
    )


def _constants() -> dict:
    return dict(
        sigma=SIGMA_W_PER_M2K4,
        kelvin=KELVIN_OFFSET_K,
        rpm_per_rad_s=RPM_PER_RAD_S,
        rad_s_per_rpm=RAD_S_PER_RPM,
        palmgren_min=L.PALMGREN_NU_N_MIN,
        min_speed=MIN_SPEED_RAD_S,
        ln_04=math.log(0.4),
        ln_0238=math.log(0.238),
        ln_re_lam=math.log(ht.RE_LAMINAR_MAX),
        ln_re_bridge=math.log(ht.RE_TURBULENT_MIN / ht.RE_LAMINAR_MAX),
        ln_1e6=E.LN_M2_S_PER_CST,
        rad_T_lo_c=E.RAD_T_RANGE_C[0],
        rad_T_hi_c=E.RAD_T_RANGE_C[1],
        ln_speed_bin=LN_SPEED_BIN,
        oil_bin_c=OIL_BIN_C,
    )


def _sensor(sp: SensorParams) -> dict:
    opt, lim = sp.options, sp.limits
    return dict(
        oil_mode_measured=int(opt.oil_mode == "measured"),
        ttl_every=sp.ttl_every,
        dt_s=sp.dt_s,
        input_lo=_f64(sp.input_lo),
        input_hi=_f64(sp.input_hi),
        clamp_lo=_f64(sp.clamp_lo),
        clamp_hi=_f64(sp.clamp_hi),
        aux_default=_f64(sp.aux_default),
        hold_s=opt.hold_s,
        drive_frozen_s=opt.drive_frozen_s,
        oil_frozen_s=opt.oil_frozen_s,
        oil_frozen_drift_c=opt.oil_frozen_drift_c,
        oil_step_c=opt.oil_step_c,
        oil_period_s=opt.oil_period_s,
        clock_reset_s=opt.clock_reset_s,
        warning_c=_f64(lim.warning_c),
        critical_c=_f64(lim.critical_c),
        hysteresis_k=_f64(lim.hysteresis_k),
        warning_rest_c=_f64(sp.warning_rest_c),
        debounce_s=lim.debounce_s,
        lead_s=lim.lead_s,
    )


def _time_to_limit(sp: SensorParams) -> dict:
    """The time to limit's tables: heat capacities, the sparse LDL^T pattern (firmware_model.onboard.sparse_ldl),
    the components whose crossing re-linearises, the options."""
    rp, h = sp.reduced, sp.helpers
    pat = ldl_pattern(rp.link_a, rp.link_b, rp.n, rp.i_oil)
    return dict(
        C_j_per_k=_f64(h.C),
        ldl_perm=_i32(pat.perm),
        ldl_pos=_i32(pat.pos),
        ldl_col_ptr=_i32(pat.col_ptr),
        ldl_row=_i32(pat.row),
        ldl_link_slot=_i32(pat.link_slot),
        ldl_upd_ptr=_i32(pat.upd_ptr),
        ldl_upd_target=_i32(pat.upd_target),
        ldl_upd_a=_i32(pat.upd_a),
        ldl_upd_b=_i32(pat.upd_b),
        ttl_relin=_i32(h.ttl_relin_pub),
        ldl_nnz=int(pat.row.size),
        ldl_nupd=int(pat.upd_target.size),
        ttl_sump_model=int(sp.options.ttl_sump == "model"),
        ttl_relinearise=int(bool(sp.scalar_effects)),
        ttl_bound=int(sp.options.ttl_method == "bound"),
    )


def table_arrays(sp: SensorParams, ttl: bool = True) -> dict:
    """{gvs_tables field: int, float or 1-D array (int32 or float64)} of a sensor's parameters, in the struct's order
    (firmware_model.onboard.kernel_interface: a field left out or one the struct lacks raises). ``ttl`` False:
    without the time to limit's arrays (empty, ``ldl_nnz`` 0: gvs_ttl_refresh then publishes NaN), for a build
    short of flash (export-c --no-ttl; the caller also turns the early warning off)."""
    ttl_arrays = _time_to_limit(sp)
    if not ttl:
        ttl_arrays = {
            k: (np.zeros(0, dtype=v.dtype) if isinstance(v, np.ndarray) else v) for k, v in ttl_arrays.items()
        }
        ttl_arrays["ldl_nnz"] = ttl_arrays["ldl_nupd"] = 0
    return struct_values(
        STRUCT["Tables"], {**_network(sp), **_losses(sp), **_cooler(sp), **_constants(), **_sensor(sp), **ttl_arrays}
    )


def vehicle_arrays(sp: SensorParams, n_vehicles: int | None) -> dict:
    """{gvs_vehicle field: array (V, ...)} of every vehicle (None: one vehicle, V = 1): the effects (per vehicle or
    the same for all) and the boundary defaults with the hot-surroundings offset."""
    V = 1 if n_vehicles is None else int(n_vehicles)
    e = sp.effects
    out = {k: np.broadcast_to(np.asarray(getattr(e, k), dtype=float), (V,)).copy() for k in VEHICLE_EFFECTS}
    out["src_scale"] = np.broadcast_to(np.asarray(e.src_scale, dtype=float), (V, len(sp.reduced.src_names))).copy()
    bc = np.asarray(sp.T_bc_default_c, dtype=float)
    out["T_bc_default_c"] = np.broadcast_to(bc, (V, bc.shape[-1])).copy()
    return struct_values(STRUCT["Vehicle"], out)
