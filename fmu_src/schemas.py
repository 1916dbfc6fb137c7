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
"""
import threading

#: The smallest schema: parsing it runs libxml2's one-time set-up.
SMALL = (b'<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema">'
         b'<xs:element name="a" type="xs:string"/></xs:schema>')

_LOCK = threading.Lock()
_READY = False


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
    """``fmpy.validation.validate_fmu`` (a list of problems) after :func:`prime`."""
    prime()
    from fmpy.validation import validate_fmu as fmpy_validate_fmu
    return fmpy_validate_fmu(str(filename))
