"""OctoPrint connection: REST with an API key for commands, push socket for the replies.

OctoPrint has no REST endpoint for the printer's answers, so the connection reads its push
socket (``/sockjs/websocket``, one JSON object per frame, serial log lines in
``current.logs`` batched at ~2 Hz): a command counts as acknowledged when its
``Send: <gcode>`` line is followed by a ``Recv: ok`` line. Marlin's multiplier reports
(``Recv: echo:E0 Flow: 95%``) between the two are the reply. Flow (tested against
OctoPrint 1.11.8 and its virtual printer)::

    GET  /api/version                       (API key check)
    POST /api/login {"passive": true}       -> name, session  (push-socket auth)
    WS   /sockjs/websocket  {"auth": "name:session"}
    GET  /api/connection; POST {"command": "connect", "port": P} when closed and P given
    POST /api/printer/command {"commands": ["M221 S95"]}   -> 204; 409 when not operational

OctoPrint's virtual printer takes ``M220``/``M221`` silently and never reports them, so
:meth:`OctoPrintPrinter.read_factors` falls back to the acknowledged commands
(``source="commanded"``) when no report arrives. Closing never disconnects OctoPrint from
the printer (that would stop a print).
"""

from __future__ import annotations

import threading
import time
from typing import Any

import httpx

from flowtwin.control.printer import (
    CommandRejected,
    ConnectionLost,
    Factors,
    FactorTracker,
    Response,
)
from flowtwin.control.transports._net import PushSocket, guarded_client, websocket_url
from flowtwin.control.transports.credentials import ApiKey
from flowtwin.errors import GcodeError, PrinterConnectionError
from flowtwin.firmware import (
    Channel,
    Firmware,
    check_command,
    parse_factor_report,
    query_command,
)
from flowtwin.gcode.words import parse_line

__all__ = ["OctoPrintPrinter", "SentKey", "normalize_sent"]

#: A sent command as :func:`normalize_sent` keys it: code and sorted parameters.
SentKey = tuple[str, tuple[tuple[str, float | str], ...]]
_MAX_LINES = 5000


def normalize_sent(line: str) -> SentKey | None:
    """The command of a line OctoPrint logs as sent, parsed by the reader's word parser.

    :func:`flowtwin.gcode.words.parse_line` drops the line number, the checksum and the
    case, so ``"N12 M221 S95*87"`` and ``"M221 S95"`` give the same key: the command and
    its parameters in name order. ``None`` for a line that is not a G-code command.
    """
    try:
        parsed = parse_line(line.strip(), source="OctoPrint terminal")
    except GcodeError:
        return None
    if not parsed.code:
        return None
    return parsed.code, tuple(sorted(parsed.params.items()))


class OctoPrintPrinter:
    """A printer behind OctoPrint.

    Parameters
    ----------
    base_url
        ``http://host:port`` of OctoPrint; nothing else is contacted.
    api_key
        The user's API key (sent as ``X-Api-Key``).
    firmware
        Firmware of the printer behind OctoPrint (decides the encoding; on Klipper the
        multipliers are never queried).
    port
        Serial port OctoPrint should connect to if it is not connected (``"VIRTUAL"``
        for its virtual printer); None leaves the printer connection alone.
    ack_timeout_s
        How long to wait for ``Send:``/``Recv: ok`` of a command on the push socket.
    connect_timeout_s
        How long to wait for the printer to become operational.
    """

    def __init__(self, base_url: str, *, api_key: ApiKey, firmware: Firmware = Firmware.MARLIN,
                 port: str | None = None, ack_timeout_s: float = 5.0,
                 connect_timeout_s: float = 20.0, http_timeout_s: float = 5.0) -> None:
        self.base_url = base_url.rstrip("/")
        self.firmware = firmware
        self.port = port
        self.ack_timeout_s = ack_timeout_s
        self.connect_timeout_s = connect_timeout_s
        self.description = f"octoprint {self.base_url}"
        self._key = api_key
        self._http_timeout_s = http_timeout_s
        self._http: httpx.Client | None = None
        self._push: PushSocket | None = None
        self._cond = threading.Condition()
        self._lines: list[str] = []
        self._first = 0  # absolute index of self._lines[0]
        self._flags: dict[str, Any] = {}
        self._lost: str | None = None
        self._tracker = FactorTracker(firmware)

    # -- connection -----------------------------------------------------------------
    def connect(self) -> None:
        """Check the key, open the push socket, make sure the printer is operational."""
        self._close_quietly()
        self._lost = None
        self._http = guarded_client(self.base_url, timeout_s=self._http_timeout_s,
                                    headers={"X-Api-Key": self._key.reveal()})
        self._request("GET", "/api/version")
        login = self._request("POST", "/api/login", json={"passive": True}).json()
        self._push = PushSocket(websocket_url(self.base_url, "/sockjs/websocket"),
                                self._on_message)
        self._push.send({"auth": f"{login['name']}:{login['session']}"})
        state = self._connection_state()
        if state == "Closed" or state.startswith("Offline") or state.startswith("Error"):
            if self.port is None:
                raise ConnectionLost("OctoPrint is not connected to a printer",
                                     source=self.base_url, value=state,
                                     allowed="a connected printer, or give ?port=NAME")
            self._request("POST", "/api/connection",
                          json={"command": "connect", "port": self.port})
        deadline = time.monotonic() + self.connect_timeout_s
        while True:
            state = self._connection_state()
            if state in ("Operational", "Printing", "Paused", "Pausing", "Resuming",
                         "Starting", "Finishing", "Cancelling"):
                break
            if time.monotonic() > deadline:
                raise ConnectionLost("printer did not become operational",
                                     source=self.base_url, value=state)
            time.sleep(0.2)
        # The push socket's flags lag the REST state by up to one batch (0.5 s): wait until
        # it too reports an operational printer, then forget losses seen before that.
        with self._cond:
            while not self._flags.get("operational"):
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise ConnectionLost("push socket never reported an operational printer",
                                         source=self.base_url)
                self._cond.wait(remaining)
            self._lost = None
        if self.firmware is Firmware.MARLIN:
            self._tracker.reset()  # a Marlin board resets when its port is opened

    def check(self) -> None:
        """Raise :class:`ConnectionLost` if the push socket or the printer link is gone."""
        if self._push is None:
            raise ConnectionLost("not connected", source=self.base_url)
        reason = self._lost or self._push.closed_reason
        if reason is not None:
            raise ConnectionLost(f"connection lost ({reason})", source=self.base_url)

    def close(self) -> None:
        """Close the socket and HTTP client (the printer stays connected to OctoPrint)."""
        self._close_quietly()

    # -- commands -------------------------------------------------------------------
    def send_gcode(self, line: str) -> Response:
        """Send one command through OctoPrint and wait for ``Recv: ok`` on the push socket."""
        text = check_command(self.firmware, line)
        self.check()
        with self._cond:
            start = self._first + len(self._lines)
        t0 = time.monotonic()
        r = self._request("POST", "/api/printer/command", json={"commands": [text]},
                          ok_codes=(204,))
        del r
        return self._await_ack(text, start, t0)

    def set_speed_factor(self, pct: float) -> Response:
        """Set ``M220`` through OctoPrint."""
        return self._tracker.set(Channel.SPEED, pct, self.send_gcode)

    def set_flow_factor(self, pct: float) -> Response:
        """Set ``M221`` through OctoPrint."""
        return self._tracker.set(Channel.FLOW, pct, self.send_gcode)

    def read_factors(self) -> Factors:
        """Marlin: query ``M220``/``M221``; without a report, the acknowledged values."""
        if self.firmware is not Firmware.MARLIN:
            self.check()
            return self._tracker.factors()
        got: dict[Channel, float] = {}
        for channel in (Channel.SPEED, Channel.FLOW):
            resp = self.send_gcode(query_command(self.firmware, channel))
            for reply in resp.lines:
                parsed = parse_factor_report(self.firmware, reply)
                if parsed is not None and parsed[0] is channel:
                    got[channel] = parsed[1]
        if len(got) == 2:
            return Factors(got[Channel.SPEED], got[Channel.FLOW], "printer")
        return self._tracker.factors()

    # -- internals ------------------------------------------------------------------
    def _await_ack(self, text: str, start: int, t0: float) -> Response:
        want = normalize_sent(text)
        deadline = t0 + self.ack_timeout_s
        sent_at: int | None = None
        replies: list[str] = []
        i = start
        with self._cond:
            while True:
                lines, first = self._lines, self._first
                i = max(i, first)
                while i < first + len(lines):
                    entry = lines[i - first]
                    i += 1
                    if sent_at is None:
                        if (entry.startswith("Send: ") and want is not None
                                and normalize_sent(entry[6:]) == want):
                            sent_at = i
                        continue
                    if entry.startswith("Recv: "):
                        body = entry[6:].strip()
                        if body == "ok" or body.startswith("ok "):
                            return Response(text, True, tuple(replies),
                                            time.monotonic() - t0)
                        if body.lower().startswith(("error", "!!")):
                            raise CommandRejected("printer answered with an error",
                                                  source=self.base_url, value=body,
                                                  field=text)
                        replies.append(body)
                reason = self._lost or (self._push.closed_reason if self._push else "closed")
                if reason is not None:
                    raise ConnectionLost(f"connection lost while waiting for '{text}' "
                                         f"({reason})", source=self.base_url)
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    what = "acknowledgement" if sent_at is not None else "Send: line"
                    raise ConnectionLost(f"no {what} for '{text}' within "
                                         f"{self.ack_timeout_s:g} s", source=self.base_url)
                self._cond.wait(remaining)

    def _on_message(self, msg: Any) -> None:
        if not isinstance(msg, dict):
            return
        current = msg.get("current")
        event = msg.get("event")
        with self._cond:
            if isinstance(current, dict):
                logs = current.get("logs") or []
                self._lines.extend(str(x) for x in logs)
                if len(self._lines) > _MAX_LINES:
                    drop = len(self._lines) - _MAX_LINES // 2
                    del self._lines[:drop]
                    self._first += drop
                flags = (current.get("state") or {}).get("flags") or {}
                if isinstance(flags, dict) and flags:
                    if self._flags.get("operational") and flags.get("closedOrError"):
                        text = (current.get("state") or {}).get("text", "closed or error")
                        self._lost = f"printer state: {text}"
                    self._flags = flags
            if (isinstance(event, dict) and event.get("type") in ("Disconnected", "Error")
                    and self._flags.get("operational")):
                self._lost = f"event {event.get('type')}"
            self._cond.notify_all()

    def _connection_state(self) -> str:
        data = self._request("GET", "/api/connection").json()
        return str(data.get("current", {}).get("state", ""))

    def _request(self, method: str, path: str, *, json: Any = None,
                 ok_codes: tuple[int, ...] = (200, 204)) -> httpx.Response:
        if self._http is None:
            raise ConnectionLost("not connected", source=self.base_url)
        try:
            r = self._http.request(method, path, json=json)
        except httpx.TransportError as exc:
            raise ConnectionLost(f"OctoPrint unreachable ({type(exc).__name__})",
                                 source=self.base_url + path) from None
        if r.status_code in ok_codes:
            return r
        if r.status_code in (401, 403):
            raise PrinterConnectionError("OctoPrint rejected the API key",
                                         source=self.base_url + path, value=r.status_code,
                                         allowed="a valid key of a user with control rights")
        if r.status_code == 409:
            raise ConnectionLost("OctoPrint's printer is not operational",
                                 source=self.base_url + path, value=r.status_code)
        raise CommandRejected(f"OctoPrint answered HTTP {r.status_code}",
                              source=self.base_url + path, value=r.text[:200])

    def _close_quietly(self) -> None:
        if self._push is not None:
            self._push.close()
            self._push = None
        if self._http is not None:
            self._http.close()
            self._http = None
        with self._cond:
            self._lines.clear()
            self._first = 0
            self._flags = {}
