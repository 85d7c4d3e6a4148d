"""Finding where the numbers are in a text file: separator, decimal mark, width, first line.

Each content line is classified (numbers, a rule of dashes, text); the separator and block of
numeric lines that explain the most lines win. A file whose block sits under one header line
with nothing odd in it is left to the plain reader (:func:`_layout_is_plain`).
"""

from __future__ import annotations

import re

from mcfit.io.tokens import (_CLOCK, _COMMA_DECIMAL, _DATE, _FORTRAN_EXPONENT, _ISO_DATE_TIME,
                             _MAX_ROWS_AS_DATA, _NUMBER_TOKEN, _SPECIAL_TOKENS, _is_number,
                             _split)


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


_DATE_SPACE_TIME = re.compile(r"(\d{4}-\d{2}-\d{2}) (\d{1,2}:\d{2})")
# A line of dashes, equals signs or stars (with separators between), as under a header.
_RULE_LINE = re.compile(r"^[\s\-=_*~+|,;:]*$")
_RULE_CHARACTERS = re.compile(r"[-=_*~]{3,}")
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
    if _CLOCK.match(token) or _ISO_DATE_TIME.match(token) or _DATE.match(token):
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


# One way only to match each number (no "\d+\.?\d*", whose digits split many ways): a
# line that fails late, at a date field, would otherwise backtrack exponentially.
_PLAIN_NUMBER = r"[-+]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][-+]?\d+)?"


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


# Text of at least this many lines, fewer than this share of them mostly numbers and no
# block of this many numeric lines in a row, is prose.
_PROSE_LINES = 10
_MIN_NUMERIC_SHARE = 0.1
_MIN_DATA_BLOCK = 5
_TOKEN_BREAK = re.compile(r"[\s,;|]+")


def _is_numeric_line(stripped):
    """Whether at least half the fields of a stripped content line are numbers or times."""
    tokens = [t.strip("\"'") for t in _TOKEN_BREAK.split(stripped) if t]
    return 2 * sum(1 for t in tokens if _token_kind(t, True) != "text") >= len(tokens)


def _numeric_flags(lines):
    """Whether each content line (not blank, not a comment) is mostly numbers."""
    for line in lines:
        stripped = line.strip()
        if stripped and stripped[0] not in "#%":
            yield _is_numeric_line(stripped)


def _numeric_lines(lines):
    """(lines mostly numbers, lines with content, longest block of numeric lines)."""
    numeric = content = block = longest = 0
    for is_numeric in _numeric_flags(lines):
        content += 1
        numeric += is_numeric
        block = block + 1 if is_numeric else 0
        longest = max(longest, block)
    return numeric, content, longest


def _holds_numbers(lines, at_least=2):
    """Whether ``at_least`` content lines are mostly numbers (stops when they are found)."""
    found = 0
    for is_numeric in _numeric_flags(lines):
        found += is_numeric
        if found >= at_least:
            return True
    return False


def _is_prose(lines):
    """Whether text is prose or markup rather than a table: lines of numbers are rare. It
    stops at the first block of numeric lines (a table: a CSV of 10^4 rows took 29 ms
    to read through, 8 times the rest of its reading)."""
    numeric = content = block = 0
    for is_numeric in _numeric_flags(lines):
        content += 1
        numeric += is_numeric
        block = block + 1 if is_numeric else 0
        if block >= _MIN_DATA_BLOCK:
            return False
    return content >= _PROSE_LINES and numeric < _MIN_NUMERIC_SHARE * content


