"""The image term of the engine: Lindstrom & Turk 2000, §4.2.

Image-driven simplification costs a collapse by how much it changes the mean-square
luminance error against images of the original, over ``V`` views (equation 8):

    f(e, k) = sum_h sum_{(i, j) in R_h} (y0 - y^{k+1})^2 - (y0 - y^k)^2

where ``R_h`` is view ``h``'s pixel rectangle around the triangles the collapse touches.
This module keeps, inside the engine's numba loop, the images ``Y`` of the *current*
mesh and everything needed to re-render a rectangle of them:

* per view and vertex the screen position, per face and view its pixel bounding box,
  per vertex its unit normal and (gouraud) its lighting in every view;
* a per-view *tile index* (8 x 8-pixel tiles, each listing the faces whose box
  overlaps it) to find the faces under a rectangle;
* :func:`image_cost` renders each view's rectangle as it would look after a *simulated*
  collapse (the kept vertex at its new place, the removed faces gone, new texture
  coordinates and vertex normals) into scratch buffers and returns equation 8;
  :func:`commit_geometry` and :func:`commit_render` do the same for the collapse
  actually made and write it into ``Y``.

Only what can change is drawn (:func:`_render_view`): a pixel whose visible face is
not one of the changed faces keeps that face, whose depth is kept too (``DZ``), so the
changed faces are scanned over the rectangle against those depths, and every other
face is scanned only over the pixels the changed faces used to show (the *holes*):
that is the "un-rendering" of §4.2.3, surfaces hidden behind removed faces reappear.

Rendering is :mod:`methods.imaging.raster`'s: each face to draw becomes a row of the per-face
table and the same :func:`~methods.imaging.raster.scan_row` and
:func:`~methods.imaging.raster.shade_pixel` do the pixels. A pixel goes to the face with the
smaller (depth, face id), whatever order faces are scanned in, which is what a full
render drawing faces in increasing index with ``GL_LESS`` gives. Every face scanned gets
its row set up afresh from the per-vertex screen positions: the time of a re-render is
in its pixel tests, not in that set-up, and a per-view cache of the unchanged faces'
set-up did not pay (``docs/maintainers.md`` has the profile and the figures). Faces keep their
indices for the life of the engine (a collapse only deletes faces and renames
corners), and every per-vertex quantity is computed by the same function in both
cases (vertex normals summed over incident faces in increasing face index). The
maintained images, face ids and depths therefore equal a from-scratch render **bit for
bit**; ``simplify_mesh(..., verify=True)`` checks it at the end of a run.

The rectangle of a view is the union of the old and the new pixel boxes of every face
around the edge (the paper's ``[[e]] ∪ [[v]]``); with gouraud shading also the boxes of
the faces around the vertices whose normal changes (the paper's footnote 3).

The same region re-renders give the *viewpoint entropy* term of González et al. 2008
(§3, the cost of Castelló et al. 2007; ``ImageTerm.entropy_weight``): the state then
also keeps, per view, the pixel count a_f of every face (and of the background), the
sum S = sum a log a and the total A, so that H_v = log A - S / A. A candidate's new face
ids inside its rectangles, compared with ``IDS``, give the count changes; only the faces
whose count changes enter S and A, so ΔH_v costs one pass over the rectangle
(:func:`_entropy_change`), and a commit updates the counts from the same pixels. With
``weight`` 0 (entropy alone) no pixel is shaded: only ``IDS`` and ``DZ`` are kept.
The counts also tell a view where no changed face is seen; if no changed face, as
after the collapse, wins a pixel of the rectangle either (a scan that writes nothing,
:func:`~methods.imaging.raster.wins_any`), the view is left out, nothing copied.
And since |dH| is never negative, :func:`image_cost` can stop once the views done sum
past a ``bound``: the engine tries a half-edge collapse both ways, and the second way
stops as soon as it is sure to cost more than the first.

Tile index versus the paper's row/column buckets: the paper keeps a hash table of
triangles per pixel row and column and intersects the unions over the rectangle with
time stamps. Tiles need no intersection (one traversal), list a small face in one to
four tiles instead of every row and column it spans, and live in flat arrays that numba
traverses quickly. Each tile has spare capacity; a face whose box grows is appended to
the new tiles it reaches, stale entries are filtered by the box test, and the index is
rebuilt only when a tile overflows.
"""
