"""mcfit: fit the modified Coulomb damping law dy/dt = -c - b*y - a*y**2 to free-decay records.

The public surface is re-exported here lazily so that ``import mcfit`` (and ``mcfit --help``)
does not pull in the numerical stack.
"""

from __future__ import annotations

__version__ = "0.1.0"
