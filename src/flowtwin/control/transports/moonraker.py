"""Moonraker connection (Klipper): HTTP for commands and queries, websocket JSON-RPC for state.

Klipper semantics are enforced: multipliers are sent as floats (``M221 S95.5``) and read
back from the ``gcode_move`` object (``speed_factor``, ``extrude_factor``, as fractions),
**never** with a bare ``M221``/``M220``, which resets the factor to 100 % on Klipper.
Exchanges used (seen against Moonraker 0.11.0 with a Kalico klippy host)::

    GET  /server/info                              -> result.klippy_state == "ready"
    POST /printer/gcode/script {"script": "M221 S95.5"}  -> {"result": "ok"} after it ran;
                                                      HTTP 400 with the Klipper error
    GET  /printer/objects/query?gcode_move=speed_factor,extrude_factor
    WS   /websocket  server.connection.identify; printer.objects.subscribe
         <- notify_status_update [{"gcode_move": {...}}, eventtime]  (every 250 ms if changed)
         <- notify_gcode_response ["// Unknown command:\\"M900\\""]
         <- notify_klippy_disconnected / notify_klippy_shutdown

The pure helpers (:func:`rpc_request`, :func:`factors_from_status`, ...) are the protocol
layer; they are tested against exchanges recorded from a real Moonraker.
"""

from __future__ import annotations

import itertools
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
from flowtwin.errors import PrinterConnectionError
from flowtwin.firmware import Channel, Firmware, check_command

__all__ = [
    "SUBSCRIPTION",
    "MoonrakerPrinter",
    "factors_from_status",
    "rpc_request",
    "split_rpc_message",
]

#: Objects and fields the connection subscribes to.
SUBSCRIPTION: dict[str, list[str]] = {
    "gcode_move": ["speed_factor", "extrude_factor"],
    "webhooks": ["state", "state_message"],
}
_LOST_METHODS = ("notify_klippy_disconnected", "notify_klippy_shutdown")


def rpc_request(method: str, params: dict[str, Any] | None, request_id: int) -> dict[str, Any]:
    """A JSON-RPC 2.0 request object."""
    msg: dict[str, Any] = {"jsonrpc": "2.0", "method": method, "id": request_id}
    if params is not None:
        msg["params"] = params
    return msg


def split_rpc_message(msg: Any) -> tuple[str, Any]:
    """Classify a JSON-RPC message from Moonraker.

    Returns
    -------
    tuple of (str, object)
        ``("result", (id, result))``, ``("error", (id, message))``,
        ``("notify", (method, params))`` or ``("other", msg)``.
    """
    if not isinstance(msg, dict):
        return "other", msg
    if "method" in msg and "id" not in msg:
        return "notify", (str(msg["method"]), msg.get("params"))
    if "id" in msg and "error" in msg:
        err = msg["error"]
        text = err.get("message", str(err)) if isinstance(err, dict) else str(err)
        return "error", (msg["id"], text)
    if "id" in msg and "result" in msg:
        return "result", (msg["id"], msg["result"])
    return "other", msg


def factors_from_status(status: dict[str, Any]) -> dict[Channel, float]:
    """Multipliers in percent from a Klipper status dict (query result or update).

    ``gcode_move.speed_factor`` and ``extrude_factor`` are fractions (``M220 S90`` reads
    back as 0.8999999999999999); values are rounded to 1e-6 %. Fields absent from an
    incremental update are absent from the result.
    """
    gm = status.get("gcode_move") or {}
    out: dict[Channel, float] = {}
    if "speed_factor" in gm:
        out[Channel.SPEED] = round(float(gm["speed_factor"]) * 100.0, 6)
    if "extrude_factor" in gm:
        out[Channel.FLOW] = round(float(gm["extrude_factor"]) * 100.0, 6)
    return out


class MoonrakerPrinter:
    """A Klipper printer behind Moonraker.

    Parameters
    ----------
    base_url
        ``http://host:port`` of Moonraker; nothing else is contacted.
    api_key
        Optional Moonraker API key (``X-Api-Key``); trusted clients need none.
    connect_timeout_s
        How long :meth:`connect` waits for klippy to be ready.
    """

    firmware = Firmware.KLIPPER

    def __init__(self, base_url: str, *, api_key: ApiKey | None = None,
                 connect_timeout_s: float = 20.0, http_timeout_s: float = 10.0,
                 rpc_timeout_s: float = 5.0) -> None:
        self.base_url = base_url.rstrip("/")
        self.description = f"moonraker {self.base_url}"
        self.connect_timeout_s = connect_timeout_s
        self.rpc_timeout_s = rpc_timeout_s
        self._key = api_key
        self._http_timeout_s = http_timeout_s
        self._http: httpx.Client | None = None
        self._push: PushSocket | None = None
        self._cond = threading.Condition()
        self._ids = itertools.count(1)
        self._replies: dict[int, tuple[str, Any]] = {}
        self._status: dict[Channel, float] = {}
        self._gcode_lines: list[str] = []
        self._lost: str | None = None
        self._tracker = FactorTracker(Firmware.KLIPPER)

    # -- connection -----------------------------------------------------------------
    def connect(self) -> None:
        """Wait for klippy ready, open the websocket, identify and subscribe."""
        self._close_quietly()
        headers = {"X-Api-Key": self._key.reveal()} if self._key is not None else {}
        self._http = guarded_client(self.base_url, headers=headers,
                                    timeout_s=self._http_timeout_s)
        deadline = time.monotonic() + self.connect_timeout_s
        while True:
            try:
                info = self._request("GET", "/server/info").json().get("result", {})
                state = str(info.get("klippy_state", ""))
            except ConnectionLost as exc:
                state = f"unreachable ({exc.message})"
            if state == "ready":
                break
            if time.monotonic() > deadline:
                raise ConnectionLost("klippy did not become ready", source=self.base_url,
                                     value=state)
            time.sleep(0.25)
        self._lost = None
        self._push = PushSocket(websocket_url(self.base_url, "/websocket"), self._on_message,
                                headers=headers)
        self._rpc("server.connection.identify",
                  {"client_name": "flowtwin", "version": "0.1", "type": "agent",
                   "url": "https://example.invalid/flowtwin"})
        result = self._rpc("printer.objects.subscribe", {"objects": SUBSCRIPTION})
        status = result.get("status", {}) if isinstance(result, dict) else {}
        with self._cond:
            self._status = factors_from_status(status)
        hook_state = (status.get("webhooks") or {}).get("state")
        if hook_state not in (None, "ready"):
            raise ConnectionLost("klippy is not ready", source=self.base_url, value=hook_state)

    def check(self) -> None:
        """Raise :class:`ConnectionLost` if the websocket closed or klippy went away."""
        if self._push is None:
            raise ConnectionLost("not connected", source=self.base_url)
        reason = self._lost or self._push.closed_reason
        if reason is not None:
            raise ConnectionLost(f"connection lost ({reason})", source=self.base_url)

    def close(self) -> None:
        """Close the websocket and the HTTP client."""
        self._close_quietly()

    # -- commands -------------------------------------------------------------------
    def send_gcode(self, line: str) -> Response:
        """Run one command through ``/printer/gcode/script`` (returns after it ran)."""
        text = check_command(Firmware.KLIPPER, line)
        self.check()
        with self._cond:
            start = len(self._gcode_lines)
        t0 = time.monotonic()
        r = self._request("POST", "/printer/gcode/script", json={"script": text})
        latency = time.monotonic() - t0
        ok = r.json().get("result") == "ok"
        with self._cond:
            replies = tuple(self._gcode_lines[start:])
        return Response(text, ok, replies, latency)

    def set_speed_factor(self, pct: float) -> Response:
        """``M220 S<float>``."""
        return self._tracker.set(Channel.SPEED, pct, self.send_gcode)

    def set_flow_factor(self, pct: float) -> Response:
        """``M221 S<float>``."""
        return self._tracker.set(Channel.FLOW, pct, self.send_gcode)

    def read_factors(self) -> Factors:
        """Query ``gcode_move.speed_factor``/``extrude_factor`` (never a bare M221)."""
        self.check()
        r = self._request("GET", "/printer/objects/query",
                          params={"gcode_move": "speed_factor,extrude_factor"})
        got = factors_from_status(r.json().get("result", {}).get("status", {}))
        if len(got) != 2:
            raise CommandRejected("gcode_move factors missing from the query result",
                                  source=self.base_url, value=r.text[:200])
        return Factors(got[Channel.SPEED], got[Channel.FLOW], "printer")

    def pushed_factors(self) -> dict[Channel, float]:
        """The factors last pushed by ``notify_status_update`` (percent)."""
        with self._cond:
            return dict(self._status)

    # -- internals ------------------------------------------------------------------
    def _rpc(self, method: str, params: dict[str, Any] | None) -> Any:
        if self._push is None:
            raise ConnectionLost("not connected", source=self.base_url)
        rid = next(self._ids)
        self._push.send(rpc_request(method, params, rid))
        deadline = time.monotonic() + self.rpc_timeout_s
        with self._cond:
            while rid not in self._replies:
                if self._push.closed_reason is not None:
                    raise ConnectionLost(f"websocket closed ({self._push.closed_reason})",
                                         source=self.base_url)
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise ConnectionLost(f"no reply to {method}", source=self.base_url)
                self._cond.wait(min(remaining, 0.25))
            kind, value = self._replies.pop(rid)
        if kind == "error":
            raise CommandRejected(f"{method} failed", source=self.base_url, value=value)
        return value

    def _on_message(self, msg: Any) -> None:
        kind, body = split_rpc_message(msg)
        with self._cond:
            if kind in ("result", "error"):
                rid, value = body
                self._replies[int(rid)] = (kind, value)
            elif kind == "notify":
                method, params = body
                if method == "notify_status_update" and params:
                    self._status.update(factors_from_status(params[0]))
                    state = (params[0].get("webhooks") or {}).get("state")
                    if state is not None and state != "ready":
                        self._lost = f"klippy state {state}"
                elif method == "notify_gcode_response" and params:
                    self._gcode_lines.extend(str(p) for p in params)
                    if len(self._gcode_lines) > 2000:
                        del self._gcode_lines[:1000]
                elif method in _LOST_METHODS:
                    self._lost = method
            self._cond.notify_all()

    def _request(self, method: str, path: str, *, json: Any = None,
                 params: dict[str, str] | None = None) -> httpx.Response:
        if self._http is None:
            raise ConnectionLost("not connected", source=self.base_url)
        try:
            r = self._http.request(method, path, json=json, params=params)
        except httpx.TransportError as exc:
            raise ConnectionLost(f"Moonraker unreachable ({type(exc).__name__})",
                                 source=self.base_url + path) from None
        if r.status_code == 200:
            return r
        if r.status_code in (401, 403):
            raise PrinterConnectionError("Moonraker refused the request (authorization)",
                                         source=self.base_url + path, value=r.status_code,
                                         allowed="a valid API key, or a trusted client")
        message = _error_message(r)
        if r.status_code == 400:
            raise CommandRejected("Klipper rejected the command", source=self.base_url + path,
                                  value=message)
        raise ConnectionLost(f"Moonraker answered HTTP {r.status_code}",
                             source=self.base_url + path, value=message)

    def _close_quietly(self) -> None:
        if self._push is not None:
            self._push.close()
            self._push = None
        if self._http is not None:
            self._http.close()
            self._http = None
        with self._cond:
            self._replies.clear()
            self._gcode_lines.clear()


def _error_message(r: httpx.Response) -> str:
    try:
        err = r.json().get("error", {})
    except ValueError:
        return r.text[:200]
    return str(err.get("message", ""))[:200] if isinstance(err, dict) else str(err)[:200]
