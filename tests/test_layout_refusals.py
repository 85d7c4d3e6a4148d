"""Records in the layouts of lab software that were refused as "beating of two modes" (issue
26): a Logger Pro video analysis of a large pendulum and a LabVIEW .lvm record of a struck
tuning fork, written by the tests in each export's layout. Both were refused at 6877af3;
the decay before the floor or the noise is fitted, and a note says where it ends."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from mcfit.cli import cli


def _logger_pro(path, seed):
    """Logger Pro's text export of a video analysis at 5 frames/s: a pendulum of period
    2.17 s swinging 40 cm, b = 0.013/s (180 cycles in 391 s), positions on a grid of 0.3
    cm pixels, and an equilibrium that drifts by 6 cm over the last 61 s (the camera or
    the support moving)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 391.0, 0.2)
    x = 40.0 * np.exp(-0.013 * t) * np.cos(2 * np.pi * t / 2.17)
    x += np.where(t > 330.0, 6.0 * ((t - 330.0) / 61.0) ** 2, 0.0)
    x = np.round((x + rng.normal(0.0, 0.1, t.size)) / 0.3) * 0.3
    velocity = np.gradient(x, t)
    head = ("Vernier Format 2\npendulum.cmbl 4/16/2021 11:27:25 .\nLatest\n"
            "Time\tX\tX Velocity\nt\tx\tvx\ns\tcm\tcm/s\n\n")
    path.write_text(head + "".join(f"{a:.1f}\t{b:.4f}\t{v:.4f}\n"
                                   for a, b, v in zip(t, x, velocity)))


def _labview_fork(path, seed):
    """A LabVIEW measurement file at 10 kHz of a struck 440 Hz tuning fork, b = 2.3/s, that
    decays into noise of 0.01 V by about 2 s, with a 1 ms glitch of 0.5 V at 2.53 s."""
    rng = np.random.default_rng(seed)
    t = np.arange(30_000) / 10_000
    x = np.exp(-2.3 * t) * np.sin(2 * np.pi * 440.0 * t) + rng.normal(0.0, 0.01, t.size)
    x += np.where((t >= 2.53) & (t < 2.531), 0.5, 0.0)
    block = ("LabVIEW Measurement\t\nWriter_Version\t2\nSeparator\tTab\nDecimal_Separator\t,"
             "\nDate\t2021/04/16\nTime\t11:27:25,437502\n***End_of_Header***\t\n\n"
             f"Channels\t1\t\nSamples\t{t.size}\t\nX_Dimension\tTime\t\n"
             "Delta_X\t0,000100\t\n***End_of_Header***\t\n")
    rows = "".join(f"{a:.6f}\t{v:.6f}\t\n".replace(".", ",") for a, v in zip(t, x))
    path.write_text(block + "X_Value\tVoltage\tComment\n" + rows)


@pytest.mark.parametrize("write, name, seed, b", [
    (_logger_pro, "pendulum.txt", 0, 0.013),
    (_logger_pro, "pendulum.txt", 1, 0.013),
    (_labview_fork, "fork.lvm", 1, 2.3),
])
def test_a_decay_into_a_floor_or_noise_is_fitted_not_refused_as_beating(
        tmp_path, write, name, seed, b):
    """6877af3 refused these ("the amplitude ... falls to -1.34 at t = 356.7 and rises
    again to 2.05 at t = 357.8: beating of two modes"; the fork: "falls to -0.0135 at
    t = 1.907 and rises again to 0.0138 at t = 1.924"). The decay is fitted by the
    turning points, b within 3 standard errors, and a note says where the decay ends."""
    path = tmp_path / name
    write(path, seed)
    result = CliRunner().invoke(cli, [str(path), "--format", "json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["status"] == "ok" and data["method"] == "turning-points"
    assert abs(data["params"]["b"]["value"] - b) < 3 * data["params"]["b"]["stderr"]
    assert not any("beating" in w for w in data["warnings"])
    assert any(note.startswith(("the decay ends in the noise", "the motion stops by",
                                "noise floor: the crest phase is lost"))
               for note in data["notes"])
