"""Run several FMUs with fmpy inside one Python process; report each run as a JSON line.

usage: python fmpy_host.py JOBS

JOBS is a JSON list of ``{"fmu": path, "start": {name: value}, "steps": n, "read": name}``.
Every FMU is instantiated (debug logging off) before any is stepped, so FMUs that share a
model identifier run side by side.  For each job one line ``RESULT {"value": ..., "error":
...}`` is printed after all steps; fmpy's logger prints the FMUs' messages as they come.
"""
import json
import shutil
import sys

import fmpy
from fmpy.fmi2 import FMU2Slave


def main(jobs):
    runs, folders = [], []
    for i, job in enumerate(jobs):
        unzipped = fmpy.extract(job["fmu"])
        folders.append(unzipped)
        md = fmpy.read_model_description(unzipped)
        variables = {v.name: v for v in md.modelVariables}
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                        modelIdentifier=md.coSimulation.modelIdentifier, instanceName="run%d" % i)
        fmu.instantiate(loggingOn=False)
        runs.append((job, fmu, variables, float(md.defaultExperiment.stepSize)))
    for job, fmu, variables, h in runs:
        result = {"value": None, "error": None}
        try:
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
            for name, value in job.get("start", {}).items():
                v = variables[name]
                setter = fmu.setReal if v.type == "Real" else fmu.setInteger
                setter([v.valueReference], [value])
            fmu.exitInitializationMode()
            for k in range(job["steps"]):
                fmu.doStep(k * h, h)
            result["value"] = fmu.getReal([variables[job["read"]].valueReference])[0]
        except Exception as exc:  # report the failing call, keep running the others
            result["error"] = str(exc)
        print("RESULT " + json.dumps(result), flush=True)
    for folder in folders:  # the FMUs stay loaded; their unzipped files are not needed now
        shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main(json.loads(sys.argv[1]))
