"""libcosim's trace of an SSP archive: tutti's SSP tests compare tutti's run with it.

usage: reference.py SYSTEM.ssp STEP_SECONDS STEPS COMPONENT.VARIABLE...

Loads the archive with libcosim (libcosimpy's CosimExecution.from_ssp_file, its fixed-step
algorithm with STEP), steps STEPS times and prints, after each step, one CSV line: the time
the step ended at, then each variable's last value (booleans as 0/1). A variable's value
after the step ending at (k+1)·h is what tutti records in the row of step k (docs/ssp.md).
"""

import sys

from libcosimpy.CosimEnums import CosimVariableType
from libcosimpy.CosimExecution import CosimExecution
from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
from libcosimpy.CosimObserver import CosimObserver


def main():
    ssp, step, steps, names = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4:]
    log_output_level(CosimLogLevel.ERROR)
    h = round(step * 1e9)
    ex = CosimExecution.from_ssp_file(ssp, step_size=h)
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    slaves = {}
    for s in ex.slave_infos():
        name = s.name.decode() if isinstance(s.name, bytes) else s.name
        slaves[name] = s.index
    columns = []
    for full in names:
        comp, var = full.split(".", 1)
        index = slaves[comp]
        found = None
        for v in ex.slave_variables(index):
            vname = v.name.decode() if isinstance(v.name, bytes) else v.name
            if vname == var:
                found = v
        if found is None:
            sys.exit(f"{full}: no such variable in libcosim's model of {comp}")
        columns.append((index, found.reference, CosimVariableType(found.type)))
    for k in range(1, steps + 1):
        ex.step(1)
        row = [f"{k * h / 1e9!r}"]
        for index, ref, ty in columns:
            if ty == CosimVariableType.REAL:
                row.append(repr(obs.last_real_values(index, [ref])[0]))
            elif ty == CosimVariableType.INTEGER:
                row.append(str(obs.last_integer_values(index, [ref])[0]))
            elif ty == CosimVariableType.BOOLEAN:
                row.append("1" if obs.last_boolean_values(index, [ref])[0] else "0")
            else:
                sys.exit(f"unsupported type {ty}")
        print(",".join(row))


if __name__ == "__main__":
    main()
