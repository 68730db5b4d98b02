"""A small Marlin-like firmware on the master side of a pty, for the serial tests.

Run as ``python marlin_responder.py FD [options]`` with FD the pty master (inherited).
It implements what the host protocol needs, written from Marlin's documented behaviour:
``N<n> ... *<cs>`` lines with XOR checksums, ``M110 N<k>``, "Error:checksum mismatch" /
"Error:Line Number is not Last Line Number+1" followed by ``Resend: k`` and ``ok``,
``echo:busy: processing``, integer ``M220``/``M221`` (``strtol``: ``S95.7`` → 95) and their
reports ``FR:N%`` / ``echo:E0 Flow: N%``. Faults are injected by option:

--corrupt N[,N...]   treat the first arrival of these line numbers as corrupted
--skip N             answer line N as if line N-1 had been lost (line-number error)
--busy N             send ``echo:busy: processing`` twice before the ``ok`` of line N
--hangup-after K     close the port after K numbered commands (cable pulled)
--log FILE           append every received line to FILE
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time


def checksum(payload: bytes) -> int:
    cs = 0
    for b in payload:
        cs ^= b
    return cs


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("fd", type=int)
    ap.add_argument("--corrupt", default="")
    ap.add_argument("--skip", type=int, default=-1)
    ap.add_argument("--busy", type=int, default=-1)
    ap.add_argument("--hangup-after", type=int, default=-1)
    ap.add_argument("--log", default=None)
    args = ap.parse_args()
    fd = args.fd
    corrupt = {int(x) for x in args.corrupt.split(",") if x}
    skipped = False
    last_n = 0
    speed, flow = 100, 100
    numbered = 0
    logf = open(args.log, "a", encoding="ascii") if args.log else None

    def send(text: str) -> None:
        os.write(fd, (text + "\n").encode("ascii"))

    def resend(reason: str) -> None:
        send(f"Error:{reason}, Last Line: {last_n}")
        send(f"Resend: {last_n + 1}")
        send("ok")

    send("start")
    buf = b""
    while True:
        try:
            chunk = os.read(fd, 4096)
        except OSError:
            return 0
        if not chunk:
            return 0
        buf += chunk
        while b"\n" in buf:
            raw, buf = buf.split(b"\n", 1)
            line = raw.strip(b"\r ")
            if not line:
                continue
            if logf:
                logf.write(line.decode("ascii", "replace") + "\n")
                logf.flush()
            text = line.decode("ascii", "replace")
            m = re.match(r"^N(-?\d+)\s+(.*)\*(\d+)$", text)
            if text.startswith("N"):
                if m is None:
                    send(f"Error:No Checksum with line number, Last Line: {last_n}")
                    send(f"Resend: {last_n + 1}")
                    send("ok")
                    continue
                n = int(m.group(1))
                payload = line[: line.rindex(b"*")]
                if checksum(payload) != int(m.group(3)) or n in corrupt:
                    corrupt.discard(n)
                    resend("checksum mismatch")
                    continue
                if n == args.skip and not skipped:
                    skipped = True
                    last_n = n - 2  # pretend line n-1 never arrived
                    resend("Line Number is not Last Line Number+1")
                    continue
                if n != last_n + 1 and not m.group(2).startswith("M110"):
                    resend("Line Number is not Last Line Number+1")
                    continue
                last_n = n
                cmd = m.group(2).strip()
                numbered += 1
            else:
                cmd = text
            word = cmd.split()[0].upper() if cmd.split() else ""
            sval = re.search(r"\bS(-?\d+)", cmd)  # strtol semantics: integer part
            if word == "M110":
                nv = re.search(r"\bN(-?\d+)", cmd[4:])
                last_n = int(nv.group(1)) if nv else 0
            elif word == "M220":
                if sval:
                    speed = max(10, min(999, int(sval.group(1))))
                else:
                    send(f"FR:{speed}%")
            elif word == "M221":
                if sval:
                    flow = int(sval.group(1))
                else:
                    send(f"echo:E0 Flow: {flow}%")
            elif word not in ("G0", "G1", "G4", "M105", "M400", "G92", "G28", "G90", "G91"):
                send(f'echo:Unknown command: "{cmd}"')
            if text.startswith("N") and m is not None and int(m.group(1)) == args.busy:
                send("echo:busy: processing")
                time.sleep(0.05)
                send("echo:busy: processing")
            send("ok")
            if 0 <= args.hangup_after <= numbered:
                time.sleep(0.3)  # let the host read the ok: the cable is pulled between commands
                os.close(fd)
                return 0


if __name__ == "__main__":
    sys.exit(main())
