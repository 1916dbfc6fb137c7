"""A minimal FMI 2.0 co-simulation host in standard-library Python (any Python 3).

usage: python ctypes_host.py FMU_DIR MODEL_IDENTIFIER GUID VALUE_REFERENCE STEPS STEP_SIZE

Does what c_host.c does, from inside a Python process (so the FMU finds the Python C API
already loaded), with the same output lines and exit codes.
"""
import ctypes
import sys

fmi2Component = ctypes.c_void_p
LOGGER = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int,
                          ctypes.c_char_p, ctypes.c_char_p)
ALLOCATE = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_size_t, ctypes.c_size_t)
FREE = ctypes.CFUNCTYPE(None, ctypes.c_void_p)


class Callbacks(ctypes.Structure):
    _fields_ = [("logger", LOGGER), ("allocateMemory", ALLOCATE), ("freeMemory", FREE),
                ("stepFinished", ctypes.c_void_p), ("componentEnvironment", ctypes.c_void_p)]


def _log(env, name, status, category, message):
    text = (message or b"").decode("utf-8", "replace").replace("%%", "%")
    print("LOG %d %s: %s" % (status, (category or b"").decode(), text), flush=True)


def main(fmu_dir, model_identifier, guid, vr, steps, step_size):
    lib = ctypes.CDLL("%s/binaries/linux64/%s.so" % (fmu_dir, model_identifier))
    libc = ctypes.CDLL(None)
    libc.calloc.restype = ctypes.c_void_p
    lib.fmi2Instantiate.restype = fmi2Component
    lib.fmi2Instantiate.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p,
                                    ctypes.c_char_p, ctypes.POINTER(Callbacks), ctypes.c_int,
                                    ctypes.c_int]
    callbacks = Callbacks(LOGGER(_log), ALLOCATE(lambda n, size: libc.calloc(n, size)),
                          FREE(lambda p: libc.free(ctypes.c_void_p(p))), None, None)
    c = lib.fmi2Instantiate(b"ctypes_host", 1, guid.encode(),
                            ("file://%s/resources" % fmu_dir).encode(), ctypes.byref(callbacks),
                            0, 0)
    if not c:
        print("INSTANTIATE FAILED", flush=True)
        return 2
    c = fmi2Component(c)

    def check(name, *args):
        status = getattr(lib, name)(c, *args)
        if status > 1:
            print("CALL %s returned %d" % (name, status), flush=True)
            sys.exit(3)

    check("fmi2SetupExperiment", 0, ctypes.c_double(0.0), ctypes.c_double(0.0), 0,
          ctypes.c_double(0.0))
    check("fmi2EnterInitializationMode")
    check("fmi2ExitInitializationMode")
    t = 0.0
    for _ in range(steps):
        check("fmi2DoStep", ctypes.c_double(t), ctypes.c_double(step_size), 1)
        t += step_size
    value = ctypes.c_double()
    check("fmi2GetReal", ctypes.byref(ctypes.c_uint(vr)), ctypes.c_size_t(1), ctypes.byref(value))
    print("VALUE %r" % value.value, flush=True)
    check("fmi2Terminate")
    lib.fmi2FreeInstance.argtypes = [fmi2Component]
    lib.fmi2FreeInstance(c)
    return 0


if __name__ == "__main__":
    fmu_dir, model_identifier, guid, vr, steps, step_size = sys.argv[1:]
    sys.exit(main(fmu_dir, model_identifier, guid, int(vr), int(steps), float(step_size)))
