"""The edits of an independent tampering campaign (issue 40), each a few lines: unzip an FMU,
edit it, zip it again.  Every edit is written from the model's own table
(``fmu_src/<Name>.py``'s ``VARIABLES``), so it applies to every FMU kind (Python, native FMI 2.0
and 3.0) and to models added later."""
import re
import struct
import zipfile
import zlib
from pathlib import Path

from driftfmu.simulations import fmucheck


def rewrite(src, dst, md=None, members=None, drop=(), add=None):
    """Copy the FMU ``src`` to ``dst``: ``md(text) -> text`` edits modelDescription.xml,
    ``members[name](bytes) -> bytes`` edits a member (None drops it), ``drop`` drops members by
    prefix, ``add`` adds members."""
    members = dict(members or {})
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for item in zin.infolist():
            if any(item.filename.startswith(d) for d in drop):
                continue
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml" and md is not None:
                data = md(data.decode("utf-8")).encode("utf-8")
            if item.filename in members:
                data = members[item.filename](data)
                if data is None:
                    continue
            zout.writestr(item.filename, data)
        for name, data in (add or {}).items():
            zout.writestr(name, data)
    return Path(dst)


def model_of(fmu):
    with zipfile.ZipFile(fmu) as z:
        return fmucheck.parse_description(fmu, z.read("modelDescription.xml"))


def _variable_pattern(fmi, name):
    """The regex of variable ``name``'s element (FMI 2.0: its ScalarVariable with its type
    element; FMI 3.0: its typed element)."""
    if fmi == 2:
        return re.compile(r'<ScalarVariable name="%s"[^>]*>.*?</ScalarVariable>\s*'
                          % re.escape(name), re.S)
    return re.compile(r'<(Float64|Int32)\s+name="%s"[^>]*?(/>|>.*?</\1>)\s*' % re.escape(name),
                      re.S)


def _set_attribute(element, attribute, value):
    if re.search(r'\b%s="[^"]*"' % attribute, element):
        return re.sub(r'\b%s="[^"]*"' % attribute, '%s="%s"' % (attribute, value), element,
                      count=1)
    return element.replace("/>", ' %s="%s"/>' % (attribute, value), 1)


def edit_variable(text, fmi, name, attribute, value):
    """The model description ``text`` with ``attribute`` of variable ``name`` set to ``value``
    (``start``, ``min``, ``max`` go to the type element in FMI 2.0)."""
    pattern = _variable_pattern(fmi, name)
    element = pattern.search(text).group(0)
    if fmi == 2 and attribute in ("start", "min", "max"):
        typed = re.search(r"<(Real|Integer)\b[^>]*/>", element).group(0)
        new = element.replace(typed, _set_attribute(typed, attribute, value))
    else:
        new = _set_attribute(element, attribute, value) if fmi == 3 else re.sub(
            r'\b%s="[^"]*"' % attribute, '%s="%s"' % (attribute, value), element, count=1)
    return text.replace(element, new)


def outputs(fmu):
    return [v for v in model_of(fmu).variables if v.causality == "output"]


def binary(fmu):
    return fmucheck.binary_member(model_of(fmu))


def _swap_vrs(src, dst):
    desc, (a, b) = model_of(src), outputs(src)[:2]

    def md(text):
        text = edit_variable(text, desc.fmi, a.name, "valueReference", "@@")
        text = edit_variable(text, desc.fmi, b.name, "valueReference", str(a.vr))
        return text.replace('valueReference="@@"', 'valueReference="%d"' % b.vr)
    return rewrite(src, dst, md)


def _shared_vr(src, dst):
    desc, (a, b) = model_of(src), outputs(src)[:2]
    return rewrite(src, dst, lambda t: edit_variable(t, desc.fmi, a.name, "valueReference",
                                                     str(b.vr)))


def _remove_variable(src, dst):
    desc, a = model_of(src), outputs(src)[-1]
    return rewrite(src, dst, lambda t: _variable_pattern(desc.fmi, a.name).sub("", t, count=1))


def _extra_variable(src, dst):
    desc = model_of(src)
    if desc.fmi == 2:
        extra = ('<ScalarVariable name="extra" valueReference="999" causality="output" '
                 'variability="continuous"><Real/></ScalarVariable>')
    else:
        extra = ('<Float64 name="extra" valueReference="999" causality="output" '
                 'variability="continuous"/>')
    return rewrite(src, dst, lambda t: t.replace("</ModelVariables>",
                                                 extra + "</ModelVariables>", 1))


def _start(name, value):
    def edit(src, dst):
        desc = model_of(src)
        return rewrite(src, dst, lambda t: edit_variable(t, desc.fmi, name, "start", value))
    return edit


def _attribute(pick, attribute, value):
    def edit(src, dst):
        desc = model_of(src)
        name = pick(desc)
        return rewrite(src, dst, lambda t: edit_variable(t, desc.fmi, name, attribute, value))
    return edit


def _root(attribute, value):
    def edit(src, dst):
        return rewrite(src, dst, lambda t: re.sub(r'\b%s="[^"]*"' % attribute,
                                                  '%s="%s"' % (attribute, value), t, count=1))
    return edit


def _type(src, dst):
    desc = model_of(src)
    real = next(v for v in desc.variables if v.causality == "parameter" and v.type in
                ("Real", "Float64"))
    pattern = _variable_pattern(desc.fmi, real.name)

    def md(text):
        element = pattern.search(text).group(0)
        if desc.fmi == 2:
            new = re.sub(r"<Real\b", "<Integer", element)
            new = re.sub(r'(<Integer[^>]*?)\s(unit|start|min|max)="[^"]*"', r"\1", new)
        else:
            new = re.sub(r"^<Float64\b", "<Int32", element.lstrip())
        return text.replace(element, new)
    return rewrite(src, dst, md)


def _binary(edit):
    def change(src, dst):
        return rewrite(src, dst, members={binary(src): edit})
    return change


def _rename_binary(src, dst):
    name = binary(src)
    with zipfile.ZipFile(src) as z:
        data = z.read(name)
    return rewrite(src, dst, members={name: lambda d: None},
                   add={name.rsplit("/", 1)[0] + "/Renamed" + Path(name).suffix: data})


def _md_cut(src, dst):
    return rewrite(src, dst, lambda t: t[:len(t) // 2])


def _duplicate_member(src, dst):
    with zipfile.ZipFile(src) as z:
        data = z.read("modelDescription.xml")
    import warnings
    rewrite(src, dst)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # zipfile: "Duplicate name"
        with zipfile.ZipFile(dst, "a") as z:
            z.writestr("modelDescription.xml", data.replace(b'valueReference="0"',
                                                              b'valueReference="77"', 1))
    return Path(dst)


def _restored(src, dst):
    """A harmless edit: every member stored instead of deflated, in another order, with the
    model description's description changed (the FMU as another zip tool writes it)."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_STORED) as zout:
        for item in reversed(zin.infolist()):
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml":
                data = re.sub(rb'description="[^"]*"', b'description="re-packed"', data, count=1)
            zout.writestr(item.filename, data)
    return Path(dst)


def _start_same_value(src, dst):
    """A harmless edit: a start value written another way (``0.001`` as ``1e-3``)."""
    desc = model_of(src)
    ts = next(v for v in desc.variables if v.name == "Ts")
    return rewrite(src, dst, lambda t: edit_variable(t, desc.fmi, "Ts", "start",
                                                     "%.0e" % float(ts.start)))


def first_parameter_with(names):
    def pick(desc):
        return next(v.name for v in desc.variables if v.name in names)
    return pick


#: name -> (edit(src, dst), the models it applies to or None for all, harmless?)
EDITS = {
    "swapped value references": (_swap_vrs, None, False),
    "one value reference for two outputs": (_shared_vr, None, False),
    "a variable removed": (_remove_variable, None, False),
    "a variable added": (_extra_variable, None, False),
    "A = 1.5": (_start("A", "1.5"), ("Excitation", "DriftEstimator", "DualDriftEstimator"), False),
    "R = -1": (_start("R", "-1"), ("Accelerometer", "DriftEstimator", "DualDriftEstimator"),
               False),
    "Ts = 0": (_start("Ts", "0"), None, False),
    "estimator = 7": (_start("estimator", "7"), ("DriftEstimator", "DualDriftEstimator"), False),
    "a start value in range, not the FMU's": (_start("Ts", "0.002"), None, False),
    "a declared max widened": (_attribute(first_parameter_with(("A", "cross", "rho")), "max",
                                          "5"), None, False),
    "a type changed": (_type, None, False),
    "a causality changed": (_attribute(lambda d: next(v.name for v in d.variables
                                                      if v.causality == "output"),
                                       "causality", "local"), None, False),
    "the GUID changed": (_root("guid", "{00000000-1111-2222-3333-444444444444}"), None, False),
    "the instantiation token changed": (_root("instantiationToken", "{0-1-2-3-4}"), None, False),
    "the model identifier changed": (_root("modelIdentifier", "Renamed"), None, False),
    "the model name changed": (_root("modelName", "Renamed"), None, False),
    "the FMI version changed": (_root("fmiVersion", "1.0"), None, False),
    "the model description cut": (_md_cut, None, False),
    "modelDescription.xml twice": (_duplicate_member, None, False),
    "the binary cut in half": (_binary(lambda d: d[:len(d) // 2]), None, False),
    "the binary's headers only": (_binary(lambda d: d[:4096]), None, False),
    "the binary zeroed": (_binary(lambda d: bytes(len(d))), None, False),
    "the binary renamed": (_rename_binary, None, False),
    "no binary": (lambda s, d: rewrite(s, d, drop=(binary(s).rsplit("/", 1)[0] + "/",)), None,
                  False),
    "re-packed by another tool": (_restored, None, True),
    "a start value written another way": (_start_same_value, None, True),
}


def applies(edit, model, fmi):
    _, models, _ = EDITS[edit]
    if edit == "the GUID changed" and fmi != 2 or \
            edit == "the instantiation token changed" and fmi != 3:
        return False
    return models is None or model in models


# -- a zip bomb -------------------------------------------------------------------------------

def zip_bomb(src, dst, member="resources/bomb.bin", size=3 << 30):
    """The FMU ``src`` with one more member of ``size`` zero bytes (3 GiB: about 3 MB
    compressed), written by hand: a raw deflate stream of identical fully flushed blocks, its
    CRC-32 and sizes declared as zipfile writes them (no ZIP64 below 4 GiB)."""
    chunk = 1 << 20
    c = zlib.compressobj(9, zlib.DEFLATED, -15)
    block = c.compress(bytes(chunk)) + c.flush(zlib.Z_FULL_FLUSH)
    tail = c.flush()
    crc, zeros = 0, bytes(chunk)
    for _ in range(size // chunk):
        crc = zlib.crc32(zeros, crc)
    entries = []
    with zipfile.ZipFile(src) as z:
        for item in z.infolist():
            data = z.read(item.filename)
            d = zlib.compressobj(6, zlib.DEFLATED, -15)
            packed = d.compress(data) + d.flush()
            entries.append((item.filename.encode(), [packed], len(packed), len(data),
                            zlib.crc32(data)))
    count = size // chunk
    entries.append((member.encode(), [block] * count + [tail], len(block) * count + len(tail),
                    size, crc))
    with open(dst, "wb") as out:
        central = b""
        for name, pieces, csize, usize, ccrc in entries:
            offset = out.tell()
            out.write(struct.pack("<IHHHHHIIIHH", 0x04034B50, 20, 0, 8, 0, 0x21, ccrc, csize,
                                  usize, len(name), 0) + name)
            for piece in pieces:
                out.write(piece)
            central += struct.pack("<IHHHHHHIIIHHHHHII", 0x02014B50, 20, 20, 0, 8, 0, 0x21,
                                   ccrc, csize, usize, len(name), 0, 0, 0, 0, 0o644 << 16,
                                   offset) + name
        start = out.tell()
        out.write(central)
        out.write(struct.pack("<IHHHHIIH", 0x06054B50, 0, 0, len(entries), len(entries),
                              len(central), start, 0))
    return Path(dst)
