"""User-provided text (suite, case, group and policy names, error messages: anything read from
a suite file, ``suite.json``, ``results.parquet`` or ``errors.jsonl``) made inert in the
Markdown report and the HTML page rendered from it."""

from __future__ import annotations

import re

_MARKDOWN = re.compile(r"([\\`*_\[\]()!|#{}~])")
"""Characters with a meaning in Markdown (emphasis, code, links and images, table cells,
headings); each is escaped with a backslash, which Python-Markdown and GitHub both honour."""
_ENTITIES = {"&": "&amp;", "<": "&lt;", ">": "&gt;"}
"""Raw HTML is written as entities: a name never becomes a tag."""


def escape(value: object) -> str:
    """``value`` as text that Markdown shows literally: no tag, link, image, emphasis, table
    cell border or line break comes from it (newlines become spaces)."""
    text = " ".join(str(value).splitlines())
    text = _MARKDOWN.sub(r"\\\1", text)
    return "".join(_ENTITIES.get(c, c) for c in text)
