"""A griffe extension for the API reference (mkdocs.yml loads it): what static analysis misses.

- The packages that export their names through :func:`gentlerl.lazy.lazy_exports` get those
  names as their ``__all__`` and as members (aliases of the defining modules' objects), so a
  package page lists them as it lists an eagerly imported package's names.
- An attribute without a docstring takes the Sphinx ``#:`` comment above it, or, for a config
  field, its :func:`~gentlerl.config.fields.setting`'s help, range and whether a resume may
  change it (what ``gentlerl train --help`` prints).
- Docstrings are written for Sphinx. Before they are rendered: ``:role:`~a.b.C``` becomes a
  cross-reference (``C`` as code, linked when ``a.b.C`` is on the site, plain code otherwise:
  an autorefs ``optional`` reference, so a target the site does not document never fails
  ``mkdocs build --strict``); a name without ``gentlerl.`` is resolved where the docstring is,
  as Sphinx does; ``:math:`x``` and ``.. math::`` become arithmatex's ``\\(x\\)`` and ``\\[x\\]``;
  ````x```` becomes ```x```; a ``text::`` literal block becomes a fenced code block (Python
  where it parses).

The conversion is pure text (:func:`convert`), importable without griffe, so the tests check it.
"""

from __future__ import annotations

import ast
import html
import re
import textwrap
from collections.abc import Callable, Iterator
from typing import Any

try:
    from griffe import Alias, Docstring, Extension
except ImportError:  # the tests read convert() without the docs extra installed
    Extension = object  # type: ignore[assignment,misc]

ROLE = re.compile(r":(?:py:)?(class|func|meth|attr|mod|data|obj|exc|const):`([^`]+)`")
MATH = re.compile(r":math:`([^`]+)`")
DOUBLE = re.compile(r"``(.+?)``")
DIRECTIVE = re.compile(r"^(?P<indent>\s*)\.\. math::\s*(?P<rest>.*)$")
LITERAL = re.compile(r"^(?P<indent>\s*)(?P<text>.*?)::\s*$")


def _indent(line: str) -> int:
    return len(line) - len(line.lstrip())


def _block(lines: list[str], start: int, indent: int) -> int:
    """The end of the block of lines below ``start`` indented deeper than ``indent`` (blank lines
    inside it included, trailing ones not)."""
    end = start
    j = start
    while j < len(lines):
        if lines[j].strip():
            if _indent(lines[j]) <= indent:
                break
            end = j + 1
        j += 1
    return end


def _parses(code: str) -> bool:
    try:
        ast.parse(code)
    except SyntaxError:
        return False
    return True


def _blocks(text: str) -> str:
    """``.. math::`` directives to ``\\[...\\]`` blocks and ``text::`` literal blocks to fenced
    code (a doctest block, ``>>>``, is left to the renderer)."""
    lines = text.split("\n")
    out: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        math = DIRECTIVE.match(line)
        literal = None if math else LITERAL.match(line)
        if not (math or literal) or (literal and line.strip().startswith("..")):
            out.append(line)
            i += 1
            continue
        indent = _indent(line)
        end = _block(lines, i + 1, indent)
        body = textwrap.dedent("\n".join(lines[i + 1 : end])).strip("\n")
        pad = " " * indent
        if math:
            formula = "\n".join(filter(None, [math["rest"].strip(), body]))
            out += ["", f"{pad}\\[", *[pad + f for f in formula.split("\n")], f"{pad}\\]", ""]
        elif body:
            text_ = literal["text"].rstrip()
            if text_:
                out.append(f"{pad}{text_}:")
            language = "python" if _parses(body) else "text"  # a directory tree: text
            out += ["", f"{pad}```{language}", *[pad + b if b else b for b in body.split("\n")]]
            out += [f"{pad}```", ""]
        else:  # a line that only ends in ``::`` with nothing indented below it
            out.append(line)
            end = i + 1
        i = end
    return "\n".join(out)


def convert(text: str, resolve: Callable[[str], str] = lambda name: name) -> str:
    """A Sphinx-flavoured docstring as mkdocstrings' Markdown; ``resolve`` turns a role's target
    (as written, without ``~``) into the full dotted path it names."""

    def role(match: re.Match) -> str:
        target = match[2].strip()
        if "<" in target and target.endswith(">"):  # :class:`title <a.b.C>`
            title, target = target[:-1].split("<", 1)
            title, target = title.strip(), target.strip()
        else:
            target = target.lstrip("!")
            short = target.startswith("~")
            target = target.lstrip("~")
            title = target.lstrip(".").rsplit(".", 1)[-1] if short else target.lstrip(".")
        identifier = resolve(target.lstrip("."))
        return (
            f'<autoref identifier="{html.escape(identifier)}" optional>'
            f"<code>{html.escape(title)}</code></autoref>"
        )

    text = _blocks(text)
    text = MATH.sub(lambda m: f"\\({m[1]}\\)", text)
    text = ROLE.sub(role, text)
    return DOUBLE.sub(lambda m: f"`{m[1]}`", text)


def lazy_names(source: str) -> dict[str, str]:
    """``{name: defining module}`` of a package ``__init__`` calling ``lazy_exports(__name__,
    {module: (name, ...)})``; empty for any other module."""
    found: dict[str, str] = {}
    for node in ast.walk(ast.parse(source)):
        if (
            isinstance(node, ast.Call)
            and getattr(node.func, "id", None) == "lazy_exports"
            and len(node.args) == 2
            and isinstance(node.args[1], ast.Dict)
        ):
            for module, names in zip(node.args[1].keys, node.args[1].values, strict=True):
                for name in ast.literal_eval(names):
                    found[name] = ast.literal_eval(module)
    return found


def setting_help(value: str) -> str | None:
    """The docstring of a config field whose value is ``setting(default, help, ...)``."""
    try:
        call = ast.parse(value, mode="eval").body
    except SyntaxError:
        return None
    if not (
        isinstance(call, ast.Call) and getattr(call.func, "id", None) == "setting" and call.args
    ):
        return None
    try:
        options = {k.arg: ast.literal_eval(k.value) for k in call.keywords}
        text = ast.literal_eval(call.args[1]) if len(call.args) > 1 else options["help"]
    except (ValueError, KeyError):
        return None
    parts = [str(text).rstrip(".") + "."]
    if isinstance(options.get("choices"), tuple):
        parts.append("One of " + ", ".join(f"`{c}`" for c in options["choices"]) + ".")
    if options.get("bounds"):
        parts.append(f"Range: `{options['bounds']}`.")
    if options.get("resumable"):
        parts.append("A resumed run may change it.")
    if options.get("ablation"):
        parts.append("An ablation knob.")
    return " ".join(parts)


def comment_doc(lines: list[str], lineno: int) -> str | None:
    """The ``#:`` comment lines right above line ``lineno`` (1-based) of a source file."""
    found: list[str] = []
    i = lineno - 2
    while i >= 0 and lines[i].strip().startswith("#:"):
        found.insert(0, lines[i].strip()[2:].strip())
        i -= 1
    return "\n".join(found) or None


def _objects(obj: Any) -> Iterator[Any]:
    """``obj`` and every object defined under it (aliases, imported names, are skipped)."""
    yield obj
    for member in obj.members.values():
        if not member.is_alias:
            yield from _objects(member)


def _resolver(obj: Any) -> Callable[[str], str]:
    def resolve(name: str) -> str:
        if name.startswith("gentlerl."):
            return name
        first, _, rest = name.partition(".")
        scope = obj if obj.is_class or obj.is_module else obj.parent
        try:
            path = scope.resolve(first)
        except Exception:  # not a name of this scope (a builtin, torch, a typo): code, no link
            return name
        return f"{path}.{rest}" if rest else path

    return resolve


class SphinxRoles(Extension):
    """Lazy exports as members, Sphinx roles as cross-references (the module docstring)."""

    def on_package(self, *, pkg: Any, loader: Any, **kwargs: Any) -> None:
        modules = [o for o in _objects(pkg) if o.is_module]
        for module in modules:
            if module.filepath and module.filepath.name == "__init__.py":
                names = lazy_names(module.filepath.read_text())
                for name, where in sorted(names.items()):
                    module.set_member(name, Alias(name, f"{where}.{name}", parent=module))
                if names:
                    module.exports = sorted(names)
        sources: dict[Any, list[str]] = {}
        for obj in _objects(pkg):
            if obj.is_attribute and obj.docstring is None:
                if obj.filepath not in sources:
                    sources[obj.filepath] = obj.filepath.read_text().splitlines()
                text = comment_doc(sources[obj.filepath], obj.lineno or 0)
                if text is None and obj.value is not None and obj.parent.is_class:
                    text = setting_help(str(obj.value))
                if text:
                    obj.docstring = Docstring(
                        text,
                        parent=obj,
                        parser=loader.docstring_parser,
                        parser_options=loader.docstring_options,
                    )
            if obj.docstring is not None:
                obj.docstring.value = convert(obj.docstring.value, _resolver(obj))


__all__ = ["SphinxRoles", "comment_doc", "convert", "lazy_names", "setting_help"]
