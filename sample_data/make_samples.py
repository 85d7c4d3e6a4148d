"""Regenerate the sample records: python sample_data/make_samples.py (from the repository root).

Each waveform is written by `mcfit simulate` with a fixed seed; the Excel file and the
turning-point table are made from simulate's output / the closed form.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).parent

# name: simulate options (handbook scenes, docs/theory.md section 9)
SCENES = {
    "fig20_19_all_three.csv": "--a 0.1 --b 0.1 --c 0.01 --y0 4 --period 0.5 --duration 20 "
                              "--rate 100 --noise 0.005 --offset 0.3 --seed 1",
    "fig20_21_soup_can.csv": "--a 0.22 --y0 1 --period 0.5 --duration 20 --rate 100 "
                             "--noise 0.002 --seed 2",
    "fig20_22_evacuated.csv": "--a 0.0012 --b 0.0004 --y0 1 --period 1 --duration 1400 "
                              "--rate 16 --noise 0.0005 --drift 2e-6 --seed 3",
    "coulomb_stop.csv": "--b 0.02 --c 0.01 --y0 1 --period 1 --duration 90 --rate 50 "
                        "--noise 0.001 --seed 4",
}


def simulate(name: str, options: str) -> None:
    command = [sys.executable, "-m", "mcfit", "simulate", *options.split(), "-o",
               str(HERE / name)]
    subprocess.run(command, check=True)


# A PASCO Capstone export of five runs of a rotary pendulum (rad), the eddy-current magnet
# moved closer each run (b grows), the bearing's friction c the same; runs end at
# different times and are padded with empty cells.
CAPSTONE_RUNS = [(0.03 + 0.02 * k, 40.0 - 5.0 * k) for k in range(5)]


def capstone_runs(path: Path) -> None:
    import tempfile

    columns = {}
    with tempfile.TemporaryDirectory() as folder:
        for k, (b, duration) in enumerate(CAPSTONE_RUNS, start=1):
            name = str(Path(folder) / f"run{k}.csv")
            simulate(name, f"--b {b} --c 0.004 --y0 0.8 --period 1.6 --duration {duration} "
                           f"--rate 25 --noise 0.001 --seed {10 + k}")
            run = pd.read_csv(name)
            columns[f"Time (s) Run #{k}"] = run["t"].round(2)
            columns[f"Angle, Ch 1+2 (rad) Run #{k}"] = run["x"].round(4)
            columns[f"Angular Velocity, Ch 1+2 (rad/s) Run #{k}"] = np.gradient(
                run["x"], run["t"]).round(3)
    frame = pd.DataFrame({name: pd.Series(values) for name, values in columns.items()})
    frame.to_csv(path, index=False)


def ni_waveform(path: Path) -> None:
    """An NI LabVIEW "Write Waveforms to Spreadsheet" CSV of an RLC circuit's ringing
    (V_C, 500 kHz): a preamble (waveform, t0, delta t, a blank line), the header, and
    time stamps as dates with microseconds; the trigger column steps to 5 V."""
    from datetime import datetime, timedelta

    with tempfile_csv() as name:
        simulate(name, "--b 500 --y0 1 --period 3.3333333e-4 --duration 0.006 "
                       "--rate 500000 --noise 0.002 --seed 6")
        run = pd.read_csv(name)
    start = datetime(2021, 4, 16, 11, 27, 25, 437502)

    def stamp(k):
        moment = start + timedelta(microseconds=2 * k)
        return f"{moment.month}/{moment.day}/{moment.year}  {moment:%H:%M:%S.%f}"
    lines = ["waveform,Trig,V_C", f"t0,{stamp(0)},{stamp(0)}",
             "delta t,2.000000E-6,2.000000E-6", "", "time,Trig,V_C"]
    lines += [f"{stamp(k)},{5.0 if k >= 50 else 0.0:.6f},{v:.6f}"
              for k, v in enumerate(run["x"])]
    path.write_text("\n".join(lines) + "\n")


def phyphox_xls(path: Path) -> None:
    """A phyphox "Excel" export (legacy .xls) of a gyroscope on a pendulum: the swing is
    about z, x and y hold noise. Written with xlwt (a test dependency)."""
    import xlwt

    with tempfile_csv() as name:
        simulate(name, "--a 0.3 --b 0.05 --y0 1.5 --period 1.6 --duration 40 --rate 50 "
                       "--noise 0.003 --seed 7")
        run = pd.read_csv(name)
    rng = np.random.default_rng(8)
    columns = {"Time (s)": run["t"], "Rotation x (rad/s)": rng.normal(0.0, 0.01, run.shape[0]),
               "Rotation y (rad/s)": rng.normal(0.002, 0.01, run.shape[0]),
               "Rotation z (rad/s)": run["x"]}
    book = xlwt.Workbook()
    sheet = book.add_sheet("Raw Data")
    for j, (label, values) in enumerate(columns.items()):
        sheet.write(0, j, label)
        for i, value in enumerate(values):
            sheet.write(i + 1, j, round(float(value), 6))
    book.save(str(path))


def pipe_table(path: Path) -> None:
    """A markdown pipe table of a short decay, as pasted from a lab notebook."""
    with tempfile_csv() as name:
        simulate(name, "--b 0.2 --y0 2 --period 1 --duration 10 --rate 20 --noise 0.002 "
                       "--seed 9")
        run = pd.read_csv(name)
    lines = ["| t (s) | angle (deg) |", "|---:|---:|"]
    lines += [f"| {t:.2f} | {x:.4f} |" for t, x in zip(run["t"], run["x"])]
    path.write_text("\n".join(lines) + "\n")


def simulated(options: str) -> pd.DataFrame:
    """The record ``mcfit simulate`` writes with ``options``, as a frame (t, x)."""
    with tempfile_csv() as name:
        simulate(name, options)
        return pd.read_csv(name)


def labview_lvm(path: Path) -> None:
    """A LabVIEW measurement file: two header blocks, X_Value, decimal commas, and the
    empty Comment column LabVIEW adds (a pendulum's angle sensor at 50 Hz)."""
    run = simulated("--a 0.2 --b 0.03 --y0 0.6 --period 1.4 --duration 30 --rate 50 "
                    "--noise 0.001 --seed 10")
    block = ("LabVIEW Measurement\t\nWriter_Version\t2\nSeparator\tTab\nDecimal_Separator\t,"
             "\nDate\t2021/04/16\nTime\t11:27:25,437502\n***End_of_Header***\t\n\n"
             f"Channels\t1\t\nSamples\t{run.shape[0]}\t\nX_Dimension\tTime\t\n"
             "Delta_X\t0,020000\t\n***End_of_Header***\t\n")
    rows = "".join(f"{t:.6f}\t{x:.6f}\t\n".replace(".", ",") for t, x in zip(run["t"], run["x"]))
    path.write_text(block + "X_Value\tAngle\tComment\n" + rows)


def logger_pro(path: Path) -> None:
    """A Vernier Logger Pro text export: a header block, names, short names and units
    rows, and the velocity column it computes (a cart on springs at 20 Hz)."""
    run = simulated("--b 0.08 --c 0.002 --y0 0.12 --period 1.2 --duration 40 --rate 20 "
                    "--noise 0.0005 --seed 11")
    velocity = np.gradient(run["x"], run["t"])
    head = ("Vernier Format 2\nsprings.cmbl 4/16/2021 11:27:25 .\nLatest\n"
            "Time\tPosition\tVelocity\nt\tx\tv\ns\tm\tm/s\n\n")
    rows = "".join(f"{t:.2f}\t{x:.5f}\t{v:.4f}\n"
                   for t, x, v in zip(run["t"], run["x"], velocity))
    path.write_text(head + rows)


def tracker(path: Path) -> None:
    """A Tracker (Open Source Physics) export of a video at 30 frames/s: a "mass A" line
    above the header and times printed to 3 significant figures."""
    run = simulated("--a 0.5 --y0 0.25 --period 1.5 --duration 30 --rate 30 "
                    "--noise 0.0008 --seed 12")
    times = [np.format_float_positional(v, precision=3, unique=False, fractional=False)
             .rstrip(".") for v in run["t"]]
    rows = "".join(f"{t}\t{x:.4f}\n" for t, x in zip(times, run["x"]))
    path.write_text("mass A\nt\tx\n" + rows)


def serial_logs(monitor: Path, logger: Path) -> None:
    """An Arduino reading a potentiometer on a pendulum (10-bit counts, 50 Hz): as the
    IDE's serial monitor shows it with timestamps (``16:04:31.273 -> 812``), and as a
    sketch prints it with its own millis() time."""
    from datetime import datetime, timedelta

    run = simulated("--b 0.1 --c 4 --y0 300 --period 1.3 --duration 30 --rate 50 "
                    "--noise 1 --seed 13")
    counts = np.round(512 + run["x"]).astype(int)
    start = datetime(2021, 4, 16, 16, 4, 31, 273000)
    monitor.write_text("".join(f"{start + timedelta(seconds=float(t)):%H:%M:%S.%f}"[:-3]
                               + f" -> {c}\n" for t, c in zip(run["t"], counts)))
    logger.write_text("millis,adc\n" + "".join(f"{4312 + round(1000 * t)},{c}\n"
                                                for t, c in zip(run["t"], counts)))


# The struck tuning fork of tuning_fork_wav: its truth, which tests check the fit against.
FORK = {"frequency": 440.0, "q": 2000.0, "amplitude": 0.5, "rate": 8000, "duration": 3.0,
        "noise": 2e-4, "seed": 14}


def tuning_fork_wav(path: Path) -> None:
    """A struck 440 Hz tuning fork at a microphone, Q = 2000 (b = pi*f/Q = 0.6912 1/s):
    3 s of 16-bit mono PCM at 8 kHz, half full scale at the strike, a little noise."""
    from scipy.io import wavfile

    f, rate = FORK["frequency"], FORK["rate"]
    t = np.arange(round(FORK["duration"] * rate)) / rate
    b = np.pi * f / FORK["q"]
    x = FORK["amplitude"] * np.exp(-b * t) * np.cos(2 * np.pi * f * t)
    x += np.random.default_rng(FORK["seed"]).normal(0.0, FORK["noise"], t.size)
    wavfile.write(path, rate, np.round(x * 32768).astype(np.int16))


def tempfile_csv():
    """A context giving the name of a CSV file in a temporary folder."""
    import contextlib
    import tempfile

    @contextlib.contextmanager
    def named():
        with tempfile.TemporaryDirectory() as folder:
            yield str(Path(folder) / "run.csv")
    return named()


def main() -> None:
    for name, options in SCENES.items():
        simulate(name, options)
    # Excel: the soup-can record with a header carrying units.
    frame = pd.read_csv(HERE / "fig20_21_soup_can.csv")
    frame.columns = ["time (s)", "angle (rad)"]
    frame.to_excel(HERE / "fig20_21_soup_can.xlsx", sheet_name="soup can", index=False)
    # Fig. 20.20's form: peak speed per swing (cm/s) against cycle number n.
    rng = np.random.default_rng(5)
    from mcfit import decay

    n = np.arange(0, 40)
    speed = decay.amplitude(n, 7.69, 0.036, 0.025, 0.0) + rng.normal(0.0, 0.01, n.size)
    table = pd.DataFrame({"n": n, "peak speed (cm/s)": np.round(speed, 4)})
    with open(HERE / "fig20_20_peak_speed_cycles.csv", "w") as stream:
        stream.write("# peak speed per swing from a photogate, against cycle number n\n")
        table.to_csv(stream, index=False)
    capstone_runs(HERE / "capstone_runs.csv")
    ni_waveform(HERE / "ni_waveform.csv")
    phyphox_xls(HERE / "phyphox_gyroscope.xls")
    pipe_table(HERE / "pipe_table.md")
    labview_lvm(HERE / "labview.lvm")
    logger_pro(HERE / "logger_pro.txt")
    tracker(HERE / "tracker.txt")
    serial_logs(HERE / "serial_monitor.txt", HERE / "serial_logger.csv")
    tuning_fork_wav(HERE / "tuning_fork.wav")


if __name__ == "__main__":
    main()
