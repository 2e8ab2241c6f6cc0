"""Shared timing helper for the bench scripts."""

import statistics
import time


def median_seconds(fn, repeats):
    """Median wall time of `repeats` calls of `fn`: the machine is shared, so medians, not means."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)
