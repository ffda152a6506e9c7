"""The images of the report: which files of a run folder it may show, and how.

Images are read only from inside the run folder and only when they are PNG files
(:func:`run_png`; :func:`run_file` is the check of place, name and size it shares with
the 3D view's meshes). The report then shows them one of two ways:

- :class:`RunFiles` (the default): as files of the run folder, linked by relative URLs,
  so the folder opens from disk with no server and can be zipped or published as it is.
  A sheet shows a thumbnail (:data:`THUMB_SIZE`² JPEG at quality :data:`THUMB_QUALITY`,
  in ``images/thumbs/``) that links to the full PNG; difference images are written to
  ``images/diff/`` and plots as SVG to ``images/plots/``. Thumbnails are made only from
  PNGs that :func:`run_png` accepts, and nothing is written outside the run folder
  (:meth:`RunFiles.file` writes the report's other files, such as the 3D view's, the
  same way).
- :class:`Inline` (``--single-file``): every image a base64 data URI in the page, as one
  self-contained file for small runs.
"""

from __future__ import annotations

import base64
import io
from functools import lru_cache
from pathlib import Path, PurePosixPath
from typing import NamedTuple
from urllib.parse import quote

import numpy as np

from bench.io.atomic import write_atomic

__all__ = ["THUMB_QUALITY", "THUMB_SIZE", "Inline", "Png", "RunFiles", "Shown", "run_file",
           "run_png"]

#: The first bytes of every PNG file.
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: Largest image shown (a sheet view is well under 1 MB, a 1024² artifact a few MB).
MAX_IMAGE_BYTES = 32 << 20
#: Largest image decoded for a thumbnail or a difference image (a PNG is compressed: a
#: small file may hold a huge picture).
MAX_PIXELS = 4096 * 4096
#: Thumbnails fit in THUMB_SIZE × THUMB_SIZE pixels (a 512² view becomes 256²) ...
THUMB_SIZE = 256
#: ... and are JPEG files of this quality (about 10 KB for a sheet view).
THUMB_QUALITY = 85


class Png(NamedTuple):
    """A PNG file of the run folder that may be shown: its bytes, and its path relative
    to the (resolved) run folder, with no ``..`` and no links."""

    data: bytes
    path: str


class Shown(NamedTuple):
    """An image as the page refers to it: ``src`` for ``<img>``, ``href`` the full-size
    image a click away (None when ``src`` is the image itself). Both are URL-quoted and
    HTML-escaped, ready for an attribute."""

    src: str
    href: str | None = None


def run_png(run_dir: Path, relative, refused: list[str] | None = None,
            what: str = "") -> Png | None:
    """The PNG file ``run_dir/relative``, or None.

    Refused (None, and a reason appended to ``refused`` when given): a name that is not
    a relative string, a path that leaves the run folder (``..``, an absolute path, a
    link to elsewhere), a name without ``.png``, a file that does not start with the PNG
    signature or is over :data:`MAX_IMAGE_BYTES`. A file that is simply absent is None
    (and a reason only for ``what``-named images a record promised).
    """
    found = run_file(run_dir, relative, refused, what or "image", ".png", MAX_IMAGE_BYTES,
                     missing=bool(what))
    if found is None:
        return None
    data, path = found
    if not data.startswith(PNG_SIGNATURE):
        if refused is not None:
            refused.append(f"{what or 'image'} {str(relative)!r}: not a PNG file; not shown")
        return None
    return Png(data, path)


def run_file(run_dir: Path, relative, refused: list[str] | None, what: str, suffix: str,
             max_bytes: int, missing: bool = False) -> tuple[bytes, str] | None:
    """The bytes of the file ``run_dir/relative`` and its path relative to the resolved
    run folder, or None: refused (with a reason in ``refused``, naming it ``what``) when
    the name is not a relative string, the path leaves the run folder (``..``, an
    absolute path, a link to elsewhere), its name does not end in ``suffix`` or the
    file is over ``max_bytes``; a file that is simply absent is None, with a reason
    only when ``missing``."""
    def refuse(why: str) -> None:
        if refused is not None:
            refused.append(f"{what} {str(relative)!r}: {why}; not shown")

    if not isinstance(relative, (str, Path)) or not str(relative):
        refuse("not a file name")
        return None
    path = run_dir / relative
    root = run_dir.resolve()
    try:
        resolved = path.resolve()
    except (OSError, RuntimeError):  # RuntimeError: a symlink loop
        refuse("cannot be resolved")
        return None
    if Path(relative).is_absolute() or not resolved.is_relative_to(root):
        refuse("outside the run folder")
        return None
    name = resolved.name
    if not name.lower().endswith(suffix) or len(name) == len(suffix):  # ".PNG" is no PNG
        refuse(f"not a {suffix} file")
        return None
    try:
        if not resolved.is_file():
            if missing:
                refuse("no such file in the run folder")
            return None
        if resolved.stat().st_size > max_bytes:
            refuse(f"larger than {max_bytes >> 20} MB")
            return None
        data = resolved.read_bytes()
    except OSError as exc:
        refuse(f"unreadable ({exc.strerror or exc})")
        return None
    return data, resolved.relative_to(root).as_posix()


def _decode(data: bytes):
    """``data`` as an RGB PIL image, or None when it cannot be decoded or is larger than
    :data:`MAX_PIXELS`."""
    from PIL import Image

    try:
        with Image.open(io.BytesIO(data)) as image:
            if image.width * image.height > MAX_PIXELS:
                return None
            return image.convert("RGB")
    except (OSError, ValueError, SyntaxError, Image.DecompressionBombError):
        return None


def _luminance(data: bytes) -> np.ndarray | None:
    """The luminance of a PNG's pixels, or None when it cannot be decoded."""
    from metrics.image import luminance

    image = _decode(data)
    return None if image is None else luminance(np.asarray(image))


@lru_cache(maxsize=16)
def _original_luminance(data: bytes) -> np.ndarray | None:
    """:func:`_luminance` of an original's view, which every result of the model is
    compared with (read-only: it is shared)."""
    y = _luminance(data)
    if y is not None:
        y.flags.writeable = False
    return y


def difference_png(original: Png | None, simplified: Png | None) -> bytes | None:
    """|ΔY| scaled ×4 and inverted (white = equal), as in Plate 13's difference images,
    as PNG bytes; None when either image is missing or the two cannot be compared."""
    from PIL import Image

    if original is None or simplified is None:
        return None
    a, b = _original_luminance(original.data), _luminance(simplified.data)
    if a is None or b is None or a.shape != b.shape:
        return None
    diff = 255 - np.clip(4 * np.abs(a - b), 0, 255)
    buf = io.BytesIO()
    Image.fromarray(diff.astype(np.uint8)).save(buf, format="PNG")
    return buf.getvalue()


def thumbnail(data: bytes) -> bytes | None:
    """A JPEG of ``data`` fitting :data:`THUMB_SIZE`², or None when it cannot be decoded."""
    from PIL import Image

    image = _decode(data)
    if image is None:
        return None
    image.thumbnail((THUMB_SIZE, THUMB_SIZE), Image.Resampling.LANCZOS)
    buf = io.BytesIO()
    image.save(buf, format="JPEG", quality=THUMB_QUALITY, optimize=True)
    return buf.getvalue()


def _data_uri(data: bytes, kind: str = "image/png") -> str:
    return f"data:{kind};base64," + base64.b64encode(data).decode()


def _url(path: str) -> str:
    """A path relative to the run folder as a relative URL in an HTML attribute (every
    character outside letters, digits and ``/._-~`` percent-encoded, so a quote or a
    ``#`` in a record's key cannot end the attribute or the path)."""
    return quote(path, safe="/")


def _figure_bytes(fig, kind: str) -> bytes:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    metadata = {"Date": None} if kind == "svg" else None  # the same plot, the same file
    fig.savefig(buf, format=kind, dpi=90, bbox_inches="tight", metadata=metadata)
    plt.close(fig)
    return buf.getvalue()


class Inline:
    """``--single-file``: every image a data URI in the page."""

    files = False

    def plot(self, fig, name: str) -> str:
        return _data_uri(_figure_bytes(fig, "png"))

    def view(self, png: Png) -> Shown | None:
        return Shown(_data_uri(png.data))

    def difference(self, data: bytes, simplified: Png) -> Shown | None:
        return Shown(_data_uri(data))


class RunFiles:
    """Images as files of the run folder ``run_dir``, linked by relative URLs; what
    cannot be written inside the run folder is noted in ``refused`` and not shown."""

    files = True

    def __init__(self, run_dir: Path, refused: list[str]):
        self.root = Path(run_dir).resolve()
        self.refused = refused
        self._shown: dict[str, Shown | None] = {}  # by path: an original's views recur

    def plot(self, fig, name: str) -> str:
        """``fig`` as ``images/plots/<name>.svg``; ``name`` is the report's own
        (letters, digits, ``-`` and ``_``), never a record's string."""
        import matplotlib

        path = f"images/plots/{name}.svg"
        with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": name}):
            data = _figure_bytes(fig, "svg")
        return _url(path) if self._write(path, data) else ""

    def view(self, png: Png) -> Shown | None:
        """The thumbnail of a PNG of the run folder, linking to the PNG itself (made
        once per file: the original's views are shown beside every result's)."""
        if png.path not in self._shown:
            self._shown[png.path] = self._thumbnail(png)
        return self._shown[png.path]

    def _thumbnail(self, png: Png) -> Shown | None:
        data = thumbnail(png.data)
        if data is None:
            self.refused.append(f"image {png.path!r}: cannot be decoded; not shown")
            return None
        thumb = self._thumb_path(png.path)
        return Shown(_url(thumb), _url(png.path)) if self._write(thumb, data) else None

    def difference(self, data: bytes, simplified: Png) -> Shown | None:
        """The difference image of ``simplified`` (a sheet view) in ``images/diff/``,
        with its thumbnail."""
        path = "images/diff/" + _under_images(simplified.path)
        if not self._write(path, data):
            return None
        return self.view(Png(data, path))

    @staticmethod
    def _thumb_path(path: str) -> str:
        return "images/thumbs/" + str(Path(_under_images(path)).with_suffix(".jpg"))

    def file(self, relative: str, data: bytes) -> str:
        """Write ``data`` as the run folder's file ``relative``: a name the report makes,
        either of its own or from the path of a file the run folder holds (as
        :func:`run_file` hands it back: relative to the resolved run folder, no ``..``),
        never a record's string as it is. Its URL, or "" when it was not written (the
        reason is in ``refused``): a name that is absolute or holds ``..`` is refused,
        and so is a folder that a link takes out of the run folder."""
        if PurePosixPath(relative).is_absolute() or ".." in PurePosixPath(relative).parts:
            self.refused.append(f"{relative!r}: not a path inside the run folder; not written")
            return ""
        return _url(relative) if self._write(relative, data) else ""

    def _write(self, relative: str, data: bytes) -> bool:
        """Write ``data`` to ``root/relative`` (atomically), unless a link in the run
        folder would take it elsewhere (then a note in ``refused``)."""
        path = self.root / relative
        if not _inside(self.root, path.parent):
            self.refused.append(f"{relative!r}: its folder leaves the run folder; not written")
            return False
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            write_atomic(path, data)
        except OSError as exc:  # e.g. a folder where the file goes
            self.refused.append(f"{relative!r}: cannot write it ({exc.strerror or exc}); "
                                "not shown")
            return False
        return True


def _under_images(path: str) -> str:
    """``path`` without its leading ``images/``; a path elsewhere in the run folder goes
    under ``_/`` (no job key or original folder is called ``_``)."""
    return path.removeprefix("images/") if path.startswith("images/") else "_/" + path


def _inside(root: Path, folder: Path) -> bool:
    """Whether ``folder``, once made, lies inside ``root``: its nearest existing
    ancestor resolves inside (the parts made later are plain folders)."""
    existing = next(p for p in (folder, *folder.parents) if p.exists() or p.is_symlink())
    try:
        return existing.resolve(strict=True).is_relative_to(root) and existing.is_dir()
    except (OSError, RuntimeError):
        return False
