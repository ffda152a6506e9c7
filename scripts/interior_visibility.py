"""Where the faces of the lt2000-interior results go: exterior or interior (the model's
own classification) crossed with seen or never seen by a protocol view
(metrics.visibility), for each method of the suite and for image-driven's
pre-simplification alone (memoryless to the faces image-driven starts its image phase
from). Usage: .venv/bin/python scripts/interior_visibility.py [FACES]"""

import sys

from scipy.spatial import cKDTree

import bench  # noqa: F401  (the BLAS kernel pin comes first)
from bench.catalog import resolve_model
from bench.core.method import run_method
from bench.core.registry import registry
from metrics.interior import exterior_faces, exterior_sphere
from metrics.visibility import seen_faces


def split(original, seen, result):
    centre, radius = exterior_sphere(original)
    exterior = exterior_faces(result, centre, radius)
    tree = cKDTree(original.positions[original.faces].mean(axis=1))
    _, nearest = tree.query(result.positions[result.faces].mean(axis=1))
    never = ~seen[nearest]
    n = result.n_faces
    return {"faces": n, "exterior seen": (exterior & ~never).sum() / n,
            "exterior never seen": (exterior & never).sum() / n,
            "interior seen": (~exterior & ~never).sum() / n,
            "interior never seen": (~exterior & never).sum() / n}


def main():
    faces = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
    original = resolve_model("interior")
    seen = seen_faces(original)
    methods = registry("method")
    rows = {"original": split(original, seen, original)}
    pre = run_method(methods.load("memoryless")(), original, 10 * faces)
    rows[f"memoryless to {10 * faces} (image-driven's pre-simplification)"] = \
        split(original, seen, pre.mesh)
    for label, name, params in (("image-driven", "image-driven", {}),
                                ("image-driven[geometry_weight=0]", "image-driven",
                                 {"geometry_weight": 0.0}),
                                ("memoryless", "memoryless", {}), ("qslim", "qslim", {})):
        cls = methods.load(name)
        method = cls(cls.Params(**params))
        rows[label] = split(original, seen, run_method(method, original, faces).mesh)
    cols = list(next(iter(rows.values())))
    print(f"{'':<62}" + "".join(f"{c:>22}" for c in cols))
    for label, row in rows.items():
        print(f"{label:<62}" + "".join(
            f"{row[c]:>22}" if c == "faces" else f"{row[c]:>22.1%}" for c in cols))


if __name__ == "__main__":
    main()
