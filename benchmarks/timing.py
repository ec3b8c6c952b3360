"""How the benchmark scripts time a call: one warm-up, then wall and process CPU time per repeat.

CPU time (``time.process_time``) is the figure to trust on a shared machine,
where other jobs stretch the wall clock.
"""
import time
from typing import Callable, List, Tuple


def wall_and_cpu_ms(fn: Callable[[], object], repeats: int) -> Tuple[List[float], List[float]]:
    """Wall and CPU milliseconds of each of ``repeats`` calls of ``fn()`` after one warm-up call
    (numba compiles, caches fill)."""
    fn()
    wall, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        cpu.append((time.process_time() - c) * 1e3)
        wall.append((time.perf_counter() - t) * 1e3)
    return wall, cpu
