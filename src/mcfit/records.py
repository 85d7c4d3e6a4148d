"""Reading decay records (CSV, TSV, semicolon, whitespace text, Excel, stdin) into a :class:`Record`.

This is the only module that imports pandas. It turns whatever file a person has into two
float64 arrays, ``t`` and ``x``, and says in ``Record.notes`` what it decided on the way
(columns chosen, decimal commas, padding dropped, timestamps ignored...). Every failure a
person can fix raises :class:`mcfit.errors.InputError` (or ``UsageError`` for contradictory
options) with one line naming the file, the problem and the fix.

A file is judged by its content: a gzip or workbook signature, else text. Text that is more
than a header line over numbers (header blocks, separator lines, a units row, repeated
headers, notes after the data, D exponents, clock times, data in rows) is first rewritten
by the tidying step as one header line over tab-separated numbers; a workbook sheet is
turned into such text too, so every source meets the same column choice and checks.

Column choice without options: a column named like time (``time``, ``t``, ``time (s)``...)
or else the first strictly increasing column is the time; the signal is the first other
column that oscillates (velocity, acceleration, residual and fit columns come last).
"""

from __future__ import annotations

import csv
import io
import re
import stat
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from mcfit.errors import InputError, UsageError
from mcfit.options import check_read_options
from mcfit.record import Record, detect_kind

__all__ = ["Record", "read_record", "read_records", "TEXT_EXTENSIONS", "EXCEL_EXTENSIONS"]

TEXT_EXTENSIONS = (".csv", ".tsv", ".txt", ".dat")
EXCEL_EXTENSIONS = (".xlsx", ".xlsm")

# Bytes sniffed to choose separator, decimal mark, header and columns.
_SNIFF_BYTES = 1 << 20
# Lines of data parsed as the sample that guides the choice of columns.
_SAMPLE_LINES = 20000
# Line breaks of str.splitlines that pandas' parser does not break lines at.
_PYTHON_ONLY_LINE_BREAKS = ("\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029")
_TIME_NAMES = {"time", "t", "times", "tempo", "zeit", "temps", "tiempo", "seconds", "sec",
               "timestamp", "stamp", "elapsed", "elapsed time", "time elapsed", "time_elapsed",
               "elapsed_time", "x_value", "clock", "time stamp", "time_s", "latest: time"}
_CYCLE_NAMES = {"n", "cycle", "cycles", "cycle number", "swing", "swings", "period number",
                "peak", "peak number", "k", "index"}
_SECONDARY_SIGNAL_WORDS = ("vel", "speed", "acc", "resid", "error", "err", "fit", "model",
                           "derivative")
_NUMBER = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eE][+-]?\d+)?$")
# Time units a header may name, in seconds (the report gives coefficients per second).
_SECONDS_PER_UNIT = {
    "s": 1.0, "sec": 1.0, "secs": 1.0, "second": 1.0, "seconds": 1.0,
    "ms": 1e-3, "msec": 1e-3, "us": 1e-6, "usec": 1e-6, "ns": 1e-9,
    "min": 60.0, "mins": 60.0, "minute": 60.0, "minutes": 60.0,
    "h": 3600.0, "hr": 3600.0, "hrs": 3600.0, "hour": 3600.0, "hours": 3600.0,
}
# Control characters other than tab, newline, vertical tab, form feed and carriage return.
_CONTROL_CHARACTER = re.compile("[\x00-\x08\x0e-\x1f\x7f-\x9f]")
# The ASCII bytes that are not control characters (deleted to count the others).
_NOT_CONTROL_BYTES = bytes(b for b in range(128) if not _CONTROL_CHARACTER.match(chr(b)))
_COMMA_DECIMAL = re.compile(r"^[+-]?\d*,\d+([eE][+-]?\d+)?$")
_UNIT = re.compile(r"^(.*?)\s*[\(\[]\s*([^\)\]]*)\s*[\)\]]\s*$")


def read_record(source, *, time_col=None, signal_col=None, sheet=None, rate=None,
                kind=None, domain=None, run=None, angle_from=None):
    """Read a decay record from a file, ``"-"`` (stdin) or an open stream.

    Parameters
    ----------
    source : str, os.PathLike or file-like
        Delimited text of any extension (separator sniffed: comma, semicolon, tab or
        whitespace; decimal comma accepted), gzip-compressed text, ``.xlsx``/``.xlsm``,
        ``.ods`` and ``.xls`` (with pandas' engine installed), ``"-"`` for stdin, or an open
        text or binary stream holding delimited text.
    time_col, signal_col : str or int, optional
        Column name (units in parentheses may be left out, case ignored) or 1-based index.
    sheet : str or int, optional
        Excel sheet name or 1-based index (default: the first sheet that holds numbers).
    rate : float, optional
        Sample rate in Hz: ``t = index / rate`` (for files without a usable time column).
    kind : {"waveform", "turning-points"}, optional
        Override the detected kind of record.
    domain : {"time", "cycle"}, optional
        Override the detected meaning of the time column (seconds or cycle number n).
    run : int, optional
        For a file of runs side by side, the run to read (its number, ``7`` for
        ``Run #7``, or its place in the file); needed when the file holds several.
    angle_from : (str or int, str or int), optional
        Columns of a tracked pendulum bob's x and y (pivot at the origin): the signal is
        the swing angle ``atan2(x, -y)`` in radians.

    Returns
    -------
    Record

    Raises
    ------
    InputError
        The file cannot be read or holds no usable columns (message: file, problem, fix).
    UsageError
        Contradictory or invalid options.
    """
    records = read_records(source, time_col=time_col, signal_col=signal_col, sheet=sheet,
                           rate=rate, kind=kind, domain=domain, run=run,
                           angle_from=angle_from)
    if len(records) > 1:
        runs = ", ".join(r.run for r in records)
        raise UsageError(f"{records[0].source} holds {len(records)} runs side by side "
                         f"({runs}); pick one with run=N, or read them all with "
                         "read_records.")
    return records[0]


def read_records(source, *, time_col=None, signal_col=None, sheet=None, rate=None,
                 kind=None, domain=None, run=None, angle_from=None):
    """Every run of a file as a :class:`Record`, in file order; see :func:`read_record`.

    Runs side by side are columns labelled ``Run #N`` (columns without a label, such as a
    shared time, belong to every run) or repeated groups of columns that each start with a
    time column. A file without them is one record with ``run`` None.
    """
    check_read_options(kind=kind, domain=domain, rate=rate, time_col=time_col,
                       signal_col=signal_col, angle_from=angle_from)
    rate = _checked_rate(rate)
    table = _open_table(source, sheet)
    # The column heuristics (spans, slopes, steps) overflow to inf or NaN for values near
    # the float64 limit, which then fail their tests as they should; the turning-point
    # search rejects such values with a message.
    with np.errstate(over="ignore", invalid="ignore"):
        runs = _chosen_runs(table, run, (time_col, signal_col) + tuple(angle_from or ()))
        return [_build_record(table, time_col, signal_col, rate, kind, domain,
                              run=run_of_file, angle_from=angle_from)
                for run_of_file in runs]


def _checked_rate(rate):
    """The sample rate as a float, or None (checked by :func:`check_read_options`)."""
    return None if rate is None else float(rate)


# --------------------------------------------------------------------------- opening


class _Table:
    """Column names plus a way to read chosen columns as float64."""

    def __init__(self, name, names, sample, reader, notes, complete=False):
        self.clock = []           # 0-based columns read from clock times
        self.transposed = False   # the data were written in rows
        self.token_lines = []     # the first data lines as text, for the time's resolution
        self.sep = None
        self.decimal = "."
        self.name = name          # file name for messages
        self.names = names        # list of column labels as shown to a user
        self.sample = sample      # DataFrame of floats (NaN where not numeric), first rows
        self.reader = reader      # callable(0-based indices) -> DataFrame of float64, in order
        self.notes = notes
        self.complete = complete  # the sample is every row, as the reader would give it


def _open_table(source, sheet):
    if hasattr(source, "read"):
        data = source.read()
        name = getattr(source, "name", None)  # an open file's path, as it was given
        name = name if isinstance(name, str) and not name.startswith("<") else "<stdin>"
        return _text_table(name, _to_bytes(data), None)
    if isinstance(source, str) and source == "-":
        return _text_table("<stdin>", _to_bytes(sys.stdin.buffer.read()), None)
    path = Path(source)
    name = str(source)  # as given: in a batch, file names alone can be ambiguous
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise InputError(f"file not found: {source}. Check the path and the working "
                         "directory.") from None
    except NotADirectoryError:
        raise InputError(f"file not found: {source} (a part of the path is a file, not a "
                         "directory). Check the path.") from None
    except OSError as exc:  # a folder on the way that may not be entered, a loop...
        raise InputError(f"cannot read {source}: {exc.strerror or exc}. Check the "
                         "permissions of the file and of its folders.") from None
    if stat.S_ISDIR(mode):
        raise InputError(f"{source} is a directory, not a file. Give a data file inside it.")
    if not stat.S_ISREG(mode):
        # Reading a FIFO or a device could block forever or never end.
        raise InputError(f"{source} is not a regular file (a pipe, socket or device). Copy "
                         "the record to a file, or pipe it to mcfit as - (stdin).")
    suffix = path.suffix.lower()
    if suffix in _REFUSED_EXTENSIONS:
        raise InputError(f"unsupported file type '{suffix}' for {name}; use .csv, .tsv, .txt, "
                         ".dat or .xlsx (or export the data as delimited text).")
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
    # The content decides, not the extension: a workbook or a gzip file by its signature,
    # anything else (.lvm, .log, no extension) as text.
    if head.startswith(_GZIP_SIGNATURE):
        return _gzip_table(path, name, sheet)
    if suffix in _EXCEL_ENGINES and not (suffix in EXCEL_EXTENSIONS
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
                       ".avi", ".wav", ".mp3", ".cmbl", ".py", ".ipynb")
# Workbook extensions: pandas engine and the package that provides it.
_EXCEL_ENGINES = {".xlsx": ("openpyxl", "openpyxl"), ".xlsm": ("openpyxl", "openpyxl"),
                  ".xls": ("xlrd", "xlrd"), ".ods": ("odf", "odfpy")}


def _gzip_table(path, name, sheet):
    import gzip
    import zlib
    try:
        data = gzip.decompress(path.read_bytes())
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


def _utf16_without_bom(head):
    """'utf-16-le' or 'utf-16-be' when every other byte is NUL (ASCII text in UTF-16)."""
    sample = head[: 1 << 16]
    if len(sample) < 8 or b"\x00" not in sample:
        return None
    pairs = len(sample) // 2
    odd_nul = sample[1:2 * pairs:2].count(0)
    even_nul = sample[0:2 * pairs:2].count(0)
    if odd_nul >= 0.9 * pairs and even_nul <= 0.02 * pairs:
        return "utf-16-le"
    if even_nul >= 0.9 * pairs and odd_nul <= 0.02 * pairs:
        return "utf-16-be"
    return None


def _binary_problem(text):
    """A description of the binary bytes in decoded text, or None for plain text."""
    if "\x00" in text:
        return "NUL bytes"
    window = text[: 1 << 16]
    if window.isascii():  # the usual case: bytes.translate counts several times faster
        control = len(window.encode("ascii").translate(None, _NOT_CONTROL_BYTES))
    else:
        control = len(_CONTROL_CHARACTER.findall(window))
    if control > max(2, 0.01 * min(len(text), 1 << 16)):
        return "control bytes"
    return None


def _decode(head):
    """(text, encoding, note, exact) for the sniffed bytes; ``exact`` is True when every
    byte was decoded as pandas will decode it (nothing cut, ignored or replaced)."""
    if head.startswith(b"\xef\xbb\xbf"):
        text, exact = _decode_leniently(head[3:], "utf-8", "ignore")
        return text, "utf-8-sig", "byte-order mark skipped", exact
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        text, exact = _decode_leniently(head, "utf-16", "ignore")
        return text, "utf-16", "UTF-16 text", exact
    utf16 = _utf16_without_bom(head)
    if utf16 is not None:
        cut = len(head) - len(head) % 2
        text, exact = _decode_leniently(head[:cut], utf16, "replace")
        return text, utf16, "UTF-16 text without a byte-order mark", exact and cut == len(head)
    try:
        return head.decode("utf-8"), "utf-8", None, True
    except UnicodeDecodeError as exc:
        if exc.start > len(head) - 4:  # a character cut by the sniff limit
            return head[:exc.start].decode("utf-8"), "utf-8", None, False
        return head.decode("latin-1"), "latin-1", None, True


def _decode_leniently(data, encoding, errors):
    """(text, exact): strict decoding if it works, else decoding with ``errors``."""
    try:
        return data.decode(encoding), True
    except UnicodeDecodeError:
        return data.decode(encoding, errors=errors), False


def _split(line, sep):
    if sep is None:
        return line.split()
    if '"' in line and len(sep) == 1:  # a quoted field may hold the separator
        fields = next(csv.reader([line], delimiter=sep, skipinitialspace=True))
    else:
        fields = line.split(sep)
    return [f.strip().strip('"').strip("'").strip() for f in fields]


def _is_number(token):
    return bool(_NUMBER.match(token.strip())) or token.strip().lower() in ("nan", "inf", "-inf")


def _text_table(name, head, path, tail=b"", tidied=None):
    """A :class:`_Table` for delimited text; ``tidied`` is (names present, notes, clock
    columns, transposed) for text already rewritten by :func:`_tidy_text`."""
    if not head or head.isspace():  # as head.strip() == b"", without copying the file
        raise InputError(f"{name} is empty. Give a file with a time and a signal column.")
    text, encoding, enc_note, exact_text = _decode(head)
    notes = [enc_note] if enc_note else []
    if tidied is None and (text.endswith("\x00") or tail.endswith(b"\x00")):
        if path is not None and tail:
            head, path, tail = _read_whole(name, path), None, b""
            text, encoding, enc_note, exact_text = _decode(head)
        text, nul_note = _drop_trailing_nul(text)
        if nul_note:
            notes.append(nul_note)
            head, path, encoding, exact_text = text.encode("utf-8"), None, "utf-8", True
    problem = _binary_problem(text)
    if problem is not None:
        raise InputError(f"{name} is not a text record: it holds binary data ({problem}). "
                         "Give a CSV, TSV or text export of the data (an Excel workbook must "
                         "end in .xlsx).")
    lines = text.splitlines()
    if path is not None and len(head) == _SNIFF_BYTES and lines:
        if len(lines) <= _MAX_ROWS_AS_DATA:  # a few very long lines: data written in rows
            head, path, tail = _read_whole(name, path), None, b""
            text, encoding, enc_note, exact_text = _decode(head)
            lines = text.splitlines()
        else:
            lines = lines[:-1]  # the last line may be cut by the sniff limit
    if tidied is None:
        tail_lines = []
        if tail and not encoding.startswith("utf-16"):
            tail_lines = tail.decode(encoding, errors="replace").splitlines()[1:]
        tidy = _tidy_text(name, lines, tail_lines)
        if tidy is not None and path is not None and (tail or len(head) == _SNIFF_BYTES):
            whole, _, _, _ = _decode(_read_whole(name, path))
            tidy = _tidy_text(name, whole.splitlines(), [])
        if tidy is not None:
            tidy_text, tidy_notes, clock, transposed, has_names = tidy
            return _text_table(name, tidy_text.encode("utf-8"), None,
                               tidied=(has_names, notes + tidy_notes, clock, transposed))
        clock, transposed = [], False
    else:
        has_names, notes, clock, transposed = tidied
    # Data lines: not blank, not a comment.
    comment_chars = set()
    first_content = None
    content = []
    for number, line in enumerate(lines):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped[0] in "#%":
            comment_chars.add(stripped[0])
            continue
        if first_content is None:
            first_content = number
        content.append((number, stripped))
        if len(content) >= 200:
            break
    if not content:
        raise InputError(f"{name} holds only comments or blank lines. Give a file with data rows.")
    if tidied is None:
        sep, decimal = _sniff_separator([line for _, line in content[:50]])
        first_fields = _split(content[0][1], sep)
        has_header = not all(_is_number(f) or f == "" for f in first_fields)
    else:  # one tab-separated header line (if any) and numbers with decimal points
        sep, decimal, has_header = "\t", ".", has_names
    if has_header:
        names = _header_names(content[0][1], sep, content[1:])
        data_start = content[1][0] if len(content) > 1 else None
        if data_start is None:
            raise InputError(f"{name} has a header row but no data rows. Give a file with "
                             "data below the header.")
    else:
        ncols = max(len(_split(line, sep)) for _, line in content[:50])
        names = [f"column {i + 1}" for i in range(ncols)]
        data_start = content[0][0]
    if decimal == ",":
        notes.append("decimal commas read as decimal points")
    if comment_chars:
        notes.append("comment lines starting with " + " or ".join(sorted(comment_chars))
                     + " skipped")
    comment = "#" if "#" in comment_chars else ("%" if comment_chars else None)
    other_comment = "%" if comment == "#" and "%" in comment_chars else None

    def source_bytes():
        if path is None:
            return io.BytesIO(head)
        return path

    def reader(indices, nrows=None, as_text=False):
        kwargs = dict(
            sep=r"\s+" if sep is None else sep, decimal=decimal, header=None,
            skiprows=_skip_rows(data_start, lines, other_comment), usecols=list(indices),
            comment=comment, skip_blank_lines=True, encoding=encoding, engine="c",
            nrows=nrows, quotechar='"', skipinitialspace=sep is not None,
        )
        if as_text:
            kwargs["dtype"] = str
            kwargs["keep_default_na"] = False
        else:
            kwargs["dtype"] = np.float64
        if sep is None:
            kwargs.pop("skipinitialspace")
        frame = pd.read_csv(source_bytes(), **kwargs)
        # usecols gives the columns in file order; the time column may follow the signal.
        return frame.iloc[:, [sorted(indices).index(index) for index in indices]]

    sample_text = "\n".join(lines[data_start:data_start + _SAMPLE_LINES])
    try:
        with warnings.catch_warnings():
            # Rows longer than the sniffed width (a leading empty field) are cut here; the
            # sample only guides the choice of columns, so pandas' warning is noise.
            warnings.simplefilter("ignore", pd.errors.ParserWarning)
            sample, plain = _sample_frame(sample_text, sep, decimal, comment, len(names))
    except (pd.errors.EmptyDataError, pd.errors.ParserError) as exc:
        raise _parse_error(name, exc) from None
    # A plain numeric file read whole is parsed once: when the sample holds every data line
    # and the reader would split and convert them alike, the sample is the data. The first
    # row must be full: pandas takes the number of columns from it.
    whole = (path is None or len(head) < _SNIFF_BYTES) and len(lines) - data_start <= _SAMPLE_LINES
    complete = (whole and plain and exact_text and other_comment is None
                and sample.shape[0] > 0 and not np.isnan(sample.iat[0, -1])
                and _lines_alike(text, lines[:data_start], sample_text))
    table = _Table(name, names, sample, reader, notes, complete=complete)
    table.clock, table.transposed, table.decimal = clock, transposed, decimal
    table.token_lines, table.sep = lines[data_start:data_start + 2000], sep
    return table


def _read_whole(name, path):
    try:
        return path.read_bytes()
    except OSError as exc:
        raise InputError(f"cannot read {name}: {exc.strerror}. Check its permissions.") from None


def _drop_trailing_nul(text):
    """(text, note): NUL bytes at the very end (a copy cut short by a power loss) dropped,
    with the incomplete last line; text unchanged (no note) when NULs are elsewhere too."""
    kept = text.rstrip("\x00")
    if "\x00" in kept or not kept.strip():
        return text, None
    dropped = len(text) - len(kept)
    note = f"{dropped} NUL bytes at the end dropped (the file was cut short, as by a power "
    if kept.endswith(("\n", "\r")):
        return kept, note + "loss while copying)"
    return kept[:max(kept.rfind("\n"), 0)] + "\n", note + ("loss while copying), with the "
                                                            "incomplete last line")


def _sample_frame(sample_text, sep, decimal, comment, width):
    """(frame, plain): the sample lines as floats, NaN where not numeric.

    ``plain`` is True when every field is a number or empty and no row has more than
    ``width`` fields: then nothing was skipped or coerced, and the reader (which differs
    only by skipping initial spaces, which float parsing ignores) gives the same floats.
    """
    # pandas parses UTF-8 bytes about twice as fast as the same text in a StringIO.
    data = sample_text.encode("utf-8")
    common = dict(sep=r"\s+" if sep is None else sep, header=None, comment=comment,
                  skip_blank_lines=True, engine="c", names=range(width), index_col=False,
                  encoding="utf-8")
    try:
        frame = pd.read_csv(io.BytesIO(data), dtype=np.float64, decimal=decimal,
                            on_bad_lines="error", **common)
        return frame, True
    except ValueError:  # text, or rows too long: as before, without the promise
        pass
    try:  # all numbers: pandas' C parser makes the floats directly
        frame = pd.read_csv(io.BytesIO(data), dtype=np.float64, decimal=decimal,
                            on_bad_lines="skip", **common)
    except ValueError:  # some text: parse as strings, text becomes NaN
        frame = _numeric_frame(pd.read_csv(io.BytesIO(data), dtype=str, keep_default_na=False,
                                           on_bad_lines="skip", **common), decimal)
    return frame, False


def _lines_alike(text, head_lines, sample_text):
    """Whether pandas, reading the file, sees the same lines as ``str.splitlines`` did.

    They differ on line breaks that only Python knows (form feed, U+2028...), on a lone
    carriage return (pandas counts skipped rows and blank lines differently after one) and
    on quotes: a quote opened in a skipped line runs on into the next lines for pandas.
    """
    if any(mark in text for mark in _PYTHON_ONLY_LINE_BREAKS) or '"' in sample_text:
        return False
    if "\r" in text and text.count("\r") != text.count("\r\n"):
        return False
    return all(line.count('"') % 2 == 0 for line in head_lines)


def _parse_error(name, exc):
    return InputError(f"cannot parse {name}: {str(exc).splitlines()[0]}. Check the quotes "
                      "and that every row has the same separator.")


def _skip_rows(data_start, lines, other_comment):
    skip = list(range(data_start))
    if other_comment:
        skip += [i for i, line in enumerate(lines)
                 if i >= data_start and line.strip().startswith(other_comment)]
    return skip


def _sniff_separator(lines):
    """(sep, decimal): sep None means whitespace."""
    def consistent(sep):
        counts = [len(_split(line, sep)) for line in lines]
        return min(counts) >= 2 and max(counts) - min(counts) <= max(counts) // 2

    data_lines = lines[1:] if len(lines) > 1 else lines
    for sep in (";", "\t"):
        if all(sep in line for line in data_lines) and consistent(sep):
            fields = [f for line in data_lines for f in _split(line, sep) if f]
            decimal = "," if any(_COMMA_DECIMAL.match(f) for f in fields) else "."
            return sep, decimal
    ws_fields = [line.split() for line in data_lines]
    if "," in "".join(data_lines):
        # "1,5 2,25": whitespace-separated with decimal commas, not CSV.
        if (all(len(f) >= 2 for f in ws_fields)
                and all(_COMMA_DECIMAL.match(tok) or _is_number(tok) and "," not in tok
                        for f in ws_fields for tok in f)
                and any(_COMMA_DECIMAL.match(tok) for f in ws_fields for tok in f)):
            return None, ","
        return ",", "."
    return None, "."


def _header_names(line, sep, content):
    if sep is not None:
        names = _split(line, sep)
    else:
        # Whitespace-separated headers: "time (s)" is one name, so glue unit tokens back.
        names = []
        for token in line.split():
            if names and (token[0] in "([" or names[-1].count("(") > names[-1].count(")")
                          or names[-1].count("[") > names[-1].count("]")):
                names[-1] = names[-1] + " " + token
            else:
                names.append(token)
    ncols = max((len(_split(other, sep)) for _, other in content[:50]), default=len(names))
    names = [n if n else f"column {i + 1}" for i, n in enumerate(names)]
    names += [f"column {i + 1}" for i in range(len(names), ncols)]
    seen = {}
    for i, n in enumerate(names):  # duplicate names (several runs side by side)
        if n in seen:
            names[i] = f"{n} ({i + 1})"
        seen.setdefault(n, i)
    return names


def _numeric_frame(frame, decimal):
    out = {}
    for column in frame.columns:
        values = frame[column].astype(str).str.strip()
        if decimal == ",":
            values = values.str.replace(",", ".", regex=False)
        out[column] = pd.to_numeric(values.replace("", np.nan), errors="coerce")
    return pd.DataFrame(out, dtype=np.float64)


def _sheet_name(sheets, sheet, name):
    """The sheet named or numbered (1-based) by the user; the first by default."""
    if sheet is None:
        return sheets[0]
    if isinstance(sheet, int) or (isinstance(sheet, str) and sheet.isdigit()
                                  and sheet not in sheets):
        index = int(sheet)
        if not 1 <= index <= len(sheets):
            raise UsageError(f"sheet {index} not found in {name}; it has {len(sheets)} "
                             f"sheet(s): {', '.join(sheets)}. Use `sheet` with a name or "
                             "1-based index.")
        return sheets[index - 1]
    if sheet in sheets:
        return sheet
    raise UsageError(f"sheet '{sheet}' not found in {name}; sheets are: {', '.join(sheets)}. "
                     "Use `sheet`.")


_CFB_SIGNATURE = b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1"  # OLE compound file


def _excel_table(path, name, sheet, suffix):
    engine, package = _EXCEL_ENGINES[suffix]
    try:
        with open(path, "rb") as handle:
            signature = handle.read(8)
    except OSError as exc:
        raise InputError(f"cannot read {name}: {exc.strerror or exc}. Check its "
                         "permissions.") from None
    if signature == _CFB_SIGNATURE and engine == "openpyxl":
        # Excel saves a password-protected workbook as an OLE compound file holding the
        # encrypted package; an old binary .xls is one too. Neither is a zip .xlsx.
        raise InputError(f"{name} is a password-protected (encrypted) workbook or an old "
                         ".xls renamed .xlsx, which mcfit cannot open. In Excel remove the "
                         "password and save as .xlsx, or export CSV.")
    try:
        book = pd.ExcelFile(path, engine=engine)
    except ImportError:
        raise InputError(f"reading {suffix} workbooks such as {name} needs the Python package "
                         f"{package}: install it (pip install {package}), or save the "
                         "workbook as .xlsx or CSV.") from None
    except Exception as exc:  # zipfile.BadZipFile, KeyError, ValueError... from the engine
        raise InputError(f"cannot read {name} as an Excel workbook ({type(exc).__name__}): the "
                         f"file is damaged or not {suffix}. Re-save it from Excel or export "
                         "CSV.") from None
    notes = []
    try:
        if sheet is not None:
            sheet_name = _sheet_name(book.sheet_names, sheet, name)
            raw = _read_sheet(book, sheet_name, sheet)
        else:
            # A first sheet of notes: the data are on the first sheet that holds numbers.
            for sheet_name in book.sheet_names:
                raw = _read_sheet(book, sheet_name, sheet)
                if _numeric_rows(raw) >= 2:
                    break
            else:
                sheet_name = book.sheet_names[0]
                raw = _read_sheet(book, sheet_name, sheet)
            if sheet_name != book.sheet_names[0]:
                notes.append(f"the first sheet, '{book.sheet_names[0]}', holds no data")
    finally:
        book.close()
    if engine == "openpyxl" and _suspect_formulas(raw):
        _refuse_uncached_formulas(path, name, sheet_name)
    raw = raw.dropna(how="all").dropna(axis=1, how="all")
    if raw.empty:
        raise InputError(f"sheet '{sheet_name}' of {name} is empty. Choose the sheet holding "
                         "the data with `sheet`.")
    text = "".join("\t".join(_cell_text(v) for v in row) + "\n"
                   for row in raw.itertuples(index=False, name=None))
    table = _text_table(name, text.encode("utf-8"), None)
    table.notes[:0] = [f"sheet '{sheet_name}'"] + notes
    return table


def _read_sheet(book, sheet_name, sheet):
    try:
        return pd.read_excel(book, sheet_name=sheet_name, header=None)
    except Exception as exc:
        raise InputError(f"cannot read sheet {sheet_name!r} of {book.io} "
                         f"({type(exc).__name__}). Re-save the workbook or export CSV.") from None


def _numeric_rows(raw):
    """Rows with at least one number, date or time cell."""
    def numeric(v):
        return (not isinstance(v, (str, bool)) and not pd.isna(v)) if not isinstance(
            v, str) else _is_number(v)
    return sum(any(numeric(v) for v in row) for row in raw.itertuples(index=False, name=None))


def _cell_text(value):
    """One cell as the text a CSV export would hold (floats exact, dates in ISO form)."""
    import datetime
    if isinstance(value, str):
        return " ".join(value.split())
    if value is None or (not isinstance(value, (datetime.time, bool)) and pd.isna(value)):
        return ""
    if isinstance(value, (bool, np.bool_)):
        return str(value)
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, datetime.datetime):
        return value.isoformat(sep=" ")
    if isinstance(value, datetime.time):
        return value.isoformat()
    if isinstance(value, datetime.timedelta):
        return repr(value.total_seconds())
    return " ".join(str(value).split())


def _suspect_formulas(raw):
    """Whether a column is a header alone (as formula cells without saved values read)."""
    raw = raw.dropna(how="all")
    if raw.shape[0] < 3:
        return True
    filled = raw.notna().sum(axis=0)
    return bool(((filled == 1) & raw.iloc[0].notna()).any())


def _refuse_uncached_formulas(path, name, sheet_name):
    """Raise when the sheet's formulas have no saved values: a program such as a Python
    script wrote the formulas, and nothing has calculated them since."""
    import openpyxl
    try:
        formulas = openpyxl.load_workbook(path, read_only=True, data_only=False)
        values = openpyxl.load_workbook(path, read_only=True, data_only=True)
    except Exception:  # the workbook was read once already; leave the rest to the reader
        return
    try:
        first = None
        header = {}
        for row_f, row_v in zip(formulas[sheet_name].iter_rows(),
                                values[sheet_name].iter_rows()):
            for cell_f, cell_v in zip(row_f, row_v):
                if getattr(cell_f, "data_type", None) == "s" and cell_f.value is not None:
                    header.setdefault(cell_f.column, str(cell_f.value))
                if getattr(cell_f, "data_type", None) == "f" and cell_v.value is None:
                    first = cell_f
                    break
            if first is not None:
                break
    finally:
        formulas.close()
        values.close()
    if first is None:
        return
    column = header.get(first.column)
    where = f"column '{column}', " if column else ""
    raise InputError(f"the formula cells of sheet '{sheet_name}' of {name} have no saved "
                     f"values ({where}cell {first.coordinate}, row {first.row}): the program "
                     "that wrote the file did not calculate them. Open it in a spreadsheet "
                     "program (Excel, LibreOffice Calc) and save it, then read it again.")


# --------------------------------------------------------------------------- tidying
# Exports from loggers and lab software wrap the numbers in more than a header line: header
# blocks, separator lines, a units row, repeated headers, notes at the end, Fortran D
# exponents, clock times, data written in rows. The layout of such a file is found here and
# the file rewritten as one header line plus tab-separated numbers, which the plain reader
# then reads; a plain file is left to the plain reader as it is.

_NUMBER_TOKEN = re.compile(r"^[+-]?(\d+([.,]\d*)?|[.,]\d+)([eEdD][+-]?\d+)?$")
_SPECIAL_TOKENS = {"nan", "inf", "-inf", "+inf", "na", "n/a", "null", "none", "-nan"}
_FORTRAN_EXPONENT = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)[dD][+-]?\d+$")
# Clock times: "16:04:31.273", "4:31.2" (minutes), ISO dates with a time.
_CLOCK = re.compile(r"^(\d{1,2}:)?\d{1,2}:\d{2}([.,]\d+)?$")
_ISO_DATE_TIME = re.compile(r"^\d{4}-\d{2}-\d{2}[T ]\d{1,2}:\d{2}(:\d{2}([.,]\d+)?)?"
                            r"(Z|[+-]\d{2}:?\d{2})?$")
_DATE_SPACE_TIME = re.compile(r"(\d{4}-\d{2}-\d{2}) (\d{1,2}:\d{2})")
# A line of dashes, equals signs or stars (with separators between), as under a header.
_RULE_LINE = re.compile(r"^[\s\-=_*~+|,;:]*$")
_RULE_CHARACTERS = re.compile(r"[-=_*~]{3,}")
# A units row: short tokens such as s, m, V, m/s^2, deg, rad, (s), [mm].
_UNIT_TOKEN = re.compile(r"^[\(\[]?[A-Za-zµμ°%Ω][A-Za-z0-9µμ°%Ω/^*·.\- ]{0,9}[\)\]]?$")
# Rows as data: at most this many rows, each at least this many values long.
_MAX_ROWS_AS_DATA = 4
_MIN_VALUES_IN_A_ROW = 20
# Lines classified to find the layout (plus the last lines of the file).
_LAYOUT_LINES = 400


def _token_kind(token, decimal_comma):
    """'num', 'clock', 'empty' or 'text' for one field."""
    if not token:
        return "empty"
    if _NUMBER_TOKEN.match(token):
        return "num" if decimal_comma or "," not in token else "text"
    if token.lower() in _SPECIAL_TOKENS:
        return "num"
    if _CLOCK.match(token) or _ISO_DATE_TIME.match(token):
        return "clock"
    return "text"


def _line_fields(line, sep):
    if sep is None:
        # "2024-03-01 16:04:31" is one field, not two, in whitespace-separated text.
        line = _DATE_SPACE_TIME.sub(r"\1T\2", line)
    return _split(line, sep)


def _classify_line(line, sep, decimal_comma):
    """('num' | 'rule' | 'text', fields) for one stripped content line."""
    if _RULE_LINE.match(line) and _RULE_CHARACTERS.search(line):
        return "rule", []
    fields = _line_fields(line, sep)
    kinds = [_token_kind(f, decimal_comma) for f in fields]
    if all(k != "text" for k in kinds) and any(k in ("num", "clock") for k in kinds):
        return "num", fields
    return "text", fields


class _Layout:
    """Where the numbers are in a text file, and what else it holds."""

    def __init__(self, sep, decimal_comma, width, classes, content):
        self.sep = sep
        self.decimal_comma = decimal_comma
        self.width = width
        self.classes = classes      # per content line: (kind, fields)
        self.content = content      # [(line number, stripped line)]
        self.start = None           # content index of the first data line
        self.run = 0                # data lines in the first block


def _find_layout(content):
    """The separator and data block that explain the most lines, as a :class:`_Layout`."""
    best, best_score = None, None
    header_fields = None
    for sep in (";", "\t", ",", None):
        for decimal_comma in ((False,) if sep == "," else (True, False)):
            classes = [_classify_line(line, sep, decimal_comma) for _, line in content]
            # The longest block of numeric lines of one width (rules and text may not cut
            # it short only at its start: the first such block counts).
            run_start, run, width = None, 0, None
            i = 0
            while i < len(classes):
                kind, fields = classes[i]
                if kind != "num":
                    i += 1
                    continue
                w = len(fields)
                j, count = i, 0
                while j < len(classes) and classes[j][0] in ("num", "rule") and (
                        classes[j][0] == "rule" or len(classes[j][1]) == w):
                    count += classes[j][0] == "num"
                    j += 1
                if count > run:
                    run_start, run, width = i, count, w
                i = max(j, i + 1)
            if not run:
                continue
            # The data start at the first numeric line of that width: text lines further
            # down (a bad value, a repeated header) are not a header block.
            run_start = next(k for k, c in enumerate(classes)
                             if c[0] == "num" and len(c[1]) == width)
            # The line above the block, if text, is the header: its width should match.
            above = [c for c in classes[:run_start] if c[0] == "text"]
            header_fields = above[-1][1] if above else None
            matches = header_fields is not None and len(header_fields) == width
            if header_fields is None and decimal_comma and width == 1:
                matches = _zero_padded_fractions(content[run_start:run_start + 200])
            score = (run, matches, width > 1, sep is not None, not decimal_comma)
            if best_score is None or score > best_score:
                layout = _Layout(sep, decimal_comma, width, classes, content)
                layout.start, layout.run = run_start, run
                best, best_score = layout, score
    return best


def _layout_is_plain(layout):
    """Whether the plain reader reads this file as it is (one header line at most, no
    rules, units, D exponents, clock times, one-column decimal commas or rows of data)."""
    if layout is None:
        return True
    if layout.start > 1:
        return False
    if any(kind == "rule" for kind, _ in layout.classes):
        return False
    if layout.decimal_comma and layout.width == 1:
        return False
    if layout.run <= _MAX_ROWS_AS_DATA and layout.width >= _MIN_VALUES_IN_A_ROW:
        return False
    for kind, fields in layout.classes[layout.start:layout.start + 50]:
        if kind == "num" and any(_FORTRAN_EXPONENT.match(f) or _CLOCK.match(f)
                                 or _ISO_DATE_TIME.match(f) for f in fields):
            return False
    header = layout.content[layout.start - 1][1] if layout.start else None
    data_lines = [c for c in layout.classes[layout.start:] if c[0] != "rule"]
    if header is not None and any(line == header for _, line in
                                  layout.content[layout.start:]):
        return False  # a repeated header
    # Text after the last numeric line: notes at the end.
    return not (len(data_lines) > 1 and _is_note(data_lines[-1], layout))


def _is_note(line_class, layout):
    """Whether a text line below the data is a note rather than a row with a bad value
    (which must be reported, not dropped): it is not as wide as the data or does not start
    with a number."""
    kind, fields = line_class
    return kind == "text" and (len(fields) != layout.width or _token_kind(
        fields[0], layout.decimal_comma) not in ("num", "clock"))


def _tidy_text(name, lines, tail_lines=()):
    """(text, notes, clock_columns, transposed) or None when the plain reader suffices.

    ``text`` is the record rewritten as an optional tab-separated header line and
    tab-separated numbers with decimal points.
    """
    comment_chars = set()

    def content_lines(numbered, limit):
        out = []
        for number, line in numbered:
            stripped = line.strip()
            if not stripped:
                continue
            if stripped[0] in "#%":
                comment_chars.add(stripped[0])
                continue
            out.append((number, stripped))
            if len(out) >= limit:
                break
        return out

    # The first lines and the last ones decide whether the plain reader suffices; a long
    # file is scanned whole only when it does not.
    content = content_lines(enumerate(lines), _LAYOUT_LINES)
    if not content:
        return None
    whole = len(content) < _LAYOUT_LINES
    last = [] if whole else content_lines(
        ((n, lines[n]) for n in range(len(lines) - 1, content[-1][0], -1)), 20)[::-1]
    tail_content = [(-1, line.strip()) for line in tail_lines[-20:] if line.strip()
                    and line.strip()[0] not in "#%"]
    window = content + last + tail_content
    if _surely_plain(window, []):
        return None
    layout = _find_layout(window)
    if layout is None or _layout_is_plain(layout):
        first = content[0][1]
        if not (first.startswith("[") or re.match(r"^\w+\s*=\s*\[", first)):
            return None
        return _matlab_rows(content if whole else content_lines(enumerate(lines), len(lines)))
    if not whole:  # the separator and width found, every line is classified with them
        content = content_lines(enumerate(lines), len(lines))
        sample = layout
        layout = _Layout(sample.sep, sample.decimal_comma, sample.width,
                         [_classify_line(line, sample.sep, sample.decimal_comma)
                          for _, line in content], content)
        layout.start = next(k for k, c in enumerate(layout.classes)
                            if c[0] == "num" and len(c[1]) == sample.width)
        layout.run = max(sample.run, _MAX_ROWS_AS_DATA + 1)
    notes = []
    if comment_chars:
        notes.append("comment lines starting with " + " or ".join(sorted(comment_chars))
                     + " skipped")
    if layout.run <= _MAX_ROWS_AS_DATA and layout.width >= _MIN_VALUES_IN_A_ROW:
        return _rows_as_columns(layout, notes)
    return _tidy_columns(name, layout, notes)


_KNOWN_UNITS = set(_SECONDS_PER_UNIT) | {
    "m", "mm", "cm", "km", "um", "v", "mv", "uv", "a", "ma", "rad", "mrad", "deg", "°", "n",
    "mn", "g", "kg", "hz", "m/s", "m/s^2", "m/s²", "cm/s", "mm/s", "rad/s", "deg/s", "°/s",
    "counts", "pa", "kpa", "%"}


def _is_units_row(fields, width):
    tokens = [f.strip("()[] ") for f in fields if f]
    return (len(fields) <= width and len(tokens) >= max(1, width - 1)
            and all(_UNIT_TOKEN.match(f) and len(f) <= 10 for f in tokens)
            and any(f.lower().replace("µ", "u").replace("μ", "u") in _KNOWN_UNITS
                    for f in tokens))


_INTEGER_COMMA_INTEGER = re.compile(r"^[+-]?\d+,(\d+)$")


def _zero_padded_fractions(content):
    """Whether lines such as '38,0169' are one number with a decimal comma: every line is
    two integers around one comma and some second integer has a leading zero, which no
    program writes for an integer."""
    matches = [_INTEGER_COMMA_INTEGER.match(line) for _, line in content]
    numbered = [m for m in matches if m]
    return (len(numbered) >= 0.9 * len(matches) and len(numbered) >= 3
            and any(len(m.group(1)) > 1 and m.group(1)[0] == "0" for m in numbered))


def _surely_plain(content, tail_content):
    """A quick look for the usual file, to spare it the search for a layout: one header
    line at most, as wide as the numeric lines below it (first lines and last lines)."""
    if len(content) <= _MAX_ROWS_AS_DATA:
        return False
    sep, decimal = _sniff_separator([line for _, line in content[:50]])
    decimal_comma = decimal == ","
    lines = [line for _, line in content[1:200] + content[-20:] + tail_content]
    width = None if decimal_comma else _plain_width(lines, sep)
    plain = width is not None
    if not plain:
        widths = set()
        for line in lines:
            kind, fields = _classify_line(line, sep, decimal_comma)
            if kind != "num":
                return False
            widths.add(len(fields))
        if len(widths) != 1:
            return False
        width = widths.pop()
    if sep == "," and width == 2 and _zero_padded_fractions(content[:200]):
        return False
    kind, fields = _classify_line(content[0][1], sep, decimal_comma)
    if kind == "rule" or (kind == "text" and len(_header_fields(content[0][1], sep, width))
                          != width):
        return False
    if plain:  # no D exponents nor clock times: the expression admits neither
        return True
    return not any(_FORTRAN_EXPONENT.match(f) or _CLOCK.match(f) or _ISO_DATE_TIME.match(f)
                   for _, line in content[1:50] for f in _line_fields(line, sep))


_PLAIN_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def _plain_width(lines, sep):
    """The number of fields when every line is plain numbers with decimal points, split
    by ``sep`` (None: whitespace) alike, else None: one regular expression a line, the
    common case at a tenth of the cost of classifying each field."""
    if not lines:
        return None
    between = r"\s+" if sep is None else r"\s*" + re.escape(sep) + r"\s*"
    width = len(_split(lines[0], sep))
    row = re.compile(_PLAIN_NUMBER + f"(?:{between}{_PLAIN_NUMBER}){{{width - 1}}}")
    return width if all(row.fullmatch(line) for line in lines) else None


def _header_fields(line, sep, width):
    """A header line split as the plain reader would, trailing empty fields dropped."""
    fields = _header_names(line, sep, []) if sep is None else _split(line, sep)
    while len(fields) > width and not fields[-1]:
        fields.pop()
    if sep is None and len(fields) == width + 1:
        # "date time angle" over "2024-03-01 16:04:31 12.5": the date and time are one field.
        lower = [f.lower() for f in fields]
        for k in range(len(fields) - 1):
            if (lower[k], lower[k + 1]) == ("date", "time"):
                fields[k:k + 2] = [fields[k] + " " + fields[k + 1]]
                break
    if width == 1 and len(fields) > 1 and sep is None:
        fields = [" ".join(fields)]
    return fields


def _header_rows(layout):
    """(names, units, header rows, text lines above them): the header is the text lines
    just above the data that are as wide as the data; a units row may close it."""
    above = [layout.content[i][1] for i in range(layout.start)
             if layout.classes[i][0] == "text"]
    width = layout.width
    rows = []
    for line in reversed(above):
        fields = _header_fields(line, layout.sep, width)
        # A header may name a last column that every data row leaves empty (LabVIEW's
        # Comment): the stripped data lines lost those trailing separators.
        wanted = len(rows[0]) if rows else width
        if len(fields) != wanted and not (not rows and width < len(fields) <= width + 2):
            break
        rows.insert(0, fields)
    header_rows = list(rows)
    units = None
    if len(rows) >= 2 and _is_units_row(rows[-1], width):
        units = rows.pop()
    names = None
    if rows:
        timed = [r for r in rows if any(_is_time_name(f) for f in r)]
        names = list(timed[0] if timed else rows[-1])
    return names, units, header_rows, above[:len(above) - len(header_rows)]


def _tidy_columns(name, layout, notes):
    width = layout.width
    names, units, header_rows, block = _header_rows(layout)
    if block:
        notes.append(f"{_count(len(block), 'line')} above the column names skipped (a "
                     f"header block starting '{block[0][:40]}')")
    if names is not None:
        names = [(n or "").strip() for n in names][:width]
        names += [""] * (width - len(names))
        if units is not None:
            unit_list = list(units) + [""] * (width - len(units))
            names = [f"{n} ({u.strip('()[]')})" if u and _base_name(n)[1] is None and n
                     else n for n, u in zip(names, unit_list)]
            notes.append("units row under the header read: " + ", ".join(
                u for u in units if u))
    rows, rules, repeats, trailing = [], 0, 0, []
    classes = layout.classes
    last_num = max(i for i, c in enumerate(classes) if c[0] == "num")
    for i in range(layout.start, len(classes)):
        kind, fields = classes[i]
        if kind == "rule":
            rules += 1
            continue
        if kind == "text" and (_header_fields(layout.content[i][1], layout.sep,
                                              len(header_rows[0]) if header_rows else width)
                               in header_rows):
            repeats += 1
            continue
        if i > last_num and _is_note(classes[i], layout):
            trailing.append(layout.content[i][1])
            continue
        rows.append(fields)
    rules += sum(1 for c in classes[:layout.start] if c[0] == "rule")
    if rules:
        notes.append(f"{_count(rules, 'separator line')} (dashes or equals signs) skipped")
    if repeats:
        notes.append(f"{_count(repeats, 'repeated header line')} skipped")
    if trailing:
        notes.append(f"{_count(len(trailing), 'line')} of text after the data skipped "
                     f"(starting '{trailing[0][:40]}')")
    if layout.decimal_comma and any("," in f for r in rows[:200] for f in r):
        notes.append("decimal commas read as decimal points")
    if any(_FORTRAN_EXPONENT.match(f) for r in rows[:200] for f in r):
        notes.append("Fortran D exponents (1.0D-03) read as E exponents")
    columns = [[(r[k] if k < len(r) else "") for r in rows] for k in range(width)]
    clock = []
    for k, column in enumerate(columns):
        if any(_CLOCK.match(v) or _ISO_DATE_TIME.match(v) for v in column[:50]):
            seconds, first = _clock_seconds(column)
            if seconds is not None:
                columns[k] = seconds
                clock.append(k)
                label = (names[k] if names and names[k] else f"column {k + 1}")
                notes.append(f"clock times in '{label}' read as seconds after the first "
                             f"({first})")
                if names is not None and _base_name(names[k])[1] is None:
                    names[k] = f"{names[k] or 'clock'} (s)"
                continue
        columns[k] = [_normal_number(v, layout.decimal_comma) for v in column]
    out = []
    if names is not None:
        out.append("\t".join(n.replace("\t", " ") or f"column {k + 1}"
                             for k, n in enumerate(names)))
    out.extend("\t".join(values) for values in zip(*columns))
    return "\n".join(out) + "\n", notes, clock, False, names is not None


def _count(n, noun):
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _normal_number(token, decimal_comma):
    if decimal_comma:
        token = token.replace(",", ".")
    if "d" in token or "D" in token:
        token = token.replace("d", "e").replace("D", "E")
    return token


def _clock_seconds(column):
    """(seconds as text, first clock time) for clock times or ISO date-times, or (None, None)
    when some value is neither; empty cells stay empty. A time of day that steps back by
    more than twelve hours has passed midnight."""
    from datetime import datetime, timezone
    values = []
    for v in column:
        v = v.strip()
        if not v:
            values.append(None)
            continue
        if _ISO_DATE_TIME.match(v):
            try:
                stamp = datetime.fromisoformat(v.replace(",", ".").replace("Z", "+00:00"))
            except ValueError:
                return None, None
            if stamp.tzinfo is not None:
                stamp = stamp.astimezone(timezone.utc).replace(tzinfo=None)
            values.append(stamp)
            continue
        if not _CLOCK.match(v):
            return None, None
        parts = v.replace(",", ".").split(":")
        seconds = float(parts[-1]) + 60 * int(parts[-2])
        if len(parts) == 3:
            seconds += 3600 * int(parts[0])
        values.append(("day", seconds))
    first_index = next((i for i, v in enumerate(values) if v is not None), None)
    if first_index is None:
        return None, None
    out, day, previous, origin = [], 0.0, None, None
    for v in values:
        if v is None:
            out.append("")
            continue
        if isinstance(v, tuple):
            v = v[1]
            if previous is not None and v + day < previous - 43200:
                day += 86400.0
            v = v + day
        elif isinstance(v, datetime):
            # Seconds from the first date-time, exactly (epoch seconds would lose the
            # microseconds to rounding).
            if origin is None:
                origin = v
            if not isinstance(origin, datetime):
                return None, None
            v = (v - origin).total_seconds()
            out.append(repr(round(v, 9)))
            continue
        if origin is None:
            origin = v
        if isinstance(origin, datetime):
            return None, None
        previous = v
        out.append(repr(round(v - origin, 9)))
    return out, column[first_index].strip()


def _rows_as_columns(layout, notes):
    rows = [fields for kind, fields in layout.classes if kind == "num"]
    labelled = [c[1] for c in layout.classes if c[0] == "text"
                and len(c[1]) == layout.width + 1 and all(
                    _token_kind(f, layout.decimal_comma) != "text" for f in c[1][1:])]
    names = None
    if labelled and not rows:
        names = [r[0] for r in labelled]
        rows = [r[1:] for r in labelled]
    notes.append(f"data written in rows ({len(rows)} rows of {layout.width} values) read as "
                 "columns")
    if layout.decimal_comma:
        notes.append("decimal commas read as decimal points")
    columns = [[_normal_number(v, layout.decimal_comma) for v in r] for r in rows]
    out = ["\t".join(names)] if names else []
    out.extend("\t".join(values) for values in zip(*columns))
    return "\n".join(out) + "\n", notes, [], True, names is not None


def _matlab_rows(content):
    """A MATLAB matrix literal ``[t; x]`` (or ``name = [...]``) written as rows, or None."""
    text = " ".join(line for _, line in content)
    match = re.match(r"^(\w+\s*=\s*)?\[(.*)\]\s*;?$", text)
    if not match:
        return None
    rows = [r.replace(",", " ").split() for r in match.group(2).split(";") if r.strip()]
    if not rows or len(rows) > _MAX_ROWS_AS_DATA or any(len(r) != len(rows[0]) for r in rows):
        return None
    if not all(_NUMBER_TOKEN.match(v) or v.lower() in _SPECIAL_TOKENS for r in rows for v in r):
        return None
    if len(rows[0]) < len(rows):
        rows = [list(c) for c in zip(*rows)]
        note = "MATLAB matrix read"
    else:
        note = (f"data written in rows ({len(rows)} rows of {len(rows[0])} values, a MATLAB "
                "matrix) read as columns")
    columns = [[_normal_number(v, False) for v in r] for r in rows]
    return ("\n".join("\t".join(v) for v in zip(*columns)) + "\n", [note], [], True, False)


# --------------------------------------------------------------------------- choosing


_INNER_UNIT = re.compile(r"^(.*?)\s*[\(\[]\s*([^\)\]]*?)\s*[\)\]]\s*(.*)$")


def _base_name(label):
    """'Time (s)' -> ('time', 's'); 'angle' -> ('angle', None);
    'Position (mm) Run #1' -> ('position run #1', 'mm')."""
    match = _UNIT.match(label.strip())
    if match and match.group(1):
        return match.group(1).strip().lower(), match.group(2).strip() or None
    match = _INNER_UNIT.match(label.strip())
    if match and match.group(1) and match.group(2).lower() in _KNOWN_UNITS:
        return (f"{match.group(1)} {match.group(3)}".strip().lower(),
                match.group(2).strip())
    return label.strip().lower(), None


_RUN_SUFFIX = re.compile(r"\s*\brun\s*#?\s*\d+$")


def _is_time_name(label):
    """Whether a column label names the time ('Time (s)', 'Time (s) Run #1', 'X_Value')."""
    base = _base_name(label)[0]
    return base in _TIME_NAMES or _RUN_SUFFIX.sub("", base) in _TIME_NAMES


# --------------------------------------------------------------------------- runs

_RUN_LABEL = re.compile(r"\brun\s*#?\s*(\d+)\s*$", re.IGNORECASE)


@dataclass(frozen=True)
class _Run:
    """One run of a file: its label ("Run 7", None for a file of one run), its number, the
    0-based columns it may use, and how many runs the file holds."""

    label: str | None
    number: int
    columns: tuple[int, ...]
    count: int = 1


def _plain_name(table, index):
    """A column's name without the " (N)" that tells repeated header names apart."""
    name = table.names[index]
    marker = f" ({index + 1})"
    if name.endswith(marker) and name[:-len(marker)] in table.names[:index]:
        return name[:-len(marker)]
    return name


def _labelled_runs(table):
    """Runs named by a "Run #N" suffix; unlabelled columns belong to every run."""
    numbers = [_RUN_LABEL.search(name) for name in table.names]
    found = list(dict.fromkeys(int(m.group(1)) for m in numbers if m))
    shared = tuple(i for i, m in enumerate(numbers) if m is None)
    return [(n, tuple(sorted(shared + tuple(i for i, m in enumerate(numbers)
                                            if m and int(m.group(1)) == n))))
            for n in found]


def _repeated_groups(table):
    """Runs as repeated groups of columns, each starting with a time column of one name."""
    starts = [i for i in range(len(table.names)) if _is_time_name(_plain_name(table, i))]
    if len(starts) < 2 or starts[0] != 0:
        return []
    bounds = starts + [len(table.names)]
    groups = [tuple(range(a, b)) for a, b in zip(bounds, bounds[1:])]
    shapes = {tuple(_plain_name(table, i) for i in group) for group in groups}
    if len(shapes) != 1 or len(groups[0]) < 2:
        return []
    return [(k + 1, group) for k, group in enumerate(groups)]


def _file_runs(table):
    """The file's runs side by side, in file order (one run of all columns if none)."""
    runs = _labelled_runs(table)
    if len(runs) < 2:
        runs = _repeated_groups(table)
    if len(runs) < 2:
        return [_Run(None, 1, tuple(range(len(table.names))))]
    return [_Run(f"Run {number}", number, columns, len(runs)) for number, columns in runs]


def _chosen_runs(table, wanted, column_specs):
    """The runs to read: the one numbered ``wanted``, those holding a column named in
    ``column_specs`` when it names one column of the file, else all."""
    runs = _file_runs(table)
    for spec in column_specs:
        if spec is None or len(runs) == 1:
            continue
        try:
            index = _resolve_column(table, spec, "signal")
        except UsageError:  # a name every run holds: chosen in each run
            continue
        runs = [r for r in runs if index in r.columns] or runs
    if wanted is None:
        return runs
    chosen = [r for r in runs if r.number == int(wanted)]
    if not chosen and runs[0].label is None and int(wanted) == 1:
        return runs
    if not chosen:
        held = ", ".join(str(r.number) for r in runs) if runs[0].label else "one run"
        raise UsageError(f"run {wanted} not found in {table.name}; it holds {held}. "
                         "Give one of those numbers to `run`.")
    return chosen


def _resolve_column(table, spec, role, within=None):
    """The 0-based column named or numbered by ``spec``; a name is looked for among the
    columns ``within`` (default all), also without its unit and its run label."""
    option = {"time": "`time_col`", "signal": "`signal_col`"}.get(role, "`angle_from`")
    listing = ", ".join(table.names)
    if isinstance(spec, (int, np.integer)) or (isinstance(spec, str) and spec.strip().isdigit()
                                              and spec not in table.names):
        index = int(spec)
        if not 1 <= index <= len(table.names):
            raise UsageError(f"column {index} not found in {table.name}; it has "
                             f"{len(table.names)} columns: {listing}. Use {option} with a "
                             "1-based index or a name.")
        return index - 1
    spec = str(spec)
    if spec in table.names:
        return table.names.index(spec)
    wanted = _base_name(spec)[0]
    candidates = range(len(table.names)) if within is None else within
    matches = [i for i in candidates if table.names[i].strip().lower() == spec.strip().lower()
               or _base_name(table.names[i])[0] == wanted
               or _RUN_SUFFIX.sub("", _base_name(_plain_name(table, i))[0]) == wanted]
    if len(matches) == 1:
        return matches[0]
    if len(matches) > 1:
        raise UsageError(f"column '{spec}' is ambiguous in {table.name}; columns are: "
                         f"{listing}. Use {option} with the full name or a 1-based index.")
    raise UsageError(f"column '{spec}' not found in {table.name}; columns are: {listing}. "
                     f"Use {option}.")


def _strictly_increasing(values):
    v = values[np.isfinite(values)]
    return v.size >= 3 and bool(np.all(np.diff(v) > 0))


def _oscillation_score(values):
    """Fraction of steps where the signal crosses its (detrended) middle; 0 if not varying."""
    v = values[np.isfinite(values)]
    if v.size < 8 or np.ptp(v) == 0:
        return 0.0
    index = np.arange(v.size)
    trend = np.polyval(np.polyfit(index, v, 1), index)
    centred = v - trend
    crossings = np.count_nonzero(np.diff(np.sign(centred)) != 0)
    return crossings / v.size


def _choose_time(table, rate, columns):
    sample = table.sample
    named = [i for i in columns if _is_time_name(table.names[i])]
    # Elapsed seconds are the better time when the file also holds clock times.
    named = [i for i in named if i not in table.clock] + [i for i in named if i in table.clock]
    cycle_named = [i for i in columns if _base_name(table.names[i])[0] in _CYCLE_NAMES]
    increasing = [i for i in columns if _strictly_increasing(sample[i].values)]
    # Logger timestamps that repeat: a time column, but an unusable one.
    repeating = [i for i in columns if i not in increasing
                 and _timestamp_problem(sample[i].values) is not None
                 and np.all(np.diff(sample[i].values[np.isfinite(sample[i].values)]) >= 0)]
    if rate is not None:
        return None, named + [i for i in increasing + repeating if i not in named]
    for candidates in (named, cycle_named):
        if candidates:
            return candidates[0], []
    if increasing:
        return increasing[0], []
    if repeating:
        return repeating[0], []
    # No increasing column: a turning-point table may list its times unsorted.
    for i in columns:
        v = sample[i].values
        v = v[np.isfinite(v)]
        if v.size >= 4 and np.unique(v).size == v.size and v.size < 5000:
            return i, []
    return None, []


def _choose_signal(table, time_index, ignored, columns):
    sample = table.sample
    candidates = [i for i in columns
                  if i != time_index and i not in ignored and i not in table.clock
                  and np.count_nonzero(np.isfinite(sample[i].values)) >= 2
                  and np.ptp(sample[i].values[np.isfinite(sample[i].values)]) > 0]
    if not candidates:  # only constant columns: say so when they are read
        rest = [i for i in columns if i != time_index and i not in ignored
                and np.isfinite(sample[i].values).any()]
        return (rest[0], []) if rest else (None, [])
    secondary = [i for i in candidates
                 if any(w in _base_name(table.names[i])[0] for w in _SECONDARY_SIGNAL_WORDS)]
    primary = [i for i in candidates if i not in secondary]
    # Scoring orders the primary candidates; one needs no score.
    oscillating = ([i for i in primary if _oscillation_score(sample[i].values) > 0.02]
                   if len(primary) > 1 else primary)
    order = oscillating + [i for i in primary if i not in oscillating] + secondary
    return order[0], [i for i in order[1:]]


def _describe(table, index):
    label = table.names[index]
    return f"'{label}' (column {index + 1})" if not label.startswith("column ") else label


def _read_columns(table, indices):
    if table.complete:  # already parsed, as floats
        return [table.sample[index].to_numpy(dtype=np.float64, copy=False) for index in indices]
    try:
        frame = table.reader(indices)
    except (pd.errors.EmptyDataError, pd.errors.ParserError) as exc:
        # Before ValueError: both are ValueErrors, and re-reading would fail again.
        raise _parse_error(table.name, exc) from None
    except UnicodeDecodeError as exc:
        # Sniffing saw only the first megabyte; a byte further on is not in its encoding.
        raise InputError(f"cannot read {table.name}: past its first megabyte it is not "
                         f"{exc.encoding} text ({exc.reason}). Save the file as UTF-8.") from None
    except ValueError as exc:
        # Text in a numeric column: find it, to say where.
        try:
            text = table.reader(indices, as_text=True)
        except ValueError:  # not text but the shape: rows shorter than the header says
            raise InputError(f"cannot parse {table.name}: {str(exc).splitlines()[0]}. Check "
                             "that every row has the same number of columns.") from None
        for position, index in enumerate(indices):
            values = text.iloc[:, position].astype(str).str.strip()
            if table.decimal == ",":
                values_read = values.str.replace(",", ".", regex=False)
            else:
                values_read = values
            converted = pd.to_numeric(values_read.replace("", np.nan), errors="coerce")
            bad = converted.isna() & values.ne("") & ~values.str.lower().isin(
                ["nan", "na", "n/a", "null", "none", "-nan", "inf", "-inf"])
            clockish = values.map(lambda v: bool(isinstance(v, str) and (
                _CLOCK.match(v) or _ISO_DATE_TIME.match(v))))
            if bad.any() and clockish.mean() > 0.5:
                # Clock times that did not all convert: name the odd one out.
                odd = bad & ~clockish
                row = int(np.flatnonzero((odd if odd.any() else bad).values)[0])
                first = str(values[clockish].iloc[0])
                raise InputError(
                    f"'{_shown(values.iloc[row])}' in the clock-time column {_describe(table, index)} "
                    f"of {table.name} (data row {row + 1}) is not a clock time like the "
                    f"others ('{first}'). Fix or delete that row, or choose another time "
                    "column with `time_col` or give `rate=HZ`.") from None
            if bad.any():
                row = int(np.flatnonzero(bad.values)[0])
                raise InputError(
                    f"text '{_shown(values.iloc[row])}' in numeric column {_describe(table, index)} of "
                    f"{table.name} (data row {row + 1}). Fix or delete that row, or start it "
                    "with # to make it a comment.") from None
        columns = ", ".join(_describe(table, index) for index in indices)
        raise InputError(f"cannot read the columns {columns} of {table.name} as numbers "
                         f"({str(exc).splitlines()[0]}). Check that every row has the same "
                         "number of columns.") from None
    return [frame.iloc[:, position].to_numpy(dtype=np.float64, copy=False)
            for position in range(len(indices))]


def _shown(value):
    """A cell's text for a one-line message: a quoted field may span lines."""
    text = str(value)
    text = text.replace("\r\n", "\n").replace("\r", "\n").replace("\n", "\\n")
    return text if len(text) <= 60 else text[:57] + "..."


def _timestamp_problem(t):
    """Describe unusable logger timestamps (repeats or bursts), or None."""
    # Copies of a long record's times are avoided: they set the reader's peak memory.
    finite = t if np.isfinite(t).all() else t[np.isfinite(t)]
    if finite.size < 4:
        return None
    steps = np.diff(finite)
    if not np.all(steps > 0):
        repeats = np.count_nonzero(steps == 0)
        if repeats > 0 and np.all(steps >= 0):
            return (f"{repeats} of {steps.size} time steps repeat the previous timestamp "
                    "(the logger stamps samples in bursts)")
        return None
    if steps.size >= 4:
        median = np.median(steps)
        long_steps = np.count_nonzero(steps > 4 * median)
        if long_steps >= 3 and long_steps >= 0.05 * steps.size:
            return (f"time steps come in bursts ({long_steps} of {steps.size} steps are more "
                    "than 4 times the median step)")
    return None


# Glitched timestamps (repeated or stepping back) repaired when at most this fraction of the
# steps is wrong; more means the column is not a clean clock, and a person must decide.
_MAX_GLITCH_FRACTION = 0.01


def _repair_times(table, time_index, t, x, notes):
    """(t, x, event_driven) with rounded, event-driven or glitched timestamps dealt with.

    A time column rounded in print (Tracker's 3 significant figures) is rebuilt as the
    evenly spaced times it rounds; an event-driven log (a row each time the signal moves
    by one step) keeps its uneven times; a few repeated or backward timestamps are set to
    the middle of their neighbours, or dropped. Each repair adds a note.
    """
    if t.size < 4 or (np.all(np.diff(t) > 0) and _timestamp_problem(t) is None):
        return t, x, False
    label = _describe(table, time_index)
    rebuilt = _unrounded_times(table, time_index, t)
    if rebuilt is not None:
        t, model = rebuilt
        step = float(np.median(np.diff(t)))
        notes.append(f"time column {label} is rounded ({model}); times rebuilt as evenly "
                     f"spaced, step {step:.6g} s ({1 / step:.6g} Hz)")
        return t, x, False
    event_step = _event_step(x)
    if event_step is not None:
        same = np.flatnonzero(np.diff(t) == 0)
        if same.size and np.all(np.diff(t) >= 0):
            keep = np.ones(t.size, dtype=bool)
            keep[same] = False  # of rows sharing a timestamp, the last is the state then
            t, x = t[keep], x[keep]
            notes.append(f"{same.size} rows sharing their timestamp with the next row "
                         "dropped (the last row of each time kept)")
        notes.append(f"an event-driven log (a row each time the signal moves by "
                     f"{event_step:g}): its uneven time steps are real and kept")
        return t, x, True
    steps = np.diff(t)
    if np.all(steps > 0):
        return t, x, False
    repaired = _mend_glitches(t)
    if repaired is None:
        return t, x, False
    t_new, keep, fixed, first = repaired
    bad = fixed + int(np.count_nonzero(~keep))
    what = []
    if fixed:
        what.append(f"{fixed} set to the middle of their neighbours")
    if not keep.all():
        what.append(f"{int(np.count_nonzero(~keep))} rows dropped")
    notes.append(f"{bad} glitched timestamps (repeated or stepping back) in {label}, the "
                 f"first at data row {first + 1}: " + ", ".join(what))
    return t_new[keep], x[keep], False


def _mend_glitches(t):
    """(times, rows kept, number set right, first glitch) for a few glitched timestamps,
    or None when there are too many or they cannot be told from the rest.

    A glitch is a time off the local run of the clock: t_i - i*step against its running
    median over five rows differs by more than half a step. A glitch between two good
    rows is set to their middle; other glitches, and rows that still do not increase
    (kept by the longest increasing run), are dropped.
    """
    steps = np.diff(t)
    step = float(np.median(steps))
    if not step > 0:
        return None
    limit = _MAX_GLITCH_FRACTION * steps.size
    drift = t - step * np.arange(t.size)
    window = np.lib.stride_tricks.sliding_window_view(np.pad(drift, 2, mode="edge"), 5)
    glitch = np.abs(drift - np.median(window, axis=1)) > 0.5 * step
    if not glitch.any() or np.count_nonzero(glitch) > limit:
        glitch = np.zeros(t.size, dtype=bool)
    t = t.copy()
    keep = ~glitch
    fixed = 0
    for i in np.flatnonzero(glitch):
        if 0 < i < t.size - 1 and not glitch[i - 1] and not glitch[i + 1] and (
                t[i - 1] < t[i + 1]):
            t[i] = 0.5 * (t[i - 1] + t[i + 1])
            keep[i] = True
            fixed += 1
    order = np.flatnonzero(keep)
    increasing = order[_longest_increasing(t[order])]
    if fixed + t.size - increasing.size > limit:
        return None
    keep = np.zeros(t.size, dtype=bool)
    keep[increasing] = True
    bad = glitch | ~keep
    return t, keep, fixed, int(np.flatnonzero(bad)[0])


def _longest_increasing(t):
    """Indices of a longest strictly increasing subsequence of ``t`` (patience sorting)."""
    import bisect
    tails, tail_index = [], []
    previous = np.full(t.size, -1, dtype=np.intp)
    for i, value in enumerate(t.tolist()):
        k = bisect.bisect_left(tails, value)
        if k == len(tails):
            tails.append(value)
            tail_index.append(i)
        else:
            tails[k] = value
            tail_index[k] = i
        previous[i] = tail_index[k - 1] if k else -1
    out = []
    i = tail_index[-1] if tail_index else -1
    while i >= 0:
        out.append(i)
        i = previous[i]
    return np.array(out[::-1], dtype=np.intp)


def _event_step(x):
    """The step of an event-driven log (nearly every row moves the signal by one step),
    else None."""
    finite = x[np.isfinite(x)]
    if finite.size < 20:
        return None
    moves = np.abs(np.diff(finite))
    moving = moves[moves > 0]
    if moving.size < 0.9 * moves.size:
        return None
    step = moving.min()
    if np.count_nonzero(np.abs(moving - step) <= 1e-9 * max(step, 1e-300)) < 0.9 * moves.size:
        return None
    return float(step)


_DECIMAL_TOKEN = re.compile(r"^[+-]?(\d*)(?:\.(\d*))?(?:[eE]([+-]?\d+))?$")


def _print_resolutions(tokens):
    """Ways the times may have been printed, as (description, value -> resolution): to a
    fixed number of decimals, or of significant figures (Tracker's default). Tokens with
    fewer digits (trailing zeros left out) are exact at the finer resolution too."""
    decimals, figures = 0, 0
    for token in tokens:
        match = _DECIMAL_TOKEN.match(token.strip())
        if not match or not (match.group(1) or match.group(2)) or match.group(3) is not None:
            return []
        whole, fraction = match.group(1), match.group(2) or ""
        decimals = max(decimals, len(fraction))
        figures = max(figures, len((whole + fraction).lstrip("0")))
    if figures == 0 or decimals > 12:
        return []

    def fixed(v):
        return np.full(v.shape, 10.0 ** -decimals)

    def significant(v):
        magnitude = np.floor(np.log10(np.maximum(np.abs(v), 1e-300)))
        return 10.0 ** (magnitude - figures + 1)
    return [(f"to {decimals} decimals", fixed), (f"to {figures} significant figures",
                                                 significant)]


def _unrounded_times(table, time_index, t):
    """(evenly spaced times, how they were rounded) when ``t`` is an evenly sampled time
    rounded in print, else None. The line a + b*i is the one that stays closest to every
    time in units of its rounding (a linear programme); rounding explains the times when
    no time is further from it than half its last printed digit."""
    tokens = []
    for line in table.token_lines[:2000]:
        fields = _split(line.strip(), table.sep) if line.strip() else []
        if len(fields) > time_index and fields[time_index]:
            tokens.append(fields[time_index])
    if len(tokens) < 20 or t.size < 20 or not np.all(np.isfinite(t)):
        return None
    # Samples in equal groups per timestamp (2, 2, 2...) fit a rounded clock as well as
    # bursts; with a fixed number of decimals they are taken for bursts, as the logger's
    # own stamps. Rounding to significant figures changes the group size with the time.
    _, groups = np.unique(t, return_counts=True)
    regular = bool(np.all(groups[1:-1] == groups[1])) if groups.size > 2 else True
    for how, resolution in _print_resolutions(tokens):
        if regular and "decimals" in how:
            continue
        line = _line_within(t, 0.5 * resolution(t))
        if line is not None:
            return line, how
    return None


def _line_within(t, half):
    """a + b*i, shape (n,), within ``half`` of every ``t`` with b > 0, or None."""
    from scipy.optimize import linprog
    i = np.arange(t.size, dtype=np.float64)
    # minimise s subject to |a + b*i - t| <= s*half  (variables a, b, s)
    ones = np.ones(t.size)
    a_ub = np.block([[ones[:, None], i[:, None], -half[:, None]],
                     [-ones[:, None], -i[:, None], -half[:, None]]])
    b_ub = np.concatenate([t, -t])
    result = linprog([0.0, 0.0, 1.0], A_ub=a_ub, b_ub=b_ub,
                     bounds=[(None, None), (None, None), (0, None)], method="highs")
    if not result.success or result.x[2] > 1.0 + 1e-6 or result.x[1] <= 0:
        return None
    a, b = result.x[0], result.x[1]
    return a + b * i


def _chosen_columns(table, time_col, signal_col, rate, run, angle_from):
    """(time index or None, signal index, other signal candidates, ignored time columns)
    among the run's columns; for ``angle_from`` the signal is the bob's x column."""
    name, columns = table.name, run.columns
    ignored = []
    if time_col is not None:
        time_index = _resolve_column(table, time_col, "time", columns)
    else:
        time_index, ignored = _choose_time(table, rate, columns)
    signal_col = angle_from[0] if angle_from is not None else signal_col
    if signal_col is not None:
        role = "signal" if angle_from is None else "angle"
        signal_index, others = _resolve_column(table, signal_col, role, columns), []
    else:
        signal_index, others = _choose_signal(table, time_index, ignored, columns)
        if signal_index is None:
            if table.sample.shape[1] == 1 or time_index is None:
                raise InputError(f"no signal column found in {name} (columns: "
                                 f"{', '.join(table.names)}). Use `signal_col`.")
            raise InputError(f"no varying signal column in {name} besides the time "
                             f"{_describe(table, time_index)}; columns are: "
                             f"{', '.join(table.names)}. Use `signal_col`.")
    if time_index is not None and time_index == signal_index:
        raise UsageError(f"the time and the signal are the same column "
                         f"{_describe(table, signal_index)} of {name}. Use `time_col` and "
                         "`signal_col` with different columns.")
    if time_index is None and rate is None:
        raise InputError(f"no time column found in {name} (no column increases steadily). "
                         "Name it with `time_col` or give the sample rate with `rate=HZ`.")
    return time_index, signal_index, others, ignored


def _swing_angle(table, x, y_index, notes):
    """The swing angle atan2(x, -y) of a bob tracked at (x, y), pivot at the origin; with
    y growing downwards (image coordinates: the bob hangs at y > 0), atan2(x, y)."""
    y = _read_columns(table, [y_index])[0][:x.size]
    finite = np.isfinite(y)
    downwards = finite.any() and np.median(y[finite]) > 0
    angle = np.arctan2(x, y if downwards else -y)
    formula = "atan2(x, y), y growing downwards" if downwards else "atan2(x, -y)"
    notes.append(f"signal: the swing angle {formula}, in radians, y from "
                 f"{_describe(table, y_index)} (pivot at the origin)")
    return angle


def _end_of(present):
    """One past the last True of ``present`` (which holds one), without an index array."""
    return present.size - int(np.argmax(present[::-1]))


def _build_record(table, time_col, signal_col, rate, kind, domain, run=None,
                  angle_from=None):
    run = run or _Run(None, 1, tuple(range(len(table.names))))
    name = table.name
    notes = list(table.notes)
    present = ~np.isnan(table.sample.to_numpy(dtype=np.float64))
    if table.sample.shape[0] == 0 or not present.any():
        raise InputError(f"{name} has no numeric data rows. Give a file with a time and a "
                         "signal column of numbers.")
    numeric_rows = int(np.count_nonzero(present.any(axis=1)))
    if numeric_rows < 2:
        raise InputError(f"{name} has only {numeric_rows} data row. A decay record needs "
                         "many samples over several cycles.")
    if len(table.names) == 1 and time_col is None and rate is None and signal_col is None:
        rows = " (its values written in one row)" if table.transposed else ""
        raise InputError(f"{name} has one column{rows}, {_describe(table, 0)}, and no time "
                         "column. Give the sample rate with `rate=HZ`, or add a time column.")
    time_index, signal_index, others, ignored = _chosen_columns(
        table, time_col, signal_col, rate, run, angle_from)
    if run.label is not None:
        notes.append(f"{run.label}, one of {run.count} runs side by side in the file, fitted "
                     f"as a record of its own (`run={run.number}` picks it)")

    indices = [signal_index] if time_index is None else [time_index, signal_index]
    columns = _read_columns(table, indices)
    x = columns[-1]
    t = columns[0] if time_index is not None else None
    y_index = None
    if angle_from is not None:
        y_index = _resolve_column(table, angle_from[1], "angle", run.columns)
        x = _swing_angle(table, x, y_index, notes)

    # Side-by-side runs: shorter runs are padded with empty cells at the end.
    present = np.isfinite(x) if t is None else np.isfinite(t)
    if not present.any():
        what = "signal" if t is None else "time"
        column = signal_index if t is None else time_index
        raise InputError(f"the {what} column {_describe(table, column)} of {name} holds no "
                         "numbers. Choose another column with `time_col` or `signal_col`.")
    end = _end_of(present)
    if end < x.size:
        notes.append(f"{x.size - end} empty trailing rows dropped (padding)")
        x = x[:end]
        t = None if t is None else t[:end]
    if t is not None:
        missing_t = ~np.isfinite(t)
        if missing_t.any():
            notes.append(f"{int(missing_t.sum())} rows without a time value dropped")
            t, x = t[~missing_t], x[~missing_t]
    finite = np.isfinite(x)
    if not finite.any():
        raise InputError(f"the signal column {_describe(table, signal_index)} of {name} holds "
                         "no numbers (all empty or NaN). Choose the signal with `signal_col`.")
    values = x if finite.all() else x[finite]  # copied only where there are gaps
    if values.min() == values.max():
        raise InputError(f"the signal column {_describe(table, signal_index)} of {name} is "
                         f"constant ({values[0]:g}). Choose the signal with `signal_col`.")
    del values
    # Trailing NaN in the signal alone (a shorter run sharing the time column).
    last_x = _end_of(finite)
    del finite
    if last_x < x.size:
        notes.append(f"{x.size - last_x} trailing rows without a signal value dropped")
        x = x[:last_x]
        t = None if t is None else t[:last_x]

    time_unit = _base_name(table.names[time_index])[1] if time_index is not None else "s"
    signal_unit = _base_name(table.names[signal_index])[1]
    signal_label = table.names[signal_index]
    if angle_from is not None:
        signal_unit = "rad"
        signal_label = f"angle from {signal_label}, {table.names[y_index]}"
    time_label = table.names[time_index] if time_index is not None else None

    if rate is not None:
        if ignored:
            probe = table.sample[ignored[0]].values
            problem = _timestamp_problem(probe)
            text = f"; its timestamps are unusable: {problem}" if problem else ""
            notes.append(f"time built from the sample rate {rate:g} Hz; column "
                         f"{_describe(table, ignored[0])} ignored{text}")
        else:
            notes.append(f"time built from the sample rate {rate:g} Hz")
        t = np.arange(x.size, dtype=np.float64) / rate
        detected_kind = "waveform"
    else:
        detected_kind = detect_kind(t, x)
    chosen_kind = kind or detected_kind
    if kind is None and detected_kind == "turning-points":
        notes.append("read as a table of turning points (override with `kind=waveform`)")

    if chosen_kind == "turning-points":
        finite = np.isfinite(t) & np.isfinite(x)
        if np.count_nonzero(~finite):
            notes.append(f"{int(np.count_nonzero(~finite))} incomplete rows dropped")
        t, x = t[finite], x[finite]
        if np.unique(t).size != t.size:
            raise InputError(f"the time column {_describe(table, time_index)} of {name} repeats "
                             "values in a turning-point table. Remove the duplicate rows.")
        if not np.all(np.diff(t) > 0):
            order = np.argsort(t, kind="stable")
            t, x = t[order], x[order]
            notes.append("turning points sorted by time")
    else:
        t, x, event_driven = _repair_times(table, time_index, t, x, notes)
        if not np.all(np.diff(t) > 0):
            problem = _timestamp_problem(t)
            where = int(np.flatnonzero(~(np.diff(t) > 0))[0]) + 1
            if problem:
                raise InputError(f"the time column {_describe(table, time_index)} of {name} is "
                                 f"unusable: {problem}. Give the sample rate with `rate=HZ`.")
            raise InputError(f"the time column {_describe(table, time_index)} of {name} does "
                             f"not increase (data row {where + 1}: {t[where - 1]:g} then "
                             f"{t[where]:g}). Sort the file, choose another column with "
                             "`time_col`, or use `rate=HZ`.")
        problem = None if event_driven else _timestamp_problem(t)
        if problem:
            notes.append(f"irregular timestamps: {problem}; if the logger stamps samples in "
                         "bursts, use `rate=HZ`")
        gaps = np.count_nonzero(~np.isfinite(x))
        if gaps:
            notes.append(f"{gaps} samples without a signal value (gaps)")

    if domain is None:
        domain = "time"
        if time_index is not None and (_base_name(table.names[time_index])[0] in _CYCLE_NAMES):
            domain = "cycle"
        elif (chosen_kind == "turning-points" and t.size >= 2 and np.all(t == np.round(t))
              and np.all(np.diff(t) == np.diff(t)[0]) and time_unit is None):
            domain = "cycle"
        if domain == "cycle":
            notes.append("time column read as cycle number n (override with `domain=time`)")

    if time_index is not None and time_col is None:
        notes.append(f"time column: {_describe(table, time_index)} (chosen automatically; "
                     "use `time_col` to change)")
    if signal_col is None and angle_from is None:
        other = ""
        if others:
            other = "; other candidates: " + ", ".join(_describe(table, i) for i in others)
        notes.append(f"signal column: {_describe(table, signal_index)} (chosen automatically; "
                     f"use `signal_col` to change{other})")

    if domain == "time" and time_unit is not None:
        seconds = _SECONDS_PER_UNIT.get(time_unit.strip().lower().replace("μ", "u").replace("µ", "u"))
        if seconds is None:
            notes.append(f"time unit '{time_unit}' not recognised: coefficients are per "
                         f"{time_unit}, not per second")
        elif seconds != 1.0:
            t = t * seconds
            notes.append(f"time converted from {time_unit} to seconds")
            time_unit = "s"
        else:  # "seconds", "sec": the report speaks of seconds as "s"
            time_unit = "s"

    t = np.ascontiguousarray(t, dtype=np.float64)
    x = np.ascontiguousarray(x, dtype=np.float64)
    t.setflags(write=False)
    x.setflags(write=False)
    return Record(source=name, t=t, x=x, kind=chosen_kind, domain=domain,
                  time_column=time_label, signal_column=signal_label,
                  time_unit=time_unit, signal_unit=signal_unit,
                  columns=tuple(table.names), notes=tuple(notes), run=run.label)
