"""Meeting the partners at ``initialize``: addresses, sockets, handshake, mesh exchange."""

from __future__ import annotations

import contextlib
import os
import socket
import time
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from gymprecice.plugin.precice_xml import PreciceConfig
from gymprecice.testing.fake_precice.channel import Channel, Listener, connect_to
from gymprecice.testing.fake_precice.coupling import Coupling
from gymprecice.testing.fake_precice.errors import PreciceError
from gymprecice.testing.fake_precice.mesh import Mesh
from gymprecice.testing.fake_precice.version import PRECICE_VERSION

ADDRESS_FILE = "fake-precice.address"
POLL_SECONDS = 0.002


class Rendezvous:
    """How one participant meets its partners, as the ``<m2n:sockets>`` tags say.

    The acceptor of each link publishes a socket address in
    ``<exchange-directory>/precice-run/<acceptor>-<connector>/``; the connector waits for
    it without a timeout, like preCICE. A handshake checks the partner's name, preCICE
    version and configuration file; then the provided meshes go to their receivers.
    """

    def __init__(
        self, name: str, cfg: PreciceConfig, meshes: dict[str, Mesh], config_hash: str
    ) -> None:
        self.name = name
        self.cfg = cfg
        self.spec = cfg.participants[name]
        self.meshes = meshes
        self.config_hash = config_hash

    def links(self) -> list[tuple[str, str, str]]:
        """(acceptor, connector, exchange directory) of every m2n this participant is part of."""
        links = []
        for m2n in self.cfg.m2n:
            if self.name in (m2n.acceptor, m2n.connector):
                links.append((m2n.acceptor, m2n.connector, m2n.exchange_directory or "."))
        return sorted(links)

    def connect(self, coupling: Coupling, scheme_partners: Iterable[str]) -> None:
        """Publish or find every partner's address, connect, and shake hands (blocks)."""
        links = self.links()
        partners = {a if c == self.name else c for a, c, _ in links}
        needed = set(scheme_partners)
        needed.update(self.spec.received_meshes.values())
        for other in self.cfg.participants.values():
            if any(src == self.name for src in other.received_meshes.values()):
                needed.add(other.name)
        needed.discard(self.name)
        for partner in sorted(needed - partners):
            coupling.channel(partner)  # raises with the m2n advice
        listeners: list[tuple[str, Path, Listener]] = []
        try:
            for acceptor, connector, directory in links:
                if acceptor != self.name:
                    continue
                link_dir = Path(directory) / "precice-run" / f"{acceptor}-{connector}"
                address = link_dir / ADDRESS_FILE
                if address.exists():
                    raise PreciceError(
                        "Unable to establish connection as a connection file already exists at "
                        f'"{address}". This is likely a leftover of a previous crash or stop during '
                        'communication build-up. Please remove the "precice-run" directory and '
                        "restart the simulation."
                    )
                listener = Listener()
                link_dir.mkdir(parents=True, exist_ok=True)
                tmp = link_dir / (ADDRESS_FILE + "~")
                tmp.write_text(
                    f"{listener.address}\nAcceptor: {acceptor}, Requester: {connector}\n"
                )
                os.replace(tmp, address)
                listeners.append((connector, address, listener))
            hello = {"participant": self.name, "version": PRECICE_VERSION, "hash": self.config_hash}
            pending: list[Channel] = []
            for acceptor, connector, directory in links:
                if connector != self.name:
                    continue
                link_dir = Path(directory) / "precice-run" / f"{acceptor}-{connector}"
                sock = self._request(link_dir, acceptor)
                ch = Channel(sock, self.name, acceptor)
                ch.send("hello", hello)
                pending.append(ch)
            for connector, address, listener in listeners:
                conn = listener.accept()
                with contextlib.suppress(OSError):
                    address.unlink()
                ch = Channel(conn, self.name, connector)
                remote, _ = ch.recv("hello")
                self._check_hello(remote, connector)
                ch.send("hello", hello)
                coupling.channels[connector] = ch
            for ch in pending:
                remote, _ = ch.recv("hello")
                self._check_hello(remote, ch.remote)
                coupling.channels[ch.remote] = ch
        finally:  # a listener nobody reached: closed (its file, if any, removed)
            for _connector, _address, listener in listeners:
                listener.close()

    def _request(self, link_dir: Path, acceptor: str) -> socket.socket:
        """Wait (forever, like preCICE) for the acceptor's address, then connect."""
        address = link_dir / ADDRESS_FILE
        while True:
            try:
                text = address.read_text()
            except OSError:
                if link_dir.is_dir() and any(
                    p.name != ADDRESS_FILE and not p.name.endswith("~") for p in link_dir.iterdir()
                ):
                    raise PreciceError(
                        f'Participant "{acceptor}" publishes its address in "{link_dir}" the way '
                        "real preCICE does, but this participant runs gymprecice's fake_precice. "
                        "Mixing preCICE versions can lead to undefined behavior and is, thus, "
                        "forbidden: run every participant with the same library."
                    ) from None
                time.sleep(POLL_SECONDS)
                continue
            path = text.splitlines()[0].strip() if text else ""
            try:
                return connect_to(path)
            except OSError:
                time.sleep(POLL_SECONDS)

    def _check_hello(self, remote: dict[str, str], expected: str) -> None:
        if remote.get("participant") != expected:
            raise PreciceError(
                f'Expected to be connected to participant "{expected}" but participant '
                f'"{remote.get("participant")}" answered. Check the m2n tags of the configuration.'
            )
        if remote.get("version") != PRECICE_VERSION:
            raise PreciceError(
                f"This participant {self.name} uses preCICE version {PRECICE_VERSION} but the "
                f"requester participant {expected} uses preCICE version {remote.get('version')}. "
                "Mixing preCICE versions can lead to undefined behavior and is, thus, forbidden."
            )
        if remote.get("hash") != self.config_hash:
            raise PreciceError(
                f"This participant {self.name} uses a different configuration file than the "
                f"remote participant {expected}. Hashes differ {self.config_hash} != "
                f"{remote.get('hash')}."
            )

    def exchange_meshes(self, coupling: Coupling) -> None:
        """Send provided meshes to their receivers; one link at a time, in a global order."""
        for acceptor, connector, _ in self.links():
            partner = connector if acceptor == self.name else acceptor
            ch = coupling.channels[partner]
            outgoing = sorted(
                m
                for m, src in self.cfg.participants[partner].received_meshes.items()
                if src == self.name
            )
            incoming = sorted(m for m, src in self.spec.received_meshes.items() if src == partner)
            for name in outgoing:
                if name not in self.spec.provided_meshes:
                    raise PreciceError(
                        f'Participant "{partner}" receives mesh "{name}" from "{self.name}", '
                        f'but "{self.name}" does not provide it (<provide-mesh name="{name}" />).'
                    )
            if acceptor == self.name:
                self._send_meshes(ch, outgoing)
                self._receive_meshes(ch, incoming)
            else:
                self._receive_meshes(ch, incoming)
                self._send_meshes(ch, outgoing)

    def _send_meshes(self, ch: Channel, names: list[str]) -> None:
        ch.send("meshes", names, [self.meshes[n].coordinates for n in names])

    def _receive_meshes(self, ch: Channel, names: list[str]) -> None:
        sent, arrays = ch.recv("meshes")
        got = dict(zip(sent, arrays))
        for name in names:
            if name not in got:
                raise PreciceError(
                    f'Participant "{ch.remote}" did not send mesh "{name}"; check that it '
                    f'provides it (<provide-mesh name="{name}" />).'
                )
            mesh = self.meshes[name]
            mesh.chunks = [np.array(got[name], dtype=np.float64).reshape(-1, mesh.dims)]
            mesh.coords = None
