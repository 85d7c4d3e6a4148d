"""The ``mcfit`` command line (click).

Only click and the standard library are imported at module level, so ``mcfit --help`` and
``mcfit --version`` stay fast; each command imports the numerical modules it needs.
Expected failures (:class:`mcfit.errors.McfitError`) print one line ``Error: ...`` on
stderr and exit with the error's code; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import math
import os
import sys
import tempfile

import click

from mcfit import __version__
from mcfit.errors import McfitError, UsageError

__all__ = ["cli", "main", "McfitGroup"]

# A record larger than this is almost certainly a typo in --duration or --rate.
_MAX_SAMPLES = 100_000_000


class _ReportedError(click.ClickException):
    """A McfitError shown as click shows its own errors: ``Error: message`` on stderr."""

    def __init__(self, error: McfitError):
        super().__init__(" ".join(str(error).split()))  # one line
        self.exit_code = error.exit_code


class McfitGroup(click.Group):
    """A click group that reports :class:`McfitError` and can have a default command.

    ``default_command`` names a subcommand that receives the arguments when the first one
    is not a subcommand name or an option of the group, so that ``mcfit FILE...`` can mean
    ``mcfit fit FILE...`` once a ``fit`` command exists. It is ``None`` (off) for now.
    """

    default_command: str | None = None

    def parse_args(self, ctx, args):
        if (self.default_command is not None and args and not args[0].startswith("-")
                and args[0] not in self.commands):
            args = [self.default_command, *args]
        return super().parse_args(ctx, args)

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except McfitError as error:
            raise _ReportedError(error) from error


class _Number(click.ParamType):
    """A finite float with an optional lower bound (open or closed)."""

    name = "float"

    def __init__(self, minimum=None, open_minimum=False):
        self.minimum = minimum
        self.open_minimum = open_minimum

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            number = value
        else:
            try:
                number = float(value)
            except (TypeError, ValueError):
                self.fail(f"{value!r} is not a number.", param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number.", param, ctx)
        if self.minimum is not None:
            if self.open_minimum and number <= self.minimum:
                self.fail(f"{value} must be > {self.minimum:g}.", param, ctx)
            if not self.open_minimum and number < self.minimum:
                self.fail(f"{value} must be >= {self.minimum:g}.", param, ctx)
        return number


_NON_NEGATIVE = _Number(minimum=0.0)
_POSITIVE = _Number(minimum=0.0, open_minimum=True)
_ANY = _Number()


@click.group(cls=McfitGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, "--version", prog_name="mcfit",
                      message="%(prog)s %(version)s")
def cli():
    """Fit the modified Coulomb damping law dy/dt = -c - b*y - a*y^2 to free-decay records.

    \b
    Exit codes: 0 success, 1 a failure reported as "Error: ...", 2 bad usage.
    """


_SIMULATE_HELP = """Write a synthetic free-decay record as CSV with header t,x.

Integrates x'' + (pi*w/2)*(c + b*A + a*A^2)*sgn(x') + w^2*x = 0 (Handbook Eq. 20.55,
w = 2*pi/PERIOD, A = sqrt(x^2 + (x'/w)^2)) from x = Y0, x' = 0 at t = 0 and samples
it at RATE Hz up to DURATION seconds. The turning-point amplitude then follows
dy/dt = -c - b*y - a*y^2.

\b
Methods:
  auto          the averaged model if its error, about 0.8/Q at the start,
                meets --rtol; otherwise accurate (default)
  averaged      y(t)*cos(w*t) with y(t) in closed form (fast, error ~ 1/Q)
  cromer-euler  the handbook's Table 20.1 scheme, first order in --dt
  symplectic    Strang splitting, exact rotation; second order between
                velocity reversals
  accurate      DOP853 with a step end at every velocity reversal and
                static friction at turning points

\b
Example (the handbook's Figure 20.19, with noise):
  mcfit simulate --a 0.1 --b 0.1 --c 0.01 --y0 4 --period 0.5 \\
      --duration 20 --rate 100 --noise 0.01 --seed 1 -o fig2019.csv
"""


@cli.command(help=_SIMULATE_HELP, short_help="Write a synthetic decay record (CSV).")
@click.option("--a", "a", type=_NON_NEGATIVE, default=0.0, show_default=True,
              help="Fluid (quadratic) coefficient, 1/(U*s).")
@click.option("--b", "b", type=_NON_NEGATIVE, default=0.0, show_default=True,
              help="Hysteretic (constant-Q) coefficient, 1/s.")
@click.option("--c", "c", type=_NON_NEGATIVE, default=0.0, show_default=True,
              help="Coulomb coefficient, U/s.")
@click.option("--y0", type=_POSITIVE, default=1.0, show_default=True,
              help="Initial amplitude, U.")
@click.option("--period", type=_POSITIVE, default=1.0, show_default=True,
              help="Period T in seconds.")
@click.option("--duration", type=_NON_NEGATIVE, default=10.0, show_default=True,
              help="Record length in seconds.")
@click.option("--rate", type=_POSITIVE, default=100.0, show_default=True,
              help="Sampling rate in Hz.")
@click.option("--noise", type=_NON_NEGATIVE, default=0.0, show_default=True, metavar="SIGMA",
              help="Standard deviation of Gaussian noise added to x, U.")
@click.option("--offset", type=_ANY, default=0.0, show_default=True, metavar="X",
              help="Constant added to x, U.")
@click.option("--drift", type=_ANY, default=0.0, show_default=True, metavar="X_PER_S",
              help="Linear drift added to x, U per second.")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed of the noise generator; the same seed gives the same record.")
@click.option("--method", type=click.Choice(["auto", "averaged", "cromer-euler", "symplectic",
                                             "accurate"]),
              default="auto", show_default=True, help="How to compute x(t) (see above).")
@click.option("--dt", type=_POSITIVE, default=None,
              help="Step in seconds for cromer-euler and symplectic "
                   "[default: the largest 1/(k*RATE), k whole, not above PERIOD/250].")
@click.option("--rtol", type=_POSITIVE, default=1e-6, show_default=True,
              help="Error allowed relative to Y0 (chooses the method for auto).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, writable=True, allow_dash=True),
              default="-", show_default=True, help="Output CSV file; - for stdout.")
def simulate(a, b, c, y0, period, duration, rate, noise, offset, drift, seed, method, dt, rtol,
             output):
    if dt is not None and method not in ("cromer-euler", "symplectic"):
        raise UsageError(f"--dt applies only to --method cromer-euler or symplectic, "
                         f"not {method}; drop --dt or choose one of those methods.")
    n_samples = math.floor(duration * rate) + 1
    if n_samples > _MAX_SAMPLES:
        raise UsageError(f"--duration {duration:g} at --rate {rate:g} gives {n_samples} samples, "
                         f"more than {_MAX_SAMPLES}; shorten the record or lower the rate.")

    import numpy as np

    from mcfit import motion

    t, x = motion.simulate_record(a, b, c, y0, period, duration, rate, method=method, dt=dt,
                                  rtol=rtol, noise=noise, offset=offset, drift=drift,
                                  rng=np.random.default_rng(seed))

    def write(stream):
        stream.write("t,x\n")
        np.savetxt(stream, np.column_stack([t, x]), fmt="%.15g", delimiter=",")

    if output == "-":
        write(sys.stdout)
    else:
        _write_atomically(output, write)


def _write_atomically(path, write):
    """Write a text file through a temporary file in the same directory and os.replace."""
    directory = os.path.dirname(os.path.abspath(path))
    try:
        existing_mode = os.stat(path).st_mode & 0o777
    except FileNotFoundError:
        umask = os.umask(0)
        os.umask(umask)
        existing_mode = 0o666 & ~umask
    except OSError as error:
        raise McfitError(f"cannot write {path}: {error.strerror or error}") from error
    try:
        handle, temporary = tempfile.mkstemp(dir=directory, prefix=f".{os.path.basename(path)}.",
                                             suffix=".tmp")
    except OSError as error:
        raise McfitError(f"cannot write {path}: {error.strerror or error}; check that the "
                         "directory exists and is writable.") from error
    try:
        with os.fdopen(handle, "w", newline="") as stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary, existing_mode)
        os.replace(temporary, path)
    except BaseException as error:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        if isinstance(error, OSError):
            raise McfitError(f"cannot write {path}: {error.strerror or error}") from error
        raise


def main(argv=None):
    """Console entry point (``mcfit``) and ``python -m mcfit``."""
    cli.main(args=argv, prog_name="mcfit")
