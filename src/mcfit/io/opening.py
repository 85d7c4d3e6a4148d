"""Opening a record: a path, ``"-"`` or a stream to a table, judged by its content.

A gzip or workbook signature decides, not the extension; anything else (``.lvm``, ``.log``,
no extension) is read as text.
"""

from __future__ import annotations

import stat
import sys
from pathlib import Path

from mcfit.errors import InputError, UsageError
from mcfit.files import RECORD_TYPES, record_type, supported_types
from mcfit.io.excel import _CFB_SIGNATURE, _excel_table
from mcfit.io.limits import MAX_BYTES, read_at_most, too_large
from mcfit.io.table import _SNIFF_BYTES, _text_table
from mcfit.io.wav import _wav_table, is_wav

TEXT_EXTENSIONS = dict(RECORD_TYPES)["text"]
EXCEL_EXTENSIONS = (".xlsx", ".xlsm")  # zip workbooks, read by openpyxl


def _open_table(source, sheet):
    if hasattr(source, "read"):
        name = getattr(source, "name", None)  # an open file's path, as it was given
        name = name if isinstance(name, str) and not name.startswith("<") else "<stdin>"
        return _text_table(name, read_at_most(source, name), None)
    if isinstance(source, str) and source == "-":
        if sys.stdin is None:
            raise InputError("standard input is closed, so - cannot be read. Give the record "
                             "on stdin (mcfit - < run.csv) or name the file.")
        return _text_table("<stdin>", read_at_most(sys.stdin.buffer, "<stdin>"), None)
    path = Path(source)
    name = str(source)  # as given: in a batch, file names alone can be ambiguous
    try:
        info = path.stat()
    except FileNotFoundError:
        raise InputError(f"file not found: {source}. Check the path and the working "
                         "directory.") from None
    except NotADirectoryError:
        raise InputError(f"file not found: {source} (a part of the path is a file, not a "
                         "directory). Check the path.") from None
    except OSError as exc:  # a folder on the way that may not be entered, a loop...
        raise InputError(f"cannot read {source}: {exc.strerror or exc}. Check the "
                         "permissions of the file and of its folders.") from None
    if stat.S_ISDIR(info.st_mode):
        raise InputError(f"{source} is a directory, not a file. Give a data file inside it.")
    if not stat.S_ISREG(info.st_mode):
        # Reading a FIFO or a device could block forever or never end.
        raise InputError(f"{source} is not a regular file (a pipe, socket or device). Copy "
                         "the record to a file, or pipe it to mcfit as - (stdin).")
    if info.st_size > MAX_BYTES:
        raise too_large(name, "the file", info.st_size, MAX_BYTES)
    suffix = path.suffix.lower()
    if suffix in _REFUSED_EXTENSIONS:
        raise InputError(f"unsupported file type '{suffix}' for {name}; use "
                         f"{supported_types()} (or export the data as delimited text).")
    try:
        with open(path, "rb") as handle:
            head = handle.read(_SNIFF_BYTES)
            tail = b""
            if len(head) == _SNIFF_BYTES:
                size = handle.seek(0, 2)
                handle.seek(max(len(head), size - _TAIL_BYTES))
                tail = handle.read()
    except OSError as exc:
        raise InputError(f"cannot read {name}: {exc.strerror}. Check its permissions.") from None
    # The content decides, not the extension: a workbook, WAV or gzip file by its
    # signature, anything else (.lvm, .log, no extension) as text; a .wav is audio or
    # damaged.
    kind = record_type(suffix)
    if head.startswith(_GZIP_SIGNATURE):
        return _gzip_table(path, name, sheet)
    if kind == "audio" or is_wav(head):
        if sheet is not None:
            raise UsageError(f"`sheet` applies to Excel files only, and {name} is WAV audio.")
        return _wav_table(path, name)
    if kind == "workbook" and not (suffix in EXCEL_EXTENSIONS
                                         and head.startswith(_CFB_SIGNATURE)):
        return _excel_table(path, name, sheet, suffix)
    if suffix in EXCEL_EXTENSIONS or head.startswith(_ZIP_SIGNATURE):
        return _excel_table(path, name, sheet, ".xlsx")
    if head.startswith(_CFB_SIGNATURE):
        return _excel_table(path, name, sheet, ".xls")
    if sheet is not None:
        raise UsageError(f"`sheet` applies to Excel files only, and {name} is a text file.")
    return _text_table(name, head, path, tail=tail)


_GZIP_SIGNATURE = b"\x1f\x8b"
_ZIP_SIGNATURE = b"PK\x03\x04"
# Bytes read from the end of a file longer than the sniff, for notes or NUL bytes at its end.
_TAIL_BYTES = 1 << 14
# Files that are surely not a record, refused by name before reading.
_REFUSED_EXTENSIONS = (".json", ".xml", ".html", ".htm", ".pdf", ".png", ".jpg", ".jpeg",
                       ".gif", ".svg", ".doc", ".docx", ".ppt", ".pptx", ".numbers", ".mat",
                       ".npy", ".npz", ".h5", ".hdf5", ".zip", ".7z", ".rar", ".mp4", ".mov",
                       ".avi", ".mp3", ".cmbl", ".py", ".ipynb")


def _gzip_table(path, name, sheet):
    import gzip
    import zlib
    try:
        with gzip.open(path) as stream:
            data = read_at_most(stream, name, "the decompressed text")
    except (OSError, EOFError, zlib.error) as exc:
        raise InputError(f"cannot decompress {name}: {exc}. The gzip file is damaged; "
                         "decompress it with another program or export the data again.") from None
    if data.startswith(_ZIP_SIGNATURE) or data.startswith(_CFB_SIGNATURE):
        raise InputError(f"{name} holds a compressed workbook, which mcfit cannot open. "
                         "Decompress it first.")
    if sheet is not None:
        raise UsageError(f"`sheet` applies to Excel files only, and {name} is a text file.")
    table = _text_table(name, data, None)
    table.notes.insert(0, "gzip-compressed file decompressed")
    return table


def _to_bytes(data):
    return data.encode("utf-8") if isinstance(data, str) else bytes(data)
