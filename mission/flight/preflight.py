"""Checks of ``fly-mission``'s options before anything starts (no vehicle, no connection, no upload).

Why: a bad ``--rss-source``, a missing FIFO, an ``--out`` that is a file or an unknown ``--connect`` scheme
must be one line and exit 2 at once, not a failure after the vehicle took off or the mission was uploaded.
"""

from __future__ import annotations

import socket
from pathlib import Path

from mission.errors import InputError

# MAVSDK v4 connection schemes (``udp://``/``tcp://`` are its older spellings, still accepted)
SCHEMES = ("udpin", "udpout", "tcpin", "tcpout", "serial", "serial_flowcontrol", "udp", "tcp")


def check_connect(url: str | None) -> None:
    """``--connect`` must be ``scheme://address`` with a scheme MAVSDK knows and, for a network, a port."""
    if not url:
        return
    scheme, sep, rest = url.partition("://")
    if not sep or scheme not in SCHEMES:
        raise InputError(
            f"unknown connection {url!r}; use e.g. udpin://0.0.0.0:14540, tcpout://127.0.0.1:5760 or "
            "serial:///dev/ttyACM0:57600",
            field="--connect",
        )
    if scheme.startswith(("udp", "tcp")):
        host, _, port = rest.rpartition(":")
        if not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise InputError(f"{url!r} needs HOST:PORT after {scheme}://", field="--connect")


def check_rss_source(text: str) -> None:
    """The RSS source parses, its FIFO/file exists, its UDP port can be bound."""
    from mission.flight.sources import parse_source

    kind, arg = parse_source(text)
    if kind == "aerpaw-fifo":
        p = Path(arg)
        if not p.exists():
            raise InputError("no such file or named pipe", source=str(p), field="--rss-source")
        if p.is_dir():
            raise InputError("is a folder, not a named pipe or file", source=str(p), field="--rss-source")
    elif kind == "udp":
        host, _, port = arg.rpartition(":")
        if not port.isdigit() or not 0 <= int(port) < 65536:
            raise InputError(f"bad UDP port in {arg!r}", field="--rss-source")
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind((host or "0.0.0.0", int(port)))
            except OSError as e:
                raise InputError(f"cannot listen on {arg!r}: {e.strerror}", field="--rss-source") from None


def check_out(out: Path) -> None:
    """``--out`` is a folder (existing or creatable), not a file."""
    for p in (out, *out.parents):
        if p.exists():
            if not p.is_dir():
                raise InputError("is a file; --out wants a folder for flight logs", source=str(p), field="--out")
            break


def check_options(opts) -> None:
    """All checks of ``FlyOptions`` that need no vehicle; raises ``InputError`` on the first problem."""
    check_connect(opts.connect)
    check_rss_source(opts.rss_source)
    check_out(Path(opts.out))
    for name in ("link_timeout_s", "land_timeout_s", "connect_timeout_s"):
        v = getattr(opts, name)
        if v is not None and not v > 0:
            raise InputError(f"must be positive, got {v:g}", field="--" + name.removesuffix("_s").replace("_", "-"))
