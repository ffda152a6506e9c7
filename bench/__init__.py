"""A benchmark suite for appearance-preserving mesh simplification."""

import os as _os
import platform as _platform


def _fixed_blas_kernel() -> None:
    """Make OpenBLAS use one kernel on every x86-64 machine with AVX2 and FMA.

    OpenBLAS chooses its kernels by the CPU it finds, and its AVX-512 kernels round
    some products differently from its AVX2 ones; perceptual-mt's cut decisions turn
    that last-bit difference into a different mesh (on the torus at 655 faces, d_rms
    19.6951 with the AVX-512 kernels, 19.6896 with the AVX2 ones). Set before numpy loads
    OpenBLAS, and inherited by every job process, so the suite's numbers do not depend
    on which of these machines ran it. An explicit ``OPENBLAS_CORETYPE`` is kept.
    """
    if "OPENBLAS_CORETYPE" in _os.environ or _platform.machine() not in ("x86_64", "AMD64"):
        return
    try:
        with open("/proc/cpuinfo") as f:
            flags = next((line for line in f if line.startswith("flags")), "").split()
    except OSError:
        return
    if "avx2" in flags and "fma" in flags:
        _os.environ["OPENBLAS_CORETYPE"] = "Haswell"


_fixed_blas_kernel()

from bench.core.mesh import Mesh  # after the BLAS kernel is fixed

__version__ = "0.1.0"
__all__ = ["Mesh", "__version__"]
