"""FMUs on paper: the model description driftfmu's builder writes for a model (from its table,
fmu_src/native_build.py) and, as the binary for this platform, a real shared library of this
machine that is no FMU (the C maths library).  Every check that reads an FMU without loading
it runs on them without building one (the tests of the everyday loop's unit tier, and the
mutation check's)."""
import ctypes.util
import os
import zipfile
from pathlib import Path

from driftfmu.fmu_src import native_build
from driftfmu.simulations import fmucheck


def library():
    """The bytes of a whole shared library of this machine (libm)."""
    import ctypes
    name = ctypes.util.find_library("m") or "libm.so.6"
    path = ctypes.CDLL(name)._name
    for candidate in (path, "/lib/x86_64-linux-gnu/libm.so.6", "/usr/lib/libm.so.6",
                      "/lib64/libm.so.6"):
        if os.path.isabs(candidate) and os.path.isfile(candidate):
            return Path(candidate).read_bytes()
    import glob
    for candidate in glob.glob("/lib*/**/libm.so.6", recursive=True) + \
            glob.glob("/usr/lib*/**/libm.so.6", recursive=True):
        return Path(candidate).read_bytes()
    raise RuntimeError("no libm found")


def paper_fmu(path, name, fmi=2):
    """Write the paper FMU of driftfmu's model ``name`` (FMI 2.0 or 3.0) to ``path``."""
    slave = native_build.slave_class(name)
    if fmi == 2:
        md = native_build.fmi2_model_description(slave, "{paper}", ["%s_step.c" % name],
                                                 log=lambda line: None)
    else:
        md = native_build.fmi3_model_description(slave, "{paper}", log=lambda line: None)
    desc = fmucheck.parse_description(path, md)
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", md)
        z.writestr(fmucheck.binary_member(desc), library())
        z.writestr("documentation/index.html", "<html></html>")
    return Path(path)
