"""The reader's compiled paths against independent references: numbers, running E,
feature/layer columns, buffer growth, checksum precedence, chunking."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from flowtwin.errors import GcodeError
from flowtwin.gcode._bytes import _parse_number, _parse_number_long
from flowtwin.gcode.inputs import line_chunks
from flowtwin.gcode.moves import MoveKind
from flowtwin.gcode.reader import ReadOptions, iter_move_chunks, read_gcode


def _checksummed(body: str) -> str:
    x = 0
    for ch in body.encode():
        x ^= ch
    return f"{body}*{x}"


def test_number_fast_path_agrees_with_long_path_and_python() -> None:
    rng = np.random.default_rng(11)
    alphabet = np.array(list(b"0123456789.-+ eX:/"), dtype=np.uint8)
    for _ in range(3000):
        raw = rng.choice(alphabet, size=int(rng.integers(0, 24))).astype(np.uint8)
        buf = np.concatenate((raw, np.array([10], dtype=np.uint8)))
        fast = _parse_number(buf, 0, raw.size)
        slow = _parse_number_long(buf, 0, raw.size)
        assert fast[1:] == slow[1:]
        if fast[2]:
            assert fast[0] == slow[0] and math.copysign(1, fast[0]) == math.copysign(1, slow[0])
    # up to 15 significant digits the value is float(text) exactly (correct rounding);
    # 19+ digits leave int64 and must take the long path (a wrapped mantissa is garbage)
    for text in ("-0", "123456789.012345", "0.000000000000001", "999999999999999",
                 "1234567890123456789012", "0.1234567890123456789"):
        buf = np.frombuffer(text.encode() + b"\n", dtype=np.uint8)
        value, end, ok = _parse_number(buf, 0, len(text))
        assert ok and end == len(text)
        if len(text.strip("-0.")) <= 15:
            assert value == float(text)
        else:
            assert value == pytest.approx(float(text), rel=1e-15)


def test_running_e_is_the_cumulative_sum_per_tool_across_chunks() -> None:
    lines = ["M83", "M207 S1.5 F1800"]
    rng = np.random.default_rng(3)
    for i in range(400):
        if i % 37 == 0:
            lines.append(f"T{int(rng.integers(0, 3))}")
        if i % 53 == 0:
            lines.append("G10")  # firmware retraction: rows added by Python
            lines.append("G11")
        if i % 71 == 0:
            lines.append("G92 E0")
        lines.append(f"G1 X{i % 50}.{i % 7} Y{i % 13} E{rng.uniform(-0.5, 1.0):.5f}")
    data = ("\n".join(lines) + "\n").encode()
    whole = read_gcode(data)
    moves = whole.moves
    assert (moves["kind"] & MoveKind.FW_RETRACT).any() and len(np.unique(moves["tool"])) == 3
    for tool in np.unique(moves["tool"]):
        sel = moves["tool"] == tool
        # summed in file order, as numpy's (sequential) cumulative sum does
        assert np.array_equal(moves["e"][sel], np.cumsum(moves["de"][sel]))
    parts = np.concatenate([p.moves for p in iter_move_chunks(data, chunk_bytes=333)])
    assert np.array_equal(parts["e"], moves["e"])


def test_feature_and_layer_columns_follow_the_markers() -> None:
    rng = np.random.default_rng(5)
    lines, features, layers = ["M83"], [], []
    feature_names = ["Perimeter", "Solid infill", "Skirt"]
    feature, layer = -1, -1
    for _ in range(2000):
        r = rng.uniform()
        if r < 0.05:
            name = feature_names[int(rng.integers(0, 3))]
            lines.append(f";TYPE:{name}")
            feature = name  # type: ignore[assignment]
        elif r < 0.07:
            lines.append(";LAYER_CHANGE")
            layer += 1
        elif r < 0.09:
            lines.append("  \t;TYPE:Skirt\r")  # comment-only line after blanks
            feature = "Skirt"  # type: ignore[assignment]
        else:
            lines.append(f"G1 X{rng.uniform(0, 100):.3f} E0.01")
            features.append(feature)
            layers.append(layer)
    data = ("\n".join(lines) + "\n").encode()
    whole = read_gcode(data)
    names = [whole.features[i] if i >= 0 else -1 for i in whole.moves["feature"]]
    assert names == features
    assert whole.moves["layer"].tolist() == layers
    parts = list(iter_move_chunks(data, chunk_bytes=400))
    joined = np.concatenate([p.moves for p in parts])
    assert np.array_equal(joined["feature"], whole.moves["feature"])
    assert np.array_equal(joined["layer"], whole.moves["layer"])


def test_row_buffer_grows_for_dense_moves_and_long_arcs() -> None:
    # ~6 bytes per row (far more rows per byte than the initial estimate) and one arc of
    # floor(2π·50 / 0.01) = 31415 segments
    dense = "".join(f"G1X{i % 10}\n" for i in range(1, 30001))
    data = ("G1 X50 Y0\n" + dense + "G1 X50 Y0\nG2 X50 Y0 I-50 J0\n" + dense).encode()
    opts = ReadOptions(arc_segment_mm=0.01)
    whole = read_gcode(data, options=opts)
    n_arc = int(math.floor(2 * math.pi * 50 / 0.01))
    # every dense line moves except where X repeats (never: i % 10 changes each line)
    assert len(whole.moves) == 1 + 30000 + 1 + n_arc + 30000
    assert np.count_nonzero(whole.moves["kind"] & MoveKind.ARC) == n_arc
    parts = np.concatenate([p.moves for p in iter_move_chunks(data, chunk_bytes=50_000,
                                                              options=opts)])
    for name in whole.moves.dtype.names or ():
        assert np.array_equal(parts[name], whole.moves[name]), name


@pytest.mark.parametrize(("line", "match"), [
    ("N3 G1 X1.2.3*98", "checksum"),           # a bad word and a bad checksum: checksum
    (_checksummed("N3 G1 X1.2.3"), r"\[X\]"),  # checksum right: the word is named
    ("N4 SET_VELOCITY_LIMIT ACCEL=5*1", "checksum"),
    ("N5 *1", "checksum"),
    ("Nx G1 X1", "malformed word"),
])
def test_checksum_is_checked_before_the_words(line: str, match: str) -> None:
    with pytest.raises(GcodeError, match=rf":2\b.*{match}"):
        read_gcode(f"G1 X0\n{line}\n".encode())


def test_comment_text_reaches_the_metadata_as_before() -> None:
    t = read_gcode(b"N5 ;TYPE:Skirt\nG1 X1 E1\n;caf\xe9\n\t ;TYPE:Perimeter \r\nG1 X2 E1\n")
    assert [t.features[i] for i in t.moves["feature"]] == ["Skirt", "Perimeter"]
    assert any(":3: bytes that are not UTF-8" in w for w in t.warnings)


def test_line_chunks_cut_only_after_line_breaks() -> None:
    rng = np.random.default_rng(9)
    for _ in range(300):
        data = bytes(rng.choice(np.frombuffer(b"ab\n", np.uint8), size=int(rng.integers(0, 300))))
        size = int(rng.integers(1, 64))
        pieces = list(line_chunks(io.BytesIO(data), "x", size))
        assert b"".join(pieces) == data
        assert all(p.endswith(b"\n") for p in pieces[:-1])
        assert all(p for p in pieces)
        # the last piece ends on a break unless the data does not
        assert not pieces or pieces[-1].endswith(b"\n") == data.endswith(b"\n")


@pytest.mark.parametrize("line", ["M221 S-5", "M221 S0", "M220 S0", "M220 S-50"])
def test_speed_and_flow_factors_must_be_positive(line: str) -> None:
    # the kernel used to take these silently (negative flow, zero feed rates)
    with pytest.raises(GcodeError, match=r":2 \[S\]: M22[01] .* must be positive"):
        read_gcode(f"G1 X1\n{line}\nG1 X2 E1\n".encode())
    ok = read_gcode(b"M83\nM221 S90\nM220 S50\nG1 X1 E1 F600\n").moves
    assert (float(ok["flow"][0]), float(ok["feed_mm_s"][0])) == (pytest.approx(0.9), 5.0)
