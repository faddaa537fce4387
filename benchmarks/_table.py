"""Shared by the benchmark scripts: Markdown tables (they paste into the README) and timing."""

import math
import time


def best_of(fn, n: int) -> float:
    """Shortest of n timed calls, s (the least disturbed by other processes)."""
    best = math.inf
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def print_table(rows, headers=("benchmark", "time", "note")) -> None:
    """Print rows (tuples of strings) as a Markdown table, first column padded."""
    w = max(len(headers[0]), *(len(r[0]) for r in rows))
    print("| " + " | ".join([headers[0].ljust(w), *headers[1:]]) + " |")
    print(f"|{'-' * (w + 2)}|" + "---|" * (len(headers) - 1))
    for r in rows:
        print("| " + " | ".join([r[0].ljust(w), *r[1:]]) + " |")
