"""Internal (not a stable API; use driftfmu.build_fmus and driftfmu.simulate instead).

XML Schema parsing that threads cannot break.

libxml2 sets up its built-in XML Schema types lazily, on the first schema a process parses.  When
two threads parse their first schema at the same moment, that set-up races and can leave the
whole process unable to parse any schema again ("Document is not valid XML Schema", then
"xmlSchemaPValAttrNodeValue, the given type is not a built-in type" for every later parse; seen
with lxml 6.0.2 and 6.2.0 on libxml2 2.14.6; ``tools/lxml_schema_race.py`` reproduces it
outside driftfmu).  fmpy parses the FMI schema on every validating
``read_model_description`` and ``validate_fmu``.

:func:`prime` parses one small schema, once per process and under a lock, so that the set-up is
done before any other parse.  Every path of driftfmu that reaches fmpy's schema parsing goes
through :func:`read_model_description` or :func:`validate_fmu` here (which prime first), and every
entry point that starts threads calls :func:`prime` before it starts them.

Python's own parser has a race of its kind too.  CPython 3.11 counts the depth of the ``ast``
objects it builds (``ast.parse``, ``ast.literal_eval``) in one counter per interpreter.  When a
garbage collection inside one thread's build runs Python code (a ``__del__``), another thread may
build meanwhile, and the first build then fails with "SystemError: AST constructor recursion
depth mismatch".  fmpy's validation of an FMU with structured variable names builds ``ast``
objects (lark loads its grammar with ``literal_eval``): CI saw DualDriftEstimator.fmu refused
so while the native twins were zipped and validated in two threads.  Every build of ``ast``
objects in driftfmu holds :data:`AST_LOCK`: :func:`validate_fmu` and :func:`parse_python`.
"""
import ast
import threading

#: The smallest schema: parsing it runs libxml2's one-time set-up.
SMALL = (b'<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema">'
         b'<xs:element name="a" type="xs:string"/></xs:schema>')

_LOCK = threading.Lock()
_READY = False

#: Held while driftfmu's code builds ``ast`` objects (see the module's description).
AST_LOCK = threading.RLock()


def prime():
    """Parse one small XML Schema unless this process already has: afterwards any number of
    threads may parse schemas at once.  Safe to call from any thread, as often as wanted."""
    global _READY
    if _READY:
        return
    with _LOCK:
        if not _READY:
            from lxml import etree
            etree.XMLSchema(etree.XML(SMALL))
            _READY = True


def read_model_description(filename, validate=True):
    """``fmpy.read_model_description`` after :func:`prime`."""
    prime()
    import fmpy
    return fmpy.read_model_description(str(filename), validate=validate)


def validate_fmu(filename):
    """``fmpy.validation.validate_fmu`` (a list of problems) after :func:`prime`, holding
    :data:`AST_LOCK`."""
    prime()
    from fmpy.validation import validate_fmu as fmpy_validate_fmu
    with AST_LOCK:
        return fmpy_validate_fmu(str(filename))


def parse_python(source):
    """``ast.parse(source)`` holding :data:`AST_LOCK`."""
    with AST_LOCK:
        return ast.parse(source)
