"""The API reference (``mkdocs.yml``, pages in ``docs/site/``) documents every public package:
each has its page, the nav lists every page, and the docstrings' Sphinx roles become
cross-references. What needs the ``docs`` extra (``mkdocs build --strict``) runs in ``.ci/run``;
these checks read files only."""

import importlib
import importlib.util
import re
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "gentlerl"
SITE = ROOT / "docs" / "site"
CONFIG = yaml.safe_load((ROOT / "mkdocs.yml").read_text())

#: Packages without an API page, and why. A new package gets a page (``docs/site/api/<name>.md``
#: and a nav line in mkdocs.yml) or a line here.
NOT_ON_THE_SITE = {
    "apps": "the commands: the configuration page's command table and each command's --help",
    "analysis": "what the commands compute from run directories, not an API",
    "distributed": "Ray collectors the config selects (docs/DISTRIBUTED.md)",
}


def _packages() -> list[str]:
    return sorted(p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists())


def _nav_pages(nav: object) -> list[str]:
    """Every page file the nav names, however deeply nested."""
    if isinstance(nav, str):
        return [nav]
    if isinstance(nav, dict):
        return [p for value in nav.values() for p in _nav_pages(value)]
    if isinstance(nav, list):
        return [p for item in nav for p in _nav_pages(item)]
    return []


def undocumented(packages: list[str], pages: dict[str, str], nav: list[str]) -> list[str]:
    """The packages lacking an API page that renders them (``::: gentlerl.<name>``, or blocks of
    its modules) or a nav entry for it; ``pages`` maps a page's path to its text."""
    missing = []
    for name in packages:
        if name in NOT_ON_THE_SITE:
            continue
        page = f"api/{name}.md"
        renders = re.search(rf"^::: gentlerl\.{name}(\.\w+)*\s*$", pages.get(page, ""), re.M)
        if not renders or page not in nav:
            missing.append(name)
    return missing


def test_every_public_package_has_a_page_in_the_nav():
    packages = _packages()
    assert len(packages) > 10  # the package, not a wrong path
    pages = {str(p.relative_to(SITE)): p.read_text() for p in SITE.rglob("*.md")}
    missing = undocumented(packages, pages, _nav_pages(CONFIG["nav"]))
    assert not missing, f"packages without an API page in mkdocs.yml's nav: {missing}"
    stale = sorted(set(NOT_ON_THE_SITE) - set(packages))
    assert not stale, f"NOT_ON_THE_SITE names packages the tree no longer has: {stale}"


def test_a_package_without_a_page_or_a_nav_line_is_caught():
    pages = {"api/rewards.md": "::: gentlerl.rewards\n", "api/envs.md": "# envs, no block\n"}
    nav = ["api/rewards.md", "api/envs.md"]
    assert undocumented(["rewards", "envs", "newpkg", "apps"], pages, nav) == ["envs", "newpkg"]
    assert undocumented(["rewards"], pages, []) == ["rewards"]


def test_the_nav_lists_every_page_and_names_only_pages_that_exist():
    nav = _nav_pages(CONFIG["nav"])
    pages = sorted(str(p.relative_to(SITE)) for p in SITE.rglob("*.md"))
    assert sorted(nav) == pages
    assert CONFIG["docs_dir"] == "docs/site"  # the notes in docs/*.md are not site pages


def _extension():
    path = ROOT / "docs" / "site_ext" / "sphinx_roles.py"
    spec = importlib.util.spec_from_file_location("sphinx_roles", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_sphinx_roles_become_optional_cross_references():
    convert = _extension().convert
    assert convert(":class:`~gentlerl.rewards.IntrinsicRewards`") == (
        '<autoref identifier="gentlerl.rewards.IntrinsicRewards" optional>'
        "<code>IntrinsicRewards</code></autoref>"
    )
    relative = convert(":func:`overshoot`", resolve=lambda n: f"gentlerl.functional.{n}")
    assert 'identifier="gentlerl.functional.overshoot"' in relative and ">overshoot<" in relative
    assert convert("``x`` and :math:`\\lambda`") == "`x` and \\(\\lambda\\)"
    block = convert("Holds::\n\n    a = 1\n    b = 2\n\nAfter.")
    assert block.startswith("Holds:\n\n```python\na = 1\nb = 2\n```\n\n") and block.endswith(
        "After."
    )
    assert "\\[\nx = 1\n\\]" in convert("    .. math::\n\n        x = 1\n").replace("    ", "")


def test_the_extension_reads_each_lazy_package_s_exports_as_python_does():
    lazy_names = _extension().lazy_names
    # a package whose __all__ is lazy_exports' (transforms only borrows its deprecated names)
    lazy = [
        p
        for p in _packages()
        if re.search(r"__all__ = lazy_exports\(", (PACKAGE / p / "__init__.py").read_text())
    ]
    assert {"rewards", "envs", "agent", "training"} <= set(lazy)
    for name in lazy:
        found = lazy_names((PACKAGE / name / "__init__.py").read_text())
        assert sorted(found) == importlib.import_module(f"gentlerl.{name}").__all__, name


def test_ci_builds_the_site_strictly_after_the_suite():
    ci = (ROOT / ".ci" / "run").read_text()
    build = ci.index("mkdocs build --strict")
    assert build > ci.rindex("run_suite env")
    # mkdocs serve / build's default output, ignored at the root only (docs/site/ is tracked)
    assert f"/{CONFIG['site_dir']}/" in (ROOT / ".gitignore").read_text().split()
