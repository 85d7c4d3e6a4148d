"""WAV audio (a plucked string, a struck bell or tuning fork at a microphone) as a table.

The time axis is the file's sample rate; each channel is a column, ``channel 1``,
``channel 2``...; integer PCM is scaled to full scale (int16 / 32768, 8-bit unsigned
centred on 128), float WAV is taken as it is, so the signal unit is "full scale".
"""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd

from mcfit.errors import InputError

# Samples that guide the choice of columns, as text tables' first lines do.
_SAMPLE_ROWS = 20000
# Samples of a channel (spread over the file) that measure how much it swings.
_LOUDNESS_ROWS = 1 << 20
SIGNAL_UNIT = "full scale"
RIFF_SIGNATURE = b"RIFF"


def is_wav(head):
    """Whether ``head``, a file's first bytes, starts a RIFF WAVE file."""
    return head.startswith(RIFF_SIGNATURE) and head[8:12] == b"WAVE"


def _wav_data(path, name):
    """(rate, samples of shape (n,) or (n, channels), note or None), memory-mapped where
    scipy can; the note says that the file was cut short."""
    from scipy.io import wavfile
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", wavfile.WavFileWarning)  # chunks it skips
        try:
            return (*wavfile.read(path, mmap=True), None)
        except ValueError as exc:  # 24-bit or a cut data chunk: not memory-mapped
            if "mmap" not in str(exc).lower():
                raise _damaged(name, exc) from None
        # scipy's reader fails on a damaged file in many ways (ValueError, EOFError, even
        # UnboundLocalError on a missing format chunk): each is the file's fault.
        except Exception as exc:  # noqa: BLE001
            raise _damaged(name, exc) from None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", wavfile.WavFileWarning)
        try:
            rate, data = wavfile.read(path)
        except Exception as exc:  # noqa: BLE001
            raise _damaged(name, exc) from None
    cut = any("prematurely" in str(w.message) for w in caught)
    note = (f"the file ends before its data do (cut short): the {data.shape[0]} samples it "
            "holds are read" if cut else None)
    return rate, data, note


def _damaged(name, exc):
    told = isinstance(exc, (ValueError, EOFError, OSError)) and str(exc)
    reason = str(exc).splitlines()[0] if told else "its chunks are not those of a WAV file"
    return InputError(f"cannot read {name} as WAV audio ({reason}): the file is damaged or "
                      "not PCM audio. Record or export it again as 16-bit PCM WAV.")


def _scale(dtype):
    """(offset, factor): full scale = (sample - offset) * factor, and the words for it."""
    if dtype.kind == "f":
        return 0.0, 1.0, f"{dtype.itemsize * 8}-bit float samples taken as they are"
    if dtype.kind == "u":  # 8-bit WAV is unsigned, centred on 128
        bits = dtype.itemsize * 8
        middle = 2.0 ** (bits - 1)
        return middle, 1.0 / middle, (f"{bits}-bit unsigned samples centred and scaled to "
                                      f"full scale ((x - {middle:g}) / {middle:g})")
    bits = dtype.itemsize * 8
    return 0.0, 2.0 ** -(bits - 1), (f"{bits}-bit integer samples scaled to full scale "
                                     f"(x / {2 ** (bits - 1)})")


def _wav_table(path, name):
    """A :class:`mcfit.io.table._Table` of a WAV file's channels, ``rate`` set to its rate."""
    from mcfit.io.table import _Table
    rate, data, cut = _wav_data(path, name)
    if data.ndim == 1:
        data = data[:, None]
    if data.shape[0] < 2 or data.shape[1] < 1:
        raise InputError(f"{name} holds {data.shape[0]} audio samples. A decay record needs "
                         "many samples over several cycles.")
    if not rate > 0:
        raise InputError(f"{name} gives a sample rate of {rate} Hz. Record or export it "
                         "again as WAV with its sample rate.")
    offset, factor, how = _scale(data.dtype)
    channels = data.shape[1]

    def scaled(index, rows=slice(None)):
        values = np.asarray(data[rows, index], dtype=np.float64)
        if offset:
            values -= offset
        if factor != 1.0:
            values *= factor
        return values

    def reader(indices, nrows=None, as_text=False):
        rows = slice(None) if nrows is None else slice(0, nrows)
        return pd.DataFrame({k: scaled(i, rows) for k, i in enumerate(indices)})

    names = [f"channel {k + 1} ({SIGNAL_UNIT})" for k in range(channels)]
    sample = pd.DataFrame({k: scaled(k, slice(0, _SAMPLE_ROWS)) for k in range(channels)})
    notes = [f"WAV audio: {data.shape[0]} samples at {rate:g} Hz "
             f"({data.shape[0] / rate:.6g} s), {_count_channels(channels)}; {how}; "
             "time from the file's sample rate"]
    notes += [cut] if cut else []
    table = _Table(name, names, sample, reader, notes, complete=data.shape[0] <= _SAMPLE_ROWS)
    table.rate = float(rate)
    if channels > 1:
        step = max(1, data.shape[0] // _LOUDNESS_ROWS)
        spread = [float(np.std(scaled(k, slice(None, None, step)))) for k in range(channels)]
        table.loudest = int(np.argmax(spread))
    return table


def _count_channels(channels):
    return "1 channel" if channels == 1 else f"{channels} channels"
