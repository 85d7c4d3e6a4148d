"""Limits no real record reaches, so that a hostile or broken file costs bounded time and
memory: each is refused with one line past its limit.

A record of 10^7 samples as CSV is about 250 MB, and Excel holds at most 1,048,576 rows a
sheet; exports of lab programs have a header of a few cells and a sheet or three.
"""

from __future__ import annotations

from mcfit.errors import InputError

# Bytes of a record read, as a file, from stdin or decompressed.
MAX_BYTES = 1 << 30
# A workbook's shared strings (all its text cells, uncompressed) and worksheets (its cells).
MAX_SHARED_STRING_BYTES = 32 << 20
MAX_SHEET_BYTES = 1 << 30
MAX_SHEETS = 1000
# Bytes read at a time from a stream.
_CHUNK = 1 << 20


def _size(n):
    return f"{n / (1 << 30):.3g} GiB" if n >= 1 << 30 else f"{n / (1 << 20):.3g} MiB"


def too_large(name, what, size, limit):
    """The error for ``what`` of ``size`` bytes past ``limit``."""
    return InputError(f"{name} is not read: {what} ({_size(size)} or more) passes the "
                      f"{_size(limit)} that no record reaches. Check that it is the record, or "
                      "cut it into parts.")


def read_at_most(stream, name, what="the text"):
    """The bytes of ``stream`` (binary or text), refused past :data:`MAX_BYTES`; a stream
    that starts with a megabyte of NUL bytes (``/dev/zero``) is refused at once."""
    chunks, size = [], 0
    while True:
        chunk = stream.read(_CHUNK)
        if not chunk:
            break
        if isinstance(chunk, str):
            chunk = chunk.encode("utf-8")
        if not chunks and len(chunk) == _CHUNK and not chunk.strip(b"\x00"):
            raise InputError(f"{name} is not a text record: it starts with a megabyte of NUL "
                             "bytes. Give a CSV, TSV or text export of the data.")
        size += len(chunk)
        if size > MAX_BYTES:
            raise too_large(name, what, size, MAX_BYTES)
        chunks.append(chunk)
    return b"".join(chunks)
