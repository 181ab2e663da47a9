"""Griffe extension: an attribute's `#` comment is its docstring in the API reference.

smibjax documents the fields of its Modules (units, meaning) in comments on the
field's line or on the comment lines right above it, for example

    H: Scalar = _field(5.0)  # inertia constant (s)

Griffe only reads docstrings (a string literal after the assignment), so without this
the fields would be listed bare. For an attribute that has no docstring, this uses
the comment lines directly above it followed by its own trailing comment. Loaded by
mkdocs.yml (`mkdocstrings` python handler, `extensions:`).
"""

from __future__ import annotations

import io
import tokenize

import griffe


def _comments(line: str) -> list[str]:
    """The text of the `#` comments on one source line (not `#` inside strings)."""
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(line).readline))
    except (tokenize.TokenError, IndentationError, SyntaxError):
        return []
    return [t.string[1:].strip() for t in tokens if t.type == tokenize.COMMENT]


def _is_pragma(comment: str) -> bool:
    return not comment or comment.startswith(("noqa", "type:", "pragma", "fmt:"))


class CommentDocstrings(griffe.Extension):
    def on_attribute_instance(self, *, node, attr, agent, **kwargs) -> None:
        if attr.docstring is not None or attr.lineno is None:
            return
        try:
            lines = attr.lines_collection[attr.filepath]
        except (KeyError, TypeError):
            return
        first, last = attr.lineno - 1, (attr.endlineno or attr.lineno) - 1
        above = []
        i = first - 1
        while i >= 0 and lines[i].lstrip().startswith("#"):
            above.insert(0, lines[i].strip()[1:].strip())
            i -= 1
        trailing = _comments(lines[last].strip()) if first == last else []
        text = " ".join(part for part in above + trailing if not _is_pragma(part))
        if text:
            attr.docstring = griffe.Docstring(text, parent=attr)
