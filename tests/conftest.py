"""Shared fixtures and tiny hand-built meshes.

Every hand-built mesh here is small enough that its welded topology can be counted on
paper; the expected numbers in the tests are those hand counts, not values read back
from the code.
"""

from __future__ import annotations

import os
import textwrap
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# Property tests draw the same examples on every run and machine, so a run fails only
# on a change of the code; ``pytest --hypothesis-profile explore`` searches afresh
# (with ten times the examples) for cases to add.
settings.register_profile("fixed", derandomize=True, deadline=None)
settings.register_profile("explore", max_examples=1000, deadline=None)
settings.load_profile("fixed")

# Files are read afresh, not from the user's mesh cache (bench.io.cache), which the tests
# would fill with their temporary files; tests/test_mesh_cache.py turns it on.
os.environ["BENCH_MESH_CACHE"] = "0"

# -- hand-built meshes ------------------------------------------------------------------

#: Two triangles sharing the edge (0,0,0)-(1,1,0) seen from +z (counter-clockwise)::
#:
#:     0-----1 3        render vertex 3 is a copy of 1 and 4 a copy of 2: the right
#:     |    /  /|       triangle has its own UVs along the diagonal (a UV seam).
#:     |  /  /  |
#:     2 4-----5        left face (0,2,1), right face (3,4,5)
#:
#: positions: 0=(0,1) 1=(1,1) 2=(0,0) 3=(1,1) 4=(0,0) 5=(1,0), all at z=0.
SEAM_POSITIONS = np.array([[0, 1, 0], [1, 1, 0], [0, 0, 0],
                           [1, 1, 0], [0, 0, 0], [1, 0, 0]], dtype=np.float64)
SEAM_FACES = np.array([[0, 2, 1], [3, 4, 5]], dtype=np.int32)
SEAM_UV = np.array([[0.0, 1.0], [0.5, 1.0], [0.0, 0.0],
                    [0.6, 1.0], [0.6, 0.0], [1.0, 0.0]])

#: A closed tetrahedron, faces wound outward.
TET_POSITIONS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float64)
TET_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int32)


def icosphere(subdivisions: int = 2, name: str = "icosphere"):
    """trimesh's unit icosphere as a Mesh (20 * 4^subdivisions faces, closed)."""
    import trimesh

    from bench.core.mesh import Mesh

    ico = trimesh.creation.icosphere(subdivisions)
    return Mesh(np.asarray(ico.vertices), np.asarray(ico.faces).astype(np.int32), name=name)


def blob(subdivisions: int = 2, seed: int = 1):
    """An icosphere with its radius jittered by 8 % per vertex (seeded): closed, no
    duplicated vertices, and no two edges alike, so costs have no ties."""
    ico = icosphere(subdivisions)
    rng = np.random.default_rng(seed)
    positions = ico.positions * (1 + 0.08 * rng.standard_normal((ico.n_vertices, 1)))
    return ico.replace(positions=positions, name="blob")


def write(path: Path, text: str) -> Path:
    """Write dedented ``text`` to ``path`` and return the path."""
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return path


@pytest.fixture(scope="session")
def bunny_textured():
    """The 10k-face textured bunny (loaded once; do not mutate its arrays)."""
    from bench.catalog import BUNNY_TEXTURED

    return BUNNY_TEXTURED.load()


@pytest.fixture(scope="session")
def small_torus():
    """make_torus(64, 32): 4096 faces, closed, with UV seams and a texture."""
    from bench.catalog.torus import make_torus

    return make_torus(64, 32)


def made_up_record(label: str = "q", status: str = "ok", model: str = "m", **changes) -> dict:
    """A record as the runner writes it, numbers made up (an ok one without images; any
    other status with the error "it broke"); ``changes`` replace top-level fields."""
    from metrics.protocol import Protocol

    r = {"schema": 1, "status": status, "error": None if status == "ok" else "it broke",
         "job": {"model": model, "method": label.split("[")[0], "params": {}, "label": label,
                 "target_faces": 100, "protocol": Protocol().as_dict()},
         "model": {"name": model, "hash": "0" * 40, "faces": 1000},
         "method": {"name": label, "version": "1", "view_dependent": False},
         "metrics": {"faces": 100, "d_rms": 5.0, "ssim": 0.9, "hausdorff_mean": 0.01,
                     "silhouette_mean": 2.0, "boundary_edges": 0, "seam_cracks": 0},
         "per_view": {"d_rms": [5.0] * 24}, "silhouette_histogram": [1.0] + [0.0] * 20,
         "stats": {"wall_seconds": 1.0, "tri_per_s": 900.0, "peak_mb": 10.0},
         "artifacts": [], "environment": {}}
    r.update(changes)
    return r


def without_own_scripts(page: str) -> str:
    """A report ``page`` without the report's own scripts (the error catcher, the summary
    table's and the comparison grids' toggle), which it must hold exactly once each, and
    the 3D view's (at most once): what is left may hold no script at all."""
    from bench.report.page import ERRORS_SCRIPT, SCRIPT
    from bench.report.grid import GRID_SCRIPT
    from bench.report.viewer import VIEWER_SCRIPT

    for own in (ERRORS_SCRIPT, SCRIPT, GRID_SCRIPT):
        assert page.count(own) == 1
        page = page.replace(own, "")
    assert page.count(VIEWER_SCRIPT) <= 1
    return page.replace(VIEWER_SCRIPT, "")
