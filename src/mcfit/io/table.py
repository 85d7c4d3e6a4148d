"""Delimited text to a table of columns: header, separator and a pandas reader of chosen columns.

Text that is more than a header line over numbers is first rewritten by
:mod:`mcfit.io.tidying`, so every source meets the same parser and checks.
"""

from __future__ import annotations

import io
import warnings

import numpy as np
import pandas as pd

from mcfit.errors import InputError
from mcfit.io.decoding import _binary_problem, _decode, _drop_trailing_nul, _read_whole
from mcfit.io.layouts import recognised_layout
from mcfit.io.sniffing import (_header_names, _holds_numbers, _is_prose, _numeric_lines,
                               _sniff_separator)
from mcfit.io.tidying import _tidy_text
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


def _text_table(name, head, path, tail=b"", tidied=None):
    """A :class:`_Table` for delimited text; ``tidied`` is (names present, notes, clock
    columns, transposed) for text already rewritten by :func:`_tidy_text`."""
    if path is not None and len(head) == _SNIFF_BYTES and head.isspace():
        head, path, tail = _read_whole(name, path), None, b""  # the data start further on
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
        # A few very long lines (data written in rows), or no data yet: read it all.
        if len(lines) <= _MAX_ROWS_AS_DATA or not _holds_numbers(lines[:-1]):
            head, path, tail = _read_whole(name, path), None, b""
            text, encoding, enc_note, exact_text = _decode(head)
            lines = text.splitlines()
        else:
            lines = lines[:-1]  # the last line may be cut by the sniff limit
    if tidied is None and (path is None or len(head) < _SNIFF_BYTES) and _is_prose(lines):
        numeric, content, _ = _numeric_lines(lines)
        raise InputError(f"{name} is not a table of numbers: {numeric} of its {content} lines "
                         "are numbers (it reads as prose or markup). Give a CSV or text export "
                         "with a time and a signal column.")
    if tidied is None:
        rewritten = _rewritten_layout(name, lines, path, tail or len(head) == _SNIFF_BYTES)
        if rewritten is not None:
            table = _text_table(name, rewritten[0], None)
            table.notes[:0] = notes + rewritten[1]
            return table
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
    # "#" starts a comment even where none was seen: a note may follow the sniffed lines.
    comment = "%" if comment_chars == {"%"} else "#"
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


def _rewritten_layout(name, lines, path, cut):
    """(utf-8 text, notes) for an export layout that :data:`LAYOUTS` rewrites, else None;
    ``cut`` says that ``lines`` are the first of a longer file at ``path``."""
    layout = recognised_layout(lines)
    if layout is None or layout.rewrite is None:
        return None
    if path is not None and cut:
        lines = _decode(_read_whole(name, path))[0].splitlines()
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
