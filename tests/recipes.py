"""The recipes of docs/hosts.md as written: the code block after each ``<!-- recipe: NAME -->``
comment (mkdocs shows the block, not the comment), for the tests that run them."""
import re
from pathlib import Path

HOSTS = Path(__file__).resolve().parent.parent / "docs" / "hosts.md"


def recipe(name, page=HOSTS):
    """The text of the code block that follows ``<!-- recipe: name -->`` in ``page``."""
    text = Path(page).read_text()
    found = re.search(r"<!-- recipe: %s -->\s*```[a-z]*\n(.*?)```" % re.escape(name), text,
                      re.S)
    assert found, "docs/%s has no block marked <!-- recipe: %s -->" % (Path(page).name, name)
    return found.group(1)


def commands(name, page=HOSTS):
    """The command lines of a ``sh`` recipe (continuation lines joined, comments dropped)."""
    lines = recipe(name, page).replace("\\\n", " ").splitlines()
    return [line.split(" #")[0].strip() for line in lines
            if line.strip() and not line.lstrip().startswith("#")]
