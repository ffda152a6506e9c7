"""A benchmark suite for appearance-preserving mesh simplification."""

from bench.mesh import Mesh

__version__ = "0.1.0"
__all__ = ["Mesh", "__version__"]
