"""Rewriting an export as one header line over tab-separated numbers.

Exports from loggers and lab software wrap the numbers in more than a header line: header
blocks, separator lines, a units row, repeated headers, notes at the end, Fortran D
exponents, clock times, data written in rows. The layout of such a file is found by
:mod:`mcfit.io.sniffing` and the file rewritten here, then read by the plain reader; a
plain file is left as it is.
"""

from __future__ import annotations

import re

from mcfit.io.sniffing import (_LAYOUT_LINES, _Layout, _MIN_VALUES_IN_A_ROW, _classify_line,
                               _find_layout, _header_fields, _is_note, _layout_is_plain,
                               _surely_plain, _token_kind)
from mcfit.io.clocks import text_clock_origin
from mcfit.io.tokens import (_CLOCK, _DATE, _FORTRAN_EXPONENT, _ISO_DATE_TIME, _KNOWN_UNITS,
                             _MAX_ROWS_AS_DATA, _NUMBER_TOKEN, _SPECIAL_TOKENS, _base_name, _count,
                             _is_time_name)

# A units row: short tokens such as s, m, V, m/s^2, deg, rad, (s), [mm].
_UNIT_TOKEN = re.compile(r"^[\(\[]?[A-Za-zµμ°%Ω][A-Za-z0-9µμ°%Ω/^*·.\- ]{0,9}[\)\]]?$")


def _content_lines(numbered, limit, comment_chars):
    """[(line number, stripped line)] of the first ``limit`` of ``numbered`` that are
    neither blank nor comments; the comment characters seen are added to
    ``comment_chars``."""
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


def _tidy_text(name, lines, tail_lines=()):
    """(text, notes, clock_columns, transposed) or None when the plain reader suffices.

    ``text`` is the record rewritten as an optional tab-separated header line and
    tab-separated numbers with decimal points.
    """
    comment_chars = set()

    def content_lines(numbered, limit):
        return _content_lines(numbered, limit, comment_chars)

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


def _is_units_row(fields, width):
    tokens = [f.strip("()[] ") for f in fields if f]
    return (len(fields) <= width and len(tokens) >= max(1, width - 1)
            and all(_UNIT_TOKEN.match(f) and len(f) <= 10 for f in tokens)
            and any(f.lower().replace("µ", "u").replace("μ", "u") in _KNOWN_UNITS
                    for f in tokens))


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
    _join_dates(columns, names, notes)
    clock = {}
    for k, column in enumerate(columns):
        if any(_CLOCK.match(v) or _ISO_DATE_TIME.match(v) for v in column[:50]):
            seconds, first = _clock_seconds(column)
            if seconds is not None:
                columns[k] = seconds
                label = (names[k] if names and names[k] else f"column {k + 1}")
                clock[k] = text_clock_origin(first, label)
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


def _join_dates(columns, names, notes):
    """A column of dates before one of times of day: each time gets its date (a clock
    that passes midnight stays right), and the dates are left out of the numbers."""
    for k in range(len(columns) - 1):
        dates, times = columns[k], columns[k + 1]
        if not (any(_DATE.match(v) for v in dates[:50])
                and all(not v or _DATE.match(v) for v in dates)
                and all(not v or _CLOCK.match(v) for v in times)):
            continue
        columns[k + 1] = [f"{d.replace('/', '-').replace('.', '-')}T{v}" if d and v else v
                          for d, v in zip(dates, times)]
        columns[k] = [""] * len(dates)
        label = names[k] if names and names[k] else f"column {k + 1}"
        notes.append(f"dates in '{label}' joined to the times of day after them")


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
