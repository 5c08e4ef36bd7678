"""What a campaign records about itself: its settings, a robot fingerprint, versions.

A resumed run must be the same run: its settings (and optik's version, which decides the
numbers) are compared with those stored beside the finished chunks, and a difference is
an error rather than a file that mixes two runs.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import json
import platform
from typing import Any

import numpy as np

from optik.errors import OptikError
from optik.model import Robot

VERSIONED = ("optik", "numpy", "numba", "dask", "distributed", "zarr", "xarray", "pyarrow")


def robot_fingerprint(robot: Robot) -> str:
    """SHA-256 (hex, 16 digits) of the robot's kinematics and limits: same arm, same hash."""
    digest = hashlib.sha256()
    K, prismatic, C, _, lower, upper = robot.chain.kernel_args()
    for array in (K, prismatic, C, lower, upper):
        digest.update(np.ascontiguousarray(array).tobytes())
    return digest.hexdigest()[:16]


def array_fingerprint(array: np.ndarray) -> str:
    """SHA-256 (hex, 16 digits) of an array's shape and float64 bytes."""
    data = np.ascontiguousarray(array, dtype=np.float64)
    digest = hashlib.sha256(repr(data.shape).encode())
    digest.update(data.tobytes())
    return digest.hexdigest()[:16]


def versions() -> dict[str, str]:
    """Versions of optik, Python and the packages whose code decides a campaign's numbers."""
    return dict(_versions())


@functools.cache
def _versions() -> dict[str, str]:
    """:func:`versions`, looked up once per process (about 30 ms of package metadata)."""
    found = {"python": platform.python_version()}
    for name in VERSIONED:
        try:
            found[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            found[name] = "not installed"
    if found["optik"] == "not installed":  # a source checkout without metadata
        from optik._version import __version__

        found["optik"] = __version__
    return found


def as_json(value: Any) -> Any:
    """``value`` as plain JSON types (numpy scalars and arrays to numbers and lists)."""
    return json.loads(json.dumps(value, default=lambda v: np.asarray(v).tolist()))


def check_same_run(where: str, stored: dict[str, Any], settings: dict[str, Any]) -> None:
    """Raise unless a stored run has the same settings as the one asked for.

    Raises:
        OptikError: the settings differ (the message lists the differing keys).
    """
    wanted = as_json(settings)
    differ = sorted(k for k in set(stored) | set(wanted) if stored.get(k) != wanted.get(k))
    if differ:
        detail = "; ".join(
            f"{k}: stored {stored.get(k)!r}, asked {wanted.get(k)!r}" for k in differ
        )
        raise OptikError(
            f"{where}: cannot resume a run with other settings ({detail:.600}); "
            "give another output path, or the same settings"
        )


__all__ = ["array_fingerprint", "as_json", "check_same_run", "robot_fingerprint", "versions"]
