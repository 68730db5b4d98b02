"""Byte-level helpers of the G-code scanning kernel (numba): numbers, letters, comments."""

from __future__ import annotations

import numpy as np

from flowtwin._jit import njit

__all__ = ["MAX_ABS_VALUE"]

_POW10 = np.array([10.0 ** i for i in range(23)])

#: Comment prefixes that carry nothing the reader uses (per-line widths and heights, wipe
#: and timing marks: the nominal width of a move follows from its E and the bead model
#: [001 Eq. 7]). The kernel skips these lines instead of handing them to Python; they are
#: by far the most frequent comments (PrusaSlicer writes a ``;WIDTH:`` per extrusion).
_SKIP_COMMENTS = (b";WIDTH:", b"; LINE_WIDTH:", b";HEIGHT:", b";WIPE_START", b";WIPE_END",
                  b"; WIPE_START", b"; WIPE_END", b";TIME_ELAPSED:", b";PRINTING_TIME:",
                  b";REMAINING_TIME:")
_SKIP_LEN = np.array([len(p) for p in _SKIP_COMMENTS], dtype=np.int64)
_SKIP_BYTES = np.zeros((len(_SKIP_COMMENTS), int(_SKIP_LEN.max())), dtype=np.uint8)
for _k, _p in enumerate(_SKIP_COMMENTS):
    _SKIP_BYTES[_k, : len(_p)] = np.frombuffer(_p, dtype=np.uint8)


@njit(cache=True, nogil=True)
def _skippable_comment(buf, i, eol):  # type: ignore[no-untyped-def]
    """True if the comment at ``buf[i]`` starts with one of :data:`_SKIP_COMMENTS`."""
    for k in range(_SKIP_LEN.shape[0]):
        n = _SKIP_LEN[k]
        if i + n > eol:
            continue
        same = True
        for j in range(n):
            if buf[i + j] != _SKIP_BYTES[k, j]:
                same = False
                break
        if same:
            return True
    return False
#: Largest coordinate accepted (mm); beyond this a number is an error, not a position.
MAX_ABS_VALUE = 1.0e9


@njit(cache=True, inline="always")
def _upper(c: int) -> int:
    if 97 <= c <= 122:
        return c - 32
    return c


@njit(cache=True, nogil=True)
def _parse_number_long(buf, i, end):  # type: ignore[no-untyped-def]
    """:func:`_parse_number` for more than 18 digits (the mantissa leaves int64)."""
    neg = False
    if i < end and (buf[i] == 45 or buf[i] == 43):  # - +
        neg = buf[i] == 45
        i += 1
    mant = 0
    ndig = 0
    frac = 0
    seen_dot = False
    big = 0.0
    use_big = False
    while i < end:
        c = buf[i]
        if 48 <= c <= 57:
            if ndig < 18:
                mant = mant * 10 + (c - 48)
            else:
                if not use_big:
                    big = float(mant)
                    use_big = True
                big = big * 10.0 + (c - 48)
            ndig += 1
            if seen_dot:
                frac += 1
            i += 1
        elif c == 46 and not seen_dot:  # '.'
            seen_dot = True
            i += 1
        else:
            break
    if ndig == 0:
        return 0.0, i, False
    if use_big:
        val = big / (10.0 ** frac)
    elif frac <= 22:
        val = float(mant) / _POW10[frac]
    else:
        val = float(mant) / (10.0 ** frac)
    if neg:
        val = -val
    return val, i, True


@njit(cache=True, inline="always")
def _parse_number(buf, i, end):  # type: ignore[no-untyped-def]
    """Parse ``[+-]digits[.digits]`` at ``buf[i]``; return (value, next_index, ok).

    The digits form an integer mantissa (exact up to 18 digits) divided by a power of ten:
    the quotient of two exact doubles is correctly rounded (15 significant digits and
    fewer, every number a slicer writes); longer numbers take :func:`_parse_number_long`.
    """
    first = i
    neg = False
    if i < end and (buf[i] == 45 or buf[i] == 43):  # - +
        neg = buf[i] == 45
        i += 1
    digits = i
    mant = 0
    while i < end:
        d = buf[i] - 48
        if d < 0 or d > 9:
            break
        mant = mant * 10 + d
        i += 1
    ndig = i - digits
    frac = 0
    if i < end and buf[i] == 46:  # '.'
        i += 1
        f0 = i
        while i < end:
            d = buf[i] - 48
            if d < 0 or d > 9:
                break
            mant = mant * 10 + d
            i += 1
        frac = i - f0
        ndig += frac
    if ndig == 0:
        return 0.0, i, False
    if ndig > 18:
        return _parse_number_long(buf, first, end)
    val = float(mant) / _POW10[frac]
    if neg:
        val = -val
    return val, i, True


@njit(cache=True, inline="always")
def _is_word_end(c: int) -> bool:
    # space, tab, CR, ';', '*', or a letter starts the next word
    return (c == 32 or c == 9 or c == 13 or c == 59 or c == 42
            or (65 <= c <= 90) or (97 <= c <= 122))


