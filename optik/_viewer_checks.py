"""What reaches the viewer from outside, checked (:mod:`optik.viewer`).

A dragged pose from the page, and the address its server is asked to listen on.
"""

from __future__ import annotations

import socket
from typing import Any

import numpy as np

from optik._checks import FloatArray
from optik.errors import OptikError
from optik.poses import pose


def dragged_pose(position: Any, wxyz: Any) -> FloatArray:
    """The 4x4 pose of a gizmo update from the page (position (3,) m, quaternion (4,)).

    Raises:
        OptikError: not 3 and 4 finite numbers, or a zero quaternion.
    """
    try:
        p = np.asarray(position, dtype=float)
        w = np.asarray(wxyz, dtype=float)
    except (TypeError, ValueError):
        raise OptikError("dragged target: position and quaternion must be numbers") from None
    if p.shape != (3,) or w.shape != (4,):
        raise OptikError(
            f"dragged target: expected a position (3,) and a quaternion (4,), got "
            f"{p.shape} and {w.shape}"
        )
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(w))):
        raise OptikError("dragged target: position and quaternion must be finite")
    largest = float(np.max(np.abs(w)))
    if largest == 0.0:
        raise OptikError("dragged target: zero quaternion")
    w = w / largest  # no overflow in the norm (1e308 entries)
    return pose(p, quat_wxyz=w / float(np.linalg.norm(w)))


def check_bindable(host: str, port: int) -> None:
    """Refuse an address the server could not listen on, before viser starts.

    viser waits for its server thread without a timeout, and that thread never signals
    when it cannot bind (an address of another machine, a malformed host, the last port
    taken): the process would hang.

    Raises:
        OptikError: ``host`` does not resolve or is not an address of this machine, or
            ``port`` is taken and no higher port is left to try.
    """
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError) as exc:
        raise OptikError(f"host {host!r} does not resolve: {exc}") from None
    family, kind, proto, _, address = infos[0]
    with socket.socket(family, kind, proto) as probe:
        try:
            probe.bind((address[0], 0))
        except OSError as exc:
            raise OptikError(f"cannot listen on host {host!r}: {exc.strerror}") from None
    # viser moves to the next port while one is taken, and past 65535 its thread fails:
    # one of port..65535 must be free.
    reason = ""
    for candidate in range(port, 65536):
        with socket.socket(family, kind, proto) as probe:
            try:
                probe.bind((address[0], candidate))
            except OSError as exc:
                reason = exc.strerror or str(exc)
                continue
        return
    where = f"port {port}" if port == 65535 else f"ports {port} to 65535"
    raise OptikError(f"{where} on {host!r}: every one is taken ({reason})")
