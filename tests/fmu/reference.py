"""Reference trajectory of an FMU simulated standalone by fmpy, for tests/cli/fmu_run.rs.

usage: reference.py FMU START STEPS H INPUT_NAME INPUT_VALUE PARAMS_JSON OUTPUTS_CSV
Prints one CSV row per communication step after the start: the step number (1..STEPS) and
the named outputs (booleans as 0/1), with the given constant input and parameters.
"""

import json
import sys

import numpy as np
from fmpy import simulate_fmu

fmu, start, steps, h, input_name, input_value, params, outputs = sys.argv[1:9]
start, steps, h, input_value = float(start), int(steps), float(h), float(input_value)
outputs = outputs.split(",")
signal = np.array([(start, input_value)], dtype=[("time", np.float64), (input_name, np.float64)])
result = simulate_fmu(
    fmu,
    start_time=start,
    stop_time=start + steps * h,
    output_interval=h,
    input=signal,
    start_values=json.loads(params),
    output=outputs,
    fmi_type="CoSimulation",
)
# Row 0 is the state at the start; row n the state after n steps.
for n in range(1, len(result)):
    row = [repr(float(result[name][n])) for name in outputs]
    print(",".join([str(n)] + row))
