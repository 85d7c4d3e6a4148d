"""What ``mcfit bench`` prints about itself: tables whose columns stay apart, and one
description of the quick and full grids in the help and the README."""

import re
from pathlib import Path

from click.testing import CliRunner

from mcfit.cli import cli

README = Path(__file__).parents[1] / "README.md"


def test_the_fitting_table_keeps_negative_and_long_values_apart():
    """Every row splits into as many fields as the header has columns, whatever the
    signs and widths of the values (a bias of -0.00052 after an RMSE of 1.52)."""
    from mcfit.bench.accuracy import FitCell, format_fitting
    from mcfit.bench.config import QUICK

    scene = QUICK.fit_scenes[0]
    letters = scene.model
    huge = {k: -1.234e-05 for k in letters}
    cell = FitCell(scene.name, 1e3, 20.25, "mcfit", {k: 1.5e-3 for k in letters},
                   {k: 1.52 for k in letters}, {k: -0.00052 for k in letters}, huge,
                   12.5, 8, 0, 7)
    lines = format_fitting([cell], QUICK).splitlines()
    head, row = lines[-2], lines[-1]
    columns = 3 + 4 * len(letters) + 3  # SNR, spc, method; four per letter; ms, failed, ok
    assert len(row.split()) == columns
    assert len(head.replace("model ok", "model_ok").split()) == columns + 4 * len(letters)
    assert " -0.00052" in row and " 1.52 " in row


def test_the_full_grid_is_described_alike_in_the_help_and_the_readme():
    """--full: about an hour (BENCHMARKS.md: the methods section alone 37.5 minutes);
    plots come from --output-dir with either grid, not from --full."""
    text = CliRunner().invoke(cli, ["bench", "--help"], terminal_width=200).output
    flat = " ".join(text.split())
    assert "(minutes)" not in flat
    assert re.search(r"--full\s+Run the whole grid \(about an hour\)", flat)
    assert "--full runs the whole grid" in flat and "about an hour" in flat
    readme = README.read_text()
    lines = [line for line in readme.splitlines() if line.startswith("mcfit bench")]
    assert not any("--full for plots" in line for line in lines)
    assert any("--full" in line and "about an hour" in line for line in lines)
