"""matplotlib's pyplot with a non-interactive backend, for every figure optik draws."""

from __future__ import annotations

from typing import Any

from optik.errors import OptikError


def pyplot() -> Any:
    """The pyplot module with a non-interactive backend, or a clear error."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as exc:  # pragma: no cover - matplotlib is in the test extra
        raise OptikError("plots need matplotlib: pip install 'optik[report]'") from exc
    return plt
