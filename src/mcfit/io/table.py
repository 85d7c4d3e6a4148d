"""Delimited text to a table of columns: header, separator and a pandas reader of chosen columns.

Text that is more than a header line over numbers is first rewritten by
:mod:`mcfit.io.tidying`, so every source meets the same parser and checks.
"""

from __future__ import annotations

import io
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from mcfit.errors import InputError
from mcfit.io.decoding import _binary_problem, _decode, _drop_trailing_nul, _read_whole
from mcfit.io.layouts import recognised_layout
from mcfit.io.sniffing import (_header_names, _holds_numbers, _is_prose, _numeric_lines,
                               _sniff_separator)
from mcfit.io.tidying import _content_lines, _tidy_text
from mcfit.io.tokens import _CLOCK, _ISO_DATE_TIME, _MAX_ROWS_AS_DATA, _is_number, _shown, _split

# Bytes sniffed to choose separator, decimal mark, header and columns.
_SNIFF_BYTES = 1 << 20
# Lines of data parsed as the sample that guides the choice of columns.
_SAMPLE_LINES = 20000
# Line breaks of str.splitlines that pandas' parser does not break lines at.
_PYTHON_ONLY_LINE_BREAKS = ("\x0b", "\x0c", "\x1c", "\x1d", "\x1e", "\x85", "\u2028", "\u2029")


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
        self.rate = None          # the sample rate a file gives (WAV audio), in Hz
        self.loudest = None       # the channel that swings most, of a multi-channel file
        self.origins = {}         # 0-based clock-time columns -> their first clock reading


def _text_table(name, head, path, tail=b"", tidied=None):
    """A :class:`_Table` for delimited text: ``head`` is the file's first bytes (all of it
    when ``path`` is None) and ``tail`` its last; ``tidied`` is (names present, notes, clock
    columns, transposed) for text already rewritten by :func:`_tidy_text`."""
    source = _decoded(name, head, path, tail, tidied is None)
    if tidied is None:
        table = _rewritten_table(source)
        if table is not None:
            return table
        return _plain_table(source, None, source.notes, [], False)
    return _plain_table(source, *tidied)


@dataclass
class _Text:
    """A record's text as decoded, and where it came from: ``path`` is None once ``head``
    holds the whole file, else ``head`` holds its first bytes and ``tail`` its last."""

    name: str
    head: bytes
    path: object
    tail: bytes
    text: str = ""
    encoding: str = "utf-8"
    exact: bool = True  # every byte decoded as pandas will decode it
    notes: list = field(default_factory=list)
    lines: list = field(default_factory=list)

    @property
    def cut(self):
        """Whether ``head`` is only the first part of the file."""
        return self.path is not None and len(self.head) == _SNIFF_BYTES

    def decode(self):
        """Decode ``head``; returns the note on its encoding, or None."""
        self.text, self.encoding, note, self.exact = _decode(self.head)
        return note

    def read_whole(self):
        self.head, self.path, self.tail = _read_whole(self.name, self.path), None, b""


def _decoded(name, head, path, tail, drop_nul):
    """The :class:`_Text` of a record, its ``lines`` split; the whole file is read when its
    first megabyte holds no data. Refuses empty and binary files."""
    source = _Text(name, head, path, tail)
    if source.cut and head.isspace():
        source.read_whole()  # the data start further on
    if not source.head or source.head.isspace():  # as strip() == b"", without a copy
        raise InputError(f"{name} is empty. Give a file with a time and a signal column.")
    note = source.decode()
    source.notes = [note] if note else []
    if drop_nul and (source.text.endswith("\x00") or source.tail.endswith(b"\x00")):
        if source.path is not None and source.tail:
            source.read_whole()
            source.decode()
        text, nul_note = _drop_trailing_nul(source.text)
        if nul_note:
            source.notes.append(nul_note)
            source.head, source.path, source.text = text.encode("utf-8"), None, text
            source.encoding, source.exact = "utf-8", True
    problem = _binary_problem(source.text)
    if problem is not None:
        raise InputError(f"{name} is not a text record: it holds binary data ({problem}). "
                         "Give a CSV, TSV or text export of the data (an Excel workbook must "
                         "end in .xlsx).")
    source.lines = source.text.splitlines()
    if source.cut and source.lines:
        # A few very long lines (data written in rows), or no data yet: read it all.
        if len(source.lines) <= _MAX_ROWS_AS_DATA or not _holds_numbers(source.lines[:-1]):
            source.read_whole()
            source.decode()
            source.lines = source.text.splitlines()
        else:
            source.lines = source.lines[:-1]  # the last line may be cut by the sniff limit
    return source


def _rewritten_table(source):
    """The table of text that an export layout or the tidying step rewrites, else None;
    prose is refused."""
    name, lines = source.name, source.lines
    if not source.cut and _is_prose(lines):
        numeric, content, _ = _numeric_lines(lines)
        raise InputError(f"{name} is not a table of numbers: {numeric} of its {content} lines "
                         "are numbers (it reads as prose or markup). Give a CSV or text export "
                         "with a time and a signal column.")
    rewritten = _rewritten_layout(source)
    if rewritten is not None:
        table = _text_table(name, rewritten[0], None)
        table.notes[:0] = source.notes + rewritten[1]
        return table
    tail_lines = []
    if source.tail and not source.encoding.startswith("utf-16"):
        tail_lines = source.tail.decode(source.encoding, errors="replace").splitlines()[1:]
    tidy = _tidy_text(name, lines, tail_lines)
    if tidy is not None and source.cut:
        whole, _, _, _ = _decode(_read_whole(name, source.path))
        tidy = _tidy_text(name, whole.splitlines(), [])
    if tidy is None:
        return None
    tidy_text, tidy_notes, clock, transposed, has_names = tidy
    return _text_table(name, tidy_text.encode("utf-8"), None,
                       tidied=(has_names, source.notes + tidy_notes, clock, transposed))


def _plain_table(source, has_names, notes, clock, transposed):
    """The table of text that is at most a header line over rows (``has_names`` None: the
    separator and header are sniffed; else tab-separated, as the tidying step writes)."""
    name, lines = source.name, source.lines
    content, comment_chars = _first_content_lines(lines)
    if not content:
        raise InputError(f"{name} holds only comments or blank lines. Give a file with data rows.")
    if has_names is None:
        sep, decimal = _sniff_separator([line for _, line in content[:50]])
        first_fields = _split(content[0][1], sep)
        has_names = not all(_is_number(f) or f == "" for f in first_fields)
    else:  # one tab-separated header line (if any) and numbers with decimal points
        sep, decimal = "\t", "."
    if has_names:
        names = _header_names(content[0][1], sep, content[1:])
        if len(content) < 2:
            raise InputError(f"{name} has a header row but no data rows. Give a file with "
                             "data below the header.")
        data_start = content[1][0]
    else:
        ncols = max(len(_split(line, sep)) for _, line in content[:50])
        names = [f"column {i + 1}" for i in range(ncols)]
        data_start = content[0][0]
    if decimal == ",":
        notes.append("decimal commas read as decimal points")
    if comment_chars:
        notes.append("comment lines starting with " + " or ".join(sorted(comment_chars))
                     + " skipped")
    # "#" starts a comment even where none was seen: a note may follow the sniffed lines.
    comment = "%" if comment_chars == {"%"} else "#"
    other_comment = "%" if comment == "#" and "%" in comment_chars else None
    reader = _column_reader(source, sep, decimal, data_start, comment, other_comment)
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
    whole = not source.cut and len(lines) - data_start <= _SAMPLE_LINES
    complete = (whole and plain and source.exact and other_comment is None
                and sample.shape[0] > 0 and not np.isnan(sample.iat[0, -1])
                and _lines_alike(source.text, lines[:data_start], sample_text))
    table = _Table(name, names, sample, reader, notes, complete=complete)
    table.clock, table.transposed, table.decimal = list(clock), transposed, decimal
    table.origins = clock if isinstance(clock, dict) else {}
    table.token_lines, table.sep = lines[data_start:data_start + 2000], sep
    return table


def _first_content_lines(lines):
    """([(line number, stripped line)] of the first 200 lines that are neither blank nor
    comments, the comment characters seen)."""
    comment_chars = set()
    return _content_lines(enumerate(lines), 200, comment_chars), comment_chars


def _column_reader(source, sep, decimal, data_start, comment, other_comment):
    """``reader(indices, nrows=None, as_text=False)``: the chosen 0-based columns of the
    data rows as a DataFrame, in the order asked, by pandas' C parser."""
    def reader(indices, nrows=None, as_text=False):
        kwargs = dict(
            sep=r"\s+" if sep is None else sep, decimal=decimal, header=None,
            skiprows=_skip_rows(data_start, source.lines, other_comment),
            usecols=list(indices), comment=comment, skip_blank_lines=True,
            encoding=source.encoding, engine="c", nrows=nrows, quotechar='"',
            skipinitialspace=sep is not None,
        )
        if as_text:
            kwargs["dtype"] = str
            kwargs["keep_default_na"] = False
        else:
            kwargs["dtype"] = np.float64
        if sep is None:
            kwargs.pop("skipinitialspace")
        data = io.BytesIO(source.head) if source.path is None else source.path
        frame = pd.read_csv(data, **kwargs)
        # usecols gives the columns in file order; the time column may follow the signal.
        return frame.iloc[:, [sorted(indices).index(index) for index in indices]]
    return reader


def _rewritten_layout(source):
    """(utf-8 text, notes) for an export layout that :data:`LAYOUTS` rewrites, else None."""
    layout = recognised_layout(source.lines)
    if layout is None or layout.rewrite is None:
        return None
    lines = source.lines
    if source.cut:
        lines = _decode(_read_whole(source.name, source.path))[0].splitlines()
    rewritten = layout.rewrite(lines)
    if rewritten is None:
        return None
    return ("\n".join(rewritten[0]) + "\n").encode("utf-8"), rewritten[1]


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


def _numeric_frame(frame, decimal):
    out = {}
    for column in frame.columns:
        values = frame[column].astype(str).str.strip()
        if decimal == ",":
            values = values.str.replace(",", ".", regex=False)
        out[column] = pd.to_numeric(values.replace("", np.nan), errors="coerce")
    return pd.DataFrame(out, dtype=np.float64)


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
                    f"'{_shown(values.iloc[row])}' in the clock-time column "
                    f"{_describe(table, index)} of {table.name} (data row {row + 1}) is not a "
                    f"clock time like the others ('{first}'). Fix or delete that row, or "
                    "choose another time column with `time_col` or give `rate=HZ`.") from None
            if bad.any():
                row = int(np.flatnonzero(bad.values)[0])
                raise InputError(
                    f"text '{_shown(values.iloc[row])}' in numeric column "
                    f"{_describe(table, index)} of {table.name} (data row {row + 1}). Fix or "
                    "delete that row, or start it with # to make it a comment.") from None
        columns = ", ".join(_describe(table, index) for index in indices)
        raise InputError(f"cannot read the columns {columns} of {table.name} as numbers "
                         f"({str(exc).splitlines()[0]}). Check that every row has the same "
                         "number of columns.") from None
    return [frame.iloc[:, position].to_numpy(dtype=np.float64, copy=False)
            for position in range(len(indices))]
