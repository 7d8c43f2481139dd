"""The C of the FMI co-simulation wrappers around the kernel (tools.export.fmu writes one into the FMU).

``CORE_C`` is the sensor instance both FMI versions share: state, the variant's tables with tunable limits, the
latest inputs and outputs; ``do_step`` steps the kernel every 0.1 s of the communication step (which must be a
multiple of it). ``FMI2_C`` and ``FMI3_C`` are the two standard interfaces over it. Value references are laid out in
blocks (``@BLOCKS@`` is filled by tools.export.fmu from the same layout it writes into modelDescription.xml).
"""

CORE_C = r"""#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "gvs_sensor.h"

@BLOCKS@

typedef struct Instance_ Instance;
struct Instance_ {
    gvs_state st;
    gvs_tables tb;
    gvs_real warning_c[GVS_MAX_PUB], critical_c[GVS_MAX_PUB], rest_c[GVS_MAX_PUB];
    double inputs[GVS_N_INPUTS];
    double initial_temp_c, time_s;
    gvs_outputs out;
    int initialised;                             /* PHASE_*: stepping only when PHASE_STEPPING */
    int awaiting;                                /* waiting for the first oil reading (gvs_sensor_start) */
    long waited;                                 /* the 0.1 s steps waited for it */
    const char *name;
    void *env;                                   /* the importer's logger and its environment */
    void (*log)(Instance *m, int error, const char *msg);
    void *logger;
};

enum { PHASE_SETUP = 0, PHASE_STEPPING = 1, PHASE_TERMINATED = 2 };

static void reset(Instance *m)
{
    int i;
    m->tb = GVS_TABLES;
    for (i = 0; i < GVS_MAX_PUB; ++i) {
        m->warning_c[i] = GVS_TABLES.warning_c[i];
        m->critical_c[i] = GVS_TABLES.critical_c[i];
    }
    for (i = 0; i < GVS_N_INPUTS; ++i) m->inputs[i] = INPUT_START[i];
    m->initial_temp_c = NAN;
    m->time_s = 0.0;
    m->initialised = PHASE_SETUP;
    m->awaiting = 0;
    m->waited = 0;
    memset(&m->out, 0, sizeof m->out);
    memset(&m->st, 0, sizeof m->st);             /* no counter of the run before a reset reads on */
}

/* the outputs at the start, before any step: the state as started (levels as kept, the time to limit not yet
 * refreshed: NaN; nothing stepped: mode 2, no input valid), not zeros */
static void publish_state(Instance *m)
{
    int i;
    memset(&m->out, 0, sizeof m->out);
    for (i = 0; i < GVS_MAX_PUB; ++i) {
        m->out.T_c[i] = m->st.T_c[0][GVS_TABLES.published_index[i]];
        m->out.level[i] = m->st.level[i];
        m->out.ttl_s[i] = (gvs_real)NAN;
    }
    m->out.model_oil_temp_c = m->st.T_c[1][GVS_TABLES.i_oil];
    m->out.oil_innovation_c = (gvs_real)NAN;
    m->out.degraded_mode = 2;
    m->out.oil_source = 1;
    memcpy(m->out.rejects, m->st.rejects, sizeof m->out.rejects);
}

/* the state as the parameters and inputs set so far start it, and its outputs (publish_state); without
 * initial_temp_c and a plausible oil input: waiting for the oil (gvs_sensor_start: outputs "not initialised"),
 * as the CAN service waits, so that a reading one step late does not leave every part at the ambient */
static void start_state(Instance *m)
{
    double T0 = m->initial_temp_c == m->initial_temp_c ? m->initial_temp_c : m->inputs[GVS_I_OIL];
    m->waited = 0;
    m->awaiting = !gvs_sensor_start(&m->st, 0.0, T0, m->inputs[GVS_I_AMB], &m->out);
    /* a start at initial_temp_c is no oil reading: the first one is not judged against it */
    if (!m->awaiting && m->initial_temp_c == m->initial_temp_c) m->st.age_s[GVS_I_OIL] = (gvs_real)GVS_OIL_AGE_NONE_S;
    if (!m->awaiting) publish_state(m);
}

/* outputs read before the end of initialisation: the state the values set so far would start (not zeros: a time
 * to limit of 0 would read "at the limit") */
static void outputs_now(Instance *m)
{
    if (m->initialised == PHASE_SETUP) start_state(m);
}

/* the end of initialisation: the tuned limits checked and taken, the state started; 0 or -1 (logged) */
static int exit_init(Instance *m)
{
    int i;
    if (!(m->time_s - m->time_s == 0.0)) {
        m->log(m, 1, "the start time must be a finite time");
        return -1;
    }
    for (i = 0; i < GVS_MAX_PUB; ++i) {
        char msg[200];
        const char *name = i < N_PUB_NAMES ? PUB_NAMES[i] : "?";
        if (!(m->warning_c[i] >= (gvs_real)LIMIT_LO_C && m->warning_c[i] <= (gvs_real)LIMIT_HI_C
              && m->critical_c[i] >= (gvs_real)LIMIT_LO_C && m->critical_c[i] <= (gvs_real)LIMIT_HI_C)) {
            snprintf(msg, sizeof msg, "the limits of %s (warning %g, critical %g degC) must lie in " LIMIT_RANGE_TEXT
                     " degC (as the limits file)", name, (double)m->warning_c[i], (double)m->critical_c[i]);
            m->log(m, 1, msg);
            return -1;
        }
        if (!(m->warning_c[i] < m->critical_c[i] && m->critical_c[i] - m->warning_c[i] > GVS_TABLES.hysteresis_k[i])) {
            snprintf(msg, sizeof msg, "the warning limit of %s (%g degC) must lie below its critical limit (%g degC) "
                     "by more than its hysteresis (%g K)", name, (double)m->warning_c[i], (double)m->critical_c[i],
                     (double)GVS_TABLES.hysteresis_k[i]);
            m->log(m, 1, msg);
            return -1;
        }
        m->rest_c[i] = m->warning_c[i] - GVS_TABLES.hysteresis_k[i];
    }
    m->tb.warning_c = m->warning_c;
    m->tb.critical_c = m->critical_c;
    m->tb.warning_rest_c = m->rest_c;
    if (m->initial_temp_c == m->initial_temp_c && !(m->initial_temp_c >= (double)GVS_TABLES.input_lo[GVS_I_OIL]
                                                     && m->initial_temp_c <= (double)GVS_TABLES.input_hi[GVS_I_OIL])) {
        char msg[200];
        snprintf(msg, sizeof msg, "initial_temp_c = %g degC must be NaN (the first oil input) or within the oil "
                 "input's plausible range, %g..%g degC", m->initial_temp_c, (double)GVS_TABLES.input_lo[GVS_I_OIL],
                 (double)GVS_TABLES.input_hi[GVS_I_OIL]);
        m->log(m, 1, msg);
        return -1;
    }
    start_state(m);
    m->initialised = PHASE_STEPPING;
    return 0;
}

/* one communication step of h seconds from t: h / 0.1 s kernel steps; 0 or -1 (logged) */
static int do_step(Instance *m, double t, double h)
{
    double n_real = h / (double)GVS_TABLES.dt_s;
    long n, k;
    gvs_inputs in;
    int i;
    char msg[200];
    if (m->initialised != PHASE_STEPPING) {
        m->log(m, 1, m->initialised == PHASE_TERMINATED ? "no step after terminate (reset and initialise again)"
                                                        : "no step before the end of initialisation");
        return -1;
    }
    if (!(n_real >= 0.5 && n_real < 1e9)) {                /* NaN, inf, zero, negative, or beyond any run (and a
                                                              * long of 32 bits, as on Windows, holds the count) */
        snprintf(msg, sizeof msg, "the communication step must be a positive multiple of 0.1 s (it is %g s)", h);
        m->log(m, 1, msg);
        return -1;
    }
    n = (long)floor(n_real + 0.5);
    if (fabs(n_real - (double)n) > 1e-6) {
        snprintf(msg, sizeof msg, "the communication step must be a positive multiple of 0.1 s (it is %.9g s)", h);
        m->log(m, 1, msg);
        return -1;
    }
    if (!(t - t == 0.0)) {                                  /* NaN or inf */
        m->log(m, 1, "the communication point must be a finite time");
        return -1;
    }
    if (!(fabs(t - m->time_s) <= 1e-3 * (double)GVS_TABLES.dt_s + 1e-12 * fabs(t))) {   /* rounding, not a skip */
        snprintf(msg, sizeof msg, "a communication step must start where the last one ended, at %.9g s (this one "
                 "starts at %.9g s; this FMU cannot skip or go back)", m->time_s, t);
        m->log(m, 1, msg);
        return -1;
    }
    for (i = 0; i < GVS_N_INPUTS; ++i) in.raw[i] = m->inputs[i];
    in.t_s = NAN;
    for (k = 0; k < n; ++k) {
        if (m->awaiting) {                 /* started at the first plausible oil input, or after the wait */
            if (!gvs_sensor_start(&m->st, (double)m->waited * (double)GVS_TABLES.dt_s, in.raw[GVS_I_OIL],
                                  in.raw[GVS_I_AMB], &m->out)) {
                ++m->waited;
                continue;
            }
            m->awaiting = 0;
        }
#if GVS_EXPORT_TTL
        gvs_ttl_point point;           /* the time to limit refreshed after the step that is due (tuned limits) */
        gvs_step(&m->tb, &GVS_VEHICLE, &m->st, &in, 1, &m->out, &point);
        if (point.due) gvs_ttl_refresh(&m->tb, &GVS_VEHICLE, &point, m->st.ttl_s);
#else
        gvs_step(&m->tb, &GVS_VEHICLE, &m->st, &in, 1, &m->out, 0);
#endif
    }
    m->time_s = t + h;
    return 0;
}

static double real_out(Instance *m, unsigned vr, int *ok)
{
    *ok = 1;
    outputs_now(m);
    if (vr >= VR_T && vr < VR_T + GVS_MAX_PUB) return (double)m->out.T_c[vr - VR_T];
    if (vr >= VR_TTL && vr < VR_TTL + GVS_MAX_PUB) return (double)m->out.ttl_s[vr - VR_TTL];
    if (vr == VR_MODEL_OIL) return (double)m->out.model_oil_temp_c;
    if (vr == VR_INNOVATION) return (double)m->out.oil_innovation_c;
    if (vr >= VR_INPUT && vr < VR_INPUT + GVS_N_INPUTS && INPUT_EXPOSED[vr - VR_INPUT]) return m->inputs[vr - VR_INPUT];
    if (vr >= VR_WARNING && vr < VR_WARNING + GVS_MAX_PUB) return (double)m->warning_c[vr - VR_WARNING];
    if (vr >= VR_CRITICAL && vr < VR_CRITICAL + GVS_MAX_PUB) return (double)m->critical_c[vr - VR_CRITICAL];
    if (vr == VR_INITIAL_TEMP) return m->initial_temp_c;
    if (vr == VR_TIME) return m->time_s;
    *ok = 0;
    return 0.0;
}

static int int_out(Instance *m, unsigned r, long *value)
{
    outputs_now(m);
    if (r >= VR_LEVEL && r < VR_LEVEL + GVS_MAX_PUB) *value = m->out.level[r - VR_LEVEL];
    else if (r == VR_MODE) *value = m->out.degraded_mode;
    else if (r == VR_VALID) *value = m->out.valid_flags;
    else if (r == VR_FROZEN) *value = m->out.frozen_flags;
    else if (r >= VR_REJECT && r < VR_REJECT + GVS_N_REJECT) *value = (long)m->st.rejects[r - VR_REJECT];
    else return -1;
    return 0;
}

/* the variant parameter: this FMU's tables are of one variant; setting it to that value is accepted (an importer
 * applying a parameter set), any other refused; 0 or -1 (logged) */
static int set_variant(Instance *m, unsigned r, const char *value)
{
    if (r != VR_VARIANT) return -1;
    if (value == NULL || strcmp(value, GVS_VARIANT) != 0) {
        m->log(m, 1, "this FMU holds the tables of variant " GVS_VARIANT "; export an FMU of the other variant");
        return -1;
    }
    return 0;
}

/* inputs at any time, parameters before the end of initialisation only; 0 or -1 */
static int set_real(Instance *m, unsigned r, double value)
{
    if (r >= VR_INPUT && r < VR_INPUT + GVS_N_INPUTS) {
        if (!INPUT_EXPOSED[r - VR_INPUT]) return -1;   /* not an input of this FMU (its fixed value stays) */
        m->inputs[r - VR_INPUT] = value;
    }
    else if (m->initialised != PHASE_SETUP) return -1;
    else if (r >= VR_WARNING && r < VR_WARNING + GVS_MAX_PUB) m->warning_c[r - VR_WARNING] = (gvs_real)value;
    else if (r >= VR_CRITICAL && r < VR_CRITICAL + GVS_MAX_PUB) m->critical_c[r - VR_CRITICAL] = (gvs_real)value;
    else if (r == VR_INITIAL_TEMP) m->initial_temp_c = value;
    else return -1;
    return 0;
}
"""

FMI2_C = r"""/* gearbox-vsensor onboard sensor as an FMI 2.0 co-simulation FMU (generated by gearbox-vsensor export-fmu). */
#include "fmi2Functions.h"
@CORE@
typedef struct { Instance core; fmi2CallbackFunctions cb; } Fmu2;

static void log_fmi2(Instance *m, int error, const char *msg)
{
    Fmu2 *f = (Fmu2 *)m;
    if (f->cb.logger) f->cb.logger(f->cb.componentEnvironment, m->name, error ? fmi2Error : fmi2OK, "gvs", "%s", msg);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cat[])
{ (void)c; (void)on; (void)n; (void)cat; return fmi2OK; }

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String location,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging)
{
    Fmu2 *f;
    (void)location; (void)visible; (void)logging;
    if (!cb || !cb->allocateMemory || type != fmi2CoSimulation || !guid || strcmp(guid, GVS_GUID) != 0) return NULL;
    f = (Fmu2 *)cb->allocateMemory(1, sizeof(Fmu2));
    if (!f) return NULL;
    f->cb = *cb;
    f->core.name = name;
    f->core.log = log_fmi2;
    reset(&f->core);
    return f;
}

void fmi2FreeInstance(fmi2Component c)
{
    Fmu2 *f = (Fmu2 *)c;
    if (f) f->cb.freeMemory(f);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol, fmi2Real t0, fmi2Boolean stopDef,
                               fmi2Real t1)
{ (void)tolDef; (void)tol; (void)stopDef; (void)t1; ((Instance *)c)->time_s = t0; return fmi2OK; }

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return exit_init((Instance *)c) ? fmi2Error : fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { ((Instance *)c)->initialised = PHASE_TERMINATED; return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { reset((Instance *)c); return fmi2OK; }

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior)
{ (void)noSetPrior; return do_step((Instance *)c, t, h) ? fmi2Error : fmi2OK; }

fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[])
{
    size_t i;
    int ok;
    for (i = 0; i < n; ++i) {
        value[i] = real_out((Instance *)c, vr[i], &ok);
        if (!ok) return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer value[])
{
    size_t i;
    long v;
    for (i = 0; i < n; ++i) {
        if (int_out((Instance *)c, vr[i], &v)) return fmi2Error;
        value[i] = (fmi2Integer)v;
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[])
{
    size_t i;
    for (i = 0; i < n; ++i)
        if (set_real((Instance *)c, vr[i], value[i])) return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[])
{ (void)c; (void)vr; (void)v; return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[])
{
    size_t i;
    (void)c;
    for (i = 0; i < n; ++i) {
        if (vr[i] != VR_VARIANT) return fmi2Error;
        v[i] = GVS_VARIANT;
    }
    return fmi2OK;
}
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[])
{ (void)c; (void)vr; (void)v; return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[])
{ (void)c; (void)vr; (void)v; return n ? fmi2Error : fmi2OK; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[])
{
    size_t i;
    for (i = 0; i < n; ++i)
        if (set_variant((Instance *)c, vr[i], v[i]) != 0) return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)c; (void)s; return fmi2Error; }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n)
{ (void)c; (void)s; (void)n; return fmi2Error; }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n)
{ (void)c; (void)s; (void)b; (void)n; return fmi2Error; }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s)
{ (void)c; (void)b; (void)n; (void)s; return fmi2Error; }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu,
                                        const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[])
{ (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz; return fmi2Error; }
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                       const fmi2Integer o[], const fmi2Real v[])
{ (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error; }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                        const fmi2Integer o[], fmi2Real v[])
{ (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error; }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *v)
{ (void)c; (void)s; (void)v; return fmi2Discard; }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *v)
{ Instance *m = (Instance *)c; if (s == fmi2LastSuccessfulTime) { *v = m->time_s; return fmi2OK; } return fmi2Discard; }
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *v)
{ (void)c; (void)s; (void)v; return fmi2Discard; }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *v)
{ (void)c; (void)s; (void)v; return fmi2Discard; }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *v)
{ (void)c; (void)s; (void)v; return fmi2Discard; }
"""

FMI3_C = r"""/* gearbox-vsensor onboard sensor as an FMI 3.0 co-simulation FMU (generated by gearbox-vsensor export-fmu). */
#include "fmi3Functions.h"
@CORE@
typedef struct { Instance core; fmi3LogMessageCallback logger; fmi3InstanceEnvironment env; } Fmu3;

static void log_fmi3(Instance *m, int error, const char *msg)
{
    Fmu3 *f = (Fmu3 *)m;
    if (f->logger) f->logger(f->env, error ? fmi3Error : fmi3OK, "gvs", msg);
}

static fmi3Status unsupported(fmi3Instance instance)
{
    if (instance) log_fmi3((Instance *)instance, 1, "not supported by this FMU (co-simulation, no FMU state)");
    return fmi3Error;
}

const char *fmi3GetVersion(void) { return fmi3Version; }
fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{ (void)instance; (void)loggingOn; (void)nCategories; (void)categories; return fmi3OK; }

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage)
{
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "gvs", "this FMU is co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    Fmu3 *f;
    (void)resourcePath; (void)visible; (void)loggingOn; (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    if (!instantiationToken || strcmp(instantiationToken, GVS_GUID) != 0 || eventModeUsed) {
        if (logMessage) logMessage(instanceEnvironment, fmi3Error, "gvs",
                                   "wrong instantiation token, or event mode requested (this FMU has no events)");
        return NULL;
    }
    f = (Fmu3 *)calloc(1, sizeof(Fmu3));
    if (!f) return NULL;
    f->logger = logMessage;
    f->env = instanceEnvironment;
    f->core.name = instanceName;
    f->core.log = log_fmi3;
    reset(&f->core);
    return f;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible; (void)loggingOn;
    (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage) logMessage(instanceEnvironment, fmi3Error, "gvs", "this FMU is co-simulation only");
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    ((Instance *)instance)->time_s = startTime;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{ return exit_init((Instance *)instance) ? fmi3Error : fmi3OK; }
fmi3Status fmi3EnterStepMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance instance) { ((Instance *)instance)->initialised = PHASE_TERMINATED; return fmi3OK; }
fmi3Status fmi3Reset(fmi3Instance instance) { reset((Instance *)instance); return fmi3OK; }

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime)
{
    Instance *m = (Instance *)instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    if (do_step(m, currentCommunicationPoint, communicationStepSize)) return fmi3Error;
    *lastSuccessfulTime = m->time_s;
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          fmi3Float64 values[], size_t nValues)
{
    size_t i;
    int ok;
    if (nValues != nValueReferences) return fmi3Error;
    for (i = 0; i < nValueReferences; ++i) {
        values[i] = real_out((Instance *)instance, valueReferences[i], &ok);
        if (!ok) return fmi3Error;
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                          const fmi3Float64 values[], size_t nValues)
{
    size_t i;
    if (nValues != nValueReferences) return fmi3Error;
    for (i = 0; i < nValueReferences; ++i)
        if (set_real((Instance *)instance, valueReferences[i], values[i])) return fmi3Error;
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Int32 values[], size_t nValues)
{
    size_t i;
    long v;
    if (nValues != nValueReferences) return fmi3Error;
    for (i = 0; i < nValueReferences; ++i) {
        if (int_out((Instance *)instance, valueReferences[i], &v)) return fmi3Error;
        values[i] = (fmi3Int32)v;
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        fmi3Int64 values[], size_t nValues)
{
    size_t i;
    long v;
    if (nValues != nValueReferences) return fmi3Error;
    for (i = 0; i < nValueReferences; ++i) {
        if (int_out((Instance *)instance, valueReferences[i], &v)) return fmi3Error;
        values[i] = (fmi3Int64)v;
    }
    return fmi3OK;
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                        const fmi3Int32 values[], size_t nValues)
{ (void)valueReferences; (void)values; (void)nValues; return nValueReferences ? unsupported(instance) : fmi3OK; }

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         fmi3String values[], size_t nValues)
{
    size_t i;
    (void)instance;
    if (nValues != nValueReferences) return fmi3Error;
    for (i = 0; i < nValueReferences; ++i) {
        if (valueReferences[i] != VR_VARIANT) return fmi3Error;
        values[i] = GVS_VARIANT;
    }
    return fmi3OK;
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences,
                         const fmi3String values[], size_t nValues)
{
    size_t i;
    if (nValues != nValueReferences) return fmi3Error;
    for (i = 0; i < nValueReferences; ++i)
        if (set_variant((Instance *)instance, valueReferences[i], values[i]) != 0) return fmi3Error;
    return fmi3OK;
}

/* the rest of the FMI 3 interface: not supported by a co-simulation FMU without FMU state, clocks or derivatives */
fmi3Status fmi3EnterEventMode(fmi3Instance instance) { return unsupported(instance); }
fmi3Status fmi3GetFloat32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float32 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3GetInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int8 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3GetUInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt8 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3GetInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Int16 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3GetUInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt16 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3GetUInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt32 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3GetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Boolean values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, size_t valueSizes[], fmi3Binary values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Clock values[]) { return unsupported(instance); }
fmi3Status fmi3SetFloat32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float32 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3SetInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int8 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3SetUInt8(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt8 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3SetInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int16 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3SetUInt16(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt16 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3SetUInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt32 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3SetInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int64 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3SetUInt64(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Boolean values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const size_t valueSizes[], const fmi3Binary values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Clock values[]) { return unsupported(instance); }
fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference, size_t* nDependencies) { return unsupported(instance); }
fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent, size_t elementIndicesOfDependent[], fmi3ValueReference independents[], size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[], size_t nDependencies) { return unsupported(instance); }
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState* FMUState) { return unsupported(instance); }
fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) { return unsupported(instance); }
fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState* FMUState) { return unsupported(instance); }
fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t* size) { return unsupported(instance); }
fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[], size_t size) { return unsupported(instance); }
fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size, fmi3FMUState* FMUState) { return unsupported(instance); }
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) { return unsupported(instance); }
fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[], size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) { return unsupported(instance); }
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) { return unsupported(instance); }
fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) { return unsupported(instance); }
fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) { return unsupported(instance); }
fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]) { return unsupported(instance); }
fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3Float64 shifts[]) { return unsupported(instance); }
fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, fmi3UInt64 counters[], fmi3UInt64 resolutions[]) { return unsupported(instance); }
fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float64 intervals[]) { return unsupported(instance); }
fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) { return unsupported(instance); }
fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Float64 shifts[]) { return unsupported(instance); }
fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) { return unsupported(instance); }
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) { return unsupported(instance); }
fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean* discreteStatesNeedUpdate, fmi3Boolean* terminateSimulation, fmi3Boolean* nominalsOfContinuousStatesChanged, fmi3Boolean* valuesOfContinuousStatesChanged, fmi3Boolean* nextEventTimeDefined, fmi3Float64* nextEventTime) { return unsupported(instance); }
fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) { return unsupported(instance); }
fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint, fmi3Boolean* enterEventMode, fmi3Boolean* terminateSimulation) { return unsupported(instance); }
fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) { return unsupported(instance); }
fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[], size_t nContinuousStates) { return unsupported(instance); }
fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[], size_t nContinuousStates) { return unsupported(instance); }
fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) { return unsupported(instance); }
fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) { return unsupported(instance); }
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates) { return unsupported(instance); }
fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t* nEventIndicators) { return unsupported(instance); }
fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t* nContinuousStates) { return unsupported(instance); }
fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference valueReferences[], size_t nValueReferences, const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) { return unsupported(instance); }
fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference, fmi3Float64 activationTime) { return unsupported(instance); }
"""


def fmu_c(fmi_version: int, blocks: str) -> str:
    """The wrapper's C for FMI ``fmi_version`` (2 or 3) with the value-reference ``blocks`` filled in."""
    wrapper = FMI2_C if fmi_version == 2 else FMI3_C
    return wrapper.replace("@CORE@", CORE_C.replace("@BLOCKS@", blocks))
