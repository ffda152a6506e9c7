"""Named experiment suites for ``bench run --suite NAME``.

A suite fixes models, method variants (a method name plus parameter overrides), face
budgets and the evaluation protocols, so an experiment is one reproducible command.
Every (model, variant, budget) is evaluated under each of the suite's protocols, one
job and one record per protocol.

The ``lt2000-*`` suites are the experiments of Lindstrom & Turk 2000, §5 (seed
000_70ceec953310b20c.txt), under our protocol:

- ``lt2000-bunny`` (§5.1, Table 1, Figures 5–7): the paper's five bunny sizes, 2,899 /
  1,333 / 654 / 304 / 143 faces of 69,451, scaled to our 56,172-face bunny (2,345 /
  1,078 / 529 / 246 / 116), plus 1,332 faces;
- ``lt2000-torus`` (§5.4, Plates 12–13): the textured torus at 512 faces;
- ``lt2000-interior`` (§5.2, Plates 2–3): the ``interior`` model at 2,000 faces, with
  no and with 10 of 20 interior views. 2,000 is below the shell's own 4,543 faces, so
  every face spent on the hidden object is taken from the visible shell, yet large
  enough that the shell and its four round openings stay recognisable. It is 4 % of the
  model, as Table 1's largest bunny (2,899 of 69,451), and keeps image-driven's work
  (pre-simplification to 20,000 faces, then 18,000 image-costed collapses) of the order
  of the bunny's at 1,332 faces. memoryless and qslim put 33-40 % of a 1,000-4,000 face
  budget on the hidden object;
- ``lt2000-shading`` (§5.3, Plates 4 and 8): the bunny at 1,332 faces optimised for flat
  and for Gouraud shading with specular highlights (as the paper's second dragon was
  guided), each evaluated under flat shading and under Gouraud shading with specular
  highlights, with qslim as the geometry-driven reference of the paper's closing remark
  in §5.3.

``w2003`` is the comparison of Williams et al. 2003, §6 (seed 002_4e0fded99a2f0055.txt):
perceptual-mt under its four error metrics, per-vertex lighting with specular
highlights (where the paper's gain is largest, Figure 4a and d), on the puzzle torus and
the bunny at 90 % and 98 % simplification. perceptual-mt is view-dependent: each view
is imaged with its own cut.

``g2007`` is González, Castelló & Chover 2007 (seed 003_a77a1165a4e02bd6.txt):
canny-texture against its base alone over the whole budget range, from the paper's own
50 % and 25 % (§4) to the 2-0.5 % where the version-4 penalty failed, on the torus and
``bunny-textured``; canny-texture also with that version-4 penalty (``canny_units=area``)
and with ``canny_weight=0`` (quadric's policy exactly, so that the base's crossing edges
are recorded too; its d_rms equals quadric's).

``g2008`` is González et al. 2008 (seed 004_7b79a0217de1c060.txt): entropy-twin on the
game-style ``crate`` (duplicated vertices on every box edge) and ``barrel`` (two
materials meeting along a seam) at 300 and 100 faces, where qslim on the same unwelded
input opens seams, on ``bunny-textured`` at 1,000 and 500 faces, and at the sizes of
the paper's Table 1 (815 -> 100, 4,698 -> 500, 13,810 -> 1,000 faces; its models are not
public, so ours are pre-decimated to those sizes: ``bunny-textured-815``,
``bunny-textured-4698``, ``torus-13810``); entropy-twin also without its UV correction,
to show what the correction does to d_rms.

``w2003-paper`` is the same comparison in the paper's own setting (§6, Figure 4): one
representative view per model (``metrics.views.REPRESENTATIVE_VIEW``) at 1,024², 50 %
gray background, as protocol options (``Protocol.views``, ``Protocol.resolution``).

The ``*-ablation`` suites take a claim that does not hold apart: ``lt2000-interior-
ablation`` varies image-driven's memoryless tie-breaker and pre-simplification on the
``interior`` model; ``g2008-ablation`` switches off, one at a time, the background in
entropy-twin's entropy, its Canny term and its pre-simplification, and tries full-edge
(optimal) placement instead of its half-edge collapse; ``w2003-ablation`` switches off,
one at a time, the parts of perceptual-mt's error the paper's gain should come from
(maximal silhouette contrast, §5.4's lighting bounds, the bounding sphere as feature
size), moves the CSF's peak sensitivity and the observer's pixels per degree, and
refines every view from scratch, at 98 % under both settings.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from pathlib import Path

from bench.records.claims import Claim

__all__ = ["Suite", "SUITES", "get_suite", "evaluation_protocols", "SHADINGS",
           "PROTOCOL_OPTIONS", "assets_folder"]


def assets_folder() -> Path:
    """Where suites find real assets the project does not ship: ``$BENCH_ASSETS``, else
    ``shared/assets`` beside the project's folder."""
    env = os.environ.get("BENCH_ASSETS")
    return Path(env) if env else Path(__file__).resolve().parents[3] / "shared" / "assets"

#: Evaluation shadings the protocol knows.
SHADINGS = ("flat", "gouraud")


@dataclass(frozen=True)
class Suite:
    """A named experiment: models × method variants × face budgets × protocols."""

    name: str
    description: str
    models: tuple[str, ...]
    #: (method, params) pairs; None = every available, view-independent method
    variants: tuple[tuple[str, dict], ...] | None = None
    ratios: tuple[float, ...] = ()
    #: model -> face budgets, taking precedence over ratios
    faces: dict = field(default_factory=dict)
    #: evaluation protocols as (shading, specular) pairs, or (shading, specular,
    #: options) where options sets other :class:`~metrics.protocol.Protocol` fields
    #: (:data:`PROTOCOL_OPTIONS`: ``resolution``, ``views``); every job runs under each
    protocols: tuple[tuple, ...] = (("flat", False),)
    #: the papers' claims this suite tests (:mod:`bench.records.claims`); each is scoped
    #: to the suite's models and budgets unless it narrows them itself, and to the
    #: suite's evaluation label (shading and image settings) when it has one protocol
    claims: tuple[Claim, ...] = ()
    #: real assets the project does not ship, as paths under :func:`assets_folder`
    #: (``::``-options allowed): run when present, left out with a note when not
    assets: tuple[str, ...] = ()

    def asset_specs(self) -> list[str]:
        """The model specs of :attr:`assets`: paths (and a ``::texture=`` option's
        image) under :func:`assets_folder`."""
        root = assets_folder()
        specs = []
        for asset in self.assets:
            path, *options = asset.split("::")
            specs.append("::".join([str(root / path)] + [
                f"texture={root / o[len('texture='):]}" if o.startswith("texture=") else o
                for o in options]))
        return specs

    def present_assets(self) -> tuple[list[str], list[str]]:
        """(the asset model specs whose files exist, the assets missing)."""
        present, missing = [], []
        for spec in self.asset_specs():
            (present if Path(spec.split("::")[0]).is_file() else missing).append(spec)
        return present, missing

    def __post_init__(self) -> None:
        if not self.protocols:
            raise ValueError(f"suite {self.name!r} needs at least one evaluation protocol")
        for entry in self.protocols:
            shading, specular, options = _protocol_entry(entry)
            if shading not in SHADINGS or not isinstance(specular, bool):
                raise ValueError(f"suite {self.name!r}: protocol ({shading!r}, {specular!r}) "
                                 f"is not (one of {'|'.join(SHADINGS)}, True|False)")
            unknown = sorted(set(options) - set(PROTOCOL_OPTIONS))
            if unknown:
                raise ValueError(f"suite {self.name!r}: protocol option {unknown[0]!r} is not "
                                 f"one of {', '.join(PROTOCOL_OPTIONS)}")
            _protocol(shading, specular, options)  # the Protocol checks the values
        if len({_protocol(*_protocol_entry(e)) for e in self.protocols}) != len(self.protocols):
            raise ValueError(f"suite {self.name!r} lists a protocol twice: {self.protocols}")
        budgets = tuple(sorted({f for fs in self.faces.values() for f in fs}, reverse=True))
        # a suite of one protocol scopes its claims to it, so that records of the same
        # jobs under other image settings (w2003 and w2003-paper) never decide them
        from bench.records.results import shading_label

        only = (shading_label(_protocol(*_protocol_entry(self.protocols[0])).as_dict())
                if len(self.protocols) == 1 else None)
        object.__setattr__(self, "claims", tuple(replace(
            c, suite=self.name,
            models=c.models or self.models + tuple(self.asset_specs()),
            faces=c.faces or (budgets if not c.ratios else ()),
            ratios=c.ratios or (self.ratios if not (c.faces or budgets) else ()),
            shading=c.shading or only)
            for c in self.claims))


#: Protocol fields a suite may set besides the shading (:class:`Suite` ``protocols``).
PROTOCOL_OPTIONS = ("resolution", "views", "screen_sizes")


def _protocol_entry(entry) -> tuple[str, bool, dict]:
    """(shading, specular, options) of a suite's protocol entry."""
    if not isinstance(entry, tuple) or len(entry) not in (2, 3):
        raise ValueError(f"a suite's protocol is (shading, specular) or (shading, specular, "
                         f"options), got {entry!r}")
    options = entry[2] if len(entry) == 3 else {}
    if not isinstance(options, dict):  # a bad suite is one kind of error: ValueError
        raise ValueError(f"a suite's protocol options must be a dict, got {options!r}")  # noqa: TRY004
    return entry[0], entry[1], options


def _protocol(shading: str, specular: bool, options: dict):
    from metrics.protocol import Protocol

    return Protocol(shading=shading, specular=specular, **options)


def _scaled(faces: tuple[int, ...], of: int, to: int) -> tuple[int, ...]:
    """Face counts of a model with ``of`` faces scaled to one with ``to`` faces."""
    return tuple(round(f * to / of) for f in faces)


#: The image settings of Williams et al. 2003 §6 (1,024² images, "a single representative
#: view" per model, Figure 4; the background is the protocol's 50 % gray already).
W2003_PAPER_SETTING = {"resolution": 1024, "views": "representative"}

#: Table 1 of Lindstrom & Turk 2000: the bunny's final sizes, of 69,451 faces.
LT2000_BUNNY_FACES = (2899, 1333, 654, 304, 143)
#: Our bunny's faces (pymeshlab's bunny.obj).
BUNNY_FACES = 56172
#: The g2007 suite's budgets: the paper's 50 % and 25 % (§4: 75, 50 and 25 % of the
#: edges kept) down to the 2 % and 1 % of the ci suite and below.
G2007_RATIOS = (0.5, 0.25, 0.1, 0.05, 0.02, 0.01, 0.005)

#: Williams et al. 2003 §6: the models and perceptual-mt's four error metrics compared.
W2003_MODELS = ("torus-puzzle", "bunny")
W2003_VARIANTS = tuple(("perceptual-mt", {"error": e})
                       for e in ("perceptual", "object", "screen", "screen-silhouette"))

#: The methods built on the suite's own collapse engine.
ENGINE_METHODS = ("quadric", "memoryless", "canny-texture", "image-driven", "perceptual-mt",
                  "entropy-twin")


def _wild_claims() -> tuple[Claim, ...]:
    """The wild suite's claims: each engine method reaches its target within 10 % on
    every model and budget, and loses no part and no material at 10 %; image-driven's
    image error is at most qslim-texture's on the textured models."""
    claims = []
    for method in ENGINE_METHODS:
        claims += [
            Claim(f"wild-{method}-target", "real assets (issue: targets reached)",
                  f"{method} ends within 10 % of its face target on every wild model",
                  "target_distance", method, below=0.1 + 1e-9),
            Claim(f"wild-{method}-parts", "real assets (issue: parts kept)",
                  f"{method} loses no connected component at 10 % of the faces",
                  "components_lost", method, below=0.5, ratios=(0.10,)),
            Claim(f"wild-{method}-materials", "real assets (issue: materials kept)",
                  f"{method} loses no material at 10 % of the faces",
                  "materials_lost", method, below=0.5, ratios=(0.10,)),
        ]
    claims.append(Claim(
        "wild-image-driven", "Lindstrom & Turk 2000, §5 (on real assets)",
        "image-driven has an image error no higher than qslim-texture on textured wild "
        "models", "d_rms", "image-driven", "qslim-texture", below=1.0 + 1e-9))
    return tuple(claims)


#: The faces of the models of the ``lod`` suite (tests/test_screen.py checks them), so
#: its halving budgets need no model loaded.
LOD_MODELS = {"bunny": 56172, "torus": 65536, "crate": 1728, "bunny-textured": 9999,
              "two-materials": 3968, "uv-sphere": 23600, "kit": 4688, "vehicle": 3616}
#: The screen-size protocol of the ``lod`` suites (metrics.screen).
LOD_PROTOCOL = (("flat", False, {"screen_sizes": (512, 256, 128, 64, 32)}),)


def _halving(faces: int) -> tuple[int, ...]:
    from metrics.screen import halving_faces

    return tuple(halving_faces(faces))


SUITES = {
    "lod": Suite(
        "lod", "switch sizes of halving chains (50 %, 25 %, ... to 100 faces or 1/256): "
        "every available method on bunny, torus, crate, bunny-textured, two-materials and "
        "the wild analogues uv-sphere, kit, vehicle, evaluated at 512-32 px (docs/screen.md)",
        models=tuple(LOD_MODELS), faces={m: _halving(n) for m, n in LOD_MODELS.items()},
        protocols=LOD_PROTOCOL),
    "lod-ci": Suite(
        "lod-ci", "the part of the lod suite CI runs: the crate's halving chain with qslim "
        "and meshopt at 512-32 px",
        models=("crate",), variants=(("qslim", {}), ("meshopt", {})),
        faces={"crate": _halving(LOD_MODELS["crate"])}, protocols=LOD_PROTOCOL),
    "ci": Suite(
        "ci", "small enough for CI: bunny and torus at 2% and 1% of their faces, every "
        "available method", models=("bunny", "torus"), ratios=(0.02, 0.01),
        claims=(
            Claim("ci-image-driven", "Lindstrom & Turk 2000, Fig. 6",
                  "image-driven has a lower image error than qslim (at CI's budgets)",
                  "d_rms", "image-driven", "qslim", below=1.0),
            Claim("g2007-torus", "González et al. 2007, §4",
                  "the Canny texture penalty gives a textured model a lower image error "
                  "than its base method (quadric) alone", "d_rms", "canny-texture",
                  "quadric", below=1.0, models=("torus",)),
        )),
    "wild": Suite(
        "wild", "real-asset cases: every available method at 10 % and 3 % on the procedural "
        "analogues (a UV sphere's poles, a kit of many parts and flat-colour materials "
        "with non-manifold edges, a vehicle of separate parts) and, where present, the "
        "real assets of shared/assets/wild (a capsule, a bottle, a glTF truck, a cow)",
        models=("uv-sphere", "kit", "vehicle"), ratios=(0.10, 0.03),
        assets=("wild/capsule/capsule.obj", "wild/fuze/fuze.obj",
                "wild/milk-truck/CesiumMilkTruck.glb",
                "wild/spot/spot_triangulated.obj::texture=wild/spot/spot_texture.png"),
        claims=_wild_claims()),
    "lt2000-bunny": Suite(
        "lt2000-bunny", "L&T 2000 §5.1 (Table 1, Figures 5-7): the bunny at Table 1's five "
        "sizes scaled to our bunny, and at 1,332 faces",
        models=("bunny",),
        variants=(("image-driven", {}), ("memoryless", {}), ("qslim", {}),
                  ("fast-simplification", {})),
        faces={"bunny": tuple(sorted(
            _scaled(LT2000_BUNNY_FACES, 69451, BUNNY_FACES) + (1332,), reverse=True))},
        claims=(
            Claim("lt2000-fig1", "Lindstrom & Turk 2000, Fig. 1",
                  "image-driven has a lower image error than geometry-driven (memoryless) "
                  "simplification of the bunny at 1,333 faces", "d_rms", "image-driven",
                  "memoryless", below=1.0, faces=(1332,), paper="3.75 vs 4.10",
                  paper_value=3.75 / 4.10),
            Claim("lt2000-fig6", "Lindstrom & Turk 2000, Fig. 6",
                  "image-driven consistently has a lower image error than qslim",
                  "d_rms", "image-driven", "qslim", below=1.0),
            Claim("lt2000-fig6-memoryless", "Lindstrom & Turk 2000, Fig. 6",
                  "image-driven consistently has a lower image error than memoryless",
                  "d_rms", "image-driven", "memoryless", below=1.0),
            Claim("lt2000-fig5", "Lindstrom & Turk 2000, Fig. 5",
                  "image-driven has a lower mean geometric error than qslim",
                  "hausdorff_mean", "image-driven", "qslim", below=1.0),
            Claim("lt2000-fig5-memoryless", "Lindstrom & Turk 2000, Fig. 5",
                  "memoryless has the least mean geometric error (below image-driven's)",
                  "hausdorff_mean", "memoryless", "image-driven", below=1.0),
        )),
    "lt2000-torus": Suite(
        "lt2000-torus", "L&T 2000 §5.4 (Plates 12-13): the textured torus at 512 faces",
        models=("torus",),
        variants=(("image-driven", {}), ("memoryless", {}), ("qslim-texture", {}),
                  ("quadric", {})),
        faces={"torus": (512,)},
        claims=(
            Claim("lt2000-plate13", "Lindstrom & Turk 2000, Plate 13",
                  "on the textured torus at 512 faces image-driven has a lower image error "
                  "than QSlim", "d_rms", "image-driven", "qslim-texture", below=1.0,
                  paper="5.99 vs 8.76", paper_value=5.99 / 8.76),
            Claim("lt2000-plate13-memoryless", "Lindstrom & Turk 2000, Plate 13",
                  "on the textured torus at 512 faces image-driven has a lower image error "
                  "than geometry-driven (memoryless) simplification", "d_rms",
                  "image-driven", "memoryless", below=1.0, paper="5.99 vs 7.29",
                  paper_value=5.99 / 7.29),
            Claim("lt2000-plate13-qslim", "Lindstrom & Turk 2000, Plate 13 and §5.4",
                  "memoryless texture coordinates beat QSlim's even without a texture "
                  "cost", "d_rms", "memoryless", "qslim-texture", below=1.0,
                  paper="7.29 vs 8.76", paper_value=7.29 / 8.76),
        )),
    "lt2000-interior": Suite(
        "lt2000-interior", "L&T 2000 §5.2 (Plates 2-3): the interior model at 2,000 faces; "
        "image-driven with 0 and 10 interior views against memoryless and qslim "
        "(see exterior_share)",
        models=("interior",),
        variants=(("image-driven", {"interior_views": 0}),
                  ("image-driven", {"interior_views": 10}),
                  ("memoryless", {}), ("qslim", {})),
        faces={"interior": (2000,)},
        claims=(
            Claim("lt2000-interior", "Lindstrom & Turk 2000, §5.2 and Plates 2-3",
                  "with exterior views only, image-driven simplifies the hidden interior "
                  "away: at least 90 % of the faces kept are on the exterior",
                  "exterior_share", "image-driven[interior_views=0]", at_least=0.9,
                  note="the paper shows it in pictures; 90 % is our threshold"),
            Claim("lt2000-interior-never-seen", "Lindstrom & Turk 2000, §5.2 and Plates 2-3",
                  "with exterior views only, image-driven spends (almost) no faces where no "
                  "view sees the model: under 2 % of the faces kept", "never_seen_share",
                  "image-driven[interior_views=0]", below=0.02,
                  note="never_seen_share counts the faces kept where no protocol view sees "
                  "the original (metrics/visibility.py); 2 % is our threshold, chosen "
                  "before measuring"),
            Claim("lt2000-interior-never-seen-memoryless", "Lindstrom & Turk 2000, §5.2",
                  "image-driven keeps fewer faces where no view sees the model than "
                  "memoryless", "never_seen_share", "image-driven[interior_views=0]",
                  "memoryless", below=1.0),
            Claim("lt2000-interior-memoryless", "Lindstrom & Turk 2000, §5.2",
                  "image-driven keeps a larger share of exterior faces than memoryless",
                  "exterior_share", "image-driven[interior_views=0]", "memoryless",
                  at_least=1.0),
        )),
    "lt2000-shading": Suite(
        "lt2000-shading", "L&T 2000 §5.3 (Plates 4, 8): the bunny at 1,332 faces optimised "
        "for flat and for Gouraud + specular shading, each evaluated flat and Gouraud + "
        "specular; qslim for reference",
        models=("bunny",),
        variants=(("image-driven", {"shading": "flat"}),
                  ("image-driven", {"shading": "gouraud", "specular": True}), ("qslim", {})),
        faces={"bunny": (1332,)},
        protocols=(("flat", False), ("gouraud", True)),
        claims=(
            Claim("lt2000-shading-gouraud", "Lindstrom & Turk 2000, §5.3 and Plate 8",
                  "optimised for Gouraud shading with specular highlights, image-driven "
                  "has a lower image error under that shading than optimised for flat",
                  "d_rms", "image-driven[shading=gouraud,specular=true]",
                  "image-driven[shading=flat]", below=1.0, shading="gouraud-spec"),
            Claim("lt2000-shading-flat", "Lindstrom & Turk 2000, §5.3 and Plate 4",
                  "optimised for flat shading, image-driven has a lower image error under "
                  "flat shading than optimised for Gouraud with specular highlights",
                  "d_rms", "image-driven[shading=flat]",
                  "image-driven[shading=gouraud,specular=true]", below=1.0, shading="flat"),
        )),
    "w2003": Suite(
        "w2003", "Williams et al. 2003 §6: perceptual-mt's four error metrics (perceptual, "
        "object, screen, screen-silhouette) on torus-puzzle and the bunny at 90% and 98% "
        "simplification, Gouraud shading with specular highlights",
        models=W2003_MODELS, variants=W2003_VARIANTS, ratios=(0.10, 0.02),
        protocols=(("gouraud", True),),
        claims=(
            Claim("w2003-98", "Williams et al. 2003, Plate 2 and Fig. 4",
                  "at 98 % simplification with per-vertex lighting the perceptual metric "
                  "gives a lower image error than screen-space deviation", "d_rms",
                  "perceptual-mt[error=perceptual]", "perceptual-mt[error=screen]",
                  below=1.0, ratios=(0.02,), paper="ltdiff 3,123 vs 3,689",
                  paper_value=3123 / 3689,
                  note="the paper measures with its own ltdiff; ours is d_rms"),
            Claim("w2003-98-flip", "Williams et al. 2003, Plate 2 and Fig. 4",
                  "the same, measured with FLIP", "flip",
                  "perceptual-mt[error=perceptual]", "perceptual-mt[error=screen]",
                  below=1.0, ratios=(0.02,), paper="ltdiff 3,123 vs 3,689",
                  paper_value=3123 / 3689),
        )),
    "w2003-paper": Suite(
        "w2003-paper", "Williams et al. 2003 §6 in the paper's own setting: the w2003 "
        "variants evaluated on one representative view at 1,024², gray background, "
        "Gouraud shading with specular highlights",
        models=W2003_MODELS, variants=W2003_VARIANTS, ratios=(0.10, 0.02),
        protocols=(("gouraud", True, W2003_PAPER_SETTING),),
        claims=(
            Claim("w2003-98-paper", "Williams et al. 2003, Plate 2 and Fig. 4",
                  "at 98 % simplification with per-vertex lighting the perceptual metric "
                  "gives a lower image error than screen-space deviation, measured as the "
                  "paper does: one representative view at 1,024², gray background",
                  "d_rms", "perceptual-mt[error=perceptual]", "perceptual-mt[error=screen]",
                  below=1.0, ratios=(0.02,), paper="ltdiff 3,123 vs 3,689",
                  paper_value=3123 / 3689, shading="gouraud-spec-1024-representative",
                  note="one view (metrics.views.REPRESENTATIVE_VIEW, chosen before "
                  "measuring) per model, so one draw from the spread of the per-view "
                  "ratios of w2003 (the README's diagnosis); the paper measures with its "
                  "own ltdiff, ours is d_rms"),
            Claim("w2003-98-paper-flip", "Williams et al. 2003, Plate 2 and Fig. 4",
                  "the same in the paper's setting, measured with FLIP", "flip",
                  "perceptual-mt[error=perceptual]", "perceptual-mt[error=screen]",
                  below=1.0, ratios=(0.02,), paper="ltdiff 3,123 vs 3,689",
                  paper_value=3123 / 3689, shading="gouraud-spec-1024-representative"),
        )),
    "g2008": Suite(
        "g2008", "González et al. 2008 (WSCG): entropy-twin (with and without the UV "
        "correction) against qslim, qslim-texture, quadric and canny-texture on game-style "
        "meshes with duplicated vertices, and at the sizes of the paper's Table 1",
        models=("crate", "barrel", "bunny-textured", "bunny-textured-815",
                "bunny-textured-4698", "torus-13810"),
        variants=(("entropy-twin", {}), ("entropy-twin", {"uv_correction": False}),
                  ("qslim", {}), ("qslim-texture", {}), ("quadric", {}),
                  ("canny-texture", {})),
        faces={"crate": (300, 100), "barrel": (300, 100), "bunny-textured": (1000, 500),
               "bunny-textured-815": (100,), "bunny-textured-4698": (500,),
               "torus-13810": (1000,)},
        claims=(
            Claim("g2008-uv-correction", "González et al. 2008, §3",
                  "the UV correction lowers entropy-twin's image error on textured meshes",
                  "d_rms", "entropy-twin", "entropy-twin[uv_correction=false]", below=1.0),
            Claim("g2008-seams", "González et al. 2008, §3",
                  "twin edges keep the seams of game-style meshes closed: no seam cracks",
                  "seam_cracks", "entropy-twin", below=0.5, models=("crate", "barrel")),
        )),
    "g2007": Suite(
        "g2007", "González et al. 2007 (GRAPP): canny-texture (the penalty in the base "
        "cost's units, and as the version-4 area ratio at unit diagonal) against its base "
        "alone (canny_weight=0, quadric's policy, which also records the crossing edges) "
        "and quadric, on the torus and bunny-textured from 50 % to 0.5 % of the faces",
        models=("torus", "bunny-textured"),
        variants=(("canny-texture", {}), ("canny-texture", {"canny_units": "area"}),
                  ("canny-texture", {"canny_weight": 0.0}), ("quadric", {})),
        ratios=G2007_RATIOS,
        claims=(
            Claim("g2007", "González et al. 2007, §4 and Figures 7-17",
                  "the Canny texture penalty gives a textured model a lower image error "
                  "than its base method alone", "d_rms", "canny-texture", "quadric",
                  below=1.0),
            Claim("g2007-paper-range", "González et al. 2007, §4 and Figures 7-17",
                  "the same at the paper's own levels, 50 % and 25 % of the faces",
                  "d_rms", "canny-texture", "quadric", below=1.0, ratios=(0.5, 0.25),
                  note="the paper shows 75 %, 50 % and 25 % of the edges kept"),
            Claim("g2007-borders", "González et al. 2007, §4 and §5",
                  "the penalty keeps edges that cross texture borders: without it (the "
                  "base alone) a smaller share of the result's edges crosses a border",
                  "stats.crossing_share_after", "canny-texture[canny_weight=0]",
                  "canny-texture", below=1.0,
                  note="crossing_share_after: the share of the result's welded edges "
                  "whose UV segment crosses a Canny border (methods/canny_texture.py)"),
        )),
    # Ablations: what a claim's outcome comes from (issue notes give the tables).
    "lt2000-interior-ablation": Suite(
        "lt2000-interior-ablation", "ablation of lt2000-interior: image-driven with no "
        "memoryless tie-breaker (geometry_weight=0) and with twice the pre-simplified faces "
        "(presimplify_faces=40000), against the default; see never_seen_share",
        models=("interior",),
        variants=(("image-driven", {"interior_views": 0}),
                  ("image-driven", {"interior_views": 0, "geometry_weight": 0.0}),
                  ("image-driven", {"interior_views": 0, "presimplify_faces": 40000}),
                  ("memoryless", {})),
        faces={"interior": (2000,)}),
    "g2008-ablation": Suite(
        "g2008-ablation", "ablation of entropy-twin's image error: the background in the "
        "entropy, the Canny term, the pre-simplification and full-edge (optimal) against "
        "half-edge placement, next to qslim and memoryless, on the bunny (2 %) and "
        "bunny-textured (10 %)",
        models=("bunny", "bunny-textured"),
        variants=(("entropy-twin", {}), ("entropy-twin", {"background": False}),
                  ("entropy-twin", {"canny": False}),
                  ("entropy-twin", {"presimplify_faces": -1}),
                  ("entropy-twin", {"placement": "optimal"}),
                  ("qslim", {}), ("memoryless", {})),
        faces={"bunny": (1123,), "bunny-textured": (1000,)}),
    "w2003-ablation": Suite(
        "w2003-ablation", "ablation of w2003-98: perceptual-mt at 98 % without maximal "
        "contrast on silhouettes, without §5.4's lighting bounds in the contrast, with the "
        "texture deviation as feature size, with the CSF peak at 50 and 1,000 instead of "
        "200, at 10 pixels per degree instead of 32, and refined from scratch in every "
        "view, next to the screen-space error; under our protocol and the paper's "
        "setting (one view at 1,024²)",
        models=("torus-puzzle", "bunny"),
        variants=(("perceptual-mt", {}), ("perceptual-mt", {"error": "screen"}),
                  ("perceptual-mt", {"silhouette_contrast": False}),
                  ("perceptual-mt", {"lighting_contrast": False}),
                  ("perceptual-mt", {"feature_size": "deviation"}),
                  ("perceptual-mt", {"peak_sensitivity": 50.0}),
                  ("perceptual-mt", {"peak_sensitivity": 1000.0}),
                  ("perceptual-mt", {"ppd": 10.0}),
                  ("perceptual-mt", {"refinement": "scratch"})),
        ratios=(0.02,),
        protocols=(("gouraud", True), ("gouraud", True, W2003_PAPER_SETTING))),
}


def evaluation_protocols(suite: Suite | None = None, shading: str | None = None,
                         specular: bool = False) -> list:
    """The :class:`~metrics.protocol.Protocol` list of a run.

    ``--shading`` on the command line replaces the suite's protocols by the one given
    (at the default image settings); ``--specular`` alone adds specular highlights to
    each of them, keeping their options. Without a suite the default is flat shading.
    """
    if shading is not None:
        if shading not in SHADINGS:
            raise ValueError(f"shading must be one of {', '.join(SHADINGS)}, got {shading!r}")
        entries = [(shading, specular, {})]
    elif suite is not None:
        entries = [(s, spec or specular, options)
                   for s, spec, options in map(_protocol_entry, suite.protocols)]
    else:
        entries = [("flat", specular, {})]
    return list(dict.fromkeys(_protocol(*e) for e in entries))


def get_suite(name: str) -> Suite:
    from bench.core.errors import UnknownNameError
    from bench.core.registry import suggest

    if name not in SUITES:
        raise UnknownNameError(f"unknown suite '{name}'{suggest(name, SUITES)} "
                               f"(suites: {', '.join(sorted(SUITES))})")
    return SUITES[name]
