"""Serial connection to a Marlin printer: line numbers, checksums, resends, ``ok`` flow.

Marlin's host protocol, as implemented here:

* Every command goes out as ``N<n> <command>*<checksum>`` where the checksum is the XOR of
  all bytes before ``*``, and ``n`` counts up by one. ``M110 N0`` (unnumbered) sets the
  firmware's last line number to 0 after connecting, so the next line is ``N1``.
* The firmware answers each line with ``ok``. On a corrupted or out-of-order line it answers
  ``Error:checksum mismatch, Last Line: k`` / ``Error:Line Number is not Last Line
  Number+1, Last Line: k``, then ``Resend: k+1`` (``rs k+1`` on some builds), then ``ok``;
  the host resends from line ``k+1`` after that ``ok``.
* ``echo:busy: processing`` means "still working": keep waiting.
* Reports come before the ``ok``: ``echo:E0 Flow: 95%`` for ``M221``, ``FR:95%`` for ``M220``.

One command is in flight at a time (the loop sends a multiplier every ~0.5 s, far below the
link's capacity), which keeps the resend logic exact. :class:`MarlinLineCodec` is the pure
protocol layer; :class:`SerialPrinter` moves its bytes over pyserial.
"""

from __future__ import annotations

import re
import time
from dataclasses import dataclass

from flowtwin.control.printer import (
    CommandRejected,
    ConnectionLost,
    Factors,
    FactorTracker,
    Response,
)
from flowtwin.firmware import Channel, Firmware, check_command, parse_factor_report

__all__ = ["MarlinLineCodec", "Reply", "SerialPrinter", "checksum", "parse_reply"]

_RESEND_RE = re.compile(r"^(?:Resend|rs)[:\s]\s*N?(\d+)", re.IGNORECASE)


def checksum(payload: str) -> int:
    """Marlin/RepRap checksum: XOR of the bytes of ``payload`` (ASCII)."""
    cs = 0
    for b in payload.encode("ascii"):
        cs ^= b
    return cs


@dataclass(frozen=True)
class Reply:
    """One line from the firmware, classified.

    ``kind`` is ``"ok"``, ``"resend"`` (``line_no`` set), ``"busy"``, ``"error"``,
    ``"start"`` or ``"info"`` (echo and everything else).
    """

    kind: str
    text: str
    line_no: int | None = None


def parse_reply(line: str) -> Reply:
    """Classify one received line (see :class:`Reply`)."""
    text = line.strip()
    low = text.lower()
    if low == "ok" or low.startswith("ok "):
        return Reply("ok", text)
    m = _RESEND_RE.match(text)
    if m:
        return Reply("resend", text, int(m.group(1)))
    if "busy:" in low:
        return Reply("busy", text)
    if low.startswith("error") or low.startswith("!!"):
        return Reply("error", text)
    if low == "start":
        return Reply("start", text)
    return Reply("info", text)


class MarlinLineCodec:
    """Numbers and checksums outgoing lines and remembers them for resends."""

    def __init__(self) -> None:
        self.next_no = 1
        self._sent: dict[int, bytes] = {}

    def reset_command(self) -> bytes:
        """``M110 N0`` unnumbered: the firmware's next expected line becomes 1."""
        self.next_no = 1
        self._sent.clear()
        return b"M110 N0\n"

    def frame(self, command: str) -> bytes:
        """``N<n> <command>*<cs>\\n`` for the next line number; remembered for resends."""
        if "*" in command or "\n" in command or ";" in command:
            raise ValueError(f"command must be bare G-code without '*', ';' or newline: "
                             f"{command!r}")
        payload = f"N{self.next_no} {command}"
        data = f"{payload}*{checksum(payload)}\n".encode("ascii")
        self._sent[self.next_no] = data
        # Keep a short history: one line in flight, resends only ever go back a few lines.
        self._sent.pop(self.next_no - 64, None)
        self.next_no += 1
        return data

    def resend_from(self, line_no: int) -> list[bytes]:
        """The framed lines from ``line_no`` to the last one sent (for ``Resend:``)."""
        if line_no not in self._sent:
            raise KeyError(line_no)
        return [self._sent[n] for n in range(line_no, self.next_no)]


class SerialPrinter:
    """A Marlin printer on a serial port (pyserial).

    Parameters
    ----------
    port
        Device path (``/dev/ttyUSB0``) or a pyserial URL.
    baudrate
        Line speed (Marlin's default is 115200 or 250000).
    command_timeout_s
        How long one command may go without any reply (``busy`` restarts the wait).
    boot_timeout_s
        How long :meth:`connect` retries ``M110`` while the board boots after the port opens.
    max_resends
        Resend requests tolerated for one command before giving up.
    """

    firmware = Firmware.MARLIN

    def __init__(self, port: str, *, baudrate: int = 115200, command_timeout_s: float = 5.0,
                 boot_timeout_s: float = 10.0, max_resends: int = 5) -> None:
        self.port = port
        self.baudrate = baudrate
        self.command_timeout_s = command_timeout_s
        self.boot_timeout_s = boot_timeout_s
        self.max_resends = max_resends
        self.description = f"serial {port}"
        #: Raw lines written and read, for the log (newest last, capped).
        self.transcript: list[tuple[str, str]] = []
        self._codec = MarlinLineCodec()
        self._tracker = FactorTracker(Firmware.MARLIN)
        self._ser: object | None = None
        self._buf = b""
        self._lost: str | None = None

    # -- connection -----------------------------------------------------------------
    def connect(self) -> None:
        """Open the port and synchronise line numbers with ``M110 N0``."""
        import serial  # pyserial; imported here so the package works without it

        self.close()
        try:
            ser = serial.serial_for_url(self.port, baudrate=self.baudrate, timeout=0.05,
                                        write_timeout=self.command_timeout_s)
        except (serial.SerialException, OSError) as exc:
            raise ConnectionLost(f"cannot open serial port ({exc})", source=self.port) from None
        self._ser = ser
        self._buf = b""
        self._lost = None
        self._tracker.reset()  # opening the port resets a Marlin board
        deadline = time.monotonic() + self.boot_timeout_s
        while True:
            self._write(self._codec.reset_command())
            try:
                self._wait_ok(time.monotonic() + 1.0, resend_ok=False)
                return
            except _NoReply:
                if time.monotonic() > deadline:
                    raise ConnectionLost("no answer to M110 after opening the port",
                                         source=self.port) from None

    def check(self) -> None:
        """Raise :class:`ConnectionLost` after an I/O failure or before connecting."""
        if self._ser is None:
            raise ConnectionLost("not connected", source=self.port)
        if self._lost is not None:
            raise ConnectionLost(f"connection lost ({self._lost})", source=self.port)

    def close(self) -> None:
        """Close the port."""
        ser, self._ser = self._ser, None
        if ser is not None:
            ser.close()  # type: ignore[attr-defined]

    # -- commands -------------------------------------------------------------------
    def send_gcode(self, line: str) -> Response:
        """Send one numbered, checksummed line; handle resends; wait for ``ok``."""
        text = check_command(Firmware.MARLIN, line)
        self.check()
        t0 = time.monotonic()
        self._write(self._codec.frame(text))
        replies = self._wait_ok(None, resend_ok=True)
        return Response(text, True, tuple(replies), time.monotonic() - t0)

    def set_speed_factor(self, pct: float) -> Response:
        """``M220 S<int>``."""
        return self._tracker.set(Channel.SPEED, pct, self.send_gcode)

    def set_flow_factor(self, pct: float) -> Response:
        """``M221 S<int>``."""
        return self._tracker.set(Channel.FLOW, pct, self.send_gcode)

    def read_factors(self) -> Factors:
        """Ask ``M220`` and ``M221`` and parse ``FR:N%`` and ``echo:E0 Flow: N%``."""
        got: dict[Channel, float] = {}
        for channel in (Channel.SPEED, Channel.FLOW):
            for reply in self.send_gcode(channel.mcode).lines:
                parsed = parse_factor_report(Firmware.MARLIN, reply)
                if parsed is not None and parsed[0] is channel:
                    got[channel] = parsed[1]
            if channel not in got:
                raise CommandRejected(f"no report in the answer to {channel.mcode}",
                                      source=self.port)
        return Factors(got[Channel.SPEED], got[Channel.FLOW], "printer")

    # -- internals ------------------------------------------------------------------
    def _wait_ok(self, deadline: float | None, *, resend_ok: bool) -> list[str]:
        replies: list[str] = []
        resend_from: int | None = None
        resends = 0
        pending = 1  # oks still owed: one per line in flight
        limit = deadline if deadline is not None else time.monotonic() + self.command_timeout_s
        while True:
            line = self._readline(limit)
            if line is None:
                if deadline is not None:
                    raise _NoReply
                self._lost = "no reply"
                raise ConnectionLost(f"no reply within {self.command_timeout_s:g} s",
                                     source=self.port)
            reply = parse_reply(line)
            if reply.kind == "busy":
                limit = time.monotonic() + self.command_timeout_s
            elif reply.kind == "resend" and resend_ok:
                resend_from = reply.line_no
            elif reply.kind == "ok":
                if resend_from is None:
                    pending -= 1
                    if pending <= 0:
                        return replies
                    continue
                # This ok acknowledges the error; now resend from the requested line.
                resends += 1
                if resends > self.max_resends:
                    raise CommandRejected(f"line {resend_from} still rejected after "
                                          f"{self.max_resends} resends", source=self.port)
                try:
                    frames = self._codec.resend_from(resend_from)
                except KeyError:
                    raise CommandRejected("firmware asked to resend a line never sent",
                                          source=self.port, value=resend_from) from None
                resend_from = None
                pending = len(frames)  # the firmware dropped everything after the bad line
                for data in frames:
                    self._write(data)
                limit = time.monotonic() + self.command_timeout_s
            elif reply.kind == "error" and not _is_line_error(reply.text):
                raise CommandRejected("firmware error", source=self.port, value=reply.text)
            elif reply.kind in ("info", "start"):
                replies.append(reply.text)

    def _write(self, data: bytes) -> None:
        ser = self._ser
        if ser is None:
            raise ConnectionLost("not connected", source=self.port)
        self._log(">", data.decode("ascii", "replace").rstrip("\n"))
        try:
            ser.write(data)  # type: ignore[attr-defined]
            ser.flush()  # type: ignore[attr-defined]
        except OSError as exc:  # serial.SerialException is an OSError
            self._lost = str(exc)
            raise ConnectionLost(f"write failed ({exc})", source=self.port) from None

    def _readline(self, deadline: float) -> str | None:
        ser = self._ser
        if ser is None:
            raise ConnectionLost("not connected", source=self.port)
        while b"\n" not in self._buf:
            if time.monotonic() > deadline:
                return None
            try:
                chunk = ser.read(ser.in_waiting or 1)  # type: ignore[attr-defined]
            except OSError as exc:
                self._lost = str(exc)
                raise ConnectionLost(f"read failed ({exc})", source=self.port) from None
            self._buf += chunk
        raw, self._buf = self._buf.split(b"\n", 1)
        text = raw.decode("ascii", "replace").strip("\r")
        self._log("<", text)
        return text

    def _log(self, direction: str, text: str) -> None:
        self.transcript.append((direction, text))
        if len(self.transcript) > 4000:
            del self.transcript[:2000]


class _NoReply(Exception):
    """Internal: nothing received before a connect-time deadline."""


def _is_line_error(text: str) -> bool:
    low = text.lower()
    return "checksum" in low or "line number" in low or "last line" in low
