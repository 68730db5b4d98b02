"""The live configuration of a Klipper printer, read from its Moonraker.

Moonraker's object query ``GET /printer/objects/query?configfile=config`` returns
Klipper's ``configfile`` status: ``config`` maps every section of the printer's
configuration (``[include]`` files merged, ``SAVE_CONFIG`` values applied) to its options as
the raw strings of ``printer.cfg`` (Moonraker API: "Query printer object status"; Klipper
``klippy/configfile.py``). klipper_estimator reads the same object (its ``settings``
attribute). The sections are written back as a ``printer.cfg`` text that flowtwin's own
``printer.cfg`` reader then loads, so a live printer and a file are read by the same code.
Multi-line options (G-code macro bodies) are left out: no motion setting has one.

An API key for a Moonraker that requires one is taken from ``MOONRAKER_API_KEY`` (sent as
``X-Api-Key``); only the printer's own network is contacted.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from flowtwin.errors import PrinterConnectionError

__all__ = ["fetch_klipper_config", "moonraker_printer_cfg", "render_printer_cfg"]

#: Seconds to wait for Moonraker.
TIMEOUT_S = 10.0


def fetch_klipper_config(url: str, *, timeout_s: float = TIMEOUT_S
                         ) -> dict[str, dict[str, str]]:
    """Klipper's configuration (section → option → raw value) from the Moonraker at ``url``.

    Raises
    ------
    PrinterConnectionError
        Moonraker cannot be reached, refuses the request, Klipper is not ready, or the
        answer has no configuration (the message names the URL and the cause).
    """
    import httpx

    base = url.rstrip("/")
    if not base.startswith(("http://", "https://")):
        raise PrinterConnectionError("not an HTTP URL", field="--moonraker", value=url,
                                     allowed="http://host[:port] of the printer's Moonraker")
    headers = {}
    key = os.environ.get("MOONRAKER_API_KEY")
    if key:
        headers["X-Api-Key"] = key
    endpoint = base + "/printer/objects/query"
    try:
        r = httpx.get(endpoint, params={"configfile": "config"}, headers=headers,
                      timeout=timeout_s, trust_env=False)
    except httpx.HTTPError as exc:
        raise PrinterConnectionError(f"cannot reach Moonraker: {exc}", source=endpoint
                                     ) from exc
    if r.status_code != 200:
        detail = r.text.strip().replace("\n", " ")[:200]
        why = {401: "authorization required (set MOONRAKER_API_KEY or make this host a "
                    "trusted client)", 403: "forbidden",
               503: "Klipper is not ready"}.get(r.status_code, "request failed")
        raise PrinterConnectionError(f"Moonraker answered HTTP {r.status_code}: {why}",
                                     source=endpoint, value=detail)
    try:
        config = r.json()["result"]["status"]["configfile"]["config"]
    except (ValueError, KeyError, TypeError) as exc:
        raise PrinterConnectionError("Moonraker's answer has no Klipper configuration",
                                     source=endpoint, field="result.status.configfile.config",
                                     value=r.text[:200]) from exc
    if not isinstance(config, Mapping) or "printer" not in config:
        raise PrinterConnectionError("Klipper's configuration has no [printer] section",
                                     source=endpoint, field="configfile.config",
                                     allowed="a Klipper printer configuration")
    return {str(s): {str(k): str(v) for k, v in opts.items()}
            for s, opts in config.items() if isinstance(opts, Mapping)}


def render_printer_cfg(config: Mapping[str, Mapping[str, str]], source: str) -> str:
    """``printer.cfg`` text of a configuration (single-line options only)."""
    out = [f"# Klipper configuration read from {source} by flowtwin postprocess"]
    for section, options in config.items():
        if "\n" in section or "]" in section:
            continue
        out.append(f"\n[{section}]")
        for key, value in options.items():
            text = str(value)
            if "\n" in text or "\r" in text or not key or "\n" in key:
                continue
            out.append(f"{key}: {text}")
    return "\n".join(out) + "\n"


def moonraker_printer_cfg(url: str, folder: str | os.PathLike[str]) -> Path:
    """Fetch the configuration from ``url`` and write it as ``printer.cfg`` in ``folder``."""
    text = render_printer_cfg(fetch_klipper_config(url), url)
    path = Path(folder) / "printer.cfg"
    path.write_text(text, encoding="utf-8")
    return path
