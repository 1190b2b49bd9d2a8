"""CURVE keys, the team's allow-list and ZAP authentication for :mod:`btcap.transports.zeromq`.

Keys live in ZeroMQ's certificate files (``zmq.auth.create_certificates``): a robot keeps
its secret certificate ``NAME.key_secret``; the team shares a directory of public
certificates ``NAME.key``, one per member, and the file name is the member's name; its
metadata holds the member's role (:mod:`~btcap.transports.identity`). A peer is who its
key says: pyzmq's asyncio authenticator admits only keys on the allow-list and stamps
every message from that connection with the member's name as its ``User-Id``, which the
transport compares with what the message claims (the member itself, or an observer
speaking for it: ``NAME+TAG``).
"""

from __future__ import annotations

import ipaddress
import os
import tempfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zmq
import zmq.auth
from zmq.auth.asyncio import AsyncioAuthenticator
from zmq.utils import z85

from btcap.transports.identity import (
    OBSERVER,
    ROBOT,
    check_member_name,
    check_role,
    is_observer_id,
    member_of,
    read_role,
)

__all__ = [
    "DEFAULT_MAX_MESSAGE_BYTES",
    "ZAP_DOMAIN",
    "Curve",
    "KeyPair",
    "TeamKeys",
    "authenticated",
    "curve_for",
    "is_loopback",
    "write_key_pair",
]

DEFAULT_MAX_MESSAGE_BYTES = 4 * 1024 * 1024
"""Largest frame a transport accepts (and sends): libzmq drops a connection that sends
a bigger one as soon as it reads the frame's length, before allocating it."""
ZAP_DOMAIN = "btcap"
"""Without a ZAP domain libzmq would encrypt but never ask the authenticator."""
_KEY_LEN = 40  # a z85-encoded 32-byte CURVE key


def _check_key(key: bytes, where: str) -> bytes:
    try:
        if len(key) == _KEY_LEN and len(z85.decode(key)) == 32:
            return key
    except (ValueError, KeyError, TypeError):
        pass
    raise ValueError(f"{where}: not a z85-encoded CURVE key")


@dataclass(frozen=True, slots=True, repr=False)
class KeyPair:
    """One robot's CURVE key pair (z85-encoded, as in certificate files)."""

    public: bytes
    secret: bytes

    def __post_init__(self) -> None:
        _check_key(self.public, "public key")
        _check_key(self.secret, "secret key")

    def __repr__(self) -> str:  # never print a secret key into a log
        return f"KeyPair(public={self.public.decode()!r})"

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> KeyPair:
        """Read a secret certificate (``NAME.key_secret``, from ``btcap keys new``)."""
        public, secret = _load(Path(path))
        if secret is None:
            raise ValueError(f"{path}: holds no secret key (use the .key_secret file)")
        return cls(_check_key(public, str(path)), _check_key(secret, str(path)))


def write_key_pair(
    directory: str | os.PathLike[str], name: str, role: str = ROBOT
) -> tuple[Path, Path]:
    """Write ``NAME.key`` (public, for the team's directory) and ``NAME.key_secret``
    (readable by its owner only) with ``zmq.auth.create_certificates``, the ``role`` in
    their metadata; never overwrite."""
    folder = Path(directory)
    if not name or name != Path(name).name or name.startswith(".") or "/" in name:
        raise ValueError(f"key name {name!r}: expected a plain robot name")
    if (why := check_member_name(name)) is not None:
        raise ValueError(f"key name {name!r}: {why}")
    check_role(role, f"key {name!r}")
    if not folder.is_dir():
        raise ValueError(f"{folder}: no such directory")
    public, secret = folder / f"{name}.key", folder / f"{name}.key_secret"
    for path in (public, secret):
        if path.exists():
            raise ValueError(f"{path}: already exists (not overwritten)")
    done: list[Path] = []
    with tempfile.TemporaryDirectory(dir=folder, prefix=".btcap-keys-") as tmp:
        made = zmq.auth.create_certificates(tmp, name)
        os.chmod(made[1], 0o600)
        for cert in made:  # pyzmq puts metadata in the secret file only
            _add_metadata(Path(cert), {"name": name, "role": role})
        try:
            for src, dst in zip(made, (public, secret), strict=True):
                os.link(src, dst)  # unlike a rename, fails if dst appeared meanwhile
                done.append(dst)
        except FileExistsError as exc:
            for path in done:
                path.unlink()
            raise ValueError(f"{exc.filename}: already exists (not overwritten)") from None
    return public, secret


def _add_metadata(path: Path, values: Mapping[str, str]) -> None:
    """Fill the certificate's ``metadata`` section (ZeroMQ's ZPL format, quoted values)."""
    lines = "".join(f'    {key} = "{value}"\n' for key, value in values.items())
    text = path.read_text(encoding="utf-8")
    path.write_text(text.replace("\nmetadata\n", f"\nmetadata\n{lines}", 1), encoding="utf-8")


def _load(path: Path) -> tuple[bytes, bytes | None]:
    if not path.is_file():
        raise ValueError(f"{path}: no such certificate file")
    try:
        return zmq.auth.load_certificate(path)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a ZeroMQ certificate ({exc})") from None


class TeamKeys:
    """The allow-list: member name -> public key and role. Only these may talk to a secure
    transport. ``roles`` maps names to :data:`~btcap.transports.identity.ROLES`; a member
    it leaves out is a robot (files always say: see :meth:`load`)."""

    __slots__ = ("_by_key", "_by_name", "_roles", "folder")

    def __init__(
        self, members: Mapping[str, bytes], roles: Mapping[str, str] | None = None
    ) -> None:
        #: The directory it was loaded from (:meth:`load`), watched for revocations.
        self.folder: Path | None = None
        self._by_name: dict[str, bytes] = {}
        self._by_key: dict[bytes, str] = {}
        self._roles: dict[str, str] = {}
        for name, key in members.items():
            _check_key(key, f"member {name!r}")
            if (why := check_member_name(name)) is not None:
                raise ValueError(f"member {name!r}: {why}")
            other = self._by_key.get(key)
            if other is not None:
                raise ValueError(f"members {other!r} and {name!r} have the same public key")
            self._by_name[name] = key
            self._by_key[key] = name
            self._roles[name] = check_role((roles or {}).get(name, ROBOT), f"member {name!r}")
        for name in roles or {}:
            if name not in self._by_name:
                raise ValueError(f"role given for {name!r}, which has no key")

    @classmethod
    def load(cls, directory: str | os.PathLike[str]) -> TeamKeys:
        """Every ``NAME.key`` public certificate in ``directory`` (names from file names,
        roles from their metadata: one without is an error naming it)."""
        folder = Path(directory)
        if not folder.is_dir():
            raise ValueError(f"{folder}: no such directory of public certificates")
        files = [p for p in sorted(folder.glob("*.key")) if p.is_file()]
        members = {p.stem: _load(p)[0] for p in files}
        if not members:
            raise ValueError(f"{folder}: holds no public certificates (NAME.key files)")
        try:
            roles = {p.stem: read_role(p) for p in files}
        except OSError as exc:
            raise ValueError(f"{folder}: cannot read ({exc})") from None
        try:
            team = cls(members, roles)
        except ValueError as exc:
            raise ValueError(f"{folder}: {exc}") from None
        team.folder = folder
        return team

    def key_of(self, name: str) -> bytes | None:
        return self._by_name.get(name)

    def role_of(self, system_id: str) -> str | None:
        """A peer's role: its member's, ``observer`` for an observer speaking for a
        member, None for a stranger."""
        role = self._roles.get(member_of(system_id))
        return OBSERVER if role is not None and is_observer_id(system_id) else role

    def name_of(self, key: bytes) -> str | None:
        """The member holding ``key`` (z85-encoded), or None for a stranger."""
        return self._by_key.get(key)

    def __contains__(self, name: object) -> bool:
        return name in self._by_name

    def __iter__(self) -> Iterator[str]:
        return iter(self._by_name)

    def __len__(self) -> int:
        return len(self._by_name)

    def __repr__(self) -> str:
        return f"TeamKeys({sorted(self._by_name)})"


Refused = Callable[[str, bytes, "str | None"], None]
"""Told of each refused handshake: the peer's address, its z85 key, the member it names."""


class _TeamAuthenticator(AsyncioAuthenticator):
    """pyzmq's ZAP handler, admitting the team's keys and naming peers after them."""

    def __init__(
        self, context: zmq.Context[Any], team: TeamKeys, refused: Refused | None = None
    ) -> None:
        super().__init__(context)
        self.team = team
        self.refused = refused
        self.address = ""  #: the peer being checked (pyzmq does not pass it on)
        self.configure_curve_callback(ZAP_DOMAIN, self)

    async def handle_zap_message(self, msg: list[bytes]) -> None:
        self.address = msg[3].decode(errors="replace")[:80] if len(msg) > 3 else "?"
        await super().handle_zap_message(msg)

    def callback(self, domain: str, key: bytes) -> bool:
        """The credentials check pyzmq calls with the client's z85 key."""
        admitted = self.team.name_of(key) is not None
        if not admitted and self.refused is not None:
            # (the member it names: None while every known key is admitted)
            self.refused(self.address, key, self.team.name_of(key))
        return admitted

    def curve_user_id(self, client_public_key: bytes) -> str:
        name = self.team.name_of(z85.encode(client_public_key))
        assert name is not None  # only called for keys the callback admitted
        return name


class Curve:
    """CURVE for one transport: its server socket, its client sockets, its ZAP handler.

    ZAP handlers are per zmq context (one ``inproc://zeromq.zap.01`` each), so a secure
    transport wants a context of its own.
    """

    __slots__ = ("_auth", "_own", "keys", "team")

    def __init__(self, system_id: str, keys: KeyPair, team: TeamKeys) -> None:
        member = member_of(system_id)  # an observer uses its member's key
        self._own = system_id
        if team.key_of(member) != keys.public:
            raise ValueError(
                f"system {system_id!r}: its public key is not the team's certificate "
                f"{member}.key (peers would refuse it): check the keys and the system id"
            )
        self.keys = keys
        self.team = team
        self._auth: _TeamAuthenticator | None = None

    def server(self, sock: zmq.Socket[bytes]) -> None:
        sock.setsockopt(zmq.CURVE_SERVER, 1)
        sock.setsockopt(zmq.CURVE_SECRETKEY, self.keys.secret)
        sock.setsockopt(zmq.CURVE_PUBLICKEY, self.keys.public)
        sock.setsockopt(zmq.ZAP_DOMAIN, ZAP_DOMAIN.encode())
        # Until the authenticator runs, handshakes fail (and peers retry) rather than
        # being let in unauthenticated.
        sock.setsockopt(zmq.ZAP_ENFORCE_DOMAIN, 1)

    def client(self, sock: zmq.Socket[bytes], peer: str) -> None:
        """Make ``sock`` talk to ``peer`` only if the server holds that member's key."""
        server_key = self.team.key_of(member_of(peer))
        if server_key is None:
            raise ValueError(f"peer {peer!r} has no public key in the team's certificates")
        sock.setsockopt(zmq.CURVE_SERVERKEY, server_key)
        sock.setsockopt(zmq.CURVE_SECRETKEY, self.keys.secret)
        sock.setsockopt(zmq.CURVE_PUBLICKEY, self.keys.public)

    def trust(self, team: TeamKeys) -> set[str]:
        """Admit ``team`` from now on (ZAP asks it at every handshake); the members whose
        key it no longer holds (removed, or replaced by another key) are returned: their
        links were made with a key we now refuse. Raises ValueError, trusting nothing new,
        if ``team`` lacks our own key."""
        member = member_of(self._own)
        if team.key_of(member) != self.keys.public:
            raise ValueError(f"{team.folder}: holds no {member}.key with our public key")
        old, self.team = self.team, team
        if self._auth is not None:
            self._auth.team = team
        return {name for name in old if team.key_of(name) != old.key_of(name)}

    def start(self, context: zmq.Context[Any], refused: Refused | None = None) -> None:
        """Run the ZAP handler on the running asyncio loop (telling ``refused`` whom it
        refused)."""
        if self._auth is not None:
            return
        auth = _TeamAuthenticator(context, self.team, refused)
        try:
            auth.start()
        except zmq.ZMQError as exc:
            auth.stop()
            raise RuntimeError(
                f"cannot start ZAP authentication ({exc}): another secure transport "
                "shares this zmq context; give each its own"
            ) from None
        self._auth = auth

    def stop(self) -> None:
        auth, self._auth = self._auth, None
        if auth is not None:
            auth.stop()


def authenticated(ident: bytes, part: zmq.Frame) -> tuple[bytes, str]:
    """Who sent a received message (its routing id ``ident``, ``part`` one of its parts),
    and what is wrong with it ("" if nothing).

    The ``User-Id`` is the member ZAP authenticated; the routing id is the sender's
    choice (its name, a ``/`` and a per-connection suffix), only checked for a lie. An
    observer speaking for that member (``NAME+TAG``) is itself. On a problem the routing
    id is returned, for the log.
    """
    try:
        user = str(part.get("User-Id")).encode()
    except zmq.ZMQError:  # not past ZAP: never trust a missing stamp
        return ident, "unauthenticated"
    if ident == user or ident.startswith(user + b"/"):
        return user, ""
    if ident.startswith(user + b"+"):  # member names hold no '+' (TeamKeys checks)
        return ident.partition(b"/")[0], ""
    return ident, "identity mismatch"


def is_loopback(endpoint: str) -> bool:
    """Whether only this host can reach ``endpoint`` (ipc, inproc or a loopback tcp one)."""
    if endpoint.startswith(("ipc://", "inproc://")):
        return True
    if not endpoint.startswith("tcp://"):
        return False
    host = endpoint[len("tcp://") :].rpartition(":")[0].strip("[]")
    if host in ("localhost", "lo"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:  # a wildcard, a host name or an interface name
        return False


def curve_for(
    system_id: str,
    bind: str,
    keys: KeyPair | str | os.PathLike[str] | None,
    trusted: TeamKeys | str | os.PathLike[str] | None,
    insecure: bool,
) -> Curve | None:
    """A transport's CURVE set-up from keys or key files, or None after checking that a
    keyless transport binds only where this host alone can reach it."""
    if keys is None and trusted is None:
        if not insecure and not is_loopback(bind):
            raise ValueError(
                f"cannot bind {bind!r} without keys: other hosts could reach it; pass "
                "keys= and trusted=, bind a loopback address, or pass insecure=True"
            )
        return None
    if keys is None or trusted is None:
        raise ValueError(f"system {system_id!r}: keys and trusted go together (CURVE)")
    if bind.startswith("inproc://"):
        raise ValueError(f"cannot bind {bind!r} with keys: inproc:// is not encrypted")
    pair = keys if isinstance(keys, KeyPair) else KeyPair.load(keys)
    team = trusted if isinstance(trusted, TeamKeys) else TeamKeys.load(trusted)
    return Curve(system_id, pair, team)
