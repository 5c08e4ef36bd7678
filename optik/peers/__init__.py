"""Peer IK libraries behind one interface, run beside optik's solvers on the same queries.

One module per peer, one registry of names (:data:`PEERS`)::

    rtb       Robotics Toolbox for Python, ETS.ik_LM (C++)     roboticstoolbox-python
    ikpy      ikpy, scipy least squares with bounds             ikpy
    pink      pink differential IK on Pinocchio, iterated       pin-pink (+ daqp)
    eaik      EAIK closed form by subproblem decomposition      eaik
    pybullet  pybullet calculateInverseKinematics              pybullet

Install them all with ``pip install "optik[peers]"``. :func:`available_peers` tells which
import here and why the others do not; :func:`get_peer` returns a fresh adapter::

    peer = get_peer("rtb", tol=1e-6)
    peer.prepare(robot)                 # PeerUnavailable: not installed, or cannot model it
    answer = peer.solve(T_target, q0)   # PeerAnswer(q, iterations, claimed, note)
    verdict = optik.verify.verify(robot, answer.q, T_target, "pose")   # optik judges

Every adapter builds the peer's model from optik's chain (an ETS, a URDF, EAIK's joint
frames) and checks its FK against optik's before the first query; its answers are joint
vectors in optik's order and units, never judged by the adapter itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Final

from optik.errors import OptikError
from optik.peers._base import FK_MATCH_TOL, Peer, PeerAnswer, PeerUnavailable, fk_mismatch
from optik.peers.eaik import EAIKPeer
from optik.peers.ikpy import IKPyPeer
from optik.peers.pink import PinkPeer
from optik.peers.pybullet import PyBulletPeer
from optik.peers.rtb import RTBPeer

__all__ = [
    "FK_MATCH_TOL",
    "PEERS",
    "Peer",
    "PeerAnswer",
    "PeerInfo",
    "PeerUnavailable",
    "UnknownPeerError",
    "available_peers",
    "fk_mismatch",
    "get_peer",
    "peer_names",
]

#: Registry: peer name -> adapter class, in report order.
PEERS: Final[dict[str, type[Peer]]] = {
    cls.name: cls for cls in (RTBPeer, IKPyPeer, PinkPeer, EAIKPeer, PyBulletPeer)
}


class UnknownPeerError(OptikError):
    """A peer name that is not in the registry.

    Attributes:
        name: the name given.
        valid: the registered names.
    """

    def __init__(self, name: str, valid: list[str]) -> None:
        self.name = name
        self.valid = valid
        super().__init__(f"unknown peer {name!r}; valid names: {', '.join(valid)}")


@dataclass(frozen=True)
class PeerInfo:
    """Whether a peer imports here.

    Attributes:
        name: registry name.
        title: what the method is.
        distribution: its pip name.
        installed: the import succeeded.
        version: the installed version ("" when not installed).
        reason: why not installed ("" when installed).
    """

    name: str
    title: str
    distribution: str
    installed: bool
    version: str
    reason: str


def peer_names() -> tuple[str, ...]:
    """Every registered peer name, in report order."""
    return tuple(PEERS)


def get_peer(name: str, **options: Any) -> Peer:
    """A fresh adapter of peer ``name`` (nothing is imported until it is prepared).

    Args:
        name: a name of :data:`PEERS`.
        **options: the adapter's options (``tol``, ``seed``, ``timeout_s`` for all; see
            each class for its own).

    Raises:
        UnknownPeerError: ``name`` is not registered (the message lists the valid names).
    """
    if name not in PEERS:
        raise UnknownPeerError(name, list(PEERS))
    return PEERS[name](**options)


def available_peers() -> list[PeerInfo]:
    """Every registered peer with whether it imports here, its version, or the reason."""
    out = []
    for name, cls in PEERS.items():
        peer = cls()
        try:
            peer.load()
        except PeerUnavailable as exc:
            out.append(PeerInfo(name, cls.title, cls.distribution, False, "", exc.reason))
            continue
        out.append(PeerInfo(name, cls.title, cls.distribution, True, peer.version, ""))
    return out
