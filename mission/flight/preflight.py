"""Checks of ``fly-mission``'s options before anything starts (no vehicle, no connection, no
upload).

Why: a bad ``--rss-source``, a missing FIFO, an ``--out`` that is a file or an unknown ``--connect``
scheme must be one line and exit 2 at once, not a failure after the vehicle took off or the mission
was uploaded.
"""

from __future__ import annotations

import ipaddress
import re
import socket
from pathlib import Path

from mission.errors import InputError
from mission.files import check_writable_dir
from mission.flight.sources import fifo_paths, parse_source

# MAVSDK v4 connection schemes (``udp://``/``tcp://`` are its older spellings, still accepted)
SCHEMES = ("udpin", "udpout", "tcpin", "tcpout", "serial", "serial_flowcontrol", "udp", "tcp")


def check_host(host: str, what: str, field: str, source: str | None = None) -> None:
    """A network address's host: a valid IPv4/IPv6 address when it looks like one (``256.1.1.1`` is
    bad input, exit 2; an address nobody answers at is a dead link, exit 3), else a plausible host
    name."""
    h = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    looks_numeric = bool(re.fullmatch(r"[0-9.]+", h)) or ":" in h
    try:
        if looks_numeric:
            ipaddress.ip_address(h)
            return
    except ValueError:
        raise InputError(
            f"{host!r} in {what!r} is not an IP address", source=source, field=field
        ) from None
    if not _HOSTNAME.fullmatch(h):
        raise InputError(
            f"{host!r} in {what!r} is not a host name or IP address", source=source, field=field
        )


_HOSTNAME = re.compile(
    r"(?=.{1,253}$)[A-Za-z0-9]([A-Za-z0-9-]{0,61}[A-Za-z0-9])?(\.[A-Za-z0-9]([A-Za-z0-9-]{0,61}"
    r"[A-Za-z0-9])?)*\.?"
)


def check_connect(url: str | None, field: str = "--connect", source: str | None = None) -> None:
    """A connection URL (``--connect`` or the mission's ``vehicle.connection``) is well formed: a
    scheme MAVSDK knows, for a network a valid host and port, for a serial link a device that
    exists.  None: the built-in vehicle; an empty string is refused (it silently flew the built-in
    vehicle in real time)."""
    if url is None:
        return
    example = (
        "use e.g. udpin://0.0.0.0:14540, tcpout://127.0.0.1:5760 or serial:///dev/ttyACM0:57600"
    )
    if not url.strip():
        raise InputError(
            f"empty connection; {example}, or leave it out for the built-in vehicle",
            source=source,
            field=field,
        )
    scheme, sep, rest = url.partition("://")
    if not sep or scheme not in SCHEMES:
        raise InputError(f"unknown connection {url!r}; {example}", source=source, field=field)
    if scheme.startswith(("udp", "tcp")):
        host, _, port = rest.rpartition(":")
        if not host or not port.isdigit() or not 0 < int(port) < 65536:
            raise InputError(
                f"{url!r} needs HOST:PORT (port 1-65535) after {scheme}://",
                source=source,
                field=field,
            )
        check_host(host, url, field, source)
    else:  # serial:///dev/ttyACM0[:57600]
        dev, _, baud = rest.rpartition(":")
        if not baud.isdigit():
            dev = rest
        if not dev or not Path(dev).exists():
            raise InputError(
                f"no such serial device {dev or '(none)'!r} in {url!r}", source=source, field=field
            )
        if Path(dev).is_dir() or Path(dev).is_file():
            raise InputError(
                f"{dev!r} in {url!r} is not a serial device", source=source, field=field
            )


def check_rss_source(text: str) -> None:
    """The RSS source parses, its FIFO/file exists, its UDP port can be bound."""
    kind, arg = parse_source(text)
    if kind == "aerpaw-fifo":
        for path in fifo_paths(arg):
            if path is None:
                continue
            p = Path(path)
            if not p.exists():
                raise InputError("no such file or named pipe", source=str(p), field="--rss-source")
            if p.is_dir():
                raise InputError(
                    "is a folder, not a named pipe or file", source=str(p), field="--rss-source"
                )
    elif kind == "udp":
        host, _, port = arg.rpartition(":")
        if not port.isdigit() or not 0 <= int(port) < 65536:
            raise InputError(f"bad UDP port in {arg!r}", field="--rss-source")
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind((host or "0.0.0.0", int(port)))
            except OSError as e:
                raise InputError(
                    f"cannot listen on {arg!r}: {e.strerror}", field="--rss-source"
                ) from None


def check_out(out: Path) -> None:
    """``--out`` is a folder (existing or creatable) that can be written, not a file: refused before
    the vehicle starts (it failed only once the mission was uploaded)."""
    for p in (out, *out.parents):
        if p.exists():
            if not p.is_dir():
                raise InputError(
                    "is a file; --out wants a folder for flight logs", source=str(p), field="--out"
                )
            break
    check_writable_dir(out, "--out")


def check_options(opts) -> None:
    """All checks of ``FlyOptions`` that need no vehicle; raises ``InputError`` on the first
    problem."""
    check_connect(opts.connect)
    check_rss_source(opts.rss_source)
    check_out(Path(opts.out))
    for name in ("link_timeout_s", "land_timeout_s", "connect_timeout_s"):
        v = getattr(opts, name)
        if v is not None and not v > 0:
            raise InputError(
                f"must be positive, got {v:g}",
                field="--" + name.removesuffix("_s").replace("_", "-"),
            )
