/* The functions of the FMI standard that cosim never calls on stanley.c's FMU.
 *
 * fmpy resolves every function of its FMI 2 or FMI 3 co-simulation class when it loads an
 * FMU's library, so the library must export them all. These return the error status
 * (fmi2Error = fmi3Error = 3) and do nothing else; they are compiled without the FMI
 * headers, with no parameters, because nothing calls them (a caller's arguments would be
 * ignored under the C calling conventions of x86-64 and AArch64). A real FMU implements
 * what its model description promises (getting and setting its state, other types ...).
 */

#define UNUSED(name) int name(void) { return 3; }

#if FMI_VERSION == 2
UNUSED(fmi2CancelStep) UNUSED(fmi2DeSerializeFMUstate) UNUSED(fmi2FreeFMUstate)
UNUSED(fmi2GetBoolean) UNUSED(fmi2GetBooleanStatus) UNUSED(fmi2GetDirectionalDerivative)
UNUSED(fmi2GetFMUstate) UNUSED(fmi2GetInteger) UNUSED(fmi2GetIntegerStatus)
UNUSED(fmi2GetRealOutputDerivatives) UNUSED(fmi2GetRealStatus) UNUSED(fmi2GetStatus)
UNUSED(fmi2GetString) UNUSED(fmi2GetStringStatus) UNUSED(fmi2SerializeFMUstate)
UNUSED(fmi2SerializedFMUstateSize) UNUSED(fmi2SetBoolean) UNUSED(fmi2SetFMUstate)
UNUSED(fmi2SetInteger) UNUSED(fmi2SetRealInputDerivatives) UNUSED(fmi2SetString)
#elif FMI_VERSION == 3
UNUSED(fmi3ActivateModelPartition) UNUSED(fmi3CompletedIntegratorStep)
UNUSED(fmi3DeserializeFMUState) UNUSED(fmi3EnterConfigurationMode)
UNUSED(fmi3EnterContinuousTimeMode) UNUSED(fmi3EnterEventMode)
UNUSED(fmi3EvaluateDiscreteStates) UNUSED(fmi3ExitConfigurationMode)
UNUSED(fmi3FreeFMUState) UNUSED(fmi3GetAdjointDerivative) UNUSED(fmi3GetBinary)
UNUSED(fmi3GetBoolean) UNUSED(fmi3GetClock) UNUSED(fmi3GetContinuousStateDerivatives)
UNUSED(fmi3GetContinuousStates) UNUSED(fmi3GetDirectionalDerivative)
UNUSED(fmi3GetEventIndicators) UNUSED(fmi3GetFMUState) UNUSED(fmi3GetFloat32)
UNUSED(fmi3GetInt16) UNUSED(fmi3GetInt32) UNUSED(fmi3GetInt64) UNUSED(fmi3GetInt8)
UNUSED(fmi3GetIntervalDecimal) UNUSED(fmi3GetIntervalFraction)
UNUSED(fmi3GetNominalsOfContinuousStates) UNUSED(fmi3GetNumberOfContinuousStates)
UNUSED(fmi3GetNumberOfEventIndicators) UNUSED(fmi3GetNumberOfVariableDependencies)
UNUSED(fmi3GetOutputDerivatives) UNUSED(fmi3GetShiftDecimal) UNUSED(fmi3GetShiftFraction)
UNUSED(fmi3GetString) UNUSED(fmi3GetUInt16) UNUSED(fmi3GetUInt32) UNUSED(fmi3GetUInt64)
UNUSED(fmi3GetUInt8) UNUSED(fmi3GetVariableDependencies)
UNUSED(fmi3InstantiateModelExchange) UNUSED(fmi3InstantiateScheduledExecution)
UNUSED(fmi3SerializeFMUState) UNUSED(fmi3SerializedFMUStateSize) UNUSED(fmi3SetBinary)
UNUSED(fmi3SetBoolean) UNUSED(fmi3SetClock) UNUSED(fmi3SetContinuousStates)
UNUSED(fmi3SetFMUState) UNUSED(fmi3SetFloat32) UNUSED(fmi3SetInt16) UNUSED(fmi3SetInt32)
UNUSED(fmi3SetInt64) UNUSED(fmi3SetInt8) UNUSED(fmi3SetIntervalDecimal)
UNUSED(fmi3SetIntervalFraction) UNUSED(fmi3SetShiftDecimal) UNUSED(fmi3SetShiftFraction)
UNUSED(fmi3SetString) UNUSED(fmi3SetTime) UNUSED(fmi3SetUInt16) UNUSED(fmi3SetUInt32)
UNUSED(fmi3SetUInt64) UNUSED(fmi3SetUInt8) UNUSED(fmi3UpdateDiscreteStates)
#endif
