"""Specification of baslip.studies.schedulerprobe: only an address that speaks first with a
plausible Dask handshake passes for a scheduler; anything else is named, in bounded time."""

import socket
import struct
import threading

import pytest

from baslip.studies.schedulerprobe import not_a_scheduler


@pytest.fixture
def speaker():
    """A server on 127.0.0.1 that sends each connection ``greeting[0]`` and closes it."""
    greeting = [b""]
    listener = socket.create_server(("127.0.0.1", 0))

    def serve():
        while True:
            try:
                connection, _ = listener.accept()
            except OSError:  # closed: the test is over
                return
            with connection:
                connection.sendall(greeting[0])

    threading.Thread(target=serve, daemon=True).start()
    yield listener.getsockname()[1], greeting
    listener.close()


def test_a_plausible_handshake_passes(speaker):
    port, greeting = speaker
    greeting[0] = struct.pack("<Q", 58) + bytes(58)
    assert not_a_scheduler("127.0.0.1", port) is None


@pytest.mark.parametrize("sent, words", [
    (b"SSH-2.0-OpenSSH_9.6\r\n", "does not speak Dask's protocol"),
    (struct.pack("<Q", 0), "does not speak Dask's protocol"),
    (b"", "closed the connection without a Dask handshake"),
])
def test_anything_else_is_named(speaker, sent, words):
    port, greeting = speaker
    greeting[0] = sent
    assert words in not_a_scheduler("127.0.0.1", port)


def test_a_silent_server_is_named_and_a_closed_port_cannot_be_reached():
    with socket.create_server(("127.0.0.1", 0)) as silent:  # listens, never speaks
        assert not_a_scheduler("127.0.0.1", silent.getsockname()[1], timeout_s=0.2) == "nothing answered within 0.2 s"
        free = socket.socket()
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
        free.close()
    with pytest.raises(ConnectionRefusedError):
        not_a_scheduler("127.0.0.1", port, timeout_s=0.2)
