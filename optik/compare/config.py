"""What a comparison run covers (:class:`RunConfig`) and what it did (:class:`RunStats`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from typing import Any

from optik._checks import FloatArray, check_bool, check_int, check_real
from optik.compare.backends import step_backends
from optik.compare.peer_runs import PeerStatus
from optik.compare.results import Key, ResultRow, settings_json
from optik.errors import OptikError
from optik.peers import UnknownPeerError, peer_names
from optik.problems import Problem
from optik.solvers import available_solvers

#: Largest ``n`` and ``closed_form_configs`` (targets or configurations per robot; the
#: CLI's ``-n`` takes the same bound).
MAX_TARGETS = 1_000_000
#: Largest ``seed`` (numpy's seeds of the targets take 32 bits; the CLI's ``--seed`` too).
MAX_SEED = 2**32 - 1
#: Largest ``timeout_s``: a day (the report's figures scale their axes by it).
MAX_TIMEOUT_S = 86_400.0


__all__ = ["RunConfig", "RunStats", "ik_settings"]


@dataclass(frozen=True)
class RunConfig:
    """What a comparison run covers.

    Attributes:
        problems: problem names or files for the full-IK section, or loaded
            :class:`~optik.problems.Problem` objects (a robot given by its URDF or DH table).
        solvers: solver names for the full-IK section (``"auto"`` allowed).
        n: targets per robot.
        seed: seed of the targets (and of each solve's restarts).
        tol: IK tolerance: position (m) and orientation (rad).
        timeout_s: time budget of one IK call, s; failures count at this time in the
            shifted geometric mean.
        mode: ``"pose"`` or ``"position"``.
        caps: per-solver cap on the number of targets per robot (slow solvers).
        closed_form_problems: problems of the closed-form section (default ``problems``).
        closed_form_configs: configurations per robot in the closed-form section.
        step_backends: step-program backends (``qp:<name>``, ``casadi:<plugin>``) of the
            closed-form section; ``None`` means every one installed (:func:`step_backends`).
        seeds: run the seed 001 and seed 003 sections.
        peers: peer libraries (:mod:`optik.peers` names) run in the full-IK section beside
            the solvers, as rows of solver ``peer:<name>``; one not installed, or unable to
            model a robot, is reported with the reason.
    """

    problems: tuple[str | Problem, ...]
    solvers: tuple[str, ...]
    n: int = 20
    seed: int = 0
    tol: float = 1e-6
    timeout_s: float = 1.0
    mode: str = "pose"
    caps: Mapping[str, int] = field(default_factory=dict)
    closed_form_problems: tuple[str | Problem, ...] | None = None
    closed_form_configs: int = 3
    step_backends: tuple[str, ...] | None = None
    seeds: bool = True
    peers: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        # A name given twice runs once: its rows share their keys, and a figure would draw
        # it twice.
        object.__setattr__(self, "solvers", tuple(dict.fromkeys(self.solvers)))
        object.__setattr__(self, "peers", tuple(dict.fromkeys(self.peers)))
        count = {"minimum": 0, "maximum": MAX_TARGETS}
        object.__setattr__(self, "n", check_int("n", self.n, **count))
        configs = check_int("closed_form_configs", self.closed_form_configs, **count)
        object.__setattr__(self, "closed_form_configs", configs)
        object.__setattr__(self, "seed", check_int("seed", self.seed, minimum=0, maximum=MAX_SEED))
        object.__setattr__(self, "tol", check_real("tol", self.tol, positive=True))
        timeout = check_real("timeout_s", self.timeout_s, positive=True, maximum=MAX_TIMEOUT_S)
        object.__setattr__(self, "timeout_s", timeout)
        object.__setattr__(self, "seeds", check_bool("seeds", self.seeds))
        if not isinstance(self.caps, Mapping):
            raise OptikError(f"caps must be a mapping of solver names to counts, got {self.caps!r}")
        for name, cap in self.caps.items():
            check_int(f"caps[{name!r}]", cap, **count)
        if self.step_backends is not None:
            unknown_steps = [b for b in self.step_backends if b not in step_backends()]
            if unknown_steps:
                raise OptikError(
                    f"unknown or unavailable step backend(s) {unknown_steps}; available: "
                    f"{list(step_backends())}"
                )
        if self.mode not in ("pose", "position"):
            raise OptikError(f"mode must be 'pose' or 'position', got {self.mode!r}")
        known = {"auto", *available_solvers()}
        unknown = [s for s in self.solvers if s not in known]
        if unknown:
            raise OptikError(
                f"unknown or unavailable solver(s) {unknown}; available: {sorted(known)}"
            )
        for name in self.peers:
            if name not in peer_names():
                raise UnknownPeerError(name, list(peer_names()))

    def targets_for(self, solver: str) -> int:
        """Number of targets per robot that ``solver`` runs (``n``, or its cap).

        Args:
            solver: the solver's name.
        """
        return min(self.n, self.caps.get(solver, self.n))

    def to_dict(self) -> dict[str, Any]:
        """The configuration as plain JSON-able data (recorded in ``summary.json``)."""
        data = asdict(replace(self, problems=(), closed_form_problems=None))
        data["caps"] = dict(self.caps)
        # A loaded problem is recorded by its file (or name): a Robot is not JSON.
        data["problems"] = [_problem_label(p) for p in self.problems]
        if self.closed_form_problems is not None:
            data["closed_form_problems"] = [_problem_label(p) for p in self.closed_form_problems]
        return data


def _problem_label(problem: str | Problem) -> str:
    if isinstance(problem, str):
        return problem
    return str(problem.path) if problem.path is not None else problem.name


def ik_settings(config: RunConfig, solver: str) -> str:
    """The settings JSON of an ``ik`` row: mode, tol, timeout, seed and warm start.

    ``auto`` keeps :func:`optik.solve_ik`'s analytic warm start (its answer is the closed
    form when the robot has one); every named solver runs with ``warm_start="q0"`` and no
    ``q0``, so it is measured from the same starts as the others (the seed table's nearest
    entries, then seeded uniform draws; see :mod:`optik.ik`).
    """
    return settings_json(
        {
            "mode": config.mode,
            "seed": config.seed,
            "timeout_s": config.timeout_s,
            "tol": config.tol,
            "warm_start": "analytic" if solver == "auto" else "q0",
        }
    )


@dataclass
class RunStats:
    """What :func:`run` did.

    Attributes:
        written: rows produced and appended by this call.
        skipped: rows already in the file (``resume``).
        rows: every row of the file after the run, old and new.
        step_backends: the closed-form section's backends (empty: none installed).
        trajectory: seed 003's joint trajectory (K, 2), rad, for the plot.
        planned: the keys of every row this configuration asks for (the report summarises
            only these; a resumed file may hold rows of other settings).
        peers: one status per (peer, problem) of :attr:`RunConfig.peers`: ran, or why not.
        answers: the joint vector (dof,) of every peer row this call produced with an
            answer, by row key (for re-verification; rows resumed from the file have none).
    """

    written: int = 0
    skipped: int = 0
    rows: list[ResultRow] = field(default_factory=list)
    step_backends: tuple[str, ...] = ()
    trajectory: FloatArray | None = None
    planned: set[Key] = field(default_factory=set)
    peers: list[PeerStatus] = field(default_factory=list)
    answers: dict[Key, FloatArray] = field(default_factory=dict)
