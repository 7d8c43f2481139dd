/* gearbox-vsensor onboard step: the generic C99 kernel (see gvs_kernel.h). Each block names the function of the
 * numpy reference it mirrors (firmware_model/onboard/...) and the seed's equations. */
#include <math.h>
#include <string.h>
#include <stdint.h>

#include "gvs_kernel.h"


#ifndef GVS_SOURCE_ID
#define GVS_SOURCE_ID "unknown"
#endif
/* the SHA-256 prefix of the sources this build was made from (the Python loader refuses a stale build) */
const char *const gvs_source_id_str = GVS_SOURCE_ID;

#ifdef GVS_REAL_FLOAT
#define R_(x) ((float)(x))
#define EXP expf
#define EXPM1 expm1_f
#define LOG logf
#define LOG10 log10_f
#define POW pow_f
#define SQRT sqrtf
#define FABS fabsf
#define RINT rint_f
#define CEIL ceil_f
/* the time-to-limit march's clock: single precision in the float build (no soft double on an FPU without one;
 * a crossing moves by far less than the float build's tolerance), double otherwise (bit-identical to numpy) */
typedef float march_t;
#else
#define R_(x) ((double)(x))
#define EXP exp
#define EXPM1 expm1
#define LOG log
#define LOG10 log10
#define POW pow
#define SQRT sqrt
#define FABS fabs
#define RINT rint
#define CEIL ceil
typedef double march_t;
#endif
#define M_(x) ((march_t)(x))
#if defined(GVS_REAL_FLOAT) && defined(__GNUC__)
/* small helpers kept out of line in the float build, the ECU's, where flash comes before speed: -flto would copy
 * each into its callers (measured on the Cortex-M4F footprint: ~0.5 KB together) */
#define GVS_OUTLINE __attribute__((noinline))
/* ... and its copy loops stay loops, not calls of the C library's memcpy (~300 B of flash, fast on long blocks the
 * sensor never copies) */
#ifndef __clang__
#pragma GCC optimize("no-tree-loop-distribute-patterns")
#endif
#else
#define GVS_OUTLINE
#endif
/* the constants shared with the numpy reference (march, effect codes, speed columns, ...) are the generated
 * header's GVS_* (firmware_model/onboard/kernel_interface.py) */

#ifdef GVS_REAL_FLOAT
/* a^b for the float build as expf(b logf(a)): libm's powf alone is ~1.9 KB of an ECU's flash (expf and logf are
 * linked anyway); relative error ~|b ln a| x 2^-24, far inside the float build's tolerance; powf's special cases */
static float pow_f(float a, float b)
{
    if (b == 0.0f) return 1.0f;
    if (!(a > 0.0f)) return a == 0.0f ? (b > 0.0f ? 0.0f : (float)INFINITY) : (float)NAN;
    return expf(b * logf(a));
}

/* rintf and ceilf for the float build, exactly (the default rounding mode: to nearest, ties to even), without
 * libm's (~320 B of an ECU's flash): from 2^23 on every float is an integer (and NaN, inf pass through); below it
 * adding and taking away 2^23 rounds to an integer, and the sign of a zero result is the argument's */
/* expm1f and log10f from expf and logf (linked anyway) instead of libm's own (~920 B): e^x - 1 by Kahan's
 * (u - 1) x / ln u, u = e^x (the rounding of u cancels: a few ulp where e^x - 1 alone loses every digit),
 * log10 as ln / ln 10 (1-2 ulp); far inside the float build's tolerance */
static float expm1_f(float x)
{
    float u = expf(x), um1 = u - 1.0f;
    if (um1 == 0.0f) return x;                                  /* |x| below an ulp of 1 */
    if (um1 == -1.0f || um1 == (float)INFINITY) return um1;     /* e^x underflows to 0 or overflows in float */
    return um1 * (x / logf(u));
}
static float log10_f(float x) { return logf(x) * 0.43429448190325182f; }

#define F_INT_FROM 8388608.0f
static float rint_f(float x)
{
    float a = fabsf(x);
    if (!(a < F_INT_FROM)) return x;
    return copysignf((float)(a + F_INT_FROM) - F_INT_FROM, x);
}
static float ceil_f(float x)
{
    float a;
    if (!(fabsf(x) < F_INT_FROM)) return x;
    a = (float)(int32_t)x;                 /* toward zero, then up when that was down */
    return copysignf(a < x ? a + 1.0f : a, x);
}
#endif

static gvs_real min_r(gvs_real a, gvs_real b) { return a < b ? a : b; }
GVS_OUTLINE static gvs_real max_r(gvs_real a, gvs_real b) { return a > b ? a : b; }
GVS_OUTLINE static gvs_real clip_r(gvs_real x, gvs_real lo, gvs_real hi) { return x < lo ? lo : (x > hi ? hi : x); }

/* |speed| of the shaft in speed_coef column col (tables.pump_speed_col, churn_speed_col, output_speed_col; -1: no
 * such shaft, 0) at this gear row (evaluate.shaft_speed_rad_s) */
static gvs_real shaft_speed(const gvs_tables *tb, int32_t row, int32_t col, gvs_real omega_in_rad_s)
{
    return col < 0 ? R_(0.0) : FABS(tb->speed_coef[row * tb->n_speed + col]) * omega_in_rad_s;
}
/* what the oil-system flow is proportional to (evaluate.pump_drive): a shaft pump's shaft speed [rad/s], a motor
 * pump's 1 (its flow is fixed) */
static gvs_real pump_drive(const gvs_tables *tb, int32_t row, gvs_real omega_in_rad_s)
{
    if (tb->pump_code == GVS_PUMP_MOTOR)  /* 0 while the machine stands (pump_stop_rad_s > 0), else 1 */
        return (tb->pump_stop_rad_s > R_(0.0) && !(FABS(omega_in_rad_s) > tb->pump_stop_rad_s)) ? R_(0.0) : R_(1.0);
    return shaft_speed(tb, row, tb->pump_speed_col, omega_in_rad_s);
}
/* the oil-system flow per unit of pump_drive (evaluate.flow_per_drive): m3/rad of a shaft pump, m3/s of a motor's */
static gvs_real flow_per_drive(const gvs_tables *tb)
{
    return tb->pump_code == GVS_PUMP_MOTOR ? tb->pump_flow_m3_s : tb->flow_m3_per_rad;
}
/* dst = src: n reals; the rejection counters */
static void copy_r(gvs_real *dst, const gvs_real *src, int32_t n)
{
    int32_t i;
    for (i = 0; i < n; ++i) dst[i] = src[i];
}
static void copy_rejects(int64_t *dst, const int64_t *src)
{
    int i;
    for (i = 0; i < GVS_N_REJECT; ++i) dst[i] = src[i];
}

/* a finite real (in the build's own precision: a float's check is no soft double on an M4F) */
GVS_OUTLINE static int finite_g(gvs_real x) { return x == x && x - x == R_(0.0); }
/* the raw inputs and the frame times are doubles: they are judged by their bits, exactly as a double comparison
 * judges them, so that a float build links no soft double comparison (d_key orders as the value, -0 as +0; NaN
 * and the infinities are caught by finite_d before any comparison that would order them) */
GVS_OUTLINE static int finite_d(double x)
{
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    return ((u >> 52) & 0x7FFu) != 0x7FFu;
}
GVS_OUTLINE static int64_t d_key(double x)
{
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    return (u >> 63) ? -(int64_t)(u & 0x7FFFFFFFFFFFFFFFu) : (int64_t)u;
}

/* k mod m for a step count k >= 0 and m >= 1 without a 64-bit division (none in an FPU-only ECU's hardware: the
 * C library's would cost flash): 32-bit while k fits (13.6 years of 10 Hz steps), else binary long division */
GVS_OUTLINE static int64_t steps_mod(int64_t k, int32_t m)
{
    uint64_t u = (uint64_t)k, r = 0;
    int b;
    if (u <= 0xFFFFFFFFu) return (int64_t)((uint32_t)u % (uint32_t)m);
    for (b = 63; b >= 0; --b) {
        r = (r << 1) | ((u >> b) & 1u);
        if (r >= (uint64_t)m) r -= (uint64_t)m;
    }
    return (int64_t)r;
}

/* ---- oil properties at a temperature (evaluate.oil_row) ------------------------------------------------- */
typedef struct {
    gvs_real x;                 /* fractional index on the temperature grid */
    gvs_real prop[GVS_N_PROP];
} oil_row_t;

static void oil_row(const gvs_tables *tb, gvs_real T_c, oil_row_t *o, gvs_real *phi)
{
    gvs_real T_hi = tb->T_grid0_c + tb->T_grid_step_k * (gvs_real)(tb->nT - 1);
    gvs_real x = (clip_r(T_c, tb->T_grid0_c, T_hi) - tb->T_grid0_c) / tb->T_grid_step_k;
    int32_t i, j;
    gvs_real f;
    if (x != x) x = R_(0.0);        /* a NaN temperature (a corrupt state) must not become an index */
    i = (int32_t)x;
    if (i > tb->nT - 2) i = tb->nT - 2;
    f = x - (gvs_real)i;
    o->x = x;
    for (j = 0; j < GVS_N_PROP; ++j)
        o->prop[j] = tb->prop[i * GVS_N_PROP + j] * (R_(1.0) - f) + tb->prop[(i + 1) * GVS_N_PROP + j] * f;
    if (phi)
        for (j = 0; j < tb->ncol; ++j)
            phi[j] = tb->pw_phi[i * tb->ncol + j] * (R_(1.0) - f) + tb->pw_phi[(i + 1) * tb->ncol + j] * f;
}

/* ---- Nusselt of a rotating cylinder, Eq 46/47 with the bridge (evaluate.cyl_nusselt) ---------------------- */
static gvs_real cyl_nusselt(const gvs_tables *tb, gvs_real ln_re, gvs_real ln_pr)
{
    gvs_real ln46 = tb->ln_04 + R_(0.5) * ln_re + ln_pr / R_(3.0);
    gvs_real ln47 = tb->ln_0238 + R_(0.8) * ln_re + R_(0.6) * ln_pr;
    gvs_real s = clip_r((ln_re - tb->ln_re_lam) / tb->ln_re_bridge, R_(0.0), R_(1.0));
    return EXP(ln46 + s * (ln47 - ln46));
}

/* ---- the 2-D tables: cell and fraction on a speed axis u = sqrt(omega / omega_max) of n_u points
 * (evaluate.sqrt_speed_index), on a temperature grid of n points (evaluate.grid_index), and the one bilinear
 * interpolation from a cell's first corner tab[0], speed rows stride apart (evaluate.bilinear) ------------------ */
static int32_t sqrt_speed_index(gvs_real omega_rad_s, gvs_real omega_max_rad_s, int32_t n_u, gvs_real *fu)
{
    gvs_real uu = SQRT(min_r(omega_rad_s / omega_max_rad_s, R_(1.0))) * (gvs_real)(n_u - 1);
    int32_t iu = (int32_t)uu;
    if (iu > n_u - 2) iu = n_u - 2;
    *fu = uu - (gvs_real)iu;
    return iu;
}

static int32_t grid_index(gvs_real x, int32_t n, gvs_real *f)
{
    int32_t j = (int32_t)x;
    if (j > n - 2) j = n - 2;
    *f = x - (gvs_real)j;
    return j;
}

static gvs_real bilinear(const gvs_real *tab, int32_t stride, gvs_real fu, gvs_real fT)
{
    gvs_real lo = tab[0] * (R_(1.0) - fT) + tab[1] * fT;
    gvs_real hi = tab[stride] * (R_(1.0) - fT) + tab[stride + 1] * fT;
    return lo + (hi - lo) * fu;
}

/* bilinear() of a conductance table: its int16 steps in an export's float build (GVS_T2_Q16) */
#ifdef GVS_T2_Q16
static gvs_real bilinear_t2(const gvs_t2 *tab, int32_t stride, gvs_real fu, gvs_real fT)
{
    gvs_real lo = (gvs_real)tab[0] * (R_(1.0) - fT) + (gvs_real)tab[1] * fT;
    gvs_real hi = (gvs_real)tab[stride] * (R_(1.0) - fT) + (gvs_real)tab[stride + 1] * fT;
    return lo + (hi - lo) * fu;
}
#else
#define bilinear_t2 bilinear
#endif

/* ---- conductance of every link at a bin centre (conductance_bins.bin_conductances -> evaluate.conductances) -
 * G [W/K] of every link and of the oil-system streams at (gear row, speed omega_q, oil T_q): radiation (Eq 81)
 * with every node at T_q and the boundaries at their defaults. */
static void bin_conductances(const gvs_tables *tb, const gvs_vehicle *veh, int32_t gear_row, gvs_real omega_in_rad_s,
                             gvs_real T_q, gvs_real *G, gvs_real *G_streams)
{
    /* G2 zeroed: with no bilinear table and no stream (a splash-lubricated gearbox: n2 = nst = 0, one term) gcc
     * -O2 cannot see that the stream loop below never reads it and warns (-Werror in the export's Makefile) */
    gvs_real phi[GVS_MAX_TERMS], G2[GVS_MAX_TERMS] = {0}, Ge[GVS_MAX_TERMS];
    oil_row_t o;
    int32_t t;
    gvs_real omega_ls_rad_s, rho_cp_omega;
    oil_row(tb, T_q, &o, phi);
    copy_r(G, tb->G_const, tb->nl);
    for (t = 0; t < tb->npw; ++t) {                          /* power laws */
        gvs_real g = tb->pw_gear_coef[gear_row * tb->npw + t] * POW(omega_in_rad_s, tb->pw_exp[t]);
        if (tb->pw_col[t] >= 0) g *= phi[tb->pw_col[t]];
        if (tb->pw_effect[t] == GVS_EFFECT_TEETH_OIL_H) g *= veh->teeth_oil_h;
        else if (tb->pw_effect[t] == GVS_EFFECT_HOUSING_AIR_H) g *= veh->housing_air_h;
        G[tb->pw_link[t]] += g;
    }
    {                                                        /* bilinear tables */
        gvs_real fT, fu;
        int32_t jT = grid_index(o.x / (gvs_real)tb->t2_stride, tb->nT2, &fT), iu;
        for (t = 0; t < tb->n2; ++t) {
            gvs_real omega_t_rad_s = tb->t2_speed_coef[gear_row * tb->n2 + t] * omega_in_rad_s;
            iu = sqrt_speed_index(omega_t_rad_s, tb->t2_omega_max_rad_s[t], tb->n_u, &fu);
            G2[t] = bilinear_t2(tb->t2_table + ((int64_t)t * tb->n_u + iu) * tb->nT2 + jT, tb->nT2, fu, fT)
                * tb->t2_scale[t];
            G[tb->t2_link[t]] += G2[t];
        }
    }
    /* closed-form streams, NTU (Eq 69-80) */
    omega_ls_rad_s = pump_drive(tb, gear_row, omega_in_rad_s);
    rho_cp_omega = o.prop[GVS_P_RHO] * o.prop[GVS_P_CP] * omega_ls_rad_s;
    for (t = 0; t < tb->ne; ++t) {
        gvs_real mcp = tb->ef_mcp[t] * rho_cp_omega;
        gvs_real beta = tb->ef_beta[t] * (tb->ef_effect[t] == GVS_EFFECT_PLANET_OIL_H ? veh->planet_oil_h : R_(1.0));
        gvs_real hA = tb->ef_alpha[t] * o.prop[GVS_P_K] + beta;
        Ge[t] = mcp > R_(0.0) ? -mcp * EXPM1(-hA / mcp) : R_(0.0);
        G[tb->ef_link[t]] += Ge[t];
    }
    for (t = 0; t < tb->nc; ++t) {                           /* immersed wheels (Eq 46-48) */
        gvs_real omega_c_rad_s = max_r(tb->cyl_speed_coef[gear_row * tb->nc + t] * omega_in_rad_s, tb->min_speed);
        gvs_real ln_re = tb->cyl_ln_rp2[t] + LOG(omega_c_rad_s) - (o.prop[GVS_P_LN_NU_CST] + tb->ln_1e6);
        G[tb->cyl_link[t]] += tb->cyl_c[t] * o.prop[GVS_P_K] * cyl_nusselt(tb, ln_re, o.prop[GVS_P_LN_PR]);
    }
    for (t = 0; t < tb->nrad; ++t) {                         /* radiation, linearised (Eq 81) */
        gvs_real T_node_k = clip_r(T_q, tb->rad_T_lo_c, tb->rad_T_hi_c) + tb->kelvin;
        gvs_real T_bc_k = veh->T_bc_default_c[tb->rad_bc[t]] + tb->kelvin;
        G[tb->rad_link[t]] = tb->rad_area_eps[t] * tb->sigma * (T_node_k * T_node_k + T_bc_k * T_bc_k)
            * (T_node_k + T_bc_k);
    }
    for (t = 0; t < tb->nst - tb->ne; ++t) G_streams[t] = G2[tb->t2_stream_term[t]];
    for (t = 0; t < tb->ne; ++t) G_streams[tb->nst - tb->ne + t] = Ge[t];
}

/* ---- heat of every loss source (evaluate.heat_sources): meshes Eq 7-22, bearings Eq 35-40, oil-lumped sources
 * Eq 23-34, 36-37, 41, 42, and the retarder ---------------------------------------------------------------- */
static void heat_sources(const gvs_tables *tb, const gvs_vehicle *veh, int32_t gear_row, gvs_real omega_in_rad_s,
                         gvs_real torque_nm, const oil_row_t *o, gvs_real retarder_w, gvs_real *src)
{
    int32_t m, b, i = 0;
    gvs_real nu = EXP(o->prop[GVS_P_LN_NU_CST]), P_needle = R_(0.0), omega_in_sq, omega_ls_rad_s, fu, fT, P_churn;
    int32_t iu, jT;
    for (m = 0; m < tb->n_mesh; ++m, ++i) {
        gvs_real torque1_nm = tb->mesh_torque[gear_row * tb->n_mesh + m] * torque_nm;
        gvs_real omega2_rad_s = tb->mesh_omega2[gear_row * tb->n_mesh + m] * omega_in_rad_s;
        gvs_real log10_torque1, log10_omega2, x, fx, phi, P, log10_torque1_roll;
        int32_t ix;
        if (!(torque1_nm > R_(0.0) && omega2_rad_s > R_(0.0))) { src[i] = R_(0.0); continue; }
        log10_torque1 = LOG10(torque1_nm);
        log10_omega2 = LOG10(omega2_rad_s);
        x = (log10_torque1 - o->prop[GVS_P_LOG10_MU] - R_(3.0) * log10_omega2 - tb->mesh_x0[m]) / tb->x_step;
        x = clip_r(x, R_(0.0), (gvs_real)tb->nx - R_(1.000001));
        ix = (int32_t)x;
        if (ix > tb->nx - 2) ix = tb->nx - 2;    /* in float nx - 1.000001 rounds to nx - 1: stay in the table */
        fx = x - (gvs_real)ix;
        phi = tb->mesh_phi[m * tb->nx + ix] * (R_(1.0) - fx) + tb->mesh_phi[m * tb->nx + ix + 1] * fx;
        /* slip torque1 omega2 phi; rolling K mu^0.7 a^0.54 omega2^1.7 torque1^-0.13 (Eq 18) down to the mesh's
         * torque1_min, below it the loss at torque1_min scaled by torque1 / torque1_min (torque1^-1.13 taken at
         * torque1_min: continuous there and at 0) */
        log10_torque1_roll = max_r(log10_torque1, tb->mesh_roll_lt_min[m]);
        P = torque1_nm * omega2_rad_s
            * (phi + tb->mesh_roll_k[m]
                     * EXP(o->prop[GVS_P_LN_ROLL]
                           + tb->ln10 * (R_(0.7) * log10_omega2 - R_(1.13) * log10_torque1_roll)));
        src[i] = P * tb->mesh_heat_sf[m];
    }
    for (b = 0; b < tb->n_bear; ++b, ++i) {                  /* shaft bearings, Palmgren (Eq 35-40) */
        gvs_real omega_b_rad_s = tb->bear_speed[gear_row * tb->n_bear + b] * omega_in_rad_s;
        gvs_real M0 = tb->bear_c[b]
            * POW(max_r(nu * omega_b_rad_s * tb->rpm_per_rad_s, tb->palmgren_min), R_(2.0) / R_(3.0));
        gvs_real M_load = tb->bear_load[gear_row * tb->n_bear + b] * torque_nm;
        gvs_real rr = tb->bear_rr[gear_row * tb->n_bear + b];
        if (rr != R_(0.0) && torque_nm > R_(0.0) && omega_b_rad_s > R_(0.0)) {  /* SKF's rolling term, if given */
            gvs_real n_rpm = omega_b_rad_s * tb->rpm_per_rad_s;
            M_load += rr * POW(torque_nm, R_(GVS_SKF_RR_LOAD_EXP)) * POW(nu * n_rpm, R_(GVS_SKF_RR_NU_N_EXP))
                / (R_(1.0) + tb->bear_ish[b] * POW(n_rpm * n_rpm * nu, R_(GVS_SKF_ISH_EXP)));   /* inlet shear */
        }
        src[i] = (M0 + M_load) * omega_b_rad_s;
    }
    for (b = 0; b < tb->n_needle; ++b) {                     /* needle bearings on relative speed (Eq 36-37) */
        gvs_real omega_rel_rad_s = tb->needle_rel[gear_row * tb->n_needle + b] * omega_in_rad_s;
        gvs_real Mn = tb->needle_c[b]
            * POW(max_r(nu * omega_rel_rad_s * tb->rpm_per_rad_s, tb->palmgren_min), R_(2.0) / R_(3.0));
        P_needle += Mn * omega_rel_rad_s;
    }
    omega_in_sq = omega_in_rad_s * omega_in_rad_s;
    omega_ls_rad_s = shaft_speed(tb, gear_row, tb->churn_speed_col, omega_in_rad_s);
    iu = sqrt_speed_index(omega_ls_rad_s, tb->churn_omega_max_rad_s, tb->n_u_churn, &fu);  /* churning table */
    jT = grid_index(o->x, tb->nT, &fT);
    P_churn = bilinear(tb->churn_table + iu * tb->nT + jT, tb->nT, fu, fT);
    src[i++] = P_churn * tb->churn_heat_sf * veh->churn_scale + P_needle * veh->needle_scale
        + EXP(o->prop[GVS_P_LN_MU]) * omega_in_sq * tb->sync_coef[gear_row]                  /* synchronizers, Eq 41 */
        + tb->pump_coef[gear_row] * omega_in_sq;                                              /* pump, Eq 42 */
    src[i++] = retarder_w;
    for (m = 0; m < tb->ns; ++m) src[m] *= veh->src_scale[m];
}

/* ---- heat of the retarder into the sump [W]: its share of the braking power, |torque| x output-shaft speed
 * (evaluate.retarder_heat_w) ------------------------------------------------------------------------------------ */
static gvs_real retarder_heat_w(const gvs_tables *tb, const gvs_vehicle *veh, int32_t gear_row, gvs_real omega_in_rad_s,
                                gvs_real retarder_torque_nm)
{
    return veh->retarder_frac * retarder_torque_nm
        * shaft_speed(tb, gear_row, tb->output_speed_col, omega_in_rad_s);
}

/* ---- the oil cooler (physics.cooler.oil_cooler_heat, seed 3.4, Eq 82-83) --------------------------------- */
static gvs_real interp_r(gvs_real x, const gvs_real *xp, const gvs_real *fp, int32_t n)
{
    int32_t i;
    if (x <= xp[0]) return fp[0];
    if (x >= xp[n - 1]) return fp[n - 1];
    for (i = 1; i < n - 1 && x >= xp[i]; ++i) {}
    /* as numpy.interp: slope (x - xp[j]) + fp[j] */
    return ((fp[i] - fp[i - 1]) / (xp[i] - xp[i - 1])) * (x - xp[i - 1]) + fp[i - 1];
}

/* the cooler's operating point: what depends on the speeds and the air, not on the oil temperature (the powers,
 * computed once per step for both copies) */
typedef struct {
    gvs_real hA, T_air;                 /* [W/K], the air at the cooler [degC] (air coolers) */
    gvs_real T_cool;                    /* the coolant [degC] (liquid coolers) */
    gvs_real cap;                       /* the oil stream's m cp [W/K], 0 without flow */
} cooler_op_t;

static void cooler_op(const gvs_tables *tb, const gvs_vehicle *veh, gvs_real w_ls, gvs_real w_eng, gvs_real T_cool,
                      gvs_real T_amb, gvs_real v_kmh, gvs_real mcp, cooler_op_t *op)
{
    gvs_real inner;
    op->cap = mcp > R_(0.0) ? mcp : R_(0.0);
    op->T_cool = T_cool;
    op->hA = op->T_air = R_(0.0);
    if (tb->cooler_code == GVS_COOLER_NONE) return;
    /* a missing vehicle speed, or any for a drive that has none (no ram air, no recirculation): the default */
    if (v_kmh != v_kmh || !((tb->aux_expected >> (GVS_I_VKMH - GVS_I_AMB)) & 1)) v_kmh = tb->default_vkmh;
    /* the inner flow over the data sheet's: a shaft pump's speed over the reference, a motor pump's 1 (w_ls: the
     * pump_drive) */
    inner = POW(tb->pump_code == GVS_PUMP_MOTOR ? w_ls : w_ls / tb->ref_ls_speed, tb->exp_inner);
    if (tb->cooler_code == GVS_COOLER_LIQUID) {
        gvs_real outer = POW(max_r(w_eng, R_(0.0)) / tb->ref_engine_speed, tb->exp_outer);
        op->hA = tb->liquid_hA_ref * inner * outer * veh->cooler_scale;
    } else {
        gvs_real fmin = tb->air_flow_min_frac;
        gvs_real rel = min_r(max_r(v_kmh, R_(0.0)) / tb->air_ref_speed_kmh, tb->air_flow_max_rel);
        op->T_air = T_amb + interp_r(max_r(v_kmh, R_(0.0)), tb->recirc_v_kmh, tb->recirc_dT_k, tb->n_recirc);
        op->hA = tb->air_hA_ref * inner * POW(fmin + (R_(1.0) - fmin) * rel, tb->exp_outer) * veh->cooler_scale;
    }
}

/* the heat the cooler takes from oil at T_oil [W] */
static gvs_real cooler_heat(const gvs_tables *tb, const gvs_vehicle *veh, const cooler_op_t *op, gvs_real T_oil)
{
    gvs_real cap = op->cap, hA = op->hA, Q;
    if (tb->cooler_code == GVS_COOLER_NONE) return R_(0.0);
    if (tb->cooler_code == GVS_COOLER_LIQUID) {             /* liquid: can heat the oil, no thermostat */
        Q = clip_r(hA * (T_oil - op->T_cool), -tb->liquid_Qmax_heat, tb->liquid_Qmax_cool);     /* Eq 83 */
    } else {                                                 /* air, behind a thermostat (Eq 82 coupled) */
        gvs_real T_open = tb->thermostat_open_c + veh->thermostat_offset_c;
        gvs_real T_full = tb->thermostat_full_c + veh->thermostat_offset_c;
        gvs_real a, D, q_lin, q;
        a = hA * max_r(T_oil - op->T_air, R_(0.0));
        D = T_full - T_open;
        /* the thermostat reads the return (Eq 82 coupled: a / cap) or the sump (no coupling) */
        q_lin = a * (T_oil - T_open) / (D + (tb->thermostat_sump > R_(0.5) ? R_(0.0) : a / (cap > R_(0.0) ? cap : R_(1.0))));
        q = min_r(clip_r(q_lin, R_(0.0), a), tb->air_Qmax_cool);
        Q = (cap > R_(0.0) && a > R_(0.0)) ? q : R_(0.0);
    }
    return cap > R_(0.0) ? Q : R_(0.0);
}

/* the sump heater's heat into the oil at T_oil [W] (physics.cooler.heater_heat_w): full power at or below
 * heater_set - heater_band, none at or above heater_set, linear between; the cooler's heat is taken net of it */
static gvs_real heater_heat(const gvs_tables *tb, gvs_real T_oil)
{
    if (!(tb->heater_w > R_(0.0))) return R_(0.0);
    return tb->heater_w * clip_r((tb->heater_set_c - T_oil) / tb->heater_band_k, R_(0.0), R_(1.0));
}

/* d(-heater)/dT_oil [W/K] (physics.cooler.heater_slope_w_per_k) */
static gvs_real heater_slope(const gvs_tables *tb, gvs_real T_oil)
{
    gvs_real x;
    if (!(tb->heater_w > R_(0.0))) return R_(0.0);
    x = (tb->heater_set_c - T_oil) / tb->heater_band_k;
    return (x > R_(0.0) && x < R_(1.0)) ? tb->heater_w / tb->heater_band_k : R_(0.0);
}

/* the cooler's heat net of the heater with the sump measured and tables.measured_balance set
 * (physics.cooler.measured_balance_heat_w): what the sump's gain H leaves, the jets giving back gs / mcp of it,
 * between a closed bypass and the fully open valve */
static gvs_real balance_heat(const gvs_tables *tb, const cooler_op_t *op, gvs_real H, gvs_real gs, gvs_real T_oil)
{
    gvs_real heat = heater_heat(tb, T_oil), keep, a;
    if (!(op->cap > R_(0.0))) return R_(0.0);
    keep = max_r(R_(1.0) - gs / op->cap, tb->balance_keep_min);
    a = min_r(op->hA * max_r(T_oil - op->T_air, R_(0.0)), tb->air_Qmax_cool);
    return clip_r(H / keep + heat, R_(0.0), a) - heat;
}

GVS_OUTLINE static gvs_real inlet_drop_k(const gvs_tables *tb, gvs_real Q, gvs_real mcp)
{
    return clip_r(mcp > R_(0.0) ? Q / mcp : R_(0.0), -tb->inlet_drop_max_k, tb->inlet_drop_max_k);
}

/* the nodes' share q of the sources' heat src */
static void scatter_heat(const gvs_tables *tb, const gvs_real *src, gvs_real *q)
{
    int32_t i, k;
    for (i = 0; i < tb->n; ++i) q[i] = R_(0.0);
    for (k = 0; k < tb->nsrc_nz; ++k) q[tb->src_nz_node[k]] += src[tb->src_nz_src[k]] * tb->src_nz_w[k];
}

/* ---- input checks (input_check.check_inputs) --------------------------------------------------------------- */
typedef struct {
    int ok[GVS_N_INPUTS];
    gvs_real used[GVS_N_INPUTS];
    int measured, drive_ok, drive_frozen, oil_frozen;
    gvs_real drive_age_s;
} check_t;

static void check_inputs(const gvs_tables *tb, gvs_state *st, const double *raw_d, int64_t *counts, check_t *c)
{
    gvs_real raw[GVS_N_INPUTS], fixed[GVS_N_INPUTS], same[GVS_N_INPUTS], age[GVS_N_INPUTS];
    int finite[GVS_N_INPUTS], in_range[GVS_N_INPUTS], clamped[GVS_N_INPUTS], i, jumpy, oil_in_range, gear_ok;
    gvs_real dt = tb->dt_s, twin_oil, oil_ref;
    /* the checks and the clamp on the double value (a float build must judge 1e308 as the reference does) */
    for (i = 0; i < GVS_N_INPUTS; ++i) {
        double r = raw_d[i], lo = (double)tb->clamp_lo[i], hi = (double)tb->clamp_hi[i], f;
        raw[i] = (gvs_real)(r);
        int64_t kr = d_key(r);
        finite[i] = finite_d(r);
        in_range[i] = finite[i] && kr >= d_key((double)tb->input_lo[i]) && kr <= d_key((double)tb->input_hi[i]);
        f = i == GVS_I_RET ? fabs(r) : (kr < d_key(lo) ? lo : (kr > d_key(hi) ? hi : r));
        clamped[i] = in_range[i] && d_key(f) != kr;    /* beyond the plausible range: missing, not clamped */
        fixed[i] = finite[i] ? (gvs_real)(f) : raw[i];
    }
    /* an integer in range and a gear of the description (its bit in gear_defined) */
    gear_ok = in_range[GVS_I_GEAR] && raw[GVS_I_GEAR] == RINT(raw[GVS_I_GEAR])
        && ((tb->gear_defined >> ((int32_t)raw[GVS_I_GEAR] - tb->gear_min)) & 1);
    oil_in_range = in_range[GVS_I_OIL];
    if (tb->oil_mode_measured) {
        /* off both the last good reading and the main copy's sump (that reading carried by the model since) by more
         * than oil_step_c and a drift over the time since it came (its age and the period one reading stands for) */
        gvs_real allow = tb->oil_step_c + R_(GVS_OIL_DRIFT_K_PER_S) * (st->age_s[GVS_I_OIL] + tb->oil_period_s);
        jumpy = oil_in_range && FABS(raw[GVS_I_OIL] - st->T_c[GVS_MAIN][tb->i_oil]) > allow
            && FABS(raw[GVS_I_OIL] - st->hold[GVS_I_OIL]) > allow;
    } else                      /* the reading is not used: a step from a good value less than 1 s old */
        jumpy = oil_in_range && st->age_s[GVS_I_OIL] <= R_(1.0)
            && FABS(raw[GVS_I_OIL] - st->hold[GVS_I_OIL]) > tb->oil_step_c;
    for (i = 0; i < GVS_N_INPUTS; ++i)
        same[i] = (finite[i] && raw[i] == st->raw_prev[i]) ? st->same_s[i] + dt : R_(0.0);
    twin_oil = st->T_c[GVS_TWIN][tb->i_oil];
    oil_ref = same[GVS_I_OIL] > R_(0.0) ? st->oil_ref_c : twin_oil;
    c->oil_frozen = oil_in_range && same[GVS_I_OIL] >= tb->oil_frozen_s
        && FABS(twin_oil - oil_ref) >= tb->oil_frozen_drift_c;
    c->drive_frozen = same[GVS_I_SPEED] >= tb->drive_frozen_s && same[GVS_I_TORQUE] >= tb->drive_frozen_s
        && finite[GVS_I_SPEED] && fixed[GVS_I_SPEED] > R_(0.0);
    for (i = 0; i < GVS_N_INPUTS; ++i) c->ok[i] = in_range[i];
    c->ok[GVS_I_GEAR] = gear_ok;
    c->ok[GVS_I_OIL] = oil_in_range && !jumpy && !c->oil_frozen;
    for (i = 0; i < GVS_N_INPUTS; ++i) {
        /* auxiliary inputs are not held: a missing one takes its default */
        gvs_real fallback = i >= GVS_I_AMB ? tb->aux_default[i - GVS_I_AMB] : st->hold[i];
        c->used[i] = c->ok[i] ? fixed[i] : fallback;
        age[i] = c->ok[i] ? R_(0.0) : st->age_s[i] + dt;
    }
    counts[GVS_RJ_SPEED_MISSING] = !in_range[GVS_I_SPEED];      /* NaN, inf, or a value no J1939 frame can carry */
    counts[GVS_RJ_TORQUE_MISSING] = !in_range[GVS_I_TORQUE];
    counts[GVS_RJ_GEAR_MISSING] = !finite[GVS_I_GEAR];
    counts[GVS_RJ_OIL_MISSING] = !finite[GVS_I_OIL];
    counts[GVS_RJ_SPEED_CLAMPED] = clamped[GVS_I_SPEED];
    counts[GVS_RJ_TORQUE_CLAMPED] = clamped[GVS_I_TORQUE];
    counts[GVS_RJ_GEAR_UNKNOWN] = finite[GVS_I_GEAR] && !gear_ok;
    counts[GVS_RJ_OIL_IMPLAUSIBLE] = (finite[GVS_I_OIL] && !oil_in_range) || jumpy;
    counts[GVS_RJ_OIL_FROZEN] = c->oil_frozen;
    counts[GVS_RJ_DRIVE_FROZEN] = c->drive_frozen;
    /* an auxiliary input the drive has not (its bit in aux_expected clear) is not applicable: not counted */
    counts[GVS_RJ_AUX_MISSING] = 0;
    for (i = GVS_I_AMB; i < GVS_N_INPUTS; ++i)
        counts[GVS_RJ_AUX_MISSING] += !c->ok[i] && ((tb->aux_expected >> (i - GVS_I_AMB)) & 1);
    c->measured = tb->oil_mode_measured ? c->ok[GVS_I_OIL] : 0;
    c->drive_ok = c->ok[GVS_I_SPEED] && c->ok[GVS_I_TORQUE] && c->ok[GVS_I_GEAR];
    c->drive_age_s = max_r(max_r(age[GVS_I_SPEED], age[GVS_I_TORQUE]), age[GVS_I_GEAR]);
    /* the state's part of the checks (written back by the caller's step) */
    for (i = 0; i < GVS_N_INPUTS; ++i) {
        st->same_s[i] = same[i];
        st->age_s[i] = age[i];
        st->raw_prev[i] = raw[i];
        if (c->ok[i]) st->hold[i] = c->used[i];
    }
    st->oil_ref_c = oil_ref;
}

/* ---- the conductance bin of the operating point (conductance_bins.bin_centre) ------------------------------ */
GVS_OUTLINE static gvs_real speed_bin_centre(const gvs_tables *tb, gvs_real w)
{
    if (!(w >= tb->speed_bin_min)) return R_(0.0);
    return EXP(RINT(LOG(w) / tb->ln_speed_bin) * tb->ln_speed_bin);
}

/* ---- warning levels (warning_levels.update_levels; step._levels) ------------------------------------------ */
static void update_levels(const gvs_tables *tb, gvs_state *st, const gvs_real *T_pub, int available,
                          const gvs_real *ttl_now)
{
    int i, rest = available;
    for (i = 0; i < tb->n_pub && rest; ++i)
        rest = T_pub[i] < tb->warning_rest_c[i] && st->level[i] == GVS_LEVEL_NORMAL && st->pending_s[i] == R_(0.0)
            && (tb->lead_s <= R_(0.0) || ttl_now[i] > R_(2.0) * tb->lead_s);
    if (rest) {            /* nothing near a limit: the state machine rests */
        for (i = 0; i < tb->n_pub; ++i) { st->level[i] = GVS_LEVEL_NORMAL; st->pending_s[i] = R_(0.0); }
        return;
    }
    for (i = 0; i < tb->n_pub; ++i) {
        int lv = st->level[i], target, held, crit, warn, change, take;
        gvs_real T = T_pub[i], pend;
        crit = T >= tb->critical_c[i] || (lv == GVS_LEVEL_CRITICAL && T > tb->critical_c[i] - tb->hysteresis_k[i]);
        held = lv >= GVS_LEVEL_WARNING && lv <= GVS_LEVEL_CRITICAL;
        warn = T >= tb->warning_c[i] || (held && T > tb->warning_c[i] - tb->hysteresis_k[i]);
        if (tb->lead_s > R_(0.0))      /* NaN (not available) compares false, like inf */
            warn = warn || ttl_now[i] <= tb->lead_s || (held && ttl_now[i] <= R_(2.0) * tb->lead_s);
        target = crit ? GVS_LEVEL_CRITICAL : (warn ? GVS_LEVEL_WARNING : GVS_LEVEL_NORMAL);
        if (!available) target = GVS_LEVEL_NA;
        change = target != lv;
        pend = change ? st->pending_s[i] + tb->dt_s : R_(0.0);
        /* half a step of slack: a float sum of 600 steps of 0.1 s falls short of 60 s (warning_levels.py) */
        take = change && (target == GVS_LEVEL_NA || lv == GVS_LEVEL_NA || pend >= tb->debounce_s - R_(0.5) * tb->dt_s);
        st->level[i] = (int8_t)(take ? target : lv);
        st->pending_s[i] = take ? R_(0.0) : pend;
    }
}

/* ---- a step whose time went backwards (step._skip) ----------------------------------------------------------- */
static int skip_step(const gvs_tables *tb, gvs_state *st, gvs_outputs *out)
{
    int i;
    st->rejects[GVS_RJ_TIME_BACKWARD] += 1;
    for (i = 0; i < tb->n_pub; ++i) {
        out->T_c[i] = st->T_c[GVS_MAIN][tb->published_index[i]];
        out->level[i] = st->level[i];
        out->ttl_s[i] = st->ttl_s[i];
    }
    out->degraded_mode = GVS_MODE_HOLDING;
    out->speed_valid = out->torque_valid = out->gear_valid = out->oil_valid = 0;
    out->valid_flags = 0;
    out->frozen_flags = 0;
    out->model_oil_temp_c = st->T_c[GVS_TWIN][tb->i_oil];
    out->oil_innovation_c = (gvs_real)NAN;
    out->oil_inlet_temp_c = (gvs_real)NAN;
    out->oil_source = 1;
    copy_rejects(out->rejects, st->rejects);
    return GVS_SKIPPED;
}

/* 1 when this build's NaN comparisons work: a compiler told NaN cannot occur (-ffast-math, -ffinite-math-only,
 * clang's -fno-honor-nans, which defines no macro the #error above could see) folds x != x to false, and the input
 * checks would take NaN for a value */
static int nan_checks_work(void)
{
    volatile gvs_real zero = R_(0.0);      /* the real type: a double division is soft-float on an M4F (1 KB) */
    gvs_real x = zero / zero;
    return x != x;
}

int gvs_check_tables(const gvs_tables *tb)
{
    if (!nan_checks_work()) return GVS_BAD_TABLES;
    if (tb->n > GVS_MAX_NODES || tb->nl > GVS_MAX_LINKS || tb->ldl_nnz > GVS_MAX_LNZ || tb->ns > GVS_MAX_SRC || tb->nb > GVS_MAX_BC
        || tb->nst > GVS_MAX_STREAMS || tb->n2 > GVS_MAX_TERMS || tb->ne > GVS_MAX_TERMS
        || tb->ncol > GVS_MAX_TERMS || tb->n_gears < 1 || tb->n_gears > GVS_MAX_GEARS
        || tb->n_pub < 1 || tb->n_pub > GVS_MAX_PUB || tb->pump_speed_col < -1 || tb->pump_speed_col >= tb->n_speed
        || tb->pump_code < GVS_PUMP_NONE || tb->pump_code > GVS_PUMP_MOTOR
        || tb->churn_speed_col < -1 || tb->churn_speed_col >= tb->n_speed || tb->output_speed_col < -1
        || tb->output_speed_col >= tb->n_speed || tb->n_needle < 0 || tb->ns != tb->n_mesh + tb->n_bear + 2
        || tb->nT < 2 || tb->nT2 < 2 || tb->n_u < 2 || tb->n_u_churn < 2 || tb->nx < 2 || tb->ttl_every < 1)
        return GVS_BAD_TABLES;
#ifdef GVS_NO_TTL_BOUND
    if (tb->ttl_bound) return GVS_BAD_TABLES;    /* tables asking for the bounded method this build left out */
#endif
    return GVS_OK;
}

/* ---- network part of the step (step._network_step) --------------------------------------------------------
 * operating point, heat through the lag, conductances of the bin, cooler and inlet drop, one explicit step of
 * both copies; T holds both copies on entry (main sump already replaced) and after the step on return. */
typedef struct {
    gvs_real src[GVS_MAX_SRC], T_bc[GVS_MAX_BC];
    const gvs_real *G, *Gs;             /* the bin's conductances: the state's memo, read in place */
    gvs_real dT_in[2], Q_cool[2], rho_cp, omega_in, T_oil_main;
    gvs_real Q_law, dT_law;             /* the main copy's by the cooler's law (step.NetworkStep.law_main) */
    int32_t row;
} net_t;

#ifdef GVS_STEP_MEMO
/* one explicit step of one copy T from its heat r (the main copy's arithmetic of network_step, in its order) */
static void euler_one_copy(const gvs_tables *tb, const net_t *nt, gvs_real *T0, gvs_real *r0)
{
    int32_t i, k;
    for (k = 0; k < tb->nst; ++k) {
        gvs_real f0 = nt->Gs[k] * nt->dT_in[GVS_MAIN];
        r0[tb->stream_node[k]] -= f0;
        r0[tb->i_oil] += f0;
    }
    r0[tb->i_oil] -= nt->Q_cool[GVS_MAIN];
    for (k = 0; k < tb->nl; ++k) {
        int32_t a = tb->link_a[k], b = tb->link_b[k];
        gvs_real g = nt->G[k];
        if (b < tb->n) {
            gvs_real f0 = g * (T0[a] - T0[b]);      /* heat from a to b */
            r0[a] -= f0;
            r0[b] += f0;
        } else {
            r0[a] -= g * (T0[a] - nt->T_bc[b - tb->n]);
        }
    }
    for (i = 0; i < tb->n; ++i) T0[i] += tb->dt_over_C[i] * r0[i];
}
#endif

static void network_step(const gvs_tables *tb, const gvs_vehicle *veh, gvs_state *st, const check_t *c,
                         double oil_raw, net_t *nt)
{
    gvs_real rate[2][GVS_MAX_NODES], delivered[GVS_MAX_SRC], (*T)[GVS_MAX_NODES] = st->T_c;
    gvs_real w = c->used[GVS_I_SPEED] * tb->rad_s_per_rpm, torque = FABS(c->used[GVS_I_TORQUE]);
    gvs_real retarder_w, w_ls, mcp;
    cooler_op_t cop;
    oil_row_t o;
    int32_t i, k, cp;
    nt->omega_in = w;
    nt->row = (int32_t)c->used[GVS_I_GEAR] - tb->gear_min;
    nt->T_oil_main = c->measured ? (gvs_real)(oil_raw) : T[GVS_MAIN][tb->i_oil];
    T[GVS_MAIN][tb->i_oil] = nt->T_oil_main;
    oil_row(tb, nt->T_oil_main, &o, NULL);
    for (i = 0; i < tb->nb; ++i) nt->T_bc[i] = veh->T_bc_default_c[i];
    nt->T_bc[tb->i_ambient] = c->used[GVS_I_AMB];
    nt->T_bc[tb->i_coolant] = c->used[GVS_I_COOL];
    /* heat (loss maps) through the first-order heat lag, exact step average (physics.heat_lag) */
    retarder_w = retarder_heat_w(tb, veh, nt->row, w, c->used[GVS_I_RET]);
#ifdef GVS_STEP_MEMO
    /* the host's build: the same inputs and sump as the last step (a held row), the same sources (a pure function) */
    if (st->memo_heat_valid && st->memo_heat_row == nt->row && st->memo_heat_key[0] == w
        && st->memo_heat_key[1] == torque && st->memo_heat_key[2] == nt->T_oil_main
        && st->memo_heat_key[3] == retarder_w) {
        copy_r(nt->src, st->memo_src, tb->ns);
    } else {
        heat_sources(tb, veh, nt->row, w, torque, &o, retarder_w, nt->src);
        copy_r(st->memo_src, nt->src, tb->ns);
        st->memo_heat_row = nt->row;
        st->memo_heat_key[0] = w;
        st->memo_heat_key[1] = torque;
        st->memo_heat_key[2] = nt->T_oil_main;
        st->memo_heat_key[3] = retarder_w;
        st->memo_heat_valid = 1;
    }
#else
    heat_sources(tb, veh, nt->row, w, torque, &o, retarder_w, nt->src);
#endif
    for (i = 0; i < tb->ns; ++i) {
        gvs_real y = st->lag_w[i] + (nt->src[i] - st->lag_w[i]) * tb->lag_gain;
        delivered[i] = nt->src[i] - tb->lag_tau_over_dt * (y - st->lag_w[i]);
        st->lag_w[i] = y;
    }
    scatter_heat(tb, delivered, rate[GVS_MAIN]);   /* the heat into each node, both copies' rates from it */
    /* conductances at the centre of the operating point's bin: 1 % in speed, 0.5 K in oil */
    {
        gvs_real w_q = speed_bin_centre(tb, w), T_q = RINT(nt->T_oil_main / tb->oil_bin_c) * tb->oil_bin_c;
        if (!(st->memo_valid && st->memo_row == nt->row && st->memo_omega_q == w_q && st->memo_T_q == T_q)) {
            bin_conductances(tb, veh, nt->row, w_q, T_q, st->memo_G, st->memo_Gs);
            st->memo_row = nt->row;
            st->memo_omega_q = w_q;
            st->memo_T_q = T_q;
            st->memo_valid = 1;
        }
        nt->G = st->memo_G;
        nt->Gs = st->memo_Gs;
    }
    w_ls = pump_drive(tb, nt->row, w);
    nt->rho_cp = o.prop[GVS_P_RHO] * o.prop[GVS_P_CP];
    mcp = nt->rho_cp * flow_per_drive(tb) * w_ls;
    cooler_op(tb, veh, w_ls, w, c->used[GVS_I_COOL], c->used[GVS_I_AMB], c->used[GVS_I_VKMH], mcp, &cop);
    for (cp = 0; cp < 2; ++cp) {
        nt->Q_cool[cp] = cooler_heat(tb, veh, &cop, T[cp][tb->i_oil]) - heater_heat(tb, T[cp][tb->i_oil]);
        nt->dT_in[cp] = inlet_drop_k(tb, nt->Q_cool[cp], mcp);
    }
    nt->Q_law = nt->Q_cool[GVS_MAIN];
    nt->dT_law = nt->dT_in[GVS_MAIN];
    if (c->measured && tb->measured_balance > R_(0.5)) {
        /* the main copy's cooler from the sump's balance (step._measured_balance): its sources, its links */
        const gvs_real *T0 = T[GVS_MAIN];
        gvs_real H = rate[GVS_MAIN][tb->i_oil], gs = R_(0.0);
        for (k = 0; k < tb->nl; ++k) {
            int32_t a = tb->link_a[k], b = tb->link_b[k];
            if (a == tb->i_oil) H += nt->G[k] * ((b < tb->n ? T0[b] : nt->T_bc[b - tb->n]) - T0[a]);
            else if (b == tb->i_oil) H += nt->G[k] * (T0[a] - T0[b]);
        }
        for (k = 0; k < tb->nst; ++k) gs += nt->Gs[k];
        nt->Q_cool[GVS_MAIN] = balance_heat(tb, &cop, H, gs, T0[tb->i_oil]);
        nt->dT_in[GVS_MAIN] = inlet_drop_k(tb, nt->Q_cool[GVS_MAIN], mcp);
    }
#ifdef GVS_STEP_MEMO
    /* the host's build: with the sump modelled the twin is the main copy bit for bit (same heat, conductances and
     * start): one copy stepped, the twin copied, the same bits as stepping both */
    if (!c->measured && memcmp(T[GVS_MAIN], T[GVS_TWIN], (size_t)tb->n * sizeof(gvs_real)) == 0) {
        euler_one_copy(tb, nt, T[GVS_MAIN], rate[GVS_MAIN]);
        copy_r(T[GVS_TWIN], T[GVS_MAIN], tb->n);
        return;
    }
#endif
    /* one explicit (forward Euler) step of both copies, side by side: two independent chains of updates (each
     * copy's sums in the same order as one copy at a time) */
    {
        gvs_real *T0 = T[GVS_MAIN], *T1 = T[GVS_TWIN], *r0 = rate[GVS_MAIN], *r1 = rate[GVS_TWIN];
        gvs_real d0 = nt->dT_in[GVS_MAIN], d1 = nt->dT_in[GVS_TWIN];
        for (i = 0; i < tb->n; ++i) r1[i] = r0[i];
        for (k = 0; k < tb->nst; ++k) {
            int32_t s = tb->stream_node[k];
            gvs_real f0 = nt->Gs[k] * d0, f1 = nt->Gs[k] * d1;
            r0[s] -= f0;
            r0[tb->i_oil] += f0;
            r1[s] -= f1;
            r1[tb->i_oil] += f1;
        }
        r0[tb->i_oil] -= nt->Q_cool[GVS_MAIN];
        r1[tb->i_oil] -= nt->Q_cool[GVS_TWIN];
        for (k = 0; k < tb->nl; ++k) {
            int32_t a = tb->link_a[k], b = tb->link_b[k];
            gvs_real g = nt->G[k];
            if (b < tb->n) {
                gvs_real f0 = g * (T0[a] - T0[b]), f1 = g * (T1[a] - T1[b]);      /* heat from a to b */
                r0[a] -= f0;
                r1[a] -= f1;
                r0[b] += f0;
                r1[b] += f1;
            } else {
                gvs_real Tb = nt->T_bc[b - tb->n];
                r0[a] -= g * (T0[a] - Tb);
                r1[a] -= g * (T1[a] - Tb);
            }
        }
        for (i = 0; i < tb->n; ++i) {
            T0[i] += tb->dt_over_C[i] * r0[i];
            T1[i] += tb->dt_over_C[i] * r1[i];
        }
    }
    if (c->measured) T[GVS_MAIN][tb->i_oil] = (gvs_real)(oil_raw);
}

static void ttl_point(const gvs_tables *tb, const gvs_state *st, const check_t *c, const net_t *nt,
                      gvs_ttl_point *p)
{
    int32_t i;
    for (i = 0; i < tb->n; ++i) p->T_main_c[i] = st->T_c[GVS_MAIN][i];
    for (i = 0; i < tb->ns; ++i) p->src_w[i] = nt->src[i];
    for (i = 0; i < tb->nl; ++i) p->G_w_per_k[i] = nt->G[i];
    for (i = 0; i < tb->nst; ++i) p->G_streams_w_per_k[i] = nt->Gs[i];
    for (i = 0; i < tb->nb; ++i) p->T_bc_c[i] = nt->T_bc[i];
    for (i = 0; i < GVS_N_INPUTS; ++i) p->used[i] = c->used[i];
    /* the sump modelled ahead (ttl_sump "model"): the cooler's law, whatever the step took for a measured one */
    p->dT_in_k = tb->ttl_sump_model ? nt->dT_law : nt->dT_in[GVS_MAIN];
    p->Q_cool_w = tb->ttl_sump_model ? nt->Q_law : nt->Q_cool[GVS_MAIN];
    p->omega_in_rad_s = nt->omega_in;
    p->T_oil_c = nt->T_oil_main;
    p->rho_cp_j_per_m3k = nt->rho_cp;
    p->measured = c->measured;
    p->row = nt->row;
    p->due = 1;
}


/* ---- time to limit: the held-input system marched (time_to_limit.time_to_limit, held_march) --------------------
 * C dT/dt = -A T + b with the inputs held, A = K (+ the cooler's slope on the sump) - u e_sump^T when the
 * oil-system inlet follows a modelled sump; K and C/h + K factorised as a sparse LDL^T (the pattern from the
 * tables), the coupling column by Sherman-Morrison. The march's settings: GVS_MARCH_*, GVS_TTL_*, GVS_HERMITE_*. */
#define LDL_SLOTS (GVS_MAX_NODES + GVS_MAX_LNZ)

typedef struct {
    const gvs_real *G;                  /* link conductances [W/K] */
    gvs_real slope;                     /* cooler slope on the sump's diagonal [W/K] */
    gvs_real u[GVS_MAX_NODES];          /* coupling column [W/K] */
    gvs_real w[GVS_MAX_NODES];          /* M^-1 (scale u) of the factorised M (Sherman-Morrison) */
    gvs_real S[LDL_SLOTS];              /* LDL^T slots */
    gvs_real K[LDL_SLOTS];              /* K's slots, unfactorised (held: the sump's row and column identity) */
    int coupled, held, metzler;         /* metzler: the maximum principle holds (held_march) */
    int weighted;                       /* not metzler: wt > 0 with B wt = 1 (held_march.HeldSystem.weights) */
    gvs_real wt[GVS_MAX_NODES];
#ifndef GVS_NO_TTL_BOUND
    int by_row;                         /* coupled march: w = M^-1 e_sump (held_factor), cw = d e_sump^T M^-1 u */
    gvs_real cw, d;
#endif
} held_t;

/* S = c_scale C + d K (held: the sump's row and column identity) */
static void ldl_assemble(const gvs_tables *tb, held_t *hs, gvs_real c_scale, gvs_real d)
{
    int32_t n = tb->n, k;
    gvs_real *S = hs->S;
    for (k = 0; k < n + tb->ldl_nnz; ++k) S[k] = R_(0.0);
    for (k = 0; k < n; ++k) S[tb->ldl_pos[k]] = c_scale * tb->C_j_per_k[k];
    for (k = 0; k < tb->nl; ++k) {
        int32_t a = tb->link_a[k], b = tb->link_b[k];
        gvs_real g = d * hs->G[k];
        S[tb->ldl_pos[a]] += g;
        if (b < n) {
            S[tb->ldl_pos[b]] += g;
            S[tb->ldl_link_slot[k]] -= g;
        }
    }
    S[tb->ldl_pos[tb->i_oil]] += d * hs->slope;
    if (hs->held) {
        for (k = 0; k < tb->nl; ++k)
            if (tb->link_b[k] < n && (tb->link_a[k] == tb->i_oil || tb->link_b[k] == tb->i_oil))
                S[tb->ldl_link_slot[k]] = R_(0.0);
        S[tb->ldl_pos[tb->i_oil]] = R_(1.0);
    }
}

static int ldl_factor(const gvs_tables *tb, gvs_real *S)
{
    int32_t n = tb->n, k, u, e;
    for (k = 0; k < n; ++k) {
        gvs_real dk = S[k], inv;
        if (!(dk > R_(0.0)) || !finite_g(dk)) return -1;
        inv = R_(1.0) / dk;
        for (u = tb->ldl_upd_ptr[k]; u < tb->ldl_upd_ptr[k + 1]; ++u)
            S[tb->ldl_upd_target[u]] -= S[tb->ldl_upd_a[u]] * inv * S[tb->ldl_upd_b[u]];
        for (e = tb->ldl_col_ptr[k]; e < tb->ldl_col_ptr[k + 1]; ++e) S[n + e] *= inv;
        S[k] = inv;                                  /* the diagonal kept as its inverse */
    }
    return 0;
}

/* x = (LDL^T)^-1 x, x in node order (S from ldl_factor: L below the diagonal, D^-1 on it) */
static void ldl_solve(const gvs_tables *tb, const gvs_real *S, gvs_real *x)
{
    gvs_real y[GVS_MAX_NODES];
    int32_t n = tb->n, k, e;
    for (k = 0; k < n; ++k) y[k] = x[tb->ldl_perm[k]];
    for (k = 0; k < n; ++k)
        for (e = tb->ldl_col_ptr[k]; e < tb->ldl_col_ptr[k + 1]; ++e) y[tb->ldl_row[e]] -= S[n + e] * y[k];
    for (k = 0; k < n; ++k) y[k] *= S[k];          /* D^-1 */
    for (k = n - 1; k >= 0; --k) {
        gvs_real acc = y[k];                       /* in a register: no store-to-load chain through y[k] */
        for (e = tb->ldl_col_ptr[k]; e < tb->ldl_col_ptr[k + 1]; ++e) acc -= S[n + e] * y[tb->ldl_row[e]];
        y[k] = acc;
    }
    for (k = 0; k < n; ++k) x[tb->ldl_perm[k]] = y[k];
}

/* factorise M = c_scale C + d K and, coupled, w = M^-1 (d u); -1 when M is not positive definite or the coupled
 * matrix M - d u e^T is singular. c_scale 0 (K itself, once per march) assembles from the links and keeps K's slots;
 * the march's steps then assemble C + d K from those slots (one pass, no link loop) */
static int held_factor(const gvs_tables *tb, held_t *hs, gvs_real c_scale, gvs_real d)
{
    int32_t i;
    if (c_scale == R_(0.0)) {
        ldl_assemble(tb, hs, c_scale, d);
        copy_r(hs->K, hs->S, tb->n + tb->ldl_nnz);
    } else {
        int32_t k, n = tb->n;
        for (k = 0; k < n; ++k) {
            int32_t q = tb->ldl_pos[k];
            hs->S[q] = c_scale * tb->C_j_per_k[k] + d * hs->K[q];
        }
        for (k = n; k < n + tb->ldl_nnz; ++k) hs->S[k] = d * hs->K[k];
        if (hs->held) hs->S[tb->ldl_pos[tb->i_oil]] = R_(1.0);
    }
    if (ldl_factor(tb, hs->S) != 0) return -1;
#ifndef GVS_NO_TTL_BOUND
    if (hs->coupled && hs->by_row && c_scale != R_(0.0)) {
        int32_t n = tb->n, k;
#ifdef GVS_REAL_FLOAT
        /* the float build (flash before speed) solves for e_sump in full: the forward pass over zeros keeps
         * them +0, so w is bit for bit the shortcut's below */
        for (k = 0; k < n; ++k) hs->w[k] = k == tb->i_oil ? R_(1.0) : R_(0.0);
        ldl_solve(tb, hs->S, hs->w);
#else
        /* the sump is eliminated last: L^-1 e_sump = e_sump, so M^-1 e_sump is D^-1 and the backward pass only */
        gvs_real y[GVS_MAX_NODES];
        int32_t e;
        for (k = 0; k < n - 1; ++k) y[k] = R_(0.0);
        y[n - 1] = hs->S[n - 1];
        for (k = n - 2; k >= 0; --k) {
            gvs_real acc = R_(0.0);
            for (e = tb->ldl_col_ptr[k]; e < tb->ldl_col_ptr[k + 1]; ++e) acc -= hs->S[n + e] * y[tb->ldl_row[e]];
            y[k] = acc;
        }
        for (k = 0; k < n; ++k) hs->w[tb->ldl_perm[k]] = y[k];
#endif
        hs->cw = R_(0.0);
        for (k = 0; k < n; ++k) hs->cw += hs->w[tb->ldl_perm[k]] * hs->u[tb->ldl_perm[k]];
        hs->cw *= d;
        hs->d = d;
        return R_(1.0) - hs->cw != R_(0.0) ? 0 : -1;
    }
#endif
    if (hs->coupled) {
        for (i = 0; i < tb->n; ++i) hs->w[i] = d * hs->u[i];
        ldl_solve(tb, hs->S, hs->w);
        if (!(R_(1.0) - hs->w[tb->i_oil] != R_(0.0))) return -1;
    }
    return 0;
}

/* x = (M - d u e_sump^T)^-1 x (Sherman-Morrison over the factorised M) */
static void held_solve(const gvs_tables *tb, const held_t *hs, gvs_real *x)
{
    int32_t i;
#ifndef GVS_NO_TTL_BOUND
    if (hs->coupled && hs->by_row && hs->d > R_(0.0)) {
        /* (M - d u e^T) y = x: y_sump = e^T M^-1 x / (1 - cw), then M y = x + d u y_sump */
        gvs_real ys = R_(0.0);
        for (i = 0; i < tb->n; ++i) ys += hs->w[i] * x[i];
        ys = ys / (R_(1.0) - hs->cw) * hs->d;
        for (i = 0; i < tb->n; ++i) x[i] += hs->u[i] * ys;
        ldl_solve(tb, hs->S, x);
        return;
    }
#endif
    ldl_solve(tb, hs->S, x);
    if (hs->coupled) {
        gvs_real f = x[tb->i_oil] / (R_(1.0) - hs->w[tb->i_oil]);
        for (i = 0; i < tb->n; ++i) x[i] += hs->w[i] * f;
    }
}

/* Ae = A e = K e (+ slope on the sump) - u e_sump (held: the sump's row 0) */
static void held_apply(const gvs_tables *tb, const held_t *hs, const gvs_real *e, gvs_real *Ae)
{
    int32_t n = tb->n, k, i;
    for (i = 0; i < n; ++i) Ae[i] = R_(0.0);
    for (k = 0; k < tb->nl; ++k) {
        int32_t a = tb->link_a[k], b = tb->link_b[k];
        if (b < n) {
            gvs_real f = hs->G[k] * (e[a] - e[b]);
            Ae[a] += f;
            Ae[b] -= f;
        } else {
            Ae[a] += hs->G[k] * e[a];
        }
    }
    Ae[tb->i_oil] += hs->slope * e[tb->i_oil];
    if (hs->coupled)
        for (i = 0; i < n; ++i) Ae[i] -= hs->u[i] * e[tb->i_oil];
    if (hs->held) Ae[tb->i_oil] = R_(0.0);
}

/* the cooler's operating point with the point's inputs (op); 0: no cooler, or no drive (it takes no heat) */
static int point_cooler(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, cooler_op_t *op)
{
    gvs_real w_ls = pump_drive(tb, p->row, p->omega_in_rad_s);
    gvs_real mcp = p->rho_cp_j_per_m3k * flow_per_drive(tb) * w_ls;
    const gvs_real *u = p->used;
    if (tb->cooler_code == GVS_COOLER_NONE || !(w_ls > R_(0.0))) return 0;
    cooler_op(tb, veh, w_ls, p->omega_in_rad_s, u[GVS_I_COOL], u[GVS_I_AMB], u[GVS_I_VKMH], mcp, op);
    return 1;
}

/* dQ_cooler/dT_oil [W/K] (held_inputs.cooler_slope_w_per_k), the heater's taken off: liquid its hA unless saturated,
 * air a finite difference, no cooler or drive the heater's alone */
static gvs_real cooler_slope(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real T)
{
    gvs_real Q, Q_hi, Q_lo;
    cooler_op_t op;
    if (!point_cooler(tb, veh, p, &op)) return heater_slope(tb, T);
    if (tb->cooler_code == GVS_COOLER_LIQUID) {
        Q = cooler_heat(tb, veh, &op, T);
        return ((-tb->liquid_Qmax_heat < Q && Q < tb->liquid_Qmax_cool) ? op.hA : R_(0.0)) + heater_slope(tb, T);
    }
    Q_hi = cooler_heat(tb, veh, &op, T + R_(0.05)) - heater_heat(tb, T + R_(0.05));
    Q_lo = cooler_heat(tb, veh, &op, T - R_(0.05)) - heater_heat(tb, T - R_(0.05));
    return max_r((Q_hi - Q_lo) / R_(0.1), R_(0.0));
}

/* time_to_limit._weights: wt = B^-1 1 (rhs NULL; the chord systems: B^-1 C, ttl_bound.positive_weights), B = K - u2
 * e_sump^T (A's diagonal, minus the moduli of its off-diagonal entries: only the sump's column differs from K's, -|col|
 * instead of -G), by Sherman-Morrison on K's factors in hs->S; hs->weighted when every wt is finite and positive. u2
 * is built in the scratch rs. */
static void held_weights(const gvs_tables *tb, held_t *hs, const gvs_real *col, gvs_real *rs, const gvs_real *rhs)
{
    int32_t n = tb->n, i, io = tb->i_oil;
    gvs_real den, f;
    for (i = 0; i < n; ++i) {
        rs[i] = i != io ? FABS(col[i]) - col[i] + hs->u[i] : hs->u[i];
        hs->wt[i] = rhs ? rhs[i] : R_(1.0);
    }
    ldl_solve(tb, hs->S, rs);
    ldl_solve(tb, hs->S, hs->wt);
    den = R_(1.0) - rs[io];
    if (!(den != R_(0.0))) return;
    f = hs->wt[io] / den;
    hs->weighted = 1;
    for (i = 0; i < n; ++i) {
        hs->wt[i] += rs[i] * f;
        if (!(hs->wt[i] > R_(0.0)) || !finite_g(hs->wt[i])) hs->weighted = 0;
    }
}

/* -A's sump column (the coupling u and the links to the sump) */
static void sump_column(const gvs_tables *tb, const held_t *hs, gvs_real *col)
{
    int32_t n = tb->n, i, k, io = tb->i_oil;
    for (i = 0; i < n; ++i) col[i] = hs->u[i];                 /* -A's sump column */
    for (k = 0; k < tb->nl; ++k) {
        int32_t a = tb->link_a[k], b = tb->link_b[k];
        if (b >= n) continue;
        if (a == io) col[b] += hs->G[k];
        else if (b == io) col[a] += hs->G[k];
    }
}

/* ---- the bounded time to limit (ttl_bound): the sump's path to its far value in parts ------------------------
 * in each part the losses follow their chord, q(T_sump) = q(T_end) + beta (T_sump - T_end), and the cooler and the
 * inlet drop lines under their curves; beta joins the coupling column on the sump (ttl_bound.chord_system) */
typedef struct {
    gvs_real slope;                     /* the part's cooler line [W/K] (at least 0) */
    gvs_real Q0;                        /* ... its heat at the part's start sump [W] */
    gvs_real inlet;                     /* the part's inlet-drop line [K/K] (0: the drop held at dT0) */
    gvs_real T0;                        /* the part's start sump [degC] */
    gvs_real dT0;                       /* ... and the inlet-drop line there [K] */
    gvs_real T_far;                     /* the part's end sump [degC] */
    gvs_real beta[GVS_MAX_NODES];       /* the node heat's chord over the part [W/K] */
    const gvs_real *T_start;            /* the march's start state (NULL: the point's) */
    const gvs_real *done;               /* per published component: finite, decided by an earlier part (or NULL) */
    march_t t0;                         /* the march's start time [s] */
    gvs_real T_ev;                      /* the sump at which the march stops (NaN: none) */
    march_t t_ev;                       /* out: when the sump reached it (NaN: never in the march) */
    gvs_real *T_at;                     /* out: every node then */
} ttl_chord_t;

#ifndef GVS_NO_TTL_BOUND
/* ttl_bound.chord_system on the built held system (K factorised in hs->S, w = K^-1 u when coupled, b in Tb):
 * A - beta e_sump^T, b - beta T_far, when 1 - e_sump^T A^-1 beta stays above GVS_COUPLING_MARGIN; the maximum
 * principle needs beta <= 0 and a non-negative sump column. held_build leaves the weights to this (they are decided
 * once, for the system with or without the chord) */
static void chord_column(const gvs_tables *tb, held_t *hs, const ttl_chord_t *ch, gvs_real *Tb)
{
    gvs_real x[GVS_MAX_NODES], col[GVS_MAX_NODES], rs[GVS_MAX_NODES];
    int32_t n = tb->n, i, io = tb->i_oil;
    for (i = 0; i < n; ++i) x[i] = ch->beta[i];
    ldl_solve(tb, hs->S, x);                           /* K^-1 beta; e^T A^-1 beta by Sherman-Morrison */
    if (R_(1.0) - (hs->coupled ? x[io] / (R_(1.0) - hs->w[io]) : x[io]) > R_(GVS_COUPLING_MARGIN)) {
        for (i = 0; i < n; ++i) {
            hs->u[i] += ch->beta[i];
            Tb[i] -= ch->beta[i] * ch->T_far;
            hs->w[i] = (hs->coupled ? hs->w[i] : R_(0.0)) + x[i];  /* K^-1 (u + beta) */
            if (ch->beta[i] > R_(0.0)) hs->metzler = 0;
        }
        hs->coupled = 1;
        sump_column(tb, hs, col);
        for (i = 0; i < n; ++i)
            if (i != io && col[i] < R_(0.0)) hs->metzler = 0;
    } else if (hs->coupled && !hs->metzler) {
        sump_column(tb, hs, col);                          /* without the chord: the coupled system's weights */
    }
    hs->weighted = 0;
    if (!hs->metzler) held_weights(tb, hs, col, rs, tb->C_j_per_k);   /* B wt = C (ttl_bound.positive_weights) */
}
#endif

/* the held system at the operating point's sump T_op (time_to_limit.held_system): factorise K, decide the
 * coupling, T_inf = A^-1 b; -1 when there is no finite steady state */
static int held_build(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, const gvs_real *src,
                      const gvs_real *G, const gvs_real *Gs, gvs_real T_op, int measured, held_t *hs,
                      gvs_real *T_inf, const ttl_chord_t *chord)
{
    int32_t n = tb->n, k, i, io = tb->i_oil;
    gvs_real T_oil = chord ? chord->T0 : p->T_oil_c, mcp, dT_in;  /* a part: linearised at its start sump */
    gvs_real w_ls = pump_drive(tb, p->row, p->omega_in_rad_s);
    gvs_real Q_c = chord ? chord->Q0 : p->Q_cool_w;            /* ... its cooler line's heat there */
    mcp = p->rho_cp_j_per_m3k * flow_per_drive(tb) * w_ls;
    hs->G = G;
    hs->held = measured;
#ifndef GVS_NO_TTL_BOUND
    hs->by_row = 0;
    hs->d = R_(0.0);
#endif
    hs->slope = measured ? R_(0.0) : (chord ? chord->slope : cooler_slope(tb, veh, p, T_op));
    hs->coupled = 0;
    for (i = 0; i < n; ++i) hs->u[i] = R_(0.0);
    /* a part's inlet follows its line (held where the line is flat); else the cooler's slope over mdot cp while the
     * drop is inside its clip now and at T_op */
    if (!measured && mcp > R_(0.0)
        && (chord ? chord->inlet != R_(0.0)
                  : hs->slope != R_(0.0) && FABS(p->dT_in_k) < tb->inlet_drop_max_k
                        && FABS((Q_c + hs->slope * (T_op - T_oil)) / mcp) < tb->inlet_drop_max_k)) {
        for (k = 0; k < tb->nst; ++k) {
            gvs_real f = Gs[k] * (chord ? chord->inlet : hs->slope / mcp);
            hs->u[tb->stream_node[k]] -= f;
            hs->u[io] += f;
        }
        hs->coupled = 1;
    }
    /* K, and the coupling's stability: det(K - u e^T) = det(K) (1 - e^T K^-1 u) */
    {
        int coupled = hs->coupled;
        hs->coupled = 0;
        if (held_factor(tb, hs, R_(0.0), R_(1.0)) != 0) return -1;
        if (coupled) {
            for (i = 0; i < n; ++i) hs->w[i] = hs->u[i];
            ldl_solve(tb, hs->S, hs->w);
            if (R_(1.0) - hs->w[io] > R_(GVS_COUPLING_MARGIN)) hs->coupled = 1;
            else for (i = 0; i < n; ++i) hs->u[i] = R_(0.0);
        }
    }
    /* the maximum principle with the coupling: no negative entry in -A's sump column, no positive row sum of -A */
    hs->metzler = 1;
    hs->weighted = 0;
    if (hs->coupled) {
        gvs_real col[GVS_MAX_NODES], rs[GVS_MAX_NODES];
        memset(rs, 0, sizeof rs);                      /* (gcc cannot see that the loop below sets rs[io]) */
        sump_column(tb, hs, col);
        for (i = 0; i < n; ++i) rs[i] = -hs->u[i];
        for (k = 0; k < tb->nl; ++k)
            if (tb->link_b[k] >= n) rs[tb->link_a[k]] += G[k];
        rs[io] += hs->slope;
        for (i = 0; i < n; ++i)
            if ((i != io && col[i] < R_(0.0)) || rs[i] < R_(0.0)) hs->metzler = 0;
        if (!hs->metzler && !chord) held_weights(tb, hs, col, rs, NULL);   /* with a chord: chord_column decides */
    }
    /* b: heat, inlet drop, boundaries, the sump */
    scatter_heat(tb, src, T_inf);
    dT_in = chord ? chord->dT0 : p->dT_in_k;
    if (!hs->coupled && T_op != T_oil && !measured)
        dT_in = clip_r(mcp > R_(0.0) ? (Q_c + hs->slope * (T_op - T_oil)) / mcp : R_(0.0),
                       -tb->inlet_drop_max_k, tb->inlet_drop_max_k);
    for (k = 0; k < tb->nst; ++k) {
        gvs_real f = Gs[k] * dT_in;
        T_inf[tb->stream_node[k]] -= f;
        T_inf[io] += f;
    }
    if (hs->coupled)
        for (i = 0; i < n; ++i) T_inf[i] -= hs->u[i] * T_oil;
    for (k = 0; k < tb->nl; ++k) {
        int32_t a = tb->link_a[k], b = tb->link_b[k];
        if (b >= n) T_inf[a] += G[k] * p->T_bc_c[b - n];
        else if (measured && (a == io || b == io)) T_inf[a == io ? b : a] += G[k] * T_oil;
    }
    if (measured) T_inf[io] = T_oil;
    else T_inf[io] += hs->slope * T_oil - Q_c;
#ifndef GVS_NO_TTL_BOUND
    if (chord) chord_column(tb, hs, chord, T_inf);
#else
    (void)chord;
#endif
    /* T_inf = A^-1 b: the factorised K (w = K^-1 u) with the coupling by Sherman-Morrison */
    held_solve(tb, hs, T_inf);
    for (i = 0; i < n; ++i)
        if (!finite_g(T_inf[i])) return -1;
    return 0;
}

static gvs_real hermite(gvs_real s, gvs_real h, gvs_real f0, gvs_real g0, gvs_real f1, gvs_real g1)
{
    gvs_real s2 = s * s, s3 = s2 * s;
    return (R_(2.0) * s3 - R_(3.0) * s2 + R_(1.0)) * f0 + (s3 - R_(2.0) * s2 + s) * h * g0
        + (R_(3.0) * s2 - R_(2.0) * s3) * f1 + (s3 - s2) * h * g1;
}

static gvs_real first_root(gvs_real h, gvs_real f0, gvs_real g0, gvs_real f1, gvs_real g1)
{
    gvs_real lo = R_(0.0), hi = R_(1.0);
    int j;
    for (j = 1; j <= GVS_HERMITE_SAMPLES; ++j) {
        gvs_real s = (gvs_real)j / (gvs_real)GVS_HERMITE_SAMPLES;
        if (hermite(s, h, f0, g0, f1, g1) >= R_(0.0)) { hi = s; break; }
        lo = s;
    }
    for (j = 0; j < GVS_HERMITE_BISECTIONS; ++j) {
        gvs_real mid = R_(0.5) * (lo + hi);
        if (hermite(mid, h, f0, g0, f1, g1) >= R_(0.0)) hi = mid;
        else lo = mid;
    }
    return hi;
}

/* one term of held_march._bound_scale: max(m, x_i) when Metzler, max(m, |x_i| / wt_i) when weighted (m from 0) */
static gvs_real bound_max(const held_t *hs, const gvs_real *x, int32_t i, gvs_real m)
{
    gvs_real v;
    if (hs->metzler) v = x[i];
    else if (hs->weighted) v = FABS(x[i]) / hs->wt[i];
    else return m;
    return v > m ? v : m;
}

/* held_march._skip_to: no node warms faster than the largest de/dt now (the maximum principle on the derivative;
 * absolute: the largest |de/dt|, rows diagonally dominant), so no open row crosses before min gap / rate: the first
 * step ends at the last grid point before that or t_cap (an event's earliest time), before t_end (*t_skip, *h the
 * step after it). Nothing warming now closes every row; NaN: no skip unless capped. Returns whether a row is open. */
static int skip_to(const gvs_tables *tb, const gvs_real *T0, const gvs_real *de, const held_t *hs, int8_t *open,
                   march_t *t_skip, march_t *h, march_t ratio, march_t t_cap, march_t t_end)
{
    gvs_real rate = hs->metzler ? de[0] : FABS(de[0]) / hs->wt[0];
    march_t t_min = t_cap;
    int32_t i, j;
    int any = 0;
    for (i = 1; i < tb->n; ++i) {
        gvs_real x = hs->metzler ? de[i] : FABS(de[i]) / hs->wt[i];
        if (x > rate || x != x) rate = x;
    }
    if (rate <= R_(0.0))
        for (j = 0; j < tb->n_pub; ++j) open[j] = 0;
    for (j = 0; j < tb->n_pub; ++j)
        if (open[j]) {
            int32_t r = tb->published_index[j];
            march_t tj = (march_t)(tb->warning_c[j] - T0[r])
                / ((march_t)rate * (hs->metzler ? M_(1.0) : (march_t)hs->wt[r]));
            if (tj < t_min) t_min = tj;
            any = 1;
        }
    if (!(rate > R_(0.0)) && !(t_cap < (march_t)INFINITY)) return any;
    while (*t_skip + *h <= t_min && *t_skip + *h < t_end) {
        *t_skip += *h;
        *h *= ratio;
    }
    return any;
}

#ifndef GVS_NO_TTL_BOUND
/* held_march._bound_scale: no node of the solution x exceeds it (times wt) later */
static gvs_real scale_of(const gvs_tables *tb, const held_t *hs, const gvs_real *x)
{
    gvs_real m = R_(0.0);
    int32_t i;
    for (i = 0; i < tb->n; ++i) m = bound_max(hs, x, i, m);
    return m;
}
#endif

/* the loss sources' heat with the point's load at sump T [W] (ttl_bound.loss_heat_w; the re-linearised march's) */
static void point_heat(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real T, gvs_real *src)
{
    gvs_real w = p->omega_in_rad_s;
    oil_row_t o;
    oil_row(tb, T, &o, NULL);
    heat_sources(tb, veh, p->row, w, FABS(p->used[GVS_I_TORQUE]), &o,
                 retarder_heat_w(tb, veh, p->row, w, p->used[GVS_I_RET]), src);
}

/* the conductances of the bin of the point's speed and sump T */
static void point_conductances(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real T,
                               gvs_real *G, gvs_real *Gs)
{
    bin_conductances(tb, veh, p->row, speed_bin_centre(tb, p->omega_in_rad_s), RINT(T / tb->oil_bin_c) * tb->oil_bin_c,
                     G, Gs);
}

/* one held-input solution (time_to_limit._solve + held_march.march_time_to_limit): ttl[GVS_MAX_PUB]; *T_watch the sump at
 * the first crossing of a re-linearising component (NaN: none). A part of the bounded method's path (chord) may start
 * from another state and time, skip the components an earlier part decided, and stop where the sump reaches T_ev
 * (held_march's event: the state then in chord->T_at) */
static int ttl_solve(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, const gvs_real *src,
                     const gvs_real *G, const gvs_real *Gs, gvs_real T_op, int measured, gvs_real *ttl,
                     gvs_real *T_watch, ttl_chord_t *chord)
{
    held_t hs;
    gvs_real T_inf[GVS_MAX_NODES], e[GVS_MAX_NODES], de[GVS_MAX_NODES], e_g[GVS_MAX_NODES], e_new[GVS_MAX_NODES];
    gvs_real de_new[GVS_MAX_NODES], Ae[GVS_MAX_NODES], energy = R_(0.0), energy_new, e_max = R_(0.0), bnd;
    const gvs_real *C = tb->C_j_per_k, *T0 = p->T_main_c;
    int8_t open[GVS_MAX_PUB];
    int32_t n = tb->n, i, j, any = 0, io = tb->i_oil;
    march_t t = M_(0.0), h = M_(GVS_MARCH_H0_S), t_skip = M_(0.0), t0 = M_(0.0), t_end = M_(GVS_TTL_HORIZON_S);
#ifndef GVS_NO_TTL_BOUND
    const march_t ratio = chord ? M_(GVS_TTL_BOUND_RATIO) : M_(GVS_MARCH_RATIO);   /* the parts' grid */
    int ev = 0;
    gvs_real w_ev = R_(1.0), T_ev = (gvs_real)NAN;
#else
    const march_t ratio = M_(GVS_MARCH_RATIO);
#endif
    *T_watch = (gvs_real)NAN;
    for (j = 0; j < tb->n_pub; ++j) ttl[j] = (gvs_real)NAN;
    memset(e, 0, sizeof e);
    memset(de, 0, sizeof de);
    if (held_build(tb, veh, p, src, G, Gs, T_op, measured, &hs, T_inf, chord) != 0) return -1;
#ifndef GVS_NO_TTL_BOUND
    hs.by_row = chord != NULL && tb->ldl_perm[n - 1] == io;  /* the chord systems' march: Sherman-Morrison by row */
    if (chord) {
        if (chord->T_start) T0 = chord->T_start;
        t0 = chord->t0;
        t_end = M_(GVS_TTL_HORIZON_S) - t0;
        T_ev = chord->T_ev;
        chord->t_ev = (march_t)NAN;
    }
#endif
    for (i = 0; i < n; ++i) e[i] = T0[i] - T_inf[i];
    if (measured) e[io] = R_(0.0);
    held_apply(tb, &hs, e, Ae);
    for (i = 0; i < n; ++i) {
        de[i] = -Ae[i] / C[i];
        energy += C[i] * e[i] * e[i];
        e_max = bound_max(&hs, e, i, e_max);
    }
    bnd = e_max;                                    /* held_march._bound_scale (when metzler or weighted) */
    for (j = 0; j < tb->n_pub; ++j) {
        int32_t r = tb->published_index[j];
        gvs_real lim = tb->warning_c[j];
        open[j] = 0;
#ifndef GVS_NO_TTL_BOUND
        if (chord && chord->done && chord->done[j] < (gvs_real)INFINITY) {
            ttl[j] = (gvs_real)INFINITY;            /* decided by an earlier part */
            continue;
        }
#endif
        if (measured && r == io) {
            ttl[j] = p->T_oil_c >= lim ? R_(0.0) : (gvs_real)INFINITY;
            continue;
        }
        ttl[j] = T0[r] >= lim ? (gvs_real)(CEIL(t0 / M_(GVS_TTL_QUANTUM_S)) * M_(GVS_TTL_QUANTUM_S))
                              : (gvs_real)INFINITY;
        open[j] = T0[r] < lim
            && (!(hs.metzler || hs.weighted) || T_inf[r] + bnd * (hs.metzler ? R_(1.0) : hs.wt[r]) >= lim)
            && (hs.coupled || T_inf[r] + SQRT(energy / C[r]) >= lim);
        any |= open[j];
    }
#ifndef GVS_NO_TTL_BOUND
    if (T_ev == T_ev) {                              /* the sump rises to T_ev: open while the bounds allow it */
        if (!hs.metzler && hs.weighted) w_ev = hs.wt[io];
        ev = T0[io] < T_ev;
        if (ev && (hs.metzler || hs.weighted)) ev = T_inf[io] + bnd * w_ev >= T_ev;
    }
    if ((hs.metzler || hs.weighted) && (any || ev)) {
        march_t t_cap = (march_t)INFINITY;
        if (ev) {
            gvs_real rate_ev = scale_of(tb, &hs, de);
            ev = !(rate_ev <= R_(0.0));
            if (ev && rate_ev > R_(0.0)) t_cap = (march_t)(T_ev - T0[io]) / ((march_t)rate_ev * (march_t)w_ev);
        }
        any = skip_to(tb, T0, de, &hs, open, &t_skip, &h, ratio, t_cap, t_end);
    }
    while ((any || ev) && t < t_end) {
#else
    if (any && (hs.metzler || hs.weighted))
        any = skip_to(tb, T0, de, &hs, open, &t_skip, &h, ratio, (march_t)INFINITY, t_end);
    while (any && t < t_end) {
#endif
        march_t h_step = t_skip > M_(0.0) ? t_skip : (h < t_end - t ? h : t_end - t);
        gvs_real d = (gvs_real)(M_(GVS_MARCH_D_FRAC) * h_step), s_watch = R_(2.0), s_ev = R_(2.0);
        if (held_factor(tb, &hs, R_(1.0), d) != 0) return -1;
        for (i = 0; i < n; ++i) e_g[i] = C[i] * e[i] - d * Ae[i];
        held_solve(tb, &hs, e_g);
        for (i = 0; i < n; ++i) e_new[i] = C[i] * (R_(GVS_MARCH_A1) * e_g[i] - R_(GVS_MARCH_A0) * e[i]);
        held_solve(tb, &hs, e_new);
        held_apply(tb, &hs, e_new, Ae);
        energy_new = R_(0.0);
        e_max = R_(0.0);
        for (i = 0; i < n; ++i) {
            de_new[i] = -Ae[i] / C[i];
            energy_new += C[i] * e_new[i] * e_new[i];
            e_max = bound_max(&hs, e_new, i, e_max);
        }
#ifndef GVS_NO_TTL_BOUND
        if (ev && T_inf[io] + e_new[io] >= T_ev)
            s_ev = first_root((gvs_real)h_step, T_inf[io] + e[io] - T_ev, de[io], T_inf[io] + e_new[io] - T_ev,
                              de_new[io]);
#endif
        any = 0;
        for (j = 0; j < tb->n_pub; ++j) {
            int32_t r = tb->published_index[j];
            gvs_real lim = tb->warning_c[j], f1;
            if (!open[j]) continue;
            f1 = T_inf[r] + e_new[r] - lim;
            if (f1 >= R_(0.0)) {
                gvs_real s = first_root((gvs_real)h_step, T_inf[r] + e[r] - lim, de[r], f1, de_new[r]);
                march_t tc;
                if (s > s_ev) {                     /* after the event: the next part decides */
                    any = 1;
                    continue;
                }
                tc = CEIL((t0 + t + (march_t)s * h_step) / M_(GVS_TTL_QUANTUM_S)) * M_(GVS_TTL_QUANTUM_S);
                ttl[j] = (gvs_real)(tc < M_(GVS_TTL_HORIZON_S) ? tc : M_(GVS_TTL_HORIZON_S));
                open[j] = 0;
                if (tb->ttl_relin[j] && s < s_watch) s_watch = s;
                continue;
            }
            if ((hs.metzler || hs.weighted) && T_inf[r] + e_max * (hs.metzler ? R_(1.0) : hs.wt[r]) < lim)
                open[j] = 0;
            if ((!hs.coupled || energy_new <= energy) && T_inf[r] + SQRT(energy_new / C[r]) < lim) open[j] = 0;
            any |= open[j];
        }
        if (s_watch <= R_(1.0) && *T_watch != *T_watch && !measured)
            *T_watch = T_inf[io] + hermite(s_watch, (gvs_real)h_step, e[io], de[io], e_new[io], de_new[io]);
#ifndef GVS_NO_TTL_BOUND
        if (s_ev <= R_(1.0)) {                      /* the event: the state then, the march stops */
            chord->t_ev = t0 + t + (march_t)s_ev * h_step;
            for (i = 0; i < n; ++i)
                chord->T_at[i] = T_inf[i] + hermite(s_ev, (gvs_real)h_step, e[i], de[i], e_new[i], de_new[i]);
            return 0;
        }
        if (ev && (hs.metzler || hs.weighted) && !(T_inf[io] + e_max * w_ev >= T_ev)) ev = 0;
#endif
        copy_r(e, e_new, n);
        copy_r(de, de_new, n);
        energy = energy_new;
        t += h_step;
        if (t_skip > M_(0.0)) t_skip = M_(0.0);     /* the skip was the grid's steps up to t_skip */
        else h *= ratio;
    }
    return 0;
}

#ifndef GVS_NO_TTL_BOUND /* an export whose tables use today's march leaves the bounded method out (flash) */
/* ttl_bound.cooler_heat_w: the cooler's heat with the point's inputs at sump T, net of the heater's [W] */
static gvs_real bound_cooler_heat(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real T)
{
    cooler_op_t op;
    return (point_cooler(tb, veh, p, &op) ? cooler_heat(tb, veh, &op, T) : R_(0.0)) - heater_heat(tb, T);
}

/* the oil system's m cp at the point [W/K] (ttl_bound's, in its order of products) */
static gvs_real bound_mcp(const gvs_tables *tb, const gvs_ttl_point *p)
{
    return tb->pump_code == GVS_PUMP_MOTOR
        ? p->rho_cp_j_per_m3k * (tb->pump_flow_m3_s * pump_drive(tb, p->row, p->omega_in_rad_s))
        : p->rho_cp_j_per_m3k * tb->flow_m3_per_rad * shaft_speed(tb, p->row, tb->pump_speed_col, R_(1.0))
            * p->omega_in_rad_s;
}

GVS_OUTLINE static gvs_real bound_clip(const gvs_tables *tb, gvs_real T)
{
    return clip_r(T, tb->T_grid0_c, tb->T_grid0_c + tb->T_grid_step_k * (gvs_real)(tb->nT - 1));
}

static int ttl_refresh(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real *ttl_s,
                       int bound);

/* a crossing within GVS_TTL_BOUND_GATE_S: today's march too, the earlier of the two (no warning later than today's) */
static void bound_gate(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real *ttl_s)
{
    gvs_real today[GVS_MAX_PUB];
    int j;
    for (j = 0; j < tb->n_pub && !(ttl_s[j] <= R_(GVS_TTL_BOUND_GATE_S)); ++j) {}
    if (j == tb->n_pub) return;
    ttl_refresh(tb, veh, p, today, 0);
    for (j = 0; j < tb->n_pub; ++j)
        if (today[j] < ttl_s[j]) ttl_s[j] = today[j];
}

#define SEG_N (GVS_TTL_SEG_SAMPLES + 1)  /* a sampled stretch of the path: SEG_N + 1 sumps, both ends included */

/* ttl_bound.Curves.at: the cooler's heat [W] and the clipped inlet drop [K] at sump T (the step's own at its sump) */
static void seg_curve(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real mcp, gvs_real T,
                      gvs_real *Q, gvs_real *d)
{
    if (T == p->T_oil_c) {
        *Q = p->Q_cool_w;
        *d = p->dT_in_k;
        return;
    }
    *Q = bound_cooler_heat(tb, veh, p, T);
    *d = mcp > R_(0.0) ? clip_r(*Q / mcp, -tb->inlet_drop_max_k, tb->inlet_drop_max_k) : R_(0.0);
}

/* T_a, SEG_N - 1 sumps evenly between and T_b, with the curves there */
static void seg_samples(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real mcp,
                        gvs_real T_a, gvs_real T_b, gvs_real *Tg, gvs_real *Qg, gvs_real *dg)
{
    int k;
    for (k = 0; k <= SEG_N; ++k) {
        Tg[k] = k < SEG_N ? T_a + (T_b - T_a) * ((gvs_real)k / (gvs_real)SEG_N) : T_b;
        seg_curve(tb, veh, p, mcp, Tg[k], &Qg[k], &dg[k]);
    }
}

/* ttl_bound.part_lines over samples a..b: sl = {cooler slope, its heat at Tg[a], drop slope, the drop at Tg[a]} */
static void seg_lines(const gvs_real *Tg, const gvs_real *Qg, const gvs_real *dg, int a, int b, gvs_real *sl)
{
    int i, k;
    for (i = 0; i < 2; ++i) {
        const gvs_real *f = i ? dg : Qg;
        gvs_real slope = (gvs_real)NAN;
        for (k = a; k < b; ++k) {
            gvs_real sec = (f[k] - f[b]) / (Tg[k] - Tg[b]);
            if (slope != slope || (Tg[k] < Tg[b] ? sec > slope : sec < slope)) slope = sec;   /* under the curve */
        }
        sl[2 * i] = slope;
        sl[2 * i + 1] = f[b] + slope * (Tg[a] - Tg[b]);
    }
}

/* ttl_bound.part_gap_w: how far the lines of samples a..b lie under the curves, at most [W] */
static gvs_real seg_gap(const gvs_real *Tg, const gvs_real *Qg, const gvs_real *dg, gvs_real mcp, int a, int b)
{
    gvs_real sl[4], gap = R_(0.0);
    int k;
    seg_lines(Tg, Qg, dg, a, b, sl);
    for (k = a; k < b; ++k) {
        gvs_real x = Tg[k] - Tg[a], v = (Qg[k] - sl[1] - sl[0] * x) + mcp * (dg[k] - sl[3] - sl[2] * x);
        if (v > gap) gap = v;
    }
    return gap;
}

/* ttl_bound.far_sump_c: T where the steady sump of the system with the losses, the cooler's heat and the inlet drop
 * at T is T (the step's conductances): K factorised once, every trial's steady sump r.b with r = K^-1 e_sump; the
 * Illinois method in the bracket [T0, S(T0)] (within the oil tables). NaN: no finite steady state */
static gvs_real seg_far_sump(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real mcp)
{
    held_t hs;
    gvs_real r[GVS_MAX_NODES], rw[GVS_MAX_SRC], src[GVS_MAX_SRC], x[2] = {0}, g[2] = {0}, c = R_(0.0), gc;
    gvs_real rb = R_(0.0), ru = R_(0.0);
    int32_t n = tb->n, i, k, it, io = tb->i_oil;
    hs.G = p->G_w_per_k;
    hs.slope = R_(0.0);
    hs.held = 0;
    hs.coupled = 0;
    hs.by_row = 0;
    if (held_factor(tb, &hs, R_(0.0), R_(1.0)) != 0) return (gvs_real)NAN;
    for (i = 0; i < n; ++i) r[i] = i == io ? R_(1.0) : R_(0.0);
    ldl_solve(tb, hs.S, r);
    for (k = 0; k < tb->nst; ++k) ru += p->G_streams_w_per_k[k] * (r[io] - r[tb->stream_node[k]]);
    for (k = 0; k < tb->nl; ++k)
        if (tb->link_b[k] >= n) rb += p->G_w_per_k[k] * p->T_bc_c[tb->link_b[k] - n] * r[tb->link_a[k]];
    for (i = 0; i < tb->ns; ++i) rw[i] = R_(0.0);         /* r.q = rw.src: the sources' weights on r */
    for (k = 0; k < tb->nsrc_nz; ++k) rw[tb->src_nz_src[k]] += tb->src_nz_w[k] * r[tb->src_nz_node[k]];
    for (it = -2; it < GVS_TTL_FAR_ITERS; ++it) {
        gvs_real T = it == -2 ? p->T_oil_c : it == -1 ? x[1] : c, Q, d, S = rb;
        if (it >= 0 && !(FABS(x[1] - x[0]) >= R_(GVS_TTL_FAR_TOL_K))) break;
        seg_curve(tb, veh, p, mcp, T, &Q, &d);
        if (T == p->T_oil_c) copy_r(src, p->src_w, tb->ns);
        else point_heat(tb, veh, p, T, src);
        for (i = 0; i < tb->ns; ++i) S += rw[i] * src[i];
        gc = S + ru * d - r[io] * Q - T;                    /* S(T) - T */
        if (!finite_g(gc)) return (gvs_real)NAN;
        if (it == -2) {
            x[0] = T;
            g[0] = gc;
            x[1] = bound_clip(tb, T + gc);
            if (x[1] == T) return T;
            continue;
        }
        if (it == -1) {
            g[1] = gc;
            if (g[1] * g[0] > R_(0.0)) return x[1];         /* beyond the oil tables, or no sign change */
        } else {
            if (!(FABS(gc) >= R_(GVS_TTL_FAR_TOL_K))) return c;
            if (gc * g[1] < R_(0.0)) {
                x[0] = x[1];
                g[0] = g[1];
            } else {
                g[0] *= R_(0.5);
            }
            x[1] = c;
            g[1] = gc;
        }
        c = x[1] - g[1] * (x[1] - x[0]) / (g[1] - g[0]);
    }
    return x[1];
}

/* ttl_bound.march_segments: part j's system from Tc[j] to Tc[j + 1] (the losses' chord, the lines under the curves
 * at SEG_N + 1 sumps inside it, the conductances at its start: the step's in the first), marched from the state where
 * the sump reached Tc[j]; acc the first crossings; -1: a part has no finite steady state */
static int seg_chain(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real mcp,
                     const gvs_real *Tc, int parts, gvs_real (*srcs)[GVS_MAX_SRC], gvs_real *acc)
{
    ttl_chord_t ch;
    gvs_real part[GVS_MAX_PUB], T_at[GVS_MAX_NODES], G[GVS_MAX_LINKS], Gs[GVS_MAX_STREAMS], qb[GVS_MAX_NODES];
    gvs_real Tf[SEG_N + 1], Qf[SEG_N + 1], df[SEG_N + 1], sl[4], T_watch;
    int j, i;
    ch.t0 = M_(0.0);
    for (j = 0; j < parts; ++j) {
        seg_samples(tb, veh, p, mcp, Tc[j], Tc[j + 1], Tf, Qf, df);
        seg_lines(Tf, Qf, df, 0, SEG_N, sl);
        ch.slope = sl[0] < R_(0.0) ? R_(0.0) : sl[0];
        ch.Q0 = sl[1];
        ch.inlet = sl[2];
        ch.dT0 = sl[3];
        ch.T0 = Tc[j];
        ch.T_far = Tc[j + 1];
        scatter_heat(tb, srcs[j], ch.beta);
        scatter_heat(tb, srcs[j + 1], qb);
        for (i = 0; i < tb->n; ++i) ch.beta[i] = (ch.beta[i] - qb[i]) / (Tc[j] - Tc[j + 1]);
        if (j) point_conductances(tb, veh, p, Tc[j], G, Gs);
        ch.T_start = j ? T_at : NULL;
        ch.done = j ? acc : NULL;
        ch.T_ev = j + 1 < parts ? Tc[j + 1] : (gvs_real)NAN;
        ch.T_at = T_at;
        if (ttl_solve(tb, veh, p, srcs[j + 1], j ? G : p->G_w_per_k, j ? Gs : p->G_streams_w_per_k, Tc[j], 0,
                      j ? part : acc, &T_watch, &ch) != 0)
            return -1;
        if (j)
            for (i = 0; i < tb->n_pub; ++i)
                if (!(acc[i] < (gvs_real)INFINITY)) acc[i] = part[i];
        if (ch.t_ev != ch.t_ev) break;
        ch.t0 = ch.t_ev;
    }
    return 0;
}

/* the bounded time to limit (ttl_bound.time_to_limit_bound): the sump's path from T0 to the far sump cut into at most
 * GVS_TTL_SEG_MAX parts (ttl_bound.cut_path), marched part by part with the conductances at each part's start and at
 * its end, the earlier kept; the step's own system when the sump is settled, held or the far sump is not found */
static int ttl_refresh_bound(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real *ttl_s)
{
    gvs_real T_watch, srcs[GVS_TTL_SEG_MAX + 1][GVS_MAX_SRC], Tg[SEG_N + 1], Qg[SEG_N + 1];
    gvs_real dg[SEG_N + 1], Tc[GVS_TTL_SEG_MAX + 1], gt[SEG_N + 1][SEG_N + 1], mcp = bound_mcp(tb, p), T_far, best;
    int measured = p->measured && !tb->ttl_sump_model, cuts[GVS_TTL_SEG_MAX + 1], nc = 2, j, k, m;
    if (measured || !tb->ttl_relinearise || !(FABS((T_far = seg_far_sump(tb, veh, p, mcp)) - p->T_oil_c)
                                              >= R_(GVS_TTL_BOUND_TOL_K))) {
        ttl_solve(tb, veh, p, p->src_w, p->G_w_per_k, p->G_streams_w_per_k, p->T_oil_c, measured, ttl_s, &T_watch,
                  NULL);
        bound_gate(tb, veh, p, ttl_s);
        return GVS_OK;
    }
    seg_samples(tb, veh, p, mcp, p->T_oil_c, T_far, Tg, Qg, dg);
    /* ttl_bound.cut_path: the fewest parts whose lines lie within GVS_TTL_SEG_GAP_W of the curves, else
     * GVS_TTL_SEG_MAX (3) parts with the least worst gap, every choice of cuts tried in order, the first within
     * GVS_TTL_SEG_TIE_W of the least taken */
    /* each part's gap computed when the search first asks for it (most paths are one part: one gap, not 153) */
    for (j = 0; j < SEG_N; ++j)
        for (k = j + 1; k <= SEG_N; ++k) gt[j][k] = (gvs_real)NAN;
#define GAP(a, b) (gt[a][b] == gt[a][b] ? gt[a][b] : (gt[a][b] = seg_gap(Tg, Qg, dg, mcp, a, b)))
    cuts[0] = 0;
    cuts[1] = SEG_N;
    best = GAP(0, SEG_N);
    for (m = 1; m < GVS_TTL_SEG_MAX && best > R_(GVS_TTL_SEG_GAP_W) && T_far > p->T_oil_c; ++m) {
        gvs_real least = (gvs_real)INFINITY;
        int pass, found = 0;
        for (pass = 0; pass < 2 && !found; ++pass)     /* the least worst gap, then the first within the tie */
            for (j = 1; j < SEG_N && !found; ++j)
                for (k = m == 1 ? SEG_N : j + 1; k <= SEG_N - (m == 1 ? 0 : 1) && !found; ++k) {
                    gvs_real w = GAP(0, j), x = GAP(j, k);
                    if (x > w) w = x;
                    if (m > 1 && GAP(k, SEG_N) > w) w = GAP(k, SEG_N);
                    if (!pass) {
                        if (w < least) least = w;
                    } else if (w <= least + R_(GVS_TTL_SEG_TIE_W)) {
                        found = 1;
                        best = w;
                        cuts[1] = j;
                        cuts[2] = k;
                    }
                }
        if (!found) break;
        nc = m + 2;
        if (m == 1) cuts[2] = SEG_N;
        else cuts[3] = SEG_N;
    }
#undef GAP
    for (j = 0; j < nc; ++j) {
        Tc[j] = Tg[cuts[j]];
        if (j) point_heat(tb, veh, p, Tc[j], srcs[j]);
        else copy_r(srcs[0], p->src_w, tb->ns);
    }
    if (seg_chain(tb, veh, p, mcp, Tc, nc - 1, srcs, ttl_s) != 0)
        for (j = 0; j < tb->n_pub; ++j) ttl_s[j] = (gvs_real)NAN;
    bound_gate(tb, veh, p, ttl_s);
    return GVS_OK;
}

#endif /* GVS_NO_TTL_BOUND */

static int ttl_refresh(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real *ttl_s, int bound)
{
    gvs_real T_watch, T_op = p->T_oil_c, src[GVS_MAX_SRC], G[GVS_MAX_LINKS], Gs[GVS_MAX_STREAMS];
    int measured = p->measured && !tb->ttl_sump_model, it;
    if (gvs_check_tables(tb) != GVS_OK) return GVS_BAD_TABLES;
    if (tb->ldl_nnz <= 0) {                       /* a build without the time to limit's tables: not available */
        for (it = 0; it < tb->n_pub; ++it) ttl_s[it] = (gvs_real)NAN;
        return GVS_OK;
    }
#ifndef GVS_NO_TTL_BOUND
    if (bound) return ttl_refresh_bound(tb, veh, p, ttl_s);
#else
    (void)bound;
#endif
    if (ttl_solve(tb, veh, p, p->src_w, p->G_w_per_k, p->G_streams_w_per_k, T_op, measured, ttl_s, &T_watch, NULL) != 0
        || !tb->ttl_sump_model || !tb->ttl_relinearise)
        return GVS_OK;
    for (it = 0; it < GVS_TTL_RELINEARISE_STEPS; ++it) {
        if (T_watch != T_watch || FABS(T_watch - T_op) < R_(GVS_TTL_RELINEARISE_TOL_K)) break;
        T_op = T_watch;
        point_heat(tb, veh, p, T_op, src);
        point_conductances(tb, veh, p, T_op, G, Gs);
        if (ttl_solve(tb, veh, p, src, G, Gs, T_op, measured, ttl_s, &T_watch, NULL) != 0) break;
    }
    return GVS_OK;
}

int gvs_ttl_refresh(const gvs_tables *tb, const gvs_vehicle *veh, const gvs_ttl_point *p, gvs_real *ttl_s)
{
    return ttl_refresh(tb, veh, p, ttl_s, tb->ttl_bound);
}

/* ---- the step (step.step_deferred; step._finish) ------------------------------------------------------------- */
int gvs_step(const gvs_tables *tb, const gvs_vehicle *veh, gvs_state *st, const gvs_inputs *in, int jump_done,
             gvs_outputs *out, gvs_ttl_point *ttl)
{
    int64_t counts[GVS_N_REJECT];
    gvs_real T_pub[GVS_MAX_PUB], ttl_now[GVS_MAX_PUB], ttl_lead[GVS_MAX_PUB];
    int64_t k = st->k;
    int32_t since;                  /* steps since the last refresh, at most ttl_every: a float from an int32 (an
                                     * int64's conversion is soft-float code on an M4F) */
    int i, in_hold, available, any = 0, due, fresh;
    check_t c;
    net_t nt;
    if (ttl) ttl->due = 0;
    if (gvs_check_tables(tb) != GVS_OK) return GVS_BAD_TABLES;
    memset(counts, 0, sizeof counts);
    if (finite_d(in->t_s)) {
        double gap = in->t_s - st->t_last_s;
        if (finite_d(gap)) {
            /* back by more than clock_reset_s: the clock was reset (a glitch, a restored state, an uptime
             * counter); its time is the new time base and this is one step (step.step_deferred) */
            int64_t kg = d_key(gap);
            if (kg < d_key(-(double)tb->clock_reset_s)) counts[GVS_RJ_TIME_BACKWARD] = 1;
            else if (kg < d_key(0.5 * (double)tb->dt_s)) return skip_step(tb, st, out);
            else if (kg > d_key(1.5 * (double)tb->dt_s)) {
                if (!jump_done) return GVS_NEED_JUMP;
                counts[GVS_RJ_TIME_JUMP] = 1;
                /* the inputs age by the gap (held_inputs.jump_state): a value from before it is no recent one */
                for (i = 0; i < GVS_N_INPUTS; ++i) st->age_s[i] += (gvs_real)(gap - (double)tb->dt_s);
                /* entered with the engine turning, the gap was an outage of the drive inputs: the levels wait as
                 * long as it went past the hold, at most GVS_RECOVER_MAX_S (step.jump_recover_s) */
                if (st->hold[GVS_I_SPEED] > R_(0.0)) {
                    gvs_real past = (gvs_real)(gap - (double)tb->dt_s) - tb->hold_s;
                    if (past > R_(0.0)) st->recover_s = min_r(st->recover_s + past, R_(GVS_RECOVER_MAX_S));
                }
            }
        }
    }
    check_inputs(tb, st, in->raw, counts, &c);
    network_step(tb, veh, st, &c, in->raw[GVS_I_OIL], &nt);
    /* published temperatures, warnings, the time to limit counted down */
    for (i = 0; i < tb->n_pub; ++i) T_pub[i] = st->T_c[GVS_MAIN][tb->published_index[i]];
    /* drive inputs missing past the hold: levels not available, and for as long again (at most GVS_RECOVER_MAX_S)
     * once they are back: the parts' temperatures still rest on the outage's held inputs (step._finish) */
    in_hold = c.drive_age_s <= tb->hold_s;
    available = in_hold && !(st->recover_s > R_(0.5) * tb->dt_s);
    st->recover_s = in_hold ? max_r(st->recover_s - tb->dt_s, R_(0.0))
                            : min_r(st->recover_s + tb->dt_s, R_(GVS_RECOVER_MAX_S));
    since = k == 0 ? 0 : (int32_t)(steps_mod(k - 1, tb->ttl_every) + 1);
    /* the early warning judges only a time to limit refreshed at most GVS_TTL_FRESH_S ago; an older one neither
     * raises nor holds one: it reads as "never" (step._finish) */
    fresh = (gvs_real)since * tb->dt_s <= R_(GVS_TTL_FRESH_S) + R_(0.5) * tb->dt_s;
    for (i = 0; i < tb->n_pub; ++i) {
        gvs_real t = st->ttl_s[i] - (gvs_real)since * tb->dt_s;
        ttl_now[i] = t != t ? t : max_r(t, R_(0.0));
        ttl_lead[i] = fresh ? ttl_now[i] : (gvs_real)INFINITY;
    }
    update_levels(tb, st, T_pub, available, ttl_lead);
    for (i = 0; i < tb->n_pub; ++i) any |= st->level[i] != GVS_LEVEL_NORMAL || T_pub[i] >= tb->warning_c[i];
    for (i = 0; i < tb->n_pub; ++i) {
        out->T_c[i] = T_pub[i];
        out->level[i] = st->level[i];
        if (any && st->level[i] == GVS_LEVEL_NA) out->ttl_s[i] = (gvs_real)NAN;
        else if (any && T_pub[i] >= tb->warning_c[i]) out->ttl_s[i] = R_(0.0);
        else out->ttl_s[i] = ttl_now[i];
    }
    /* status and degraded mode */
    out->degraded_mode = (int8_t)(c.drive_ok ? (c.measured ? GVS_MODE_NORMAL : GVS_MODE_OIL_MODEL) : GVS_MODE_HOLDING);
    out->speed_valid = (int8_t)c.ok[GVS_I_SPEED];
    out->torque_valid = (int8_t)c.ok[GVS_I_TORQUE];
    out->gear_valid = (int8_t)c.ok[GVS_I_GEAR];
    out->oil_valid = (int8_t)c.ok[GVS_I_OIL];
    out->valid_flags = 0;
    for (i = 0; i < GVS_N_INPUTS; ++i) out->valid_flags |= c.ok[i] ? (1 << i) : 0;
    out->frozen_flags = (c.drive_frozen ? (1 << GVS_I_SPEED) | (1 << GVS_I_TORQUE) : 0)
        | (c.oil_frozen ? (1 << GVS_I_OIL) : 0);
    out->model_oil_temp_c = st->T_c[GVS_TWIN][tb->i_oil];
    out->oil_innovation_c = c.ok[GVS_I_OIL] ? (gvs_real)(in->raw[GVS_I_OIL]) - out->model_oil_temp_c : (gvs_real)NAN;
    /* a forced oil system's inlet: the main copy's sump the step took minus the drop it gave the jets' streams */
    out->oil_inlet_temp_c = tb->oil_inlet ? nt.T_oil_main - nt.dT_in[GVS_MAIN] : (gvs_real)NAN;
    out->oil_source = (int8_t)!c.measured;
    for (i = 0; i < GVS_N_REJECT; ++i) st->rejects[i] += counts[i];
    copy_rejects(out->rejects, st->rejects);
    /* no frame time (NaN): the step was on the 0.1 s grid, the last time moves on with it (NaN stays NaN) */
    st->t_last_s = finite_d(in->t_s) ? in->t_s : st->t_last_s + (double)tb->dt_s;
    due = steps_mod(k, tb->ttl_every) == 0;
    if (due && ttl) ttl_point(tb, st, &c, &nt, ttl);
    st->k = k + 1;
    return GVS_OK;
}

int64_t gvs_run(const gvs_tables *tb, const gvs_vehicle *veh, gvs_state *st, const gvs_inputs *in, int64_t n_steps,
                int stop_on_ttl, const int8_t *keep, gvs_outputs *out, gvs_ttl_point *ttl, int *status)
{
    gvs_outputs scratch;            /* the outputs of a step not kept */
    int64_t j;
    int rc = GVS_OK;
    for (j = 0; j < n_steps; ++j) {
        gvs_outputs *o = (keep && !keep[j]) ? &scratch : out;
        rc = gvs_step(tb, veh, st, in + j, 0, o, ttl);
        if (rc == GVS_NEED_JUMP || rc == GVS_BAD_TABLES) break;
        if (o == out) ++out;
        if (ttl && ttl->due) {
            if (stop_on_ttl) { ++j; break; }
            gvs_ttl_refresh(tb, veh, ttl, st->ttl_s);
            ttl->due = 0;
        }
    }
    if (status) *status = rc;
    return j;
}

int gvs_step_batch(const gvs_tables *tb, const gvs_vehicle *veh, int64_t veh_stride, int64_t n_vehicles,
                   gvs_state *st, const gvs_inputs *in, const int8_t *jump_done, gvs_outputs *out,
                   gvs_ttl_point *ttl, int32_t *codes)
{
    int64_t v;
    int worst = GVS_OK;
    for (v = 0; v < n_vehicles; ++v) {
        int rc = gvs_step(tb, veh + v * veh_stride, st + v, in + v, jump_done ? jump_done[v] : 0, out + v,
                          ttl ? ttl + v : NULL);
        if (codes) codes[v] = rc;
        if (rc != GVS_OK && (worst == GVS_OK || rc < 0)) worst = rc;
    }
    return worst;
}

int64_t gvs_sizeof(int which)
{
    switch (which) {
    case GVS_SIZEOF_TABLES: return (int64_t)sizeof(gvs_tables);
    case GVS_SIZEOF_VEHICLE: return (int64_t)sizeof(gvs_vehicle);
    case GVS_SIZEOF_STATE: return (int64_t)sizeof(gvs_state);
    case GVS_SIZEOF_INPUTS: return (int64_t)sizeof(gvs_inputs);
    case GVS_SIZEOF_OUTPUTS: return (int64_t)sizeof(gvs_outputs);
    case GVS_SIZEOF_TTL_POINT: return (int64_t)sizeof(gvs_ttl_point);
    case GVS_SIZEOF_REAL: return (int64_t)sizeof(gvs_real);
    default: return -1;
    }
}
