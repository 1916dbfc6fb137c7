"""Reproducer: threads that parse their process's first XML Schema at once break libxml2.

Self-contained (needs only lxml), for lxml's or libxml2's tracker.  Each of ``--processes``
fresh Python processes parses a small schema document, then releases ``--threads`` threads
together into ``lxml.etree.XMLSchema(document)``.  A process is *broken* when any of those
parses raises (``XMLSchemaParseError: Document is not valid XML Schema``) or when a parse
after them fails (``Internal error: xmlSchemaPValAttrNodeValue, the given type is not a
built-in type``, from then on for every schema).  With ``--prime`` each process first parses
one schema alone; that has never broken one here.

    python tools/lxml_schema_race.py                 # e.g. "broken 28 of 100 processes"
    python tools/lxml_schema_race.py --prime         # "broken 0 of 100 processes"

Exit status 1 when a process broke, 0 when none did.  Seen with lxml 6.0.2 and 6.2.0 on
libxml2 2.14.6 (CPython 3.11, Linux x86-64, 2 cores): 28 to 53 of 100 processes without
``--prime``.  The cause: libxml2 sets up its built-in schema types lazily, on the first schema
a process parses, and that set-up is not thread-safe.
"""
import argparse
import subprocess
import sys

SCHEMA = b"""<xs:schema xmlns:xs="http://www.w3.org/2001/XMLSchema">
  <xs:element name="model">
    <xs:complexType>
      <xs:sequence><xs:element name="variable" type="xs:string" maxOccurs="unbounded"/></xs:sequence>
      <xs:attribute name="name" type="xs:normalizedString" use="required"/>
      <xs:attribute name="version" type="xs:token"/>
      <xs:attribute name="count" type="xs:unsignedInt"/>
      <xs:attribute name="start" type="xs:double"/>
    </xs:complexType>
  </xs:element>
</xs:schema>"""

#: One process: prints "broken: <first error>" or "fine".
CHILD = r"""
import sys, threading
from lxml import etree
schema, prime, n = sys.argv[1].encode(), sys.argv[2] == "1", int(sys.argv[3])
if prime:
    etree.XMLSchema(etree.XML(schema))
documents = [etree.XML(schema) for _ in range(n)]
barrier = threading.Barrier(n)
errors = []
def parse(document):
    barrier.wait()
    try:
        etree.XMLSchema(document)
    except Exception as e:
        errors.append(repr(e))
threads = [threading.Thread(target=parse, args=(d,)) for d in documents]
for t in threads:
    t.start()
for t in threads:
    t.join()
try:
    etree.XMLSchema(etree.XML(schema))
except Exception as e:
    errors.append("afterwards: %r" % e)
print("broken: %s" % errors[0] if errors else "fine")
"""


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--processes", type=int, default=100)
    parser.add_argument("--threads", type=int, default=4)
    parser.add_argument("--prime", action="store_true",
                        help="parse one schema alone first in each process")
    args = parser.parse_args(argv)
    from lxml import etree
    print("lxml %s, libxml2 %s, Python %s" % (
        ".".join(map(str, etree.LXML_VERSION)), ".".join(map(str, etree.LIBXML_VERSION)),
        sys.version.split()[0]))
    broken, first = 0, None
    for _ in range(args.processes):
        out = subprocess.run([sys.executable, "-c", CHILD, SCHEMA.decode(),
                              "1" if args.prime else "0", str(args.threads)],
                             capture_output=True, text=True).stdout.strip()
        if out != "fine":
            broken += 1
            first = first or out
    if first:
        print("first: %s" % first)
    print("broken %d of %d processes" % (broken, args.processes))
    return 1 if broken else 0


if __name__ == "__main__":
    sys.exit(main())
