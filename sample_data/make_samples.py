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

# name: simulate options (handbook scenes, THEORY.md section 6)
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


if __name__ == "__main__":
    main()
