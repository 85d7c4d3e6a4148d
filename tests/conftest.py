"""Test-suite settings.

Under CI (the ``CI`` environment variable set, as ``.ci/run`` does) Hypothesis draws the
same examples on every run, so a run's verdict never hangs on a random draw. Elsewhere
each run draws new examples and keeps looking for failures.
"""

import os

from hypothesis import settings

settings.register_profile("mcfit-ci", derandomize=True, database=None)
if os.environ.get("CI", "").lower() not in ("", "0", "false"):
    settings.load_profile("mcfit-ci")
