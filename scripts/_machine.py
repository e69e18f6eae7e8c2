"""Machine description printed by every benchmark script (benchmarks quote it)."""

from __future__ import annotations

import os
import platform
from pathlib import Path


def machine() -> str:
    """CPU model, logical CPUs, memory, load, OS and the versions that matter for speed."""
    import numba
    import numpy as np
    import pyarrow

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        kb = int(next(ln for ln in Path("/proc/meminfo").read_text().splitlines()
                      if ln.startswith("MemTotal")).split()[1])
        mem = f", {kb / 1024 ** 2:.1f} GiB RAM"
    except (OSError, StopIteration):
        pass
    try:
        load = ", load " + " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        load = ""
    return (f"{cpu}, {os.cpu_count()} logical CPUs{mem}{load}; {platform.system()} "
            f"{platform.release()}; Python {platform.python_version()}, numpy {np.__version__}, "
            f"numba {numba.__version__}, pyarrow {pyarrow.__version__}")
