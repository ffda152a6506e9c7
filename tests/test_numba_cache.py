"""The parallel kernels and numba's on-disk cache, across processes.

numba restores a cached parallel function's thread pool through the function's own
``reload_init``; a cached *serial* function that calls a parallel one compiled in
another process is stored without it, and a third process that loads it first crashes
(docs/maintainers.md, "Parallel kernels and numba's cache"). So the suite's parallel
kernels (:func:`methods.imaging.raster._render_kernel`, the image state's full render)
are called from Python only, never from another jitted function. These tests run the
whole life of a cache in fresh processes sharing one ``NUMBA_CACHE_DIR``: the first
compiles and writes it, the next ones load it, with one and with two threads, and every
process must give the same images, bit for bit.
"""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parent.parent

#: Renders a textured torus's 20 dodecahedron views, luminance and face ids, with the
#: method's rasterizer, and prints a digest of both and whether the kernel came from the
#: cache.
CODE = """
import hashlib, numba
import bench
from bench.catalog.torus import make_torus
from methods.imaging import raster
from metrics.views import silhouette_cameras
mesh = make_torus(24, 16, texture_size=32)
cams = silhouette_cameras(mesh)
lum = raster.rasterize_luminance(mesh, cams, 64, 64, shading="gouraud", specular=True)
ids = raster.face_id_buffers(mesh, cams, 64, 64)
hits = sum(raster._render_kernel.stats.cache_hits.values())
print(hashlib.sha256(lum.tobytes() + ids.tobytes()).hexdigest(), hits, numba.get_num_threads())
"""


def _run(cache: Path, threads: int) -> tuple[str, int, int]:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache), "NUMBA_NUM_THREADS": str(threads)}
    out = subprocess.run([sys.executable, "-c", CODE], cwd=ROOT, env=env, capture_output=True, check=False,
                         text=True, timeout=900)
    assert out.returncode == 0, f"exit {out.returncode}: {out.stderr[-2000:]}"
    digest, hits, used = out.stdout.split()[-3:]
    return digest, int(hits), int(used)


def test_a_second_process_loads_the_first_ones_parallel_kernels(tmp_path):
    first = _run(tmp_path, threads=2)
    second = _run(tmp_path, threads=2)
    single = _run(tmp_path, threads=1)
    assert first[1] == 0, "the first process found a cache in an empty folder"
    assert second[1] > 0 and single[1] > 0, "the later processes compiled again"
    assert (first[2], second[2], single[2]) == (2, 2, 1)
    assert first[0] == second[0] == single[0]
    assert any(p.suffix == ".nbc" for p in tmp_path.rglob("*")), "nothing was cached"


def test_the_digest_sees_a_different_picture(tmp_path):
    """The digest is of the images, not a constant: another mesh gives another one."""
    code = CODE.replace("make_torus(24, 16", "make_torus(24, 15")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    runs = [subprocess.run([sys.executable, "-c", c], cwd=ROOT, env=env, capture_output=True, check=False,
                           text=True, timeout=900) for c in (CODE, code)]
    assert all(r.returncode == 0 for r in runs), runs[0].stderr[-2000:] + runs[1].stderr[-2000:]
    digests = [r.stdout.split()[-3] for r in runs]
    assert digests[0] != digests[1]
    assert hashlib.sha256(b"").hexdigest() not in digests
