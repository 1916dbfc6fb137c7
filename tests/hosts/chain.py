"""Drive tests/hosts/chain_host.c (an FMI 2.0/3.0 host with no Python in the process, for Linux;
cross-compiled with mingw-w64, for Windows under wine; cross-compiled with zig, for aarch64 Linux
under qemu-user) from Python: compile it, write its script for a wired chain of FMUs, run it and
read its rows back as floats."""
import os
import shutil
import struct
import subprocess
import sysconfig
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "chain_host.c"
WINE = "/usr/lib/wine/wine64"
#: qemu-user for aarch64 and the aarch64 glibc it runs a program with (Debian: qemu-user,
#: libc6-arm64-cross).
QEMU_AARCH64 = shutil.which("qemu-aarch64") or shutil.which("qemu-aarch64-static")
AARCH64_SYSROOT = Path("/usr/aarch64-linux-gnu")


def fmi_headers():
    import fmpy
    return Path(fmpy.__file__).resolve().parent / "c-code"


def compile_host(target, windows=False, aarch64=False):
    """Compile the chain host (``windows``: a .exe with x86_64-w64-mingw32-gcc; ``aarch64``: an
    aarch64 Linux program with zig); return it."""
    if aarch64:
        from driftfmu.fmu_src.native_build import ZIG_TARGETS, zig_command
        cc = zig_command() + ["-target", ZIG_TARGETS["aarch64-linux"]]
    else:
        cc = ["x86_64-w64-mingw32-gcc" if windows else os.environ.get("CC", "cc")]
    command = cc + ["-std=c99", "-O2", "-I%s" % fmi_headers(), "-o", str(target), str(SOURCE)]
    command += ["-static-libgcc"] if windows else ["-ldl"]
    subprocess.run(command, check=True, capture_output=True, text=True)
    return Path(target)


def have_aarch64_tools():
    """True when zig, qemu-aarch64 and an aarch64 glibc are installed."""
    from driftfmu.fmu_src.native_build import zig_command
    return bool(zig_command() and QEMU_AARCH64
                and (AARCH64_SYSROOT / "lib" / "ld-linux-aarch64.so.1").exists())


def have_windows_tools():
    """True when mingw-w64 and wine64 are installed."""
    return bool(shutil.which("x86_64-w64-mingw32-gcc")) and os.path.exists(WINE)


def unpack(fmu, folder):
    """Extract ``fmu`` into ``folder``; return (folder, model description)."""
    from fmpy import read_model_description
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
    return folder, read_model_description(str(folder))


def script(fmi, fmus, start_values, connections, record, n, h, quiet=False, relative_to=None):
    """The host's script: ``fmus`` is {instance: (unzipped folder, model description)}."""
    lines = ["fmi %d" % fmi]
    vrs = {name: {v.name: v.valueReference for v in md.modelVariables}
           for name, (_, md) in fmus.items()}
    types = {name: {v.name: v.type for v in md.modelVariables} for name, (_, md) in fmus.items()}
    for name, (folder, md) in fmus.items():
        where = os.path.relpath(folder, relative_to) if relative_to else str(folder)
        lines.append("fmu %s %s %s %s" % (name, Path(where).as_posix(),
                                          md.coSimulation.modelIdentifier, md.guid))
    for name, values in start_values.items():
        for var, value in values.items():
            if types[name][var] in ("Integer", "Int32"):
                lines.append("int %s %d %d" % (name, vrs[name][var], int(value)))
            else:
                lines.append("real %s %d %r" % (name, vrs[name][var], float(value)))
    for s, o, d, i in connections:
        lines.append("link %s %d %s %d" % (s, vrs[s][o], d, vrs[d][i]))
    keys = []
    for name, names in record.items():
        for var in names:
            lines.append("record %s %d" % (name, vrs[name][var]))
            keys.append("%s.%s" % (name, var))
    lines.append("run %d %r%s" % (n, float(h), " quiet" if quiet else ""))
    return "\n".join(lines) + "\n", keys


def python_fmu_env():
    """Environment in which a C host finds the libpython the Python FMUs' loader needs."""
    env = dict(os.environ)
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    env["LD_LIBRARY_PATH"] = libdir + (":" + env["LD_LIBRARY_PATH"]
                                       if env.get("LD_LIBRARY_PATH") else "")
    return env


def run(host, text, keys, cwd, windows=False, env=None, timeout=600, aarch64=False):
    """Run the host on script ``text`` in ``cwd``; return (columns by key, ns per step, output).

    Raises RuntimeError with the host's output when it fails."""
    path = Path(cwd) / "script.txt"
    path.write_text(text)
    command = [WINE, str(host), "script.txt"] if windows else [str(host), "script.txt"]
    if aarch64:
        command = [QEMU_AARCH64, "-L", str(AARCH64_SYSROOT)] + command
    if windows:  # wine's own temporary folder (wine-XXXXXX) in the test's folder
        env = dict(env or os.environ, WINEDEBUG="-all", TMPDIR=str(Path(cwd).resolve()))
    result = subprocess.run(command, cwd=cwd, capture_output=True, text=True, env=env,
                            timeout=timeout)
    out = result.stdout
    if result.returncode != 0:
        raise RuntimeError("chain host failed (%d):\n%s\n%s" % (result.returncode, out[-3000:],
                                                                result.stderr[-2000:]))
    cols = {"time": []}
    cols.update({k: [] for k in keys})
    ns = None
    for line in out.splitlines():
        if line.startswith("ROW"):
            values = [struct.unpack(">d", bytes.fromhex(h))[0] for h in line.split()[1:]]
            cols["time"].append(values[0])
            for k, v in zip(keys, values[1:]):
                cols[k].append(v)
        elif line.startswith("NS_PER_STEP"):
            ns = float(line.split()[1])
    return cols, ns, out
