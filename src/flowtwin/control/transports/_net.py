"""Network plumbing shared by the OctoPrint and Moonraker connections.

Security rules enforced here: only the host and port the user gave are ever contacted
(every HTTP request is checked; redirects are not followed; proxy settings from the
environment are ignored, because a proxy is another host), and headers carrying a key are
built at the last moment from :class:`~flowtwin.control.transports.credentials.ApiKey`.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable, Mapping
from typing import Any
from urllib.parse import urlsplit

import httpx
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection
from websockets.sync.client import connect as ws_connect

from flowtwin.control.printer import ConnectionLost
from flowtwin.errors import PrinterConnectionError

__all__ = ["PushSocket", "guarded_client", "websocket_url"]

log = logging.getLogger("flowtwin.control")


def _origin(url: httpx.URL) -> tuple[str, str, int]:
    port = url.port or (443 if url.scheme in ("https", "wss") else 80)
    return (url.scheme.replace("ws", "http"), url.host, port)


def guarded_client(base_url: str, *, headers: Mapping[str, str] | None = None,
                   timeout_s: float = 5.0) -> httpx.Client:
    """An ``httpx.Client`` that can only talk to ``base_url``'s scheme, host and port."""
    allowed = _origin(httpx.URL(base_url))

    def check(request: httpx.Request) -> None:
        if _origin(request.url) != allowed:
            raise PrinterConnectionError("refusing to contact a host other than the one "
                                         "given", value=str(request.url.host),
                                         allowed=allowed[1])

    return httpx.Client(base_url=base_url, headers=dict(headers or {}), timeout=timeout_s,
                        trust_env=False, follow_redirects=False,
                        event_hooks={"request": [check]})


def websocket_url(base_url: str, path: str) -> str:
    """``ws://host:port/path`` (``wss`` for https) on the same host as ``base_url``."""
    parts = urlsplit(base_url)
    scheme = "wss" if parts.scheme == "https" else "ws"
    return f"{scheme}://{parts.netloc}{path}"


class PushSocket:
    """A websocket read by a background thread that hands each JSON message to a handler.

    Parameters
    ----------
    url
        ``ws://`` URL (same host as the REST base URL).
    on_message
        Called in the reader thread with each decoded JSON object.
    headers
        Extra request headers (e.g. ``X-Api-Key``).
    open_timeout_s
        Timeout of the opening handshake.
    """

    def __init__(self, url: str, on_message: Callable[[Any], None], *,
                 headers: Mapping[str, str] | None = None,
                 open_timeout_s: float = 5.0) -> None:
        self.url = url
        self._on_message = on_message
        self._closed_reason: str | None = None
        self._closing = False
        try:
            # legacy=True: a plain connection we close ourselves (no auto-reconnect; the
            # supervisor decides when to reconnect).
            self._ws: ClientConnection = ws_connect(  # type: ignore[assignment]
                url, proxy=None, additional_headers=dict(headers or {}),
                open_timeout=open_timeout_s, ping_interval=5.0, ping_timeout=5.0,
                close_timeout=1.0, max_size=2**22, legacy=True)
        except (OSError, TimeoutError) as exc:
            raise ConnectionLost(f"cannot open push socket ({type(exc).__name__}: {exc})",
                                 source=url) from None
        except Exception as exc:  # websockets' handshake errors (InvalidStatus, ...)
            raise PrinterConnectionError(f"push socket refused ({exc})", source=url) from None
        self._thread = threading.Thread(target=self._run, name="flowtwin-push",
                                        daemon=True)
        self._thread.start()

    @property
    def closed_reason(self) -> str | None:
        """Why the socket closed, or None while it is open."""
        return self._closed_reason

    def send(self, obj: object) -> None:
        """Send one JSON message; raises :class:`ConnectionLost` when closed."""
        try:
            self._ws.send(json.dumps(obj))
        except (ConnectionClosed, OSError) as exc:
            self._closed_reason = self._closed_reason or f"send failed: {exc}"
            raise ConnectionLost("push socket closed", source=self.url) from None

    def close(self) -> None:
        """Close the socket and join the reader thread."""
        self._closing = True
        self._ws.close()
        self._thread.join(timeout=2.0)

    def _run(self) -> None:
        try:
            for raw in self._ws:
                try:
                    obj = json.loads(raw)
                except ValueError:
                    log.warning("push socket %s: undecodable message dropped", self.url)
                    continue
                self._on_message(obj)
        except (ConnectionClosed, OSError) as exc:
            self._closed_reason = f"{type(exc).__name__}: {exc}"
        finally:
            if self._closed_reason is None:
                self._closed_reason = "closed by client" if self._closing else "closed by host"
