"""Fuzz targets: how each kind of input is made from real seeds and read by flowtwin.

A target has a name, a file suffix, ``make(rng) -> bytes`` (a document) and
``run(path, rng)`` (read it, and for G-code go on through the command pipelines). Seeds are
real data: the reference corpus (tests/data), the built-in profiles, the Klipper configs the
real-Klipper times were measured with, and CSVs, tables and images that flowtwin itself
writes. Imports of flowtwin happen inside the functions so a worker pays only for what its
targets use.
"""

from __future__ import annotations

import contextlib
import io
import os
import random
import signal
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fuzz.gcode_docs import LinePool, document
from fuzz.mutate import mutate_bytes, mutate_text_lines

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"


@dataclass
class Target:
    """One kind of input."""

    name: str
    suffix: str
    make: Callable[[random.Random], bytes]
    run: Callable[[Path, random.Random], None]
    #: relative share of the campaign's documents
    weight: float = 1.0
    stages: dict[str, int] = field(default_factory=dict)

    def count(self, stage: str) -> None:
        self.stages[stage] = self.stages.get(stage, 0) + 1


def _corpus() -> Path:
    import importlib.util

    spec = importlib.util.spec_from_file_location("flowtwin_fuzz_refdata", DATA / "refdata.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path: Path = module.corpus_dir()
    return path


def _seeded(seeds: list[bytes], edits: Callable[[random.Random, bytes], bytes]
            ) -> Callable[[random.Random], bytes]:
    def make(rng: random.Random) -> bytes:
        data = rng.choice(seeds)
        for _ in range(1 + (rng.random() < 0.3) * rng.randrange(1, 4)):
            data = edits(rng, data)
        return data
    return make


def _text_or_bytes(rng: random.Random, data: bytes) -> bytes:
    if rng.random() < 0.7:
        return mutate_text_lines(rng, data, 1 + rng.randrange(3))
    return mutate_bytes(rng, data)


# ---------------------------------------------------------------- G-code


def gcode_target(seed: int) -> Target:
    """G-code text: read, plan (Klipper and Marlin), simulate; samples compensate and CLI."""
    pool = LinePool(_corpus(), random.Random(seed))
    loaded: dict[str, Any] = {}

    def run(path: Path, rng: random.Random) -> None:
        from flowtwin.gcode.reader import read_gcode
        from flowtwin.planner.plan_file import load_printer, plan_gcode
        from flowtwin.profiles.machine import load_machine
        from flowtwin.simulation import simulate

        if not loaded:  # profiles once per worker: the documents are what is fuzzed
            loaded["machine"] = load_machine("tronvoll2019")
            loaded["printers"] = [load_printer(n) for n in ("generic-klipper", "generic-marlin")]
        data = path.read_bytes()  # the file is read once; the readers take its bytes
        target.count("read")
        read_gcode(data)
        target.count("plan")
        result = plan_gcode(data, printer=rng.choice(loaded["printers"]))
        result.summary()
        result.per_layer()
        target.count("simulate")
        simulate(data, machine=loaded["machine"]).summary()
        if rng.random() < 0.002:
            from flowtwin.compensation import compensate

            target.count("compensate")
            compensate(path, path.with_suffix(".out.gcode"), advance=True, slip=True,
                       pace=rng.random() < 0.3)
        if rng.random() < 0.002:
            target.count("cli")
            _cli([rng.choice(("plan", "simulate")), str(path), "--json"])

    target = Target("gcode", ".gcode", lambda rng: document(rng, pool), run, weight=6.0)
    return target


def _cli(argv: list[str]) -> None:
    """The CLI in-process; exit 0-2 are answers, anything else (or an exception) a failure."""
    from flowtwin.cli.main import main

    os.environ["FLOWTWIN_DEBUG"] = "1"  # internal errors raise instead of printing
    # the CLI turns SIGTERM into an interrupt while it runs; the campaign itself must stay
    # stoppable, so the worker's own handler comes back afterwards
    handler = signal.getsignal(signal.SIGTERM)
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        try:
            main(argv)
        except SystemExit as exc:
            if exc.code not in (None, 0, 1, 2):
                raise RuntimeError(f"CLI exit status {exc.code}") from None
        finally:
            signal.signal(signal.SIGTERM, handler)


def bgcode_target(seed: int) -> Target:
    """Prusa binary G-code: flowtwin's writer on real corpus slices in every storage variant
    (no checksum in half of them, so edits reach the decompressors and MeatPack)."""
    import itertools
    import tempfile

    from flowtwin.gcode.bgcode.format import ChecksumType, Compression, GcodeEncoding
    from flowtwin.gcode.bgcode.write import BgcodeOptions, text_to_bgcode

    corpus = _corpus()
    texts = [b"\n".join((corpus / name).read_bytes().split(b"\n")[:n]) + b"\n"
             for name, n in (("prusaslicer_2.8.1_minicube_small.gcode", 1500),
                             ("prusaslicer_2.7.4_vase.gcode", 600),
                             ("bambustudio_1.07_2colour_cube_small.gcode", 400))]
    seeds: list[bytes] = []
    variants = itertools.product(ChecksumType, (Compression.NONE, Compression.DEFLATE,
                                                Compression.HEATSHRINK_11_4,
                                                Compression.HEATSHRINK_12_4), GcodeEncoding)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "seed.bgcode"
        for i, (check, comp, enc) in enumerate(variants):
            text_to_bgcode(texts[i % len(texts)], out, options=BgcodeOptions(
                checksum=check, gcode=comp, gcode_encoding=enc))
            seeds.append(out.read_bytes())

    def make(rng: random.Random) -> bytes:
        return mutate_bytes(rng, rng.choice(seeds))

    def run(path: Path, rng: random.Random) -> None:
        from flowtwin.gcode.reader import read_gcode
        from flowtwin.planner.plan_file import plan_gcode

        target.count("read")
        read_gcode(path)
        target.count("plan")
        plan_gcode(path).summary()

    target = Target("bgcode", ".bgcode", make, run, weight=1.0)
    return target


# ---------------------------------------------------------------- profiles and configs


def profile_target() -> Target:
    """Profile TOML of every kind (the built-in library as seeds)."""
    data = ROOT / "src" / "flowtwin" / "data"
    seeds = [p.read_bytes() for p in sorted(data.rglob("*.toml"))]

    def run(path: Path, rng: random.Random) -> None:
        from flowtwin.profiles.toml_io import load_profile

        target.count("load")
        load_profile(path)

    target = Target("profile", ".toml", _seeded(seeds, _text_or_bytes), run)
    return target


def klipper_cfg_target() -> Target:
    """Klipper printer.cfg (the oracle's configs as seeds); a config that loads plans."""
    seeds = [p.read_bytes() for p in sorted((DATA / "klipper").glob("*.cfg"))]
    small = b"G28\nG90\nM83\nG1 Z0.2 F600\nG1 X20 Y20 E1 F3000\nG1 X40 Y20 E1\n"

    def run(path: Path, rng: random.Random) -> None:
        from flowtwin.planner.klipper_config import load_printer_cfg
        from flowtwin.planner.plan_file import plan_gcode

        target.count("load")
        load_printer_cfg(path)
        target.count("plan")
        plan_gcode(small, klipper_config=path).summary()

    target = Target("klipper-cfg", ".cfg", _seeded(seeds, _text_or_bytes), run)
    return target


# ---------------------------------------------------------------- measurement files


def records_csv_target() -> Target:
    """Test-stand records CSV (schema 1), seeds written by flowtwin's virtual stand."""
    from flowtwin.profiles import load_rollers
    from flowtwin.teststand import (
        DriveUnderTest,
        Procedure,
        SlipLaw,
        simulate_campaign,
        write_records_csv,
    )

    drive = DriveUnderTest.from_roller(load_rollers()[3], law=SlipLaw.COMBINED, k_p=0.0063)
    records = simulate_campaign(drive, seed=1, procedure=Procedure(
        pinch_forces_n=(40.0, 90.0), speeds_mm_s=(1.0,), repeats=1))
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "seed.csv"
        write_records_csv(path, records)
        full = path.read_bytes()
    lines = full.split(b"\n")
    seeds = [full, b"\n".join(lines[:60]) + b"\n"]

    def run(path: Path, rng: random.Random) -> None:
        from flowtwin.teststand import read_records_csv

        target.count("read")
        read_records_csv(path)

    target = Target("records-csv", ".csv", _seeded(seeds, _text_or_bytes), run)
    return target


def width_csv_target() -> Target:
    """Width-profile CSV of ``calibrate fit-k``."""
    rows = ["position_mm,width_mm,gcode_line"]
    for line in (120, 340):
        rows += [f"{0.5 * i:.2f},{0.45 + 0.01 * ((i * 7) % 5):.3f},{line}" for i in range(40)]
    seeds = ["\n".join(rows).encode() + b"\n",
             b"# measured\nposition_mm,width_mm\n0,0.45\n1,0.46\n2,0.47\n3,0.44\n"]

    def run(path: Path, rng: random.Random) -> None:
        from flowtwin.calibration.fits.lagfit import read_width_profiles

        target.count("read")
        read_width_profiles(path)

    target = Target("width-csv", ".csv", _seeded(seeds, _text_or_bytes), run)
    return target


def orca_table_target() -> Target:
    """OrcaSlicer adaptive pressure-advance tables."""
    seeds = [b"0.04,5,1000\n0.045,10,1000\n0.05,15,1000\n0.035,5,5000\n0.04,10,5000\n"
             b"0.045,15,5000\n", b'"0.04,5,1000\\n0.05,20,1000\\n0.03,5,3000\\n0.04,20,3000"']

    def run(path: Path, rng: random.Random) -> None:
        from flowtwin.calibration.tuning.adaptive_pa import read_orca_model

        target.count("read")
        read_orca_model(path)

    target = Target("orca-pa", ".txt", _seeded(seeds, _text_or_bytes), run, weight=0.5)
    return target


def vision_config_target() -> Target:
    """Vision TOML configs and ``--roi`` strings."""
    seeds = [b'mm_per_px = 0.0206\ncalib_width_mm = 2.87\ndirection = "down"\n'
             b'gear_radius_mm = 4.0\ngear_center_px = [300.0, 180.0]\n\n[rois]\n'
             b'filament = [334, 364, 40, 40]\ngear = [311, 167, 40, 40]\n'
             b'before = [320, 20, 190, 100]\n\n[tracking]\nmax_tracks = 60\n',
             b"[rois]\nfilament = [0, 0, 1, 1]\n"]

    def run(path: Path, rng: random.Random) -> None:
        from flowtwin.vision.config import load_config_file
        from flowtwin.vision.roi import parse_roi

        target.count("load")
        load_config_file(path)
        target.count("roi")
        text = path.read_bytes()[:60].decode("utf-8", "replace")
        parse_roi(text)

    target = Target("vision-config", ".toml", _seeded(seeds, _text_or_bytes), run, weight=0.5)
    return target


def image_target() -> Target:
    """PNG, JPEG, BMP and 16-bit PNG images (encoded by OpenCV from a drawn bead pattern)."""
    import cv2
    import numpy as np

    img = np.full((120, 200), 40, np.uint8)
    for i in range(8):
        cv2.line(img, (10, 10 + 13 * i), (190, 10 + 13 * i), 200, 3)
    seeds = [cv2.imencode(ext, img)[1].tobytes() for ext in (".png", ".jpg", ".bmp")]
    seeds.append(cv2.imencode(".png", img.astype(np.uint16) * 257)[1].tobytes())
    seeds.append(cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_GRAY2BGR))[1].tobytes())

    def make(rng: random.Random) -> bytes:
        return mutate_bytes(rng, rng.choice(seeds))

    def run(path: Path, rng: random.Random) -> None:
        from flowtwin.calibration.image.kimage import load_grey

        target.count("load")
        load_grey(path)

    target = Target("image", ".png", make, run, weight=0.5)
    return target


FACTORIES: dict[str, Callable[[int], Target]] = {
    "gcode": gcode_target,
    "bgcode": bgcode_target,
    "profile": lambda seed: profile_target(),
    "klipper-cfg": lambda seed: klipper_cfg_target(),
    "records-csv": lambda seed: records_csv_target(),
    "width-csv": lambda seed: width_csv_target(),
    "orca-pa": lambda seed: orca_table_target(),
    "vision-config": lambda seed: vision_config_target(),
    "image": lambda seed: image_target(),
}


def all_targets(seed: int, only: list[str] | None = None) -> list[Target]:
    """Every target of the campaign (or those named in ``only``)."""
    return [make(seed) for name, make in FACTORIES.items() if not only or name in only]
