/*
 * The FMI 3.0 functions Integrator.c does not implement, so that importers that resolve
 * every function of the standard up front (fmpy does) can load it. Deliberately compiled
 * without fmi3Functions.h: each stub takes no parameters and returns fmi3Error (3), which
 * is what any call, whatever its arguments, gets on x86_64; the two instantiate functions
 * of the other interfaces return NULL.
 */
#define FMI3_ERROR 3

void *fmi3InstantiateModelExchange(void) { return 0; }
void *fmi3InstantiateScheduledExecution(void) { return 0; }
int fmi3ActivateModelPartition(void) { return FMI3_ERROR; }
int fmi3CompletedIntegratorStep(void) { return FMI3_ERROR; }
int fmi3EnterConfigurationMode(void) { return FMI3_ERROR; }
int fmi3EnterContinuousTimeMode(void) { return FMI3_ERROR; }
int fmi3EnterEventMode(void) { return FMI3_ERROR; }
int fmi3EnterStepMode(void) { return FMI3_ERROR; }
int fmi3EvaluateDiscreteStates(void) { return FMI3_ERROR; }
int fmi3ExitConfigurationMode(void) { return FMI3_ERROR; }
int fmi3GetAdjointDerivative(void) { return FMI3_ERROR; }
int fmi3GetBinary(void) { return FMI3_ERROR; }
int fmi3GetClock(void) { return FMI3_ERROR; }
int fmi3GetContinuousStateDerivatives(void) { return FMI3_ERROR; }
int fmi3GetContinuousStates(void) { return FMI3_ERROR; }
int fmi3GetDirectionalDerivative(void) { return FMI3_ERROR; }
int fmi3GetEventIndicators(void) { return FMI3_ERROR; }
int fmi3GetFloat32(void) { return FMI3_ERROR; }
int fmi3GetInt16(void) { return FMI3_ERROR; }
int fmi3GetInt64(void) { return FMI3_ERROR; }
int fmi3GetInt8(void) { return FMI3_ERROR; }
int fmi3GetIntervalDecimal(void) { return FMI3_ERROR; }
int fmi3GetIntervalFraction(void) { return FMI3_ERROR; }
int fmi3GetNominalsOfContinuousStates(void) { return FMI3_ERROR; }
int fmi3GetNumberOfContinuousStates(void) { return FMI3_ERROR; }
int fmi3GetNumberOfEventIndicators(void) { return FMI3_ERROR; }
int fmi3GetNumberOfVariableDependencies(void) { return FMI3_ERROR; }
int fmi3GetOutputDerivatives(void) { return FMI3_ERROR; }
int fmi3GetShiftDecimal(void) { return FMI3_ERROR; }
int fmi3GetShiftFraction(void) { return FMI3_ERROR; }
int fmi3GetString(void) { return FMI3_ERROR; }
int fmi3GetUInt16(void) { return FMI3_ERROR; }
int fmi3GetUInt32(void) { return FMI3_ERROR; }
int fmi3GetUInt64(void) { return FMI3_ERROR; }
int fmi3GetUInt8(void) { return FMI3_ERROR; }
int fmi3GetVariableDependencies(void) { return FMI3_ERROR; }
int fmi3SetBinary(void) { return FMI3_ERROR; }
int fmi3SetBoolean(void) { return FMI3_ERROR; }
int fmi3SetClock(void) { return FMI3_ERROR; }
int fmi3SetContinuousStates(void) { return FMI3_ERROR; }
int fmi3SetDebugLogging(void) { return FMI3_ERROR; }
int fmi3SetFloat32(void) { return FMI3_ERROR; }
int fmi3SetInt16(void) { return FMI3_ERROR; }
int fmi3SetInt32(void) { return FMI3_ERROR; }
int fmi3SetInt64(void) { return FMI3_ERROR; }
int fmi3SetInt8(void) { return FMI3_ERROR; }
int fmi3SetIntervalDecimal(void) { return FMI3_ERROR; }
int fmi3SetIntervalFraction(void) { return FMI3_ERROR; }
int fmi3SetShiftDecimal(void) { return FMI3_ERROR; }
int fmi3SetShiftFraction(void) { return FMI3_ERROR; }
int fmi3SetString(void) { return FMI3_ERROR; }
int fmi3SetTime(void) { return FMI3_ERROR; }
int fmi3SetUInt16(void) { return FMI3_ERROR; }
int fmi3SetUInt32(void) { return FMI3_ERROR; }
int fmi3SetUInt64(void) { return FMI3_ERROR; }
int fmi3SetUInt8(void) { return FMI3_ERROR; }
int fmi3UpdateDiscreteStates(void) { return FMI3_ERROR; }
