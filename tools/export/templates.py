"""Text of the files `export-c` writes besides the kernel and the generated tables (tools.export.c_bundle)."""

API_HEADER = """/* gearbox-vsensor: the onboard virtual temperature sensor of a {variant} gearbox, exported for an ECU build
 * ({real} build). See README.md. */
#ifndef GVS_SENSOR_H
#define GVS_SENSOR_H

#include "gvs_kernel.h"

/* 1: the time to limit is refreshed every 1 s (gvs_ttl_refresh) and the early warning is on; 0: a build without it
 * ([export] time_to_limit = false: ttl_s NaN, no early warning, less flash and stack) */
#define GVS_EXPORT_TTL {ttl}

/* the generated tables of this variant and configuration (gvs_tables.c) and its vehicle (no effects) */
extern const gvs_tables GVS_TABLES;
extern const gvs_vehicle GVS_VEHICLE;

{published}

/* the key of a saved gvs_state: kernel sources, tables (variant, configuration), real type, sizes and the time to
 * limit of this export; store it with the state and restore only a state saved under the same key */
#define GVS_STATE_KEY {key}

/* Cold start: every node at the measured oil temperature T_oil_c (NaN, or outside the oil input's plausible
 * range: the ambient default of the tables, 25 degC unless configured). */
void gvs_sensor_init(gvs_state *st, double T_oil_c);

/* Cold start as the Python sensor makes it: at the oil reading when plausible, else at the ambient reading
 * T_ambient_c when plausible (a gearbox that stood long is at ambient), else the tables' ambient default. */
void gvs_sensor_init_ambient(gvs_state *st, double T_oil_c, double T_ambient_c);

/* degraded_mode while gvs_sensor_start waits for the first oil reading (the CAN service's DegradedMode 3) */
#define GVS_MODE_NOT_INITIALISED 3
/* how long gvs_sensor_start waits for a plausible oil reading [s] (the CAN service's init_wait_s) */
#define GVS_INIT_WAIT_S 3.0

/* Start-up as the CAN service makes it: call every 100 ms from power-on, with the time waited since then [s] and
 * the latest oil and ambient readings (NaN: none yet), until it returns 1; from then on call gvs_sensor_step. At the
 * first plausible oil reading it starts every node at it; after GVS_INIT_WAIT_S without one, at the ambient reading
 * (gvs_sensor_init_ambient), and returns 1. While it returns 0, *out says "not initialised": every temperature and
 * time to limit NaN, every level 3, degraded_mode GVS_MODE_NOT_INITIALISED. Why wait: a state started without the
 * oil (from the ambient) takes a later reading into the sump only, and the parts of a warm gearbox then read tens of
 * kelvin low for many minutes in mode 0; the oil's frame comes once a second on J1939 (TRF1), so a start that does
 * not wait misses it half the time. */
int gvs_sensor_start(gvs_state *st, double waited_s, double T_oil_c, double T_ambient_c, gvs_outputs *out);

/* Warm start from a state saved on shutdown (same GVS_STATE_KEY, CRC checked by the caller): 0, or -1 when its
 * contents are not a sensor state (a temperature not finite or outside -100..500 degC, a level outside 0..3, a
 * negative count, another real of the step not finite): then start cold with gvs_sensor_init. Restarts the time
 * base (the next t_s may be anything, an uptime counter from 0 too) and the step count, forgets the time to limit,
 * counts every input's last value as old (the stop lay between: the first oil reading is not judged a step from
 * the one before shutdown; without fresh drive inputs for a step the levels read 3), and applies a plausible oil reading
 * T_oil_c (NaN: none) as the host sensor does: more than 10 K from the saved sump, every node starts at it; else
 * the sump takes it; one within oil_step_c of a reading rejected before the stop is not applied (the step check
 * goes on judging it), and without a reading the first one is taken as it comes unless one was being rejected. It
 * does not cool the state over the time the truck stood (the host sensor does): after a long stop without an oil
 * reading, start cold instead. */
int gvs_sensor_resume(gvs_state *st, double T_oil_c);

/* One 0.1 s step: call every 100 ms with the latest inputs (NaN = not available). Each accepted call advances the
 * model by exactly 0.1 s. in->t_s (NaN: on the 100 ms grid) less than 0.05 s after the last step, or back by up to
 * {reset} s: GVS_SKIPPED (counted as time_backward; nothing integrated, outputs repeat the state). Back by more than
 * {reset} s: a reset clock, its time the new base (counted, stepped). More than 0.15 s after the last step: counted as
 * time_jump, and this build continues from the state before the gap (it does not integrate over gaps; the host
 * build does). With GVS_EXPORT_TTL the step that is due refreshes the time to limit after its outputs are written
 * (out->ttl_s shows the last refresh counted down, as on the host). Returns GVS_OK or GVS_SKIPPED. */
int gvs_sensor_step(gvs_state *st, const gvs_inputs *in, gvs_outputs *out);

#endif
"""

SENSOR_SOURCE = """/* gearbox-vsensor: start and step of the exported sensor (see gvs_sensor.h). */
#include <math.h>
#include <string.h>
#include "gvs_sensor.h"

void gvs_sensor_init(gvs_state *st, double T_oil_c)
{
    gvs_sensor_init_ambient(st, T_oil_c, NAN);
}

void gvs_sensor_init_ambient(gvs_state *st, double T_oil_c, double T_ambient_c)
{
    int i, c;
    /* a reading outside its input's plausible range (or NaN) is no start, as in the Python sensor's
     * initial_state: the oil, else the ambient reading, else the ambient default */
    int oil_ok = T_oil_c >= (double)GVS_TABLES.input_lo[GVS_I_OIL] && T_oil_c <= (double)GVS_TABLES.input_hi[GVS_I_OIL];
    int amb_ok = T_ambient_c >= (double)GVS_TABLES.input_lo[GVS_I_AMB]
        && T_ambient_c <= (double)GVS_TABLES.input_hi[GVS_I_AMB];
    gvs_real T0 = (gvs_real)(oil_ok ? T_oil_c : amb_ok ? T_ambient_c : (double)GVS_TABLES.aux_default[0]);
    memset(st, 0, sizeof *st);
    for (c = 0; c < 2; ++c)
        for (i = 0; i < GVS_TABLES.n; ++i) st->T_c[c][i] = T0;
    for (i = 0; i < GVS_N_INPUTS; ++i) { st->hold[i] = (gvs_real)NAN; st->raw_prev[i] = (gvs_real)NAN; }
    st->hold[GVS_I_SPEED] = st->hold[GVS_I_TORQUE] = st->hold[GVS_I_GEAR] = 0;
    st->hold[GVS_I_OIL] = T0;
    if (!oil_ok) st->age_s[GVS_I_OIL] = (gvs_real)GVS_OIL_AGE_NONE_S;     /* no reading yet: the first is not judged */
    st->oil_ref_c = T0;
    for (i = 0; i < GVS_MAX_PUB; ++i) st->ttl_s[i] = (gvs_real)NAN;
    st->t_last_s = NAN;
}

int gvs_sensor_start(gvs_state *st, double waited_s, double T_oil_c, double T_ambient_c, gvs_outputs *out)
{
    int i;
    int oil_ok = T_oil_c >= (double)GVS_TABLES.input_lo[GVS_I_OIL] && T_oil_c <= (double)GVS_TABLES.input_hi[GVS_I_OIL];
    if (oil_ok || !(waited_s < GVS_INIT_WAIT_S - 1e-9)) {     /* (a NaN wait: started at once) */
        gvs_sensor_init_ambient(st, T_oil_c, T_ambient_c);
        return 1;
    }
    memset(out, 0, sizeof *out);
    for (i = 0; i < GVS_MAX_PUB; ++i) {
        out->T_c[i] = (gvs_real)NAN;
        out->level[i] = 3;
        out->ttl_s[i] = (gvs_real)NAN;
    }
    out->degraded_mode = GVS_MODE_NOT_INITIALISED;
    out->model_oil_temp_c = out->oil_innovation_c = out->oil_inlet_temp_c = (gvs_real)NAN;
    out->oil_source = 1;
    return 0;
}

/* a finite value (a real of the state that may not be NaN) */
static int finite_value(gvs_real x)
{
    return x == x && x - x == x - x;
}

int gvs_sensor_resume(gvs_state *st, double T_oil_c)
{
    const gvs_tables *tb = &GVS_TABLES;
    int i, c, io = tb->i_oil, rejected, going_on;
    for (c = 0; c < 2; ++c)
        for (i = 0; i < tb->n; ++i)
            if (!(st->T_c[c][i] >= (gvs_real)-100.0 && st->T_c[c][i] <= (gvs_real)500.0)) return -1;
    for (i = 0; i < GVS_MAX_PUB; ++i)
        if (st->level[i] < 0 || st->level[i] > 3 || !(st->pending_s[i] >= (gvs_real)0.0)
            || !finite_value(st->pending_s[i])) return -1;
    for (i = 0; i < GVS_N_REJECT; ++i)
        if (st->rejects[i] < 0) return -1;
    if (st->k < 0) return -1;
    /* every other real the step reads: finite (the held inputs and their previous raw values may be NaN: none yet) */
    for (i = 0; i < tb->ns; ++i)
        if (!finite_value(st->lag_w[i])) return -1;
    for (i = 0; i < GVS_N_INPUTS; ++i)
        if (!(st->age_s[i] >= (gvs_real)0.0) || !(st->same_s[i] >= (gvs_real)0.0) || !finite_value(st->same_s[i])
            || (st->hold[i] == st->hold[i] && !finite_value(st->hold[i]))) return -1;
    /* raw_prev holds the last raw input as it came, +-inf and values beyond the real type's range included */
    if (!finite_value(st->oil_ref_c) || !(st->recover_s >= (gvs_real)0.0) || !finite_value(st->recover_s)) return -1;
    st->memo_valid = 0;                 /* the conductance memo is recomputed, never trusted from storage */
    st->memo_heat_valid = 0;            /* and the heat memo of a build with GVS_STEP_MEMO */
    /* an oil reading came before the stop and was not taken (VirtualSensor._restored_oil): one within oil_step_c of
     * it at the restart goes on being judged by the step check, it does not restart the state */
    rejected = st->age_s[GVS_I_OIL] > (gvs_real)0.0 && finite_value(st->raw_prev[GVS_I_OIL]);
    going_on = rejected && fabs(T_oil_c - (double)st->raw_prev[GVS_I_OIL]) <= (double)tb->oil_step_c;
    /* an ignition cycle lies between: every input's last value is at least hold_s old (no 0.1 s step from the one
     * before the stop; VirtualSensor._restored_state ages them by the stop, which this build does not know) */
    for (i = 0; i < GVS_N_INPUTS; ++i)
        if (!(st->age_s[i] >= tb->hold_s)) st->age_s[i] = tb->hold_s;
    /* the oil reading (VirtualSensor._restored_state with no time elapsed) */
    if (T_oil_c >= (double)tb->input_lo[GVS_I_OIL] && T_oil_c <= (double)tb->input_hi[GVS_I_OIL] && !going_on) {
        gvs_real T = (gvs_real)T_oil_c;
        if (fabs((double)st->T_c[0][io] - T_oil_c) > 10.0) {
            for (c = 0; c < 2; ++c)
                for (i = 0; i < tb->n; ++i) st->T_c[c][i] = T;
            /* every node restarted at the reading: the saved warning levels go with the saved temperatures */
            for (i = 0; i < GVS_MAX_PUB; ++i) {
                st->level[i] = 0;
                st->pending_s[i] = (gvs_real)0.0;
            }
        }
        st->T_c[0][io] = st->T_c[1][io] = T;
    } else if (!rejected) {
        /* the saved sump is from before the stop, not cooled here: the first reading is not judged against it */
        st->age_s[GVS_I_OIL] = (gvs_real)GVS_OIL_AGE_NONE_S;
    }
    st->t_last_s = NAN;
    st->k = 0;
    for (i = 0; i < GVS_MAX_PUB; ++i) st->ttl_s[i] = (gvs_real)NAN;
    return 0;
}

int gvs_sensor_step(gvs_state *st, const gvs_inputs *in, gvs_outputs *out)
{
#if GVS_EXPORT_TTL
    gvs_ttl_point point;
    int rc = gvs_step(&GVS_TABLES, &GVS_VEHICLE, st, in, 0, out, &point);
    if (rc == GVS_NEED_JUMP)
        rc = gvs_step(&GVS_TABLES, &GVS_VEHICLE, st, in, 1, out, &point);
    if (point.due) gvs_ttl_refresh(&GVS_TABLES, &GVS_VEHICLE, &point, st->ttl_s);
#else
    int rc = gvs_step(&GVS_TABLES, &GVS_VEHICLE, st, in, 0, out, 0);
    if (rc == GVS_NEED_JUMP)
        rc = gvs_step(&GVS_TABLES, &GVS_VEHICLE, st, in, 1, out, 0);
#endif
    return rc;
}
"""

TEST_PROGRAM = """/* gearbox-vsensor export-c: replay the test vectors through the exported sensor and compare with the Python
 * reference's outputs. Exit status 0 when every kept step matches. */
#include <math.h>
#include <stdio.h>
#include "gvs_sensor.h"

extern const int32_t GVS_VEC_STEPS, GVS_VEC_KEPT, GVS_VEC_EVERY;
extern const double GVS_VEC_INPUTS[], GVS_VEC_T_C[];
extern const int32_t GVS_VEC_LEVEL[], GVS_VEC_MODE[];
#if GVS_EXPORT_TTL
extern const double GVS_VEC_TTL[];

/* the time to limit agrees: both never (inf), both not available (NaN), or within the tolerance */
static int ttl_close(double got, double want, double *worst)
{
    double d;
    if (want != want || got != got) return (want != want) == (got != got);
    if (isinf(want) || isinf(got)) return want == got;
    d = fabs(got - want);
    if (d > *worst) *worst = d;
    return d <= @TTL_ABS@ || d <= @TTL_REL@ * fabs(want);
}

/* a kept step where the reference's own time to limit moved by more than the tolerance (beyond its countdown) since
   the last kept step or moves so by the next: a path that grazes the limit, where the rounding of the far sump's
   bracket decides the time and a refresh a second later moves it by more than the tolerance. A value within the
   span of the neighbouring kept steps' references (and the tolerance) agrees with the reference's path there; it is
   counted apart, and one outside that span fails */
static int ttl_in_jump(int kept, int i, double got)
{
    double prev, want, next, lo, hi, tick_s = (double)GVS_VEC_EVERY * (double)GVS_TABLES.dt_s;
    if (kept == 0 || kept + 1 >= GVS_VEC_KEPT) return 0;
    prev = GVS_VEC_TTL[(kept - 1) * GVS_MAX_PUB + i];
    want = GVS_VEC_TTL[kept * GVS_MAX_PUB + i];
    next = GVS_VEC_TTL[(kept + 1) * GVS_MAX_PUB + i];
    if (!(isfinite(prev) && isfinite(want) && isfinite(next) && isfinite(got))) return 0;
    if (fabs(want - (prev - tick_s)) <= @TTL_ABS@ + @TTL_REL@ * fabs(want)
        && fabs(next - (want - tick_s)) <= @TTL_ABS@ + @TTL_REL@ * fabs(next))
        return 0;
    lo = prev < next ? prev : next;
    hi = prev < next ? next : prev;
    return got >= lo - @TTL_ABS@ - @TTL_REL@ * fabs(lo) && got <= hi + @TTL_ABS@ + @TTL_REL@ * fabs(hi);
}

/* the early warning's thresholds (lead, 2 lead) within the time-to-limit tolerance */
static int near_lead(double ttl)
{
    double lead = (double)GVS_TABLES.lead_s;
    return lead > 0.0 && (fabs(ttl - lead) <= @TTL_ABS@ + @TTL_REL@ * lead
                          || fabs(ttl - 2.0 * lead) <= @TTL_ABS@ + 2.0 * @TTL_REL@ * lead);
}
#endif

static gvs_state state;
/* the last step at which each component's own estimate (or its time to limit) sat within the tolerance of a level
   threshold: a level that changes a debounce later than the crossing differs for a few steps between float and
   double (or C and numpy) without either being wrong */
static long last_near[GVS_MAX_PUB];

static int near_threshold(int i, double T)
{
    const gvs_tables *tb = &GVS_TABLES;
    double lim[4] = {tb->warning_c[i], tb->critical_c[i], tb->warning_c[i] - tb->hysteresis_k[i],
                     tb->critical_c[i] - tb->hysteresis_k[i]};
    int k;
    for (k = 0; k < 4; ++k)
        if (fabs(T - lim[k]) <= @TOL@) return 1;
    return 0;
}

/* a threshold (or the early warning's lead) was within the tolerance at most a debounce before (and a time-to-limit
   refresh period and two steps: the lead is judged on the refreshed value) */
static int debounced(int i, int j)
{
    double dt_s = (double)GVS_TABLES.dt_s, since_s = (double)(j - last_near[i]) * dt_s;
    return since_s <= (double)GVS_TABLES.debounce_s + ((double)GVS_TABLES.ttl_every + 2.0) * dt_s;
}

int main(void)
{
    const double tol = @TOL@;
    double worst = 0.0, ttl_worst = 0.0;
    int j, i, kept = 0, level_bad = 0, level_near = 0, mode_bad = 0, nan_out = 0, ttl_bad = 0, ttl_jump = 0;
    gvs_outputs out;
    for (i = 0; i < GVS_MAX_PUB; ++i) last_near[i] = -1000000L;
    gvs_sensor_init(&state, GVS_VEC_INPUTS[3]);
    for (j = 0; j < GVS_VEC_STEPS; ++j) {
        gvs_inputs in;
        for (i = 0; i < GVS_N_INPUTS; ++i) in.raw[i] = GVS_VEC_INPUTS[j * GVS_N_INPUTS + i];
        in.t_s = NAN;
        gvs_sensor_step(&state, &in, &out);
        for (i = 0; i < GVS_MAX_PUB; ++i) {
            nan_out += !(out.T_c[i] == out.T_c[i]);
            if (near_threshold(i, (double)out.T_c[i])) last_near[i] = j;
#if GVS_EXPORT_TTL
            if (near_lead((double)out.ttl_s[i])) last_near[i] = j;
#endif
        }
        if ((j + 1) % GVS_VEC_EVERY != 0 || kept >= GVS_VEC_KEPT) continue;
        for (i = 0; i < GVS_MAX_PUB; ++i) {
            double e = GVS_VEC_T_C[kept * GVS_MAX_PUB + i], d = fabs((double)out.T_c[i] - e);
            if (d > worst) worst = d;
#if GVS_EXPORT_TTL
            {
                double tw = GVS_VEC_TTL[kept * GVS_MAX_PUB + i];
                double worst_before = ttl_worst;
                if (!ttl_close((double)out.ttl_s[i], tw, &ttl_worst)) {
                    if (ttl_in_jump(kept, i, (double)out.ttl_s[i])) {
                        ++ttl_jump;
                        ttl_worst = worst_before;  /* the largest difference is of the values judged by it */
                    } else {
                        ++ttl_bad;
                    }
                }
                if (out.level[i] != GVS_VEC_LEVEL[kept * GVS_MAX_PUB + i]) {
                    if (near_threshold(i, e) || near_lead(tw) || debounced(i, j)) ++level_near; else ++level_bad;
                }
            }
#else
            if (out.level[i] != GVS_VEC_LEVEL[kept * GVS_MAX_PUB + i]) {
                if (near_threshold(i, e) || debounced(i, j)) ++level_near; else ++level_bad;
            }
#endif
        }
        mode_bad += out.degraded_mode != GVS_VEC_MODE[kept];
        ++kept;
    }
    printf("steps %d, kept %d: max |T - reference| %.3g K (tolerance %g), level mismatches %d (+%d within the "
           "tolerance of a threshold), mode mismatches %d, NaN outputs %d, ",
           (int)GVS_VEC_STEPS, kept, worst, tol, level_bad, level_near, mode_bad, nan_out);
#if GVS_EXPORT_TTL
    printf("time to limit outside max(@TTL_ABS@ s, @TTL_REL@ x) %d (largest difference %.3g s; +%d within the "
           "reference's own jump between refreshes), ", ttl_bad, ttl_worst, ttl_jump);
#else
    printf("time to limit not in this build (not checked), ");
#endif
    printf("counters");
    for (i = 0; i < GVS_N_REJECT; ++i) printf(" %ld", (long)state.rejects[i]);
    (void)ttl_worst;
    (void)ttl_jump;
    j = worst <= tol && level_bad == 0 && mode_bad == 0 && nan_out == 0 && ttl_bad == 0;
    printf("\\n%s\\n", j ? "PASS" : "FAIL");
    return j ? 0 : 1;
}
"""

REPLAY_PROGRAM = r"""/* gearbox-vsensor export-c: `gvs_replay IN OUT` steps the exported sensor over a whole drive and writes every
 * step's outputs, to compare two builds of the same sources (the host's and the Cortex-M4F's, `make replay` and
 * `make qemu-replay`). IN: per step 8 little-endian float64 inputs (the order of gvs_inputs.raw; NaN = not
 * available), 0.1 s apart, no header; from numpy: np.ascontiguousarray(d[:, :8], '<f8').tofile('drive.bin').
 * OUT: per step float32 T_c[GVS_MAX_PUB], float32 ttl_s[GVS_MAX_PUB], int8 level[GVS_MAX_PUB], int8 degraded_mode.
 * IN has no header, so before writing OUT the harness refuses (one sentence on stderr, exit 2, no OUT) what would
 * replay garbage or a partial record: an empty file, text, a size that is not whole 64-byte records (truncated, or
 * float32), and float32 values (told by the values, below). Bad values inside float64 records (NaN, inf, out of
 * range) are the sensor's to handle (its degraded modes): replayed, and its reject counters printed at the end.
 * Built with -DGVS_SYSTICK (the Cortex-M4F build), it also counts the processor clock cycles of each step with the
 * SysTick timer: under QEMU with -icount the emulated clock advances a fixed time per instruction, so the cycles
 * count instructions (`make qemu-replay` prints both). */
#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include "gvs_sensor.h"

#ifdef GVS_SYSTICK
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#endif

#define RECORD_BYTES (8 * GVS_N_INPUTS)   /* one step of IN */
#define PROBE_RECORDS 256                 /* the records the float32 check reads */
#define HOW_TO_WRITE " (write it from numpy: np.ascontiguousarray(d[:, :8], '<f8').tofile(path); README.md)"

/* IN is IEEE-754 binary64: a build where double is anything else stops here */
typedef char gvs_double_is_binary64[(sizeof(double) == 8 && DBL_MANT_DIG == 53) ? 1 : -1];

static gvs_state state;
#ifdef GVS_SYSTICK
static uint64_t cycles_total;           /* over the replay's steps */
static uint32_t cycles_worst;
#endif

/* One sentence on stderr, prefixed with the program's name; returns the exit status of a refusal. */
static int refuse(const char *fmt, ...)
{
    va_list ap;
    fputs("gvs_replay: ", stderr);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
    return 2;
}

/* Values no sensor input holds but two float32 read as one float64 give: subnormal (a float32 0.0 in the high
 * half) or 1e9..1e100 (a float32 above ~30 in the high half makes 2^33 and up). The hostile values of a test
 * (+-1e308, inf, NaN, a few orders out of range) are neither. */
static int odd64(double v)
{
    double a = fabs(v);
    return isfinite(v) && v != 0.0 && (a < DBL_MIN || (a > 1e9 && a < 1e100));
}

static int odd32(float v)
{
    float a = fabsf(v);
    return isfinite(v) && v != 0.0f && (a < FLT_MIN || a > 1e9f);
}

/* float32 values: most of the first records hold an odd value read as float64 and few read as 16 float32. The low
 * halves of real float64 values read as float32 are random bits (odd in nearly every record) or zeros (round
 * values), so a float64 file does not look like this; a drive of float32 values does (oil above ~30 degC, or a
 * zero torque or retarder beside a nonzero value, in nearly every record). Leaves fi at the start. */
static int looks_float32(FILE *fi, long records)
{
    unsigned char b[RECORD_BYTES];
    long k, n = records < PROBE_RECORDS ? records : PROBE_RECORDS, n64 = 0, n32 = 0;
    for (k = 0; k < n && fread(b, sizeof b, 1, fi) == 1; ++k) {
        double d[GVS_N_INPUTS];
        float f[2 * GVS_N_INPUTS];
        int i, o64 = 0, o32 = 0;
        memcpy(d, b, sizeof d);
        memcpy(f, b, sizeof f);
        for (i = 0; i < GVS_N_INPUTS; ++i) o64 |= odd64(d[i]);
        for (i = 0; i < 2 * GVS_N_INPUTS; ++i) o32 |= odd32(f[i]);
        n64 += o64;
        n32 += o32;
    }
    rewind(fi);
    return 2 * n64 > n && 2 * n32 < n;
}

/* Checks IN (module comment) and sets *records; returns 0, or 2 after one sentence on stderr. */
static int check_input(FILE *fi, const char *path, long *records)
{
    unsigned char b[RECORD_BYTES];
    const uint16_t one = 1;
    long bytes = -1;
    size_t n, i;
    int text = 1;
    memcpy(b, &one, 1);
    if (b[0] != 1) return refuse("this build's machine is big-endian and IN holds little-endian float64.");
    if (fseek(fi, 0L, SEEK_END) == 0) bytes = ftell(fi);
    if (bytes < 0 || fseek(fi, 0L, SEEK_SET) != 0)
        return refuse("cannot tell the size of %s: give IN as a regular file, not a pipe.", path);
    n = fread(b, 1, sizeof b, fi);
    if (ferror(fi)) return refuse("cannot read %s: give IN as a regular file of float64 records.", path);
    rewind(fi);
    if (bytes == 0)
        return refuse("%s is empty (0 bytes): IN holds %d little-endian float64 inputs per 0.1 s step, %d bytes a "
                      "record" HOW_TO_WRITE ".", path, GVS_N_INPUTS, RECORD_BYTES);
    /* text: the first bytes all printable or white space, which the bytes of float64 values practically never are */
    for (i = 0; i < n; ++i) text &= (b[i] >= 0x20 && b[i] < 0x7F) || b[i] == '\t' || b[i] == '\n' || b[i] == '\r';
    if (text)
        return refuse("%s looks like text (its first %lu bytes are all printable), not float64 records"
                      HOW_TO_WRITE ".", path, (unsigned long)n);
    if (bytes % RECORD_BYTES != 0)
        return refuse("%s is %ld bytes, not a whole number of %d-byte records (%d float64 inputs per step; %ld bytes "
                      "left over): truncated, or written as float32" HOW_TO_WRITE ".", path, bytes, RECORD_BYTES,
                      GVS_N_INPUTS, bytes % RECORD_BYTES);
    *records = bytes / RECORD_BYTES;
    if (looks_float32(fi, *records))
        return refuse("%s looks like float32 values, not float64: read as float64 most of its first records hold "
                      "values no input has (subnormal, or 1e9 to 1e100), read as float32 they do not"
                      HOW_TO_WRITE ".", path);
    return 0;
}

/* Steps the sensor over IN's records (at most the records its size held) into OUT; returns the steps, or -1 when
 * OUT could not be written. */
static long replay(FILE *fi, FILE *fo, long records)
{
    double raw[GVS_N_INPUTS];
    long steps = 0;
    int i;
    gvs_outputs out;
#ifdef GVS_SYSTICK
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0u;
    SYST_CSR = 5u;                      /* enabled, processor clock, no interrupt */
#endif
    while (steps < records && fread(raw, sizeof raw, 1, fi) == 1) {
        gvs_inputs in;
        float T[GVS_MAX_PUB], ttl[GVS_MAX_PUB];
        int8_t lv[GVS_MAX_PUB + 1];
#ifdef GVS_SYSTICK
        uint32_t t0, d;
#endif
        if (steps == 0) gvs_sensor_init(&state, raw[GVS_I_OIL]);
        for (i = 0; i < GVS_N_INPUTS; ++i) in.raw[i] = raw[i];
        in.t_s = NAN;
#ifdef GVS_SYSTICK
        t0 = SYST_CVR;
        gvs_sensor_step(&state, &in, &out);
        d = (t0 - SYST_CVR) & 0xFFFFFFu;    /* a down-counter: wraps after 2^24 cycles, far more than a step */
        cycles_total += d;
        if (d > cycles_worst) cycles_worst = d;
#else
        gvs_sensor_step(&state, &in, &out);
#endif
        for (i = 0; i < GVS_MAX_PUB; ++i) {
            T[i] = (float)out.T_c[i];
            ttl[i] = (float)out.ttl_s[i];
            lv[i] = (int8_t)out.level[i];
        }
        lv[GVS_MAX_PUB] = (int8_t)out.degraded_mode;
        if (fwrite(T, sizeof T, 1, fo) != 1 || fwrite(ttl, sizeof ttl, 1, fo) != 1 || fwrite(lv, sizeof lv, 1, fo) != 1)
            return -1;
        ++steps;
    }
    return steps;
}

int main(int argc, char **argv)
{
    FILE *fi, *fo;
    long records = 0, steps;
    int i, rc;
    if (argc != 3) {
        fprintf(stderr, "usage: gvs_replay IN OUT (IN: 8 little-endian float64 inputs per step; gvs_replay.c)\n");
        return 2;
    }
    if (strcmp(argv[1], argv[2]) == 0)
        return refuse("IN and OUT are both %s: opening OUT would erase the drive before it is read; name another OUT.",
                      argv[1]);
    fi = fopen(argv[1], "rb");
    if (!fi) return refuse("cannot open IN %s: %s.", argv[1], strerror(errno));
    rc = check_input(fi, argv[1], &records);
    if (rc != 0) return rc;             /* no OUT: nothing that could be taken for a replay */
    fo = fopen(argv[2], "wb");
    if (!fo) return refuse("cannot open OUT %s: %s.", argv[2], strerror(errno));
    /* OUT another name of IN (a link): opening it emptied IN, whose reads would then return the outputs written */
    if (fseek(fi, 0L, SEEK_END) != 0 || ftell(fi) != records * RECORD_BYTES || fseek(fi, 0L, SEEK_SET) != 0) {
        fclose(fo);
        return refuse("opening OUT %s changed IN %s (one file under two names?): name another OUT.", argv[2],
                      argv[1]);
    }
    steps = replay(fi, fo, records);
    /* IN changed or became unreadable while replayed, or OUT could not be written: OUT is emptied, not removed (it
     * may be a device), so no partial replay stands */
    rc = steps < 0 ? refuse("cannot write OUT %s.", argv[2])
         : ferror(fi) || steps != records ? refuse("read %ld of the %ld records of %s: it changed or could not be "
                                                   "read while replayed.", steps, records, argv[1])
                                          : 0;
    fclose(fi);
    if (fclose(fo) != 0 && rc == 0) rc = refuse("cannot write OUT %s.", argv[2]);
    if (rc != 0) {
        fo = fopen(argv[2], "wb");
        if (fo) fclose(fo);
        return rc;
    }
    printf("steps %ld\n", steps);
#ifdef GVS_SYSTICK
    printf("SysTick cycles per step: mean %.1f, max %lu\n", (double)cycles_total / (double)steps,
           (unsigned long)cycles_worst);
#endif
    /* the sensor's own handling of bad values, visible (README.md names the 13 counters in this order) */
    printf("rejected or repaired inputs:");
    for (i = 0; i < GVS_N_REJECT; ++i) printf(" %ld", (long)state.rejects[i]);
    printf("\n");
    return 0;
}
"""

MAKEFILE = """# gearbox-vsensor export-c: `make test` builds a host program that replays the test vectors and checks them;
# `make cortex-m4 qemu-test size` does the same on an emulated ARM Cortex-M4F (arm-none-eabi-gcc, qemu-system-arm).
CC ?= cc
CFLAGS ?= -std=c99 -O2 -Wall -Wextra -Wpedantic -Werror
REAL = @REAL_FLAG@
# the struct capacities of this variant (RAM: the state and the step's stack hold exactly these)
CAPS = @CAPS@
SENSOR = gvs_kernel.c gvs_sensor.c gvs_tables.c

test: gvs_test
\t./gvs_test

gvs_test: $(SENSOR) gvs_vectors.c gvs_test.c gvs_kernel.h gvs_sensor.h
\t$(CC) $(CFLAGS) $(REAL) $(CAPS) -o $@ $(SENSOR) gvs_vectors.c gvs_test.c -lm

# --- ARM Cortex-M4F (hard float, single precision), run on QEMU's mps2-an386 board with semihosting
ARM_CC ?= arm-none-eabi-gcc
ARM_SIZE ?= arm-none-eabi-size
M4 = -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16
# this export's real type ($(REAL)): a double export runs its double arithmetic in software on the M4F's
# single-precision FPU (it builds and runs, larger and slower than a float export)
# -fno-math-errno: sqrtf becomes the FPU's vsqrt without a library call to set errno (68 B of flash; the same
# values: the kernel never reads errno)
M4_CFLAGS = -std=c99 -Os -flto -fno-math-errno -Wall -Wextra -ffunction-sections -fdata-sections $(REAL) $(CAPS) -I.

cortex-m4: gvs_test_m4.elf gvs_footprint_m4.elf

gvs_test_m4.elf: $(SENSOR) gvs_vectors.c gvs_test.c cortex-m4/startup.c cortex-m4/mps2_an386.ld
\t$(ARM_CC) $(M4) $(M4_CFLAGS) --specs=rdimon.specs -T cortex-m4/mps2_an386.ld -o $@ cortex-m4/startup.c \\
\t\t$(SENSOR) gvs_vectors.c gvs_test.c -lm

# the sensor alone (one state, one step) for the footprint: flash = text + data, RAM = data + bss + stack
gvs_footprint_m4.elf: $(SENSOR) cortex-m4/footprint.c cortex-m4/startup.c
\t$(ARM_CC) $(M4) $(M4_CFLAGS) -fstack-usage --specs=nano.specs --specs=nosys.specs -Wl,--gc-sections \\
\t\t-T cortex-m4/mps2_an386.ld -o $@ cortex-m4/startup.c $(SENSOR) cortex-m4/footprint.c -lm

qemu-test: gvs_test_m4.elf
\tqemu-system-arm -M mps2-an386 -nographic -semihosting-config enable=on,target=native -kernel gvs_test_m4.elf

gvs_stack_m4.elf: $(SENSOR) cortex-m4/footprint.c cortex-m4/startup.c
\t$(ARM_CC) $(M4) $(M4_CFLAGS) -DGVS_STACK_PROBE --specs=rdimon.specs -T cortex-m4/mps2_an386.ld -o $@ \\
\t\tcortex-m4/startup.c $(SENSOR) cortex-m4/footprint.c -lm

# flash = text + data; RAM = data + bss (the state) + the stack high-water mark the probe prints
size: gvs_footprint_m4.elf gvs_stack_m4.elf
\t$(ARM_SIZE) gvs_footprint_m4.elf
\tqemu-system-arm -M mps2-an386 -nographic -semihosting-config enable=on,target=native -kernel gvs_stack_m4.elf

# a whole drive through both builds: `make replay qemu-replay IN=drive.bin` (gvs_replay.c says the formats); QEMU
# runs with -icount shift=$(ICOUNT_SHIFT): 2^shift ns of emulated time per instruction, so that the SysTick's
# 25 MHz cycles count instructions (instructions per step = cycles x 40 / 2^shift)
IN ?= drive.bin
ICOUNT_SHIFT ?= 3
replay: gvs_replay
\t./gvs_replay $(IN) host.out

gvs_replay: $(SENSOR) gvs_replay.c gvs_kernel.h gvs_sensor.h
\t$(CC) $(CFLAGS) $(REAL) $(CAPS) -o $@ $(SENSOR) gvs_replay.c -lm

gvs_replay_m4.elf: $(SENSOR) gvs_replay.c cortex-m4/startup.c cortex-m4/mps2_an386.ld
\t$(ARM_CC) $(M4) $(M4_CFLAGS) -DGVS_SYSTICK --specs=rdimon.specs -T cortex-m4/mps2_an386.ld -o $@ \\
\t\tcortex-m4/startup.c $(SENSOR) gvs_replay.c -lm

qemu-replay: gvs_replay_m4.elf
\tqemu-system-arm -M mps2-an386 -nographic -icount shift=$(ICOUNT_SHIFT) \\
\t\t-semihosting-config enable=on,target=native,arg=gvs_replay,arg=$(IN),arg=m4.out -kernel gvs_replay_m4.elf

clean:
\trm -f gvs_test gvs_replay *.o *.su *.elf host.out m4.out

.PHONY: test cortex-m4 qemu-test size replay qemu-replay clean
"""

README = """# gearbox-vsensor onboard sensor, {variant}, exported for an ECU ({real} build)

Kernel sources {source_id}. `make test` builds a host program that steps the test vectors ({vectors}, 1000 s
at 10 Hz with 20 s of hostile inputs, past its first early warning) and compares temperatures (tolerance {tol} K),
warning levels, degraded modes and the time to limit with the Python reference (gearbox-vsensor's numpy step).

## Files

| file | what |
|---|---|
| `gvs_kernel.c`, `gvs_kernel.h` | the generic C99 kernel: one 0.1 s step of the sensor; no allocation, no I/O, no mutable globals; only `<math.h>`, `<string.h>`, `<stdint.h>` |
| `gvs_tables.c` | the generated tables of {variant} ({n} thermal nodes): loss maps, conductance laws, cooler, limits, options (`const`, flash) |
| `gvs_sensor.h`, `gvs_sensor.c` | the API below |
| `gvs_vectors.c`, `gvs_test.c`, `Makefile` | the test |
| `gvs_replay.c` | a whole drive through a build (`make replay IN=drive.bin`, `make qemu-replay` on the emulated Cortex-M4F, which also counts instructions per step); [Replaying a drive](#replaying-a-drive) says the formats |

This export's real type ({real}), struct sizes and index width are fixed in `gvs_kernel.h`: compile every file with
the Makefile's flags or with none of them (another value stops the build with `#error`). Never with fast-math:
every file that includes `gvs_kernel.h` stops with `#error` under `-ffast-math` or `-ffinite-math-only`, which would
remove the NaN checks of the input validation (and a build whose NaN comparisons do not work refuses to step).

## Calling it

```c
#include "gvs_sensor.h"
static gvs_state state;                 /* RAM: sizeof(gvs_state); keep it across calls */
static int started;
/* every 100 ms from power-on (waited_s: the time since then): */
gvs_inputs in = {{{{{calling}}}, NAN}};      /* NaN = not available; t_s NaN: on the 100 ms grid */
gvs_outputs out;
if (!started)      /* waits up to GVS_INIT_WAIT_S (3 s) for the oil reading, then starts every node at it */
    started = gvs_sensor_start(&state, waited_s, in.raw[GVS_I_OIL], in.raw[GVS_I_AMB], &out);
if (started)
    gvs_sensor_step(&state, &in, &out);
```

Start with `gvs_sensor_start` (or `gvs_sensor_resume`, below), not `gvs_sensor_init_ambient` with a reading that has
not come yet: a state started without the oil (from the ambient) takes a later reading into the sump only, and the
parts of a warm gearbox then read tens of kelvin low for many minutes with `degraded_mode` 0. While it waits, `out`
says "not initialised" (temperatures and time to limit NaN, levels 3, `degraded_mode` 3), as the CAN service sends.
Each index of the outputs' arrays has a name in `gvs_sensor.h` (`GVS_PUB_<component>`, e.g. `out.T_c[{pub_example}]`).

{inputs_text} Outputs (`gvs_outputs`): `T_c[{n_pub}]`
the published component temperatures [degC] (order: the CAN outputs' component ids), `level[{n_pub}]` 0 normal,
1 warning, 2 critical, 3 not available, `degraded_mode` 0 normal, 1 oil modelled, 2 drive inputs missing (holding), 3 not initialised,
the validity bits, the modelled sump and the oil innovation (measured - model) [K], and `rejects[13]` the cumulative
counters of rejected or repaired inputs (speed_missing, speed_clamped, torque_missing, torque_clamped,
gear_missing, gear_unknown, oil_missing, oil_implausible, oil_frozen, drive_frozen, aux_missing, time_jump,
time_backward).

Bad input never produces a NaN temperature: a missing or implausible value is held, clamped or replaced by its
default and counted; drive inputs missing for more than 10 s make every level 3 (not available). That promise is
about the inputs: a state never started with `gvs_sensor_start`, `gvs_sensor_init` (or `gvs_sensor_resume`), or overwritten in RAM, is
outside it.

Timing: each accepted call advances the model by exactly 0.1 s, so call it from a 100 ms task; a scheduler that
runs 40 % slow makes the model 40 % slow, and nothing counts that unless you pass `t_s`. With `t_s` (seconds, any
origin; NaN: on the 100 ms grid): a call less than 0.05 s after the last step, or up to {reset} s back, returns
`GVS_SKIPPED` (counted as time_backward; outputs repeat the state); more than {reset} s back is a reset clock (counted,
stepped: its time is the new base); more than 0.15 s after the last step is counted as time_jump and the state
continues from before the gap (this build does not integrate over gaps: the Python sensor propagates the held
inputs over them).

{ttl_text}

Input checks a bench meets (the counters and `frozen_flags` say which fired): speed and torque bit-identical for
{drive_frozen} s while the engine turns are flagged as frozen (`frozen_flags` bits 0 and 1, `drive_frozen`; still
used, the mode stays 0), so a bench feeding constant values sees this after {drive_frozen} s; an oil reading
bit-identical for {oil_frozen} s while the modelled sump moved {oil_drift} K is frozen (modelled instead, mode 1,
`oil_frozen`); with the sump measured, an oil reading off both the last good one and the main copy's sump (that
reading carried by the model) by more than {oil_step} K + 0.05 K/s (`GVS_OIL_DRIFT_K_PER_S`) x its age (this build's
readings stand for no period: `oil_period_s` 0) is not used (`oil_implausible`, mode 1): a reading that jumps and
stays is modelled over until the allowance reaches it; with the sump modelled, a reading more than {oil_step} K from
a good one at most 1 s old is not taken that step; speed, torque or gear missing for more than {hold} s make every
level 3 (not available).

Thread safety: the functions keep no global state; one `gvs_state` per sensor, not shared between threads without
a lock.

Persisting the state across ignition cycles: `gvs_state` is plain data (`sizeof(gvs_state)` bytes in this build;
`make size` prints it for the Cortex-M4F build, with the flash and the stack the step uses).
On shutdown write it with `GVS_STATE_KEY` (from `gvs_sensor.h`: it changes with the kernel, the variant, the
configuration, the real type and the sizes, so a state of another export is never taken for this one's) and a CRC
of your choice. At start-up read it back; if the key or the CRC differs, or `gvs_sensor_resume(&state, oil_temp_c)`
returns -1 (contents that are no sensor state), start cold with `gvs_sensor_init`. `gvs_sensor_resume` restarts
the time base (your `t_s` may restart from 0) and applies the oil reading as the Python sensor does. It does not
cool the saved state over the stop: after a long stop with no oil reading at start-up, `gvs_sensor_init` (the ambient
default) is closer than the state of the last shutdown.

## Replaying a drive

`make replay IN=drive.bin` (host) and `make qemu-replay IN=drive.bin` (Cortex-M4F on QEMU) step the sensor over a
whole drive and write every step's outputs to `host.out` and `m4.out`. IN is raw binary with no header: per 0.1 s
step the 8 inputs above in `gvs_inputs.raw`'s order as little-endian float64 (64 bytes a record; NaN = not
available). Write it from numpy, as float64 whatever the array's type (float32 values written as they are make a file
of half the steps of garbage):

```python
np.ascontiguousarray(inputs[:, :8], '<f8').tofile('drive.bin')   # inputs: one row per step
```

OUT: per step float32 `T_c[{n_pub}]`, float32 `ttl_s[{n_pub}]`, int8 `level[{n_pub}]`, int8 `degraded_mode`
(numpy: `np.dtype([('T', '<f4', ({n_pub},)), ('ttl', '<f4', ({n_pub},)), ('level', 'i1', ({n_pub},)), ('mode', 'i1')])`).
Since IN cannot say its own type, `gvs_replay` refuses, with one sentence, exit 2 and no OUT, a file that is empty,
text (a CSV), not a whole number of 64-byte records (truncated, or float32 with an odd number of steps), or float32
values (told by their values: read as float64, float32 values give subnormal or 1e9..1e100 magnitudes in nearly every
record, which no input has; a float32 drive of a cold gearbox at rest can pass that check, so write float64 as
above); it also refuses OUT naming IN. Bad values inside float64 records (NaN, inf, out of range) are the sensor's
to handle: replayed, and the last line printed is the 13 reject counters in the order above.
"""

STARTUP = """/* Minimal start-up of an ARM Cortex-M4F as QEMU's mps2-an386 board emulates it: the vector table, the FPU
 * switched on, then newlib's _start (with semihosting, printf and the exit status reach the host). */
#include <stdint.h>
extern void _start(void);
extern uint32_t __stack;
void Reset_Handler(void);
void Default_Handler(void);

void Default_Handler(void) { for (;;) {} }

void Reset_Handler(void)
{
    *(volatile uint32_t *)0xE000ED88u |= 0xFu << 20;   /* CPACR: CP10 and CP11 full access (the FPU) */
    __asm volatile ("dsb\\n\\tisb");
    _start();
    for (;;) {}
}

typedef void (*vector_t)(void);
__attribute__((section(".isr_vector"), used))
const uintptr_t vector_table[16] = {
    (uintptr_t)&__stack, (uintptr_t)Reset_Handler, (uintptr_t)Default_Handler, (uintptr_t)Default_Handler,
    (uintptr_t)Default_Handler, (uintptr_t)Default_Handler, (uintptr_t)Default_Handler, 0, 0, 0, 0,
    (uintptr_t)Default_Handler, (uintptr_t)Default_Handler, 0, (uintptr_t)Default_Handler, (uintptr_t)Default_Handler,
};
"""

LINKER_SCRIPT = """/* ARM MPS2 AN386 (Cortex-M4) as QEMU emulates it: 4 MB code memory at 0, 4 MB data memory at 0x20000000 */
MEMORY
{
  FLASH (rx)  : ORIGIN = 0x00000000, LENGTH = 4M
  RAM   (rwx) : ORIGIN = 0x20000000, LENGTH = 4M
}
ENTRY(Reset_Handler)
SECTIONS
{
  .isr_vector : { KEEP(*(.isr_vector)) } > FLASH
  .text : { *(.text*) KEEP(*(.init)) KEEP(*(.fini)) *(.rodata*) . = ALIGN(4); } > FLASH
  .ARM.exidx : { *(.ARM.exidx* .gnu.linkonce.armexidx.*) } > FLASH
  .preinit_array : { PROVIDE_HIDDEN(__preinit_array_start = .); KEEP(*(.preinit_array))
                     PROVIDE_HIDDEN(__preinit_array_end = .); } > FLASH
  .init_array : { PROVIDE_HIDDEN(__init_array_start = .); KEEP(*(SORT(.init_array.*))) KEEP(*(.init_array))
                  PROVIDE_HIDDEN(__init_array_end = .); } > FLASH
  .fini_array : { PROVIDE_HIDDEN(__fini_array_start = .); KEEP(*(.fini_array))
                  PROVIDE_HIDDEN(__fini_array_end = .); } > FLASH
  .data : { *(.data*) . = ALIGN(4); } > RAM
  .bss (NOLOAD) : { __bss_start__ = .; *(.bss*) *(COMMON) . = ALIGN(4); __bss_end__ = .; } > RAM
  end = .;
  __end__ = .;
  __stack = ORIGIN(RAM) + LENGTH(RAM);
}
"""

FOOTPRINT = """/* The sensor linked alone for its footprint: one state, steps. With -DGVS_STACK_PROBE (semihosting build) it
 * also measures the stack the step uses: the region below the caller's frame is painted, the steps run, and the
 * deepest word written is the high-water mark (the step, the maths library and everything they call). */
#include <math.h>
#include <stdint.h>
#include "gvs_sensor.h"
#ifdef GVS_STACK_PROBE
#include <stdio.h>
#endif
static gvs_state state;
/* the caller's own arithmetic in single precision, as an ECU's would be (CAN signals to double by conversion only):
 * the footprint is the sensor's, not soft-double maths of the test harness */
volatile float in_speed = 1300.0f, in_oil = 80.0f;
volatile float sink;

static void steps(void)
{
    gvs_inputs in;
    gvs_outputs out;
    int i, k;
    for (i = 0; i < GVS_N_INPUTS; ++i) in.raw[i] = 20.0;
    in.raw[GVS_I_GEAR] = @GEAR@;
    in.t_s = NAN;
    for (k = 0; k < 50; ++k) {        /* moving speed and oil: new conductance bins, every law evaluated */
        in.raw[GVS_I_SPEED] = (double)(in_speed + 37.0f * (float)k);
        in.raw[GVS_I_TORQUE] = (double)(100.0f * (float)k);
        in.raw[GVS_I_OIL] = k == 20 ? (double)NAN : (double)(in_oil + 0.3f * (float)k);
        gvs_sensor_step(&state, &in, &out);
    }
    sink = out.T_c[0];
}

int main(void)
{
    gvs_sensor_init(&state, in_oil);
#ifdef GVS_STACK_PROBE
    {
        enum { PAINT_WORDS = 4096 };
        volatile uint32_t *top = (volatile uint32_t *)__builtin_frame_address(0) - 64, *p;
        uint32_t used;
        for (p = top - PAINT_WORDS; p < top; ++p) *p = 0xDEADBEEFu;
        steps();
        for (p = top - PAINT_WORDS; p < top && *p == 0xDEADBEEFu; ++p) {}
        used = (uint32_t)((top - p) * 4u);
        printf("stack used by the steps: %lu bytes (high-water mark)\\nstate: %lu bytes\\n", (unsigned long)used,
               (unsigned long)sizeof state);
    }
#else
    steps();
#endif
    return 0;
}
"""
