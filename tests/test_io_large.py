"""Files whose data start past the first megabyte, odd tables, and limits on hostile files.

Hostile files run in a subprocess with a watchdog (a timeout) and report their own peak
memory, so that a reader that grew without bound fails the test instead of the machine.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from mcfit.errors import InputError, UsageError
from mcfit.io import read_record

T = np.round(np.arange(0, 20, 0.05), 4).tolist()
X = np.round(np.exp(-0.1 * np.array(T)) * np.cos(2 * np.pi * np.array(T)), 6).tolist()
ROWS = "t,x\n" + "".join(f"{t!r},{x!r}\n" for t, x in zip(T, X))
WATCHDOG = 120  # s: a run past this is stuck, not slow
PEAK_MB = 500  # a run that reads what it refuses would pass 1000 MB


def check(record):
    np.testing.assert_array_equal(record.t, T)
    np.testing.assert_array_equal(record.x, X)


@pytest.mark.parametrize("above", [
    "".join(f"# logger comment line {k}, settings and calibration\n" for k in range(40000)),
    "".join(f"Setting {k}: {k % 7}\n" for k in range(100000)),
    "\n" * 1_200_000,
    " " * 1_100_000 + "\n",
], ids=["comments", "settings", "blank lines", "a line of spaces"])
def test_data_that_start_past_the_first_megabyte(tmp_path, above):
    assert len(above) > 1 << 20
    path = tmp_path / "late.csv"
    path.write_text(above + ROWS)
    check(read_record(path))


@pytest.mark.parametrize("where", [50, len(T)])
def test_a_comment_line_of_a_megabyte_and_more_among_the_rows(tmp_path, where):
    lines = ROWS.splitlines(keepends=True)
    lines.insert(where + 1, "#" + "note " * 260_000 + "\n")
    path = tmp_path / "noted.csv"
    path.write_text("".join(lines))
    check(read_record(path))


@pytest.mark.parametrize("table", [
    "| t | x |\n|---|:---:|\n" + "".join(f"| {t!r} | {x!r} |\n" for t, x in zip(T, X)),
    "|t|x|\n" + "".join(f"|{t!r}|{x!r}|\n" for t, x in zip(T, X)),
], ids=["spaced, with an alignment row", "tight"])
def test_a_markdown_pipe_table(tmp_path, table):
    path = tmp_path / "table.md"
    path.write_text(table)
    record = read_record(path)
    check(record)
    assert "markdown pipe table: cells read between the | marks" in record.notes


def test_a_column_name_held_twice_is_ambiguous(tmp_path):
    path = tmp_path / "twice.csv"
    path.write_text("t,x,x\n" + "".join(f"{t!r},{x!r},{-x!r}\n" for t, x in zip(T, X)))
    with pytest.raises(UsageError, match=r"column 'x' is ambiguous in .*twice.csv: columns 2 "
                                         r"and 3 are named 'x'. Use `signal_col` with a "
                                         r"1-based index."):
        read_record(path, signal_col="x")
    check(read_record(path, signal_col=2))


# The child reads with mcfit and prints its exit code, its stderr's last line and its
# peak memory as JSON.
_CHILD = """
import contextlib, io, json, resource, sys
from mcfit.cli import main
err = io.StringIO()
with contextlib.redirect_stderr(err):
    try:
        main(sys.argv[1:])
        code = 0
    except SystemExit as exc:
        code = exc.code
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
try:  # Linux: this process's own peak (ru_maxrss keeps the parent's from before exec)
    with open("/proc/self/status") as status:
        peak = next(int(row.split()[1]) for row in status if row.startswith("VmHWM")) / 1024
except (OSError, StopIteration):
    pass
print(json.dumps({"code": code, "err": err.getvalue().strip().splitlines()[-1:], "peak": peak}))
"""


def _run_bounded(args, stdin=subprocess.DEVNULL):
    done = subprocess.run([sys.executable, "-c", _CHILD, *args], stdin=stdin,
                          capture_output=True, text=True, timeout=WATCHDOG)
    assert done.returncode == 0, done.stderr
    result = json.loads(done.stdout.splitlines()[-1])
    assert result["peak"] < PEAK_MB, result
    return result


def test_a_sparse_file_of_2_gb_is_refused_at_once(tmp_path):
    path = tmp_path / "s.csv"
    with open(path, "wb") as handle:
        handle.truncate(2 << 30)  # sparse: no disk is used
    result = _run_bounded([str(path)])
    assert result["code"] == 1
    assert result["err"] == [f"Error: {path} is not read: the file (2 GiB or more) passes "
                             "the 1 GiB that no record reaches. Check that it is the record, "
                             "or cut it into parts."]


def test_a_csv_padded_with_nul_bytes_to_2_gb_is_refused(tmp_path):
    path = tmp_path / "padded.csv"
    path.write_text(ROWS)
    with open(path, "r+b") as handle:
        handle.truncate(2 << 30)
    result = _run_bounded([str(path)])
    assert result["code"] == 1
    assert "the file (2 GiB or more) passes the 1 GiB" in result["err"][0]


def test_endless_nul_bytes_on_stdin_are_refused():
    with open("/dev/zero", "rb") as zero:
        result = _run_bounded(["-"], stdin=zero)
    assert result["code"] == 1
    assert result["err"] == ["Error: <stdin> is not a text record: it starts with a megabyte "
                             "of NUL bytes. Give a CSV, TSV or text export of the data."]


def test_a_closed_stdin_is_one_line(tmp_path):
    code = ("import sys; sys.stdin.close(); sys.stdin = None\n"
            "from mcfit.io import read_record\n"
            "from mcfit.errors import InputError\n"
            "try:\n    read_record('-')\nexcept InputError as exc:\n    print(exc)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=WATCHDOG)
    assert done.stdout.startswith("standard input is closed, so - cannot be read.")


def _workbook(path, empty_sheets=0):
    openpyxl = pytest.importorskip("openpyxl")
    book = openpyxl.Workbook(write_only=True)
    for k in range(empty_sheets):
        book.create_sheet(f"empty {k}")
    sheet = book.create_sheet("data")
    sheet.append(["t", "x"])
    for t, x in zip(T, X):
        sheet.append([t, x])
    book.save(path)
    return path


def _minimal_xlsx(path, text="a note", empty_sheets=0):
    """A minimal .xlsx: ``empty_sheets`` empty sheets, then a sheet holding the rows and,
    in C1, ``text`` as a shared string (as Excel stores text; openpyxl writes no string
    past Excel's 32,767 characters, and writes 10,000 sheets slowly)."""
    import zipfile
    main = "http://schemas.openxmlformats.org/spreadsheetml/2006/main"
    rel = "http://schemas.openxmlformats.org/officeDocument/2006/relationships"
    kinds = "application/vnd.openxmlformats-officedocument.spreadsheetml"
    rows = ['<row r="1"><c r="A1" t="inlineStr"><is><t>t</t></is></c><c r="B1" t="inlineStr">'
            '<is><t>x</t></is></c><c r="C1" t="s"><v>0</v></c></row>']
    rows += [f'<row r="{i + 2}"><c r="A{i + 2}"><v>{t!r}</v></c><c r="B{i + 2}"><v>{x!r}</v>'
             '</c></row>' for i, (t, x) in enumerate(zip(T, X))]
    sheets = [f'<worksheet xmlns="{main}"><sheetData/></worksheet>'] * empty_sheets
    sheets.append(f'<worksheet xmlns="{main}"><sheetData>{"".join(rows)}</sheetData></worksheet>')
    names = [f"empty {k}" for k in range(empty_sheets)] + ["data"]
    parts = {
        "[Content_Types].xml": (
            '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
            '<Default Extension="rels" ContentType="application/vnd.openxmlformats-package.'
            'relationships+xml"/><Default Extension="xml" ContentType="application/xml"/>'
            f'<Override PartName="/xl/workbook.xml" ContentType="{kinds}.sheet.main+xml"/>'
            + "".join(f'<Override PartName="/xl/worksheets/sheet{k + 1}.xml" '
                      f'ContentType="{kinds}.worksheet+xml"/>' for k in range(len(sheets)))
            + f'<Override PartName="/xl/sharedStrings.xml" ContentType="{kinds}.'
            'sharedStrings+xml"/></Types>'),
        "_rels/.rels": (
            '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/'
            f'relationships"><Relationship Id="rId1" Type="{rel}/officeDocument" '
            'Target="xl/workbook.xml"/></Relationships>'),
        "xl/workbook.xml": (
            f'<workbook xmlns="{main}" xmlns:r="{rel}"><sheets>'
            + "".join(f'<sheet name="{name}" sheetId="{k + 1}" r:id="rId{k + 1}"/>'
                      for k, name in enumerate(names)) + "</sheets></workbook>"),
        "xl/_rels/workbook.xml.rels": (
            '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/'
            'relationships">'
            + "".join(f'<Relationship Id="rId{k + 1}" Type="{rel}/worksheet" '
                      f'Target="worksheets/sheet{k + 1}.xml"/>' for k in range(len(sheets)))
            + f'<Relationship Id="rId0" Type="{rel}/sharedStrings" '
            'Target="sharedStrings.xml"/></Relationships>'),
        "xl/sharedStrings.xml": (
            f'<sst xmlns="{main}" count="1" uniqueCount="1"><si><t>{text}</t></si></sst>'),
    }
    parts.update({f"xl/worksheets/sheet{k + 1}.xml": sheet for k, sheet in enumerate(sheets)})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, content in parts.items():
            archive.writestr(name, content)
    return path


def test_a_small_shared_string_workbook_reads(tmp_path):
    check(read_record(_minimal_xlsx(tmp_path / "note.xlsx")))
    record = read_record(_minimal_xlsx(tmp_path / "later.xlsx", empty_sheets=3))
    check(record)
    assert "the first sheet, 'empty 0', holds no data" in record.notes


def test_a_huge_shared_string_is_refused_before_it_is_read(tmp_path):
    path = _minimal_xlsx(tmp_path / "string.xlsx", "y" * (40 << 20))
    assert os.path.getsize(path) < 1 << 20  # it compresses to almost nothing
    result = _run_bounded([str(path)])
    assert result["code"] == 1
    assert result["err"][0].startswith(f"Error: {path} is not read: the text of its cells "
                                       "(40 MiB or more) passes the 32 MiB")


def test_ten_thousand_empty_sheets_are_refused_in_one_line(tmp_path):
    path = _minimal_xlsx(tmp_path / "sheets.xlsx", empty_sheets=10_000)
    result = _run_bounded([str(path)])
    assert result["code"] == 1
    assert result["err"] == [f"Error: {path} is not read: it holds 10001 sheets, past the "
                             "1000 that no record reaches. Copy the sheet with the data to a "
                             "workbook of its own, or export it as CSV."]


def test_sheets_past_the_limit_are_refused(tmp_path, monkeypatch):
    monkeypatch.setattr("mcfit.io.excel.MAX_SHEETS", 5)
    path = _workbook(tmp_path / "sheets.xlsx", empty_sheets=5)
    with pytest.raises(InputError, match=r"sheets.xlsx is not read: it holds 6 sheets, past "
                                         r"the 5 that no record reaches."):
        read_record(path)


def test_empty_sheets_before_the_data_are_not_each_parsed(tmp_path, monkeypatch):
    # pandas parsed every sheet until one held numbers: a minute for 10,000 empty sheets.
    import mcfit.io.excel as excel
    parsed = []
    read_sheet = excel._read_sheet
    monkeypatch.setattr(excel, "_read_sheet",
                        lambda *args: parsed.append(args[1]) or read_sheet(*args))
    record = read_record(_workbook(tmp_path / "many.xlsx", empty_sheets=300))
    check(record)
    assert parsed == ["data"]
    assert "the first sheet, 'empty 0', holds no data" in record.notes


def test_cells_past_the_limit_are_refused_before_they_are_read(tmp_path, monkeypatch):
    monkeypatch.setattr("mcfit.io.excel.MAX_SHEET_BYTES", 10_000)
    path = _workbook(tmp_path / "cells.xlsx")  # about 30 kB of sheet XML
    with pytest.raises(InputError, match=r"cells.xlsx is not read: the cell data of its sheets "
                                         r"\(0.0\d+ MiB or more\) passes the 0.00954 MiB"):
        read_record(path)


def test_sheets_past_the_limit_are_refused_in_legacy_xls(tmp_path, monkeypatch):
    xlwt = pytest.importorskip("xlwt")
    monkeypatch.setattr("mcfit.io.excel.MAX_SHEETS", 2)
    book = xlwt.Workbook()
    for k in range(3):
        book.add_sheet(f"s{k}").write(0, 0, 1.0)
    book.save(str(tmp_path / "old.xls"))
    with pytest.raises(InputError, match=r"old.xls is not read: it holds 3 sheets, past the 2"):
        read_record(tmp_path / "old.xls")


def test_the_cells_of_an_ods_count_too(tmp_path, monkeypatch):
    pytest.importorskip("odf")
    import pandas as pd
    path = tmp_path / "run.ods"
    pd.DataFrame({"t": T, "x": X}).to_excel(path, index=False, engine="odf")
    check(read_record(path))
    monkeypatch.setattr("mcfit.io.excel.MAX_SHEET_BYTES", 1000)
    with pytest.raises(InputError, match=r"run.ods is not read: the cell data of its sheets"):
        read_record(path)


def test_without_calamine_the_data_sheet_is_found_by_parsing(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "python_calamine", None)
    record = read_record(_workbook(tmp_path / "later.xlsx", empty_sheets=3))
    check(record)
    assert "the first sheet, 'empty 0', holds no data" in record.notes
