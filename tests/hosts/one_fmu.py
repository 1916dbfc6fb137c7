"""Instantiate, initialise, step and free one FMU in fmpy, then exit (for tests/test_exit.py)."""
import shutil
import sys

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

md = read_model_description(sys.argv[1])
unzipped = extract(sys.argv[1])
fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                modelIdentifier=md.coSimulation.modelIdentifier, instanceName="exit")
for _ in range(int(sys.argv[2]) if len(sys.argv) > 2 else 1):
    fmu.instantiate()
    fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.doStep(currentCommunicationPoint=0.0, communicationStepSize=1e-3)
    fmu.terminate()
    fmu.fmi2FreeInstance(fmu.component)
fmu.freeLibrary()
shutil.rmtree(unzipped, ignore_errors=True)
