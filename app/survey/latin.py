"""Counterbalanced condition orders: the balanced Latin square (Williams 1949).

For n conditions the first row is 0, 1, n-1, 2, n-2, ... and row i adds i (mod n). With n even,
these n rows put every condition in every position once and let every condition follow every
other exactly once (first-order carry-over balanced). With n odd one square cannot do that, so
the square's rows are followed by the same rows reversed: 2n rows, each condition twice in each
position and each ordered pair of neighbours exactly twice.
"""

from __future__ import annotations


def balanced_latin_square(n: int) -> list[list[int]]:
    """The rows (orders of condition indices) of a balanced Latin square for ``n`` conditions."""
    if n < 1:
        raise ValueError("a Latin square needs at least one condition")
    first = [0]
    lo, hi = 1, n - 1
    for k in range(1, n):
        if k % 2:
            first.append(lo)
            lo += 1
        else:
            first.append(hi)
            hi -= 1
    rows = [[(c + i) % n for c in first] for i in range(n)]
    if n % 2 and n > 1:
        rows += [list(reversed(r)) for r in rows]
    return rows


def order_for(participant_index: int, n: int) -> list[int]:
    """The order of the ``participant_index``-th participant (from 0): rows taken in turn, so
    every full multiple of the square's length is exactly balanced."""
    rows = balanced_latin_square(n)
    return rows[participant_index % len(rows)]
