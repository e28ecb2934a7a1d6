/* A path tracker as a co-simulation FMU, FMI 2.0 or FMI 3.0 (-DFMI_VERSION=2 or 3).
 *
 * Steering: Stanley's law (Thrun et al., J. Field Robotics 23(9), 2006, section 9.2;
 * Hoffmann et al., ACC 2007, eq. (4)-(7)) on the cross-track error of the centre of
 * gravity, with the path's curvature as feed-forward and yaw-rate damping:
 *
 *     steer = -heading_err - atan(gain * cte / (softening + v)) + wheelbase * kappa
 *             - yaw_damping * (yaw_rate - v * kappa)
 *
 * Speed: a proportional loop, accel = speed_gain * (v_ref - v).
 *
 * Signs are ISO 8855 (cte positive left of the path, steering positive left): the inputs
 * and outputs are cosim's signals of the same names (docs/fmu.md). Two parameters make the
 * FMU misbehave on purpose, for tests: from fail_at_s on, doStep returns an error; from
 * nan_at_s on, steer_rad is NaN (negative: never).
 *
 * Built by examples/fmu/build.py against the FMI headers fmpy ships (fmpy/c-code). The
 * functions of the standard that cosim does not call are in fmi_unused.c.
 */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if FMI_VERSION == 2
#include "fmi2Functions.h"
typedef fmi2Status Status;
typedef fmi2ValueReference ValueReference;
#define STATUS_OK fmi2OK
#define STATUS_ERROR fmi2Error
#elif FMI_VERSION == 3
#include "fmi3Functions.h"
typedef fmi3Status Status;
typedef fmi3ValueReference ValueReference;
#define STATUS_OK fmi3OK
#define STATUS_ERROR fmi3Error
#else
#error "compile with -DFMI_VERSION=2 or -DFMI_VERSION=3"
#endif

/* Value references: the indices of Model.values (build.py's variable table). */
enum {
    VR_CTE, VR_HEADING_ERR, VR_SPEED, VR_REF_SPEED, VR_CURVATURE, VR_YAW_RATE,
    VR_STEER, VR_ACCEL,
    VR_GAIN, VR_SOFTENING, VR_WHEELBASE, VR_YAW_DAMPING, VR_SPEED_GAIN,
    VR_FAIL_AT, VR_NAN_AT,
    N_VALUES,
    VR_TIME = 100 /* FMI 3's independent variable */
};

typedef struct {
    double values[N_VALUES];
    double time_s;
#if FMI_VERSION == 2
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment environment;
    char name[64];
#else
    fmi3LogMessageCallback logger;
    fmi3InstanceEnvironment environment;
#endif
} Model;

static void log_error(Model *m, const char *message) {
    if (m->logger == NULL) return;
#if FMI_VERSION == 2
    m->logger(m->environment, m->name, fmi2Error, "logStatusError", "%s", message);
#else
    m->logger(m->environment, fmi3Error, "logStatusError", message);
#endif
}

static Model *new_model(void) {
    Model *m = calloc(1, sizeof(Model));
    if (m == NULL) return NULL;
    m->values[VR_GAIN] = 1.5;
    m->values[VR_SOFTENING] = 1.0;
    m->values[VR_WHEELBASE] = 2.8;
    m->values[VR_YAW_DAMPING] = 0.1;
    m->values[VR_SPEED_GAIN] = 1.0;
    m->values[VR_FAIL_AT] = -1.0;
    m->values[VR_NAN_AT] = -1.0;
    return m;
}

/* Back to the start values at t = 0 (fmi2Reset, fmi3Reset). */
static Status reset_model(Model *m) {
    Model *fresh = new_model();
    if (fresh == NULL) return STATUS_ERROR;
    memcpy(m->values, fresh->values, sizeof m->values);
    m->time_s = 0.0;
    free(fresh);
    return STATUS_OK;
}

static Status get_values(Model *m, const ValueReference vr[], size_t n, double out[]) {
    for (size_t i = 0; i < n; i++) {
        if (vr[i] == VR_TIME) { out[i] = m->time_s; continue; }
        if (vr[i] >= N_VALUES) { log_error(m, "unknown value reference"); return STATUS_ERROR; }
        out[i] = m->values[vr[i]];
    }
    return STATUS_OK;
}

static Status set_values(Model *m, const ValueReference vr[], size_t n, const double in[]) {
    for (size_t i = 0; i < n; i++) {
        if (vr[i] >= N_VALUES || vr[i] == VR_STEER || vr[i] == VR_ACCEL) {
            log_error(m, "value reference cannot be set");
            return STATUS_ERROR;
        }
        m->values[vr[i]] = in[i];
    }
    return STATUS_OK;
}

/* The control law over one communication step [t, t + h] with the inputs held. */
static Status do_step(Model *m, double t, double h) {
    double *x = m->values;
    if (x[VR_FAIL_AT] >= 0.0 && t >= x[VR_FAIL_AT]) {
        log_error(m, "fail_at_s reached: this FMU fails on purpose");
        return STATUS_ERROR;
    }
    double v = x[VR_SPEED] > 0.0 ? x[VR_SPEED] : 0.0;
    double kappa = x[VR_CURVATURE];
    x[VR_STEER] = -x[VR_HEADING_ERR]
                  - atan(x[VR_GAIN] * x[VR_CTE] / (x[VR_SOFTENING] + v))
                  + x[VR_WHEELBASE] * kappa
                  - x[VR_YAW_DAMPING] * (x[VR_YAW_RATE] - v * kappa);
    x[VR_ACCEL] = x[VR_SPEED_GAIN] * (x[VR_REF_SPEED] - x[VR_SPEED]);
    if (x[VR_NAN_AT] >= 0.0 && t >= x[VR_NAN_AT]) x[VR_STEER] = NAN;
    m->time_s = t + h;
    return STATUS_OK;
}

#if FMI_VERSION == 2

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)c; (void)loggingOn; (void)nCategories; (void)categories;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    (void)fmuGUID; (void)fmuResourceLocation; (void)visible; (void)loggingOn;
    if (fmuType != fmi2CoSimulation) return NULL;
    Model *m = new_model();
    if (m == NULL) return NULL;
    m->logger = functions != NULL ? functions->logger : NULL;
    m->environment = functions != NULL ? functions->componentEnvironment : NULL;
    snprintf(m->name, sizeof m->name, "%s", instanceName != NULL ? instanceName : "");
    return m;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    ((Model *)c)->time_s = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2Reset(fmi2Component c) { return reset_model(c); }

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    return get_values(c, vr, nvr, value);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    return set_values(c, vr, nvr, value);
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    return do_step(c, currentCommunicationPoint, communicationStepSize);
}

#else /* FMI_VERSION == 3 */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                               size_t nCategories, const fmi3String categories[]) {
    (void)instance; (void)loggingOn; (void)nCategories; (void)categories;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)loggingOn; (void)earlyReturnAllowed; (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables; (void)intermediateUpdate;
    if (eventModeUsed) return NULL; /* this FMU has no event mode */
    Model *m = new_model();
    if (m == NULL) return NULL;
    m->logger = logMessage;
    m->environment = instanceEnvironment;
    return m;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    ((Model *)instance)->time_s = startTime;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3EnterStepMode(fmi3Instance instance) { (void)instance; return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3Reset(fmi3Instance instance) { return reset_model(instance); }

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    if (nValues != nValueReferences) return fmi3Error; /* scalars only */
    return get_values(instance, valueReferences, nValueReferences, values);
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[],
                          size_t nValues) {
    if (nValues != nValueReferences) return fmi3Error; /* scalars only */
    return set_values(instance, valueReferences, nValueReferences, values);
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    (void)noSetFMUStatePriorToCurrentPoint;
    Model *m = instance;
    fmi3Status status = do_step(m, currentCommunicationPoint, communicationStepSize);
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = m->time_s;
    return status;
}

#endif
