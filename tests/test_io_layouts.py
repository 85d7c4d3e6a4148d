"""The table of export layouts: every entry's sample reads, and its words reach the reader."""

from pathlib import Path

import pytest

from mcfit.io import read_records
from mcfit.io.layouts import LAYOUTS, recognised_layout

SAMPLES = Path(__file__).parents[1] / "sample_data"


@pytest.mark.parametrize("layout", [lay for lay in LAYOUTS if lay.sample],
                         ids=lambda lay: lay.name)
def test_each_layout_sample_is_read_with_its_time_column(layout):
    records = read_records(SAMPLES / layout.sample)
    assert records and all(r.t.size > 100 and r.time_column for r in records)
    recognise = layout.recognise
    if recognise is not None:
        lines = (SAMPLES / layout.sample).read_text(errors="replace").splitlines()
        assert recognised_layout(lines) is layout


def test_a_time_label_of_an_entry_names_the_time(tmp_path):
    # "X_Value" is LabVIEW's time label: chosen although the column before it also rises.
    path = tmp_path / "labview.lvm"
    rows = "\n".join(f"{i}\t{0.01 * i:.2f}\t{(-1) ** i * 0.99 ** i:.5f}" for i in range(200))
    path.write_text("Index\tX_Value\tVoltage\n" + rows + "\n")
    [record] = read_records(path)
    assert record.time_column == "X_Value"


def test_the_run_label_of_an_entry_splits_runs(tmp_path):
    path = tmp_path / "runs.csv"
    lines = ["Time (s) Run #3,Angle (rad) Run #3,Time (s) Run #8,Angle (rad) Run #8"]
    lines += [f"{0.1 * i:.1f},{(-1) ** i * 0.98 ** i:.4f},"
              f"{0.1 * i:.1f},{(-1) ** i * 0.97 ** i:.4f}" for i in range(100)]
    path.write_text("\n".join(lines) + "\n")
    assert [r.run for r in read_records(path)] == ["Run 3", "Run 8"]


@pytest.mark.parametrize("name, model", [
    ("ni_waveform.csv", "b"), ("phyphox_gyroscope.xls", "ab"), ("pipe_table.md", "b"),
    ("labview.lvm", "ab"), ("logger_pro.txt", "bc"), ("tracker.txt", "a"),
    ("serial_monitor.txt", "bc"), ("serial_logger.csv", "bc"),
])
def test_each_export_sample_gives_the_damping_it_was_simulated_with(name, model):
    # make_samples.py simulates each with the terms named here.
    import mcfit
    assert mcfit.analyse_file(str(SAMPLES / name)).fit.model == model
