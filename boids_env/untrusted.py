"""Reading files from elsewhere within budgets: one place for every untrusted read.

A map, a shapes file, a walk, a suite, a recipe or a model zip may come from anyone. Each is
read here, and each read is bounded *before* anything large is allocated:

- :func:`read_bytes` opens only regular files (a FIFO, a device such as ``/dev/zero``, a
  folder or a socket is refused; opening never blocks), refuses a file larger than its byte
  budget from its size, and reads at most one byte past the budget in any case;
- :func:`parse_yaml` / :func:`parse_toml` / :func:`parse_json` refuse nesting deeper than
  :data:`MAX_DEPTH` and (YAML) more than :data:`MAX_ALIASES` aliases or a document that would
  expand to more than :data:`MAX_NODES` values ("billion laughs"), with a ``ValueError``
  rather than a ``RecursionError`` or exhausted memory;
- :func:`excerpt` quotes at most a short, escaped excerpt of a value in an error message (a
  message never repeats an expanded alias or the content of a file it was not meant to read);
- :func:`safe_name` is the one boundary where a name from a file (a suite's, a case's, a
  shapes file's) is checked for length and its control characters escaped, so it reaches a
  terminal, a file name or a CSV without escape sequences.

Every error names the field (``map``, ``scene``, ``suite``, ``recipe``, ``leader_trajectory``,
…) and the limit.
"""

from __future__ import annotations

import json
import os
import reprlib
import stat
import tomllib
import zipfile
from pathlib import Path
from typing import Any

MAX_DEPTH = 32
"""Deepest nesting of lists and tables in a parsed file (ours need 4)."""
MAX_ALIASES = 64
"""Most YAML aliases (``*name``) in one document (ROS map YAMLs use none)."""
MAX_NODES = 100_000
"""Most values a YAML document may expand to, aliases counted as often as they are used."""
MAX_MODEL_BYTES = 512 * 1024 * 1024
"""A model zip larger than this (512 MiB) is refused before it is opened (ours are 1-5 MB)."""
MAX_RATIO = 20
"""Most times an entry of a zip may inflate its compressed bytes, once it holds more than
:data:`RATIO_FREE` (float weights inflate about 1.1 times, SB3's ``data`` about 3; a zip bomb
1,000): a small file never inflates to gigabytes, whatever its directory declares."""
RATIO_FREE = 4 << 20
"""Uncompressed bytes (4 MiB) an entry may hold whatever its compression ratio."""
MAX_ZIP_ENTRIES = 1000
"""Most entries in a model zip (SB3 writes 5, ``boids train`` 7)."""
MAX_NAME = 100
"""Longest name (characters) a file may give a suite, a case or a scene."""
EXCERPT = 60
"""Longest excerpt (characters) of a value quoted in an error message."""

_REPR = reprlib.Repr()
_REPR.maxlevel = 3
_REPR.maxstring = EXCERPT
_REPR.maxother = EXCERPT
for _name in ("maxlist", "maxtuple", "maxdict", "maxset", "maxfrozenset", "maxdeque",
              "maxarray"):
    setattr(_REPR, _name, 6)


def excerpt(value: Any, limit: int = EXCERPT) -> str:
    """A short, printable quotation of ``value`` for an error message: a string quoted with
    its control characters escaped, anything else as a bounded ``repr`` (nested containers cut
    at a few items and levels, so quoting a huge value costs nothing); at most ``limit``
    characters, an ellipsis marking a cut."""
    if isinstance(value, str):
        text = repr(value[: limit + 1])
    elif isinstance(value, os.PathLike):
        text = repr(os.fspath(value)[: limit + 1])
    else:
        text = _REPR.repr(value)
    text = _escape(text)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _escape(text: str) -> str:
    """``text`` with every non-printable character (ANSI escapes, bidi controls, newlines)
    written as its Python escape."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii")
                   for c in text)


def printable(text: str, limit: int = 400) -> str:
    """``text`` with its control characters escaped, cut to at most ``limit`` characters."""
    text = _escape(text)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def quote_path(path: str | Path, limit: int = 200) -> str:
    """A file's path for a message: control characters escaped, at most ``limit``
    characters."""
    return printable(os.fspath(path), limit)


def safe_name(value: Any, field: str, limit: int = MAX_NAME) -> str:
    """A name from a file, checked and made safe for terminals, file names and CSVs: a
    non-empty string of at most ``limit`` characters (else ``ValueError`` naming ``field``),
    returned with line breaks and tabs as spaces and its other control characters escaped
    (``\\x1b`` for ESC)."""
    if not isinstance(value, str) or not value:
        raise ValueError(f"{field} must be a non-empty string, got {excerpt(value)}")
    if len(value) > limit:
        raise ValueError(f"{field} must be at most {limit} characters, got {len(value)} "
                         f"({excerpt(value)})")
    return _escape(value.translate(_SPACES))


_SPACES = str.maketrans("\t\n\r\v\f", "     ")


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISDIR, "folder"), (stat.S_ISFIFO, "FIFO (named pipe)"),
                       (stat.S_ISCHR, "character device"), (stat.S_ISBLK, "block device"),
                       (stat.S_ISSOCK, "socket")):
        if test(mode):
            return name
    return "special file"


def read_bytes(path: str | Path, field: str, limit: int) -> bytes:
    """The content of ``path``, which must be a regular file of at most ``limit`` bytes.

    A FIFO, a device (``/dev/zero``, also through a symlink), a folder or a socket is refused
    (opened without blocking, then checked with ``fstat``); a larger file is refused from its
    size before reading, and at most ``limit + 1`` bytes are ever read (a file that grows
    while read is refused too). Errors are ``ValueError`` naming ``field`` and the limit."""
    where = f"{field} {quote_path(path)}"
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise ValueError(f"{where}: cannot be read ({exc.strerror or exc})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ValueError(f"{where}: not a regular file (a {_kind(info.st_mode)})")
        if info.st_size > limit:
            raise ValueError(f"{where}: {info.st_size:,} bytes, more than the {limit:,} "
                             f"allowed")
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise ValueError(f"{where}: cannot be read ({exc.strerror or exc})") from None
    finally:
        os.close(fd)
    if size > limit:
        raise ValueError(f"{where}: more than the {limit:,} bytes allowed")
    return b"".join(chunks)


def check_file(path: str | Path, field: str, limit: int) -> int:
    """The size of ``path`` if it is a regular file of at most ``limit`` bytes (checked
    without reading it or blocking), else the ``ValueError`` of :func:`read_bytes`."""
    where = f"{field} {quote_path(path)}"
    try:
        info = os.stat(path)
    except OSError as exc:
        raise ValueError(f"{where}: cannot be read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f"{where}: not a regular file (a {_kind(info.st_mode)})")
    if info.st_size > limit:
        raise ValueError(f"{where}: {info.st_size:,} bytes, more than the {limit:,} allowed")
    return info.st_size


def file_identity(path: str | Path, field: str) -> tuple[str, int, int]:
    """``(resolved path, size, mtime_ns)`` of ``path``, which must be a regular file: the
    key a parsed file is cached under (an edited file is read again); else a ``ValueError``
    naming ``field``."""
    where = f"{field} {quote_path(path)}"
    p = Path(path)
    try:
        info = p.stat()
    except OSError as exc:
        raise ValueError(f"{where}: cannot be read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(info.st_mode):
        raise ValueError(f"{where}: not a regular file (a {_kind(info.st_mode)})")
    return str(p.resolve()), info.st_size, info.st_mtime_ns


def open_zip(path: str | Path, field: str = "policy model",
             limit: int = MAX_MODEL_BYTES) -> zipfile.ZipFile:
    """``path`` opened as a zip for reading, once it is known to be a regular file of at most
    ``limit`` bytes with at most :data:`MAX_ZIP_ENTRIES` entries (a FIFO or ``/dev/zero``
    never reaches :mod:`zipfile`, which reads to the end of what it is given). Read entries
    with :func:`boids_env.files.read_zip_entry`, which bounds what each inflates to.
    ``ValueError`` naming ``field`` otherwise; a file that is not a zip raises what
    :class:`zipfile.ZipFile` raises."""
    check_file(path, field, limit)
    archive = zipfile.ZipFile(path)  # its own errors (BadZipFile, ...) as they are
    if len(archive.filelist) > MAX_ZIP_ENTRIES:
        archive.close()
        raise ValueError(f"{field} {quote_path(path)}: {len(archive.filelist):,} entries, more "
                         f"than the {MAX_ZIP_ENTRIES:,} allowed")
    return archive


def inflated_allowance(compressed: int, limit: int) -> int:
    """The most bytes ``compressed`` bytes of a zip may inflate to within ``limit``: at most
    :data:`MAX_RATIO` times as many, :data:`RATIO_FREE` in any case."""
    return min(limit, max(RATIO_FREE, MAX_RATIO * compressed))


_METHODS = {zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED, zipfile.ZIP_BZIP2, zipfile.ZIP_LZMA}


def check_zip_entry(info: zipfile.ZipInfo, limit: int) -> int:
    """The bytes the zip entry ``info`` may inflate to (:func:`inflated_allowance`), once the
    size its directory declares is within it: ``ValueError`` naming the entry and the limit
    (``limit`` bytes, or :data:`MAX_RATIO` times its compressed size) otherwise. The declared
    size may lie: read the entry stopping one byte past the returned allowance."""
    name = printable(info.filename, 120)
    if info.flag_bits & 0x1:
        raise ValueError(f"its entry {name} is encrypted")
    if info.compress_type not in _METHODS:
        raise ValueError(f"its entry {name} is compressed by method {info.compress_type}, not "
                         f"one of {sorted(_METHODS)} (stored, deflate, bzip2, lzma)")
    if info.file_size > limit:
        raise ValueError(f"its entry {name} holds {info.file_size:,} bytes uncompressed, more "
                         f"than the {limit:,} allowed")
    allowed = inflated_allowance(info.compress_size, limit)
    if info.file_size > allowed:
        raise ValueError(f"its entry {name} inflates {info.compress_size:,} bytes to "
                         f"{info.file_size:,}, more than the {MAX_RATIO} times allowed beyond "
                         f"{RATIO_FREE:,} bytes (a zip bomb)")
    return allowed


def check_zip_entries(archive: zipfile.ZipFile, limit: int) -> None:
    """Every entry of ``archive`` checked by :func:`check_zip_entry` (at most ``limit`` bytes
    each), and all of them together inflating at most :data:`MAX_RATIO` times what they take
    compressed (:data:`RATIO_FREE` in any case): for a reader that inflates them all (a copy),
    whose work then stays in proportion to the file. ``ValueError`` naming the limit."""
    for info in archive.infolist():
        check_zip_entry(info, limit)
    total = sum(info.file_size for info in archive.infolist())
    allowed = inflated_allowance(sum(info.compress_size for info in archive.infolist()), limit)
    if total > allowed:
        raise ValueError(f"its entries hold {total:,} bytes uncompressed, more than the "
                         f"{allowed:,} allowed")


def read_text(path: str | Path, field: str, limit: int) -> str:
    """:func:`read_bytes` decoded as UTF-8 (``ValueError`` naming ``field`` otherwise)."""
    raw = read_bytes(path, field, limit)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{field} {quote_path(path)}: not UTF-8 text (byte "
                         f"{exc.start})") from None


def check_depth(data: Any, field: str, limit: int = MAX_DEPTH) -> Any:
    """``data`` unchanged if its lists and tables nest at most ``limit`` deep, else a
    ``ValueError`` naming ``field`` (walked without recursion)."""
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, dict):
            children: Any = value.values()
        elif isinstance(value, list | tuple):
            children = value
        else:
            continue
        if depth > limit:
            raise ValueError(f"{field}: nested more than {limit} levels deep")
        stack.extend((child, depth + 1) for child in children)
    return data


def parse_toml(text: str, field: str) -> dict[str, Any]:
    """A TOML document, nested at most :data:`MAX_DEPTH` deep; ``ValueError`` naming
    ``field`` for anything else."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"{field}: not valid TOML ({excerpt(str(exc), 120)})") from None
    except RecursionError:
        raise ValueError(f"{field}: nested more than {MAX_DEPTH} levels deep") from None
    return check_depth(data, field)


def parse_json(text: str | bytes, field: str) -> Any:
    """A JSON document, nested at most :data:`MAX_DEPTH` deep; ``ValueError`` naming
    ``field`` for anything else."""
    try:
        data = json.loads(text)
    except RecursionError:
        raise ValueError(f"{field}: nested more than {MAX_DEPTH} levels deep") from None
    except ValueError as exc:  # JSONDecodeError and UnicodeDecodeError
        raise ValueError(f"{field}: not valid JSON ({excerpt(str(exc), 120)})") from None
    return check_depth(data, field)


def parse_yaml(text: str, field: str) -> Any:
    """A YAML document read as ``yaml.safe_load`` does (plain values only, nothing
    constructed), refused with a ``ValueError`` naming ``field`` when it nests deeper than
    :data:`MAX_DEPTH`, uses more than :data:`MAX_ALIASES` aliases or expands to more than
    :data:`MAX_NODES` values (each alias counted with everything it stands for), before any
    of it is built."""
    import yaml

    try:
        loader = _bounded_loader(yaml)(text)
    except yaml.YAMLError as exc:  # the reader checks the characters up front
        raise ValueError(f"{field}: not valid YAML ({excerpt(str(exc), 120)})") from None
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_expansion(node)
        return loader.construct_document(node)
    except _Refused as exc:
        raise ValueError(f"{field}: {exc}") from None
    except RecursionError:
        raise ValueError(f"{field}: nested more than {MAX_DEPTH} levels deep") from None
    except yaml.YAMLError as exc:
        raise ValueError(f"{field}: not valid YAML ({excerpt(str(exc), 120)})") from None
    finally:
        loader.dispose()


class _Refused(Exception):
    """A bound of :func:`parse_yaml` crossed (turned into a ValueError naming the field)."""


_LOADER: Any = None


def _bounded_loader(yaml: Any) -> Any:
    """A ``SafeLoader`` whose composer counts aliases and nesting depth."""
    global _LOADER
    if _LOADER is None:
        class BoundedLoader(yaml.SafeLoader):
            def __init__(self, stream: str) -> None:
                super().__init__(stream)
                self.aliases = 0
                self.depth = 0

            def compose_node(self, parent: Any, index: Any) -> Any:
                if self.check_event(yaml.AliasEvent):
                    self.aliases += 1
                    if self.aliases > MAX_ALIASES:
                        raise _Refused(f"more than {MAX_ALIASES} YAML aliases")
                self.depth += 1
                try:
                    if self.depth > MAX_DEPTH:
                        raise _Refused(f"nested more than {MAX_DEPTH} levels deep")
                    return super().compose_node(parent, index)
                finally:
                    self.depth -= 1

        _LOADER = BoundedLoader
    return _LOADER


def _check_expansion(root: Any) -> None:
    """Refuses a node graph that expands to more than :data:`MAX_NODES` values (a shared
    node counted once per use), in time linear in the number of distinct nodes."""
    import yaml

    size: dict[int, int] = {}
    visiting: set[int] = set()
    stack: list[tuple[Any, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        if id(node) in size:
            continue
        if not done and id(node) in visiting:
            raise _Refused("a YAML alias refers to a value that contains it")
        if isinstance(node, yaml.SequenceNode):
            children = list(node.value)
        elif isinstance(node, yaml.MappingNode):
            children = [n for pair in node.value for n in pair]
        else:
            size[id(node)] = 1
            continue
        if done:
            size[id(node)] = 1 + sum(size[id(c)] for c in children)
            if size[id(node)] > MAX_NODES:
                raise _Refused(f"expands to more than {MAX_NODES:,} values (YAML aliases "
                               f"repeat what they name)")
        else:
            visiting.add(id(node))
            stack.append((node, True))
            stack.extend((c, False) for c in children if id(c) not in size)
