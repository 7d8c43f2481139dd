/* GENERATED from firmware_model/onboard/kernel_interface.py: do not edit. Regenerate with
 * `python -m firmware_model.onboard.kernel_interface --write`
 * (tests/firmware_model/test_kernel_interface.py compares). */
/* gearbox-vsensor onboard step: a generic C99 kernel.
 *
 * One call of gvs_step() is one 0.1 s step of the onboard virtual sensor, exactly as the numpy reference
 * (firmware_model/onboard/step.py, step_deferred) does it: input checks, holds and reject counters; loss maps
 * and conductance laws at the centre of the operating point's bin; the heat lag; the cooler and its inlet drop;
 * one explicit (forward Euler) step of the main network and of the open-loop twin; warning levels with hysteresis
 * and debounce (early warning from the time to limit); degraded modes and status.
 *
 * Everything gearbox-specific is data (struct gvs_tables), generated from the one description by
 * firmware_model.onboard.kernel_tables: handed over at run time from Python, or written as a C source of const
 * arrays for an embedded build. The kernel has no dynamic allocation, no I/O, no mutable globals, and uses
 * nothing from libc beyond <math.h>, <string.h> and <stdint.h>.
 *
 * The real type is chosen at compile time: double by default (parity with the numpy reference), float with
 * -DGVS_REAL_FLOAT (an ECU with a single-precision FPU). Time stamps stay double in both builds.
 *
 * The time to limit is refreshed every ttl_every steps from the operating point a step hands out in a
 * gvs_ttl_point: gvs_ttl_refresh() marches the held-input system (no eigen-decomposition: a sparse LDL^T and
 * TR-BDF2 on a geometric grid; docs/sensor.md), gvs_run() does it in place when asked, and a caller that wants the
 * step's frames out first calls it after the step. One part of the sensor is left to the host: the propagation of
 * the state over a forward time jump (the kernel returns GVS_NEED_JUMP before touching the state; the host
 * propagates state->T_c and calls again with jump_done = 1).
 */
#ifndef GVS_KERNEL_H
#define GVS_KERNEL_H

#include <stdint.h>

/* The kernel's and the API's NaN and range checks are comparisons with NaN: -ffast-math (-ffinite-math-only) lets
 * the compiler assume they never hold, so bad input reads as good and tables are indexed with garbage (a crash under
 * clang). Every file that includes this header stops; gvs_check_tables() also refuses to step a build whose NaN
 * comparisons do not work (clang's -fno-honor-nans defines no macro). */
#if defined(__FAST_MATH__) || defined(__FINITE_MATH_ONLY__) && __FINITE_MATH_ONLY__
#error "gearbox-vsensor's C must not be compiled with -ffast-math or -ffinite-math-only (its NaN checks would vanish)"
#endif

/* the sources' SHA-256 prefix this build was made from */
extern const char *const gvs_source_id_str;

#ifdef GVS_REAL_FLOAT
typedef float gvs_real;
#else
typedef double gvs_real;
#endif

/* the tables' index arrays: int32 (the Python binding's), or int16 in an exported build whose indices all fit
 * (GVS_INDEX16, set by the export's Makefile: half the flash of the index tables) */
#ifdef GVS_INDEX16
typedef int16_t gvs_idx;
#else
typedef int32_t gvs_idx;
#endif

/* the bilinear conductance tables (t2_table): gvs_real, or int16 steps of a per-table scale (t2_scale) in an
 * exported float build (GVS_T2_Q16, set by the export: 9 KB of flash; within 1.5e-5 of each table's largest value) */
#ifdef GVS_T2_Q16
typedef int16_t gvs_t2;
#else
typedef gvs_real gvs_t2;
#endif

/* capacities of the plain structs (the tables give the actual sizes; gvs_check_tables() refuses larger ones);
 * an ECU build sets them to the exported variant's sizes (-DGVS_MAX_NODES=61 ...) to save RAM */
#ifndef GVS_MAX_NODES
/* nodes of the network */
#define GVS_MAX_NODES 96
#endif
#ifndef GVS_MAX_LINKS
/* links */
#define GVS_MAX_LINKS 192
#endif
#ifndef GVS_MAX_SRC
/* heat sources */
#define GVS_MAX_SRC 32
#endif
#ifndef GVS_MAX_BC
/* boundary temperatures */
#define GVS_MAX_BC 8
#endif
#ifndef GVS_MAX_STREAMS
/* oil-system streams */
#define GVS_MAX_STREAMS 32
#endif
#ifndef GVS_MAX_LNZ
/* entries of L below the diagonal in the time to limit's sparse LDL^T (GRS905: 178) */
#define GVS_MAX_LNZ 512
#endif
#ifndef GVS_MAX_TERMS
/* the most terms of one kind of conductance law (tables, closed-form streams) and oil-factor columns */
#define GVS_MAX_TERMS 64
#endif
#ifndef GVS_MAX_PUB
/* published components (tables.n_pub; the description's published.order) */
#define GVS_MAX_PUB 48
#endif
#ifndef GVS_MAX_GEARS
/* gear rows of the per-gear tables (tables.n_gears) */
#define GVS_MAX_GEARS 32
#endif

#define GVS_N_INPUTS 8                          /* input fields (records.INPUT_FIELDS) */
#define GVS_N_REJECT 13                         /* reject counters (records.REJECT_REASONS) */
#define GVS_N_PROP 8                            /* columns of the oil property table */
#define GVS_SKF_RR_LOAD_EXP 0.31                /* SKF's rolling moment: exponent of the load (tables.bear_rr) */
#define GVS_SKF_RR_NU_N_EXP 0.6                 /* ... and of nu n [cSt rpm] */
#define GVS_SKF_ISH_EXP 0.64                    /* ... its inlet shear factor: exponent of n^2 nu [rpm2 cSt] */
#define GVS_MARCH_H0_S 1.0                      /* time to limit: first march step [s] */
#define GVS_MARCH_RATIO 1.4                     /* each march step this many times longer than the last */
#define GVS_TTL_HORIZON_S 2000000.0             /* time to limit beyond this is never (inf) [s] */
#define GVS_TTL_QUANTUM_S 0.0078125             /* result: the first multiple of this at or after the crossing [s] */
#define GVS_MARCH_D_FRAC 0.29289321881345254    /* TR-BDF2, gamma = 2 - sqrt(2): d = MARCH_D_FRAC h = 1 - 1/sqrt(2) */
#define GVS_MARCH_A1 1.2071067811865475         /* BDF2 stage: 1 / (gamma (2 - gamma)) */
#define GVS_MARCH_A0 0.20710678118654763        /* BDF2 stage: (1 - gamma)^2 / (gamma (2 - gamma)) */
#define GVS_HERMITE_SAMPLES 16                  /* samples of the Hermite interpolant looking for a crossing */
#define GVS_HERMITE_BISECTIONS 40               /* then bisections */
#define GVS_TTL_RELINEARISE_STEPS 2             /* re-linearisations at the predicted sump */
#define GVS_TTL_RELINEARISE_TOL_K 0.5           /* ... until the sump moves less than this [K] */
#define GVS_COUPLING_MARGIN 1e-06               /* the coupled held system needs 1 - e^T K^-1 u above this */
#define GVS_TTL_BOUND_TOL_K 0.5                 /* bounded time to limit: a sump this close to its far value is settled [K] */
#define GVS_TTL_BOUND_GATE_S 60.0               /* a crossing within this: today's march too, the earlier [s] */
#define GVS_TTL_BOUND_RATIO 2.5                 /* ... its marches: each step this many times longer than the last */
#define GVS_TTL_FAR_ITERS 12                    /* ... its far sump: at most this many solves in the bracket */
#define GVS_TTL_FAR_TOL_K 0.05                  /* ... until the bracket is narrower than this [K] */
#define GVS_TTL_SEG_MAX 3                       /* ... the sump's path to its far value in at most this many parts */
#define GVS_TTL_SEG_SAMPLES 16                  /* ... sampled at this many sumps between */
#define GVS_TTL_SEG_GAP_W 200.0                 /* ... cut where its lines lie this far under the curves [W] */
#define GVS_TTL_SEG_TIE_W 1.0                   /* ... at the first sample within this of the best [W] */
#define GVS_TTL_FRESH_S 10.0                    /* an early warning judges a time to limit at most this old [s] */
#define GVS_RECOVER_MAX_S 600.0                 /* levels not available after an outage: at most this long [s] */
#define GVS_OIL_DRIFT_K_PER_S 0.05              /* oil off the last good one and its carry: step + this x age */
#define GVS_OIL_AGE_NONE_S 1000000000.0         /* the age of an oil reading never taken [s] */

/* input fields (records.INPUT_FIELDS order) */
enum { GVS_I_SPEED = 0, GVS_I_TORQUE = 1, GVS_I_GEAR = 2, GVS_I_OIL = 3, GVS_I_AMB = 4, GVS_I_COOL = 5, GVS_I_VKMH = 6,
       GVS_I_RET = 7 };
/* return codes of gvs_step */
enum { GVS_OK = 0, GVS_SKIPPED = 1, GVS_NEED_JUMP = 2, GVS_BAD_TABLES = -1 };
/* reject counters (records.REJECT_REASONS order) */
enum { GVS_RJ_SPEED_MISSING = 0, GVS_RJ_SPEED_CLAMPED = 1, GVS_RJ_TORQUE_MISSING = 2, GVS_RJ_TORQUE_CLAMPED = 3,
       GVS_RJ_GEAR_MISSING = 4, GVS_RJ_GEAR_UNKNOWN = 5, GVS_RJ_OIL_MISSING = 6, GVS_RJ_OIL_IMPLAUSIBLE = 7,
       GVS_RJ_OIL_FROZEN = 8, GVS_RJ_DRIVE_FROZEN = 9, GVS_RJ_AUX_MISSING = 10, GVS_RJ_TIME_JUMP = 11,
       GVS_RJ_TIME_BACKWARD = 12 };
/* warning levels (firmware_model.components) */
enum { GVS_LEVEL_NORMAL = 0, GVS_LEVEL_WARNING = 1, GVS_LEVEL_CRITICAL = 2, GVS_LEVEL_NA = 3 };
/* degraded modes (firmware_model.components) */
enum { GVS_MODE_NORMAL = 0, GVS_MODE_OIL_MODEL = 1, GVS_MODE_HOLDING = 2 };
/* the two copies of the network in the state (records) */
enum { GVS_MAIN = 0, GVS_TWIN = 1 };
/* columns of the oil property table (tables.prop) */
enum { GVS_P_LOG10_MU = 0, GVS_P_LN_NU_CST = 1, GVS_P_LN_MU = 2, GVS_P_LN_ROLL = 3, GVS_P_RHO = 4, GVS_P_CP = 5,
       GVS_P_K = 6, GVS_P_LN_PR = 7 };
/* the vehicle effect that scales a conductance law (pw_effect, ef_effect) */
enum { GVS_EFFECT_NONE = 0, GVS_EFFECT_TEETH_OIL_H = 1, GVS_EFFECT_PLANET_OIL_H = 2, GVS_EFFECT_HOUSING_AIR_H = 3 };
/* cooler kinds (tables.cooler_code; firmware_model.physics.cooler.COOLER_KINDS) */
enum { GVS_COOLER_NONE = 0, GVS_COOLER_LIQUID = 1, GVS_COOLER_AIR = 2 };
/* oil pump kinds (tables.pump_code; PUMP_KINDS) */
enum { GVS_PUMP_NONE = 0, GVS_PUMP_SHAFT = 1, GVS_PUMP_MOTOR = 2 };
/* the argument of gvs_sizeof */
enum { GVS_SIZEOF_TABLES = 0, GVS_SIZEOF_VEHICLE = 1, GVS_SIZEOF_STATE = 2, GVS_SIZEOF_INPUTS = 3,
       GVS_SIZEOF_OUTPUTS = 4, GVS_SIZEOF_TTL_POINT = 5, GVS_SIZEOF_REAL = 6 };

/* The generated tables of one gearbox variant and sensor configuration (read only;
 * firmware_model.onboard.kernel_tables). Table shapes in the comments; 2-D arrays are row-major; "gears" rows are
 * gear - gear_min. */
typedef struct {
    /* sizes: nodes, links, boundaries, sources, power laws, tables, cylinders, closed-form streams, radiation links,
     * streams, source non-zeros; then the tables' axes */
    int32_t n, nl, nb, ns, npw, n2, nc, ne, nrad, nst, nsrc_nz, nT, ncol, n_u, nT2, n_u_churn, nx, n_mesh, n_bear;
    int32_t n_needle, n_speed, n_gears, n_pub;
    int32_t i_oil;                      /* the sump node */
    int32_t i_ambient;                  /* the ambient boundary */
    int32_t i_coolant;                  /* the coolant boundary */
    int32_t cooler_code;                /* GVS_COOLER_* */
    /* GVS_PUMP_*: the oil flow follows pump_speed_col (shaft) or is pump_flow_m3_s (motor) */
    int32_t pump_code;
    /* 1: a forced oil system, the step outputs its oil inlet (sump - inlet drop); 0: NaN */
    int32_t oil_inlet;
    int32_t gear_min;                   /* gear of row 0 */
    /* bit r: the description has gear gear_min + r (another gear input is unknown) */
    int32_t gear_defined;
    /* bit i: the drive has auxiliary input I_AMB + i (another one is not counted) */
    int32_t aux_expected;
    int32_t oil_mode_measured;          /* 1: a measured sump is used */
    int32_t ttl_every;                  /* steps between time-to-limit refreshes */
    /* network */
    const gvs_real *dt_over_C;          /* (n) [s K/J] dt / C */
    const gvs_idx *link_a;              /* (nl) */
    const gvs_idx *link_b;              /* (nl) link_b >= n: boundary link_b - n */
    const gvs_real *G_const;            /* (nl) [W/K] */
    const gvs_idx *published_index;     /* (n_pub) node of each published component */
    /* power laws: G = coef[row, t] w^exp[t] (phi(T)[col[t]] or 1) x effect */
    const gvs_idx *pw_link, *pw_col, *pw_effect; /* (npw) */
    const gvs_real *pw_exp;             /* (npw) */
    const gvs_real *pw_gear_coef;       /* (gears x npw) */
    const gvs_real *pw_phi;             /* (nT x ncol) */
    /* bilinear tables over (sqrt(w_t / w_max), T) */
    const gvs_idx *t2_link;             /* (n2) */
    const gvs_real *t2_speed_coef;      /* (gears x n2) */
    const gvs_real *t2_omega_max_rad_s; /* (n2) [rad/s] */
    const gvs_t2 *t2_table;             /* (n2 x n_u x nT2) [W/K] times t2_scale */
    const gvs_real *t2_scale;           /* (n2) per table: 1, or the step of an export's int16 table (GVS_T2_Q16) */
    int32_t t2_stride;                  /* the tables use every t2_stride-th temperature of the grid */
    /* immersed wheels, Nusselt in closed form */
    const gvs_idx *cyl_link;            /* (nc) */
    const gvs_real *cyl_speed_coef;     /* (gears x nc) */
    const gvs_real *cyl_c;              /* (nc) [m] */
    const gvs_real *cyl_ln_rp2;         /* (nc) ln(R_p^2 [m2]) */
    /* oil-system streams in closed form */
    const gvs_idx *ef_link, *ef_effect; /* (ne) */
    const gvs_real *ef_mcp, *ef_alpha, *ef_beta; /* (ne) */
    /* radiation */
    const gvs_idx *rad_link, *rad_node, *rad_bc; /* (nrad) */
    const gvs_real *rad_area_eps;       /* (nrad) [m2] */
    /* streams: G_streams = [G2[t2_stream_term], Ge]; stream s moves G dT_in from stream_node[s] to the sump */
    const gvs_idx *t2_stream_term;      /* (nst - ne) */
    const gvs_idx *stream_node;         /* (nst) */
    /* oil properties on the temperature grid */
    const gvs_real *prop;               /* (nT x N_PROP) columns GVS_P_* */
    gvs_real T_grid0_c;                 /* [degC] */
    gvs_real T_grid_step_k;             /* [K] */
    /* losses */
    const gvs_real *speed_coef;         /* (gears x n_speed) every speed per unit input speed */
    /* speed_coef column of the shaft that drives the oil pump (flow, cooler); -1 none */
    int32_t pump_speed_col;
    int32_t churn_speed_col;            /* ... of the shaft whose dipping wheels churn (the churning table); -1 none */
    int32_t output_speed_col;           /* ... of the output shaft (retarder); -1 none */
    const gvs_real *mesh_torque, *mesh_omega2; /* (gears x n_mesh) */
    const gvs_real *mesh_x0;            /* (n_mesh) */
    const gvs_real *mesh_phi;           /* (n_mesh x nx) */
    const gvs_real *mesh_roll_k, *mesh_heat_sf; /* (n_mesh) */
    const gvs_real *mesh_roll_lt_min;   /* (n_mesh) log10 T1 below which the rolling loss ramps to 0 */
    const gvs_real *bear_speed, *bear_c, *bear_load; /* (gears x n_bear) */
    const gvs_real *bear_rr;            /* (gears x n_bear) SKF rolling moment per |T|^0.31 (nu n)^0.6; all 0: none */
    const gvs_real *bear_ish;           /* (n_bear) ... over 1 + bear_ish (n^2 nu)^0.64 (SKF's inlet shear) */
    const gvs_real *needle_rel;         /* (gears x n_needle) needle bearings' relative speed per unit input speed */
    const gvs_real *needle_c;           /* (n_needle) */
    const gvs_real *sync_coef, *pump_coef; /* (gears) */
    const gvs_real *churn_table;        /* (n_u_churn x nT) [W] */
    gvs_real churn_omega_max_rad_s;     /* [rad/s] */
    gvs_real churn_heat_sf, x_step, ln10;
    /* source -> node heat, sparse: node heat[src_nz_node[k]] += delivered[src_nz_src[k]] * src_nz_w[k] */
    const gvs_idx *src_nz_src, *src_nz_node; /* (nsrc_nz) */
    const gvs_real *src_nz_w;           /* (nsrc_nz) */
    gvs_real lag_gain, lag_tau_over_dt;
    /* cooler (seed 3.4, Eq 82-83) */
    gvs_real flow_m3_per_rad;           /* [m3/rad] */
    gvs_real pump_flow_m3_s;            /* [m3/s] a motor-driven pump's fixed flow */
    gvs_real pump_stop_rad_s;           /* [rad/s] ... none while the input shaft turns at or below it (0: always) */
    gvs_real liquid_hA_ref;             /* [W/K] */
    gvs_real liquid_Qmax_cool, liquid_Qmax_heat; /* [W] */
    gvs_real air_hA_ref;                /* [W/K] */
    gvs_real air_Qmax_cool;             /* [W] */
    gvs_real thermostat_open_c, thermostat_full_c; /* [degC] */
    gvs_real thermostat_sump;           /* 1: the thermostat reads the sump (before the cooler); 0: the return, Eq 82 */
    gvs_real heater_w;                  /* [W] the sump heater's power (0: none) */
    gvs_real heater_set_c;              /* [degC] the heater is off above this sump temperature ... */
    gvs_real heater_band_k;             /* [K] ... and at full power below heater_set_c - heater_band_k */
    gvs_real measured_balance;          /* 1: a measured sump's cooler takes what the sump's balance leaves */
    gvs_real balance_keep_min;          /* ... dividing by at least this share kept (BALANCE_KEEP_MIN) */
    gvs_real ref_ls_speed, ref_engine_speed; /* [rad/s] */
    gvs_real exp_inner, exp_outer, air_flow_min_frac;
    gvs_real air_ref_speed_kmh;         /* [km/h] */
    gvs_real air_flow_max_rel;
    gvs_real inlet_drop_max_k;          /* [K] */
    gvs_real default_vkmh;              /* [km/h] */
    const gvs_real *recirc_v_kmh;       /* (n_recirc) [km/h] */
    const gvs_real *recirc_dT_k;        /* (n_recirc) [K] */
    int32_t n_recirc;
    /* constants of the laws */
    gvs_real sigma;                     /* [W/m2K4] */
    gvs_real kelvin;                    /* [K] */
    gvs_real rpm_per_rad_s, rad_s_per_rpm, palmgren_min;
    gvs_real min_speed;                 /* [rad/s] */
    gvs_real ln_04, ln_0238, ln_re_lam, ln_re_bridge, ln_1e6;
    gvs_real rad_T_lo_c, rad_T_hi_c;    /* [degC] */
    gvs_real speed_bin_min;             /* [rad/s] */
    gvs_real ln_speed_bin;
    gvs_real oil_bin_c;                 /* [degC] */
    /* sensor: inputs, options, limits */
    gvs_real dt_s;                      /* [s] */
    const gvs_real *input_lo, *input_hi, *clamp_lo, *clamp_hi; /* (N_INPUTS) */
    const gvs_real *aux_default;        /* (N_INPUTS - I_AMB) ambient, coolant, vehicle speed, retarder */
    gvs_real hold_s, drive_frozen_s, oil_frozen_s, oil_period_s; /* [s] */
    gvs_real oil_frozen_drift_c, oil_step_c; /* [K] */
    gvs_real clock_reset_s;             /* [s] t_s back by more than this: a reset clock (stepped, counted) */
    const gvs_real *warning_c, *critical_c; /* (n_pub) [degC] */
    const gvs_real *hysteresis_k;       /* (n_pub) [K] */
    const gvs_real *warning_rest_c;     /* (n_pub) [degC] */
    gvs_real debounce_s, lead_s;        /* [s] */
    /* time to limit (gvs_ttl_refresh; firmware_model.onboard.held_march, time_to_limit): heat capacities, the sparse
     * LDL^T pattern of C/h + K (firmware_model.onboard.sparse_ldl), the components whose crossing re-linearises, and
     * the options: the sump heats with the held load (else a measured sump is held), and re-linearise at the
     * predicted sump (every effect one value for all vehicles); ttl_bound: the bounded method (ttl_bound,
     * gvs_kernel.c ttl_refresh_bound; 0: today's march, ttl_method 'march') */
    const gvs_real *C_j_per_k;          /* (n) [J/K] */
    const gvs_idx *ldl_perm, *ldl_pos;  /* (n) */
    const gvs_idx *ldl_col_ptr;         /* (n + 1) */
    const gvs_idx *ldl_row;             /* (ldl_nnz) */
    const gvs_idx *ldl_link_slot;       /* (nl) */
    const gvs_idx *ldl_upd_ptr;         /* (n + 1) */
    const gvs_idx *ldl_upd_target, *ldl_upd_a, *ldl_upd_b; /* (ldl_nupd) */
    const gvs_idx *ttl_relin;           /* (n_pub) */
    int32_t ldl_nnz, ldl_nupd, ttl_sump_model, ttl_relinearise, ttl_bound;
} gvs_tables;

/* Effect values and boundary defaults of one vehicle (firmware_model.effects; neutral = 1 / 0). */
typedef struct {
    gvs_real src_scale[GVS_MAX_SRC];    /* loss scale of each heat source */
    gvs_real teeth_oil_h, planet_oil_h, housing_air_h, cooler_scale; /* conductance and cooler scales */
    gvs_real thermostat_offset_c;       /* [K] */
    gvs_real retarder_frac;             /* share of the retarder's power that heats the oil */
    gvs_real churn_scale, needle_scale;
    gvs_real T_bc_default_c[GVS_MAX_BC]; /* [degC] hot-surroundings offset applied */
} gvs_vehicle;

/* Everything the sensor remembers (SensorState of the numpy reference). */
typedef struct {
    gvs_real T_c[2][GVS_MAX_NODES];     /* [degC] main copy, open-loop twin */
    gvs_real lag_w[GVS_MAX_SRC];        /* [W] */
    gvs_real hold[GVS_N_INPUTS];        /* held inputs */
    gvs_real age_s[GVS_N_INPUTS], same_s[GVS_N_INPUTS]; /* [s] */
    gvs_real raw_prev[GVS_N_INPUTS];
    gvs_real oil_ref_c;                 /* [degC] */
    gvs_real pending_s[GVS_MAX_PUB], ttl_s[GVS_MAX_PUB]; /* [s] */
    double t_last_s;                    /* [s] frame time of the last step (NaN unknown) */
    int64_t k;                          /* steps done */
    int64_t rejects[GVS_N_REJECT];
    gvs_real recover_s;                 /* [s] the drive inputs' outage past the hold still to recover from */
    /* memo of the last conductance bin (a pure function of its key: the outputs never depend on it; a state packed
     * from elsewhere starts with memo_valid = 0) */
    gvs_real memo_G[GVS_MAX_LINKS];     /* [W/K] */
    gvs_real memo_Gs[GVS_MAX_STREAMS];  /* [W/K] */
    gvs_real memo_omega_q;              /* [rad/s] */
    gvs_real memo_T_q;                  /* [degC] */
    int32_t memo_row, memo_valid;
    /* memo of the last heat sources, in a build with GVS_STEP_MEMO only (the host's: a held replay steps the same
     * inputs tens of times a row; an ECU's inputs change every frame, so its build leaves the code out): the sources
     * at (gear row, speed, torque, sump, retarder); a state packed from elsewhere starts with memo_heat_valid = 0 */
    gvs_real memo_src[GVS_MAX_SRC];     /* [W] */
    gvs_real memo_heat_key[4];          /* speed [rad/s], |torque| [N m], sump [degC], retarder heat [W] */
    int32_t memo_heat_row, memo_heat_valid;
    int8_t level[GVS_MAX_PUB];          /* GVS_LEVEL_* */
} gvs_state;

/* One step's inputs. */
typedef struct {
    double raw[GVS_N_INPUTS];           /* GVS_I_* order (NaN: not available) */
    double t_s;                         /* [s] frame time (NaN: the caller keeps the grid) */
} gvs_inputs;

/* One step's outputs (SensorOutputs and SensorStatus of the numpy reference). */
typedef struct {
    gvs_real T_c[GVS_MAX_PUB];          /* [degC] */
    gvs_real ttl_s[GVS_MAX_PUB];        /* [s] */
    gvs_real model_oil_temp_c;          /* [degC] */
    gvs_real oil_innovation_c;          /* [K] */
    /* [degC] a forced oil system's inlet: the sump the step took - the inlet drop */
    gvs_real oil_inlet_temp_c;
    int64_t rejects[GVS_N_REJECT];      /* the cumulative reject counters after this step */
    int32_t valid_flags, frozen_flags;  /* bit GVS_I_* per input */
    int8_t level[GVS_MAX_PUB];          /* GVS_LEVEL_* */
    int8_t degraded_mode;               /* GVS_MODE_* */
    int8_t speed_valid, torque_valid, gear_valid, oil_valid, oil_source;
} gvs_outputs;

/* The operating point of a due time-to-limit refresh (TtlPoint of the numpy reference). */
typedef struct {
    gvs_real T_main_c[GVS_MAX_NODES];   /* [degC] */
    gvs_real src_w[GVS_MAX_SRC];        /* [W] */
    gvs_real G_w_per_k[GVS_MAX_LINKS];  /* [W/K] */
    gvs_real G_streams_w_per_k[GVS_MAX_STREAMS]; /* [W/K] */
    gvs_real T_bc_c[GVS_MAX_BC];        /* [degC] */
    gvs_real used[GVS_N_INPUTS];        /* inputs used */
    gvs_real dT_in_k;                   /* [K] */
    gvs_real Q_cool_w;                  /* [W] */
    gvs_real omega_in_rad_s;            /* [rad/s] */
    gvs_real T_oil_c;                   /* [degC] */
    gvs_real rho_cp_j_per_m3k;          /* [J/m3K] */
    int32_t due, measured, row;
} gvs_ttl_point;

/* 0 when the tables fit the structs, else GVS_BAD_TABLES. */
int gvs_check_tables(const gvs_tables *tb);     /* also GVS_BAD_TABLES when a build's NaN checks do not work */

/* One 0.1 s step of one vehicle, in place. jump_done: the host has propagated the state over the forward time
 * jump this step's t_s shows (count it and step); 0: return GVS_NEED_JUMP first. ttl: filled when a refresh of the
 * time to limit is due after this step (may be NULL). Returns GVS_OK, GVS_SKIPPED (time went backwards: nothing
 * integrated, outputs repeat the state), GVS_NEED_JUMP or GVS_BAD_TABLES. */
int gvs_step(const gvs_tables *tb, const gvs_vehicle *veh, gvs_state *st, const gvs_inputs *in, int jump_done,
             gvs_outputs *out, gvs_ttl_point *ttl);

/* The time to limit [s] of every published component (0: at or above its warning limit now; +inf: not within
 * GVS_TTL_HORIZON_S; NaN: the held system has no finite steady state, or tables without the time to limit's,
 * ldl_nnz 0) from a due refresh's operating point p, into ttl_s[tb->n_pub].
 * Returns GVS_OK, or GVS_BAD_TABLES. Cost: one sparse factorisation and solve, then march steps (from
 * GVS_MARCH_H0_S, each GVS_MARCH_RATIO times longer, to the horizon) of one factorisation and three solves each
 * until every component has crossed or provably cannot. */
int gvs_ttl_refresh(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real *ttl_s);

/* Steps over a table of inputs (n_steps rows) for one vehicle, writing one gvs_outputs per step, or with keep
 * (n_steps flags; NULL: every step) only for the steps whose flag is set, one after the other (a held replay keeps
 * one step a row: the others' outputs are never written). A step that leaves a due time-to-limit refresh: with
 * stop_on_ttl the run stops after it (the caller refreshes), else the refresh runs in place (gvs_ttl_refresh into
 * st->ttl_s) when ttl is given. Stops before a step that needs a jump propagated; returns the number of steps done
 * (the caller resumes from there). *status: the last gvs_step return code. */
int64_t gvs_run(const gvs_tables *tb, const gvs_vehicle *veh, gvs_state *st, const gvs_inputs *in, int64_t n_steps,
                int stop_on_ttl, const int8_t *keep, gvs_outputs *out, gvs_ttl_point *ttl, int *status);

/* One step of n_vehicles vehicles (arrays of states, inputs, outputs, time-to-limit points; jump_done and ttl may
 * be NULL), vehicle parameters veh[v * veh_stride] (stride 0: one set for all). codes[v]: each vehicle's return
 * code (may be NULL). Returns GVS_OK when every vehicle stepped, else the first other code (errors first). */
int gvs_step_batch(const gvs_tables *tb, const gvs_vehicle *veh, int64_t veh_stride, int64_t n_vehicles,
                   gvs_state *st, const gvs_inputs *in, const int8_t *jump_done, gvs_outputs *out,
                   gvs_ttl_point *ttl, int32_t *codes);

/* sizeof of the structs, which = GVS_SIZEOF_* (the binding checks its layouts against them) */
int64_t gvs_sizeof(int which);

#endif
