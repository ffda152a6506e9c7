"""Method time of one job in two checkouts, alternating fresh processes:

    .venv/bin/python scripts/compare_speed.py DIR_A DIR_B ROUNDS [FACES] [METHOD]
                                              [--model NAME] [--threads N]

Each round runs, in a fresh process per checkout (its code first on the import path,
numba's caches warm from a first run), METHOD (default image-driven) once on a
200-face icosphere as a warm-up and then on the model (``--model``, any name or path
``bench run`` takes; default the bunny) to FACES faces (default 1,332) on N threads
(``--threads``; default numba's, all cores), and prints the method's
``wall_seconds`` and ``cpu_seconds`` (all threads; on a shared machine the
processor time varies far less than the wall time); at the end the medians and B/A of
both. A and B take turns, so drift of a shared machine hits both alike. Run nothing else
meanwhile. González et al. 2008's Table 1 rows, for instance::

    scripts/compare_speed.py A B 3 100 entropy-twin --model bunny-textured-815
"""

import statistics
import subprocess
import sys
from pathlib import Path

CLASSES = {"image-driven": ("methods.image_driven", "ImageDriven"),
           "memoryless": ("methods.memoryless", "Memoryless"),
           "entropy-twin": ("methods.entropy_twin", "EntropyTwin"),
           "quadric": ("methods.quadric", "Quadric")}

CODE = """
import sys
sys.path.insert(0, sys.argv[1])
sys.path.insert(1, sys.argv[2])
import bench
from bench.core.method import run_method
from bench.catalog import resolve_model
from conftest import icosphere
from {module} import {cls}
run_method({cls}(), icosphere(3), 200)
stats = run_method({cls}(), resolve_model({model!r}), {faces}).stats
print(stats["wall_seconds"], stats["cpu_seconds"])
"""


USAGE = ("usage: compare_speed.py DIR_A DIR_B ROUNDS [FACES] [METHOD] [--model NAME] "
         "[--threads N]")


def _option(args: list, name: str, default):
    """The value after ``name`` in ``args`` (both removed), else ``default``."""
    if name not in args:
        return default
    i = args.index(name)
    if i + 1 == len(args):
        sys.exit(f"compare_speed: {name} needs a value ({USAGE})")
    value = args[i + 1]
    del args[i:i + 2]
    return value


def _count(text: str, what: str) -> int:
    """``text`` as a whole number of at least 1, else a one-line error naming ``what``."""
    if not text.isdigit() or int(text) < 1:
        sys.exit(f"compare_speed: {what} must be a whole number of at least 1, got {text!r}")
    return int(text)


def main() -> None:
    args = sys.argv[1:]
    model = _option(args, "--model", "bunny")
    env = {"PATH": "/usr/bin:/bin", "HOME": str(Path.home())}
    threads = _option(args, "--threads", None)
    if threads is not None:
        env["NUMBA_NUM_THREADS"] = str(_count(threads, "--threads"))
    if not 3 <= len(args) <= 5:
        sys.exit(USAGE)
    a, b, rounds = args[0], args[1], _count(args[2], "ROUNDS")
    faces = _count(args[3], "FACES") if len(args) > 3 else 1332
    method = args[4] if len(args) > 4 else "image-driven"
    if method not in CLASSES:
        sys.exit(f"compare_speed: METHOD must be one of {', '.join(CLASSES)}, got {method!r}")
    module, cls = CLASSES[method]
    for tree in (a, b):
        if not (Path(tree) / "methods").is_dir():
            sys.exit(f"compare_speed: {tree} is not a checkout of this project (no methods/)")
    code = CODE.format(module=module, cls=cls, faces=faces, model=model)
    tests = str(Path(__file__).resolve().parent.parent / "tests")
    times, cpus = {a: [], b: []}, {a: [], b: []}
    for _ in range(rounds):
        for tree in (a, b):
            out = subprocess.run([sys.executable, "-c", code, tree, tests], cwd=tree,
                                 capture_output=True, text=True, check=False,
                                 env={**env, "PYTHONPATH": tree})
            if out.returncode:
                sys.exit(out.stderr[-2000:])
            wall, cpu = out.stdout.split()[-2:]
            times[tree].append(float(wall))
            cpus[tree].append(float(cpu))
            print(f"{tree}: {times[tree][-1]:.3f} s (cpu {cpus[tree][-1]:.3f} s)", flush=True)
    ma, mb = statistics.median(times[a]), statistics.median(times[b])
    print(f"median A {ma:.3f} s, B {mb:.3f} s, B/A {mb / ma:.3f}")
    ca, cb = statistics.median(cpus[a]), statistics.median(cpus[b])
    print(f"cpu median A {ca:.3f} s, B {cb:.3f} s, B/A {cb / ca:.3f}")


if __name__ == "__main__":
    main()
