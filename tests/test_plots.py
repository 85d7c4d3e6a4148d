"""The report figure: every panel for every sample and every run of a multi-run file, with
titles, units, ranges and legends checked on the drawn figure (Agg, no display)."""

import math
import struct
from dataclasses import replace
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from click.testing import CliRunner

matplotlib.use("Agg")

from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

import mcfit  # noqa: E402
from mcfit import decay  # noqa: E402
from mcfit.analysis import analyse_record  # noqa: E402
from mcfit.cli import cli  # noqa: E402
from mcfit.options import DEFAULT_PANELS, PANELS  # noqa: E402
from mcfit.plots import record_view, report_figure  # noqa: E402
from mcfit.plots.binning import binned_medians, binned_rates, full_periods  # noqa: E402
from mcfit.io import read_records  # noqa: E402

ROOT = Path(__file__).parents[1]
SAMPLES = sorted(p for p in (ROOT / "sample_data").iterdir() if p.suffix in (".csv", ".xlsx"))
REALDATA = ROOT.parent / "shared" / "realdata"

TITLES = {"record and turning points": "record",
          "amplitudes: selected fit against single-regime fits": "amplitude",
          "quality factor Q and its parts": "q", "damping rate against amplitude": "rate",
          "quality factor against amplitude": "qamp",
          "period against amplitude (backbone)": "backbone"}


def _analyses():
    """(id, analysis) of every record of every sample, each run of a multi-run file apart."""
    found = []
    for path in SAMPLES:
        records = read_records(str(path))
        # Of a multi-run file, the first and the last run (the others are drawn alike).
        for record in records[:1] + records[1:][-1:]:
            analysis = analyse_record(record, method="turning-points")
            found.append((f"{path.name}#{record.run}" if record.run else path.name, analysis))
    return found


ANALYSES = _analyses()


def _panels(figure):
    return {TITLES[a.get_title()]: a for a in figure.axes if a.get_title() in TITLES}


@pytest.fixture(scope="module", params=ANALYSES, ids=[name for name, _ in ANALYSES])
def drawn(request):
    """(analysis, figure, {panel: axes}) with every panel (ranges are set when the panels
    are; only the layout waits for a drawing)."""
    _, analysis = request.param
    figure = analysis.figure(panels=PANELS)
    return analysis, figure, _panels(figure)


def test_every_panel_is_drawn_and_the_title_is_the_file_name(drawn):
    analysis, figure, panels = drawn
    assert set(panels) == set(PANELS)
    record = analysis.record
    name = Path(record.source).name
    assert figure.get_suptitle() == (f"{name}, {record.run}" if record.run else name)
    assert "/" not in figure.get_suptitle()


def test_axis_labels_and_the_parameter_box_carry_the_unit(drawn):
    analysis, figure, panels = drawn
    unit = analysis.record.signal_unit
    label = panels["amplitude"].get_ylabel()
    box = next(t.get_text() for a in figure.axes for t in a.texts
               if "turning points, reduced chi-square" in t.get_text())
    assert "column" not in label and "column" not in box
    if unit is None:
        assert label == "amplitude"
        assert "U: the signal's unit" in box
    else:
        assert label == f"amplitude ({unit})"
        assert panels["rate"].get_xlabel() == f"amplitude ({unit})"
        coefficients = [line for line in box.splitlines() if line[:3] in ("a (", "c (")]
        assert coefficients and all(unit in line for line in coefficients)
        assert "U*" not in box and "(U/" not in box


@pytest.mark.parametrize("name", ["fig20_19_all_three.csv", "capstone_runs.csv#Run 1",
                                  "fig20_20_peak_speed_cycles.csv"])
def test_legends_take_no_width_and_cover_no_measured_point(name):
    """Each legend lies within its axes' width (inside them, or under them below the axis
    label), and no measured point (turning points, amplitudes, binned medians, measured
    rates) is under it."""
    figure = dict(ANALYSES)[name].figure(panels=PANELS)
    figure.set_dpi(40)  # the layout is in inches and points: a coarse raster is enough
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    renderer = canvas.get_renderer()
    legends = 0
    for axes in figure.axes:
        legend = axes.get_legend()
        if legend is None:
            continue
        legends += 1
        box, frame = legend.get_window_extent(renderer), axes.get_window_extent(renderer)
        assert frame.x0 - 0.5 <= box.x0 and box.x1 <= frame.x1 + 0.5, axes.get_title()
        inside = box.y0 >= frame.y0 - 0.5 and box.y1 <= frame.y1 + 0.5
        label = axes.xaxis.label
        below = box.y1 <= frame.y0 and (not label.get_visible() or not label.get_text()
                                        or box.y1 <= label.get_window_extent(renderer).y0)
        assert inside or below, axes.get_title()
        for line in axes.get_lines():
            if line.get_marker() in ("None", None, ""):
                continue
            xy = line.get_transform().transform(line.get_xydata())
            xy = xy[np.all(np.isfinite(xy), axis=1)]
            covered = ((xy[:, 0] > box.x0) & (xy[:, 0] < box.x1) & (xy[:, 1] > box.y0)
                       & (xy[:, 1] < box.y1))
            # A faint measured point or two may sit under a framed legend, nothing more.
            assert np.count_nonzero(covered) <= 0.02 * len(xy), (axes.get_title(),
                                                                 line.get_label())
    assert legends >= 5


def test_listed_curves_are_on_scale(drawn):
    """A curve named in a legend has points within the axes' range."""
    _, _, panels = drawn
    for name, axes in panels.items():
        low, high = axes.get_ylim()
        legend = axes.get_legend()
        if legend is None:
            continue
        listed = {t.get_text() for t in legend.get_texts()}
        for line in axes.get_lines():
            if line.get_label() in listed and isinstance(line, Line2D):
                y = np.asarray(line.get_ydata(), dtype=float)
                assert np.any((y >= low) & (y <= high)), (name, line.get_label())


def test_the_amplitude_range_is_the_datas_and_the_selected_fits(drawn):
    analysis, _, panels = drawn
    fit = analysis.fit
    axes = panels["amplitude"]
    low, high = axes.get_ylim()
    sigma = np.where(np.isfinite(fit.sigma), fit.sigma, 0.0)
    t = np.linspace(fit.t[0], fit.t[-1], 600)
    shown = np.concatenate([fit.y - sigma, fit.y + sigma, fit.amplitude(t)])
    if axes.get_yscale() == "log":
        shown = shown[shown > 0]
        assert low <= shown.min() and high >= shown.max()
        # Not stretched: at most 30 % wider in decades than what must be shown.
        assert math.log10(high / low) <= 1.3 * math.log10(shown.max() / shown.min()) + 0.05
    else:
        assert low <= shown.min() and high >= shown.max()
        assert high - low <= 1.3 * (shown.max() - shown.min())


def test_comparison_curves_do_not_stretch_the_axes():
    """fig 20.19: the Coulomb-only fit plunges to 0 before the record ends; the axis still
    spans only the data and the selected fit (about 1.8 decades, not 3)."""
    analysis = dict(ANALYSES)["fig20_19_all_three.csv"]
    figure = analysis.figure()
    axes = next(a for a in figure.axes if a.get_title().startswith("amplitudes"))
    low, high = axes.get_ylim()
    assert low <= analysis.fit.y.min() and high >= analysis.fit.y.max()
    assert math.log10(high / low) < 2.2  # the data span 1.8 decades
    legend = {t.get_text() for t in axes.get_legend().get_texts()}
    assert "Coulomb only (c)" in legend  # on scale over most of the record


def test_the_default_panels_are_todays():
    analysis = dict(ANALYSES)["fig20_19_all_three.csv"]
    figure = analysis.figure()
    titles = {TITLES[a.get_title()] for a in figure.axes if a.get_title() in TITLES}
    assert titles == set(DEFAULT_PANELS) == {"record", "amplitude", "q", "rate"}


def test_binned_medians_ignore_an_outlier_and_give_the_medians_error():
    rng = np.random.default_rng(3)
    x = rng.uniform(0.1, 1.0, 400)
    y = 0.2 + rng.normal(0.0, 0.01, x.size)
    y[17] = -4.8
    bins = binned_medians(x, y, bins=5)
    assert bins.count.sum() == 400 and np.all(bins.count == 80)
    np.testing.assert_allclose(bins.y, 0.2, atol=4 * 0.0125 / math.sqrt(80))
    # The standard error of a median is sqrt(pi/2) sigma/sqrt(n) for Gaussian scatter.
    np.testing.assert_allclose(bins.error, math.sqrt(math.pi / 2) * 0.01 / math.sqrt(80),
                               rtol=0.3)
    # Each bin's x is the median amplitude of its fifth of the sorted amplitudes.
    np.testing.assert_allclose(bins.x, [np.median(c) for c in np.array_split(np.sort(x), 5)])


def test_binned_rates_are_robust_and_their_errors_are_the_scatters():
    """Amplitudes exp(-0.2 t) with 1 % noise and one crest misread: every bin's rate is
    0.2 within 4 of its errors, and over 200 records the errors match the rates' spread
    (independent: the spread is measured, the errors are propagated from sigma)."""
    rng = np.random.default_rng(7)
    t = np.arange(80) * 0.5
    estimates, errors = [], []
    for _ in range(200):
        y = np.exp(-0.2 * t) * (1 + rng.normal(0.0, 0.01, t.size))
        bins = binned_rates(t, y, 0.01 * np.exp(-0.2 * t))
        estimates.append(bins.y)
        errors.append(bins.error)
    estimates, errors = np.array(estimates), np.array(errors)
    # sqrt(pi/2) is the median's large-sample factor; for the 4 slopes of a bin it is
    # about 1.1: the errors may be up to 20 % large, never small.
    ratio = errors.mean(axis=0) / estimates.std(axis=0)
    assert np.all(ratio > 0.9) and np.all(ratio < 1.35)
    y = np.exp(-0.2 * t)
    y[30] *= 50.0
    bins = binned_rates(t, y * (1 + rng.normal(0.0, 0.01, t.size)), 0.01 * y)
    assert np.all(np.abs(bins.y - 0.2) <= 4 * bins.error)


def test_the_rate_panel_shows_binned_medians_on_the_model():
    """fig 20.19 (a, b, c known; reduced chi-square about 1): each bin's median damping rate
    lies within 4 error bars of c/y + b + a*y at the bin's amplitude."""
    analysis = dict(ANALYSES)["fig20_19_all_three.csv"]
    axes = next(a for a in analysis.figure().axes if a.get_title().startswith("damping rate"))
    container = next(c for c in axes.containers if c.get_label() == "median in amplitude bin")
    x, y = (np.asarray(v) for v in container.lines[0].get_data())
    errors = np.array([abs(s[1][1] - s[0][1]) / 2 for s in container.lines[2][0].get_segments()])
    v = analysis.fit.values
    model = decay.decay_rate(x, v["a"], v["b"], v["c"]) / x
    assert x.size >= 5 and np.all(errors > 0)
    assert np.all(np.abs(y - model) <= 4 * errors)


def test_one_wild_rate_does_not_squash_the_rate_panel():
    """A crest misread by a factor 100 gives a rate far off (about -4.8/s at fig 20.19's
    scale); the panel keeps the bulk in view and says a point is off scale."""
    analysis = dict(ANALYSES)["fig20_19_all_three.csv"]
    fit = analysis.fit
    y = fit.y.copy()
    y[40] *= 60.0
    spoiled = replace(analysis, fit=replace(fit, y=y))
    axes = next(a for a in spoiled.figure().axes if a.get_title().startswith("damping rate"))
    low, high = axes.get_ylim()
    assert low > 0.05 and high < 0.6  # the true rates run from 0.15 to 0.45 per second
    assert any("off scale" in t.get_text() for t in axes.texts)


def test_full_periods_cancel_an_offset_equilibrium():
    """Crests of period 2 s whose half-periods alternate 0.9 and 1.1 s (an offset
    equilibrium) give periods of exactly 2 s; a skipped crest breaks the run."""
    t = np.cumsum(np.r_[0.0, np.tile([0.9, 1.1], 10)])
    y = np.linspace(1.0, 0.5, t.size)
    amplitude, period = full_periods(t, y, 2.0)
    np.testing.assert_allclose(period, 2.0, rtol=1e-12)
    np.testing.assert_allclose(amplitude, y[1:-1])
    gap = np.delete(t, 7)
    assert full_periods(gap, np.delete(y, 7), 2.0)[1].size == t.size - 2 - 3


def test_unit_title_panels_and_size_from_the_command_line(tmp_path):
    path = tmp_path / "fig.png"
    result = CliRunner().invoke(cli, [str(ROOT / "sample_data" / "fig20_19_all_three.csv"),
                                      "--plot", str(path), "--unit", "mm", "--title",
                                      "Fig. 20.19", "--panels", "amplitude,qamp",
                                      "--figsize", "8,5"])
    assert result.exit_code == 0, result.output
    width, height = struct.unpack(">II", path.read_bytes()[16:24])
    assert (width, height) == (880, 550)  # 110 dpi
    analysis = dict(ANALYSES)["fig20_19_all_three.csv"]
    figure = analysis.figure("Fig. 20.19", panels="amplitude,qamp", unit="mm")
    assert figure.get_suptitle() == "Fig. 20.19"
    labels = {a.get_title(): a.get_ylabel() for a in figure.axes}
    assert labels["amplitudes: selected fit against single-regime fits"] == "amplitude (mm)"
    box = next(t.get_text() for a in figure.axes for t in a.texts if "a (" in t.get_text())
    assert "a (1/(mm*s))" in box and "c (mm/s)" in box


def test_dpi_sets_the_pngs_pixels(tmp_path):
    path = tmp_path / "fig.png"
    result = CliRunner().invoke(cli, [str(ROOT / "sample_data" / "fig20_19_all_three.csv"),
                                      "--plot", str(path), "--figsize", "8,5", "--dpi", "50",
                                      "--panels", "amplitude,qamp"])
    assert result.exit_code == 0, result.output
    assert struct.unpack(">II", path.read_bytes()[16:24]) == (400, 250)


@pytest.mark.parametrize("arguments, message", [
    (["--dpi", "0"], "--dpi"),
    (["--panels", "amplitude,bogus"], "--panels"),
    (["--panels", "q,q"], "--panels"),
    (["--figsize", "8"], "--figsize"),
    (["--figsize", "0,5"], "--figsize"),
])
def test_bad_figure_options_are_usage_errors(tmp_path, arguments, message):
    result = CliRunner().invoke(cli, [str(ROOT / "sample_data" / "fig20_19_all_three.csv"),
                                      "--plot", str(tmp_path / "f.png"), *arguments])
    assert result.exit_code == 2 and message in result.output
    assert not (tmp_path / "f.png").exists()


def test_figure_options_need_a_figure():
    result = CliRunner().invoke(cli, [str(ROOT / "sample_data" / "fig20_19_all_three.csv"),
                                      "--title", "Run 3"])
    # --unit is not one of them: it names the signal's unit for every output.
    assert result.exit_code == 2 and "--title" in result.output and "--plot" in result.output


def test_a_multi_run_file_gives_one_titled_figure_per_run(tmp_path):
    result = CliRunner().invoke(cli, [str(ROOT / "sample_data" / "capstone_runs.csv"),
                                      "--plot", str(tmp_path / "runs.png"), "--panels",
                                      "backbone", "--title", "Capstone", "--figsize", "8,4",
                                      "--method", "turning-points"])
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"runs-run{n}.png"
                                                           for n in range(1, 6)]


@pytest.mark.skipif(not (REALDATA / "pendulum_cup").is_dir(), reason="no real records")
def test_a_pendulum_fit_draws_its_period_law():
    """The large-swing pendulum (83 degrees): the backbone's curve is T0*2K(k)/pi and the
    measured periods lengthen with amplitude as it does (within their error bars x 4)."""
    from mcfit.fit.pendulum import period_ratio

    analysis = mcfit.analyse_file(str(REALDATA / "pendulum_cup" / "trial1_rawdata.txt"),
                                  signal_col=2, pendulum=True)
    view = record_view(analysis)
    assert view.unit == "rad"
    axes = next(a for a in report_figure(view, analysis.fit, panels=["backbone"]).axes
                if a.get_title().startswith("period"))
    law = next(line for line in axes.get_lines() if line.get_label().startswith("pendulum"))
    x, y = (np.asarray(v) for v in law.get_data())
    np.testing.assert_allclose(y, analysis.fit.small_angle_period * period_ratio(x))
    bins = next(c for c in axes.containers if c.get_label() == "median in amplitude bin")
    bx, by = (np.asarray(v) for v in bins.lines[0].get_data())
    errors = np.array([abs(s[1][1] - s[0][1]) / 2 for s in bins.lines[2][0].get_segments()])
    expected = analysis.fit.small_angle_period * period_ratio(bx)
    assert np.all(np.abs(by - expected) <= 4 * errors + 2e-3)


@pytest.mark.parametrize("model", ["power", "none", "b"])
def test_every_panel_draws_for_a_forced_model(model):
    """A power law, no damping and a single regime: every panel is drawn and the ranges
    are finite (no parts of Q where one term is the total)."""
    analysis = mcfit.analyse_file(str(ROOT / "sample_data" / "fig20_21_soup_can.csv"),
                                  model=model, method="turning-points")
    panels = _panels(analysis.figure(panels=PANELS))
    assert set(panels) == set(PANELS)
    for axes in panels.values():
        assert all(math.isfinite(v) for v in axes.get_ylim())
    if model == "b":
        legend = {t.get_text() for t in panels["q"].get_legend().get_texts()}
        assert not any(label.startswith("Q hysteretic") for label in legend)


def test_curves_differ_in_dash_pattern_not_colour_alone():
    """Printed in grey, the selected fit and the single-regime fits, and the parts of Q,
    stay apart by their dash patterns."""
    analysis = dict(ANALYSES)["fig20_19_all_three.csv"]
    panels = _panels(analysis.figure())
    for name in ("amplitude", "q"):
        lines = [line for line in panels[name].get_lines()
                 if not line.get_label().startswith("_") and line.get_linestyle() != "None"]
        dashes = [(line.get_linestyle(), str(line._unscaled_dash_pattern)) for line in lines]
        assert len(lines) >= 4 and len(set(dashes)) == len(lines), name


def _box_text(figure):
    return next(t.get_text() for a in figure.axes for t in a.texts
                if "reduced chi-square" in t.get_text())


def test_the_box_counts_samples_for_a_waveform_fit_and_turning_points_otherwise():
    path = str(ROOT / "sample_data" / "capstone_runs.csv")
    waveform = mcfit.analyse_file(path, run=4, method="waveform")
    assert waveform.fit.method == "waveform" and waveform.fit.n_points > waveform.turning.count
    box = _box_text(waveform.figure(panels="record"))
    assert f"{waveform.fit.n_points} samples, reduced chi-square" in box
    assert "turning points" not in box
    crests = mcfit.analyse_file(path, run=4, method="turning-points")
    box = _box_text(crests.figure(panels="record"))
    assert f"{crests.turning.count} turning points, reduced chi-square" in box


def test_a_crest_left_out_before_the_release_is_drawn_on_the_record():
    """A pendulum held aside at 20 (plus an offset) for 3 s, then let go: the crest left out
    before the release is drawn where the record is at its time, within the signal's range,
    not at its half-cycle fit's magnitude above it; the used ones at their amplitudes."""
    t = np.arange(0.0, 30.0, 0.02)
    s = np.clip(t - 3.0, 0.0, None)
    x = decay.amplitude(s, 20.0, 0.002, 0.03, 0.04) * np.cos(2 * np.pi * s)
    x[t < 3.0] = 20.0
    x += 0.3 + np.random.default_rng(1).normal(0.0, 0.05, t.size)
    # A window from the start keeps the held part (else the free decay is placed after
    # it before the turning points are looked for): its crest is left out there.
    analysis = mcfit.analyse(t, x, model="abc", method="turning-points", start=0.0)
    turning = analysis.turning
    left_out = ~turning.used
    assert "before release" in turning.excluded_reason
    view = record_view(analysis)
    assert np.all(view.turning_x[left_out] <= x.max())
    np.testing.assert_allclose(view.turning_x[left_out], np.interp(turning.t[left_out], t, x))
    used = turning.used
    np.testing.assert_allclose(view.turning_x[used], turning.equilibrium_at(turning.t[used])
                               + turning.sign[used] * turning.y[used])


def _note(axes):
    return "\n".join(t.get_text() for t in axes.texts if "off scale" in t.get_text())


def test_a_part_of_q_off_scale_is_named_with_its_values():
    """fig20_19: Q hysteretic = omega/(2 b) = 62.6 lies above the Q-against-amplitude
    range (15 to 45); the panel says so with its value, and draws no such curve."""
    analysis = dict(ANALYSES)["fig20_19_all_three.csv"]
    fit = analysis.fit
    axes = _panels(analysis.figure(panels="qamp"))["qamp"]
    q_hysteretic = 2 * np.pi / analysis.turning.period / (2 * fit.values["b"])
    assert axes.get_ylim()[1] < q_hysteretic
    assert f"Q hysteretic off scale ({q_hysteretic:.3g})" in _note(axes)
    assert "Q hysteretic" not in {line.get_label() for line in axes.get_lines()}


@pytest.mark.skipif(not (REALDATA / "pendulum_cup").is_dir(), reason="no real records")
def test_the_pendulums_q_coulomb_off_scale_is_named():
    analysis = mcfit.analyse_file(str(REALDATA / "pendulum_cup" / "lab1_data.txt"),
                                  signal_col=2, pendulum=True)
    axes = _panels(analysis.figure(panels="q"))["q"]
    coulomb = analysis.fit.q_parts["coulomb"]
    assert np.nanmin(coulomb) > axes.get_ylim()[1]
    assert "Q Coulomb off scale" in _note(axes)


def test_the_q_band_is_listed_only_where_it_shows():
    """fig20_19: Q 14 to 38 known to +-0.1 on axes to 120 (the band is a tenth of the
    line's width): no band, and the total says so. A short noisy record: Q known to a
    few percent, the band is drawn and listed."""
    axes = _panels(dict(ANALYSES)["fig20_19_all_three.csv"].figure(panels="q"))["q"]
    labels = {t.get_text() for t in axes.get_legend().get_texts()}
    assert "95 % band" not in labels and not axes.collections
    assert "Q total (95 % band narrower than the line)" in labels
    t = np.arange(0.0, 12.0, 0.02)
    x = decay.amplitude(t, 1.0, 0.0, 0.1, 0.0) * np.cos(2 * np.pi * t)
    x += np.random.default_rng(3).normal(0.0, 0.03, t.size)
    noisy = mcfit.analyse(t, x, model="b", method="turning-points")
    axes = _panels(noisy.figure(panels="q"))["q"]
    labels = {t.get_text() for t in axes.get_legend().get_texts()}
    assert {"95 % band", "Q total"} <= labels and len(axes.collections) == 1
    half = noisy.fit.interval_factor * noisy.fit.q_stderr
    points = axes.get_window_extent().height * 72 / axes.figure.dpi / axes.get_ylim()[1]
    assert np.max(half) * points > 1.0 + 1.9 / 2


def test_a_single_regime_fit_off_the_amplitude_scale_is_named():
    """A comparison fit wholly above the amplitudes (its y0 made 100 times the record's)
    is not listed in the legend and the panel's foot says it is off scale."""
    analysis = dict(ANALYSES)["fig20_19_all_three.csv"]
    fit = analysis.fit
    candidates = tuple(replace(c, values={**c.values, "y0": 100 * c.values["y0"]})
                       if c.model == "c" else c for c in fit.candidates)
    view = record_view(analysis)
    figure = report_figure(view, replace(fit, candidates=candidates), panels="amplitude")
    axes = _panels(figure)["amplitude"]
    assert "Coulomb only (c) off scale" in _note(axes)
    labels = {t.get_text() for t in axes.get_legend().get_texts()}
    assert "Coulomb only (c)" not in labels and "fluid only (a)" in labels


def test_a_waveform_fit_shows_its_turning_points_against_its_law_in_percent():
    """A waveform fit fitted the samples: the strip under the amplitudes gives the turning
    points' gap from its law in percent (a crest of exp(-0.8 t) cos(2 pi t) stands
    1 - cos(atan(0.8/omega_d)) = 0.82 % below the envelope) and says it was not fitted,
    with the word for b the damping form gives."""
    from mcfit.io import Record

    t = np.arange(0.0, 6.0, 1 / 400)
    x = np.exp(-0.8 * t) * np.cos(2 * np.pi * t)
    x = x + 1e-4 * np.random.default_rng(3).standard_normal(t.size)
    analysis = analyse_record(Record(source="viscous", t=t, x=x))
    assert analysis.fit.method == "waveform" and analysis.fit.damping_form == "velocity"
    figure = analysis.figure()
    strip = next(a for a in figure.axes if a.get_ylabel() == "point - law (%)")
    gap = strip.lines[-1].get_ydata()
    omega_d = math.sqrt((2 * np.pi) ** 2 - 0.8**2)
    assert np.median(gap) == pytest.approx(-100 * (1 - math.cos(math.atan(0.8 / omega_d))),
                                           abs=0.1)
    assert any("not fitted: the waveform was" in text.get_text() for text in strip.texts)
    box = "\n".join(text.get_text() for a in figure.axes for text in a.texts)
    assert "viscous damping" in box and "hysteretic" not in box
