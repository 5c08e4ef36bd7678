"""Kernels beside the sources serve a user who cannot write there (optik._shipped_kernels)."""

from __future__ import annotations

import json
import operator
import os
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

from optik._kernel_cache import current_stamp, read_index
from optik._shipped_kernels import _seed

CHECKOUT = Path(__file__).resolve().parent.parent

# First calls of the kinematics, counting numba's compilations.
FIRST_CALLS = textwrap.dedent(
    """
    import json, os, sys
    from numba.core import caching, event

    sys.path.insert(0, sys.argv[2])  # the checkout, or a symlink to it
    if sys.argv[1] == "read-only":
        # What a user who cannot write optik's __pycache__ folders sees (the tests run
        # as their owner): numba's probe fails, and so does os.access.
        package = os.path.join(os.environ["OPTIK_CHECKOUT"], "optik")
        access = os.access

        def no_write(path, mode, *args, **kwargs):
            real = os.path.realpath(path)
            inside = real.startswith(package) and real.endswith("__pycache__")
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
    assert optik.__file__.startswith(sys.argv[2]), optik.__file__
    robot = optik.load_problem("panda").robot
    T, J = robot.fk_jacobian(robot.mid_limits)
    print(json.dumps({"compiles": Count.n, "x": float(T[0, 3])}))
    """
)


def _first_calls(mode: str, home: Path, root: Path = CHECKOUT) -> dict[str, float]:
    home.mkdir(exist_ok=True)
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env.update(XDG_CACHE_HOME=str(home), OPTIK_CHECKOUT=str(CHECKOUT))
    done = subprocess.run(
        [sys.executable, "-c", FIRST_CALLS, mode, str(root)],
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
    # Imported through a symlink to the package's folder: numba is given that path.
    link = tmp_path / "link"
    link.symlink_to(CHECKOUT, target_is_directory=True)
    through_link = _first_calls("read-only", tmp_path / "linked", link)
    assert through_link["compiles"] == 0


class _Unreadable:
    """Unpickles into a division by zero."""

    def __reduce__(self) -> tuple[object, tuple[int, int]]:
        return operator.truediv, (1, 0)


def _index(path: Path, version: str, stamp: object, data: list[str]) -> None:
    """Write a numba cache index naming ``data`` files, as numba writes it."""
    overloads = {(f"signature {k}", "target"): name for k, name in enumerate(data)}
    path.write_bytes(pickle.dumps(version, protocol=-1) + pickle.dumps((stamp, overloads)))


def test_seeding_copies_fresh_kernels_over_missing_or_stale_ones(tmp_path: Path) -> None:
    # A user's stale index (an earlier release) was kept: that user compiled every kernel
    # again after an upgrade. A stale shipped index (another numba) is worth nothing.
    sources = tmp_path / "package"
    shipped, cache = sources / "__pycache__", tmp_path / "cache"
    shipped.mkdir(parents=True)
    cache.mkdir()
    (sources / "kern.py").write_text("# kernels\n")
    fresh = current_stamp(sources / "kern.py")
    stale = (fresh[0], ("another source", "another fingerprint"))
    for name, (version, stamp) in {"a": fresh, "b": fresh, "c": fresh, "d": stale}.items():
        _index(shipped / f"kern.{name}-1.py311.nbi", version, stamp, [f"kern.{name}-1.py311.1.nbc"])
        (shipped / f"kern.{name}-1.py311.1.nbc").write_text(f"shipped {name}")
    # An index whose signatures cannot be rebuilt here: skipped, not an error in import.
    (shipped / "kern.e-1.py311.nbi").write_bytes(
        pickle.dumps(fresh[0]) + pickle.dumps((fresh[1], {_Unreadable(): "kern.e-1.1.nbc"}))
    )
    _index(cache / "kern.b-1.py311.nbi", *fresh, ["kern.b-1.py311.7.nbc"])  # the user's own
    _index(cache / "kern.c-1.py311.nbi", *stale, ["kern.c-1.py311.1.nbc"])  # an old release's
    (cache / "kern.c-1.py311.1.nbc").write_text("old c")
    assert _seed.__wrapped__(str(shipped), str(cache)) == 2  # a and c
    assert read_index(cache / "kern.a-1.py311.nbi")[:2] == fresh
    assert (cache / "kern.a-1.py311.1.nbc").read_text() == "shipped a"
    assert read_index(cache / "kern.b-1.py311.nbi")[2] == {
        ("signature 0", "target"): "kern.b-1.py311.7.nbc"
    }
    assert read_index(cache / "kern.c-1.py311.nbi")[:2] == fresh
    assert (cache / "kern.c-1.py311.1.nbc").read_text() == "shipped c"
    assert not (cache / "kern.d-1.py311.nbi").exists()
    assert not (cache / "kern.e-1.py311.nbi").exists()
    assert not list(cache.glob(".*"))  # no temporary file left
