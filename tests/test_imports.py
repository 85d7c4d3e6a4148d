"""Import hygiene, checked once for every layer: the core imports no I/O, plotting or
command-line library, `mcfit --help` no numerical one (nor Dask), the package no pandas."""

import os
import subprocess
import sys

import pytest

HELP = "from mcfit.cli import main\ntry:\n    main({})\nexcept SystemExit:\n    pass\n"
NUMERICAL = ("numpy", "scipy", "pandas", "lmfit", "matplotlib", "dask", "distributed")
IO_AND_CLI = ("click", "pandas", "matplotlib")

CASES = [
    ("mcfit --help", HELP.format("['--help']"), NUMERICAL),
    ("mcfit fit --help", HELP.format("['fit', '--help']"), NUMERICAL),
    ("mcfit simulate --help", HELP.format("['simulate', '--help']"), NUMERICAL),
    ("the package and its Record", "import mcfit\nmcfit.Record\n", ("pandas",)),
    ("the turning points", "import mcfit.turning\n", IO_AND_CLI),
    ("the equation of motion", "import mcfit.motion\n", IO_AND_CLI),
    ("the amplitude law", "import mcfit.decay\n", IO_AND_CLI),
    # The fit is left out: lmfit itself imports pandas and matplotlib.
    ("the options", "import mcfit.options\n", NUMERICAL + IO_AND_CLI),
]


@pytest.mark.parametrize("what, code, unwanted", CASES, ids=[case[0] for case in CASES])
def test_imports_only_what_it_needs(what, code, unwanted):
    report = f"import sys\nprint(sorted(m for m in {unwanted!r} if m in sys.modules))"
    result = subprocess.run([sys.executable, "-c", code + report], capture_output=True,
                            text=True, env={**os.environ, "PYTHONWARNINGS": "ignore"},
                            check=True, timeout=120)
    assert result.stdout.strip().splitlines()[-1] == "[]", f"{what} imports {result.stdout}"
