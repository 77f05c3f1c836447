"""Does an address answer as a Dask scheduler? Asked with a plain socket, before Dask's
client is given the address.

Dask's client trusts what the other end sends: pointed at a web server, it sends its
handshake, reads the server's "HTTP/1.1 400" as the length of a message (8 bytes as an
integer: 3.07 EiB) and tries to allocate that much. A Dask scheduler speaks first: as
soon as a connection is accepted it sends its handshake, whose first 8 bytes are the
handshake's length (a few dozen bytes). So the probe connects, sends nothing, and waits
a bounded time for those 8 bytes.
"""

from __future__ import annotations

import socket
import struct

#: Seconds to wait for the connection and for the scheduler's first bytes.
PROBE_TIMEOUT_S = 5.0
#: Largest plausible handshake, in bytes (a scheduler's is under 1 kB).
MAX_HANDSHAKE_BYTES = 1 << 20


def scheduler_problem(address: str) -> str | None:
    """What is wrong with the scheduler at ``address`` (``tcp://HOST:PORT``), as one
    line, or None if it answers as a Dask scheduler (an address without a port is left to
    Dask)."""
    host, _, port = address.split("://", 1)[-1].rpartition(":")
    if not (host and port.isdigit()):
        return None
    try:
        why = not_a_scheduler(host.strip("[]"), int(port))
    except OSError as err:
        return f"cannot reach the Dask scheduler at {address}: {err.strerror or err}"
    return None if why is None else f"{address} is no Dask scheduler: {why}"


def not_a_scheduler(host: str, port: int, timeout_s: float = PROBE_TIMEOUT_S) -> str | None:
    """Why ``host:port``, once reached, is no Dask scheduler (one short phrase), or None
    if it speaks first with a plausible handshake within ``timeout_s`` seconds. Raises
    OSError if it cannot be reached (refused, or no connection within ``timeout_s``)."""
    with socket.create_connection((host, port), timeout=timeout_s) as connection:
        try:
            header = _first_bytes(connection, 8)
        except TimeoutError:
            return f"nothing answered within {timeout_s:g} s"
        except OSError as err:  # reset by the other end
            return err.strerror or str(err)
    if len(header) < 8:
        return "it closed the connection without a Dask handshake"
    (length,) = struct.unpack("<Q", header)
    if not 0 < length <= MAX_HANDSHAKE_BYTES:
        return f"it does not speak Dask's protocol (it sent {header[:8]!r})"
    return None


def _first_bytes(connection: socket.socket, count: int) -> bytes:
    """Up to ``count`` bytes, fewer if the other end closes first."""
    data = b""
    while len(data) < count:
        chunk = connection.recv(count - len(data))
        if not chunk:
            break
        data += chunk
    return data
