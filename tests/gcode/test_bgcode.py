"""Prusa binary G-code (.bgcode) against an independent implementation.

Oracle: PyPI ``pybgcode-jneilliii`` (Python binding of Prusa's libbgcode, a test-only
dependency). Text original: Debian PrusaSlicer 2.5 fine-segment print
(``tests/data/PROVENANCE.md``) with two thumbnails added to its header (the 2.5 CLI
renders none).
"""

from __future__ import annotations

import base64
import gzip
import io
import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from flowtwin.errors import GcodeError
from flowtwin.gcode.bgcode import (
    BgcodeOptions,
    ChecksumType,
    Compression,
    GcodeEncoding,
    iter_blocks,
    text_to_bgcode,
)
from flowtwin.gcode.bgcode.meatpack import drop_empty_lines, pack, unpack
from flowtwin.gcode.reader import read_gcode
from flowtwin.gcode.writer import rewrite_gcode

pybgcode = pytest.importorskip("pybgcode")

DATA = Path(__file__).resolve().parents[1] / "data"
KINEMATIC = ["x", "y", "z", "e", "de", "feed_mm_s", "flow", "tool", "kind"]


def _oracle_config(gcode: Compression = Compression.HEATSHRINK_12_4,
                   encoding: GcodeEncoding = GcodeEncoding.MEATPACK_COMMENTS,
                   metadata: Compression | None = None, checksum: ChecksumType | None = None):
    c = pybgcode.get_config()
    c.compression.gcode = pybgcode.CompressionType(int(gcode))
    c.gcode_encoding = pybgcode._bgcode.GCodeEncodingType(int(encoding))
    if metadata is not None:
        for kind in ("file_metadata", "printer_metadata", "print_metadata", "slicer_metadata"):
            setattr(c.compression, kind, pybgcode.CompressionType(int(metadata)))
    if checksum is not None:
        c.checksum = pybgcode._bgcode.ChecksumType(int(checksum))
    return c


def oracle_to_binary(src: Path, dst: Path, **config) -> None:
    i, o = pybgcode.open(str(src), "r"), pybgcode.open(str(dst), "wb")
    try:
        res = pybgcode.from_ascii_to_binary(i, o, _oracle_config(**config))
    finally:
        pybgcode.close(i)
        pybgcode.close(o)
    assert res == pybgcode.EResult.Success, res


def oracle_to_text(src: Path, dst: Path) -> bytes:
    i, o = pybgcode.open(str(src), "rb"), pybgcode.open(str(dst), "w")
    try:
        res = pybgcode.from_binary_to_ascii(i, o, True)
    finally:
        pybgcode.close(i)
        pybgcode.close(o)
    assert res == pybgcode.EResult.Success, res
    return dst.read_bytes()


@pytest.fixture(scope="module")
def original(tmp_path_factory) -> Path:
    """The text print with a PNG and a QOI thumbnail in its header."""
    text = gzip.decompress((DATA / "prusaslicer_2.5_cylinder_fine.gcode.gz").read_bytes())
    lines = text.split(b"\n")
    thumbs = []
    for word, size, payload in (("thumbnail", "16x16", bytes(range(256)) * 3),
                                ("thumbnail_QOI", "8x4", b"qoif" + bytes(90))):
        b64 = base64.b64encode(payload).decode()
        rows = [b64[k:k + 78] for k in range(0, len(b64), 78)]
        thumbs += [";", f"; {word} begin {size} {len(b64)}", *(f"; {r}" for r in rows),
                   f"; {word} end", ";", ""]
    lines[2:2] = [t.encode() for t in thumbs]
    path = tmp_path_factory.mktemp("bgcode") / "cylinder.gcode"
    path.write_bytes(b"\n".join(lines))
    return path


def _same_moves(a, b, columns=KINEMATIC) -> None:
    assert len(a.moves) == len(b.moves)
    for col in columns:
        np.testing.assert_array_equal(a.moves[col], b.moves[col], err_msg=col)


def _events(table):
    return [(e.move_index, e.code, e.params) for e in table.events]


CASES = [(gc, enc, None, None) for gc, enc in itertools.product(Compression, GcodeEncoding)]
CASES += [(Compression.HEATSHRINK_11_4, GcodeEncoding.MEATPACK_COMMENTS, Compression.DEFLATE,
           ChecksumType.NONE),
          (Compression.DEFLATE, GcodeEncoding.NONE, Compression.HEATSHRINK_12_4, None),
          (Compression.NONE, GcodeEncoding.MEATPACK, Compression.HEATSHRINK_11_4, None)]


@pytest.mark.parametrize(("gcode", "encoding", "metadata", "checksum"), CASES,
                         ids=lambda v: getattr(v, "name", str(v)))
def test_oracle_files_read_as_their_text(original, tmp_path, gcode, encoding, metadata,
                                         checksum):
    binary = tmp_path / "oracle.bgcode"
    oracle_to_binary(original, binary, gcode=gcode, encoding=encoding, metadata=metadata,
                     checksum=checksum)
    assert binary.read_bytes()[:4] == b"GCDE"
    text = read_gcode(original)
    got = read_gcode(binary)
    # the moves of the text original (line numbers differ: the oracle moves the header)
    columns = KINEMATIC + ([] if encoding == GcodeEncoding.MEATPACK else ["layer", "feature"])
    _same_moves(text, got, columns)
    assert [(c, p) for _, c, p in _events(got)] == [(c, p) for _, c, p in _events(text)]
    # everything, line numbers included, as the oracle's own text of the file
    back = tmp_path / "oracle.gcode"
    oracle_to_text(binary, back)
    ref = read_gcode(back)
    np.testing.assert_array_equal(got.moves, ref.moves)
    assert _events(got) == _events(ref)
    assert got.n_lines == ref.n_lines
    meta = dict(got.metadata)
    info = meta.pop("bgcode")
    meta_ref = dict(ref.metadata)
    assert meta == meta_ref
    assert meta["slicer"] == "PrusaSlicer" and meta["slicer_version"] == "2.5.0"
    assert info["gcode_encoding"] == encoding.name
    assert info["compression"]["gcode"] == gcode.name
    assert info["thumbnails"] == ["PNG 16x16", "QOI 8x4"]
    assert info["checksum"] == (ChecksumType.CRC32 if checksum is None else checksum).name


def test_meatpack_round_trip_keeps_commands_and_comments(original):
    text = drop_empty_lines(original.read_bytes())
    kept = b"".join((ln if ln.startswith(b";") else ln.split(b";")[0].strip()) + b"\n"
                    for ln in text.split(b"\n") if ln)
    assert drop_empty_lines(unpack(pack(text, keep_comments=True))) == kept
    commands = [ln.split(b";")[0].strip() for ln in text.split(b"\n")]
    assert drop_empty_lines(unpack(pack(text, keep_comments=False))) == b"".join(
        c + b"\n" for c in commands if c)
    # spacing a reader cannot restore is written as it is
    odd = b"G1  X1 Y2\n  G1 X1 ; note\nM117 Hello  World\ng1 x2\nG1 X1\tY2\n"
    assert unpack(pack(odd, keep_comments=True)) == (
        b"G1  X1 Y2\nG1 X1\nM117 Hello  World\ng1 x2\nG1 X1 Y2\n")


WRITE_CASES = [(gc, enc) for gc, enc in itertools.product(Compression, GcodeEncoding)]


@pytest.mark.parametrize(("gcode", "encoding"), WRITE_CASES,
                         ids=lambda v: getattr(v, "name", str(v)))
def test_written_files_read_back_by_oracle(original, tmp_path, gcode, encoding):
    # canonical text: what the oracle makes of the original (its header layout)
    ref_bin = tmp_path / "ref.bgcode"
    oracle_to_binary(original, ref_bin, gcode=gcode, encoding=encoding)
    ref_text = oracle_to_text(ref_bin, tmp_path / "ref.gcode")
    canonical = tmp_path / "canonical.gcode"
    oracle_to_binary(original, tmp_path / "c.bgcode", encoding=GcodeEncoding.NONE)
    canonical.write_bytes(oracle_to_text(tmp_path / "c.bgcode", tmp_path / "c.gcode"))
    mine = tmp_path / "mine.bgcode"
    options = BgcodeOptions(gcode=gcode, gcode_encoding=encoding, printer_metadata=gcode)
    blocks = text_to_bgcode(canonical, mine, options=options)
    assert blocks == sum(b.type == 1 for b in iter_blocks(open(ref_bin, "rb"), "ref"))
    assert oracle_to_text(mine, tmp_path / "mine.gcode") == ref_text
    # and flowtwin reads its own file as the text it was made from
    _same_moves(read_gcode(mine), read_gcode(tmp_path / "mine.gcode"), [*KINEMATIC, "line"])


def test_bgcode_text_bgcode_keeps_every_block(original, tmp_path):
    first = tmp_path / "a.bgcode"
    oracle_to_binary(original, first)
    second = tmp_path / "b.bgcode"
    text_to_bgcode(first, second)
    a = list(iter_blocks(open(first, "rb"), "a"))
    b = list(iter_blocks(open(second, "rb"), "b"))
    assert [(x.type, x.compression, x.params, x.data) for x in a if x.type != 1] == \
           [(x.type, x.compression, x.params, x.data) for x in b if x.type != 1]
    # the same G-code (cut into blocks at other places: the oracle cuts before encoding)
    assert b"".join(x.data for x in a if x.type == 1) == \
           b"".join(x.data for x in b if x.type == 1)
    assert {(x.compression, x.params) for x in b if x.type == 1} == \
           {(Compression.HEATSHRINK_12_4, (GcodeEncoding.MEATPACK_COMMENTS,))}


def test_rewrite_edits_a_bgcode_and_keeps_it_binary(original, tmp_path):
    src = tmp_path / "in.bgcode"
    oracle_to_binary(original, src)
    table = read_gcode(src)
    line = int(table.moves["line"][100])
    dst = tmp_path / "out.bgcode"
    rewrite_gcode(src, dst, {line: "G1 X100 Y100 E0.5"})
    assert dst.read_bytes()[:4] == b"GCDE"
    text = oracle_to_text(dst, tmp_path / "out.gcode").split(b"\n")
    assert text[line - 1] == b"G1 X100 Y100 E0.5"
    before = oracle_to_text(src, tmp_path / "in.gcode").split(b"\n")
    assert [i for i, (x, y) in enumerate(zip(before, text, strict=True)) if x != y] == [line - 1]


def test_stream_without_seek(original, tmp_path):
    binary = tmp_path / "oracle.bgcode"
    oracle_to_binary(original, binary)

    class Pipe(io.RawIOBase):
        def __init__(self, data: bytes) -> None:
            self._data = io.BytesIO(data)

        def readable(self) -> bool:
            return True

        def readinto(self, b):  # a pipe returns short reads
            chunk = self._data.read(min(len(b), 1000))
            b[:len(chunk)] = chunk
            return len(chunk)

    piped = read_gcode(io.BufferedReader(Pipe(binary.read_bytes())))
    np.testing.assert_array_equal(piped.moves, read_gcode(binary).moves)


# ------------------------------------------------------------------ corrupt files ---

@pytest.fixture(scope="module")
def valid(original, tmp_path_factory) -> bytes:
    path = tmp_path_factory.mktemp("corrupt") / "ok.bgcode"
    oracle_to_binary(original, path)
    return path.read_bytes()


def _blocks(data: bytes):
    return list(iter_blocks(io.BytesIO(data), "x", decode_gcode=False))


def test_flipped_byte_names_block_offset_and_crc(valid, tmp_path):
    gcode_blocks = [b for b in _blocks(valid) if b.type == 1]
    target = gcode_blocks[3]
    bad = bytearray(valid)
    bad[target.offset + 40] ^= 0x10
    path = tmp_path / "flipped.bgcode"
    path.write_bytes(bytes(bad))
    with pytest.raises(GcodeError) as err:
        read_gcode(path)
    msg = str(err.value)
    assert str(path) in msg and f"block {target.index} at byte {target.offset}" in msg
    assert "CRC32 mismatch" in msg


def test_truncated_file(valid, tmp_path):
    path = tmp_path / "cut.bgcode"
    path.write_bytes(valid[:len(valid) - 1000])
    last = _blocks(valid)[-1]
    with pytest.raises(GcodeError, match=rf"block {last.index} at byte {last.offset}.*truncated"):
        read_gcode(path)


def test_bad_magic_and_version():
    with pytest.raises(GcodeError, match="does not start with 'GCDE'"):
        list(iter_blocks(io.BytesIO(b"GCDX" + bytes(6)), "x"))
    with pytest.raises(GcodeError, match="unsupported binary G-code version; got 7"):
        list(iter_blocks(io.BytesIO(b"GCDE" + (7).to_bytes(4, "little") + bytes(2)), "x"))


def test_unknown_compression_and_undecodable_data(valid):
    blocks = _blocks(valid)
    g = next(b for b in blocks if b.type == 1)
    bad = bytearray(valid)
    bad[g.offset + 2] = 9
    where = rf"block {g.index} at byte {g.offset}"
    with pytest.raises(GcodeError, match=where + ".*unknown compression 9"):
        list(iter_blocks(io.BytesIO(bytes(bad)), "x"))
    # without checksums a damaged heatshrink stream is caught by its size
    path_free = bytearray(valid)
    path_free[8] = 0   # checksum type NONE: the CRCs are now read as block bytes
    with pytest.raises(GcodeError, match="corrupt binary G-code"):
        list(iter_blocks(io.BytesIO(bytes(path_free)), "x"))


def test_cli_plan_reads_bgcode(original, tmp_path):
    binary = tmp_path / "p.bgcode"
    oracle_to_binary(original, binary)
    from typer.testing import CliRunner

    from flowtwin.cli.main import app

    a = CliRunner().invoke(app, ["plan", str(binary), "--json"])
    b = CliRunner().invoke(app, ["plan", str(original), "--json"])
    assert a.exit_code == 0, a.output
    assert b.exit_code == 0, b.output
    ja, jb = json.loads(a.output), json.loads(b.output)
    for key in ("total_time_s", "net_filament_mm", "moves", "layers", "time_by_feature_s"):
        assert ja[key] == jb[key], key


def test_corrupt_bgcode_cli_message(valid, tmp_path, capsys):
    bad = bytearray(valid)
    bad[len(bad) // 2] ^= 0xFF
    path = tmp_path / "bad.bgcode"
    path.write_bytes(bytes(bad))
    from flowtwin.cli.main import main

    with pytest.raises(SystemExit) as exc:
        main(["plan", str(path)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "bad.bgcode [block" in err and "CRC32 mismatch" in err and "Traceback" not in err
