"""The documentation: the FMU reference page and each FMU's documentation/index.html are what the
VARIABLES tables say; every public API function has a docstring and is in the API reference."""
import html
import html.parser
import inspect
import re
import zipfile
from pathlib import Path

import pytest

import driftfmu
from driftfmu.fmu_src import documentation

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
docs_only = pytest.mark.skipif(not DOCS.is_dir(), reason="no docs/ (an installed package)")


@docs_only
def test_fmu_reference_page_is_the_generated_one():
    expected = documentation.reference_markdown()
    assert (DOCS / "fmus.md").read_text(encoding="utf-8") == expected, (
        "docs/fmus.md is stale: python -m driftfmu.fmu_src.documentation > docs/fmus.md")


def test_reference_has_every_variable_of_every_fmu():
    text = documentation.reference_markdown()
    for name in documentation.NAMES:
        for spec in documentation.slave_class(name).VARIABLES:
            assert "| `%s` |" % spec["name"] in text, (name, spec["name"])


def _fmus(python_fmus, native_fmus_all):
    """(name, kind, FMI version, path) of every FMU as the build ships it: the Python FMUs, the
    native FMI 2.0 and 3.0 FMUs and the FMI 2.0 FMUs for ARM (when zig built them)."""
    from driftfmu.fmu_src import native_build
    for name, path in python_fmus.items():
        yield name, "python", 2, path
    for v, paths in native_fmus_all.items():
        for name, path in paths.items():
            yield name, "native", v, path
    arm = next(iter(native_fmus_all[2].values())).parent.parent / native_build.FMI2_ARM
    for path in sorted(arm.glob("*.fmu")):
        yield path.stem, "native", 2, path


class _Page(html.parser.HTMLParser):
    """What a test reads of a page: its text, every link (href/src), every id, and the rows of
    its tables (cells' text, and the link of each cell)."""

    def __init__(self, text):
        super().__init__()
        self.links, self.ids, self.rows, self.text = [], set(), [], []
        self._row = self._cell = None
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.ids.add(attrs["id"])
        for key in ("href", "src"):
            if key in attrs:
                self.links.append(attrs[key])
                if self._cell is not None:
                    self._cell["link"] = attrs[key]
        if tag == "tr":
            self._row = []
        elif tag in ("td", "th") and self._row is not None:
            self._cell = {"text": "", "link": None}

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append(self._cell)
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None

    def handle_data(self, data):
        self.text.append(data)
        if self._cell is not None:
            self._cell["text"] += data


#: Absolute URLs a page may link to (none: the page stands alone inside the FMU).
ALLOWED_URLS = ()
#: A file path in running text: a folder, a name and an extension (sources/config.h), or a
#: Markdown page.
PATH = re.compile(r"(?<![\w/.-])((?:[\w.-]+/)+[\w.-]*\.[A-Za-z]{1,4}|[\w.-]+\.md)(?![\w/])")


def _in_archive(target, names):
    """The archive file a link of documentation/index.html (or a path named in its text)
    means, if the archive has it."""
    import posixpath
    for base in ("documentation", ""):
        path = posixpath.normpath(posixpath.join(base, target))
        if path in names:
            return path
    return None


def check_page(page, names, md, name):
    """Every check of one FMU's documentation/index.html against its archive (``names``) and
    its model description ``md``; returns the number of variables checked."""
    doc = _Page(page)
    text = "".join(doc.text)
    # the general sensor: the 4th-order characteristic and the known input
    for term in ("a3 x^3", "a4 x^4", "B u_k", "a2 E[x^2] + a3 E[x^3] + a4 E[x^4]"):
        assert term in text, (name, term)
    # no dead link: an anchor of the page, a file of the archive, or an allowed URL
    for link in doc.links:
        if link.startswith("#"):
            assert link[1:] in doc.ids, (name, link)
        elif re.match(r"^[a-z][a-z0-9+.-]*:", link):
            assert link in ALLOWED_URLS, (name, link)
        else:
            assert _in_archive(link, names), (name, link)
    # no file the FMU does not carry is named
    for path in PATH.findall(text):
        assert _in_archive(path, names), (name, path)
    # every variable of the model description, with its value reference, causality,
    # variability and unit, the unit as its UnitDefinitions entry defines it
    rows = {r[1]["text"]: r for r in doc.rows if len(r) == 10 and r[0]["text"].isdigit()}
    units = {r[0]["text"]: r for r in doc.rows if len(r) == 3}
    definitions = {u.name: u for u in md.unitDefinitions}
    for v in md.modelVariables:
        row = rows.pop(v.name)
        assert (int(row[0]["text"]), row[2]["text"], row[3]["text"], row[4]["text"]) == \
            (v.valueReference, v.causality, v.variability, v.type), (name, v.name)
        if not v.unit:
            assert row[5]["text"] == "" and row[5]["link"] is None, (name, v.name)
            continue
        assert row[5]["link"] == "#" + documentation._anchor(v.unit), (name, v.name)
        assert row[5]["text"] == documentation.unit_text(v.unit), (name, v.name)
        declared, reads, definition = (c["text"] for c in units[v.unit])
        assert (declared, reads) == (v.unit, documentation.unit_text(v.unit))
        base = definitions[v.unit].baseUnit
        if base is None:
            assert definition.startswith("no base-unit form"), (name, v.unit)
            continue
        exponents = {b: getattr(base, b) for b in ("kg", "m", "s", "A", "K", "mol", "cd",
                                                   "rad") if getattr(base, b)}
        assert definition == documentation.unit_definition_text(
            v.unit, reads, base.factor, exponents), (name, v.unit, definition)
    assert rows == {}, (name, "rows the model description does not have", sorted(rows))
    # each input says for which settings it matters
    inputs = {r[0]["text"] for r in doc.rows if len(r) == 2 and r[0]["text"] != "input"}
    assert inputs == {v.name for v in md.modelVariables if v.causality == "input"}, name
    return len(md.modelVariables)


@pytest.mark.qualification
@pytest.mark.integration
def test_every_fmu_documents_itself_whole(python_fmus, native_fmus_all, report):
    """Every FMU's documentation/index.html (Python, native FMI 2.0 and 3.0, FMI 2.0 for ARM)
    is the generated one and agrees with its model description: every variable with its value
    reference, causality, variability and unit, each unit as the UnitDefinitions define it;
    the general sensor's a3, a4 and B u; links that resolve inside the archive and no file the
    FMU does not carry; binaries.txt names only files that are there."""
    from driftfmu.fmu_src.schemas import read_model_description, validate_fmu
    seen = variables = 0
    kinds = set()
    for name, kind, v, path in _fmus(python_fmus, native_fmus_all):
        with zipfile.ZipFile(path) as archive:
            names = set(archive.namelist())
            page = archive.read("documentation/index.html").decode("utf-8")
            binaries = (archive.read("documentation/binaries.txt").decode("utf-8")
                        if "documentation/binaries.txt" in names else None)
            if v == 3:
                assert archive.read("documentation/licenses/LICENSE.txt") == \
                    (ROOT / "LICENSE").read_bytes()
        assert page == documentation.index_html(name, kind, v, names), path
        variables += check_page(page, names, read_model_description(path), "%s (%s)" % (
            name, path))
        if kind == "native":
            assert binaries is not None, path
            named = PATH.findall(binaries)
            assert named and all(_in_archive(p, names) for p in named), (path, named)
        assert validate_fmu(str(path)) == [], path
        kinds.add((kind, v, path.parent.name))
        seen += 1
    assert seen == len(python_fmus) + sum(len(p) for p in native_fmus_all.values()) + \
        (len(python_fmus) if any(k[2] == "fmi2-aarch64" for k in kinds) else 0)
    report("FMU documentation: %d FMUs (%s), %d variables checked against their model "
           "descriptions, every link resolved" % (seen, ", ".join(sorted(
               "%s FMI %d.0 %s" % k for k in kinds)), variables))


def test_index_html_states_the_general_model_the_host_rules_and_the_letter():
    page = documentation.index_html("DriftEstimator", "python", 2, ["binaries/linux64/x.so"])
    for text in ("K = P- H / (H^2 P- + R)", "<td>dc_ekf1</td>", "Sensor Letters 4(4)",
                 "D. Karatzas", "Tested here: linux64 only", "binaries: linux64",
                 "x- = A x+_{k-1} + B u_k", "3 a3 x-^2 + 4 a4 x-^3", "E[x^3] = 0",
                 "a quarter period after", "whatever loggingOn says",
                 "only when B != 0 and process = 1", '<a href="#unit-V/g2">V/g²</a>',
                 "1 V/g² = 0.010398211550100477 kg·s·A⁻¹"):
        assert text in page, text
    assert "docs/" not in page and "V/g2</td>" not in page.replace("<code>V/g2</code>", "")
    assert "licenses/LICENSE.txt" in documentation.index_html("Excitation", "native", 3)
    assert 'href="binaries.txt"' not in page   # (only a native FMU carries it)


def test_every_input_of_every_fmu_says_when_it_matters():
    for name in documentation.NAMES:
        for spec in documentation.slave_class(name).VARIABLES:
            if spec["causality"] == "input":
                assert documentation.INPUT_USE.get((name, spec["name"])), (name, spec["name"])


API = [n for n in driftfmu.__all__ if n != "__version__"]


@pytest.mark.parametrize("name", API)
def test_public_function_has_a_numpydoc_docstring(name):
    doc = inspect.getdoc(getattr(driftfmu, name)) or ""
    assert doc.strip(), "%s has no docstring" % name
    for section in ("Parameters\n----------", "Returns\n-------"):
        assert section in doc, "%s: docstring lacks %s" % (name, section.split()[0])
    # every parameter of the signature is documented
    for p in inspect.signature(getattr(driftfmu, name)).parameters.values():
        key = ("**" + p.name) if p.kind is p.VAR_KEYWORD else p.name
        assert re.search(r"^\s*%s\b|[ ,]%s\b" % (re.escape(key), re.escape(p.name)), doc, re.M), \
            "%s: parameter %s is not documented" % (name, key)


@docs_only
@pytest.mark.parametrize("name", API)
def test_public_function_is_in_the_api_reference(name):
    assert re.search(r"^::: driftfmu\.%s$" % name, (DOCS / "api.md").read_text(), re.M), \
        "docs/api.md lacks '::: driftfmu.%s'" % name


@docs_only
def test_site_builds_in_strict_mode(tmp_path):
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings")
    import subprocess
    import sys
    run = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                          str(tmp_path / "site")], cwd=ROOT, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    assert (tmp_path / "site" / "api" / "index.html").is_file()
    api = (tmp_path / "site" / "api" / "index.html").read_text()
    for name in API:
        assert 'id="driftfmu.%s"' % name in api, name
    # offline: no script or style sheet from another host (highlight.js came from a CDN)
    for page in (tmp_path / "site").rglob("*.html"):
        text = page.read_text(encoding="utf-8")
        remote = re.findall(r'<(?:script|link)\b[^>]*(?:src|href)="(?:https?:)?//[^"]*"', text)
        assert not remote, (page.relative_to(tmp_path), remote)
    assert "css/pygments.css" in api
    # code highlighted at build time: Pygments' token classes in the code blocks
    home = (tmp_path / "site" / "index.html").read_text(encoding="utf-8")
    assert re.search(r'<div class="language-bash highlight"><pre>.*<span class="', home, re.S)
    # signatures formatted one parameter a line, not one long line
    signature = re.search(r'<div class="language-python doc-signature highlight">(.*?)</div>',
                          api, re.S).group(1)
    assert signature.count("\n") > 3, signature[:300]
    # cross-references resolved: no Sphinx role left as text, autorefs turned into links
    text = re.sub(r"<[^>]+>", "", api)
    assert not re.findall(r":(?:data|func|mod|class|meth|attr):", text)
    assert "[driftfmu." not in text
    assert '<a class="autorefs autorefs-internal" title="driftfmu.simulate"' in api or \
        'href="#driftfmu.simulate"' in api


@docs_only
def test_the_home_page_sets_up_as_the_readme_does():
    """docs/index.md's set-up commands are the README's, the same lines in the same order."""
    def bash_lines(text):
        blocks = re.findall(r"```bash\n(.*?)```", text, re.S)
        return [line.split("#")[0].strip() for b in blocks for line in b.splitlines()
                if line.split("#")[0].strip()]
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    setup = readme[readme.index("## Two commands"):]
    setup = setup[:setup.index("\n## ", 3)]
    home = (DOCS / "index.md").read_text(encoding="utf-8")
    assert bash_lines(setup), "README.md: no set-up commands found"
    assert bash_lines(home) == bash_lines(setup), (bash_lines(home), bash_lines(setup))


def _package_modules():
    """Every module file of the installed or checked-out ``driftfmu`` package: its own folder
    (``driftfmu/``, in a wheel also the subpackages) and the subpackages' folders."""
    import driftfmu.fmu_src
    import driftfmu.models
    import driftfmu.simulations
    folders = [Path(driftfmu.__file__).parent] + [
        Path(p) for pkg in (driftfmu.models, driftfmu.fmu_src, driftfmu.simulations)
        for p in pkg.__path__]
    files = {f.resolve() for d in folders for f in d.rglob("*.py")}
    return sorted(files)


def _module_name(path):
    return "/".join(path.parts[-3:])


PUBLIC_MODULES = ("__init__.py", "_api.py")  # driftfmu's own: the API


def test_every_module_but_the_api_says_it_is_internal():
    import ast
    files = _package_modules()
    names = {_module_name(f) for f in files}
    assert any(n.endswith("models/ekf.py") for n in names)
    assert any(n.endswith("simulations/cli.py") for n in names)
    assert any(n.endswith("fmu_src/builder.py") for n in names)
    api = {f for f in files if f.parent == Path(driftfmu.__file__).resolve().parent
           and f.name in PUBLIC_MODULES}
    assert len(api) == 2
    public = set(driftfmu.__all__)
    for f in sorted(set(files) - api):
        doc = ast.get_docstring(ast.parse(f.read_text(encoding="utf-8"))) or ""
        first = doc.splitlines()[0] if doc else ""
        m = re.fullmatch(r"Internal \(not a stable API; use (.+) instead\)\.", first)
        assert m, "%s: the docstring's first line does not say it is internal: %r" % (
            _module_name(f), first)
        named = re.findall(r"driftfmu\.(\w+)", m.group(1))
        assert all(n in public for n in named), "%s names %s, not public" % (
            _module_name(f), named)
        assert named or "driftfmu" in m.group(1), _module_name(f)
    for f in api:  # the API says it is the API
        doc = ast.get_docstring(ast.parse(f.read_text(encoding="utf-8"))) or ""
        assert not doc.startswith("Internal"), f.name


@docs_only
def test_the_issue_20_audit_names_tests_that_exist():
    """docs/native-hardening.md's audit table names its tests as ABBREVIATION::test_name (and
    "F cases `name`" for a case of tests/fuzz/cases.py): each must be defined where it says."""
    text = (DOCS / "native-hardening.md").read_text(encoding="utf-8")
    audit = text[text.index("## Audit"):]
    files = {"NH": "test_native_hardening.py", "F": "test_fuzz.py", "M": "test_memory.py",
             "H": "test_hardening.py", "N": "test_native.py"}
    named = re.findall(r"\b(NH|F|M|H|N)::(test_\w+)", audit)
    assert len(named) > 30
    for short, test in named:
        source = (ROOT / "tests" / files[short]).read_text(encoding="utf-8")
        assert re.search(r"^def %s\(" % test, source, re.M), "%s::%s" % (short, test)
    cases = (ROOT / "tests" / "fuzz" / "cases.py").read_text(encoding="utf-8")
    for case in re.findall(r"F cases? `(\w+?)\*?`", audit):
        assert re.search(r"^def %s" % case, cases, re.M), case
