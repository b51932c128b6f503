"""The report as one self-contained HTML page: styled, readable tables, verdicts coloured,
every figure inlined as a data URI (the single file can be mailed)."""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Collection
from pathlib import Path

from boids_env.files import write_text

GOOD = ("reproduced", "better", "safer")
BAD = ("not reproduced", "worse", "less safe")
NEUTRAL = ("no significant difference", "as safe", "not run")
"""Table cells holding exactly one of these words are coloured green, red or grey."""

STYLE = """
:root { --ink: #1d2330; --muted: #5b6475; --line: #dde1e8; --zebra: #f6f7f9;
        --good: #1b7a3d; --good-bg: #e3f4e8; --bad: #b42318; --bad-bg: #fde7e5;
        --neutral-bg: #eef0f3; }
body { font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif;
       color: var(--ink); max-width: 1180px; margin: 2.5em auto; padding: 0 1.5em; }
h1 { font-size: 1.7em; margin-bottom: .2em; }
h2 { font-size: 1.3em; margin-top: 2.2em; padding-bottom: .25em;
     border-bottom: 2px solid var(--line); }
h3 { font-size: 1.1em; margin-top: 1.6em; }
h4 { font-size: 1em; margin-top: 1.3em; color: var(--muted); }
p, li { max-width: 80ch; }
p:has(img) { max-width: none; }
code { background: var(--zebra); padding: 0 .25em; border-radius: 3px; }
.scroll { overflow-x: auto; margin: .8em 0 1.2em; }
table { border-collapse: collapse; font-size: 13.5px; }
th { background: #eef1f6; text-align: left; vertical-align: bottom; white-space: normal;
     min-width: 4em; max-width: 11em; }
th, td { border: 1px solid var(--line); padding: 4px 9px; }
td { white-space: nowrap; }
td { font-variant-numeric: tabular-nums; }
tbody tr:nth-child(even) td { background: var(--zebra); }
td.good { background: var(--good-bg) !important; color: var(--good); font-weight: 600; }
td.bad { background: var(--bad-bg) !important; color: var(--bad); font-weight: 600; }
td.neutral { color: var(--muted); }
img { max-width: 100%; height: auto; display: block; margin: .8em 0; }
img.traj { display: inline-block; width: 32%; min-width: 260px; margin: .3em .4%; }
.note { color: var(--muted); font-size: .92em; }
"""


def write_html(markdown_text: str, path: Path, title: str, base: Path,
               figures: Collection[str] = ()) -> Path:
    """Renders the report's Markdown to ``path``: the figures the report drew (``figures``:
    their paths relative to ``base``, as the Markdown names them) are inlined as data URIs,
    wide tables scroll, verdict cells are coloured. No other file is ever read: an image the
    Markdown names that is not one of ``figures``, or whose path leads out of ``base`` (a
    link included), is left as it is."""
    import markdown

    body = markdown.markdown(markdown_text, extensions=["tables", "sane_lists"])
    body = re.sub(r"<img ([^>]*?)src=\"([^\"]+)\"",
                  lambda m: _inline(m, base, frozenset(figures)), body)
    body = re.sub(r"<td([^>]*)>([^<]*)</td>", _verdict_cell, body)
    body = body.replace("<table>", "<div class=\"scroll\"><table>").replace(
        "</table>", "</table></div>")
    page = (f"<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
            f"<title>{html.escape(title)}</title><style>{STYLE}</style></head>"
            f"<body>\n{body}\n</body></html>\n")
    return write_text(path, page)


def _inline(match: re.Match[str], base: Path, figures: frozenset[str]) -> str:
    attrs, src = match.group(1), match.group(2)
    file = base / src
    if src not in figures or not _inside(file, base):
        return match.group(0)
    data = base64.b64encode(file.read_bytes()).decode("ascii")
    kind = "svg+xml" if file.suffix == ".svg" else file.suffix.lstrip(".")
    extra = "class=\"traj\" " if file.name.startswith("traj_") else ""
    return f"<img {extra}{attrs}src=\"data:image/{kind};base64,{data}\""


def _inside(file: Path, base: Path) -> bool:
    """Whether ``file`` is a regular file inside ``base``, no link on the way."""
    try:
        real = file.resolve(strict=True)
        return (real.is_relative_to(base.resolve(strict=True)) and real.is_file()
                and real == base.resolve() / file.relative_to(base))
    except (OSError, ValueError):
        return False


def _verdict_cell(match: re.Match[str]) -> str:
    attrs, text = match.group(1), match.group(2)
    for words, css in ((BAD, "bad"), (GOOD, "good"), (NEUTRAL, "neutral")):
        if text.strip() in words:
            return f"<td class=\"{css}\"{attrs}>{text}</td>"
    return match.group(0)
