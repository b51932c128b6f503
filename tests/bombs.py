"""Zip bombs for tests, built in milliseconds: a deflate stream of ``n`` zero bytes made of one
compressed megabyte repeated (each piece ends in a full flush, so the pieces chain), and a zip
writer that takes such a stream as an entry's data and may declare sizes that lie."""

from __future__ import annotations

import struct
import zlib

_PIECE = 1 << 20


def deflated_zeros(n: int, head: bytes = b"") -> bytes:
    """A raw deflate stream inflating to ``head`` then zero bytes, ``len(head) + n`` in all
    (``n`` a multiple of 1 MiB), about ``n / 1000`` bytes long."""
    start = zlib.compressobj(9, zlib.DEFLATED, -15)
    first = start.compress(head) + start.flush(zlib.Z_FULL_FLUSH)
    piece = zlib.compressobj(9, zlib.DEFLATED, -15)
    zeros = piece.compress(bytes(_PIECE)) + piece.flush(zlib.Z_FULL_FLUSH)
    return first + zeros * (n // _PIECE) + zlib.compressobj(9, zlib.DEFLATED, -15).flush()


def zip_bytes(entries: list[tuple[str, bytes, int | None]]) -> bytes:
    """A zip of ``(name, data, inflated_size)`` entries: ``data`` as it is (stored) when
    ``inflated_size`` is None, else a raw deflate stream declared to inflate to
    ``inflated_size`` bytes (true or not; the CRC is not the data's)."""
    out, central = bytearray(), bytearray()
    for name, data, size in entries:
        raw_name = name.encode()
        method, crc = (0, zlib.crc32(data)) if size is None else (8, 0)
        size = len(data) if size is None else size
        common = struct.pack("<HHHHHIIIH", 20, 0, method, 0, 0x21, crc, len(data), size,
                             len(raw_name))
        offset = len(out)
        out += b"PK\x03\x04" + common + struct.pack("<H", 0) + raw_name + data
        central += (b"PK\x01\x02" + struct.pack("<H", 20) + common
                    + struct.pack("<HHHHII", 0, 0, 0, 0, 0, offset) + raw_name)
    end = struct.pack("<4sHHHHIIH", b"PK\x05\x06", 0, 0, len(entries), len(entries),
                      len(central), len(out), 0)
    return bytes(out + central + end)
