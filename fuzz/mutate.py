"""Mutation operators: text lines, numbers, bytes (all driven by one ``random.Random``)."""

from __future__ import annotations

import random
import re

#: numbers a parser meets at its edges
BOUNDARY_NUMBERS = ("0", "-0", "+0", "0.0", "-0.0", ".5", "5.", "1e308", "-1e308", "1e309",
                    "1e-320", "nan", "NaN", "inf", "-inf", "Infinity", "9" * 40, "-" + "9" * 40,
                    "1.2.3", "", "+", "-", ".", "1e", "e5", "0x10", "1_000", "١٢", "1,5",
                    "2147483648", "-2147483649", "18446744073709551616", "0.000001",
                    "999999999", "1e9", "-1e9", "1000000001", "3.4028236e38")
_NUMBER = re.compile(rb"-?\d+(?:\.\d*)?|-?\.\d+")
_ODD_TEXT = ("\t", "\r", "\x0b", "\x0c", "\xa0", "\u2028", "µ", "€", "\ufeff", "\x7f",
             "(comment)", ";", "*", "*123", "N", "%", "\\", '"', "'", "<script>", "\x01")


def mutate_line(rng: random.Random, line: bytes) -> bytes:
    """One random edit of a G-code line: a number, a word, a letter or odd text."""
    choice = rng.randrange(10)
    if choice <= 3:  # replace one number with a boundary value
        spans = [m.span() for m in _NUMBER.finditer(line)]
        if spans:
            a, b = rng.choice(spans)
            return line[:a] + rng.choice(BOUNDARY_NUMBERS).encode() + line[b:]
    if choice == 4:  # drop a character
        if line:
            i = rng.randrange(len(line))
            return line[:i] + line[i + 1:]
    if choice == 5:  # duplicate a word
        words = line.split(b" ")
        i = rng.randrange(len(words))
        words.insert(i, words[i])
        return b" ".join(words)
    if choice == 6:  # insert odd text
        i = rng.randrange(len(line) + 1)
        return line[:i] + rng.choice(_ODD_TEXT).encode() + line[i:]
    if choice == 7:  # change a letter
        letters = [i for i, c in enumerate(line) if 65 <= c <= 90 or 97 <= c <= 122]
        if letters:
            i = rng.choice(letters)
            return line[:i] + bytes([rng.choice(b"GMTXYZEFSPIJRKQNLABCDHUVW")]) + line[i + 1:]
    if choice == 8:  # lower case
        return line.lower()
    return flip_bytes(rng, line, 1)


def flip_bytes(rng: random.Random, data: bytes, count: int) -> bytes:
    """``data`` with ``count`` random bytes replaced by random values."""
    if not data:
        return bytes([rng.randrange(256)])
    buf = bytearray(data)
    for _ in range(count):
        buf[rng.randrange(len(buf))] = rng.randrange(256)
    return bytes(buf)


def mutate_bytes(rng: random.Random, data: bytes) -> bytes:
    """A structural edit of a whole file: flip, truncate, splice, repeat or empty."""
    choice = rng.randrange(8)
    if choice <= 2:
        return flip_bytes(rng, data, 1 + rng.randrange(8))
    if choice == 3 and data:
        return data[:rng.randrange(len(data))]
    if choice == 4 and data:
        a = rng.randrange(len(data))
        b = rng.randrange(len(data))
        return data[:a] + data[b:]
    if choice == 5 and data:
        a = rng.randrange(len(data))
        return data[:a] + data[a:a + rng.randrange(1, 64)] * rng.randrange(2, 50) + data[a:]
    if choice == 6:
        return b""
    lines = data.split(b"\n")
    i = rng.randrange(len(lines))
    lines[i] = mutate_line(rng, lines[i])
    return b"\n".join(lines)


def mutate_text_lines(rng: random.Random, text: bytes, edits: int) -> bytes:
    """``edits`` line edits (number, word, letter, odd text) of a text file."""
    lines = text.split(b"\n")
    for _ in range(edits):
        i = rng.randrange(len(lines))
        lines[i] = mutate_line(rng, lines[i])
    return b"\n".join(lines)
