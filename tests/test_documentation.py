"""The documentation: the FMU reference page and each FMU's documentation/index.html are what the
VARIABLES tables say; every public API function has a docstring and is in the API reference."""
import html
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


def _fmus(python_fmus, native_fmus):
    for name, path in python_fmus.items():
        yield name, "python", 2, path
    for v, paths in native_fmus.items():
        for name, path in paths.items():
            yield name, "native", v, path


@pytest.mark.qualification
@pytest.mark.integration
def test_every_fmu_carries_its_generated_documentation(python_fmus, native_fmus_all):
    native_fmus = native_fmus_all  # as the build ships them: every platform's binaries
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu
    seen = 0
    for name, kind, v, path in _fmus(python_fmus, native_fmus):
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
            page = archive.read("documentation/index.html").decode("utf-8")
            assert page == documentation.index_html(name, kind, v,
                                                    documentation.platforms_of(names)), path
            if v == 3:
                assert archive.read("documentation/licenses/LICENSE.txt") == \
                    (ROOT / "LICENSE").read_bytes()
        # the page's table agrees with the FMU's model description, row by row
        md = {var.name: var for var in read_model_description(str(path)).modelVariables}
        rows = re.findall(r"<tr><td>(\d+)</td><td>([^<]*)</td><td>([^<]*)</td>", page)
        assert len(rows) == len(documentation.slave_class(name).VARIABLES)
        for vr, var, causality in rows:
            var = html.unescape(var)
            assert md[var].valueReference == int(vr), (path, var)
            assert md[var].causality == causality, (path, var)
        assert validate_fmu(str(path)) == [], path
        seen += 1
    assert seen == len(python_fmus) + sum(len(p) for p in native_fmus.values())


def test_index_html_states_equations_variables_and_the_letter():
    page = documentation.index_html("DriftEstimator", "python", 2, ["linux64"])
    for text in ("K = P- H / (H^2 P- + R)", "<td>dc_ekf1</td>", "Sensor Letters 4(4)",
                 "Tested here: linux64 only", "binaries: linux64"):
        assert text in page, text
    assert "licenses/LICENSE.txt" in documentation.index_html("Excitation", "native", 3)


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
