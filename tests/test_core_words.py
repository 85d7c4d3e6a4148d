"""The core speaks Python; only the command line names its flags."""

import re
from pathlib import Path

import pytest

from mcfit.options import FLAGS, for_command_line

SOURCE = Path(__file__).parents[1] / "src" / "mcfit"
CORE = ["record.py", "decay.py", "motion.py", "phase_plane.py", "hum.py", "model_error.py",
        "analysis.py", "bounds.py", "api.py", "report.py", "batch.py", "plain.py", "dask_jobs.py",
        *(f"io/{p.name}" for p in sorted((SOURCE / "io").glob("*.py"))),
        *(f"fit/{p.name}" for p in (SOURCE / "fit").glob("*.py")),
        *(f"turning/{p.name}" for p in sorted((SOURCE / "turning").glob("*.py")))]


@pytest.mark.parametrize("module", CORE)
def test_no_core_module_names_a_command_line_flag(module):
    text = (SOURCE / module).read_text(encoding="utf-8")
    flags = re.findall(r"--[a-z][a-z-]*", text)
    assert not flags, f"{module} names {sorted(set(flags))}"


def test_options_in_python_spelling_become_flags():
    assert for_command_line("Use `signal_col`.") == "Use --signal-col."
    assert for_command_line("give `rate=HZ` or `time_col`") == "give --rate HZ or --time-col"
    assert for_command_line("(`run=7` picks it)") == "(--run 7 picks it)"
    # Only the options: other quoted words stay as they are.
    assert for_command_line("a `note` and `x=1`") == "a `note` and `x=1`"
    # Each flag is its keyword with dashes, except `kind` (a builtin's name as a flag).
    flags = dict(FLAGS)
    assert flags.pop("kind") == "--input"
    assert all(flag == "--" + name.replace("_", "-") for name, flag in flags.items())
