"""Workbooks (``.xlsx``, ``.xlsm``, ``.xls``, ``.ods``): the sheet holding the data, as text."""

from __future__ import annotations

import numpy as np
import pandas as pd

from mcfit.errors import InputError, UsageError
from mcfit.io.limits import (MAX_SHARED_STRING_BYTES, MAX_SHEET_BYTES, MAX_SHEETS,
                             too_large)
from mcfit.io.table import _text_table
from mcfit.io.tokens import _is_number

# Workbook extensions: pandas engine and the package that provides it. Calamine reads the
# legacy .xls (pandas deprecates xlrd) and .ods (many times faster than odfpy).
_EXCEL_ENGINES = {".xlsx": ("openpyxl", "openpyxl"), ".xlsm": ("openpyxl", "openpyxl"),
                  ".xls": ("calamine", "python-calamine"), ".ods": ("calamine", "python-calamine")}


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
    if engine == "openpyxl" or suffix == ".ods":
        _check_workbook_parts(path, name)
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
        if len(book.sheet_names) > MAX_SHEETS:
            raise _too_many_sheets(name, len(book.sheet_names))
        if sheet is not None:
            sheet_name = _sheet_name(book.sheet_names, sheet, name)
            raw = _read_sheet(book, sheet_name, sheet)
        else:
            # A first sheet of notes: the data are on the first sheet that holds numbers.
            sheet_name = _first_sheet_with_numbers(path, book.sheet_names)
            if sheet_name is None:  # calamine refused the workbook: parse sheet by sheet
                sheet_name = next((n for n in book.sheet_names if _numeric_rows(
                    _read_sheet(book, n, sheet).itertuples(index=False, name=None)) >= 2),
                                  book.sheet_names[0])
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


def _numeric_rows(rows):
    """Rows (tuples of cells) with at least one number, date or time cell."""
    def numeric(v):
        return (not isinstance(v, (str, bool)) and not pd.isna(v)) if not isinstance(
            v, str) else _is_number(v)
    return sum(any(numeric(v) for v in row) for row in rows)


# Rows of each sheet looked at to find the first that holds data.
_SCAN_ROWS = 10000


def _first_sheet_with_numbers(path, sheet_names):
    """The first sheet with two rows holding a number in its first rows, else the first
    sheet; None when calamine cannot read the workbook. Calamine reads a sheet's first
    rows in microseconds, so that many sheets of notes or empty sheets cost little."""
    try:
        from python_calamine import CalamineWorkbook
        book = CalamineWorkbook.from_path(str(path))
        for sheet_name in sheet_names:
            if _numeric_rows(book.get_sheet_by_name(sheet_name).to_python(
                    nrows=_SCAN_ROWS)) >= 2:
                return sheet_name
    except Exception:  # ImportError, or calamine's errors on a workbook it cannot read
        return None
    return sheet_names[0]


def _check_workbook_parts(path, name):
    """Refuse a zip workbook whose sheet count, text or cells pass :mod:`mcfit.io.limits`
    (from the sizes its zip directory gives, before anything is decompressed)."""
    import zipfile
    try:
        with zipfile.ZipFile(path) as archive:
            parts = archive.infolist()
    except (zipfile.BadZipFile, OSError):
        return  # the engine says what is wrong
    # An .xlsx keeps a part per sheet; an .ods keeps every sheet in content.xml.
    sheets = [p for p in parts if p.filename == "content.xml" or (
        p.filename.startswith("xl/worksheets/") and p.filename.endswith(".xml"))]
    if len(sheets) > MAX_SHEETS:  # an .xlsx's: an .ods's are counted once it is open
        raise _too_many_sheets(name, len(sheets))
    strings = sum(p.file_size for p in parts if p.filename.lower() == "xl/sharedstrings.xml")
    if strings > MAX_SHARED_STRING_BYTES:
        raise too_large(name, "the text of its cells", strings, MAX_SHARED_STRING_BYTES)
    cells = sum(p.file_size for p in sheets)
    if cells > MAX_SHEET_BYTES:
        raise too_large(name, "the cell data of its sheets", cells, MAX_SHEET_BYTES)


def _too_many_sheets(name, count):
    return InputError(f"{name} is not read: it holds {count} sheets, past the {MAX_SHEETS} "
                      "that no record reaches. Copy the sheet with the data to a workbook of "
                      "its own, or export it as CSV.")


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
