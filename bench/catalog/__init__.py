"""The model catalog: built-in test meshes, and any mesh file given by path.

Built-ins are registered under the ``bench.models`` entry-point group like any
plug-in model, each as a :class:`ModelSpec`. :func:`resolve_model` turns a command-line
word into a :class:`~bench.core.mesh.Mesh`: a registered name, or else a path to a file.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

from bench.core.errors import InputError, UnknownNameError
from bench.core.mesh import Mesh
from bench.core.registry import suggest

__all__ = [
    "BARREL",
    "BUNNY",
    "BUNNY_TEXTURED",
    "BUNNY_TEXTURED_815",
    "BUNNY_TEXTURED_4698",
    "CRATE",
    "INTERIOR",
    "TORUS",
    "TORUS_13810",
    "TORUS_PUZZLE",
    "TWO_MATERIALS",
    "KIT",
    "UV_SPHERE",
    "VEHICLE",
    "ModelSpec",
    "parse_model_spec",
    "pymeshlab_sample",
    "resolve_model",
]


@dataclass(frozen=True)
class ModelSpec:
    """A named model: how to obtain it and where it comes from."""

    name: str
    description: str
    source: str
    loader: Callable[[], Mesh]
    requires: dict = field(default_factory=dict)
    #: For a model made from another one (simplified or subdivided): the faces it is
    #: made with. Such a model costs work to load, so listings show it without building
    #: it.
    derived_faces: int | None = None
    #: How such a model is made from another ("simplification", "subdivision").
    derived_by: str = "simplification"

    def load(self) -> Mesh:
        mesh = self.loader()
        return mesh.replace(name=self.name, metadata={**mesh.metadata, "model": self.name})


def pymeshlab_sample(filename: str) -> Path:
    """Path of a mesh shipped in pymeshlab's ``tests/sample_meshes`` folder (found
    without importing pymeshlab, which takes a while)."""
    import importlib.util

    spec = importlib.util.find_spec("pymeshlab")
    if spec is None or spec.origin is None:
        raise InputError("pymeshlab is not installed; its sample meshes (bunny, ...) come "
                         "with it: pip install 'pymeshlab>=2023.12'")
    path = Path(spec.origin).parent / "tests" / "sample_meshes" / filename
    if not path.exists():
        raise InputError(f"{path}: pymeshlab's sample mesh is missing; reinstall with "
                         "pip install --force-reinstall pymeshlab")
    return path


def _load_sample(filename: str) -> Callable[[], Mesh]:
    def load() -> Mesh:
        from bench.io.meshio import load_mesh

        return load_mesh(pymeshlab_sample(filename))
    return load


def _torus() -> Mesh:
    from bench.catalog.torus import make_torus

    return make_torus()


def _interior() -> Mesh:
    from bench.catalog.interior import make_interior

    return make_interior()


def _torus_puzzle() -> Mesh:
    from bench.catalog.puzzle import make_torus_puzzle

    return make_torus_puzzle()


BUNNY = ModelSpec(
    "bunny", "Stanford bunny, flat-shaded comparisons of Lindstrom & Turk 2000",
    "pymeshlab tests/sample_meshes/bunny.obj", _load_sample("bunny.obj"),
    requires={"pymeshlab": "pymeshlab>=2023.12"})
BUNNY_TEXTURED = ModelSpec(
    "bunny-textured", "10k-face bunny with a texture atlas and real UV seams",
    "pymeshlab tests/sample_meshes/bunny10k_textured.obj + TextureDouble_A.png",
    _load_sample("bunny10k_textured.obj"), requires={"pymeshlab": "pymeshlab>=2023.12"})
TORUS = ModelSpec(
    "torus", "swept spinning-ellipse torus with a non-linear texture map (L&T 2000 §5.4)",
    "procedural (bench.catalog.torus, seed 2000)", _torus)
INTERIOR = ModelSpec(
    "interior", "spherical shell with four round openings around a densely tessellated "
    "bumpy object; faces classified exterior/interior (L&T 2000 §5.2)",
    "procedural (bench.catalog.interior)", _interior)
TORUS_PUZZLE = ModelSpec(
    "torus-puzzle", "the swept torus at 57,660 faces with a jigsaw puzzle texture, lit "
    "(Williams et al. 2003, Plate 1)", "procedural (bench.catalog.puzzle, seed 2003)",
    _torus_puzzle)


def _crate() -> Mesh:
    from bench.catalog.gamemodels import make_crate

    return make_crate()


def _barrel() -> Mesh:
    from bench.catalog.gamemodels import make_barrel

    return make_barrel()


def _two_materials() -> Mesh:
    from bench.catalog.materials import make_two_materials

    return make_two_materials()


def _predecimated(base: ModelSpec, faces: int) -> Callable[[], Mesh]:
    """``base`` simplified to ``faces`` by our Garland-Heckbert 1998 engine (texture
    quadrics, seams kept closed, every UV chart kept): a stand-in for the sizes of
    González et al. 2008's Table 1, whose models are not public."""
    def load() -> Mesh:
        from methods.engine.policy import Policy
        from methods.engine.simplify import simplify_mesh

        return simplify_mesh(base.load(), faces, Policy(texture_weight=1.0)).mesh
    return load


CRATE = ModelSpec(
    "crate", "subdivided box (12 x 12 quads a side) with per-face UVs: duplicated "
    "vertices along every box edge, three at each corner (González et al. 2008)",
    "procedural (bench.catalog.gamemodels, seed 2008)", _crate)
BARREL = ModelSpec(
    "barrel", "two materials in one atlas: a stave body and two metal lids whose rims "
    "share positions, not vertices, with the body (sub-meshes meeting along a seam)",
    "procedural (bench.catalog.gamemodels, seed 2008)", _barrel)
TWO_MATERIALS = ModelSpec(
    "two-materials", "a sphere whose halves are two materials with their own textures "
    "(bricks north, waves south), packed into one atlas as the loaders pack a "
    "multi-material OBJ or glTF; metadata['atlas'] lists the materials",
    "procedural (bench.catalog.materials)", _two_materials)
BUNNY_TEXTURED_815 = ModelSpec(
    "bunny-textured-815", "bunny-textured pre-decimated to 815 faces (Table 1 of "
    "González et al. 2008: 815 -> 100)", "bunny-textured, quadric engine (texture "
    "quadrics)", _predecimated(BUNNY_TEXTURED, 815), requires={"pymeshlab": "pymeshlab>=2023.12"},
    derived_faces=815)
BUNNY_TEXTURED_4698 = ModelSpec(
    "bunny-textured-4698", "bunny-textured pre-decimated to 4,698 faces (Table 1 of "
    "González et al. 2008: 4,698 -> 500)", "bunny-textured, quadric engine (texture "
    "quadrics)", _predecimated(BUNNY_TEXTURED, 4698),
    requires={"pymeshlab": "pymeshlab>=2023.12"}, derived_faces=4698)
TORUS_13810 = ModelSpec(
    "torus-13810", "the textured torus pre-decimated to 13,810 faces (Table 1 of "
    "González et al. 2008: 13,810 -> 1,000)", "torus, quadric engine (texture quadrics)",
    _predecimated(TORUS, 13810), derived_faces=13810)


def _wild(make: str) -> Callable[[], Mesh]:
    def load() -> Mesh:
        from bench.catalog import wild

        return getattr(wild, make)()
    return load


UV_SPHERE = ModelSpec(
    "uv-sphere", "a UV sphere of 200 segments and 60 rings: each pole one position with "
    "200 render vertices, a wrap-around seam (the wild suite)",
    "procedural (bench.catalog.wild)", _wild("make_uv_sphere"))
KIT = ModelSpec(
    "kit", "a kit of 17 small props in six flat-colour materials: boxes, barrels, bolts, a "
    "box standing on another unwelded, sign plates on non-manifold edges (the wild suite)",
    "procedural (bench.catalog.wild, seed 43)", _wild("make_kit"))
VEHICLE = ModelSpec(
    "vehicle", "a vehicle-like assembly: a textured body and cabin, four separate wheels, "
    "hubcaps and axles in three materials (the wild suite)",
    "procedural (bench.catalog.wild)", _wild("make_vehicle"))


def _subdivided(base: ModelSpec, times: int) -> Callable[[], Mesh]:
    """``base`` with every triangle cut into four at its edges' midpoints, ``times``
    times (4^times as many faces, the same surface): the inputs of the engine's
    scaling benchmark (``scripts/speed_targets.py``)."""
    def load() -> Mesh:
        from bench.catalog.scale import subdivide

        mesh = base.load()
        for _ in range(times):
            mesh = subdivide(mesh)
        return mesh
    return load


BUNNY_X4 = ModelSpec(
    "bunny-x4", "the bunny subdivided once at its edges' midpoints: 224,688 faces, the "
    "same surface (scaling benchmark)", "bunny, midpoint subdivision",
    _subdivided(BUNNY, 1), requires={"pymeshlab": "pymeshlab>=2023.12"},
    derived_faces=224688, derived_by="subdivision")
BUNNY_X16 = ModelSpec(
    "bunny-x16", "the bunny subdivided twice at its edges' midpoints: 898,752 faces "
    "(scaling benchmark)", "bunny, midpoint subdivision",
    _subdivided(BUNNY, 2), requires={"pymeshlab": "pymeshlab>=2023.12"},
    derived_faces=898752, derived_by="subdivision")
BUNNY_X64 = ModelSpec(
    "bunny-x64", "the bunny subdivided three times at its edges' midpoints: 3,595,008 "
    "faces (scaling benchmark)", "bunny, midpoint subdivision",
    _subdivided(BUNNY, 3), requires={"pymeshlab": "pymeshlab>=2023.12"},
    derived_faces=3595008, derived_by="subdivision")


def _looks_like_path(word: str) -> bool:
    return os.sep in word or "/" in word or Path(word).suffix != "" or Path(word).exists()


@lru_cache(maxsize=8)
def _load_registered(name: str) -> Mesh:
    from bench.core.registry import registry

    return registry("model").load(name).load()


#: What a model spec's options are written like (docs/models.md).
SPEC_SYNTAX = "MODEL::texture=IMAGE"


def parse_model_spec(word: str) -> tuple[str, dict]:
    """``"spot.obj::texture=spot.png"`` -> ``("spot.obj", {"texture": "spot.png"})``: a
    model (a name or a file) and its options, each ``::key=value`` after it. The one
    option is ``texture``, an image to use as the model's texture. InputError, in one
    line, for a malformed spec or an unknown option."""
    base, *items = word.split("::")
    options = {}
    for item in items:
        key, sep, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not base.strip() or not sep or not key or not value:
            raise InputError(f"model {word!r}: options are written {SPEC_SYNTAX}, e.g. "
                             "spot.obj::texture=spot_texture.png")
        if key != "texture":
            raise InputError(f"model {word!r}: unknown option '{key}'; the one option is "
                             f"texture ({SPEC_SYNTAX})")
        if key in options:
            raise InputError(f"model {word!r}: {key} given twice")
        options[key] = value
    return base, options


def resolve_model(word: str) -> Mesh:
    """A registered model's mesh, or the mesh in the file ``word``.

    Registered names win over files of the same name in the working directory only
    when the word has no extension or path separator. Options follow the model as
    ``::key=value`` (:func:`parse_model_spec`): ``spot.obj::texture=spot.png`` gives
    ``spot.obj`` the texture ``spot.png``.
    """
    from bench.core.registry import registry
    from bench.io.meshio import apply_texture, load_mesh

    if "::" in word:
        base, options = parse_model_spec(word)
        if base in registry("model"):
            return apply_texture(_load_registered(base), options["texture"])
        if _looks_like_path(base):
            return load_mesh(base, texture_file=options["texture"])
        word = base  # an unknown name: said below
    models = registry("model")
    if word in models:
        return _load_registered(word)
    if _looks_like_path(word):
        return load_mesh(word)
    hint = suggest(word, models.names())
    raise UnknownNameError(f"unknown model '{word}'{hint} (not a file either; "
                           "`bench list models` shows the built-in names)")
