"""Where a benchmark's figures were taken: CPU model, its widest SIMD level, every BLAS loaded and its kernel.

A ratio measured on one machine is not a ratio on another: the eq 28 study measured 1.89× its
numba twin on one CPU and 4.2× on a CPU without AVX-512. Every ``benchmarks/bench_*.py`` prints
``machine_line()`` first, so a quoted figure always carries where it came from
(``tests/project/test_benchmarks.py`` checks that each prints it).

>>> line = machine_line()
>>> line.startswith("machine: CPU ") and "; SIMD " in line and "; BLAS " in line
True
>>> _owner("/x/site-packages/scipy.libs/libscipy_openblas-6cdc3b4a.so")
'scipy'

"""

from __future__ import annotations

import os
import platform

#: the SIMD levels named, widest first, as /proc/cpuinfo's flags spell them
_SIMD = (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("avx", "AVX"), ("sse4_2", "SSE4.2"), ("asimd", "NEON (ASIMD)"))


def _cpuinfo() -> dict:
    try:
        text = open("/proc/cpuinfo", encoding="utf-8").read()
    except OSError:
        return {}
    info: dict = {}
    for line in text.splitlines():
        key, _, value = line.partition(":")
        key = key.strip()
        if key in ("model name", "flags", "Features") and key not in info:
            info[key] = value.strip()
    return info


def cpu_model() -> str:
    return _cpuinfo().get("model name") or platform.processor() or platform.machine() or "unknown"


def simd_level() -> str:
    """The widest SIMD instruction set the CPU reports (Linux: /proc/cpuinfo), or "unknown"."""
    info = _cpuinfo()
    flags = set((info.get("flags") or info.get("Features") or "").split())
    return next((name for flag, name in _SIMD if flag in flags), "unknown")


def _owner(filepath: str) -> str:
    """Which package brought a loaded library: the wheel's ``<package>.libs`` folder that holds it
    (numpy and scipy each ship their own OpenBLAS), else the library's file name."""
    parts = filepath.replace("\\", "/").split("/")
    return next((p[: -len(".libs")] for p in parts if p.endswith(".libs")), parts[-1] or "?")


def blas() -> str:
    """Every BLAS loaded once numpy and scipy.linalg are imported (threadpoolctl), each as its
    package, library, version, the kernel it chose for this CPU and its threads — numpy's and
    scipy's wheels each carry an OpenBLAS, and both run in a study (numpy's matmul/einsum,
    scipy.linalg's factorisations), often different versions."""
    import numpy  # noqa: F401 - loads the BLAS threadpoolctl inspects

    try:
        import scipy.linalg  # noqa: F401 - loads scipy's own BLAS, which the studies' factorisations use
    except ImportError:
        pass
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return "unknown (threadpoolctl not installed)"
    libs = [i for i in threadpool_info() if i.get("user_api") == "blas"]
    if not libs:
        return "unknown"
    return "; ".join(
        f"{_owner(str(b.get('filepath', '')))}'s {b.get('internal_api')} {b.get('version')} kernel "
        f"{b.get('architecture') or '?'} ({b.get('num_threads')} threads)"
        for b in sorted(libs, key=lambda b: _owner(str(b.get("filepath", ""))))
    )


def machine_line() -> str:
    """One line: CPU model, logical CPUs, SIMD level, every loaded BLAS and its kernel, numpy version."""
    import numpy as np

    return (
        f"machine: CPU {cpu_model()} ({os.cpu_count()} logical); SIMD {simd_level()}; BLAS {blas()}; "
        f"numpy {np.__version__}, Python {platform.python_version()}"
    )


if __name__ == "__main__":
    print(machine_line())
