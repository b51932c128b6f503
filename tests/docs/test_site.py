"""The site as a whole: every relative link resolves, the README stays short, and the site
builds with MkDocs in strict mode (any warning fails) into pages that load nothing from the
internet."""

import importlib.util
import os
import re
import subprocess
import sys
import unicodedata
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
README_LINES = 250

_FENCED = re.compile(r"^([ \t]*)(`{3,}|~{3,}).*?^\1\2[ \t]*$", re.M | re.S)
_LINK = re.compile(r"!?\[(?:[^\]\\]|\\.)*\]\((?P<target><[^>]*>|[^)\s]+)(?:\s+\"[^\"]*\")?\)"
                   r"|^\s*\[[^\]]+\]:\s*(?P<ref>\S+)", re.M)
_HEADING = re.compile(r"^#{1,6}\s+(?P<text>.*?)\s*(?:\{(?P<attrs>[^}]*)\})?\s*#*\s*$", re.M)


def _pages() -> list[Path]:
    return [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]


def _generated(reference) -> dict[Path, str]:
    return {DOCS / path: generate() for path, generate in reference.PAGES.items()}


def slug(text: str) -> str:
    """The anchor MkDocs' toc extension gives a heading (its default slugify)."""
    text = re.sub(r"<[^>]+>|[`*]", "", text)
    text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    text = re.sub(r"[^\w\s-]", "", text).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def anchors(text: str) -> set[str]:
    """Heading anchors of a page (explicit ``{#id}`` ones included) and ``id="..."``s."""
    text = _FENCED.sub("", text)
    found = set(re.findall(r"""\bid=["']([^"']+)["']""", text))
    for heading in _HEADING.finditer(text):
        explicit = re.search(r"#([\w-]+)", heading["attrs"] or "")
        found.add(explicit[1] if explicit else slug(heading["text"]))
    return found


def links(text: str) -> list[tuple[int, str]]:
    """(line, target) of every Markdown link outside code."""
    blanked = _FENCED.sub(lambda m: "\n" * m[0].count("\n"), text)
    blanked = re.sub(r"(`+)(?:(?!\1).)+?\1", lambda m: " " * len(m[0]), blanked)
    out = []
    for match in _LINK.finditer(blanked):
        target = (match["target"] or match["ref"]).strip("<>")
        out.append((blanked.count("\n", 0, match.start()) + 1, target))
    return out


def broken_links(page: Path, text: str, generated: dict[Path, str]) -> list[str]:
    bad = []
    for line, target in links(text):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):  # http:, mailto:, ...
            continue
        path, _, anchor = target.partition("#")
        dest = (page.parent / path).resolve() if path else page
        where = f"{page.relative_to(ROOT)}:{line}: {target}"
        if path and dest not in generated and not dest.exists():
            bad.append(f"{where} (no such file)")
            continue
        if anchor and dest.suffix == ".md" and dest.is_relative_to(DOCS):
            content = (text if not path else generated.get(dest)
                       or dest.read_text(encoding="utf-8"))
            if anchor not in anchors(content):
                bad.append(f"{where} (no such anchor)")
    return bad


def test_every_relative_link_resolves(reference):
    generated = _generated(reference)
    pages = {p: p.read_text(encoding="utf-8") for p in _pages()}
    bad = [b for page, text in {**pages, **generated}.items()
           for b in broken_links(page, text, generated)]
    assert not bad, "broken links:\n" + "\n".join(bad)


def test_the_link_check_finds_missing_files_and_anchors(tmp_path, reference):
    generated = _generated(reference)
    page = DOCS / "how-to" / "example.md"
    text = ("# Example\n\n## A `code` heading\n\nSee [run](run.md), [cfg](../reference/config.md"
            "#worldconfig), [here](#a-code-heading), [web](https://example.org).\n"
            "Broken: [x](nope.md), [y](run.md#nowhere), [z](#missing), "
            "[w](../reference/cli.md#boids-nothing).\n\n```md\n[not a link](skipped.md)\n```\n"
            "Also `[code](skipped.md)`.\n")
    bad = broken_links(page, text, generated)
    assert [b.split(": ", 1)[1] for b in bad] == [
        "nope.md (no such file)", "run.md#nowhere (no such anchor)", "#missing (no such anchor)",
        "../reference/cli.md#boids-nothing (no such anchor)"]


def test_the_generated_pages_are_not_committed_as_text(reference):
    # a committed copy would go stale; the build generates them from the code
    assert sorted(reference.PAGES) == ["reference/cli.md", "reference/config.md",
                                       "reference/metrics.md", "reference/models.md",
                                       "reference/observations.md"]
    assert not [p for p in reference.PAGES if (DOCS / p).exists()]


def test_the_readme_is_short():
    lines = len((ROOT / "README.md").read_text(encoding="utf-8").splitlines())
    assert lines <= README_LINES, f"README.md has {lines} lines, more than {README_LINES}: " \
                                  "the rest belongs on the site (docs/)"


def _have_docs_extra() -> bool:
    return all(importlib.util.find_spec(m) for m in ("mkdocs", "material", "mkdocstrings"))


@pytest.mark.slow
def test_the_site_builds_strictly_and_offline(tmp_path):
    if not _have_docs_extra():
        if os.environ.get("BOIDS_REQUIRE_DOCS") == "1":
            pytest.fail("BOIDS_REQUIRE_DOCS=1 but the docs extra is not installed")
        pytest.skip("the docs extra is not installed (pip install -e '.[docs]'); CI builds "
                    "the site (BOIDS_REQUIRE_DOCS=1)")
    site = tmp_path / "site"
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-d", str(site)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "SDL_VIDEODRIVER": "dummy",
                               "NO_MKDOCS_2_WARNING": "1"})
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-4000:]
    for page in ("reference/config.html", "reference/cli.html", "reference/observations.html",
                 "reference/metrics.html", "reference/api.html", "how-to/run.html"):
        assert (site / page).is_file(), page
    api = (site / "reference/api.html").read_text()
    assert "BoidsEnv" in api and "ReynoldsPolicy" in api and "run_suite" in api
    assert not re.search(r":(mod|func|class|data|meth|attr):<code", api)  # reST roles shown
    assert (site / "search" / "search_index.js").is_file()  # the offline search's index
    online = []
    for html in site.rglob("*.html"):
        for tag in re.findall(r"<(?:script|link|img|iframe|source)\b[^>]*>", html.read_text()):
            if re.search(r"""(?:src|href)=["']?(?:https?:)?//""", tag):
                online.append(f"{html.relative_to(site)}: {tag}")
    for css in site.rglob("*.css"):
        online += [f"{css.relative_to(site)}: {u}"
                   for u in re.findall(r"url\(\s*['\"]?(?:https?:)?//[^)]*\)", css.read_text())]
    assert not online, "the site loads from the internet:\n" + "\n".join(online[:20])
