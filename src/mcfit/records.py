"""Reading decay records (CSV, TSV, semicolon, whitespace text, Excel, stdin) into a :class:`Record`.

This is the only module that imports pandas. It turns whatever file a person has into two
float64 arrays, ``t`` and ``x``, and says in ``Record.notes`` what it decided on the way
(columns chosen, decimal commas, padding dropped, timestamps ignored...). Every failure a
person can fix raises :class:`mcfit.errors.InputError` (or ``UsageError`` for contradictory
options) with one line naming the file, the problem and the fix.

Column choice without options: a column named like time (``time``, ``t``, ``time (s)``...)
or else the first strictly increasing column is the time; the signal is the first other
column that oscillates (velocity, acceleration, residual and fit columns come last).
"""

from __future__ import annotations

import io
import re
import stat
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from mcfit.errors import InputError, UsageError

__all__ = ["Record", "read_record", "TEXT_EXTENSIONS", "EXCEL_EXTENSIONS"]

TEXT_EXTENSIONS = (".csv", ".tsv", ".txt", ".dat")
EXCEL_EXTENSIONS = (".xlsx", ".xlsm")
KINDS = ("waveform", "turning-points")
DOMAINS = ("time", "cycle")

# Bytes sniffed to choose separator, decimal mark, header and columns.
_SNIFF_BYTES = 1 << 20
# Lines of data parsed as the sample that guides the choice of columns.
_SAMPLE_LINES = 20000
# Line breaks of str.splitlines that pandas' parser does not break lines at.
_PYTHON_ONLY_LINE_BREAKS = ("\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029")
_TIME_NAMES = {"time", "t", "times", "tempo", "zeit", "temps", "tiempo", "seconds", "sec",
               "timestamp", "stamp", "elapsed", "elapsed time"}
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


@dataclass(frozen=True, eq=False)
class Record:
    """A decay record as read from a file: plain arrays plus what was decided on the way.

    Attributes
    ----------
    source : str
        File name as given (``"<stdin>"`` for ``-`` or a stream).
    t : ndarray, shape (n,)
        Time (in ``time_unit``, seconds unless the header says otherwise) or cycle number
        (``domain == "cycle"``). Increasing for waveforms; turning-point tables are sorted.
    x : ndarray, shape (n,)
        Signal (waveform) or turning-point values (signed or not); NaN marks a gap.
    kind : {"waveform", "turning-points"}
    domain : {"time", "cycle"}
    time_column, signal_column : str or None
        Column names as in the file (``"column 2"`` without a header); ``time_column`` is
        None when the time was built from ``rate``.
    time_unit, signal_unit : str or None
        Units read from headers such as ``time (s)``.
    columns : tuple of str
        Every column of the file, in order.
    notes : tuple of str
        One sentence per decision or oddity, for the report.
    """

    source: str
    t: np.ndarray
    x: np.ndarray
    kind: str = "waveform"
    domain: str = "time"
    time_column: str | None = None
    signal_column: str | None = None
    time_unit: str | None = None
    signal_unit: str | None = None
    columns: tuple[str, ...] = ()
    notes: tuple[str, ...] = field(default=())

    def to_dict(self):
        """Plain-Python summary (no arrays), ready for JSON."""
        finite = np.isfinite(self.t)
        return {
            "source": self.source, "kind": self.kind, "domain": self.domain,
            "time_column": self.time_column, "signal_column": self.signal_column,
            "time_unit": self.time_unit, "signal_unit": self.signal_unit,
            "columns": list(self.columns), "samples": int(self.t.size),
            "t_start": float(self.t[finite][0]) if finite.any() else None,
            "t_end": float(self.t[finite][-1]) if finite.any() else None,
            "notes": list(self.notes),
        }


def read_record(source, *, time_col=None, signal_col=None, sheet=None, rate=None,
                input=None, domain=None):  # noqa: A002 - mirrors the --input option
    """Read a decay record from a file, ``"-"`` (stdin) or an open stream.

    Parameters
    ----------
    source : str, os.PathLike or file-like
        ``.csv``, ``.tsv``, ``.txt``, ``.dat`` (separator sniffed: comma, semicolon, tab or
        whitespace; decimal comma accepted), ``.xlsx``/``.xlsm``, ``"-"`` for stdin, or an
        open text or binary stream holding delimited text.
    time_col, signal_col : str or int, optional
        Column name (units in parentheses may be left out, case ignored) or 1-based index.
    sheet : str or int, optional
        Excel sheet name or 1-based index (default: the first sheet).
    rate : float, optional
        Sample rate in Hz: ``t = index / rate`` (for files without a usable time column).
    input : {"waveform", "turning-points"}, optional
        Override the detected kind of record.
    domain : {"time", "cycle"}, optional
        Override the detected meaning of the time column (seconds or cycle number n).

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
    if input is not None and input not in KINDS:
        raise UsageError(f"input must be 'waveform' or 'turning-points', not {input!r}.")
    if domain is not None and domain not in DOMAINS:
        raise UsageError(f"domain must be 'time' or 'cycle', not {domain!r}.")
    if rate is not None:
        try:
            rate = float(rate)
        except (TypeError, ValueError):
            raise UsageError(f"rate must be a number of samples per second, not {rate!r}.")
        if not np.isfinite(rate) or rate <= 0:
            raise UsageError(f"rate must be a positive number of samples per second, not {rate}.")
        if time_col is not None:
            raise UsageError("give either a time column or a sample rate, not both.")
    table = _open_table(source, sheet)
    # The column heuristics (spans, slopes, steps) overflow to inf or NaN for values near
    # the float64 limit, which then fail their tests as they should; the turning-point
    # search rejects such values with a message.
    with np.errstate(over="ignore", invalid="ignore"):
        return _build_record(table, time_col, signal_col, rate, input, domain)


# --------------------------------------------------------------------------- opening


class _Table:
    """Column names plus a way to read chosen columns as float64."""

    def __init__(self, name, names, sample, reader, notes, complete=False):
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
    if suffix in EXCEL_EXTENSIONS:
        return _excel_table(path, name, sheet)
    if suffix in (".xls", ".ods", ".numbers"):
        raise InputError(f"unsupported file type '{suffix}' for {name}; save it as .xlsx or "
                         "export it as CSV.")
    if suffix not in TEXT_EXTENSIONS:
        raise InputError(f"unsupported file type '{suffix or '(none)'}' for {name}; use .csv, "
                         ".tsv, .txt, .dat or .xlsx (or rename a delimited text file to .csv).")
    if sheet is not None:
        raise UsageError(f"--sheet applies to Excel files only, and {name} is a text file.")
    try:
        with open(path, "rb") as handle:
            head = handle.read(_SNIFF_BYTES)
    except OSError as exc:
        raise InputError(f"cannot read {name}: {exc.strerror}. Check its permissions.") from None
    return _text_table(name, head, path)


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
    return [f.strip().strip('"').strip("'").strip() for f in line.split(sep)]


def _is_number(token):
    return bool(_NUMBER.match(token.strip())) or token.strip().lower() in ("nan", "inf", "-inf")


def _text_table(name, head, path):
    if not head or head.isspace():  # as head.strip() == b"", without copying the file
        raise InputError(f"{name} is empty. Give a file with a time and a signal column.")
    text, encoding, enc_note, exact_text = _decode(head)
    problem = _binary_problem(text)
    if problem is not None:
        raise InputError(f"{name} is not a text record: it holds binary data ({problem}). "
                         "Give a CSV, TSV or text export of the data (an Excel workbook must "
                         "end in .xlsx).")
    notes = [enc_note] if enc_note else []
    lines = text.splitlines()
    if path is not None and len(head) == _SNIFF_BYTES and lines:
        lines = lines[:-1]  # the last line may be cut by the sniff limit
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
    sep, decimal = _sniff_separator([line for _, line in content[:50]])
    first_fields = _split(content[0][1], sep)
    has_header = not all(_is_number(f) or f == "" for f in first_fields)
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
    return _Table(name, names, sample, reader, notes, complete=complete)


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
                             f"sheet(s): {', '.join(sheets)}. Use --sheet with a name or "
                             "1-based index.")
        return sheets[index - 1]
    if sheet in sheets:
        return sheet
    raise UsageError(f"sheet '{sheet}' not found in {name}; sheets are: {', '.join(sheets)}. "
                     "Use --sheet.")


_CFB_SIGNATURE = b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1"  # OLE compound file


def _excel_table(path, name, sheet):
    try:
        with open(path, "rb") as handle:
            signature = handle.read(8)
    except OSError as exc:
        raise InputError(f"cannot read {name}: {exc.strerror or exc}. Check its "
                         "permissions.") from None
    if signature == _CFB_SIGNATURE:
        # Excel saves a password-protected workbook as an OLE compound file holding the
        # encrypted package; an old binary .xls is one too. Neither is a zip .xlsx.
        raise InputError(f"{name} is a password-protected (encrypted) workbook or an old "
                         ".xls renamed .xlsx, which mcfit cannot open. In Excel remove the "
                         "password and save as .xlsx, or export CSV.")
    try:
        book = pd.ExcelFile(path, engine="openpyxl")
    except Exception as exc:  # zipfile.BadZipFile, KeyError, ValueError... from openpyxl
        raise InputError(f"cannot read {name} as an Excel workbook ({type(exc).__name__}): the "
                         "file is damaged or not .xlsx. Re-save it from Excel or export "
                         "CSV.") from None
    try:
        sheet_name = _sheet_name(book.sheet_names, sheet, name)
        raw = pd.read_excel(book, sheet_name=sheet_name, header=None)
    except (InputError, UsageError):
        raise
    except Exception as exc:
        raise InputError(f"cannot read sheet {sheet!r} of {name} ({type(exc).__name__}). "
                         "Re-save the workbook or export CSV.") from None
    finally:
        book.close()
    raw = raw.dropna(how="all").dropna(axis=1, how="all")
    if raw.empty:
        raise InputError(f"sheet '{sheet_name}' of {name} is empty. Choose the sheet holding "
                         "the data with --sheet.")
    raw.columns = range(raw.shape[1])
    first = raw.iloc[0]
    has_header = any(isinstance(v, str) and not _is_number(v) for v in first)
    if has_header:
        names = [str(v).strip() if isinstance(v, str) or not pd.isna(v) else f"column {i + 1}"
                 for i, v in enumerate(first)]
        body = raw.iloc[1:]
        if body.empty:
            raise InputError(f"sheet '{sheet_name}' of {name} has a header row but no data "
                             "rows. Add data below the header.")
    else:
        names = [f"column {i + 1}" for i in range(raw.shape[1])]
        body = raw
    text = body.astype(str).replace({"nan": "", "None": ""})
    decimal = "," if text.apply(lambda c: c.str.match(_COMMA_DECIMAL.pattern)).any().any() else "."
    numeric = _numeric_frame(text, decimal)
    notes = [f"sheet '{sheet_name}'"]
    if decimal == ",":
        notes.append("decimal commas read as decimal points")

    def reader(indices, nrows=None, as_text=False):
        if as_text:
            return text.iloc[:, list(indices)]
        return numeric.iloc[:, list(indices)]

    return _Table(name, names, numeric, reader, notes)


# --------------------------------------------------------------------------- choosing


def _base_name(label):
    """'Time (s)' -> ('time', 's'); 'angle' -> ('angle', None)."""
    match = _UNIT.match(label.strip())
    if match and match.group(1):
        return match.group(1).strip().lower(), match.group(2).strip() or None
    return label.strip().lower(), None


def _resolve_column(table, spec, role):
    option = "--time-col" if role == "time" else "--signal-col"
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
    matches = [i for i, n in enumerate(table.names)
               if n.strip().lower() == spec.strip().lower() or _base_name(n)[0] == wanted]
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


def _choose_time(table, rate):
    sample = table.sample
    named = [i for i, n in enumerate(table.names) if _base_name(n)[0] in _TIME_NAMES]
    cycle_named = [i for i, n in enumerate(table.names) if _base_name(n)[0] in _CYCLE_NAMES]
    increasing = [i for i in range(sample.shape[1]) if _strictly_increasing(sample[i].values)]
    # Logger timestamps that repeat: a time column, but an unusable one.
    repeating = [i for i in range(sample.shape[1]) if i not in increasing
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
    for i in range(sample.shape[1]):
        v = sample[i].values
        v = v[np.isfinite(v)]
        if v.size >= 4 and np.unique(v).size == v.size and v.size < 5000:
            return i, []
    return None, []


def _choose_signal(table, time_index, ignored):
    sample = table.sample
    candidates = [i for i in range(sample.shape[1])
                  if i != time_index and i not in ignored
                  and np.count_nonzero(np.isfinite(sample[i].values)) >= 2
                  and np.ptp(sample[i].values[np.isfinite(sample[i].values)]) > 0]
    if not candidates:  # only constant columns: say so when they are read
        rest = [i for i in range(sample.shape[1]) if i != time_index and i not in ignored
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


def _detect_kind(t, x):
    """'turning-points' for a table of extrema or amplitudes, else 'waveform'."""
    finite = np.isfinite(t) & np.isfinite(x)
    t, x = t[finite], x[finite]
    if x.size < 3 or x.size > 5000:
        return "waveform"
    order = np.argsort(t, kind="stable")
    v = x[order]
    if np.all(v >= 0) or np.all(v <= 0):
        magnitude = np.abs(v)
        decreasing = np.count_nonzero(np.diff(magnitude) < 0) / (v.size - 1)
        return "turning-points" if decreasing >= 0.65 else "waveform"
    centred = v - np.median(v)
    alternating = np.count_nonzero(np.diff(np.sign(centred)) != 0) / (v.size - 1)
    return "turning-points" if alternating >= 0.9 else "waveform"


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
            converted = pd.to_numeric(values.str.replace(",", ".", regex=False)
                                      .replace("", np.nan), errors="coerce")
            bad = converted.isna() & values.ne("") & ~values.str.lower().isin(
                ["nan", "na", "n/a", "null", "none", "-nan", "inf", "-inf"])
            if bad.any():
                row = int(np.flatnonzero(bad.values)[0])
                raise InputError(
                    f"text '{values.iloc[row]}' in numeric column {_describe(table, index)} of "
                    f"{table.name} (data row {row + 1}). Fix or delete that row, or start it "
                    "with # to make it a comment.") from None
        raise
    return [frame.iloc[:, position].to_numpy(dtype=np.float64, copy=False)
            for position in range(len(indices))]


def _timestamp_problem(t):
    """Describe unusable logger timestamps (repeats or bursts), or None."""
    finite = t[np.isfinite(t)]
    if finite.size < 4:
        return None
    steps = np.diff(finite)
    repeats = np.count_nonzero(steps == 0)
    if repeats > 0 and np.all(steps >= 0):
        return (f"{repeats} of {steps.size} time steps repeat the previous timestamp "
                "(the logger stamps samples in bursts)")
    positive = steps[steps > 0]
    if positive.size >= 4 and np.all(steps > 0):
        median = np.median(positive)
        long_steps = np.count_nonzero(steps > 4 * median)
        if long_steps >= 3 and long_steps >= 0.05 * steps.size:
            return (f"time steps come in bursts ({long_steps} of {steps.size} steps are more "
                    "than 4 times the median step)")
    return None


def _build_record(table, time_col, signal_col, rate, kind, domain):
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
        raise InputError(f"{name} has one column, {_describe(table, 0)}, and no time column. "
                         "Give the sample rate with --rate HZ, or add a time column.")
    ignored = []
    if time_col is not None:
        time_index = _resolve_column(table, time_col, "time")
    else:
        time_index, ignored = _choose_time(table, rate)
    if signal_col is not None:
        signal_index = _resolve_column(table, signal_col, "signal")
        others = []
    else:
        signal_index, others = _choose_signal(table, time_index, ignored)
        if signal_index is None:
            if table.sample.shape[1] == 1 or time_index is None:
                raise InputError(f"no signal column found in {name} (columns: "
                                 f"{', '.join(table.names)}). Use --signal-col.")
            raise InputError(f"no varying signal column in {name} besides the time "
                             f"{_describe(table, time_index)}; columns are: "
                             f"{', '.join(table.names)}. Use --signal-col.")
    if time_index is not None and time_index == signal_index:
        raise UsageError(f"the time and the signal are the same column "
                         f"{_describe(table, signal_index)} of {name}. Use --time-col and "
                         "--signal-col with different columns.")
    if time_index is None and rate is None:
        raise InputError(f"no time column found in {name} (no column increases steadily). "
                         "Name it with --time-col or give the sample rate with --rate HZ.")

    indices = [signal_index] if time_index is None else [time_index, signal_index]
    columns = _read_columns(table, indices)
    x = columns[-1]
    t = columns[0] if time_index is not None else None

    # Side-by-side runs: shorter runs are padded with empty cells at the end.
    present = np.isfinite(x) if t is None else np.isfinite(t)
    last = np.flatnonzero(present)
    if last.size == 0:
        what = "signal" if t is None else "time"
        column = signal_index if t is None else time_index
        raise InputError(f"the {what} column {_describe(table, column)} of {name} holds no "
                         "numbers. Choose another column with --time-col/--signal-col.")
    end = last[-1] + 1
    if end < x.size:
        notes.append(f"{x.size - end} empty trailing rows dropped (padding)")
        x = x[:end]
        t = None if t is None else t[:end]
    if t is not None:
        missing_t = ~np.isfinite(t)
        if missing_t.any():
            notes.append(f"{int(missing_t.sum())} rows without a time value dropped")
            t, x = t[~missing_t], x[~missing_t]
    if not np.isfinite(x).any():
        raise InputError(f"the signal column {_describe(table, signal_index)} of {name} holds "
                         "no numbers (all empty or NaN). Choose the signal with --signal-col.")
    finite_x = x[np.isfinite(x)]
    if np.ptp(finite_x) == 0:
        raise InputError(f"the signal column {_describe(table, signal_index)} of {name} is "
                         f"constant ({finite_x[0]:g}). Choose the signal with --signal-col.")
    # Trailing NaN in the signal alone (a shorter run sharing the time column).
    last_x = np.flatnonzero(np.isfinite(x))[-1] + 1
    if last_x < x.size:
        notes.append(f"{x.size - last_x} trailing rows without a signal value dropped")
        x = x[:last_x]
        t = None if t is None else t[:last_x]

    time_unit = _base_name(table.names[time_index])[1] if time_index is not None else "s"
    signal_unit = _base_name(table.names[signal_index])[1]
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
        detected_kind = _detect_kind(t, x)
    chosen_kind = kind or detected_kind
    if kind is None and detected_kind == "turning-points":
        notes.append("read as a table of turning points (override with --input waveform)")

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
        steps = np.diff(t)
        if not np.all(steps > 0):
            problem = _timestamp_problem(t)
            where = int(np.flatnonzero(~(steps > 0))[0]) + 1
            if problem:
                raise InputError(f"the time column {_describe(table, time_index)} of {name} is "
                                 f"unusable: {problem}. Give the sample rate with --rate HZ.")
            raise InputError(f"the time column {_describe(table, time_index)} of {name} does "
                             f"not increase (data row {where + 1}: {t[where - 1]:g} then "
                             f"{t[where]:g}). Sort the file, choose another column with "
                             "--time-col, or use --rate HZ.")
        problem = _timestamp_problem(t)
        if problem:
            notes.append(f"irregular timestamps: {problem}; if the logger stamps samples in "
                         "bursts, use --rate HZ")
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
            notes.append("time column read as cycle number n (override with --domain time)")

    if time_index is not None and time_col is None:
        notes.append(f"time column: {_describe(table, time_index)} (chosen automatically; "
                     "use --time-col to change)")
    if signal_col is None:
        other = ""
        if others:
            other = "; other candidates: " + ", ".join(_describe(table, i) for i in others)
        notes.append(f"signal column: {_describe(table, signal_index)} (chosen automatically; "
                     f"use --signal-col to change{other})")

    if domain == "time" and time_unit is not None:
        seconds = _SECONDS_PER_UNIT.get(time_unit.strip().lower().replace("μ", "u").replace("µ", "u"))
        if seconds is None:
            notes.append(f"time unit '{time_unit}' not recognised: coefficients are per "
                         f"{time_unit}, not per second")
        elif seconds != 1.0:
            t = t * seconds
            notes.append(f"time converted from {time_unit} to seconds")
            time_unit = "s"

    t = np.ascontiguousarray(t, dtype=np.float64)
    x = np.ascontiguousarray(x, dtype=np.float64)
    t.setflags(write=False)
    x.setflags(write=False)
    return Record(source=name, t=t, x=x, kind=chosen_kind, domain=domain,
                  time_column=time_label, signal_column=table.names[signal_index],
                  time_unit=time_unit, signal_unit=signal_unit,
                  columns=tuple(table.names), notes=tuple(notes))
