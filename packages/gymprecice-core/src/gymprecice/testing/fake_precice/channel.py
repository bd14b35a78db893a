"""The transport between two participants: one Unix socket, length-prefixed messages."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import socket
import struct
import sys
import tempfile
import uuid
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from gymprecice.testing.fake_precice.errors import PreciceError, partner_gone


class Channel:
    """One connected socket to one coupling partner, with length-prefixed messages.

    A message is a small JSON header (kind, a value, array descriptors) followed by the raw
    bytes of float64 arrays; nothing is unpickled, so nothing a peer sends can run code.
    """

    _PREFIX = struct.Struct("<QI")

    def __init__(self, sock: socket.socket, local: str, remote: str) -> None:
        self.sock = sock
        self.local = local
        self.remote = remote
        #: why the partner is known gone (a later send or receive fails at once)
        self.lost: str | None = None

    def send(self, kind: str, value: Any = None, arrays: Sequence[np.ndarray] = ()) -> None:
        blobs = [np.ascontiguousarray(a, dtype=np.float64) for a in arrays]
        header = json.dumps({"k": kind, "v": value, "a": [list(b.shape) for b in blobs]})
        head = header.encode()
        body_len = len(head) + sum(b.nbytes for b in blobs)
        parts = [self._PREFIX.pack(body_len, len(head)), head, *(b.tobytes() for b in blobs)]
        try:
            self.sock.sendall(b"".join(parts))
        except OSError as exc:
            self._lost("Sending data to", exc.strerror or str(exc))

    def recv(self, kind: str) -> tuple[Any, list[np.ndarray]]:
        prefix = self._read(self._PREFIX.size)
        body_len, head_len = self._PREFIX.unpack(prefix)
        body = self._read(body_len)
        header = json.loads(bytes(body[:head_len]))
        if header["k"] != kind:
            raise PreciceError(
                f'Communication with participant "{self.remote}" is out of step: expected '
                f'"{kind}" but received "{header["k"]}". Both participants must run the '
                "same preCICE configuration with the same preCICE version."
            )
        arrays: list[np.ndarray] = []
        offset = head_len
        for shape in header["a"]:
            count = int(np.prod(shape)) if shape else 1
            nbytes = 8 * count
            arrays.append(
                np.frombuffer(body, dtype=np.float64, count=count, offset=offset).reshape(shape)
            )
            offset += nbytes
        return header["v"], arrays

    def _read(self, n: int) -> bytearray:
        buf = bytearray(n)
        view = memoryview(buf)
        got = 0
        while got < n:
            try:
                k = self.sock.recv_into(view[got:], n - got)
            except InterruptedError:
                continue
            except OSError as exc:
                self._lost("Receiving data from", exc.strerror or str(exc))
            if k == 0:  # the partner closed the connection (died or finalized early)
                self._lost("Receiving data from", "end of file (the connection was closed)")
            got += k
        return buf

    def _lost(self, direction: str, reason: str) -> NoReturn:
        """The partner is gone: wait as preCICE does, then give up (:func:`partner_gone`);
        at once when this channel already gave up once (a later call on it)."""
        if self.lost is not None:
            raise PreciceError(self.lost)
        try:
            partner_gone(direction, self.remote, reason)
        except PreciceError as exc:
            self.lost = str(exc)
            raise

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.sock.close()


def short_socket_dir() -> Path:
    """A private (0700) directory whose path is short enough for ``AF_UNIX`` (108 bytes)."""
    base = tempfile.gettempdir()
    if len(base) > 60:
        base = "/tmp"
    return Path(tempfile.mkdtemp(prefix="fprc-", dir=base))


#: how an abstract socket's address is written in an address file (as ``ss`` shows it)
ABSTRACT_PREFIX = "@"


class Listener:
    """A listening ``AF_UNIX`` socket and the address a partner connects to.

    On Linux the socket lives in the abstract namespace: it has no file, so a participant
    killed while it waits for its partner leaves nothing behind in the temporary directory.
    Elsewhere it is a file in a private directory, removed when the listener closes.
    """

    def __init__(self) -> None:
        self.server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._dir: Path | None = None
        if sys.platform.startswith("linux"):
            name = f"gymprecice-fake-precice-{os.getpid()}-{uuid.uuid4().hex}"
            self.server.bind("\0" + name)
            self.address = ABSTRACT_PREFIX + name
        else:
            self._dir = short_socket_dir()
            self.address = str(self._dir / "s")
            self.server.bind(self.address)
        self.server.listen(1)

    def accept(self) -> socket.socket:
        """The partner's connection; the listener is closed once it has come."""
        conn, _ = self.server.accept()
        self.close()
        return conn

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.server.close()
        if self._dir is not None:
            shutil.rmtree(self._dir, ignore_errors=True)
            self._dir = None


def connect_to(address: str) -> socket.socket:
    """A socket connected to a :class:`Listener`'s ``address`` (raises ``OSError``)."""
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    target = "\0" + address[1:] if address.startswith(ABSTRACT_PREFIX) else address
    try:
        sock.connect(target)
    except OSError:
        sock.close()
        raise
    return sock
