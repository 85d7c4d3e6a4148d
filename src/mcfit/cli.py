"""The ``mcfit`` command line (click).

Only click and the standard library are imported at module level, so ``mcfit --help`` and
``mcfit --version`` stay fast; each command imports the numerical modules it needs.
Expected failures (:class:`mcfit.errors.McfitError`) print one line ``Error: ...`` on
stderr and exit with the error's code; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import signal
import sys
import warnings

import click

from mcfit import __version__
from mcfit.errors import (ClosedOutputError, InputError, McfitError, UsageError,
                          escape_controls, printable)
from mcfit.files import Output, is_regular_or_new, supported_types
from mcfit.options import (BENCH_SECTIONS, CRITERIA, DOMAINS, FIT_METHODS, FORMATS, KINDS,
                           PANELS, SAMPLES_PER_CYCLE, SIMULATE_METHODS, check_fit_options,
                           check_plot_name, check_read_options, for_command_line,
                           parse_figsize, parse_panels)

__all__ = ["cli", "main", "McfitGroup"]

# A record larger than this is almost certainly a typo in --duration or --rate.
_MAX_SAMPLES = 100_000_000


class _ReportedError(click.ClickException):
    """A McfitError shown as click shows its own errors: ``Error: message`` on stderr."""

    def __init__(self, error: McfitError):
        # One line, no control characters, options named as flags.
        super().__init__(printable(for_command_line(str(error))))
        self.exit_code = error.exit_code


class _Stopped(BaseException):
    """A stop signal (SIGTERM, SIGHUP) received: ends the run as Ctrl-C does."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


@contextlib.contextmanager
def _stop_signals_interrupt():
    """While the block runs, SIGTERM and SIGHUP raise :class:`_Stopped` in it, unless
    ignored when it starts (``nohup`` ignores SIGHUP; they stay ignored).

    Their default action kills the process at once, leaving temporary files and losing
    the records already finished; raised as an exception they unwind like Ctrl-C does.
    """
    def stop(signum, frame):
        raise _Stopped(signum)

    previous = {}
    try:
        for signum in (signal.SIGTERM, signal.SIGHUP):
            if signal.getsignal(signum) != signal.SIG_IGN:
                previous[signum] = signal.signal(signum, stop)
    except ValueError:  # not the main thread: signals cannot be handled here
        pass
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _exit_code_of(interruption) -> int:
    """128 + the signal's number, as a shell reports a process ended by that signal."""
    signum = getattr(interruption, "signum", signal.SIGINT)
    return 128 + signum


class McfitGroup(click.Group):
    """A click group that reports :class:`McfitError` and can have a default command.

    ``default_command`` names a subcommand that receives the arguments when the first one
    is neither a subcommand name nor one of the group's own options (--help, --version), so that ``mcfit FILE...`` means
    ``mcfit fit FILE...``.
    """

    default_command: str | None = "fit"

    def parse_args(self, ctx, args):
        group_options = {"-h", "--help", "--version"}
        if (self.default_command is not None and args and args[0] not in group_options
                and args[0] not in self.commands):
            if (args[0] != "-" and not os.path.exists(args[0])
                    and not ctx.resilient_parsing):  # shell completion: never an error
                import difflib  # only for a name that is neither a command nor a file

                near = difflib.get_close_matches(args[0], list(self.commands), n=1,
                                                 cutoff=0.75)
                if near:
                    raise click.UsageError(f"no command or file {args[0]!r}; did you mean "
                                           f"'mcfit {near[0]}'?")
            args = [self.default_command, *args]
        return super().parse_args(ctx, args)

    def shell_complete(self, ctx, incomplete):
        """The subcommands, options and, for the default command, file names: ``mcfit
        <TAB>`` offers records to fit as well as ``fit``, ``simulate`` and ``bench``."""
        items = super().shell_complete(ctx, incomplete)
        if self.default_command is not None and not incomplete.startswith("-"):
            items.append(_file_item(incomplete))
        return items

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except ClosedOutputError:
            sys.exit(1)  # the reader has gone (| head): quiet, as Unix filters are
        except McfitError as error:
            raise _ReportedError(error) from error
        except click.ClickException as error:
            # click quotes names as given (a file name may hold escape sequences).
            error.message = printable(error.message)
            raise


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
@click.option("--method", type=click.Choice(SIMULATE_METHODS),
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
    if rate * period < SAMPLES_PER_CYCLE:  # the record would alias, or mcfit could not fit it
        per_cycle = f"{rate * period:.3g} sample{'' if rate * period == 1 else 's'}"
        raise UsageError(f"--rate {rate:g} gives {per_cycle} a cycle of "
                         f"--period {period:g} s; mcfit finds turning points from "
                         f"{SAMPLES_PER_CYCLE} a cycle: give --rate "
                         f"{_rounded_up(SAMPLES_PER_CYCLE / period):g} or more.")
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

    with _stop_signals_interrupt():
        try:
            _write_whole(output, write)
        except (KeyboardInterrupt, _Stopped) as interruption:
            kept = "" if output == "-" else f"; {output} was left as it was"
            click.echo(f"\nInterrupted: the record was not written whole{kept}.", err=True)
            sys.exit(_exit_code_of(interruption))


def _rounded_up(value, digits=4):
    """``value`` rounded up to ``digits`` significant digits (a rate that is enough)."""
    scale = 10.0 ** (digits - 1 - math.floor(math.log10(value)))
    return math.ceil(value * scale) / scale


_FIT_HELP = """Fit the damping law to each record FILE and report a, b, c and Q(t).

FILE is a record file (delimited text, a workbook or WAV audio; types: %s),
- for stdin, or a directory (its record files). For each record mcfit finds the
turning points, fits dy/dt = -c - b*y - a*y^2 to their amplitudes, keeps the damping regimes the record supports (fluid a,
hysteretic b, Coulomb c) and reports Q initial/final/min/max. The word "fit" may be
left out: mcfit FILE... does the same.

\b
Output (stdout): a readable report (default), --format json (one object for one
file, JSON Lines for several, in input order) or --format csv (one row per file).
Diagnostics and progress go to stderr (with -q, errors only).

\b
Exit codes:
  0  every record was fitted
  1  at least one record failed: an Error line on stderr says why (so does its
     JSON or CSV row, and its block in a text report written with -o); the
     others are still reported. Also a directory that could not be listed.
  2  usage error (bad or contradictory options); an option that one file
     cannot satisfy (a column it lacks) fails that file instead (1)

\b
Examples:
  mcfit sample_data/fig20_19_all_three.csv
  mcfit run1.csv --plot run1.png
  mcfit data/ --format csv -o results.csv --plot-dir plots --jobs 2
  mcfit lab.txt --signal-col 2 --model ab
  mcfit peaks.csv --input turning-points --domain cycle
  mcfit swing.csv --pendulum --degrees
""" % supported_types()


def _file_item(incomplete):
    """A shell-completion item that asks the shell for file names (bash's ``compgen -f``,
    zsh's ``_path_files``, fish's ``__fish_complete_path``)."""
    from click.shell_completion import CompletionItem

    return CompletionItem(incomplete, type="file")


def _complete_files(ctx, param, incomplete):
    """Record files and directories for ``mcfit fit <TAB>``."""
    return [_file_item(incomplete)]


def _column(value):
    """A column option: 1-based index when it is a whole number, else a name."""
    if value is None:
        return None
    return int(value) if value.strip().isdigit() else value


@cli.command("fit", help=_FIT_HELP, short_help="Fit records and report damping and Q (default).")
@click.argument("files", nargs=-1, required=True, shell_complete=_complete_files)
@click.option("--time-col", metavar="NAME|N", help="Time column, by name or 1-based index.")
@click.option("--signal-col", metavar="NAME|N", help="Signal column, by name or 1-based index.")
@click.option("--sheet", metavar="NAME|N", help="Excel sheet, by name or 1-based index.")
@click.option("--rate", type=_POSITIVE, metavar="HZ",
              help="Sample rate: time from the sample index (no or unusable time column).")
@click.option("--input", "input_kind", type=click.Choice(KINDS),
              help="Kind of record [default: detected].")
@click.option("--domain", type=click.Choice(DOMAINS),
              help="Whether the first column is time or cycle number n [default: detected].")
@click.option("--criterion", type=click.Choice(CRITERIA), default="aicc",
              show_default=True, help="Information criterion that chooses the regimes.")
@click.option("--model", metavar="LETTERS|none|power",
              help="Force the regimes, e.g. ab; none for constant amplitude; power for "
                   "dy/dt = -k*y^n.")
@click.option("--bootstrap", type=click.IntRange(min=0), default=0, metavar="N",
              help="Residual-bootstrap refits for 95 % intervals; unless --model is given, "
                   "each chooses the model anew.")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed of the bootstrap resampling.")
@click.option("--method", type=click.Choice(FIT_METHODS),
              default="auto", show_default=True,
              help="Fit the turning points by the averaged law, or the waveform by the "
                   "equation of motion; auto takes the waveform only where the averaged "
                   "law's bias would exceed 0.3 standard errors (low Q).")
@click.option("--format", "output_format", type=click.Choice(FORMATS),
              default="text", show_default=True, help="Output format.")
@click.option("-o", "--output", type=click.Path(allow_dash=True), default="-",
              help="Write results to this file (whole, via a temporary file); - for stdout.")
@click.option("--plot", "plot_file", type=click.Path(dir_okay=False),
              help="Report figure for a single file (.png, .pdf or .svg); for a file of "
                   "several runs, one per run, named like fig-run7.png.")
@click.option("--plot-dir", type=click.Path(file_okay=False),
              help="Directory for one PNG report figure per record (batch).")
@click.option("--jobs", type=click.IntRange(min=1), default=1, show_default=True,
              help="Worker processes; results stay in input order.")
@click.option("--dask", metavar="ADDRESS",
              help="Fit on a Dask cluster: its scheduler's address (tcp://host:8786) or "
                   "scheduler file; needs pip install 'mcfit-damping[dask]'.")
@click.option("--turning-points-out", type=click.Path(dir_okay=False), metavar="FILE.csv",
              help="Also write every record's turning points (t, amplitude, sigma, used or "
                   "why not, fitted envelope) to this CSV file.")
@click.option("--start", type=float, metavar="T",
              help="Fit only from this time in seconds (or cycle number) on, e.g. after the "
                   "release; times as the record gives them, a clock (Unix epoch, date and "
                   "time) as seconds from its first sample.")
@click.option("--end", type=float, metavar="T",
              help="Fit only up to this time in seconds (or cycle number).")
@click.option("--run", type=click.IntRange(min=1), metavar="N",
              help="Of a file's runs side by side ('Run #N' columns, or repeated time and "
                   "signal columns), fit only run N [default: every run, as a record of "
                   "its own].")
@click.option("--angle-from", metavar="X,Y",
              help="Fit the swing angle atan2(x, -y) of a tracked pendulum bob from its x "
                   "and y columns (names or 1-based indices; pivot at the origin).")
@click.option("--pendulum", is_flag=True,
              help="The signal is a pendulum's swing angle (radians): fit with the "
                   "large-swing geometry of sin(theta); coefficients keep their small-angle "
                   "meaning.")
@click.option("--degrees", is_flag=True,
              help="The angle is in degrees (also when the signal column's name says 'deg' "
                   "or '°').")
@click.option("--unit", metavar="TEXT",
              help="The signal's unit, for every output: text, JSON, CSV and the figure "
                   "(mm gives a in 1/(mm*s)); in place of the header's, with a note "
                   "[default: from the header, e.g. 'Position (mm)'].")
@click.option("--title", metavar="TEXT",
              help="The figure's title [default: the file name, with the run].")
@click.option("--panels", metavar="LIST",
              help="The figure's panels, in order, from: " + ", ".join(PANELS)
                   + " (qamp: Q against amplitude; backbone: period against amplitude) "
                   "[default: record,amplitude,q,rate].")
@click.option("--figsize", metavar="W,H", help="The figure's size in inches, e.g. 12,9.")
@click.option("--dpi", type=click.IntRange(min=20, max=2400), metavar="N",
              help="Resolution of a PNG figure in dots per inch [default: 110].")
@click.option("-q", "--quiet", is_flag=True,
              help="No notes or progress bar on stderr: only errors, and the results.")
def fit(files, time_col, signal_col, sheet, rate, input_kind, domain, criterion, model,
        bootstrap, seed, method, output_format, output, plot_file, plot_dir, jobs, dask,
        turning_points_out, start, end, run, angle_from, pendulum, degrees, unit, title,
        panels, figsize, dpi, quiet):
    if dask is not None and jobs > 1:
        raise UsageError("give --dask ADDRESS or --jobs N, not both: with --dask the "
                         "cluster's workers fit the records.")
    # A record's fit is many small problems: BLAS threads only spin on other cores (79 ms
    # of CPU per 40 ms of wall time at --jobs 1). Set before numpy is first imported (here
    # and in the workers); user settings win.
    for variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(variable, "1")
    angle_from = _angle_columns(angle_from)
    check_read_options(kind=input_kind, domain=domain, rate=rate, time_col=time_col,
                       signal_col=signal_col, angle_from=angle_from)
    model = check_fit_options(criterion=criterion, model=model, bootstrap=bootstrap,
                              method=method, pendulum=pendulum, start=start, end=end)
    if turning_points_out == "-" and output == "-":
        raise UsageError("--turning-points-out - and the results would share stdout; give "
                         "one of them a file name (-o FILE or --turning-points-out FILE.csv).")
    if plot_file is not None and plot_dir is not None:
        raise UsageError("give --plot FILE or --plot-dir DIR, not both.")
    if plot_file is not None:
        check_plot_name(plot_file)
    figure_options = _figure_options(plot_file or plot_dir, title=title, panels=panels,
                                     figsize=figsize, dpi=dpi)
    options = dict(time_col=_column(time_col), signal_col=_column(signal_col),
                   sheet=_column(sheet), rate=rate, kind=input_kind, domain=domain,
                   criterion=criterion, model=model,
                   bootstrap=bootstrap, seed=seed, method=method, pendulum=pendulum,
                   degrees=True if degrees else None, start=start, end=end, run=run,
                   angle_from=angle_from, unit=unit,
                   turning_points_out=turning_points_out is not None, **figure_options)
    with _stop_signals_interrupt():
        try:
            failures = _fit_files(files, output, output_format, plot_file, plot_dir, jobs,
                                  options, turning_points_out, dask, quiet)
        except (KeyboardInterrupt, _Stopped) as interruption:
            # Stopped before the first record was written: nothing to keep.
            click.echo("\nInterrupted before any record was finished.", err=True)
            sys.exit(_exit_code_of(interruption))
    sys.exit(1 if failures else 0)


def _figure_options(plot, **given):
    """The figure's options, checked; refused without a figure to apply them to."""
    named = [f"--{name}" for name, value in given.items() if value is not None]
    if named and plot is None:
        raise UsageError(f"{', '.join(named)} shape{'s' if len(named) == 1 else ''} the "
                         "figure: give --plot FILE or --plot-dir DIR too.")
    if given["panels"] is not None:
        given["panels"] = parse_panels(given["panels"])
    if given["figsize"] is not None:
        given["figsize"] = parse_figsize(given["figsize"])
    return given


def _angle_columns(text):
    """The (x, y) columns of --angle-from X,Y, or None."""
    if text is None:
        return None
    parts = [part.strip() for part in text.split(",")]
    if len(parts) != 2 or not all(parts):
        raise UsageError(f"--angle-from {text!r}: give the bob's two columns as X,Y, e.g. "
                         "--angle-from x,y or --angle-from 2,3.")
    return tuple(_column(part) for part in parts)


def _fit_files(files, output, output_format, plot_file, plot_dir, jobs, options,
               turning_points_out=None, dask=None, quiet=False):
    """Check the outputs against each other and the inputs, then fit and write; return the
    number of failed records. ``quiet``: no notes or progress bar, only errors."""
    from mcfit import batch

    inputs = batch.find_inputs(files)
    if not inputs.files:  # every directory named was unlistable
        raise InputError(inputs.problems[0])
    sources = list(inputs.files)
    if plot_file is not None and len(sources) != 1:
        raise UsageError("--plot takes one record; for several use --plot-dir DIR.")
    if output != "-" and os.path.isdir(output):  # checked here, not by click: one line
        example = os.path.join(output, "results." + output_format.replace("text", "txt"))
        raise UsageError(f"-o {output} is a directory; give a file name, e.g. {example}.")
    if "-" in sources and dask is not None:
        raise UsageError("--dask cannot read stdin (-): the cluster's workers read the "
                         "records; save it to a file and name that.")
    if "-" in sources:
        jobs = 1  # stdin can be read by one process only
        if sys.stdin is None:  # started with stdin closed (<&-)
            raise InputError("cannot read stdin (-): it is closed; pipe a record into mcfit "
                             "or name a file.")
    if plot_dir is not None:
        taken = set()
        plot_paths = [batch.plot_path_for(s, plot_dir, taken) for s in sources]
        plots = [("--plot-dir", path) for path in plot_paths]
    else:
        plot_paths = [plot_file] * len(sources)
        plots = [("--plot", plot_file)] if plot_file is not None else []
    outputs = (([("-o", output)] if output != "-" else []) + plots
               + ([("--turning-points-out", turning_points_out)] if turning_points_out else []))
    _refuse_outputs_that_clash(outputs, sources)
    if plot_dir is not None:
        try:
            os.makedirs(plot_dir, exist_ok=True)
        except OSError as error:
            raise McfitError(f"cannot create plot directory {plot_dir}: "
                             f"{error.strerror or error}") from error
    options = batch.FitOptions(output_format=output_format, **options)
    for note in () if quiet else inputs.notes:
        click.echo(f"Note: {printable(note)}", err=True)
    for problem in inputs.problems:  # counted as failures: the batch exits 1
        click.echo(f"Error: {printable(problem)}", err=True)
    if dask is None:
        if not quiet:
            _note_jobs_cap(jobs, len(sources), batch.available_cpus())
        results = batch.run_jobs(sources, options, plot_paths, jobs=jobs)
    else:
        from mcfit import dask_jobs

        results = dask_jobs.run_jobs(sources, options, plot_paths, dask)
    try:
        return len(inputs.problems) + _write_results(
            results, sources, output_format, output, bootstrap=options.bootstrap > 0,
            turning_points_out=turning_points_out, quiet=quiet)
    finally:
        results.close()  # ends the worker processes at once after an error


def _note_jobs_cap(jobs, records, cpus):
    """Say so when --jobs asks for more workers than there are CPUs to run them."""
    if min(jobs, records) > cpus:
        click.echo(f"Note: --jobs {jobs} is more than the {cpus} CPU{'s' * (cpus > 1)} "
                   f"available; running {cpus} worker process{'es' * (cpus > 1)}.", err=True)


def _refuse_outputs_that_clash(outputs, sources):
    """Usage errors, before any work, for outputs that would destroy each other or an input.

    ``outputs`` holds (option, path) pairs. A device or a FIFO is written in place and
    destroys nothing, so only regular files (or new names) are checked. An output inside a
    directory being read is fine: a later run leaves it out (mcfit knows its own files).
    """
    outputs = [(option, path) for option, path in outputs if is_regular_or_new(path)]
    seen = {}
    for option, path in outputs:
        key = os.path.realpath(path)
        if key in seen:
            raise UsageError(f"{seen[key]} and {option} both name {path}; one would overwrite "
                             "the other. Give them different names.")
        seen[key] = f"{option} {path}"
        for source in sources:
            if source != "-" and os.path.exists(path) and os.path.exists(source) \
                    and os.path.samefile(path, source):
                raise UsageError(f"{option} {path} is one of the input records; choose "
                                 "another output file, inputs are never overwritten.")


def _write_results(results, sources, output_format, output, bootstrap=False,
                   turning_points_out=None, quiet=False):
    """Write each result as it arrives; return the number of failed records. ``quiet``:
    no progress bar.

    With -o the lines go to a temporary file that replaces the target at the end, or at an
    interruption, so the file always holds whole records only; the same for the turning
    points' file.
    """
    total = len(sources)
    target = Output(output)
    points = _TurningPointsOutput(turning_points_out)
    failures = done = written = 0
    show_progress = total > 1 and not quiet and _is_terminal(sys.stderr)
    progress = (click.progressbar(length=total, label="fitting", file=sys.stderr)
                if show_progress else None)
    from mcfit import report

    try:
        if output_format == "csv":
            target.write(report.csv_header(bootstrap))
        for file_result in results:
            done += 1
            for result in file_result.records:
                failures += _write_result(result, target, points, output_format, written,
                                          bootstrap)
                written += output_format == "text" and (
                    result["analysis"]["status"] == "ok" or target.temporary is not None)
            if output_format == "text" and len(file_result.records) > 1:
                target.write("\n" + report.runs_summary(
                    file_result.source, [r["analysis"] for r in file_result.records]))
            if progress is not None:
                progress.update(1)
    except (KeyboardInterrupt, _Stopped) as interruption:
        name = ("Interrupted" if isinstance(interruption, KeyboardInterrupt)
                else f"Stopped by {signal.Signals(interruption.signum).name}")
        kept = f" and kept in {output}." if target.temporary is not None else "."
        click.echo(f"\n{name}: {done} of {total} records finished{kept}", err=True)
        target.commit()
        points.commit()
        sys.exit(_exit_code_of(interruption))
    except BaseException:
        target.discard()
        points.discard()
        raise
    finally:
        if progress is not None:
            progress.render_finish()
    target.commit()
    points.commit()
    return failures


def _is_terminal(stream) -> bool:
    """Whether ``stream`` is a terminal; False for a closed or missing stream."""
    try:
        return stream is not None and stream.isatty()
    except (AttributeError, OSError, ValueError):
        return False


def _write_result(result, target, points, output_format, written, bootstrap=False):
    """Write one record's output (from its plain data) and errors; return how many
    failures it counts."""
    from mcfit import report

    data = result["analysis"]
    failures = 0
    points.write(report.turning_points_rows(result["turning_points"]))
    if output_format == "json":
        output = report.to_json(data)
    elif output_format == "csv":
        output = report.to_csv_row(data, bootstrap=bootstrap)
    else:
        output = report.to_text(data)
    # The library names options in Python spelling; here they are flags.
    output = for_command_line(output)
    if data["status"] != "ok":
        failures += 1
        click.echo(f"Error: {printable(for_command_line(data['error']))}", err=True)
    if result["plot_error"]:
        failures += 1
        click.echo(f"Error: {printable(result['plot_error'])}", err=True)
    if output_format == "json":
        target.write(output + "\n")
    elif output_format == "csv":
        target.write(output)
    elif data["status"] == "ok" or target.temporary is not None:
        # On stdout the Error line above (stderr) says all a failed record's report would;
        # a report file (-o) keeps it, so that the file accounts for every record.
        target.write(("\n" if written else "") + _printable_lines(output))
    return failures


class _TurningPointsOutput:
    """The --turning-points-out file (header, then each record's rows), or nothing."""

    def __init__(self, path):
        self.output = None
        if path is not None:
            from mcfit.report import turning_points_header

            self.output = Output(path)
            self.output.write(turning_points_header())

    def write(self, rows):
        if self.output is not None and rows:
            self.output.write(rows)

    def commit(self):
        if self.output is not None:
            self.output.commit()

    def discard(self):
        if self.output is not None:
            self.output.discard()


def _printable_lines(text):
    """A text report with every line made safe for a terminal (notes quote file contents)."""
    return "\n".join(escape_controls(line) for line in text.split("\n"))


_BENCH_HELP = """Measure speed against error and print the tables (BENCHMARKS.md).

\b
Sections:
  integrators  work against precision of cromer-euler, symplectic, accurate
               and averaged on three scenes (Q 12.5 all three regimes,
               Q 1000 hysteretic, a Coulomb stop)
  fitting      RMSE and bias of a, b, c over repeated noisy records in units
               of the Cramer-Rao bound, and time per record, for mcfit, the
               log decrement of single-sample peaks and a Hilbert envelope
  verdicts     how often the reported model is the true one (spurious and
               missed terms, "cannot tell") and the coverage of the 95 %
               intervals of a, b, c and Q, by Monte Carlo
  methods      the turning-point fit against the waveform fit by the equation
               of motion at Q 2 to 50: b's bias, RMSE and coverage in standard
               errors, time per record, and how often --method auto chose each
  cycles       turning-point cost per cycle from 10^3 to 10^5 cycles (10^6
               and a CSV of 10^7 samples and 10^6 cycles with --full)
  throughput   each speed target of issue 17 against its measured figure:
               turning points + fit per record, mcfit DIR at --jobs 1 and 2
               (--method auto and turning-points), start-up, and with --full
               a CSV of 10^7 samples (time and peak memory)
  edges        records from an independent integration where real records
               live (low Q with friction, viscous, a held start, large swings,
               a near tie, a beat, 8 bits): right, flagged or silently wrong
               per scene with 95 % intervals (5 records a scene, 60 with --full)
  waveform     the default method on a mixed batch (half with Q <= 8) against
               --method turning-points, and the waveform fit's time at Q 2-10

The default quick grid runs in about five minutes on two cores; --full runs the
whole grid (more steps, tolerances, SNRs and samples per cycle, 100 records a
fitting cell, 400 a verdicts scene, 40 a methods Q, a CSV of 10^7 samples):
about an hour, most of it the methods section. --output-dir writes the plots
with either grid. Times are measured on this machine; nothing is asserted.

\b
Examples:
  mcfit bench
  mcfit bench --section fitting --repeats 20
  mcfit bench --full --output-dir bench-plots > bench.txt
"""


@cli.command("bench", help=_BENCH_HELP, short_help="Benchmark integrators, fits and throughput.")
@click.option("--full", is_flag=True,
              help="Run the whole grid (about an hour) instead of the quick one (about five "
                   "minutes).")
@click.option("--section", "sections", multiple=True,
              type=click.Choice(BENCH_SECTIONS),
              help="Run only this section (repeatable) [default: all].")
@click.option("--repeats", type=click.IntRange(min=2), default=None, metavar="N",
              help="Noisy records per fitting cell [default: 8 quick, 100 full].")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Seed of the random records [default: 2026].")
@click.option("--output-dir", type=click.Path(file_okay=False), default=None,
              help="Write integrators.png and fitting.png into this directory.")
def bench_command(full, sections, repeats, seed, output_dir):
    import dataclasses

    from mcfit import bench

    config = bench.FULL if full else bench.QUICK
    if repeats is not None:
        config = dataclasses.replace(config, repeats=repeats)
    if seed is not None:
        config = dataclasses.replace(config, seed=seed)
    try:
        for block in bench.run(config, sections or bench.SECTIONS, plot_dir=output_dir,
                               progress=lambda message: click.echo(message, err=True)):
            click.echo(block + "\n")
    except OSError as error:
        raise McfitError(f"cannot write the bench plots to {output_dir}: "
                         f"{error.strerror or error}") from error


def _write_whole(path, write):
    """Write text with ``write(stream)`` to stdout (``-``), a device, or a file whole."""
    output = Output(path)
    try:
        output.write_with(write)
        output.commit()
    except BaseException:
        output.discard()
        raise


def main(argv=None):
    """Console entry point (``mcfit``) and ``python -m mcfit``.

    Warnings are for the developers of mcfit, who see them in the tests (and with
    ``python -W default -m mcfit``); a person running mcfit gets the Error line or the
    result, not a numpy RuntimeWarning before it. A write past the file-size limit raises
    EFBIG, cleaned up like any write error, instead of killing the process (SIGXFSZ).
    """
    if not sys.warnoptions:
        warnings.simplefilter("ignore")
        os.environ["PYTHONWARNINGS"] = "ignore"  # worker processes that start afresh
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    _hold_closed_streams()
    _messages_never_fail()
    cli.main(args=argv, prog_name="mcfit")


def _hold_closed_streams():
    """Put /dev/null on a standard descriptor (0, 1, 2) the process was started without.

    Else the next file opened takes its number, and whatever writes to "stderr" (a library
    in a worker) writes into the results. ``sys.stdin`` and ``sys.stdout`` stay None, so
    that reading stdin or writing results to stdout says that it is closed.
    """
    for descriptor in (0, 1, 2):
        try:
            os.fstat(descriptor)
        except OSError:
            devnull = os.open(os.devnull, os.O_RDWR)
            if devnull != descriptor:
                os.dup2(devnull, descriptor)
                os.close(devnull)


class _MessageWriter(io.RawIOBase):
    """The descriptor of stderr, dropping what it cannot take (a full disk, a closed
    pipe) instead of raising: messages are secondary to results."""

    def __init__(self, descriptor: int):
        super().__init__()
        self.descriptor = descriptor

    def writable(self):
        return True

    def fileno(self):
        return self.descriptor

    def isatty(self):
        return os.isatty(self.descriptor)

    def write(self, data):
        try:
            return os.write(self.descriptor, data)
        except OSError:
            return len(data)


def _messages_never_fail():
    """Make ``sys.stderr`` a stream whose writes never fail (see :class:`_MessageWriter`);
    a stderr that is not descriptor 2 (a test's capture) is left alone."""
    stream = sys.stderr
    try:
        if stream is not None and stream.fileno() != 2:
            return
    except (AttributeError, OSError, ValueError):
        return
    encoding = getattr(stream, "encoding", None) or "utf-8"
    sys.stderr = io.TextIOWrapper(io.BufferedWriter(_MessageWriter(2)), encoding=encoding,
                                  errors="backslashreplace", line_buffering=True,
                                  write_through=True)
