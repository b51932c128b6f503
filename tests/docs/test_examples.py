"""The code examples of the documentation run as tests, so that none rots.

The convention (every page of ``docs/`` and ``README.md``):

- every fenced ``python`` block runs; a page's blocks run in order in one namespace (as
  ``__main__``), in a fresh temporary folder, with ``SDL_VIDEODRIVER=dummy``;
- a block whose previous non-blank line is ``<!-- docs-test: skip (reason) -->`` does not run;
  the reason is mandatory;
- ``bash`` / ``console`` / ``sh`` / ``shell`` blocks do not run, unless preceded by
  ``<!-- docs-test: run -->``: then each command (a ``console`` block's ``$ `` lines) runs in
  the page's temporary folder, with a timeout, the installed ``boids`` first on the PATH;
- a marker anywhere else, or a malformed one, fails the page's test.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import traceback
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PYTHON = {"python", "py", "python3"}
SHELL = {"bash", "console", "sh", "shell"}
COMMAND_TIMEOUT = 120
"""Seconds one documented shell command may take."""

_FENCE = re.compile(r"^(?P<indent>[ \t]*)(?P<fence>`{3,}|~{3,})[ \t]*(?P<info>[^`\n]*)$")
_MARKER = re.compile(r"^\s*<!--\s*docs-test:(?P<body>.*?)-->\s*$")
_SKIP = re.compile(r"^\s*skip\s+\((?P<reason>[^)]*\S[^)]*)\)\s*$")


@dataclass(frozen=True)
class Block:
    """One fenced code block of a page."""

    line: int
    """1-based line of the block's first code line."""
    lang: str
    code: str
    marker: str | None = None
    """``skip`` or ``run`` when a docs-test marker precedes it."""
    reason: str = ""


class MarkerError(ValueError):
    """A docs-test marker that breaks the convention."""


def pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def parse(text: str, where: str = "page") -> list[Block]:
    """The fenced blocks of a Markdown text with their markers; ``MarkerError`` for a
    marker that is malformed or precedes no block."""
    lines = text.splitlines()
    blocks: list[Block] = []
    pending: tuple[int, str, str] | None = None  # (line, kind, reason) of an open marker
    i = 0
    while i < len(lines):
        line = lines[i]
        marker = _MARKER.match(line)
        fence = _FENCE.match(line)
        if marker:
            if pending:
                raise MarkerError(f"{where}:{pending[0]}: docs-test marker precedes no block")
            pending = (i + 1, *_marker(marker["body"], f"{where}:{i + 1}"))
        elif fence:
            i, block = _block(lines, i, fence, pending)
            blocks.append(block)
            pending = None
        elif line.strip() and pending:
            raise MarkerError(f"{where}:{pending[0]}: docs-test marker precedes no block")
        i += 1
    if pending:
        raise MarkerError(f"{where}:{pending[0]}: docs-test marker precedes no block")
    return blocks


def _marker(body: str, where: str) -> tuple[str, str]:
    body = body.strip()
    if body == "run":
        return "run", ""
    skip = _SKIP.match(body)
    if skip:
        return "skip", skip["reason"].strip()
    if body.startswith("skip"):
        raise MarkerError(f"{where}: a skip needs its reason: <!-- docs-test: skip (why) -->, "
                          f"got {body!r}")
    raise MarkerError(f"{where}: unknown docs-test marker {body!r} (skip (reason) or run)")


def _block(lines: list[str], start: int, fence: re.Match[str],
           pending: tuple[int, str, str] | None) -> tuple[int, Block]:
    indent, mark = fence["indent"], fence["fence"]
    lang = fence["info"].strip().split(" ")[0].strip("{}.").lower() if fence["info"] else ""
    end = start + 1
    close = re.compile(rf"^[ \t]*{re.escape(mark[0])}{{{len(mark)},}}[ \t]*$")
    while end < len(lines) and not close.match(lines[end]):
        end += 1
    body = [ln[len(indent):] if ln.startswith(indent) else ln.lstrip()
            for ln in lines[start + 1:end]]
    kind, reason = (pending[1], pending[2]) if pending else (None, "")
    return end, Block(start + 2, lang, "\n".join(body) + "\n", kind, reason)


def commands(block: Block) -> list[str]:
    """The commands of a shell block: ``\\``-continued lines joined, comments and blank lines
    left out; in a ``console`` block only the ``$ `` lines (the rest is output)."""
    out: list[str] = []
    pending = ""
    for raw in block.code.splitlines():
        line = raw.rstrip()
        if block.lang == "console":
            if not pending and not line.startswith("$ "):
                continue
            line = line.removeprefix("$ ") if not pending else line
        if not pending and (not line.strip() or line.lstrip().startswith("#")):
            continue
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        out.append(pending + line)
        pending = ""
    if pending:
        out.append(pending)
    return out


def run_page(path: Path, tmp: Path) -> int:
    """Runs a page's examples by the convention in ``tmp``; returns how many ran. Raises
    ``AssertionError`` naming the page and line of the first that fails."""
    rel = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
    blocks = parse(path.read_text(encoding="utf-8"), str(rel))
    namespace: dict[str, object] = {"__name__": "__main__"}  # as a reader runs it
    ran = 0
    cwd, video = Path.cwd(), os.environ.get("SDL_VIDEODRIVER")
    os.chdir(tmp)
    os.environ["SDL_VIDEODRIVER"] = "dummy"
    try:
        for block in blocks:
            if block.marker == "skip":
                continue
            if block.lang in PYTHON:
                if block.marker == "run":
                    raise MarkerError(f"{rel}:{block.line}: 'run' marks shell blocks; python "
                                      f"blocks always run")
                _run_python(block, str(path), namespace, f"{rel}:{block.line}")
                ran += 1
            elif block.lang in SHELL and block.marker == "run":
                for command in commands(block):
                    _run_command(command, tmp, f"{rel}:{block.line}")
                ran += 1
    finally:
        os.chdir(cwd)
        if video is None:
            os.environ.pop("SDL_VIDEODRIVER", None)
        else:
            os.environ["SDL_VIDEODRIVER"] = video
    return ran


def _run_python(block: Block, filename: str, namespace: dict[str, object], where: str) -> None:
    # padded so that tracebacks give the page's own line numbers
    source = "\n" * (block.line - 1) + block.code
    try:
        exec(compile(source, filename, "exec"), namespace)
    except Exception:
        raise AssertionError(f"the python example at {where} failed:\n"
                             f"{traceback.format_exc()}") from None


def _run_command(command: str, cwd: Path, where: str) -> None:
    env = {**os.environ, "SDL_VIDEODRIVER": "dummy",
           "PATH": os.pathsep.join([str(Path(sys.executable).parent),
                                    os.environ.get("PATH", "")])}
    try:
        done = subprocess.run(["bash", "-euo", "pipefail", "-c", command], cwd=cwd, env=env,
                              capture_output=True, text=True, timeout=COMMAND_TIMEOUT)
    except subprocess.TimeoutExpired:
        raise AssertionError(f"the command at {where} ran past {COMMAND_TIMEOUT} s: "
                             f"{command}") from None
    assert done.returncode == 0, (f"the command at {where} exited {done.returncode}: "
                                  f"{shlex.quote(command)}\n{done.stdout[-3000:]}"
                                  f"{done.stderr[-3000:]}")


def _page_params() -> list[object]:
    params: list[object] = []
    for path in pages():
        params.append(pytest.param(path, id=str(path.relative_to(ROOT))))
    return params


@pytest.mark.parametrize("path", _page_params())
def test_the_examples_of_every_page_run(path, tmp_path):
    run_page(path, tmp_path)


# ------------------------------------------------------------------ the convention itself
PAGE = """\
# A page

```python
x = 2
```

<!-- docs-test: skip (needs a GPU) -->

```python
raise RuntimeError("skipped")
```

!!! note
    ```py
    y = x * 3
    ```

```bash
exit 1
```

<!-- docs-test: run -->
```console
$ echo one > out.txt
some output
$ test "$(cat out.txt)" = one && \\
    echo two
```

~~~python
assert y == 6
~~~
"""


def test_the_parser_finds_every_block_and_its_marker():
    blocks = parse(PAGE)
    assert [(b.line, b.lang, b.marker, b.reason) for b in blocks] == [
        (4, "python", None, ""), (10, "python", "skip", "needs a GPU"), (15, "py", None, ""),
        (19, "bash", None, ""), (24, "console", "run", ""), (31, "python", None, "")]
    assert blocks[2].code == "y = x * 3\n"
    assert commands(blocks[4]) == ["echo one > out.txt",
                                   'test "$(cat out.txt)" = one &&      echo two']
    assert commands(Block(1, "bash", "# set up\nls \\\n  -l\n\npwd\n")) == ["ls    -l", "pwd"]


def test_a_page_runs_in_order_in_one_namespace_skipping_what_is_marked(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(PAGE)
    work = tmp_path / "work"
    work.mkdir()
    assert run_page(page, work) == 4  # three python blocks and the marked console block
    assert (work / "out.txt").read_text() == "one\n"


@pytest.mark.parametrize("marker", ["<!-- docs-test: skip -->", "<!-- docs-test: skip () -->",
                                    "<!-- docs-test: skipit (x) -->",
                                    "<!-- docs-test: runs -->"])
def test_a_malformed_marker_fails(marker):
    with pytest.raises(MarkerError, match="page:1"):
        parse(f"{marker}\n```python\npass\n```\n")


def test_a_marker_before_no_block_fails():
    with pytest.raises(MarkerError, match="precedes no block"):
        parse("<!-- docs-test: run -->\nSome text.\n\n```bash\nls\n```\n")
    with pytest.raises(MarkerError, match="precedes no block"):
        parse("text\n<!-- docs-test: skip (why) -->\n")


def test_a_failing_example_names_its_page_and_line(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("# P\n\n```python\nx = 1\n```\n\n```python\nassert x == 2, 'x is 1'\n```\n")
    with pytest.raises(AssertionError, match=r"page.md:8 failed(.|\n)*line 8(.|\n)*x is 1"):
        run_page(page, tmp_path)
    page.write_text("<!-- docs-test: run -->\n```bash\nfalse\n```\n")
    with pytest.raises(AssertionError, match=r"page.md:3 exited 1"):
        run_page(page, tmp_path)
