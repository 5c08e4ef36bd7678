"""Seed 001's comparison: pseudoinverse vs Jacobian transpose on the DOBOT's path.

From the home configuration (rear arm vertical, forearm horizontal) through the three
targets of the chapter's Table 2, each part starting where the previous one ended,
position only, accepted error 0.2 mm (the arm's repeatability).

Run: ``python examples/03_dobot_pinv_vs_transpose.py``.
"""

from __future__ import annotations

from optik.compare import CHAPTER_TABLE_2, dobot_chapter_rows


def main() -> dict[str, dict[str, int]]:
    """Iterations per method and part, printed beside the chapter's numbers."""
    # The same computation as the report's seed 001 section (the chapter's two methods).
    counts: dict[str, dict[str, int]] = {}
    for row in dobot_chapter_rows(solvers=("pinv", "transpose")):
        if not row.backend_converged:
            raise RuntimeError(f"{row.solver} did not converge on {row.target}")
        counts.setdefault(row.target, {})[row.solver] = int(row.iterations or 0)
    print(f"{'part':<8}{'pinv':>6}{'transpose':>11}   chapter (pinv / transpose)")
    for part, (pinv, transpose) in CHAPTER_TABLE_2.items():
        ours = counts[part]
        print(f"{part:<8}{ours['pinv']:>6}{ours['transpose']:>11}   {pinv} / {transpose}")
    holds = all(c["pinv"] <= c["transpose"] for c in counts.values())
    print(f"the chapter's finding (pinv needs fewer iterations) holds: {holds}")
    return counts


if __name__ == "__main__":
    main()
