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

/* capacities of the plain structs (the tables give the actual sizes; gvs_check_tables() refuses larger ones);
 * an ECU build sets them to the exported variant's sizes (-DGVS_MAX_NODES=61 ...) to save RAM */
#ifndef GVS_MAX_NODES
#define GVS_MAX_NODES 96
#endif
#ifndef GVS_MAX_LINKS
#define GVS_MAX_LINKS 192
#endif
#ifndef GVS_MAX_SRC
#define GVS_MAX_SRC 32
#endif
#ifndef GVS_MAX_BC
#define GVS_MAX_BC 8
#endif
#ifndef GVS_MAX_STREAMS
#define GVS_MAX_STREAMS 32
#endif
/* entries of L below the diagonal in the time to limit's sparse LDL^T (GRS905: 178) */
#ifndef GVS_MAX_LNZ
#define GVS_MAX_LNZ 512
#endif
/* the most terms of one kind of conductance law (tables, closed-form streams) and oil-factor columns */
#ifndef GVS_MAX_TERMS
#define GVS_MAX_TERMS 64
#endif
#define GVS_N_PUB 28
#define GVS_N_INPUTS 8
#define GVS_N_REJECT 13
#define GVS_N_GEARS 17

/* input fields (INPUT_FIELDS order) */
enum { GVS_I_SPEED, GVS_I_TORQUE, GVS_I_GEAR, GVS_I_OIL, GVS_I_AMB, GVS_I_COOL, GVS_I_VKMH, GVS_I_RET };
/* return codes of gvs_step */
enum { GVS_OK = 0, GVS_SKIPPED = 1, GVS_NEED_JUMP = 2, GVS_BAD_TABLES = -1 };

/* The generated tables of one gearbox variant and sensor configuration (read only). Shapes in comments; 2-D
 * arrays are row-major. "gear row" = gear - gear_min. */
typedef struct {
    int32_t n, nl, nb, ns, npw, n2, nc, ne, nrad, nst, nsrc_nz;
    int32_t nT, ncol, n_u, nT2, n_u_churn, nx, n_mesh, n_bear, n_speed, n_gears;
    int32_t i_oil, i_ambient, i_coolant, cooler_code, gear_min, oil_mode_measured, ttl_every;
    /* network */
    const gvs_real *dt_over_C;          /* (n) dt / C [K/J s... s K/J] */
    const gvs_idx *link_a, *link_b;     /* (nl) link_b >= n: boundary link_b - n */
    const gvs_real *G_const;            /* (nl) [W/K] */
    const gvs_idx *published_index;     /* (28) */
    /* power laws: G = coef[row, t] w^exp[t] (phi(T)[col[t]] or 1) x effect */
    const gvs_idx *pw_link, *pw_col, *pw_effect;      /* (npw) */
    const gvs_real *pw_exp, *pw_gear_coef, *pw_phi;   /* (npw), (gears, npw), (nT, ncol) */
    /* bilinear tables over (sqrt(w_t / w_max), T) */
    const gvs_idx *t2_link;             /* (n2) */
    const gvs_real *t2_speed_coef, *t2_w_max, *t2_table;  /* (gears, n2), (n2), (n2, n_u, nT2) */
    int32_t t2_stride;
    /* immersed wheels, Nusselt in closed form */
    const gvs_idx *cyl_link;
    const gvs_real *cyl_speed_coef, *cyl_c, *cyl_ln_rp2;  /* (gears, nc), (nc), (nc) */
    /* oil-system streams in closed form */
    const gvs_idx *ef_link, *ef_effect;
    const gvs_real *ef_mcp, *ef_alpha, *ef_beta;       /* (ne) */
    /* radiation */
    const gvs_idx *rad_link, *rad_node, *rad_bc;
    const gvs_real *rad_area_eps;
    /* streams: G_streams = [G2[t2_stream_term], Ge]; stream s moves G dT_in from stream_node[s] to the sump */
    const gvs_idx *t2_stream_term;      /* (nst - ne) */
    const gvs_idx *stream_node;         /* (nst) */
    /* oil properties on the temperature grid */
    const gvs_real *prop;               /* (nT, 8) */
    gvs_real T_grid0_c, T_grid_step_k;
    /* losses */
    const gvs_real *speed_coef;         /* (gears, n_speed) */
    const gvs_real *mesh_torque, *mesh_omega2;          /* (gears, n_mesh) */
    const gvs_real *mesh_x0, *mesh_phi, *mesh_roll_k, *mesh_heat_sf;  /* (n_mesh), (n_mesh, nx), ... */
    const gvs_real *mesh_roll_lt_min;   /* (n_mesh) log10 T1 below which the rolling loss ramps to 0 */
    const gvs_real *bear_speed, *bear_c, *bear_load, *needle_rel, *needle_c;  /* (gears, n_bear), (n_bear) */
    const gvs_real *sync_coef, *pump_coef;              /* (gears) */
    const gvs_real *churn_table;        /* (n_u_churn, nT) */
    gvs_real churn_w_max, churn_heat_sf, x_step, ln10;
    /* source -> node heat, sparse: node heat[src_nz_node[k]] += delivered[src_nz_src[k]] * src_nz_w[k] */
    const gvs_idx *src_nz_src, *src_nz_node;
    const gvs_real *src_nz_w;
    gvs_real lag_gain, lag_tau_over_dt;
    /* cooler (seed 3.4, Eq 82-83) */
    gvs_real flow_m3_per_rad, liquid_hA_ref, liquid_Qmax_cool, liquid_Qmax_heat, air_hA_ref, air_Qmax_cool;
    gvs_real thermostat_open_c, thermostat_full_c, ref_ls_speed, ref_engine_speed, exp_inner, exp_outer;
    gvs_real air_flow_min_frac, air_ref_speed_kmh, air_flow_max_rel, inlet_drop_max_k, default_vkmh;
    const gvs_real *recirc_v_kmh, *recirc_dT_k;        /* (n_recirc) */
    int32_t n_recirc;
    /* constants of the laws */
    gvs_real sigma, kelvin, rpm_per_rad_s, rad_s_per_rpm, palmgren_min, min_speed, ln_04, ln_0238, ln_re_lam, ln_re_bridge;
    gvs_real ln_1e6, rad_T_lo_c, rad_T_hi_c;
    gvs_real speed_bin_min, ln_speed_bin, oil_bin_c;
    /* sensor: inputs, options, limits */
    gvs_real dt_s;
    const gvs_real *input_lo, *input_hi, *clamp_lo, *clamp_hi, *aux_default;  /* (8), (8), (8), (8), (4) */
    gvs_real hold_s, drive_frozen_s, oil_frozen_s, oil_frozen_drift_c, oil_step_c;
    gvs_real clock_reset_s;             /* t_s back by more than this: a reset clock (stepped, counted) */
    const gvs_real *warning_c, *critical_c, *hysteresis_k, *warning_rest_c;   /* (28) */
    gvs_real debounce_s, lead_s;
    /* time to limit (gvs_ttl_refresh; firmware_model.onboard.held_march, time_to_limit): heat capacities, the
     * sparse LDL^T pattern of C/h + K (firmware_model.onboard.sparse_ldl), the components whose crossing
     * re-linearises, and the options: the sump heats with the held load (else a measured sump is held), and
     * re-linearise at the predicted sump (every effect one value for all vehicles) */
    const gvs_real *C_j_per_k;          /* (n) [J/K] */
    const gvs_idx *ldl_perm, *ldl_pos, *ldl_col_ptr, *ldl_row, *ldl_link_slot;   /* (n), (n), (n+1), (nnz), (nl) */
    const gvs_idx *ldl_upd_ptr, *ldl_upd_target, *ldl_upd_a, *ldl_upd_b;        /* (n+1), (nupd) x 3 */
    const gvs_idx *ttl_relin;           /* (28) */
    int32_t ldl_nnz, ldl_nupd, ttl_sump_model, ttl_relinearise;
} gvs_tables;

/* Effect values and boundary defaults of one vehicle (firmware_model.effects; neutral = 1 / 0). */
typedef struct {
    gvs_real src_scale[GVS_MAX_SRC];
    gvs_real teeth_oil_h, planet_oil_h, housing_air_h, cooler_scale, thermostat_offset_c;
    gvs_real retarder_frac, churn_scale, needle_scale;
    gvs_real T_bc_default_c[GVS_MAX_BC];   /* hot-surroundings offset applied */
} gvs_vehicle;

/* Everything the sensor remembers (SensorState of the numpy reference). */
typedef struct {
    gvs_real T_c[2][GVS_MAX_NODES];   /* main copy, open-loop twin [degC] */
    gvs_real lag_w[GVS_MAX_SRC];
    gvs_real hold[GVS_N_INPUTS], age_s[GVS_N_INPUTS], same_s[GVS_N_INPUTS], raw_prev[GVS_N_INPUTS];
    gvs_real oil_ref_c;
    gvs_real pending_s[GVS_N_PUB], ttl_s[GVS_N_PUB];
    double t_last_s;                  /* frame time of the last step (NaN unknown) */
    int64_t k;                        /* steps done */
    int64_t rejects[GVS_N_REJECT];
    /* memo of the last conductance bin (a pure function of its key: the outputs never depend on it; a state
     * packed from elsewhere starts with memo_valid = 0) */
    gvs_real memo_G[GVS_MAX_LINKS], memo_Gs[GVS_MAX_STREAMS], memo_omega_q, memo_T_q;
    int32_t memo_row, memo_valid;
    int8_t level[GVS_N_PUB];
} gvs_state;

/* One step's inputs (NaN = not available); t_s the frame time (NaN: the caller keeps the grid). */
typedef struct {
    double raw[GVS_N_INPUTS];
    double t_s;
} gvs_inputs;

typedef struct {
    gvs_real T_c[GVS_N_PUB];
    gvs_real ttl_s[GVS_N_PUB];
    gvs_real model_oil_temp_c, oil_innovation_c;
    int64_t rejects[GVS_N_REJECT];    /* the cumulative reject counters after this step */
    int32_t valid_flags, frozen_flags;
    int8_t level[GVS_N_PUB];
    int8_t degraded_mode, speed_valid, torque_valid, gear_valid, oil_valid, oil_source;
} gvs_outputs;

/* The operating point of a due time-to-limit refresh (TtlPoint of the numpy reference). */
typedef struct {
    gvs_real T_main_c[GVS_MAX_NODES];
    gvs_real src_w[GVS_MAX_SRC];
    gvs_real G_w_per_k[GVS_MAX_LINKS];
    gvs_real G_streams_w_per_k[GVS_MAX_STREAMS];
    gvs_real T_bc_c[GVS_MAX_BC];
    gvs_real used[GVS_N_INPUTS];
    gvs_real dT_in_k, Q_cool_w, omega_in_rad_s, T_oil_c, rho_cp_j_per_m3k;
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
 * 2e6 s; NaN: the held system has no finite steady state, or tables without the time to limit's, ldl_nnz 0)
 * from a due refresh's operating point p, into ttl_s[28].
 * Returns GVS_OK, or GVS_BAD_TABLES. Cost: one sparse factorisation and solve, then up to 41 march steps of one
 * factorisation and three solves each until every component has crossed or provably cannot. */
int gvs_ttl_refresh(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real *ttl_s);

/* Steps over a table of inputs (n_steps rows) for one vehicle, writing one gvs_outputs per step. A step that
 * leaves a due time-to-limit refresh: with stop_on_ttl the run stops after it (the caller refreshes), else the
 * refresh runs in place (gvs_ttl_refresh into st->ttl_s) when ttl is given. Stops before a step that needs a jump
 * propagated; returns the number of steps done (the caller resumes from there). *status: the last gvs_step
 * return code. */
int64_t gvs_run(const gvs_tables *tb, const gvs_vehicle *veh, gvs_state *st, const gvs_inputs *in, int64_t n_steps,
                int stop_on_ttl, gvs_outputs *out, gvs_ttl_point *ttl, int *status);

/* One step of n_vehicles vehicles (arrays of states, inputs, outputs, time-to-limit points; jump_done and ttl may
 * be NULL), vehicle parameters veh[v * veh_stride] (stride 0: one set for all). codes[v]: each vehicle's return
 * code (may be NULL). Returns GVS_OK when every vehicle stepped, else the first other code (errors first). */
int gvs_step_batch(const gvs_tables *tb, const gvs_vehicle *veh, int64_t veh_stride, int64_t n_vehicles,
                   gvs_state *st, const gvs_inputs *in, const int8_t *jump_done, gvs_outputs *out,
                   gvs_ttl_point *ttl, int32_t *codes);

/* sizeof of the structs (the binding checks its layouts against them) */
int64_t gvs_sizeof(int which);

#endif
