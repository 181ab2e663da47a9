"""MkDocs hook: the site's Home and Guide pages are README.md, split at build time.

README.md is the one source of the guide; copying its text into docs/ would drift.
This hook (mkdocs.yml `hooks:`) reads it on every build and adds generated pages
(nothing is written to docs/; `mkdocs serve` watches README.md and rebuilds):

- the text before the first `## ` heading becomes `index.md` (Home);
- each `## ` section becomes `guide/<slug>.md`, the slug being the heading up to its
  first ':' or '(' in lower case ("Tuning the gains: `python -m tuning.optimize`" ->
  `guide/tuning-the-gains.md`); its headings move up one level (`## X` -> `# X`, the
  page title; `### Y` -> `## Y`);
- relative links and images are rewritten for the page's place in the site: a target
  under docs/ (the figures) is made relative to the page, and a link to any other
  file of the repository (not part of the site) becomes its text followed by the path
  in code, so that no link of the site points outside it.

Fenced code blocks are copied untouched (a `# comment` in one is not a heading).
mkdocs.yml's nav lists the guide pages by slug; with `validation: nav: omitted_files:
warn` and `--strict`, a new README section missing from the nav, or a renamed one
whose old slug the nav still lists, fails the build.

Simpler alternatives considered: pymdownx.snippets with section markers would need
markers in README.md and would still leave its `docs/figures/...` image paths wrong
for a page under guide/; a README.md symlinked into docs/ would be one long page.
"""

from __future__ import annotations

import posixpath
import re
from pathlib import Path

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File, Files

_FENCE = re.compile(r"^\s*(```|~~~)")
_HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
# [text](target) and ![alt](target), with an optional "title".
_LINK = re.compile(r'(!?)\[([^\]]*)\]\(\s*([^)\s]+)(\s+"[^"]*")?\s*\)')
_SCHEME = re.compile(r"^[a-zA-Z][a-zA-Z0-9+.-]*:")


def slug(heading: str) -> str:
    """`guide/` file stem of a README `## ` heading."""
    head = re.split(r"[:(]", heading, maxsplit=1)[0]
    head = head.replace("`", "").lower()
    return re.sub(r"[^a-z0-9]+", "-", head).strip("-")


def _outside_fences(lines: list[str]):
    """Yield (line, in_code) for each line, in_code for the lines of fenced blocks."""
    fence = None
    for line in lines:
        m = _FENCE.match(line)
        if fence is None and m:
            fence = m.group(1)
            yield line, True
        elif fence is not None:
            if m and m.group(1) == fence:
                fence = None
            yield line, True
        else:
            yield line, False


def split_readme(text: str) -> dict[str, list[str]]:
    """README text -> {page src_uri: lines}, in README order."""
    pages: dict[str, list[str]] = {"index.md": []}
    current = "index.md"
    for line, in_code in _outside_fences(text.splitlines()):
        m = None if in_code else _HEADING.match(line)
        if m and len(m.group(1)) == 2:
            current = f"guide/{slug(m.group(2))}.md"
            if current in pages:
                raise PluginError(
                    f"README.md: two `## ` sections share the page {current}"
                )
            pages[current] = []
        pages[current].append(line)
    return pages


def _rewrite_link(m: re.Match, page: str, docs: str) -> str:
    bang, text, target, title = m.group(1), m.group(2), m.group(3), m.group(4) or ""
    if target.startswith("#") or target.startswith("/") or _SCHEME.match(target):
        return m.group(0)
    path, _, anchor = target.partition("#")
    path = posixpath.normpath(path)
    if path == docs or path.startswith(docs + "/"):
        rel = posixpath.relpath(path[len(docs) + 1 :], posixpath.dirname(page) or ".")
        return f"{bang}[{text}]({rel}{'#' + anchor if anchor else ''}{title})"
    # A file of the repository that is not part of the site: name it, do not link it.
    return f"{text} (`{path}`)" if text and text != path else f"`{path}`"


def render(page: str, lines: list[str], docs: str = "docs") -> str:
    """One page's Markdown: headings up one level (guide pages), links rewritten."""
    out = []
    for line, in_code in _outside_fences(lines):
        if not in_code:
            m = _HEADING.match(line)
            if m and page != "index.md" and len(m.group(1)) >= 2:
                line = f"{m.group(1)[1:]} {m.group(2)}"
            line = _LINK.sub(lambda mm: _rewrite_link(mm, page, docs), line)
        out.append(line)
    return "\n".join(out).strip() + "\n"


def on_files(files: Files, config) -> Files:
    root = Path(config.config_file_path).parent
    docs = Path(config.docs_dir).resolve().relative_to(root.resolve()).as_posix()
    readme = (root / "README.md").read_text(encoding="utf-8")
    for page, lines in split_readme(readme).items():
        if files.get_file_from_path(page) is not None:
            raise PluginError(
                f"{docs}/{page} exists, but that page is generated from README.md"
            )
        content = render(page, lines, docs)
        files.append(File.generated(config, page, content=content))
    return files
