"""Decoding the bytes of a text record: encoding, byte-order marks, binary data, NUL padding."""

from __future__ import annotations

import re

from mcfit.errors import InputError
from mcfit.io.limits import MAX_BYTES, too_large

# Control characters other than tab, newline, vertical tab, form feed and carriage return.
_CONTROL_CHARACTER = re.compile("[\x00-\x08\x0e-\x1f\x7f-\x9f]")
# The ASCII bytes that are not control characters (deleted to count the others).
_NOT_CONTROL_BYTES = bytes(b for b in range(128) if not _CONTROL_CHARACTER.match(chr(b)))


def _utf16_without_bom(head):
    """'utf-16-le' or 'utf-16-be' when every other byte is NUL (ASCII text in UTF-16)."""
    sample = head[: 1 << 16]
    if len(sample) < 8 or b"\x00" not in sample:
        return None
    pairs = len(sample) // 2
    odd_nul = sample[1:2 * pairs:2].count(0)
    even_nul = sample[0:2 * pairs:2].count(0)
    if odd_nul >= 0.9 * pairs and even_nul <= 0.02 * pairs:
        return "utf-16-le"
    if even_nul >= 0.9 * pairs and odd_nul <= 0.02 * pairs:
        return "utf-16-be"
    return None


def _binary_problem(text):
    """A description of the binary bytes in decoded text, or None for plain text."""
    if "\x00" in text:
        return "NUL bytes"
    window = text[: 1 << 16]
    if window.isascii():  # the usual case: bytes.translate counts several times faster
        control = len(window.encode("ascii").translate(None, _NOT_CONTROL_BYTES))
    else:
        control = len(_CONTROL_CHARACTER.findall(window))
    if control > max(2, 0.01 * min(len(text), 1 << 16)):
        return "control bytes"
    return None


def _decode(head):
    """(text, encoding, note, exact) for the sniffed bytes; ``exact`` is True when every
    byte was decoded as pandas will decode it (nothing cut, ignored or replaced)."""
    if head.startswith(b"\xef\xbb\xbf"):
        text, exact = _decode_leniently(head[3:], "utf-8", "ignore")
        return text, "utf-8-sig", "byte-order mark skipped", exact
    if head.startswith((b"\xff\xfe", b"\xfe\xff")):
        text, exact = _decode_leniently(head, "utf-16", "ignore")
        return text, "utf-16", "UTF-16 text", exact
    utf16 = _utf16_without_bom(head)
    if utf16 is not None:
        cut = len(head) - len(head) % 2
        text, exact = _decode_leniently(head[:cut], utf16, "replace")
        return text, utf16, "UTF-16 text without a byte-order mark", exact and cut == len(head)
    try:
        return head.decode("utf-8"), "utf-8", None, True
    except UnicodeDecodeError as exc:
        if exc.start > len(head) - 4:  # a character cut by the sniff limit
            return head[:exc.start].decode("utf-8"), "utf-8", None, False
        return head.decode("latin-1"), "latin-1", None, True


def _decode_leniently(data, encoding, errors):
    """(text, exact): strict decoding if it works, else decoding with ``errors``."""
    try:
        return data.decode(encoding), True
    except UnicodeDecodeError:
        return data.decode(encoding, errors=errors), False


def _read_whole(name, path):
    try:
        with open(path, "rb") as stream:
            data = stream.read(MAX_BYTES + 1)
    except OSError as exc:
        raise InputError(f"cannot read {name}: {exc.strerror}. Check its permissions.") from None
    if len(data) > MAX_BYTES:  # it grew since it was opened
        raise too_large(name, "the file", len(data), MAX_BYTES)
    return data


def _drop_trailing_nul(text):
    """(text, note): NUL bytes at the very end (a copy cut short by a power loss) dropped,
    with the incomplete last line; text unchanged (no note) when NULs are elsewhere too."""
    kept = text.rstrip("\x00")
    if "\x00" in kept or not kept.strip():
        return text, None
    dropped = len(text) - len(kept)
    note = f"{dropped} NUL bytes at the end dropped (the file was cut short, as by a power "
    if kept.endswith(("\n", "\r")):
        return kept, note + "loss while copying)"
    return kept[:max(kept.rfind("\n"), 0)] + "\n", note + ("loss while copying), with the "
                                                            "incomplete last line")
