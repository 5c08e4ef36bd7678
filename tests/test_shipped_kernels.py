"""Kernels beside the sources serve a user who cannot write there (optik._shipped_kernels)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

from optik._shipped_kernels import _seed

CHECKOUT = Path(__file__).resolve().parent.parent

# First calls of the kinematics, counting numba's compilations.
FIRST_CALLS = textwrap.dedent(
    """
    import json, os, sys
    from numba.core import caching, event

    if sys.argv[1] == "read-only":
        # What a user who cannot write optik's __pycache__ folders sees (the tests run
        # as their owner): numba's probe fails, and so does os.access.
        package = os.path.join(os.environ["OPTIK_CHECKOUT"], "optik")
        access = os.access

        def no_write(path, mode, *args, **kwargs):
            inside = str(path).startswith(package) and str(path).endswith("__pycache__")
            return False if inside and mode & os.W_OK else access(path, mode, *args, **kwargs)

        os.access = no_write
        caching.InTreeCacheLocator.from_function = classmethod(lambda cls, f, p: None)

    class Count(event.Listener):
        n = 0
        def on_start(self, e):
            Count.n += 1
        def on_end(self, e):
            pass

    event.register("numba:compile", Count())
    import optik
    robot = optik.load_problem("panda").robot
    T, J = robot.fk_jacobian(robot.mid_limits)
    print(json.dumps({"compiles": Count.n, "x": float(T[0, 3])}))
    """
)


def _first_calls(mode: str, home: Path) -> dict[str, float]:
    home.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(XDG_CACHE_HOME=str(home), OPTIK_CHECKOUT=str(CHECKOUT))
    done = subprocess.run(
        [sys.executable, "-c", FIRST_CALLS, mode],
        env=env,
        capture_output=True,
        text=True,
        check=True,
        cwd=home,
    )
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def test_a_user_who_cannot_write_the_package_loads_its_kernels(tmp_path: Path) -> None:
    # numba ignored the package's __pycache__ for such a user and compiled every kernel
    # into ~/.cache/numba (55 compilations before a first forward kinematics).
    owner = _first_calls("owner", tmp_path / "owner")  # fills the package's cache if needed
    other = _first_calls("read-only", tmp_path / "other")
    assert other["compiles"] == 0
    assert other["x"] == owner["x"]
    assert list((tmp_path / "other" / "numba").rglob("*.nbi"))  # numba's folder of that user
    again = _first_calls("read-only", tmp_path / "other")
    assert again["compiles"] == 0


def test_seeding_copies_what_the_cache_lacks_and_leaves_its_own_indexes(tmp_path: Path) -> None:
    shipped, cache = tmp_path / "shipped", tmp_path / "cache"
    shipped.mkdir()
    cache.mkdir()
    for name, text in [
        ("k-a.py10.nbi", "index a"),
        ("k-a.py10.1.nbc", "data a1"),
        ("k-a.py10.2.nbc", "data a2"),
        ("k-b.py20.nbi", "index b"),
        ("k-b.py20.1.nbc", "data b1"),
    ]:
        (shipped / name).write_text(text)
    (cache / "k-b.py20.nbi").write_text("the user's own index b")
    assert _seed.__wrapped__(str(shipped), str(cache)) == 1
    assert sorted(p.name for p in cache.iterdir()) == [
        "k-a.py10.1.nbc",
        "k-a.py10.2.nbc",
        "k-a.py10.nbi",
        "k-b.py20.nbi",
    ]
    assert (cache / "k-a.py10.2.nbc").read_text() == "data a2"
    assert (cache / "k-b.py20.nbi").read_text() == "the user's own index b"
